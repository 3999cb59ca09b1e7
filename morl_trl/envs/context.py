"""Context spaces: the named, bounded parameter vectors that define a contextual MDP.

A *context* is a float vector ``[c]`` whose entries are named physical parameters (gravity,
masses, friction, ...). A :class:`ContextSpace` holds their order, defaults, their declared
*bounds* (the range the physics is valid in: every evaluation context lies inside) and the
domain-randomization ranges (a separate, narrower fact), validates user input, and samples
contexts reproducibly from a :class:`torch.Generator`.

A context outside its declared bounds is rejected (``ValueError`` naming the parameter, the
value and the bounds) unless the caller opts in with ``allow_extrapolation=True`` (studies of
contexts beyond the valid physics); NaN, infinite and non-positive values of parameters the
physics needs positive are rejected either way.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import torch

__all__ = ["ContextSpace"]


def _as_tuple(values: Sequence[float], name: str, n: int) -> tuple[float, ...]:
    values = tuple(float(v) for v in values)
    if len(values) != n:
        raise ValueError(f"ContextSpace: {name} has {len(values)} entries, expected {n}")
    return values


@dataclass(frozen=True)
class ContextSpace:
    """Ordered named parameters with defaults, declared bounds and domain-randomization ranges.

    Args:
        names: parameter names, in the order of the context vector.
        default: the default value of each parameter.
        low, high: the domain-randomization range of each parameter (uniform sampling).
        positive: names of parameters that the physics only accepts strictly positive
            (masses, friction, engine power); ``validate`` rejects others.
        valid_low, valid_high: the declared bounds of each parameter (inclusive), the range
            its physics is valid in; they contain the default and the randomization range.
            ``None``: unbounded (``-inf``/``inf``). ``validate`` rejects values outside
            unless ``allow_extrapolation=True``.

    Example:
        >>> import torch
        >>> space = ContextSpace(("gravity", "wind"), (-10.0, 15.0), (-13.0, 0.0), (-7.0, 20.0))
        >>> space.make(gravity=-12.0)
        tensor([-12.,  15.])
        >>> space.sample(3, generator=torch.Generator().manual_seed(0)).shape
        torch.Size([3, 2])
        >>> bounded = ContextSpace(("g",), (-10.0,), (-13.0,), (-7.0,), valid_low=(-20.0,), valid_high=(-0.5,))
        >>> bounded.make(g=3.0)
        Traceback (most recent call last):
        ...
        ValueError: context parameter 'g' is 3.0 (row 0), outside its declared bounds [-20.0, -0.5] (the range its physics is valid in); pass allow_extrapolation=True to study contexts beyond them
        >>> bounded.make(g=3.0, allow_extrapolation=True)
        tensor([3.])
    """

    names: tuple[str, ...]
    default: tuple[float, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]
    positive: frozenset[str] = field(default_factory=frozenset)
    valid_low: tuple[float, ...] | None = None
    valid_high: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        names = tuple(self.names)
        object.__setattr__(self, "names", names)
        n = len(names)
        if len(set(names)) != n:
            raise ValueError(f"ContextSpace: duplicate parameter names in {names}")
        object.__setattr__(self, "default", _as_tuple(self.default, "default", n))
        object.__setattr__(self, "low", _as_tuple(self.low, "low", n))
        object.__setattr__(self, "high", _as_tuple(self.high, "high", n))
        object.__setattr__(self, "positive", frozenset(self.positive))
        unknown = self.positive - set(names)
        if unknown:
            raise ValueError(f"ContextSpace: positive names {sorted(unknown)} are not parameters")
        for name, lo, hi in zip(names, self.low, self.high):
            if not lo <= hi:
                raise ValueError(f"ContextSpace: range of {name!r} has low {lo} > high {hi}")
        inf = float("inf")
        valid_low = (-inf,) * n if self.valid_low is None else _as_tuple(self.valid_low, "valid_low", n)
        valid_high = (inf,) * n if self.valid_high is None else _as_tuple(self.valid_high, "valid_high", n)
        object.__setattr__(self, "valid_low", valid_low)
        object.__setattr__(self, "valid_high", valid_high)
        for name, d, lo, hi, vlo, vhi in zip(names, self.default, self.low, self.high, valid_low, valid_high):
            if not (vlo <= min(lo, d) and max(hi, d) <= vhi):
                raise ValueError(
                    f"ContextSpace: the declared bounds [{vlo}, {vhi}] of {name!r} must contain its default {d} "
                    f"and its randomization range [{lo}, {hi}]"
                )

    # ------------------------------------------------------------------ basic views
    @property
    def dim(self) -> int:
        """Number of parameters ``c``."""
        return len(self.names)

    def index(self, name: str) -> int:
        """Position of ``name`` in the context vector."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(
                f"unknown context parameter {name!r}; valid names: {list(self.names)}"
            ) from None

    def default_tensor(self, device: torch.device | str | None = None) -> torch.Tensor:
        """The default context as a ``[c]`` float32 tensor."""
        return torch.tensor(self.default, dtype=torch.float32, device=device)

    def bounds(self, device=None) -> tuple[torch.Tensor, torch.Tensor]:
        """The domain-randomization ranges as two ``[c]`` tensors."""
        lo = torch.tensor(self.low, dtype=torch.float32, device=device)
        hi = torch.tensor(self.high, dtype=torch.float32, device=device)
        return lo, hi

    def valid_bounds(self, device=None) -> tuple[torch.Tensor, torch.Tensor]:
        """The declared bounds (the range the physics is valid in) as two ``[c]`` tensors."""
        lo = torch.tensor(self.valid_low, dtype=torch.float32, device=device)
        hi = torch.tensor(self.valid_high, dtype=torch.float32, device=device)
        return lo, hi

    def _tensors(self, device) -> tuple[torch.Tensor, ...]:
        """Cached ``(low, high, high - low, floor, valid_low, valid_high)`` on ``device``
        (internal: never handed out, so never modified). ``floor`` is 0 for the positive
        parameters, -inf for the others."""
        cache = self.__dict__.setdefault("_tensor_cache", {})  # not a field: outside eq and hash
        tensors = cache.get(device)  # keyed by what callers pass (None, a str or a torch.device)
        if tensors is None:
            lo, hi = self.bounds(device)
            floor = torch.tensor(
                [0.0 if name in self.positive else -float("inf") for name in self.names], device=lo.device
            )
            vlo, vhi = self.valid_bounds(lo.device)
            tensors = cache[device] = (lo, hi, hi - lo, floor, vlo, vhi)
        return tensors

    def as_dict(self, context: torch.Tensor) -> dict[str, float]:
        """Name each entry of a single ``[c]`` context (outside the bounds too: naming checks no range)."""
        context = self.validate(context, allow_extrapolation=True)
        if context.ndim != 1:
            raise ValueError(f"as_dict takes a single context of shape [{self.dim}], got {tuple(context.shape)}")
        return {n: float(v) for n, v in zip(self.names, context.tolist())}

    def make(
        self,
        overrides: Mapping[str, float] | None = None,
        /,
        *,
        allow_extrapolation: bool = False,
        **kwargs: float,
    ) -> torch.Tensor:
        """The default context with some parameters overridden by name, validated (see
        :meth:`validate` for ``allow_extrapolation``)."""
        values = list(self.default)
        for name, value in {**(overrides or {}), **kwargs}.items():
            i = self.index(name)
            try:
                values[i] = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"context parameter {name!r} must be a number, got {value!r}") from None
        return self.validate(torch.tensor(values, dtype=torch.float32), allow_extrapolation=allow_extrapolation)

    # ------------------------------------------------------------------ sampling
    def sample(
        self,
        n: int,
        generator: torch.Generator | None = None,
        device: torch.device | str | None = None,
    ) -> torch.Tensor:
        """Draw ``n`` contexts, each parameter independently uniform in ``[low, high]``."""
        if generator is not None and device is None:
            device = generator.device
        lo, _, span = self._tensors(device)[:3]
        u = torch.rand((n, self.dim), generator=generator, device=device)
        return lo + u * span

    # ------------------------------------------------------------------ validation
    def validate(self, context, *, check_range: bool = False, allow_extrapolation: bool = False) -> torch.Tensor:
        """Check a ``[..., c]`` context and return it as a float tensor.

        Raises ``ValueError`` naming the parameter, the value and what is valid when the last
        dimension is not ``c``, an entry is NaN or infinite, a parameter that the physics
        needs positive is not, an entry lies outside its declared bounds (unless
        ``allow_extrapolation``: contexts beyond the valid physics, for extrapolation
        studies), or (with ``check_range``) outside the randomization range.
        """
        context = torch.as_tensor(context)
        if not context.is_floating_point():
            context = context.float()
        if context.ndim == 0 or context.shape[-1] != self.dim:
            raise ValueError(
                f"context has shape {tuple(context.shape)}; expected [..., {self.dim}] "
                f"with parameters {list(self.names)}"
            )
        if self.dim == 0:  # a space without parameters (an env with no context): nothing to check
            return context
        flat = context.reshape(-1, self.dim)
        _, _, _, floor, vlo, vhi = self._tensors(flat.device)
        valid = (flat > floor) & (flat < float("inf"))  # NaN fails both
        if not allow_extrapolation:
            valid &= (flat >= vlo) & (flat <= vhi)
        if not bool(valid.all()):  # one reduction on the valid path; diagnose only on failure
            row, col = (int(i) for i in (~valid).nonzero()[0])
            value = flat[row, col].item()
            name = self.names[col]
            if not torch.isfinite(flat[row, col]):
                raise ValueError(f"context parameter {name!r} is {value} (row {row}); it must be a finite number")
            if not value > floor[col]:
                raise ValueError(
                    f"context parameter {name!r} is {value} (row {row}); the physics needs it strictly positive"
                )
            raise ValueError(
                f"context parameter {name!r} is {value} (row {row}), outside its declared bounds "
                f"[{self.valid_low[col]}, {self.valid_high[col]}] (the range its physics is valid in); "
                "pass allow_extrapolation=True to study contexts beyond them"
            )
        if check_range:
            lo, hi = self._tensors(flat.device)[:2]
            # a float32 round-off tolerance: samples are computed as lo + u * (hi - lo)
            tol = 1e-5 * (1.0 + torch.maximum(lo.abs(), hi.abs()))
            out = (flat < lo - tol) | (flat > hi + tol)
            if out.any():
                row, col = (int(i) for i in out.nonzero()[0])
                raise ValueError(
                    f"context parameter {self.names[col]!r} is {flat[row, col].item()} (row {row}), "
                    f"outside its range [{self.low[col]}, {self.high[col]}]"
                )
        return context

    def contains(self, context) -> bool:
        """Whether every context in ``[..., c]`` is valid and inside the ranges."""
        try:
            self.validate(context, check_range=True)
        except ValueError:
            return False
        return True

    def __repr__(self) -> str:
        rows = ", ".join(
            f"{n}={d:g}[{lo:g},{hi:g}]" + ("" if (vlo, vhi) == (-float("inf"), float("inf")) else f" in [{vlo:g},{vhi:g}]")
            for n, d, lo, hi, vlo, vhi in zip(
                self.names, self.default, self.low, self.high, self.valid_low, self.valid_high
            )
        )
        return f"ContextSpace({rows})"

    def __len__(self) -> int:
        return self.dim
