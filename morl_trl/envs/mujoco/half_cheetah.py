"""MO-HalfCheetah (SPEC §1.2): 2 objectives, context = 7 masses and the feet's friction."""

from __future__ import annotations

import mujoco
import numpy as np

from morl_trl.envs.mujoco.base import MujocoContextEnv
from morl_trl.envs.mujoco.spec import CHEETAH_CONTEXT

__all__ = ["MOHalfCheetahEnv"]


class MOHalfCheetahEnv(MujocoContextEnv):
    """Batched contextual MO-HalfCheetah.

    Observation ``[*B, 17]``: ``qpos[1:]`` and ``qvel`` (Gymnasium's ``HalfCheetah-v5``
    layout). Action ``[*B, 6]`` in ``[-1, 1]``; frame skip 5 (``dt = 0.05``). Never
    terminates (only the time limit ends an episode).

    Reward ``[*B, 2]`` = ``[x_velocity, -sum(action**2)]``; ``"original_reward"`` is
    Gymnasium ``HalfCheetah-v5``'s ``x_velocity - 0.1 * sum(action**2)``. Reset noise
    ``U(+-0.1)`` on ``qpos`` and ``0.1 * N(0, 1)`` on ``qvel``.

    Context (8): seven masses ``mass_torso, mass_bthigh, mass_bshin, mass_bfoot,
    mass_fthigh, mass_fshin, mass_ffoot`` -> ``body_mass[1:8]``; ``friction`` ->
    ``pair_friction[0:2, :2]`` of the two explicit foot-floor contact pairs (default 0.4,
    where the model equals Gymnasium's).

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("MOHalfCheetahHeavy-v5", num_envs=2, seed=0)
        >>> env.rollout(3)["next", "reward"].shape
        torch.Size([2, 3, 2])
    """

    render_camera = {"track_body": 1, "distance": 4.0, "elevation": -20.0}
    xml_file = "half_cheetah.xml"
    frame_skip = 5
    reset_noise_scale = 0.1
    context_space_ = CHEETAH_CONTEXT
    objective_names = ("forward", "energy")
    observation_dim = 17
    # Gymnasium HalfCheetah-v5's scalar reward
    forward_reward_weight = 1.0
    ctrl_cost_weight = 0.1

    def _read_context(self, model: mujoco.MjModel) -> np.ndarray:
        return np.concatenate([model.body_mass[1:8], model.pair_friction[0, :1]])

    def _write_context(self, model: mujoco.MjModel, context: np.ndarray) -> None:
        model.body_mass[1:8] = context[0:7]
        model.pair_friction[0:2, 0:2] = context[7]

    def _reset_noise(self, rng):
        s = self.reset_noise_scale
        qpos = self._init_qpos + rng.uniform(-s, s, size=self._init_qpos.size)
        qvel = self._init_qvel + s * rng.standard_normal(self._init_qvel.size)
        return qpos, qvel

    def _observation(self) -> np.ndarray:
        return np.concatenate([self._fields["qpos"][:, 1:], self._fields["qvel"]], axis=1)

    def _rewards(self, x_velocity, ctrl):
        sq = np.square(ctrl).sum(axis=1)
        reward = np.stack([x_velocity, -sq], axis=1)
        original = self.forward_reward_weight * x_velocity - self.ctrl_cost_weight * sq
        return reward, original, np.zeros(self.num_envs, dtype=bool)
