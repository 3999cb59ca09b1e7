"""Domain randomization: a new context for each sub-env at each of its resets."""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import TransformedEnv
from torchrl.envs.transforms import Transform

from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.context import ContextSpace
from morl_trl.transforms._utils import SeededTransform, innermost_env, reset_mask

__all__ = ["DomainRandomization", "DomainRandomizedEnv"]

Sampler = Callable[..., torch.Tensor]


def _accepts_previous(fn: Callable) -> bool:
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return False
    return any(p.name == "previous" or p.kind is p.VAR_KEYWORD for p in params)


class DomainRandomization(SeededTransform):
    """Draws a fresh context for every sub-env being reset, before the base env resets.

    The context is written to the reset TensorDict under ``context_key``, which the base env
    reads (see :class:`~morl_trl.envs.base.ContextualMOEnv`); sub-envs that are not being reset
    (``"_reset"`` false) keep theirs. ``make_env`` of a ``*DR-*`` id returns the fixed env
    wrapped in this transform. It works inside and outside ``SerialEnv``/``ParallelEnv``.

    Contexts come from ``context_space.sample`` (independent uniform in the ranges; domains
    with procedural contexts override it), or from ``sampler``. When the sampling function
    takes a ``previous`` keyword, it receives the current contexts ``[n, c]`` of the sub-envs
    being reset. Every draw is checked with ``context_space.validate(..., check_range=True)``
    before ``fixed`` parameters are written over it, so a sampler returning values outside the
    space raises a ``ValueError`` (naming the parameter and value) and nothing is reset.

    Seeding: ``seed`` seeds the transform's own generator; without it, the generator follows
    the env's seed (see :class:`~morl_trl.transforms._utils.SeededTransform`), so
    ``ParallelEnv.set_seed`` gives every worker its own context stream.

    Args:
        context_space: the space to sample from.
        sampler: optional ``sampler(n, generator[, previous=...]) -> [n, c]`` drawing full
            contexts inside ``context_space``.
        seed: seed of the transform's :class:`torch.Generator`.
        fixed: parameters held at a given value instead of sampled, e.g. ``{"wind_power": 0.0}``
            (these may lie outside the randomization range).
        context_key: the key the base env reads contexts from.

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
    ) -> None:
        super().__init__(in_keys=[], out_keys=[])
        if not isinstance(context_space, ContextSpace):
            raise ValueError(f"context_space must be a ContextSpace, got {type(context_space).__name__}")
        if sampler is not None and not callable(sampler):
            raise ValueError(f"sampler must be callable sampler(n, generator) -> [n, c], got {sampler!r}")
        self.context_space = context_space
        self.sampler = sampler
        self.context_key = context_key
        self.fixed = {context_space.names[context_space.index(k)]: float(v) for k, v in (fixed or {}).items()}
        context_space.make(self.fixed)  # NaN / non-positive fixed values fail here, not at the first reset
        self._fixed_idx = torch.tensor([context_space.index(k) for k in self.fixed], dtype=torch.long)
        self._fixed_val = torch.tensor(list(self.fixed.values()), dtype=torch.float32)
        fn = sampler if sampler is not None else context_space.sample
        self._pass_previous = _accepts_previous(fn)
        # ContextSpace.sample draws inside the ranges by construction; custom draws are checked
        self._check_draws = sampler is not None or type(context_space).sample is not ContextSpace.sample
        self._checked_parent = False
        self._init_seed(seed)

    # ------------------------------------------------------------------ sampling
    def sample(self, n: int, previous: torch.Tensor | None = None) -> torch.Tensor:
        """Draw ``n`` validated contexts ``[n, c]`` (CPU); ``previous`` is passed on if the sampler takes it."""
        space = self.context_space
        kwargs = {}
        if self._pass_previous:
            if previous is None:
                previous = space.default_tensor().expand(n, space.dim)
            kwargs["previous"] = previous.detach().to("cpu", torch.float32)
        if self.sampler is None:
            ctx = space.sample(n, generator=self.generator, **kwargs)
        else:
            ctx = self.sampler(n, self.generator, **kwargs)
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
            space.validate(ctx)
        return ctx

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


class DomainRandomizedEnv(TransformedEnv):
    """``TransformedEnv(env, DomainRandomization(...))`` whose auto-resets skip TorchRL's
    per-call bookkeeping: what ``make_env`` returns for a ``*DR-*`` id.

    While the transform is a lone :class:`DomainRandomization` over a
    :class:`~morl_trl.envs.base.ContextualMOEnv`, ``step_and_maybe_reset`` (what collectors
    call) takes the env's lean path, with the reset contexts drawn by the transform exactly
    as in a reset: the same TensorDicts as TorchRL's generic path, at a fraction of its cost
    per call. With more transforms (``append_transform``) it is a plain ``TransformedEnv``.

    Example:
        >>> from morl_trl.envs.toy import ToyContextEnv, TOY_CONTEXT
        >>> env = DomainRandomizedEnv(ToyContextEnv(num_envs=2), DomainRandomization(TOY_CONTEXT, seed=0))
        >>> td = env.reset().set("action", torch.ones(2, dtype=torch.long))
        >>> out, td = env.step_and_maybe_reset(td)
        >>> out["next", "reward"].shape, TOY_CONTEXT.contains(td["context"])
        (torch.Size([2, 2]), True)
    """

    def _step_and_maybe_reset(self, tensordict: TensorDictBase) -> tuple[TensorDictBase, TensorDictBase]:
        transform = self.transform
        lean = self.__dict__.get("_lean_base")
        if lean is None or lean[0] is not transform:  # (re)checked whenever the transform changes
            lean = self.__dict__["_lean_base"] = (transform, self._lean_base_env(transform))
        base = lean[1]
        if (
            base is not None
            and not self.run_type_checks
            and not self.__dict__.get("_torchrl_native_autoreset", False)
            and base._lean_step_applies(tensordict)
        ):
            return base._lean_step_and_maybe_reset(tensordict, draw_contexts=self._draw_contexts)
        return super()._step_and_maybe_reset(tensordict)

    def _lean_base_env(self, transform) -> ContextualMOEnv | None:
        """The base env when its lean path applies with ``transform`` alone, else ``None``."""
        base = self.base_env
        if (
            type(transform) is DomainRandomization
            and transform.context_key == "context"
            and isinstance(base, ContextualMOEnv)
            and type(transform)._post_step_mdp_hooks is Transform._post_step_mdp_hooks
        ):
            return base
        return None

    def _draw_contexts(self, mask: torch.Tensor) -> torch.Tensor | None:
        transform, base = self.__dict__["_lean_base"]
        return transform.draw(mask, base._context)
