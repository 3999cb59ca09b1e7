"""Training recipes: each algorithm's loop and update, written once; ``morl-trl train`` runs them.

:func:`~morl_trl.recipes.off_policy.run_training` opens the run and hands it to the algorithm's
loop, found in the one registry (:data:`~morl_trl.algorithms.registry.REGISTRY`). Each recipe module
holds its algorithm's builder, its ``update`` (one gradient update; ``compile`` / CUDA graphs wrap the
same function), its ``on_batch`` (what the loop does with one collected batch) and its ``train_*``
loop, read top to bottom inside :meth:`Run.session <morl_trl.runs.Run.session>` (run directory,
resume, evaluations, checkpoints, logs, report, Ctrl-C, clean stops):

* ``envelope``: :mod:`morl_trl.algorithms.envelope.recipe`
* ``capql``, ``mosac``, ``mosac_discrete``, ``sac``: :mod:`morl_trl.algorithms.actor_critic.recipe` (SAC's modules on
  the scalar reward: :func:`~morl_trl.algorithms.actor_critic.sac.make_sac_agent`)
* ``morld``, ``morld_psa`` (MORL/D SB, SB+PSA): :mod:`morl_trl.algorithms.morld.recipe` (a batched population, shared
  buffer, exchanges)
* ``pcn``: :mod:`morl_trl.algorithms.pcn.recipe` (the episode replay, the command, the rounds)
* ``pgmorl``: :mod:`morl_trl.algorithms.pgmorl.recipe` (population PPO, evolution)
* ``gpi_ls``, ``gpi_pd``: :mod:`morl_trl.algorithms.gpi.recipe` (the weight-support iterations, + Dyna for GPI-PD)

The configuration (:class:`~morl_trl.recipes.config.TrainConfig`) starts from the paper's
settings for the algorithm and domain; ``examples/`` holds ready config files.

Example:
    >>> from morl_trl.recipes import resolve_config, train
    >>> cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, frames=2_000)  # doctest: +SKIP
    >>> summary = train(cfg)                                                            # doctest: +SKIP
"""

from __future__ import annotations

# The names below are imported at first use (PEP 562): ``import morl_trl.recipes.config`` (what
# ``morl-trl train --help`` and its argument checks read) stays free of torch and torchrl.
from morl_trl._lazy import lazy_attributes as _lazy_attributes  # noqa: E402

_LAZY = {
    "Agent": "morl_trl.training.agent",
    "AGENT_BUILDERS": "morl_trl.algorithms.registry",
    "REGISTRY": "morl_trl.algorithms.registry",
    "TRAINING_ENV_BUILDERS": "morl_trl.algorithms.registry",
    "build_agent": "morl_trl.algorithms.registry",
    "build_training_env": "morl_trl.algorithms.registry",
    "ALGORITHMS": "morl_trl.recipes.config",
    "TrainConfig": "morl_trl.recipes.config",
    "resolve_config": "morl_trl.recipes.config",
    "evaluate_run": "morl_trl.recipes.off_policy",
    "run_training": "morl_trl.recipes.off_policy",
    "open_run": "morl_trl.recipes.off_policy",
    "train": "morl_trl.recipes.off_policy",
    "NonFiniteLossError": "morl_trl.training.optim",
    "make_training_env": "morl_trl.training.parts",
    "TrainedPolicy": "morl_trl.recipes.policy",
    "TrainResult": "morl_trl.recipes.policy",
    "load_policy": "morl_trl.recipes.policy",
    "train_policy": "morl_trl.recipes.policy",
}

__all__ = [
    "AGENT_BUILDERS",
    "ALGORITHMS",
    "Agent",
    "NonFiniteLossError",
    "REGISTRY",
    "TrainConfig",
    "TrainResult",
    "TrainedPolicy",
    "TRAINING_ENV_BUILDERS",
    "build_agent",
    "build_training_env",
    "evaluate_run",
    "load_policy",
    "resolve_config",
    "run_training",
    "open_run",
    "train",
    "train_policy",
]


__getattr__, __dir__ = _lazy_attributes(globals(), _LAZY)
