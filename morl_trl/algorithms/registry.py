"""The one registry: an algorithm's name -> its builders, its loop and its per-batch step.

Each algorithm is one folder of :mod:`morl_trl.algorithms` (its agent builder, ``update``, ``on_batch``
and ``train_*`` loop in ``recipe.py``, read top to bottom; its config dataclass in ``config.py``), its loss
in :mod:`morl_trl.objectives`; adding one is that folder, its loss, one :class:`Algorithm` row here and
one row of :data:`~morl_trl.recipes.config.ALGORITHM_SPECS` (the torch-free config registry).

Example:
    >>> REGISTRY["envelope"].train.__name__, REGISTRY["envelope"].on_batch.__module__
    ('train_envelope', 'morl_trl.algorithms.envelope.recipe')
    >>> sorted(name for name, a in REGISTRY.items() if a.build_env is not make_training_env)
    ['morld', 'morld_psa', 'pcn', 'pgmorl']
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Callable

from morl_trl.algorithms.actor_critic import recipe as actor_critic
from morl_trl.algorithms.envelope import recipe as envelope
from morl_trl.algorithms.gpi import recipe as gpi
from morl_trl.algorithms.morld import recipe as morld
from morl_trl.algorithms.pcn import recipe as pcn
from morl_trl.algorithms.pgmorl import recipe as pgmorl
from morl_trl.training.agent import Agent
from morl_trl.training.allocator import tune_malloc
from morl_trl.training.parts import make_training_env
from morl_trl.algorithms.actor_critic.sac import make_sac_agent

__all__ = ["Algorithm", "REGISTRY", "AGENT_BUILDERS", "TRAINING_ENV_BUILDERS", "algorithm", "build_agent",
           "build_training_env"]


@dataclass(frozen=True)
class Algorithm:
    """One algorithm's entry points.

    Attributes:
        build_agent: ``(cfg, env, *, gamma, device) -> Agent``: its modules, loss and optimizers.
        train: ``(run) -> (summary, agent)``: its loop (what ``morl-trl train`` runs; for the actor-critics
            ``train_actor_critic`` bound to the algorithm's builder).
        on_batch: ``(agent, batch, buffer, frames) -> (losses | None, updates)``: what its loop does with
            one collected batch (``buffer``: ``None`` for PCN and PGMORL, which keep their own data).
        build_env: ``(cfg, device) -> env``: its training env.
    """

    build_agent: Callable
    train: Callable
    on_batch: Callable
    build_env: Callable = make_training_env


def _actor_critic(builder) -> Algorithm:
    """CAPQL, MOSAC, discrete MOSAC and SAC: one loop, bound to the algorithm's builder."""
    return Algorithm(builder, partial(actor_critic.train_actor_critic, make_agent=builder), actor_critic.on_batch)


#: algorithm name -> :class:`Algorithm`
REGISTRY: dict[str, Algorithm] = {
    "envelope": Algorithm(envelope.make_envelope_agent, envelope.train_envelope, envelope.on_batch),
    "capql": _actor_critic(actor_critic.make_capql_agent),
    "mosac": _actor_critic(actor_critic.make_mosac_agent),
    "mosac_discrete": _actor_critic(actor_critic.make_discrete_mosac_agent),
    "morld": Algorithm(morld.make_morld_agent, morld.train_morld, morld.on_batch, morld.make_morld_training_env),
    "morld_psa": Algorithm(morld.make_morld_agent, morld.train_morld, morld.on_batch, morld.make_morld_training_env),
    "sac": _actor_critic(make_sac_agent),
    "pcn": Algorithm(pcn.make_pcn_agent, pcn.train_pcn, pcn.on_batch, pcn.make_pcn_training_env),
    "pgmorl": Algorithm(pgmorl.make_pgmorl_agent, pgmorl.train_pgmorl, pgmorl.on_batch,
                        pgmorl.make_pgmorl_training_env),
    "gpi_ls": Algorithm(gpi.make_gpi_agent, gpi.train_gpi, gpi.on_batch),
    "gpi_pd": Algorithm(gpi.make_gpi_agent, gpi.train_gpi, gpi.on_batch),
}

#: views of :data:`REGISTRY`: algorithm name -> agent builder / training env builder
AGENT_BUILDERS = {name: a.build_agent for name, a in REGISTRY.items()}
TRAINING_ENV_BUILDERS = {name: a.build_env for name, a in REGISTRY.items() if a.build_env is not make_training_env}


def algorithm(name: str) -> Algorithm:
    """The :class:`Algorithm` named ``name``; an unknown name is an error naming the valid ones."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown algorithm {name!r}; valid: {list(REGISTRY)}") from None


def build_agent(cfg, env, *, gamma: float, device) -> Agent:
    """The :class:`Agent` of ``cfg.algo`` for ``env`` (a batched env with ``"preference"``).

    Sets the process's allocator for training first (:func:`~morl_trl.training.allocator.tune_malloc`:
    glibc only; ``MORL_TRL_MALLOC=0`` turns it off)."""
    tune_malloc()
    return algorithm(cfg.algo).build_agent(cfg, env, gamma=gamma, device=device)


def build_training_env(cfg, device):
    """The training env of ``cfg.algo``."""
    return algorithm(cfg.algo).build_env(cfg, device)
