"""The environment registry: ids, domains, evaluation suites and ``make_env``.

Every domain is described by a :class:`DomainSpec` (data: the env class to build, its
context space, the named fixed contexts of the paper's tables and which of them form the
evaluation suite). Domain specs live in :mod:`morl_trl.envs.specs` and are imported lazily,
so that importing :mod:`morl_trl.envs` pulls in no simulator.
"""

from __future__ import annotations

import difflib
import importlib
import inspect
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import torch

from morl_trl.envs.context import ContextSpace

__all__ = [
    "DomainSpec",
    "register_domain",
    "make_env",
    "list_envs",
    "evaluation_suite",
    "context_space",
    "domain_of",
    "list_domains",
]


@dataclass(frozen=True)
class DomainSpec:
    """A contextual multi-objective domain as data.

    Args:
        name: human name, e.g. ``"MO-LunarLander"``.
        train_id: the domain-randomized training id, e.g. ``"MOLunarLanderDR-v0"``.
        env_class: ``"module:Class"`` of the batched :class:`~torchrl.envs.EnvBase`; imported
            only when an env is built. The class takes ``num_envs``, ``context``, ``device``,
            ``seed`` and the ``env_kwargs`` below.
        context_space: the domain's :class:`ContextSpace`.
        contexts: every fixed-context id of the domain mapped to its parameter overrides
            (the rest stays at the default).
        evaluation_ids: the paper's evaluation suite for ``train_id`` (a subset of ``contexts``).
        env_kwargs: extra constructor arguments (e.g. ``continuous=True``).
        gamma: the discount the paper evaluates with.
        hv_ref_point: the paper's unnormalized hypervolume reference point.
        objective_names: names of the reward entries, in order.
        max_episode_steps: the truncation horizon.
        history_len: the paper's state-action history length (``StateActionHistory``; 0: none).
        train_frames: the paper's training length in environment frames.
        eval_interval: the paper's evaluation period in frames.
        eval_weights: the paper's number of evaluation weights (energy weights, SPEC §2).
    """

    name: str
    train_id: str
    env_class: str
    context_space: ContextSpace
    contexts: Mapping[str, Mapping[str, Any]]
    evaluation_ids: tuple[str, ...]
    objective_names: tuple[str, ...]
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    gamma: float = 0.99
    hv_ref_point: tuple[float, ...] | None = None
    max_episode_steps: int = 1000
    # the paper's training and evaluation protocol (SPEC §2, §4)
    history_len: int = 0
    train_frames: int = 1_000_000
    eval_interval: int = 50_000
    eval_weights: int = 100

    def __post_init__(self) -> None:
        missing = [e for e in self.evaluation_ids if e not in self.contexts]
        if missing:
            raise ValueError(f"{self.name}: evaluation ids {missing} have no context")

    @property
    def num_objectives(self) -> int:
        return len(self.objective_names)

    def ids(self) -> list[str]:
        return [self.train_id, *self.contexts]

    def env_cls(self) -> type:
        module, _, cls = self.env_class.partition(":")
        return getattr(importlib.import_module(module), cls)

    def context_of(self, env_id: str) -> torch.Tensor:
        """The fixed context of ``env_id`` (the default context for the training id)."""
        if env_id == self.train_id:
            return self.context_space.default_tensor()
        return self.context_space.make(self.contexts[env_id])


_DOMAINS: dict[str, DomainSpec] = {}  # train id -> spec
_IDS: dict[str, DomainSpec] = {}  # every id -> spec
_LOADED = False


def register_domain(spec: DomainSpec, *, replace: bool = False) -> DomainSpec:
    """Add a domain (its training id and every fixed-context id) to the registry."""
    clashes = [i for i in spec.ids() if i in _IDS and _IDS[i].train_id != spec.train_id]
    if clashes and not replace:
        raise ValueError(f"ids already registered by another domain: {clashes}")
    _DOMAINS[spec.train_id] = spec
    for env_id in spec.ids():
        _IDS[env_id] = spec
    return spec


