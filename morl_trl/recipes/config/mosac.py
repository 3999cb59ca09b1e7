"""MOSAC (continuous) and discrete MOSAC as standalone learners: their keys and values.

The authors ran MOSAC only inside MORL/D (:mod:`morl_trl.recipes.config.morld`); these standalone
learners have no row in ``hyperparameters.toml`` and keep MORL-Baselines' class defaults.

Example:
    >>> MOSACDiscreteConfig().target_update_period, DEFAULTS_DISCRETE[LAVA_GRID]["target_update_period"]
    (2000, 200)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.recipes.config.domains import HOPPER, HUMANOID, LAVA_GRID, domain_table, frozen

__all__ = ["MOSACConfig", "MOSACDiscreteConfig", "SHARED_DEFAULTS", "DEFAULTS", "DEFAULTS_DISCRETE", "QUICK"]


@dataclass
class MOSACConfig:
    """Continuous MOSAC's keys."""

    frames_per_batch: int = 64
    init_random_frames: int = 10_000
    buffer_size: int = 1_000_000
    batch_size: int = 256
    prioritized: bool = False
    per_alpha: float = 0.6
    per_beta: float = 0.4
    per_importance_weights: bool = True
    lr: float = 3e-4
    q_lr: float | None = None
    alpha_lr: float | None = None
    updates_per_batch: int = 0
    tau: float | None = 0.005
    target_update_period: int = 1000
    max_grad_norm: float | None = None
    hidden: tuple[int, ...] = (256, 256, 256, 256)
    alpha: float = 0.2
    learn_alpha: bool = True
    # the class defaults of the authors' MOSAC (mosac_continuous_action.py:95-103,141,460-482)
    actor_scale: str = "tanh_log_std"
    policy_freq: int = 2
    loss_fresh_preferences: bool = False
    preference_distribution: str = "dirichlet"
    preference_resample: str = "episode"


@dataclass
class MOSACDiscreteConfig(MOSACConfig):
    """Discrete MOSAC's keys: hard target copies, a target entropy scale."""

    init_random_frames: int = 1_000
    batch_size: int = 128
    tau: float | None = None
    target_update_period: int = 2000
    target_entropy_scale: float = 0.3
    policy_freq: int = 1  # MOSACDiscrete steps its actor at every update


SHARED_DEFAULTS = frozen({"eval_exploration": "random"})
DEFAULTS = domain_table({HOPPER: dict(init_random_frames=10_000), HUMANOID: dict(init_random_frames=5_000)})
DEFAULTS_DISCRETE = domain_table({LAVA_GRID: dict(target_update_period=200)})
QUICK = frozen({})
