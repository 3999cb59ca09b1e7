"""MO-Humanoid (SPEC §1.2): 2 objectives, context = 13 masses and 17 joint dampings."""

from __future__ import annotations

import mujoco
import numpy as np

from morl_trl.envs.mujoco.base import MujocoContextEnv
from morl_trl.envs.mujoco.spec import HUMANOID_CONTEXT

__all__ = ["MOHumanoidEnv"]


class MOHumanoidEnv(MujocoContextEnv):
    """Batched contextual MO-Humanoid.

    Observation ``[*B, 348]``, Gymnasium ``Humanoid-v5``'s layout: ``qpos[2:]`` (22),
    ``qvel`` (23), ``cinert[1:]`` (130), ``cvel[1:]`` (78), ``qfrc_actuator[6:]`` (17),
    ``cfrc_ext[1:]`` (78), read after ``mj_step`` + ``mj_rnePostConstraint`` as Gymnasium
    does. Action ``[*B, 17]`` in ``[-0.4, 0.4]``; frame skip 5 (``dt = 0.015``).

    Reward ``[*B, 2]`` = ``[x_velocity, -sum(ctrl**2)] + 2.0``, where ``x_velocity`` is the
    centre of mass's (computed with the context's masses) and the healthy bonus 2.0 is added
    to both objectives on every step (the paper's quirks: no 1.25 forward weight, no contact
    cost). ``"original_reward"`` is the paper's f_SORL as the authors compute it:
    ``1.25 * x_velocity + 2.0 - 0.001 * sum(ctrl**2)`` (Gymnasium ``Humanoid-v5``'s reward
    with ``healthy_reward=2.0``, ``contact_cost_weight=0`` and ``ctrl_cost_weight=0.001``,
    the paper's and authors' weight, not Gymnasium's 0.1; the healthy term 2.0 is kept on
    the terminal step, where Gymnasium v5 pays 0). Terminates when the torso height ``qpos[2]`` leaves
    ``(1, 2)``. Reset noise ``U(+-1e-2)`` on ``qpos`` and ``qvel``.

    Context (30): 13 masses (``mass_torso`` ... ``mass_left_lower_arm``) ->
    ``body_mass[1:14]``; 17 joint dampings (``damping_abdomen_z`` ... ``damping_left_elbow``)
    -> ``dof_damping[6:23]``.

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("MOHumanoidLight-v5", num_envs=2, seed=0)
        >>> env.rollout(3)["observation"].shape
        torch.Size([2, 3, 348])
    """

    xml_file = "humanoid.xml"
    frame_skip = 5
    reset_noise_scale = 1e-2
    context_space_ = HUMANOID_CONTEXT
    objective_names = ("forward", "energy")
    observation_dim = 348
    healthy_bonus = 2.0
    _bound_fields = ("qpos", "qvel", "ctrl", "xipos", "cinert", "cvel", "qfrc_actuator")
    # the paper's f_SORL: Gymnasium Humanoid-v5 with healthy_reward=2.0, contact_cost_weight=0,
    # ctrl_cost_weight=0.001 (the paper's and the authors' value)
    forward_reward_weight = 1.25
    ctrl_cost_weight = 1e-3
    healthy_reward = 2.0

    def _read_context(self, model: mujoco.MjModel) -> np.ndarray:
        return np.concatenate([model.body_mass[1:14], model.dof_damping[6:23]])

    def _write_context(self, model: mujoco.MjModel, context: np.ndarray) -> None:
        model.body_mass[1:14] = context[0:13]
        model.dof_damping[6:23] = context[13:30]

    def _reset_noise(self, rng):
        s = self.reset_noise_scale
        qpos = self._init_qpos + rng.uniform(-s, s, size=self._init_qpos.size)
        qvel = self._init_qvel + rng.uniform(-s, s, size=self._init_qvel.size)
        return qpos, qvel

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._cfrc_ext = np.zeros((self.num_envs, *self._fields["xipos"].shape[1:-1], 6))
        self._scratch = mujoco.MjData(self._models[0])

    def _after_step(self, ids) -> None:
        # Gymnasium calls mj_rnePostConstraint after mj_step to fill cfrc_ext (the last 78
        # observation entries); Batch has no such hook, so run it on a copy of each sub-env's
        # MjData (a few microseconds each; the copy is exact, the state is untouched)
        for i in range(self.num_envs) if ids is None else ids:
            self._sim.get_data(i, self._scratch)
            mujoco.mj_rnePostConstraint(self._models[i], self._scratch)
            self._cfrc_ext[i] = self._scratch.cfrc_ext

    def _snapshot_extra(self) -> dict:
        return {"_cfrc_ext": self._cfrc_ext}  # (filled after each step, not by mj_forward)

    def _after_reset(self, ids: np.ndarray) -> None:
        # Gymnasium's reset ends with mj_forward, which leaves cfrc_ext at zero
        self._cfrc_ext[ids] = 0.0

    def _x_position(self) -> np.ndarray:
        # Gymnasium's mass_center: body_mass-weighted mean of the bodies' xipos
        mass = self._body_mass
        return np.einsum("nb,nb->n", mass, self._fields["xipos"][:, :, 0]) / mass.sum(axis=1)

    def _observation(self) -> np.ndarray:
        n, f = self.num_envs, self._fields
        return np.concatenate(
            [
                f["qpos"][:, 2:],
                f["qvel"],
                f["cinert"][:, 1:].reshape(n, -1),
                f["cvel"][:, 1:].reshape(n, -1),
                f["qfrc_actuator"][:, 6:],
                self._cfrc_ext[:, 1:].reshape(n, -1),
            ],
            axis=1,
        )

    def _rewards(self, x_velocity, ctrl):
        sq = np.square(ctrl).sum(axis=1)
        reward = np.stack([x_velocity, -sq], axis=1) + self.healthy_bonus
        z = self._fields["qpos"][:, 2]
        healthy = (1.0 < z) & (z < 2.0)
        # the authors keep the healthy term on the terminal step too
        original = (self.forward_reward_weight * x_velocity + self.healthy_reward) - self.ctrl_cost_weight * sq
        return reward, original, ~healthy
