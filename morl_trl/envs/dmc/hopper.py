"""DMC-Hopper (``dm_control.suite.hopper.hop``) as a batched contextual MO domain."""

from __future__ import annotations

import numpy as np

from morl_trl.envs.dmc.base import DMCContextEnv, randomize_limited_and_rotational_joints, small_control, tolerance
from morl_trl.envs.dmc.spec import HOPPER_CONTEXT

__all__ = ["DMCHopperEnv"]

# dm_control.suite.hopper's constants
_STAND_HEIGHT = 0.6
_HOP_SPEED = 2.0


class DMCHopperEnv(DMCContextEnv):
    """Batched contextual Hopper of the DeepMind Control Suite (``hopper.hop``).

    Observation ``[*B, 15]``: the suite's ``position`` (``qpos[1:]``, 6), ``velocity``
    (``qvel``, 7) and ``touch`` (``log1p`` of the toe and heel touch sensors, 2). Action
    ``[*B, 4]`` in ``[-1, 1]``; 4 physics steps of 5 ms per action.

    Reward ``[*B, 3]`` = ``[hop, stand, energy]``, each in ``[0, 1]``; ``"original_reward"``
    is the suite's ``stand * hop``.

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("DMCHopperDR-v0", num_envs=2, seed=0)
        >>> env.rollout(3)["next", "reward"].shape
        torch.Size([2, 3, 3])
    """

    suite_domain = "hopper"
    control_timestep = 0.02
    stiffness_is_factor = False
    context_space_ = HOPPER_CONTEXT
    objective_names = ("hop", "stand", "energy")
    observation_dim = 15
    render_camera = {"track_body": 1, "distance": 3.0, "elevation": -20.0}
    _bound_fields = ("qpos", "qvel", "ctrl", "xipos", "sensordata")

    def __init__(self, num_envs: int = 1, **kwargs) -> None:
        model = self._base_model()
        self._foot = model.body("foot").id
        self._touch = np.array([model.sensor(n).adr[0] for n in ("touch_toe", "touch_heel")])
        super().__init__(num_envs=num_envs, **kwargs)

    def _initialize_episode(self, model, data, rng) -> None:
        randomize_limited_and_rotational_joints(model, data, rng)

    def _observation(self) -> np.ndarray:
        touch = np.log1p(self._fields["sensordata"][:, self._touch])
        return np.concatenate([self._fields["qpos"][:, 1:], self._fields["qvel"], touch], axis=1)

    def _rewards(self, ctrl):
        xipos = self._fields["xipos"]
        height = xipos[:, self._torso, 2] - xipos[:, self._foot, 2]
        stand = tolerance(height, bounds=(_STAND_HEIGHT, 2))
        hop = tolerance(self._fields["sensordata"][:, 0], bounds=(_HOP_SPEED, float("inf")), margin=_HOP_SPEED / 2,
                        value_at_margin=0.5, sigmoid="linear")
        return np.stack([hop, stand, small_control(ctrl)], axis=1), stand * hop
