"""morl_trl.objectives: multi-objective TorchRL losses, their value estimator and networks.

Losses (all :class:`~torchrl.objectives.LossModule` subclasses taking ``[*B, k]`` rewards):

* :class:`EnvelopeQLoss` -- Envelope Q-learning (discrete actions, PER-ready).
* :class:`CAPQLLoss` -- CAPQL (continuous actions, preference-conditioned SAC).
* :class:`MOSACLoss` / :class:`DiscreteMOSACLoss` -- MORL/D's multi-objective SAC.
  CAPQL, MOSAC and MORL/D's population compose their value estimates, critic and actor losses from
  the functions of :mod:`morl_trl.objectives.actor_critic_parts`.
* :class:`PCNLoss` -- Pareto Conditioned Networks' supervised loss (:mod:`morl_trl.objectives.pcn`).
* PGMORL: TorchRL's ``ClipPPOLoss`` on a batched population (:mod:`morl_trl.objectives.pgmorl`:
  :func:`make_population_ppo_actor`, :func:`make_population_value_network`, :func:`vector_gae`).
* :class:`PopulationMOSACLoss` -- MORL/D's population of MOSAC learners as one batched module
  (:mod:`morl_trl.objectives.population`).
* :class:`GPILoss` -- GPI-LS / GPI-PD (vector Q ensemble, GPI priorities); :class:`DynamicsLoss`
  -- GPI-PD's probabilistic dynamics ensemble (:class:`ProbabilisticEnsemble`).

Policies: :class:`MOQValueModule`, the greedy action ``argmax_a w · Q(s, a, w)`` of a vector
Q-network (chain it after the network; TorchRL's ``EGreedyModule`` after it explores).

Networks: :mod:`morl_trl.objectives.networks`; populations and ensembles as one module:
:mod:`morl_trl.objectives.batched` (:class:`BatchedLinear`, :class:`BatchedLayerNorm`, :class:`BatchedMLP`). Target updates: :class:`PolyakUpdate` (TorchRL's
``SoftUpdate`` in one ``foreach`` step).
"""

import warnings as _warnings

from morl_trl.objectives.batched import BatchedLayerNorm, BatchedLinear, BatchedMLP
from morl_trl.objectives.capql import CAPQLLoss
from morl_trl.objectives.common import MultiObjectiveLossModule
from morl_trl.objectives.dynamics import DynamicsLoss, ProbabilisticEnsemble, fit_dynamics
from morl_trl.objectives.envelope import EnvelopeQLoss
from morl_trl.objectives.gpi import GPILoss, GPIPolicy, GPIQNetwork, gpi_action
from morl_trl.objectives.mosac import DiscreteMOSACLoss, MOSACLoss
from morl_trl.objectives.sequential import LeanSequential
from morl_trl.objectives.networks import (
    NatureCNN,
    PreferenceConditionedMLP,
    make_categorical_actor,
    make_gaussian_actor,
    make_vector_critic,
    make_vector_q_network,
)
from morl_trl.objectives.pcn import PCNLoss, PCNNetwork, make_pcn_network
from morl_trl.objectives.pgmorl import (
    make_population_ppo_actor,
    make_population_value_network,
    ppo_population_mlp,
    vector_gae,
)
from morl_trl.objectives.qvalue import MOQValueModule, scalarized_argmax
from morl_trl.objectives.updaters import PolyakUpdate
from morl_trl.objectives.value import VectorTD0Estimator, vector_td0_return_estimate
from morl_trl.objectives.population import PopulationMOSACLoss

__all__ = [
    "BatchedLayerNorm",
    "BatchedLinear",
    "BatchedMLP",
    "CAPQLLoss",
    "DiscreteMOSACLoss",
    "EnvelopeQLoss",
    "MOQValueModule",
    "LeanSequential",
    "MOSACLoss",
    "MultiObjectiveLossModule",
    "NatureCNN",
    "PCNLoss",
    "PCNNetwork",
    "PolyakUpdate",
    "PreferenceConditionedMLP",
    "VectorTD0Estimator",
    "make_categorical_actor",
    "make_gaussian_actor",
    "make_pcn_network",
    "make_population_ppo_actor",
    "make_population_value_network",
    "ppo_population_mlp",
    "make_vector_critic",
    "make_vector_q_network",
    "scalarized_argmax",
    "vector_gae",
    "vector_td0_return_estimate",
    "PopulationMOSACLoss",
    # GPI-LS / GPI-PD
    "GPILoss",
    "GPIPolicy",
    "GPIQNetwork",
    "gpi_action",
    "DynamicsLoss",
    "ProbabilisticEnsemble",
    "fit_dynamics",
]

#: names removed in favour of the batched module (issue 26); the old PGMORL names still resolve, with a warning
_DEPRECATED = {
    "PopulationMLP": ("ppo_population_mlp", ppo_population_mlp),
    "make_population_actor": ("make_population_ppo_actor", make_population_ppo_actor),
    "make_population_critic": ("make_population_value_network", make_population_value_network),
}


def __getattr__(name: str):
    if name in _DEPRECATED:
        new, obj = _DEPRECATED[name]
        _warnings.warn(f"morl_trl.objectives.{name} is deprecated: use morl_trl.objectives.{new} (PGMORL's "
                       f"population; the batched layers are morl_trl.objectives.batched)", DeprecationWarning,
                       stacklevel=2)
        return obj
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
