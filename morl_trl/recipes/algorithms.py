"""Which recipe builds what, per algorithm: :data:`AGENT_BUILDERS` and :data:`TRAINING_ENV_BUILDERS`.

A new algorithm is one recipe module (its agent builder and, if its training env differs, an env
builder) registered here, plus its loss in :mod:`morl_trl.objectives`.

Example:
    >>> sorted(TRAINING_ENV_BUILDERS)
    ['morld', 'morld_psa', 'pcn', 'pgmorl']
    >>> AGENT_BUILDERS["envelope"].__name__
    'make_envelope_agent'
"""

from __future__ import annotations

from morl_trl.recipes.actor_critic import make_capql_agent, make_discrete_mosac_agent, make_mosac_agent
from morl_trl.recipes.agent import Agent
from morl_trl.recipes.allocator import tune_malloc
from morl_trl.recipes.config import ALGORITHMS, TrainConfig
from morl_trl.recipes.envelope import make_envelope_agent
from morl_trl.recipes.gpi import make_gpi_agent
from morl_trl.recipes.morld import make_morld_agent, make_morld_training_env
from morl_trl.recipes.parts import make_training_env
from morl_trl.recipes.pcn import make_pcn_agent, make_pcn_training_env
from morl_trl.recipes.pgmorl import make_pgmorl_agent, make_pgmorl_training_env
from morl_trl.recipes.sac import make_sac_agent

__all__ = ["AGENT_BUILDERS", "TRAINING_ENV_BUILDERS", "build_agent", "build_training_env"]

#: algorithm name -> ``builder(cfg, env, *, gamma, device) -> Agent``
AGENT_BUILDERS = {
    "envelope": make_envelope_agent,
    "capql": make_capql_agent,
    "mosac": make_mosac_agent,
    "mosac_discrete": make_discrete_mosac_agent,
    "morld": make_morld_agent,
    "morld_psa": make_morld_agent,
    "sac": make_sac_agent,
    "pcn": make_pcn_agent,
    "pgmorl": make_pgmorl_agent,
    "gpi_ls": make_gpi_agent,
    "gpi_pd": make_gpi_agent,
}
assert tuple(AGENT_BUILDERS) == ALGORITHMS


def build_agent(cfg: TrainConfig, env, *, gamma: float, device) -> Agent:
    """The :class:`Agent` of ``cfg.algo`` for ``env`` (a batched env with ``"preference"``).

    Sets the process's allocator for training first (:func:`~morl_trl.recipes.allocator.tune_malloc`:
    glibc only; ``MORL_TRL_MALLOC=0`` turns it off)."""
    tune_malloc()
    try:
        builder = AGENT_BUILDERS[cfg.algo]
    except KeyError:
        raise ValueError(f"unknown algorithm {cfg.algo!r}; valid: {list(ALGORITHMS)}") from None
    return builder(cfg, env, gamma=gamma, device=device)


#: algorithm name -> ``builder(cfg, device) -> env`` for an algorithm whose training env is not
#: :func:`~morl_trl.recipes.parts.make_training_env`'s (DR env + history + preferences + returns)
TRAINING_ENV_BUILDERS: dict = {
    "pcn": make_pcn_training_env,
    "pgmorl": make_pgmorl_training_env,
}
TRAINING_ENV_BUILDERS["morld"] = TRAINING_ENV_BUILDERS["morld_psa"] = make_morld_training_env


def build_training_env(cfg: TrainConfig, device):
    """The training env of ``cfg.algo`` (its own builder, else :func:`make_training_env`)."""
    return TRAINING_ENV_BUILDERS.get(cfg.algo, make_training_env)(cfg, device)
