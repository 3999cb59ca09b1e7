"""The fully observable context setting: the context appended to the observation."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.data import Composite, Unbounded
from torchrl.envs.transforms import Transform

from morl_trl.envs.context import ContextSpace
from morl_trl.transforms._utils import innermost_env

__all__ = ["ContextObservation"]

_NORMALIZE = (None, "unit", "symmetric")


class ContextObservation(Transform):
    """Appends the context to the observation: ``[obs, c]`` (paper §3, "fully observable context").

    With ``normalize="unit"`` each context parameter is mapped from its randomization range
    ``[low, high]`` to ``[0, 1]``, with ``"symmetric"`` to ``[-1, 1]`` (a parameter with
    ``low == high`` maps to the middle). Contexts outside the range (some evaluation
    contexts lie outside it) map outside ``[0, 1]``; nothing is clipped.

    Keys: reads ``in_key`` and ``context_key``, writes ``out_key`` (default: ``in_key``, i.e. the
    observation is replaced by ``[obs, c]``). ``in_key=None`` writes the (normalized) context
    alone. Works at reset and step (stateless), and offline on stored data (``forward``
    transforms the root and ``"next"``).

    Args:
        context_space: gives the ranges for ``normalize``; taken from the env when omitted.
        normalize: ``None``, ``"unit"`` or ``"symmetric"``.
        in_key, out_key, context_key: see above.

    Example:
        >>> from torchrl.envs import TransformedEnv
        >>> from morl_trl.envs.toy import ToyContextEnv
        >>> env = TransformedEnv(ToyContextEnv(num_envs=1), ContextObservation(normalize="unit"))
        >>> env.reset()["observation"]          # [position, time, speed 1 in [0.5, 2], bias 0 in [-1, 1]]
        tensor([[0.0000, 0.0000, 0.3333, 0.5000]])
    """

    def __init__(
        self,
        context_space: ContextSpace | None = None,
        *,
        normalize: str | None = None,
        in_key: str | None = "observation",
        out_key: str | None = None,
        context_key: str = "context",
    ) -> None:
        if normalize not in _NORMALIZE:
            raise ValueError(f"normalize must be one of {_NORMALIZE}, got {normalize!r}")
        if out_key is None:
            if in_key is None:
                raise ValueError("ContextObservation(in_key=None) needs an out_key for the context")
            out_key = in_key
        in_keys = [context_key] if in_key is None else [in_key, context_key]
        super().__init__(in_keys=in_keys, out_keys=[out_key])
        self.context_space = context_space
        self.normalize = normalize
        self.obs_key = in_key
        self.context_key = context_key
        self._scale: tuple[torch.Tensor, torch.Tensor] | None = None

    @property
    def out_key(self):
        return self.out_keys[0]

    def _space(self) -> ContextSpace:
        if self.context_space is None:
            base = innermost_env(self.parent)
            space = base.__dict__.get("context_space") if base is not None else None
            if not isinstance(space, ContextSpace):
                raise ValueError(
                    "ContextObservation(normalize=...) needs the context ranges: pass context_space= "
                    "(the env underneath has no context_space attribute)"
                )
            self.context_space = space
        return self.context_space

    def _normalized(self, ctx: torch.Tensor) -> torch.Tensor:
        ctx = ctx.to(torch.float32)
        if self.normalize is None:
            return ctx
        if self._scale is None or self._scale[0].device != ctx.device:
            lo, hi = self._space().bounds(ctx.device)
            width = hi - lo
            self._scale = (lo, torch.where(width > 0, 1.0 / width.clamp(min=1e-30), torch.zeros_like(width)))
        lo, inv = self._scale
        u = torch.where(inv > 0, (ctx - lo) * inv, torch.full_like(ctx, 0.5))
        return u if self.normalize == "unit" else 2 * u - 1

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        ctx = next_tensordict.get(self.context_key)
        out = self._normalized(ctx)
        if self.obs_key is not None:
            obs = next_tensordict.get(self.obs_key)
            out = torch.cat([obs.to(out.dtype), out], -1)
        next_tensordict.set(self.out_key, out)
        return next_tensordict

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        return self._call(tensordict_reset)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        self._call(tensordict)
        nxt = tensordict.get("next", None)
        if nxt is not None and all(k in nxt.keys() for k in self.in_keys):
            self._call(nxt)
        return tensordict

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        ctx_spec = observation_spec[self.context_key]
        c = ctx_spec.shape[-1]
        if self.context_space is not None and self.context_space.dim != c:
            raise ValueError(
                f"the env's {self.context_key!r} has {c} entries; the context space has "
                f"{self.context_space.dim} ({list(self.context_space.names)})"
            )
        batch = ctx_spec.shape[:-1]
        width = c
        if self.obs_key is not None:
            obs_spec = observation_spec[self.obs_key]
            if obs_spec.shape[:-1] != batch:
                raise ValueError(
                    f"ContextObservation appends to flat observations; {self.obs_key!r} has shape "
                    f"{tuple(obs_spec.shape)} and {self.context_key!r} {tuple(ctx_spec.shape)}"
                )
            width += obs_spec.shape[-1]
        observation_spec[self.out_key] = Unbounded(shape=(*batch, width), dtype=torch.float32, device=ctx_spec.device)
        return observation_spec

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(in_key={self.obs_key!r}, context_key={self.context_key!r}, "
            f"out_key={self.out_key!r}, normalize={self.normalize!r})"
        )
