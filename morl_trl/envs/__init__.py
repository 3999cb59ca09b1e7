"""Contextual multi-objective domains as batched TorchRL environments.

Example:
    >>> from morl_trl.envs import make_env, evaluation_suite, list_envs
    >>> "MOLunarLanderDR-v0" in list_envs()
    True
    >>> evaluation_suite("MOHopperDR-v5")[:2]
    ['MOHopperDefault-v5', 'MOHopperLight-v5']
"""

from morl_trl.envs.base import ContextualMOEnv, NonFiniteStepError
from morl_trl.envs.context import ContextSpace
from morl_trl.envs.registry import (
    context_space,
    domain_of,
    evaluation_suite,
    is_randomized,
    list_domains,
    list_envs,
    make_env,
    register_domain,
    register_env,
    load_domain_modules,
)
from morl_trl.envs.sampler import ContextSampler
from morl_trl.envs.spec import DomainSpec, SORLReward

__all__ = [
    "ContextSampler",
    "ContextSpace",
    "ContextualMOEnv",
    "DomainSpec",
    "NonFiniteStepError",
    "SORLReward",
    "context_space",
    "domain_of",
    "evaluation_suite",
    "is_randomized",
    "list_domains",
    "list_envs",
    "make_env",
    "register_domain",
    "register_env",
    "load_domain_modules",
]
