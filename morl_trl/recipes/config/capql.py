"""CAPQL (Lu et al. 2023): its keys, and the authors' values per domain.

Source: ``hyperparameters.toml`` ``[capql.<domain>]``; ``morl-trl config capql ENV --compare-authors``.

Example:
    >>> CAPQLConfig().alpha, DEFAULTS[HUMANOID]["init_random_frames"]
    (0.2, 25000)
"""

from __future__ import annotations

from morl_trl.recipes.config.domains import HUMANOID, domain_table, frozen
from morl_trl.recipes.config.families import ACTOR_CRITIC, algorithm_config, pick

__all__ = ["CAPQLConfig", "SHARED_DEFAULTS", "DEFAULTS", "QUICK"]


CAPQLConfig = algorithm_config(
    "CAPQLConfig", "CAPQL's keys (Hopper's values: ``[capql.hopper]``).",
    # optim: one Adam (lr 3e-4) per network, one critic and one actor step per frame, Polyak 0.005;
    # temperature fixed at 0.2; log-std clamped to [-20, 2]
    pick(ACTOR_CRITIC, ("frames_per_batch", "init_random_frames", "buffer_size", "batch_size", "prioritized",
                        "per_alpha", "per_beta", "per_importance_weights", "lr", "updates_per_batch", "tau",
                        "target_update_period", "max_grad_norm", "hidden", "alpha", "learn_alpha", "actor_scale",
                        "joint_update"),
         learn_alpha=False, actor_scale="clamped_log_std"),
    # a new weight every step from the 22.5-degree cone, stored with the transition and reused by the loss
    dict(preference_distribution="cone", preference_resample="step", loss_fresh_preferences=False),
    # after learning_starts the authors collect with the deterministic tanh(mean)
    dict(capql_deterministic_collection=True),
)


SHARED_DEFAULTS = frozen({})
DEFAULTS = domain_table({HUMANOID: dict(init_random_frames=25_000)})
QUICK = frozen({})
