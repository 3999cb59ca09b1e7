"""MO-SuperMarioBros (SPEC §1.4): 32 stage ids, the zero-shot training id, 8 evaluation stages.

Data only: imports no emulator (nes-py / gym) and not the registry, which reads :data:`SPECS`.
"""

from morl_trl.envs.mario.stages import EVAL_STAGES, MARIO_STAGE_SPACE, STAGES
from morl_trl.envs.spec import DomainSpec


def _stage_id(world: int, level: int) -> str:
    return f"MOSuperMarioBros-{world}-{level}-v2"


SPECS = (
    DomainSpec(
        name="MO-SuperMarioBros",
        train_id="MOSuperMarioBrosZeroShot-v2",  # every stage but 3-3, uniformly per episode
        env_class="morl_trl.envs.mario.env:MOSuperMarioBrosEnv",
        context_space=MARIO_STAGE_SPACE,
        contexts={_stage_id(w, l): {"world": float(w), "level": float(l)} for w, l in STAGES},
        evaluation_ids=tuple(_stage_id(w, l) for w, l in EVAL_STAGES),
        objective_names=("x_pos", "coin", "enemy"),
        gamma=0.99,
        hv_ref_point=(-100.0, -100.0, -100.0),
        max_episode_steps=500,
        history_len=0,
        train_frames=3_000_000,
        eval_interval=100_000,
        eval_weights=32,
    ),
)
