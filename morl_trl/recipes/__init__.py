"""Training recipes: each algorithm's training loop, written once; ``morl-trl train`` runs them.

:func:`~morl_trl.recipes.off_policy.run_training` opens the run and hands it to the
algorithm's recipe; every recipe writes only its loop inside :meth:`Run.session
<morl_trl.runs.Run.session>` (run directory, resume, evaluations, checkpoints, logs, report,
Ctrl-C, clean stops). Envelope's, GPI-LS / GPI-PD's, the actor-critics' (CAPQL, MOSAC, SAC) and
PCN's recipes are one function each, read top to bottom; the others are an agent each, whose ``learn``
decides what a collected batch does, driven by one generic loop (:func:`~morl_trl.recipes.off_policy.train_agent`):

* ``envelope``: :func:`~morl_trl.recipes.envelope.train_envelope` (its modules:
  :func:`~morl_trl.recipes.envelope.make_envelope_agent`)
* ``capql``, ``mosac``, ``mosac_discrete``, ``sac``: :func:`~morl_trl.recipes.actor_critic.train_actor_critic`
  (its modules: :func:`~morl_trl.recipes.actor_critic.make_capql_agent`,
  :func:`~morl_trl.recipes.actor_critic.make_mosac_agent`,
  :func:`~morl_trl.recipes.actor_critic.make_discrete_mosac_agent`, SAC's
  :func:`~morl_trl.recipes.sac.make_sac_agent` on the scalar reward)
* ``morld``, ``morld_psa`` (MORL/D SB, SB+PSA): :func:`~morl_trl.recipes.morld.make_morld_agent`
  (:class:`~morl_trl.recipes.morld.MORLDAgent`: a batched population, shared buffer, exchanges)
* ``pcn``: :func:`~morl_trl.recipes.pcn.train_pcn` (its modules: :func:`~morl_trl.recipes.pcn.make_pcn_agent`;
  :class:`~morl_trl.recipes.pcn.PCNAgent`: the episode replay, the command, the rounds)
* ``pgmorl``: :func:`~morl_trl.recipes.pgmorl.make_pgmorl_agent`
  (:class:`~morl_trl.recipes.pgmorl.PGMORLAgent`: population PPO, evolution)
* ``gpi_ls``, ``gpi_pd``: :func:`~morl_trl.recipes.gpi.train_gpi` (its modules:
  :func:`~morl_trl.recipes.gpi.make_gpi_agent`; :class:`~morl_trl.recipes.gpi.GPIAgent`: the
  weight-support iterations, + Dyna for GPI-PD)

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
    "Agent": "morl_trl.recipes.agent",
    "AGENT_BUILDERS": "morl_trl.recipes.algorithms",
    "TRAINING_ENV_BUILDERS": "morl_trl.recipes.algorithms",
    "build_agent": "morl_trl.recipes.algorithms",
    "build_training_env": "morl_trl.recipes.algorithms",
    "ALGORITHMS": "morl_trl.recipes.config",
    "TrainConfig": "morl_trl.recipes.config",
    "resolve_config": "morl_trl.recipes.config",
    "evaluate_run": "morl_trl.recipes.off_policy",
    "run_training": "morl_trl.recipes.off_policy",
    "train": "morl_trl.recipes.off_policy",
    "NonFiniteLossError": "morl_trl.recipes.optim",
    "make_training_env": "morl_trl.recipes.parts",
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


__getattr__, __dir__ = _lazy_attributes(globals(), _LAZY)
