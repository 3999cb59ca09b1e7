"""Context samplers: where the contexts of the sub-envs being reset come from.

A :class:`ContextSampler` is the env's source of reset contexts (domain randomization): a
:class:`~morl_trl.envs.ContextSpace`, optional fixed parameter values, an optional custom
sampling function and its own :class:`torch.Generator`. A
:class:`~morl_trl.envs.ContextualMOEnv` built with one draws a context for every sub-env it
resets (unless the reset TensorDict gives one); ``make_env`` of a ``*DR-*`` id builds the
domain's env with ``ContextSampler(space, fixed=overrides, seed=seed)``. The
``DomainRandomization`` transform (in the transforms package) draws through one too.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping

import torch

from morl_trl.envs.context import ContextSpace

__all__ = ["ContextSampler", "check_seed", "MAX_SEED"]

Sampler = Callable[..., torch.Tensor]

#: the largest seed accepted anywhere (envs of every domain, context samplers): seeds are ints in
#: ``[0, 2**63 - 1]``, the non-negative range of a signed 64-bit integer (torch's and NumPy's seeds)
MAX_SEED = 2**63 - 1


def check_seed(seed, name: str = "seed") -> int:
    """``seed`` as an int if it is one in ``[0, 2**63 - 1]`` (bools rejected), else a ``ValueError``."""
    if isinstance(seed, bool) or not hasattr(seed, "__index__"):
        raise ValueError(f"{name} must be an int in [0, 2**63 - 1], got {seed!r} ({type(seed).__name__})")
    value = seed.__index__()
    if not 0 <= value <= MAX_SEED:
        raise ValueError(f"{name} must be an int in [0, 2**63 - 1], got {value}")
    return value


def _accepts_previous(fn: Callable) -> bool:
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return False
    return any(p.name == "previous" or p.kind is p.VAR_KEYWORD for p in params)


class ContextSampler:
    """Draws validated contexts ``[n, c]`` from a context space, with its own generator.

    Contexts come from ``context_space.sample`` (independent uniform in the ranges; domains
    with procedural contexts, such as MO-LavaGrid, override it), or from ``sampler``. When the
    sampling function takes a ``previous`` keyword, :meth:`draw` passes it the current
    contexts ``[n, c]`` of the sub-envs being reset (the default context if none is given).
    A custom draw (a ``sampler``, or a space whose ``sample`` is overridden) is checked with
    ``context_space.validate(..., check_range=True)`` before the ``fixed`` parameters are
    written over it: a draw outside the space raises a ``ValueError`` naming the parameter
    and value (and an env resets nothing).

    Seeding: ``seed`` (or :meth:`set_seed`) seeds the generator with exactly that value, so
    ``ContextSampler(space, seed=s).draw(n)`` equals ``space.sample(n,
    generator=torch.Generator().manual_seed(s))``. An env built with an unseeded sampler
    seeds it with the env's seed, and ``env.set_seed(s)`` re-seeds it with ``s``.

    Args:
        context_space: the space to draw from.
        fixed: parameters held at a given value instead of drawn, e.g.
            ``{"wind_power": 0.0}`` (these may lie outside the randomization range, but not
            outside the declared bounds unless ``allow_extrapolation``).
        sampler: optional ``sampler(n, generator[, previous=...]) -> [n, c]`` drawing full
            contexts inside ``context_space``.
        seed: seed of the generator, an int in ``[0, 2**63 - 1]`` (``None``: unseeded until
            :meth:`set_seed`, or until an env seeds it).
        allow_extrapolation: accept ``fixed`` values outside the context space's declared
            bounds (extrapolation studies; the env must allow them too).

    Example:
        >>> import torch
        >>> from morl_trl.envs import ContextSampler
        >>> from morl_trl.envs.toy import TOY_CONTEXT
        >>> sampler = ContextSampler(TOY_CONTEXT, fixed={"bias": 0.5}, seed=0)
        >>> ctx = sampler.draw(3)
        >>> ctx.shape, ctx[:, 1].tolist()
        (torch.Size([3, 2]), [0.5, 0.5, 0.5])
        >>> state = sampler.get_state()
        >>> a = sampler.draw(2)
        >>> sampler.set_state(state)
        >>> torch.equal(sampler.draw(2), a)
        True
    """

    def __init__(
        self,
        context_space: ContextSpace,
        *,
        fixed: Mapping[str, float] | None = None,
        sampler: Sampler | None = None,
        seed: int | None = None,
        allow_extrapolation: bool = False,
    ) -> None:
        if not isinstance(context_space, ContextSpace):
            raise ValueError(f"context_space must be a ContextSpace, got {type(context_space).__name__}")
        if sampler is not None and not callable(sampler):
            raise ValueError(f"sampler must be callable sampler(n, generator) -> [n, c], got {sampler!r}")
        self.context_space = context_space
        self.allow_extrapolation = bool(allow_extrapolation)
        # NaN, non-positive or out-of-bounds fixed values fail here, not at the first reset
        context_space.make(fixed or {}, allow_extrapolation=self.allow_extrapolation)
        self.fixed = {context_space.names[context_space.index(k)]: float(v) for k, v in (fixed or {}).items()}
        self._fixed_idx = torch.tensor([context_space.index(k) for k in self.fixed], dtype=torch.long)
        self._fixed_val = torch.tensor(list(self.fixed.values()), dtype=torch.float32)
        self.generator = torch.Generator()
        self._seed: int | None = None
        self.sampler = sampler
        if seed is not None:
            self.set_seed(seed)

    # ------------------------------------------------------------------ the sampling function
    @property
    def sampler(self) -> Sampler | None:
        """The custom sampling function (``None``: ``context_space.sample``)."""
        return self._sampler

    @sampler.setter
    def sampler(self, fn: Sampler | None) -> None:
        if fn is not None and not callable(fn):
            raise ValueError(f"sampler must be callable sampler(n, generator) -> [n, c], got {fn!r}")
        self._sampler = fn
        space = self.context_space
        self.takes_previous = _accepts_previous(fn if fn is not None else space.sample)
        # ContextSpace.sample draws inside the ranges by construction; custom draws are checked
        self._check_draws = fn is not None or type(space).sample is not ContextSpace.sample

    # ------------------------------------------------------------------ seeding
    @property
    def seed(self) -> int | None:
        """The last seed given to the generator (``None`` before the first one)."""
        return self._seed

    def set_seed(self, seed: int) -> None:
        """Re-seed the generator with ``seed`` (an int in ``[0, 2**63 - 1]``)."""
        self._seed = check_seed(seed)
        self.generator.manual_seed(self._seed)

    def get_state(self) -> dict:
        """The generator state and seed (for checkpoints; see :meth:`set_state`)."""
        return {"generator": self.generator.get_state(), "seed": self._seed}

    def set_state(self, state: Mapping) -> None:
        """Continue the stream saved by :meth:`get_state`."""
        self.generator.set_state(state["generator"])
        self._seed = state.get("seed", self._seed)

    # ------------------------------------------------------------------ drawing
    def draw(self, n: int, previous: torch.Tensor | None = None) -> torch.Tensor:
        """Draw ``n`` validated float32 contexts ``[n, c]`` (on the CPU).

        ``previous`` (``[n, c]``, the current contexts of the sub-envs being reset) is
        passed on if the sampling function takes it.
        """
        space = self.context_space
        if self._seed is None:  # never seeded: from torch's global generator, once
            self.set_seed(int(torch.randint(0, 2**62, (1,)).item()))
        kwargs = {}
        if self.takes_previous:
            if previous is None:
                previous = space.default_tensor().expand(n, space.dim)
            kwargs["previous"] = previous.detach().to("cpu", torch.float32)
        if self._sampler is None:
            ctx = space.sample(n, generator=self.generator, **kwargs)
        else:
            ctx = self._sampler(n, self.generator, **kwargs)
        ctx = torch.as_tensor(ctx)
        if ctx.shape != (n, space.dim):
            raise ValueError(
                f"the context sampler returned shape {tuple(ctx.shape)}; expected ({n}, {space.dim}) "
                f"with parameters {list(space.names)}"
            )
        ctx = ctx.to("cpu", torch.float32)
        if self._check_draws:
            try:
                space.validate(ctx, check_range=True)
            except ValueError as err:
                raise ValueError(f"the context sampler returned an invalid context: {err}") from None
        if self.fixed:
            ctx = ctx.clone()
            ctx[:, self._fixed_idx] = self._fixed_val
            space.validate(ctx, allow_extrapolation=self.allow_extrapolation)
        return ctx

    def __repr__(self) -> str:
        extra = f", fixed={self.fixed}" if self.fixed else ""
        fn = self._sampler
        sampler = f", sampler={getattr(fn, '__name__', fn)}" if fn is not None else ""
        return f"{type(self).__name__}({self.context_space!r}{sampler}{extra}, seed={self._seed})"
