"""MO-SuperMarioBros (SPEC §1.4): 32 stages as contexts, pixel observations, 3 objectives.

Importing this package loads no emulator (and never the old ``gym``); nes-py's core library
is loaded when the first stage starts. ``MOSuperMarioBrosEnv`` needs the ``mario`` extra
(``pip install 'morl-trl[mario]'``); without it, importing it raises ``ModuleNotFoundError``
while the stage space and the registry keep working.

Example:
    >>> from morl_trl.envs import make_env
    >>> env = make_env("MOSuperMarioBrosZeroShot-v2", num_envs=2, seed=0)   # doctest: +SKIP
    >>> td = env.reset()                                                     # doctest: +SKIP
    >>> td["context"].shape, td["observation"].shape, td["observation"].dtype   # doctest: +SKIP
    (torch.Size([2, 2]), torch.Size([2, 4, 84, 84]), torch.uint8)
"""

from morl_trl.envs.mario.game import SIMPLE_MOVEMENT, SIMPLE_MOVEMENT_BUTTONS, MarioStage
from morl_trl.envs.mario.stages import (
    EVAL_STAGES,
    HELD_OUT_STAGES,
    MARIO_STAGE_SPACE,
    STAGES,
    TRAIN_STAGES,
    MarioStageSpace,
    parse_stage,
    stage_name,
)

__all__ = [
    "MOSuperMarioBrosEnv",
    "MarioStage",
    "MarioStageSpace",
    "MARIO_STAGE_SPACE",
    "StagePool",
    "SIMPLE_MOVEMENT",
    "SIMPLE_MOVEMENT_BUTTONS",
    "STAGES",
    "TRAIN_STAGES",
    "HELD_OUT_STAGES",
    "EVAL_STAGES",
    "parse_stage",
    "stage_name",
]


def __getattr__(name: str):
    # the env module checks that the emulator is installed: import it on first use only
    if name in ("MOSuperMarioBrosEnv", "StagePool"):
        from morl_trl.envs.mario import env

        return getattr(env, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
