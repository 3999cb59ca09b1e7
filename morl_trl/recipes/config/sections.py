"""The sections every algorithm shares: run, env, eval, logging, compute.

Their defaults are the same for every algorithm; the domain's protocol (frames, history, evaluation
period and weights: :class:`~morl_trl.envs.DomainSpec`) and an algorithm's table may override them
(e.g. MORL/D evaluates with sampled actions). What each key means: :data:`~morl_trl.recipes.config.keys.KEYS`.

Example:
    >>> RunSection().frames, EvalSection().eval_episodes
    (1000000, 1)
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["RunSection", "EnvSection", "EvalSection", "LoggingSection", "ComputeSection", "SHARED"]


@dataclass
class RunSection:
    """What runs, where, for how long, and how it is checkpointed."""

    algo: str = "envelope"
    env_id: str = "MOLavaGridDR-v0"
    seed: int = 0
    frames: int = 1_000_000
    device: str = "cpu"
    num_threads: int = 1
    run_dir: str | None = None
    checkpoint_interval: int = 50_000
    keep_checkpoints: int = 2


@dataclass
class EnvSection:
    """The batched training env."""

    num_envs: int = 16
    history_len: int = 0
    gamma: float | None = None
    domain_modules: tuple[str, ...] = ()


@dataclass
class EvalSection:
    """The generalization evaluation (SPEC §2: energy weights, one episode per weight and context)."""

    eval_interval: int = 50_000
    eval_weights: int = 100
    eval_episodes: int = 1
    eval_exploration: str = "deterministic"
    eval_contexts: tuple[str, ...] | None = None
    reference_dir: str | None = None
    eval_random_baseline: bool = True
    ref_point: tuple[float, ...] | None = None


@dataclass
class LoggingSection:
    """Where the run's scalars go."""

    logger: str = "csv"
    progress: bool = True


@dataclass
class ComputeSection:
    """How the update is computed (same arithmetic up to float rounding)."""

    fused_optimizer: bool = True
    compile: bool = False
    compile_mode: str | None = None
    cudagraphs: bool = False
    capture_sampling: bool = False
    finite_check_interval: int = 100


#: section name -> its dataclass, in the order a config is printed
SHARED: dict[str, type] = {"run": RunSection, "env": EnvSection, "eval": EvalSection, "logging": LoggingSection,
                           "compute": ComputeSection}
