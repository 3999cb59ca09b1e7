"""MO-SuperMarioBros (SPEC §1.4): 32 stage ids, the zero-shot training id, 8 evaluation stages.

Data only: imports no emulator (nes-py / gym) and not the registry, which reads :data:`SPECS`.
"""

from morl_trl.envs.mario.stages import EVAL_STAGES, MARIO_STAGE_SPACE, STAGES
from morl_trl.envs.spec import DomainSpec, SORLReward


def _stage_id(world: int, level: int) -> str:
    return f"MOSuperMarioBros-{world}-{level}-v2"


# f_SORL (the paper's appendix): f forward (dx), t time penalty, d death penalty: the
# gym-super-mario-bros scalar. The vector objectives are 0.03 * (x + t), 0.03 * (coin + t),
# 0.03 * (enemy + t) (SPEC §1.4), so f = r0 / 0.03 + d.
SORL = SORLReward(
    paper="f + t + d",
    weights=(100.0 / 3.0, 0.0, 0.0),
    exact=False,
    note="d, the -25 of the frame Mario starts dying, is in original_reward but not in the default vector reward "
         "(the authors' episode ends before their MO death penalty fires, SPEC §1.4); with the env's "
         "death_penalty_on_dying=True the vector carries it and f = r0 / 0.03 exactly. original_reward is summed "
         "over the raw frames of a step, unclipped (gym-super-mario-bros clips each raw frame's reward to "
         "[-15, 15]; SPEC does not say which the authors' SAC saw).",
)

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
        sorl=SORL,
    ),
)
