"""DMC-Cheetah (``dm_control.suite.cheetah.run``) as a batched contextual MO domain."""

from __future__ import annotations

import numpy as np

from morl_trl.envs.dmc.base import DMCContextEnv, legacy_step, small_control, tolerance
from morl_trl.envs.dmc.spec import CHEETAH_CONTEXT

__all__ = ["DMCCheetahEnv"]

_RUN_SPEED = 10.0  # dm_control.suite.cheetah's
_SETTLE_STEPS = 200  # the suite's "stabilize the model before the actual simulation"


class DMCCheetahEnv(DMCContextEnv):
    """Batched contextual Cheetah of the DeepMind Control Suite (``cheetah.run``).

    Observation ``[*B, 17]``: the suite's ``position`` (``qpos[1:]``, 8) and ``velocity``
    (``qvel``, 9). Action ``[*B, 6]`` in ``[-1, 1]``; one physics step of 10 ms per action
    (the suite's task gives no control interval). A reset draws the limited joints uniformly
    in their ranges and lets the model settle for 200 physics steps, as the suite does.

    Reward ``[*B, 2]`` = ``[speed, energy]``, each in ``[0, 1]``; ``"original_reward"`` is the
    suite's ``speed``.

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("DMCCheetahSlippery-v0", num_envs=2, seed=0)
        >>> env.rollout(3)["next", "reward"].shape
        torch.Size([2, 3, 2])
    """

    suite_domain = "cheetah"
    control_timestep = None
    stiffness_is_factor = True
    context_space_ = CHEETAH_CONTEXT
    objective_names = ("speed", "energy")
    observation_dim = 17
    render_camera = {"track_body": 1, "distance": 4.0, "elevation": -20.0}
    _bound_fields = ("qpos", "qvel", "ctrl", "sensordata")

    def _initialize_episode(self, model, data, rng) -> None:
        limited = model.jnt_limited == 1  # (every joint has one dof, as the suite asserts)
        lower, upper = model.jnt_range[limited].T
        data.qpos[limited] = rng.uniform(lower, upper)
        legacy_step(model, data, _SETTLE_STEPS)
        data.time = 0

    def _observation(self) -> np.ndarray:
        return np.concatenate([self._fields["qpos"][:, 1:], self._fields["qvel"]], axis=1)

    def _rewards(self, ctrl):
        speed = tolerance(self._fields["sensordata"][:, 0], bounds=(_RUN_SPEED, float("inf")), margin=_RUN_SPEED,
                          value_at_margin=0, sigmoid="linear")
        return np.stack([speed, small_control(ctrl)], axis=1), speed
