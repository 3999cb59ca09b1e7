"""MO-Hopper (SPEC §1.2): 3 objectives, context = 4 masses, 3 joint dampings, foot friction."""

from __future__ import annotations

import mujoco
import numpy as np

from morl_trl.envs.mujoco.base import MujocoContextEnv
from morl_trl.envs.mujoco.spec import HOPPER_CONTEXT

__all__ = ["MOHopperEnv"]


class MOHopperEnv(MujocoContextEnv):
    """Batched contextual MO-Hopper.

    Observation ``[*B, 11]``: ``qpos[1:]`` and ``clip(qvel, -10, 10)`` (Gymnasium's
    ``Hopper-v5`` layout). Action ``[*B, 3]`` in ``[-1, 1]``; frame skip 4 (``dt = 0.008``).

    Reward ``[*B, 3]`` = ``[x_velocity, 10 * (z - z_init), -sum(action**2)] + 1.0``: the
    healthy bonus is added to *every* objective on every step, the terminal one included
    (the paper's quirk; ``z_init = 1.25`` is the XML's initial torso height, not the noisy
    reset height). ``"original_reward"`` is the authors' scalar reward
    ``x_velocity + 1.0 - 1e-3 * sum(action**2)``: Gymnasium's ``Hopper-v5`` function except
    that, as in the authors' env, the healthy term 1.0 is kept on the step that terminates
    (Gymnasium v5 pays 0 there; the paper writes ``1.5 v_x`` but states it is Gymnasium's).
    Terminates when ``z <= 0.7``, ``|angle| >= 0.2`` or any of ``qpos[2:], qvel`` leaves
    ``(-100, 100)``. Reset noise ``U(+-5e-3)`` on ``qpos`` and ``qvel``.

    Context (8): ``mass_torso, mass_thigh, mass_leg, mass_foot`` -> ``body_mass[1:5]``;
    ``damping_thigh, damping_leg, damping_foot`` -> ``dof_damping[3:6]``; ``friction`` ->
    ``pair_friction[0, :2]`` of the explicit foot-floor contact pair (default 1.0;
    Gymnasium's hopper has 2.0). The pair's other fields take MuJoCo's defaults (solimp
    ``0.9 0.95 0.001``, margin 0; SPEC §1.2 records only the pair's friction, so these are
    our reading of the authors' XML, not a recorded fact); Gymnasium's dynamic foot
    contact has the geoms' solimp ``.8 .8 .01`` and margin 0.002, so no friction makes this
    model Gymnasium's (``assets/hopper.xml``).

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("MOHopperSlippery-v5", num_envs=4, seed=0)
        >>> td = env.rollout(5)
        >>> td["next", "reward"].shape, td["observation"].shape
        (torch.Size([4, 5, 3]), torch.Size([4, 5, 11]))
    """

    render_camera = {"track_body": 2, "distance": 3.0, "elevation": -20.0}
    xml_file = "hopper.xml"
    frame_skip = 4
    reset_noise_scale = 5e-3
    context_space_ = HOPPER_CONTEXT
    objective_names = ("forward", "jump", "energy")
    observation_dim = 11
    healthy_bonus = 1.0
    # Gymnasium Hopper-v5's scalar reward
    forward_reward_weight = 1.0
    ctrl_cost_weight = 1e-3
    healthy_reward = 1.0

    def _read_context(self, model: mujoco.MjModel) -> np.ndarray:
        return np.concatenate([model.body_mass[1:5], model.dof_damping[3:6], model.pair_friction[0, :1]])

    def _write_context(self, model: mujoco.MjModel, context: np.ndarray) -> None:
        model.body_mass[1:5] = context[0:4]
        model.dof_damping[3:6] = context[4:7]
        model.pair_friction[0, :2] = context[7]

    def _reset_noise(self, rng):
        s = self.reset_noise_scale
        qpos = self._init_qpos + rng.uniform(-s, s, size=self._init_qpos.size)
        qvel = self._init_qvel + rng.uniform(-s, s, size=self._init_qvel.size)
        return qpos, qvel

    def _observation(self) -> np.ndarray:
        qpos, qvel = self._fields["qpos"], self._fields["qvel"]
        return np.concatenate([qpos[:, 1:], np.clip(qvel, -10.0, 10.0)], axis=1)

    def _is_healthy(self) -> np.ndarray:
        # Gymnasium: z > 0.7, -0.2 < angle < 0.2, every entry of (qpos[2:], qvel) in (-100, 100)
        qpos, qvel = self._fields["qpos"], self._fields["qvel"]
        z, angle = qpos[:, 1], qpos[:, 2]
        healthy = (np.abs(qpos[:, 2:]) < 100.0).all(axis=1) & (np.abs(qvel) < 100.0).all(axis=1)
        return healthy & (z > 0.7) & (z < np.inf) & (np.abs(angle) < 0.2)

    def _rewards(self, x_velocity, ctrl):
        sq = np.square(ctrl).sum(axis=1)
        reward = np.empty((self.num_envs, 3))
        reward[:, 0] = x_velocity
        reward[:, 1] = 10.0 * (self._fields["qpos"][:, 1] - self._init_qpos[1])
        reward[:, 2] = -sq
        reward += self.healthy_bonus
        healthy = self._is_healthy()
        # the authors keep the healthy term on the terminal step too
        original = (self.forward_reward_weight * x_velocity + self.healthy_reward) - self.ctrl_cost_weight * sq
        return reward, original, ~healthy
