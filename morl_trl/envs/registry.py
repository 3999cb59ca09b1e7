"""The environment registry: ids, domains, evaluation suites and ``make_env``.

Every domain is described by a :class:`~morl_trl.envs.spec.DomainSpec` (data: the env class
to build, its context space, the named fixed contexts of the paper's tables and which of them
form the evaluation suite). The built-in domains' specs live in their own folders
(``morl_trl/envs/<domain>/spec.py``, each a tuple ``SPECS``); the registry imports them at its
first lookup (they import no simulator, and not the registry), and ``register_domain`` adds
user domains. No simulator is imported until an env is built.
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any

import torch

from morl_trl.envs.base import check_num_envs
from morl_trl.envs.context import ContextSpace
from morl_trl.envs.sampler import ContextSampler, check_seed
from morl_trl.envs.spec import DomainSpec

__all__ = [
    "DomainSpec",
    "register_domain",
    "register_env",
    "load_domain_modules",
    "make_env",
    "list_envs",
    "evaluation_suite",
    "context_space",
    "domain_of",
    "list_domains",
]


_DOMAINS: dict[str, DomainSpec] = {}  # train id -> spec
_IDS: dict[str, DomainSpec] = {}  # every id -> spec
_LOADED = False
# the built-in domains' spec modules, in registration order (each defines SPECS)
_BUILTIN_SPECS = (
    "morl_trl.envs.lava_grid.spec",
    "morl_trl.envs.lunar_lander.spec",
    "morl_trl.envs.mario.spec",
    "morl_trl.envs.mujoco.spec",
    "morl_trl.envs.dmc.spec",
)


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
        for module in _BUILTIN_SPECS:
            for spec in importlib.import_module(module).SPECS:
                register_domain(spec)
        _load_entry_points()


#: the entry point group through which installed packages add domains: each entry names a
#: module with ``SPECS`` (a tuple of :class:`DomainSpec`), a :class:`DomainSpec`, or a callable
#: returning one or several
ENTRY_POINT_GROUP = "morl_trl.domains"


def _register_object(obj: Any, origin: str) -> list[str]:
    """Register what a domain module or entry point offers; returns the training ids added."""
    if inspect.ismodule(obj):
        obj = getattr(obj, "SPECS", ())
    elif callable(obj) and not isinstance(obj, DomainSpec):
        obj = obj()
    specs = [obj] if isinstance(obj, DomainSpec) else list(obj)
    bad = [type(s).__name__ for s in specs if not isinstance(s, DomainSpec)]
    if bad:
        raise ValueError(f"{origin} gives {bad}; a domain module offers DomainSpec objects (a tuple SPECS)")
    return [register_domain(s, replace=True).train_id for s in specs]


def _load_entry_points() -> None:
    import warnings
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            _register_object(ep.load(), f"entry point {ep.name} = {ep.value}")
        except Exception as err:  # a broken plugin must not break the built-in domains
            warnings.warn(f"morl_trl: the domain entry point {ep.name!r} ({ep.value}) failed to load: {err}",
                          stacklevel=3)


def load_domain_modules(modules) -> list[str]:
    """Import each module named in ``modules`` (``"pkg.module"``) and register its domains (its
    ``SPECS``; a module may also call :func:`register_domain` itself); returns the training ids
    added. What ``--domain-module`` and the config key ``domain_modules`` do."""
    _ensure_loaded()
    added: list[str] = []
    for name in [modules] if isinstance(modules, str) else list(modules or ()):
        try:
            module = importlib.import_module(name)
        except ImportError as err:
            raise ValueError(f"domain module {name!r} cannot be imported: {err}") from None
        added += _register_object(module, f"domain module {name!r}")
    return added


def _mo_gymnasium_ids() -> list[str]:
    """MO-Gymnasium's registered ids (for "did you mean"; none without the gym extra)."""
    try:
        import gymnasium
        import mo_gymnasium  # noqa: F401  (registers its ids)
    except ImportError:
        return []
    return [k for k, v in gymnasium.registry.items() if str(v.entry_point).startswith("mo_gymnasium")]


def _lookup(env_id: str) -> DomainSpec:
    _ensure_loaded()
    try:
        return _IDS[env_id]
    except (KeyError, TypeError):
        pass
    from morl_trl.envs.foreign import foreign_domain, is_gym_id

    if isinstance(env_id, str) and is_gym_id(env_id):  # a Gymnasium / MO-Gymnasium id: registered at first use
        return register_domain(foreign_domain(env_id))
    if not isinstance(env_id, str):
        raise ValueError(f"an env id is a str; got {type(env_id).__name__} (register a callable or an EnvBase "
                         f"first with morl_trl.envs.register_env(env, name=...))")
    else:
        from morl_trl._suggest import did_you_mean

        hint = did_you_mean(env_id, [*_IDS, *_mo_gymnasium_ids()], cutoff=0.7)
        raise ValueError(
            f"unknown env id {env_id!r}{hint}; morl_trl.envs.list_envs() (morl-trl envs) lists our {len(_IDS)} ids, "
            f"and any Gymnasium / MO-Gymnasium id with a vector reward works too"
        )


