"""DMC-Walker (``dm_control.suite.walker``, walk and run) as a batched contextual MO domain."""

from __future__ import annotations

import numpy as np

from morl_trl.envs.dmc.base import DMCContextEnv, randomize_limited_and_rotational_joints, small_control, tolerance
from morl_trl.envs.dmc.spec import WALKER_CONTEXT

__all__ = ["DMCWalkerEnv"]

# dm_control.suite.walker's constants
_STAND_HEIGHT = 1.2
_SPEEDS = {"walk": 1.0, "run": 8.0}


class DMCWalkerEnv(DMCContextEnv):
    """Batched contextual Walker of the DeepMind Control Suite (``walker.walk`` / ``walker.run``).

    Observation ``[*B, 24]``: the suite's ``orientations`` (14: ``xmat[1:, [xx, xz]]``),
    ``height`` (1) and ``velocity`` (9: ``qvel``), concatenated in that order. Action
    ``[*B, 6]`` in ``[-1, 1]``; 10 physics steps of 2.5 ms per action.

    Reward ``[*B, 3]`` = ``[speed, stand, energy]``, each in ``[0, 1]`` (see
    :mod:`morl_trl.envs.dmc.spec`); ``"original_reward"`` is the suite's
    ``stand * (5 * speed + 1) / 6``.

    Args:
        task: ``"walk"`` (target speed 1 m/s) or ``"run"`` (8 m/s).
        others: those of :class:`~morl_trl.envs.dmc.DMCContextEnv`.

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("DMCWalkerHeavy-v0", num_envs=2, seed=0)
        >>> td = env.rollout(3)
        >>> td["next", "reward"].shape, td["observation"].shape
        (torch.Size([2, 3, 3]), torch.Size([2, 3, 24]))
    """

    suite_domain = "walker"
    control_timestep = 0.025
    stiffness_is_factor = False
    context_space_ = WALKER_CONTEXT
    objective_names = ("speed", "stand", "energy")
    observation_dim = 24
    render_camera = {"track_body": 1, "distance": 4.0, "elevation": -20.0}
    _bound_fields = ("qpos", "qvel", "ctrl", "xmat", "xpos", "sensordata")

    def __init__(self, num_envs: int = 1, task: str = "walk", **kwargs) -> None:
        if task not in _SPEEDS:
            raise ValueError(f"task must be one of {sorted(_SPEEDS)}, got {task!r}")
        self.task = task
        self.move_speed = _SPEEDS[task]
        super().__init__(num_envs=num_envs, **kwargs)

    def _initialize_episode(self, model, data, rng) -> None:
        randomize_limited_and_rotational_joints(model, data, rng)

    def _observation(self) -> np.ndarray:
        xmat = self._fields["xmat"]
        orientations = xmat[:, 1:][:, :, [0, 2]].reshape(self.num_envs, -1)
        height = self._fields["xpos"][:, self._torso, 2:3]
        return np.concatenate([orientations, height, self._fields["qvel"]], axis=1)

    def _rewards(self, ctrl):
        height = self._fields["xpos"][:, self._torso, 2]
        upright = self._fields["xmat"][:, self._torso, 8]
        velocity = self._fields["sensordata"][:, 0]  # torso_subtreelinvel, x
        standing = tolerance(height, bounds=(_STAND_HEIGHT, float("inf")), margin=_STAND_HEIGHT / 2)
        stand = (3 * standing + (1 + upright) / 2) / 4
        speed = tolerance(velocity, bounds=(self.move_speed, float("inf")), margin=self.move_speed / 2,
                          value_at_margin=0.5, sigmoid="linear")
        original = stand * (5 * speed + 1) / 6
        return np.stack([speed, stand, small_control(ctrl)], axis=1), original
