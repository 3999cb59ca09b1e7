"""Domain randomization as a transform: a new context for each sub-env at each of its resets.

The env-level mechanism is :class:`~morl_trl.envs.ContextSampler` (what ``make_env`` gives a
``*DR-*`` id); :class:`DomainRandomization` is its public face for users composing their own
envs (a :class:`~morl_trl.envs.ContextualMOEnv` built directly, inside ``SerialEnv`` /
``ParallelEnv``, ...).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping

import torch
from tensordict import TensorDict, TensorDictBase

from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.context import ContextSpace
from morl_trl.envs.sampler import ContextSampler
from morl_trl.transforms._utils import SeededTransform, innermost_env, reset_mask

__all__ = ["DomainRandomization"]

Sampler = Callable[..., torch.Tensor]


class DomainRandomization(SeededTransform):
    """Draws a fresh context for every sub-env being reset, before the base env resets.

    The context is written to the reset TensorDict under ``context_key``, which the base env
    reads (see :class:`~morl_trl.envs.ContextualMOEnv`); sub-envs that are not being reset
    (``"_reset"`` false) keep theirs. A ``context`` already in the reset TensorDict is
    replaced by the draw. It works inside and outside ``SerialEnv``/``ParallelEnv``. The
    draws, their checks and the fixed values are those of a
    :class:`~morl_trl.envs.ContextSampler` (``self.context_sampler``); ``make_env`` of a
    ``*DR-*`` id puts that sampler in the env itself instead of adding this transform.

    Contexts come from ``context_space.sample`` (independent uniform in the ranges; domains
    with procedural contexts override it), or from ``sampler``. When the sampling function
    takes a ``previous`` keyword, it receives the current contexts ``[n, c]`` of the sub-envs
    being reset. Every custom draw is checked with ``context_space.validate(...,
    check_range=True)`` before ``fixed`` parameters are written over it, so a sampler
    returning values outside the space raises a ``ValueError`` (naming the parameter and
    value) and nothing is reset.

    Seeding: ``seed`` seeds the transform's own generator; without it, the generator follows
    the env's seed (see :class:`~morl_trl.transforms._utils.SeededTransform`), so
    ``ParallelEnv.set_seed`` gives every worker its own context stream.

    Args:
        context_space: the space to sample from.
        sampler: optional ``sampler(n, generator[, previous=...]) -> [n, c]`` drawing full
            contexts inside ``context_space``.
        seed: seed of the transform's :class:`torch.Generator`.
        fixed: parameters held at a given value instead of sampled, e.g. ``{"wind_power": 0.0}``
            (these may lie outside the randomization range, but outside the declared bounds
            only with ``allow_extrapolation``).
        context_key: the key the base env reads contexts from.
        allow_extrapolation: accept ``fixed`` values outside the declared bounds (the base
            env must be built with ``allow_extrapolation=True`` too, or its reset rejects them).

    Example:
        >>> from torchrl.envs import TransformedEnv
        >>> from morl_trl.envs.toy import ToyContextEnv, TOY_CONTEXT
        >>> env = TransformedEnv(ToyContextEnv(num_envs=3), DomainRandomization(TOY_CONTEXT, seed=0))
        >>> ctx = env.reset()["context"]
        >>> ctx.shape, TOY_CONTEXT.contains(ctx)
        (torch.Size([3, 2]), True)
    """

    def __init__(
        self,
        context_space: ContextSpace,
        *,
        sampler: Sampler | None = None,
        seed: int | None = None,
        fixed: Mapping[str, float] | None = None,
        context_key: str = "context",
        allow_extrapolation: bool = False,
    ) -> None:
        super().__init__(in_keys=[], out_keys=[])
        self.context_sampler = ContextSampler(
            context_space, fixed=fixed, sampler=sampler, allow_extrapolation=allow_extrapolation
        )
        self.context_key = context_key
        self._checked_parent = False
        self._init_seed(seed)
        self.context_sampler.generator = self.generator  # one stream, seeded by SeededTransform's rules
        self.context_sampler._seed = self._seed

    @property
    def context_space(self) -> ContextSpace:
        return self.context_sampler.context_space

    @property
    def fixed(self) -> dict[str, float]:
        return self.context_sampler.fixed

    @property
    def sampler(self) -> Sampler | None:
        return self.context_sampler.sampler

    @sampler.setter
    def sampler(self, fn: Sampler | None) -> None:
        self.context_sampler.sampler = fn

    @property
    def _pass_previous(self) -> bool:
        return self.context_sampler.takes_previous

    def set_seed(self, seed: int) -> None:
        super().set_seed(seed)
        sampler = self.__dict__.get("context_sampler")
        if sampler is not None:
            sampler._seed = self._seed

    def clone(self):
        other = super().clone()  # (a shallow copy with a copy of the generator)
        sampler = other.context_sampler = copy.copy(self.context_sampler)
        sampler.generator = other.generator
        return other

    # ------------------------------------------------------------------ sampling
    def sample(self, n: int, previous: torch.Tensor | None = None) -> torch.Tensor:
        """Draw ``n`` validated contexts ``[n, c]`` (CPU); ``previous`` is passed on if the sampler takes it."""
        if self._seed is None:
            self.set_seed(int(torch.randint(0, 2**62, (1,)).item()))
        return self.context_sampler.draw(n, previous)

    # ------------------------------------------------------------------ env hooks
    def _check_parent(self, parent) -> None:
        spec = parent.full_state_spec.get(self.context_key, None) if parent.full_state_spec is not None else None
        if spec is None:
            raise ValueError(
                f"DomainRandomization writes contexts under {self.context_key!r}, but the env does not "
                f"read that key at reset (its state spec has {list(parent.full_state_spec.keys(True, True))})"
            )
        if spec.shape[-1] != self.context_space.dim:
            raise ValueError(
                f"the env's {self.context_key!r} has {spec.shape[-1]} entries; the context space has "
                f"{self.context_space.dim} ({list(self.context_space.names)})"
            )
        self._checked_parent = True

    def _current_contexts(self, tensordict: TensorDictBase, batch_size, device) -> torch.Tensor:
        shape = (*batch_size, self.context_space.dim)
        current = tensordict.get(self.context_key, None)
        if current is not None and current.shape == shape:
            return current.to(device=device, dtype=torch.float32)
        base = innermost_env(self.parent)
        if isinstance(base, ContextualMOEnv) and base.batch_size == batch_size:
            return base.context.to(device)
        return self.context_space.default_tensor(device).expand(shape)

    def _reset_env_preprocess(self, tensordict: TensorDictBase | None) -> TensorDictBase:
        parent = self.parent
        batch_size, device = parent.batch_size, parent.device
        if tensordict is None:
            tensordict = TensorDict(batch_size=batch_size, device=device)
        mask = reset_mask(tensordict, batch_size, device)
        current = self._current_contexts(tensordict, batch_size, device)
        context = current.clone()
        draws = self.draw(mask, current)
        if draws is not None:
            context[mask] = draws
        return tensordict.set(self.context_key, context)

    def draw(self, mask: torch.Tensor, current: torch.Tensor) -> torch.Tensor | None:
        """The new contexts ``[n, c]`` of the ``n`` sub-envs ``mask`` being reset (``None`` if
        none), given the current contexts ``[*B, c]``; what a reset writes into those rows."""
        parent = self.parent
        if not self._checked_parent:
            self._check_parent(parent)
        self._sync_seed()
        n = int(mask.sum())
        if not n:
            return None
        previous = current[mask] if self._pass_previous else None
        return self.sample(n, previous=previous).to(current.device)

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        return tensordict_reset

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict

    def __repr__(self) -> str:
        extra = f", fixed={self.fixed}" if self.fixed else ""
        sampler = f", sampler={getattr(self.sampler, '__name__', self.sampler)}" if self.sampler else ""
        return f"{type(self).__name__}({self.context_space!r}{sampler}{extra}, seed={self._seed})"