def _ensure_loaded() -> None:
    global _LOADED
    if not _LOADED:
        _LOADED = True
        importlib.import_module("morl_trl.envs.specs")


def _lookup(env_id: str) -> DomainSpec:
    _ensure_loaded()
    try:
        return _IDS[env_id]
    except KeyError:
        close = difflib.get_close_matches(str(env_id), list(_IDS), n=5, cutoff=0.5)
        hint = f"; did you mean {close}?" if close else ""
        raise ValueError(
            f"unknown env id {env_id!r}{hint} (morl_trl.envs.list_envs() lists all {len(_IDS)} ids)"
        ) from None


def list_envs() -> list[str]:
    """Every registered id: training (DR) ids and fixed-context ids."""
    _ensure_loaded()
    return sorted(_IDS)


def list_domains() -> list[DomainSpec]:
    """The registered domains, one per training id."""
    _ensure_loaded()
    return list(_DOMAINS.values())


def domain_of(env_id: str) -> DomainSpec:
    """The :class:`DomainSpec` an id belongs to."""
    return _lookup(env_id)


def evaluation_suite(env_id: str) -> list[str]:
    """The paper's evaluation ids for the domain of ``env_id`` (usually its DR id)."""
    return list(_lookup(env_id).evaluation_ids)


def context_space(env_id: str) -> ContextSpace:
    """The :class:`ContextSpace` of the domain of ``env_id``."""
    return _lookup(env_id).context_space


def is_randomized(env_id: str) -> bool:
    """Whether ``env_id`` is a domain-randomized (training) id."""
    return _lookup(env_id).train_id == env_id


def make_env(
    env_id: str,
    num_envs: int = 1,
    device: torch.device | str = "cpu",
    seed: int | None = None,
    **overrides: Any,
):
    """Build a batched environment by id.

    A ``*DR-*`` (training) id gives the fixed env wrapped in
    :class:`~morl_trl.transforms.DomainRandomization` (a new context per sub-env at each of
    its resets), as a :class:`~morl_trl.transforms.DomainRandomizedEnv` (a ``TransformedEnv``
    whose auto-resets take the env's lean path); any other id gives its fixed context. Keyword ``overrides`` that name
    context parameters fix those parameters (also under domain randomization); other
    keywords go to the env constructor.

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("MOLunarLanderHard-v0", num_envs=4, seed=0)
        >>> env.rollout(3)["next", "reward"].shape
        torch.Size([4, 3, 4])
        >>> make_env("MOLunarLanderDR-v0", num_envs=2, seed=0, wind_power=0.0).reset()["context"][:, 1]
        tensor([0., 0.])
    """
    spec = _lookup(env_id)
    if not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"num_envs must be a positive int, got {num_envs!r}")
    space = spec.context_space
    ctx_over = {k: v for k, v in overrides.items() if k in space.names}
    kwargs = {**spec.env_kwargs, **{k: v for k, v in overrides.items() if k not in space.names}}
    base = dict(spec.contexts.get(env_id, {}))
    base.update(ctx_over)
    context = space.make(base)
    cls = spec.env_cls()
    params = inspect.signature(cls.__init__).parameters
    if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        accepted = [p for p in params if p not in ("self", "num_envs", "context", "device", "seed")]
        unknown = sorted(set(kwargs) - set(accepted))
        if unknown:
            raise ValueError(
                f"{env_id}: unknown keyword(s) {unknown}; valid are the context parameters "
                f"{list(space.names)} and the env options {accepted}"
            )
    env = cls(num_envs=num_envs, context=context, device=device, seed=seed, **kwargs)
    if env_id != spec.train_id:
        return env
    from morl_trl.transforms.domain_randomization import DomainRandomization, DomainRandomizedEnv

    return DomainRandomizedEnv(env, DomainRandomization(space, seed=seed, fixed=ctx_over))
