"""CAPQL (Lu et al. 2023): its keys, and the authors' values per domain.

Source: ``hyperparameters.toml`` ``[capql.<domain>]``; ``morl-trl config capql ENV --compare-authors``.

Example:
    >>> CAPQLConfig().alpha, DEFAULTS[HUMANOID]["init_random_frames"]
    (0.2, 25000)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.recipes.config.domains import HUMANOID, domain_table, frozen

__all__ = ["CAPQLConfig", "SHARED_DEFAULTS", "DEFAULTS", "QUICK"]


@dataclass
class CAPQLConfig:
    """CAPQL's keys (Hopper's values: ``[capql.hopper]``)."""

    frames_per_batch: int = 64
    init_random_frames: int = 1_000  # learning_starts
    buffer_size: int = 1_000_000
    batch_size: int = 256
    prioritized: bool = False
    per_alpha: float = 0.6
    per_beta: float = 0.4
    per_importance_weights: bool = True
    # optim: one Adam (lr 3e-4) per network, one critic and one actor step per frame, Polyak 0.005
    lr: float = 3e-4
    updates_per_batch: int = 0
    tau: float | None = 0.005
    target_update_period: int = 1000
    max_grad_norm: float | None = None
    hidden: tuple[int, ...] = (256, 256, 256, 256)
    # temperature fixed at 0.2; log-std clamped to [-20, 2]
    alpha: float = 0.2
    learn_alpha: bool = False
    actor_scale: str = "clamped_log_std"
    # a new weight every step from the 22.5-degree cone, stored with the transition and reused by the loss
    preference_distribution: str = "cone"
    preference_resample: str = "step"
    loss_fresh_preferences: bool = False
    # after learning_starts the authors collect with the deterministic tanh(mean)
    capql_deterministic_collection: bool = True


SHARED_DEFAULTS = frozen({})
DEFAULTS = domain_table({HUMANOID: dict(init_random_frames=25_000)})
QUICK = frozen({})
