"""MO-LavaGrid (SPEC section 1.3) as a batched pure-tensor environment on any device.

Example:
    >>> from morl_trl.envs import make_env
    >>> env = make_env("MOLavaGridDR-v0", num_envs=1024, seed=0)  # domain randomization per sub-env
    >>> env.rollout(4)["next", "reward"].shape
    torch.Size([1024, 4, 2])
"""

from morl_trl.envs.lava_grid.context import (
    CONTEXT_NAMES,
    LAVA_GRID_CONTEXT,
    LavaGridContextSpace,
    evaluation_maps,
    format_lava_map,
    lava_grid_context,
    parse_lava_map,
)
from morl_trl.envs.lava_grid.env import MOLavaGridEnv

__all__ = [
    "CONTEXT_NAMES",
    "LAVA_GRID_CONTEXT",
    "LavaGridContextSpace",
    "MOLavaGridEnv",
    "evaluation_maps",
    "format_lava_map",
    "lava_grid_context",
    "parse_lava_map",
]
