"""SAC, the single-objective baseline trained on the domain's original scalar reward (SPEC §4).

Source: ``hyperparameters.toml`` ``[sac.<domain>]`` (SACContinuous on MuJoCo, SACDiscrete on
LunarLander, LavaGrid and Mario); ``morl-trl config sac ENV --compare-authors`` lists each setting.
The authors' temperature is tuned from 1.0 (their scripts' alpha 0.2 is ignored, ``autotune``).

Example:
    >>> SACConfig().init_random_frames, DEFAULTS[LUNAR_LANDER]["update_frequency"]
    (1000, 4)
"""

from __future__ import annotations

from morl_trl.recipes.config.domains import LAVA_GRID, LUNAR_LANDER, MARIO, domain_table, frozen
from morl_trl.recipes.config.families import ACTOR_CRITIC, algorithm_config, pick

__all__ = ["SACConfig", "SHARED_DEFAULTS", "DEFAULTS", "QUICK"]


SACConfig = algorithm_config(
    "SACConfig", "SAC's keys (MuJoCo's values: ``[sac.hopper]``, SACContinuous).",
    # optim: actor 3e-4, critics and temperature 1e-3; Polyak 0.005 every update;
    # temperature tuned from 1.0 (target entropy -|A|; discrete: target_entropy_scale * ln|A|);
    # the authors' actor: log_std = -5 + 3.5 (tanh(x) + 1); 2 actor (+ temperature) steps after every
    # 2nd critic step (sac_continuous.py:134,435-456)
    pick(ACTOR_CRITIC, [k for k in ACTOR_CRITIC if k != "per_importance_weights"], q_lr=1e-3, alpha_lr=1e-3,
         alpha=1.0),
    dict(preference_distribution="dirichlet", preference_resample="episode"),
)


SHARED_DEFAULTS = frozen({"eval_exploration": "random"})
# SACDiscrete: one update every 4 frames after 20k random frames, hard target copies every
# target_net_freq FRAMES (= target_net_freq / 4 updates), Adam eps 1e-4, one lr 3e-4
_DISCRETE = dict(init_random_frames=20_000, batch_size=128, tau=None, q_lr=3e-4, alpha_lr=3e-4, adam_eps=1e-4,
                 update_frequency=4, policy_freq=1)  # SACDiscrete steps its actor at every update
DEFAULTS = domain_table({
    LUNAR_LANDER: dict(_DISCRETE, target_update_period=2000 // 4, target_entropy_scale=0.3),
    LAVA_GRID: dict(_DISCRETE, target_update_period=200 // 4, target_entropy_scale=0.89),
    MARIO: dict(_DISCRETE, batch_size=64, buffer_size=100_000, target_update_period=1000 // 4,
                target_entropy_scale=0.5, hidden=(512,)),  # net_arch [512, 512]: the CNN's 512, then 512
})
QUICK = frozen({})
