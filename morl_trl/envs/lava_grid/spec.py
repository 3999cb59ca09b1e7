"""MO-LavaGrid (SPEC section 1.3): procedural maps for training, eight hand-drawn maps for evaluation.

Data only: imports not the registry, which reads :data:`SPECS`.
"""

from morl_trl.envs.lava_grid.context import LAVA_GRID_CONTEXT, evaluation_maps
from morl_trl.envs.spec import DomainSpec, SORLReward

# the order of SPEC's id list
_SUITE = ("CheckerBoard", "Smiley", "Snake", "Islands", "Labyrinth", "Maze", "Corridor", "Room")
_MAPS = evaluation_maps()

# f_SORL = 0.9 lava + 0.1 time: the authors' env's info["original_scalar_reward"] (the reward of
# their SAC baseline); the env's "original_reward" reads these weights
SORL = SORLReward(
    paper="",
    weights=(0.9, 0.1),
    note="not in the paper (its appendix gives no MO-LavaGrid f_SORL and SPEC §3 has no single-objective data "
         "for it): the authors' env's info['original_scalar_reward'], the reward their SAC baseline trained on",
)

SPECS = (
    DomainSpec(
        name="MO-LavaGrid",
        train_id="MOLavaGridDR-v0",
        env_class="morl_trl.envs.lava_grid:MOLavaGridEnv",
        context_space=LAVA_GRID_CONTEXT,
        contexts={
            f"MOLavaGrid{name}-v0": LAVA_GRID_CONTEXT.as_dict(_MAPS[name]) for name in _SUITE
        },
        evaluation_ids=tuple(f"MOLavaGrid{name}-v0" for name in _SUITE),
        objective_names=("lava", "time"),
        gamma=0.995,
        hv_ref_point=(-1000.0, -500.0),
        max_episode_steps=256,
        history_len=0,
        train_frames=5_000_000,
        eval_interval=50_000,
        sorl=SORL,
    ),
)
