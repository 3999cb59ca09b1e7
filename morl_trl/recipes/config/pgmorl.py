"""PGMORL (Xu et al. 2020): its keys, and the authors' values per domain.

Source: ``hyperparameters.toml`` ``[pgmorl.<domain>]`` (``.init`` and the members' ``.moppo``);
``morl-trl config pgmorl ENV --compare-authors`` lists each setting.

Example:
    >>> PGMORLConfig().pgmorl_warmup, DEFAULTS[HOPPER]["pgmorl_warmup"]
    (80, 200)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.recipes.config.domains import HALF_CHEETAH, HOPPER, HUMANOID, domain_table, frozen

__all__ = ["PGMORLConfig", "SHARED_DEFAULTS", "DEFAULTS", "QUICK"]


@dataclass
class PGMORLConfig:
    """PGMORL's keys (Half-Cheetah's values: ``[pgmorl.cheetah]``)."""

    # P members x 4 envs x 2048 steps per iteration
    frames_per_batch: int = 24 * 2048
    lr: float = 3e-4
    max_grad_norm: float | None = 0.5
    hidden: tuple[int, ...] = (256, 256, 256, 256)
    pgmorl_pop: int = 6
    pgmorl_envs_per_member: int = 4
    pgmorl_warmup: int = 80
    pgmorl_evo_iterations: int = 20
    pgmorl_num_buffers: int = 100
    pgmorl_buffer_size: int = 2
    pgmorl_delta_weight: float = 0.2
    pgmorl_sparsity: float = -1.0
    pgmorl_epochs: int = 10
    pgmorl_minibatches: int = 32
    pgmorl_clip: float = 0.2
    pgmorl_gae_lambda: float = 0.95
    pgmorl_eval_obs: str = "raw"
    pgmorl_reset_each_iteration: bool = True  # envs.reset at each member's train() (mo_ppo.py:628)
    # ... with reset(seed=member.seed): the run's seed, 42 for a copied member (mo_ppo.py:355-377,628)
    pgmorl_reseed_each_iteration: bool = True


# MOPPO.eval samples its actions
SHARED_DEFAULTS = frozen({"num_envs": 24, "eval_exploration": "random"})
DEFAULTS = domain_table({
    HOPPER: dict(pgmorl_warmup=200, pgmorl_evo_iterations=40, pgmorl_num_buffers=210, pgmorl_sparsity=-1e6,
                 pgmorl_delta_weight=0.25),
    HALF_CHEETAH: dict(),
    HUMANOID: dict(pgmorl_warmup=200, pgmorl_evo_iterations=40),
})
# --quick: shorter iterations; an iteration counts one member's 4 x 256 frames (the authors' count): 10 iterations
QUICK = frozen(dict(num_envs=24, frames_per_batch=24 * 256, pgmorl_warmup=4, pgmorl_evo_iterations=2,
                    pgmorl_minibatches=8, frames=10_240, eval_interval=5_120, checkpoint_interval=3_072))
