"""The configuration of a run: shared sections plus one small dataclass per algorithm.

* :mod:`~morl_trl.recipes.config.keys`: every key, defined once (section, meaning, check).
* :mod:`~morl_trl.recipes.config.sections`: the shared sections (run, env, eval, logging, compute).
* each algorithm's own, in its folder (:mod:`morl_trl.algorithms.envelope.config`,
  ``algorithms/actor_critic/{capql,mosac,sac}_config.py``, ``algorithms/{gpi,morld,pcn,pgmorl}/config.py``;
  they import no torch): its dataclass (its keys and defaults) and, next to it, its values per domain (the
  authors' record, ``hyperparameters.toml``), frozen; :mod:`~morl_trl.recipes.config.registry` lists them.
* :mod:`~morl_trl.recipes.config.train_config`: :class:`TrainConfig`, what recipes read (flat keys).
* :mod:`~morl_trl.recipes.config.resolve`: :func:`resolve_config` (where values come from), files, resume.

``morl-trl config ALGO ENV_ID`` prints a resolved config as TOML; ``--compare-authors`` compares it
with the authors' record (:mod:`morl_trl.recipes.fidelity`).

Example:
    >>> cfg = resolve_config("gpi_ls", "MOLunarLanderDR-v0")
    >>> cfg.gpi_gradient_updates, cfg.gpi_front_episodes, sorted(cfg.sections)[:3]
    (1, 3, ['compute', 'env', 'eval'])
"""

from morl_trl.recipes.config.keys import ALGORITHMS, KEYS, SHARED_SECTIONS
from morl_trl.recipes.config.registry import ALGORITHM_SPECS
from morl_trl.recipes.config.resolve import (
    RESUME_MAY_CHANGE,
    coerce_values,
    config_values,
    flatten_tables,
    load_config_file,
    quick_preset,
    resolve_config,
    resume_config,
)
from morl_trl.recipes.config.train_config import RENAMED, TrainConfig, upgrade_keys, valid_keys

__all__ = ["ALGORITHMS", "ALGORITHM_SPECS", "KEYS", "RENAMED", "RESUME_MAY_CHANGE", "SHARED_SECTIONS", "TrainConfig",
           "coerce_values", "config_values", "flatten_tables", "load_config_file", "quick_preset", "resolve_config", "resume_config",
           "upgrade_keys", "valid_keys"]
