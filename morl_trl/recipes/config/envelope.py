"""Envelope Q-learning (Yang et al. 2019): its keys, and the authors' values per domain.

Source of every value: ``hyperparameters.toml`` ``[envelope.<domain>]`` (the authors' scripts and
their Envelope defaults); ``morl-trl config envelope ENV --compare-authors`` lists each setting.

Example:
    >>> EnvelopeConfig().num_sampled_prefs, DEFAULTS[LAVA_GRID]["num_sampled_prefs"]
    (8, 4)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.recipes.config.domains import LAVA_GRID, MARIO, domain_table, frozen

__all__ = ["EnvelopeConfig", "SHARED_DEFAULTS", "DEFAULTS", "QUICK"]


@dataclass
class EnvelopeConfig:
    """Envelope's keys (LunarLander's values: ``[envelope.lunarlander]``)."""

    # collector and replay (PER without importance weights, priority from the first sampled weight)
    frames_per_batch: int = 64
    init_random_frames: int = 100  # learning_starts
    buffer_size: int = 1_000_000
    batch_size: int = 128
    prioritized: bool = True
    per_alpha: float = 0.6
    per_beta: float = 0.4
    per_importance_weights: bool = False
    envelope_priority: str = "first"
    per_running_max: bool = True  # MORL-Baselines' buffer: (p + running max)^alpha, new items at the max
    # optim: one update per frame, hard target copy every 1000 updates, gradient norm 1
    lr: float = 3e-4
    updates_per_batch: int = 0
    target_update_period: int = 1000
    tau: float | None = None
    max_grad_norm: float | None = 1.0
    # network: w concatenated after the first hidden layer, orthogonal init
    hidden: tuple[int, ...] = (256, 256, 256, 256)
    envelope_network: str = "authors"
    # exploration: epsilon 1 -> 0.05 over 1M frames after learning_starts
    eps_start: float = 1.0
    eps_end: float = 0.05
    eps_frames: int = 1_000_000
    # preferences: |N(0, I)| normalised, one per episode; 8 sampled per update; lambda fixed at 0.95
    preference_distribution: str = "gaussian"
    preference_resample: str = "episode"
    num_sampled_prefs: int = 8
    homotopy_lambda0: float = 0.95
    homotopy_final: float | None = None
    homotopy_frames: int | None = None


SHARED_DEFAULTS = frozen({})
DEFAULTS = domain_table({
    LAVA_GRID: dict(eps_frames=5_000_000, target_update_period=200, num_sampled_prefs=4),
    MARIO: dict(batch_size=64, init_random_frames=25_000, buffer_size=100_000, eps_start=0.2, eps_end=0.01,
                hidden=(512,)),  # net_arch [512, 512]: the CNN's 512 features, then one 512 layer
})
QUICK = frozen({})