def register_env(env, name: str | None = None, *, ref_point=None, objective_names=None,
                 max_episode_steps: int | None = None, env_kwargs: dict | None = None, replace: bool = True) -> str:
    """Register a foreign env and return its id: a Gymnasium / MO-Gymnasium id (with options),
    a callable returning a TorchRL ``EnvBase`` with a vector reward, or an ``EnvBase``
    (see :mod:`morl_trl.envs.foreign`). ``name`` is the id (required but for Gymnasium ids).

    Example:
        >>> from torchrl.envs import MOGymEnv
        >>> from morl_trl.envs import make_env, register_env
        >>> env_id = register_env(lambda: MOGymEnv("deep-sea-treasure-v0"), name="my-dst", ref_point=[0, -25])
        >>> make_env(env_id, num_envs=3, seed=0).rollout(2, break_when_any_done=False)["next", "reward"].shape
        torch.Size([3, 2, 2])
    """
    from morl_trl.envs.foreign import foreign_domain

    if isinstance(env, DomainSpec):
        return register_domain(env, replace=replace).train_id
    spec = foreign_domain(env, name=name, ref_point=ref_point, objective_names=objective_names,
                          max_episode_steps=max_episode_steps, env_kwargs=env_kwargs)
    return register_domain(spec, replace=replace).train_id


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
    *,
    allow_extrapolation: bool = False,
    **overrides: Any,
):
    """Build a batched environment by id: the domain's :class:`~morl_trl.envs.ContextualMOEnv`.

    Every id gives the same kind of object (no transform), so ``env.append_transform(t)``
    returns a new ``TransformedEnv`` for every id. A ``*DR-*`` (training) id gives the env
    with a :class:`~morl_trl.envs.ContextSampler` (``ContextSampler(space, fixed=overrides,
    seed=seed)``): a new context per sub-env at each of its resets, drawn inside the env
    (auto-resets included), unless ``env.reset(td)`` gives one in ``td["context"]``. Any
    other id gives its fixed context. Keyword ``overrides`` that name context parameters fix
    those parameters (also under domain randomization); other keywords go to the env
    constructor.

    Seeding: ``seed`` (an int in ``[0, 2**63 - 1]``) seeds the sub-envs and the context
    stream (the same ``seed`` gives the same contexts, ``env.set_seed(s)`` re-seeds both).

    Bounds: a context parameter outside the domain's declared bounds (the range its physics
    is valid in, ``context_space(env_id).valid_low/valid_high``; wider than the
    randomization range) raises a ``ValueError`` naming it, its value and the bounds, here
    and at every later ``reset`` given a context. ``allow_extrapolation=True`` accepts them
    (extrapolation studies; values must still be finite, and positive where the physics
    needs it); a step whose physics then diverges raises
    :class:`~morl_trl.envs.base.NonFiniteStepError` naming the sub-env and its context.

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("MOLunarLanderHard-v0", num_envs=4, seed=0)
        >>> env.rollout(3)["next", "reward"].shape
        torch.Size([4, 3, 4])
        >>> make_env("MOLunarLanderDR-v0", num_envs=2, seed=0, wind_power=0.0).reset()["context"][:, 1]
        tensor([0., 0.])
    """
    spec = _lookup(env_id)
    num_envs = check_num_envs(num_envs)
    if seed is not None:
        seed = check_seed(seed)
    space = spec.context_space
    ctx_over = {k: v for k, v in overrides.items() if k in space.names}
    kwargs = {**spec.env_kwargs, **{k: v for k, v in overrides.items() if k not in space.names}}
    base = dict(spec.contexts.get(env_id, {}))
    base.update(ctx_over)
    try:
        context = space.make(base, allow_extrapolation=allow_extrapolation)
    except ValueError as err:
        raise ValueError(f"{env_id}: {err}") from None
    cls = spec.env_cls()
    params = inspect.signature(cls.__init__).parameters
    reserved = ("self", "num_envs", "context", "device", "seed", "context_sampler", "allow_extrapolation")
    if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        accepted = [p for p in params if p not in reserved]
        unknown = sorted(set(kwargs) - set(accepted))
        if unknown:
            raise ValueError(
                f"{env_id}: unknown keyword(s) {unknown}; valid are the context parameters "
                f"{list(space.names)} and the env options {accepted}"
            )
    if env_id == spec.train_id and space.dim:  # (an env without context parameters has nothing to draw)
        kwargs["context_sampler"] = ContextSampler(
            space, fixed=ctx_over, seed=seed, allow_extrapolation=allow_extrapolation
        )
    if allow_extrapolation:  # (domains without the option keep their signature)
        kwargs["allow_extrapolation"] = True
    return cls(num_envs=num_envs, context=context, device=device, seed=seed, **kwargs)
