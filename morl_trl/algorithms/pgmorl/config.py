"""PGMORL (Xu et al. 2020): its keys, and the authors' values per domain.

Source: ``hyperparameters.toml`` ``[pgmorl.<domain>]`` (``.init`` and the members' ``.moppo``);
``morl-trl config pgmorl ENV --compare-authors`` lists each setting.

Example:
    >>> PGMORLConfig().pgmorl_warmup, DEFAULTS[HOPPER]["pgmorl_warmup"]
    (80, 200)
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.algorithms.domains import HALF_CHEETAH, HOPPER, HUMANOID, domain_table, frozen

__all__ = ["PGMORLConfig", "SHARED_DEFAULTS", "DEFAULTS"]


@dataclass
class PGMORLConfig:
    """PGMORL's keys (Half-Cheetah's values: ``[pgmorl.cheetah]``); what each means: ``KEYS``.

    Source of each default: ``[pgmorl.cheetah.<table>] <setting>`` of ``hyperparameters.toml``, or "ours".
    """

    frames_per_batch: int = 24 * 2048  # init.steps_per_iteration: P members x 4 envs x 2048 steps per iteration
    lr: float = 3e-4  # init.learning_rate
    max_grad_norm: float | None = 0.5  # init.max_grad_norm
    hidden: tuple[int, ...] = (256, 256, 256, 256)  # init.net_arch
    pgmorl_pop: int = 6  # init.pop_size
    pgmorl_envs_per_member: int = 4  # init.num_envs
    pgmorl_warmup: int = 80  # init.warmup_iterations
    pgmorl_evo_iterations: int = 20  # init.evolutionary_iterations
    pgmorl_num_buffers: int = 100  # init.num_performance_buffer
    pgmorl_buffer_size: int = 2  # init.performance_buffer_size
    pgmorl_delta_weight: float = 0.2  # init.delta_weight
    pgmorl_sparsity: float = -1.0  # init.sparsity_coef
    pgmorl_epochs: int = 10  # init.update_epochs
    pgmorl_minibatches: int = 32  # init.num_minibatches
    pgmorl_clip: float = 0.2  # init.clip_coef
    pgmorl_gae_lambda: float = 0.95  # init.gae_lambda
    pgmorl_eval_obs: str = "raw"  # the authors' evaluation: normalised policies fed raw observations (mo_ppo.py:719-768)
    # envs.reset at each member's train() (mo_ppo.py:628) ...
    pgmorl_reset_each_iteration: bool = True  # derived.vector_env_reset_each_iteration
    # ... with reset(seed=member.seed): the run's seed, 42 for a copied member (mo_ppo.py:355-377,628)
    pgmorl_reseed_each_iteration: bool = True  # derived.vector_env_reset_each_iteration


# MOPPO.eval samples its actions
SHARED_DEFAULTS = frozen({"num_envs": 24, "eval_exploration": "random"})
DEFAULTS = domain_table({
    HOPPER: dict(pgmorl_warmup=200, pgmorl_evo_iterations=40, pgmorl_num_buffers=210, pgmorl_sparsity=-1e6,
                 pgmorl_delta_weight=0.25),
    HALF_CHEETAH: dict(),
    HUMANOID: dict(pgmorl_warmup=200, pgmorl_evo_iterations=40),
})
