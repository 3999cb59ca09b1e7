"""CAPQL (Lu et al. 2023): its keys, and the authors' values per domain.

Source: ``hyperparameters.toml`` ``[capql.<domain>]``; ``morl-trl config capql ENV --compare-authors``.

Example:
    >>> CAPQLConfig().alpha, DEFAULTS[HUMANOID]["init_random_frames"]
    (0.2, 25000)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.algorithms.domains import HUMANOID, domain_table, frozen

__all__ = ["CAPQLConfig", "SHARED_DEFAULTS", "DEFAULTS"]


@dataclass
class CAPQLConfig:
    """CAPQL's keys (Hopper's values: ``[capql.hopper]``); what each means: ``KEYS``.

    Source of each default: ``[capql.hopper.<table>] <setting>`` of ``hyperparameters.toml``, or
    "ours" (no counterpart: the authors' mechanism is fixed in their code).
    """

    # collector and replay (the authors' uniform ReplayMemory)
    frames_per_batch: int = 64  # ours (the authors step one env between updates)
    init_random_frames: int = 1000  # init.learning_starts
    buffer_size: int = 1_000_000  # init.buffer_size
    batch_size: int = 256  # init.batch_size
    prioritized: bool = False  # ours (no PER in CAPQL)
    per_alpha: float = 0.6  # ours (used only with prioritized)
    per_beta: float = 0.4  # ours (used only with prioritized)
    per_importance_weights: bool = True  # ours (used only with prioritized)
    # optim: one Adam per network, one critic and one actor step per frame, Polyak on the critics
    lr: float = 3e-4  # init.learning_rate (network.optimizers)
    updates_per_batch: int = 0  # init.gradient_updates 1: one update per frame
    tau: float | None = 0.005  # init.tau
    target_update_period: int = 1000  # ours (used only when tau is null)
    max_grad_norm: float | None = None  # ours (the authors do not clip)
    # networks: temperature fixed at 0.2; log-std clamped to [-20, 2]
    hidden: tuple[int, ...] = (256, 256, 256, 256)  # init.net_arch
    alpha: float = 0.2  # init.alpha
    learn_alpha: bool = False  # init.alpha's note: fixed, no autotuning
    actor_scale: str = "clamped_log_std"  # network.policy
    capql_log_prob: str = "clamped"  # network.log_prob (1e-6 in the Jacobian's log, clamped to [-1000, 1000])
    joint_update: bool = False  # ours (false: the authors' order, each loss computed alone)
    # preferences: a new weight every step from the 22.5-degree cone, stored with the transition and
    # reused by the loss
    preference_distribution: str = "cone"  # derived.weight_sampling
    preference_resample: str = "step"  # derived.weight_sampling
    loss_fresh_preferences: bool = False  # derived.weight_sampling (the stored weight)
    # after learning_starts the authors collect with the deterministic tanh(mean)
    capql_deterministic_collection: bool = True  # derived.behaviour_action


SHARED_DEFAULTS = frozen({})
DEFAULTS = domain_table({HUMANOID: dict(init_random_frames=25_000)})
