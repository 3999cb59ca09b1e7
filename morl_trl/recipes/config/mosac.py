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
from morl_trl.recipes.config.families import ACTOR_CRITIC, algorithm_config, pick

__all__ = ["MOSACConfig", "MOSACDiscreteConfig", "SHARED_DEFAULTS", "DEFAULTS", "DEFAULTS_DISCRETE", "QUICK"]


MOSACConfig = algorithm_config(
    "MOSACConfig", "Continuous MOSAC's keys.",
    # the class defaults of the authors' MOSAC (mosac_continuous_action.py:95-103,141,460-482)
    pick(ACTOR_CRITIC, ("frames_per_batch", "init_random_frames", "buffer_size", "batch_size", "prioritized",
                        "per_alpha", "per_beta", "per_importance_weights", "lr", "q_lr", "alpha_lr", "updates_per_batch",
                        "tau", "target_update_period", "max_grad_norm", "hidden", "alpha", "learn_alpha",
                        "actor_scale", "policy_freq", "alpha_loss_form", "joint_update"),
         init_random_frames=10_000, alpha_loss_form="log_alpha"),  # MB 1.3.0 mosac_continuous_action.py:470
    dict(loss_fresh_preferences=False, preference_distribution="dirichlet", preference_resample="episode"),
)


@dataclass
class MOSACDiscreteConfig(MOSACConfig):
    """Discrete MOSAC's keys: hard target copies, a target entropy scale."""

    init_random_frames: int = 1_000
    batch_size: int = 128
    tau: float | None = None
    target_update_period: int = 2000
    target_entropy_scale: float = 0.3
    policy_freq: int = 1  # MOSACDiscrete steps its actor at every update
    alpha_loss_form: str = "alpha"  # -alpha (...) (MB 1.3.0 mosac_discrete_action.py:492)


SHARED_DEFAULTS = frozen({"eval_exploration": "random"})
DEFAULTS = domain_table({HOPPER: dict(init_random_frames=10_000), HUMANOID: dict(init_random_frames=5_000)})
DEFAULTS_DISCRETE = domain_table({LAVA_GRID: dict(target_update_period=200)})
QUICK = frozen({})
