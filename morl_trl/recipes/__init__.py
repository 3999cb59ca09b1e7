"""Training recipes: each algorithm's training loop, written once; ``morl-trl train`` runs them.

Every algorithm runs in the one loop :func:`~morl_trl.recipes.off_policy.run_training`
(collection, evaluation, checkpoints, logs, report); what differs is its agent, whose
``learn`` decides what a collected batch does:

* ``envelope``: :func:`~morl_trl.recipes.envelope.make_envelope_agent`
* ``capql``, ``mosac``, ``mosac_discrete``: :mod:`morl_trl.recipes.actor_critic`
* ``morld``, ``morld_psa`` (MORL/D SB, SB+PSA): :func:`~morl_trl.recipes.morld.make_morld_agent`
  (:class:`~morl_trl.recipes.morld.MORLDAgent`: a batched population, shared buffer, exchanges)
* ``sac`` (the single-objective baseline): :func:`~morl_trl.recipes.sac.make_sac_agent`
* ``pcn``: :func:`~morl_trl.recipes.pcn.make_pcn_agent` (:class:`~morl_trl.recipes.pcn.PCNAgent`:
  episode replay, supervised updates)
* ``pgmorl``: :func:`~morl_trl.recipes.pgmorl.make_pgmorl_agent`
  (:class:`~morl_trl.recipes.pgmorl.PGMORLAgent`: population PPO, evolution)
* ``gpi_ls``, ``gpi_pd``: :func:`~morl_trl.recipes.gpi.make_gpi_agent`
  (:class:`~morl_trl.recipes.gpi.GPIAgent`: weight-support iterations, + Dyna for GPI-PD)

The configuration (:class:`~morl_trl.recipes.config.TrainConfig`) starts from the paper's
settings for the algorithm and domain; ``examples/`` holds ready config files.

Example:
    >>> from morl_trl.recipes import resolve_config, train
    >>> cfg = resolve_config("envelope", "MOLavaGridDR-v0", quick=True, frames=2_000)  # doctest: +SKIP
    >>> summary = train(cfg)                                                            # doctest: +SKIP
"""

from __future__ import annotations

from morl_trl.recipes.actor_critic import make_capql_agent, make_discrete_mosac_agent, make_mosac_agent
from morl_trl.recipes.agent import Agent, NonFiniteLossError
from morl_trl.recipes.config import ALGORITHMS, TrainConfig, resolve_config
from morl_trl.recipes.envelope import make_envelope_agent
from morl_trl.recipes.pcn import make_pcn_agent, make_pcn_training_env
from morl_trl.recipes.pgmorl import make_pgmorl_agent, make_pgmorl_training_env
from morl_trl.recipes.morld import make_morld_agent, make_morld_training_env
from morl_trl.recipes.sac import make_sac_agent
from morl_trl.recipes.gpi import make_gpi_agent
from morl_trl.recipes.off_policy import evaluate_run, make_training_env, run_training, train
from morl_trl.recipes.policy import TrainedPolicy, TrainResult, load_policy, train_policy

__all__ = [
    "AGENT_BUILDERS",
    "ALGORITHMS",
    "Agent",
    "NonFiniteLossError",
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
    "train",
    "train_policy",
]

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
    """The :class:`Agent` of ``cfg.algo`` for ``env`` (a batched env with ``"preference"``)."""
    try:
        builder = AGENT_BUILDERS[cfg.algo]
    except KeyError:
        raise ValueError(f"unknown algorithm {cfg.algo!r}; valid: {list(ALGORITHMS)}") from None
    return builder(cfg, env, gamma=gamma, device=device)


#: algorithm name -> ``builder(cfg, device) -> env`` for an algorithm whose training env is not
#: :func:`~morl_trl.recipes.off_policy.make_training_env`'s (DR env + history + preferences + returns)
TRAINING_ENV_BUILDERS: dict = {
    "pcn": make_pcn_training_env,
    "pgmorl": make_pgmorl_training_env,
}
TRAINING_ENV_BUILDERS["morld"] = TRAINING_ENV_BUILDERS["morld_psa"] = make_morld_training_env


def build_training_env(cfg: TrainConfig, device):
    """The training env of ``cfg.algo`` (its own builder, else :func:`make_training_env`)."""
    return TRAINING_ENV_BUILDERS.get(cfg.algo, make_training_env)(cfg, device)
