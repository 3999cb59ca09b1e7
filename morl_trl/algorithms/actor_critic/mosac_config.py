"""MOSAC (continuous) and discrete MOSAC as standalone learners: their keys and values.

The authors ran MOSAC only inside MORL/D (:mod:`morl_trl.algorithms.morld.config`); these standalone
learners have no row in ``hyperparameters.toml`` and keep MORL-Baselines' class defaults.

Example:
    >>> MOSACDiscreteConfig().target_update_period, DEFAULTS_DISCRETE[LAVA_GRID]["target_update_period"]
    (2000, 200)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.algorithms.domains import HOPPER, HUMANOID, LAVA_GRID, domain_table, frozen

__all__ = ["MOSACConfig", "MOSACDiscreteConfig", "SHARED_DEFAULTS", "DEFAULTS", "DEFAULTS_DISCRETE"]


@dataclass
class MOSACConfig:
    """Continuous MOSAC's keys; what each means: ``KEYS``.

    Source of each default: "MB" (MORL-Baselines 1.3.0's ``MOSAC.__init__``,
    mosac_continuous_action.py:95-103,141,460-482; no record row) or "ours".
    """

    # collector and replay
    frames_per_batch: int = 64  # ours
    init_random_frames: int = 10_000  # MB learning_starts
    buffer_size: int = 1_000_000  # MB
    batch_size: int = 256  # MB
    prioritized: bool = False  # MB (no PER)
    per_alpha: float = 0.6  # ours (used only with prioritized)
    per_beta: float = 0.4  # ours (used only with prioritized)
    per_importance_weights: bool = True  # ours (used only with prioritized)
    # optim
    lr: float = 3e-4  # MB policy_lr
    q_lr: float | None = None  # ours (null: lr)
    alpha_lr: float | None = None  # ours (null: lr)
    updates_per_batch: int = 0  # MB: one update per frame
    tau: float | None = 0.005  # MB
    target_update_period: int = 1000  # ours (used only when tau is null)
    max_grad_norm: float | None = None  # MB (no clipping)
    # networks and temperature
    hidden: tuple[int, ...] = (256, 256, 256, 256)  # MB net_arch
    alpha: float = 0.2  # MB
    learn_alpha: bool = True  # MB autotune
    actor_scale: str = "tanh_log_std"  # MB: log_std = -5 + 3.5 (tanh(x) + 1)
    policy_freq: int = 2  # MB: 2 actor steps after every 2nd critic step
    alpha_loss_form: str = "log_alpha"  # MB 1.3.0 mosac_continuous_action.py:470
    joint_update: bool = False  # ours (false: MB's order, each loss computed alone)
    # preferences
    loss_fresh_preferences: bool = False  # ours (the stored weight)
    preference_distribution: str = "dirichlet"  # ours
    preference_resample: str = "episode"  # ours


@dataclass
class MOSACDiscreteConfig(MOSACConfig):
    """Discrete MOSAC's keys: continuous MOSAC's, with MB 1.3.0's ``MOSACDiscrete.__init__`` defaults
    (mosac_discrete_action.py): hard target copies, a target entropy scale."""

    init_random_frames: int = 1_000  # MB learning_starts
    batch_size: int = 128  # MB
    tau: float | None = None  # MB: hard copies
    target_update_period: int = 2000  # MB target_net_freq
    target_entropy_scale: float = 0.3  # MB
    policy_freq: int = 1  # MB: MOSACDiscrete steps its actor at every update
    alpha_loss_form: str = "alpha"  # MB: -alpha (...) (mosac_discrete_action.py:492)


SHARED_DEFAULTS = frozen({"eval_exploration": "random"})
DEFAULTS = domain_table({HOPPER: dict(init_random_frames=10_000), HUMANOID: dict(init_random_frames=5_000)})
DEFAULTS_DISCRETE = domain_table({LAVA_GRID: dict(target_update_period=200)})
