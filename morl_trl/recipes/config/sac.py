"""SAC, the single-objective baseline trained on the domain's original scalar reward (SPEC §4).

Source: ``hyperparameters.toml`` ``[sac.<domain>]`` (SACContinuous on MuJoCo, SACDiscrete on
LunarLander, LavaGrid and Mario); ``morl-trl config sac ENV --compare-authors`` lists each setting.
The authors' temperature is tuned from 1.0 (their scripts' alpha 0.2 is ignored, ``autotune``).

Example:
    >>> SACConfig().init_random_frames, DEFAULTS[LUNAR_LANDER]["update_frequency"]
    (1000, 4)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.recipes.config.domains import LAVA_GRID, LUNAR_LANDER, MARIO, domain_table, frozen

__all__ = ["SACConfig", "SHARED_DEFAULTS", "DEFAULTS", "QUICK"]


@dataclass
class SACConfig:
    """SAC's keys (MuJoCo's values: ``[sac.hopper]``, SACContinuous)."""

    frames_per_batch: int = 64
    init_random_frames: int = 1_000  # learning_starts
    buffer_size: int = 1_000_000
    batch_size: int = 256
    prioritized: bool = False
    per_alpha: float = 0.6
    per_beta: float = 0.4
    # optim: actor 3e-4, critics and temperature 1e-3; Polyak 0.005 every update
    lr: float = 3e-4
    q_lr: float | None = 1e-3
    alpha_lr: float | None = 1e-3
    adam_eps: float | None = None
    updates_per_batch: int = 0
    update_frequency: int = 1
    tau: float | None = 0.005
    target_update_period: int = 1000
    max_grad_norm: float | None = None
    hidden: tuple[int, ...] = (256, 256, 256, 256)
    # temperature tuned from 1.0 (target entropy -|A|; discrete: target_entropy_scale * ln|A|)
    alpha: float = 1.0
    learn_alpha: bool = True
    target_entropy_scale: float = 0.3
    # the authors' actor: log_std = -5 + 3.5 (tanh(x) + 1); 2 actor (+ temperature) steps after every
    # 2nd critic step (sac_continuous.py:134,435-456)
    actor_scale: str = "tanh_log_std"
    policy_freq: int = 2
    preference_distribution: str = "dirichlet"
    preference_resample: str = "episode"


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
