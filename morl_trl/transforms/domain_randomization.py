"""Domain randomization: a new context for each sub-env at each of its resets."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs.transforms import Transform

from morl_trl.envs.context import ContextSpace

__all__ = ["DomainRandomization"]

Sampler = Callable[[int, torch.Generator], torch.Tensor]


class DomainRandomization(Transform):
    """Draws a fresh context for every sub-env being reset, before the base env resets.

    The context is written to the reset TensorDict under ``context_key``; the base env reads
    it (see :class:`~morl_trl.envs.base.ContextualMOEnv`). Sub-envs that are not being reset
    (``"_reset"`` false) keep theirs.

    Args:
        context_space: the space to sample from (uniform in its ranges by default).
        sampler: optional ``sampler(n, generator) -> [n, c]``; its output is checked against
            the space's ranges.
        seed: seed of the transform's own :class:`torch.Generator`.
        fixed: parameters held at a given value instead of sampled, e.g. ``{"wind_power": 0.0}``.
        context_key: the key the base env reads contexts from.

    Example:
        >>> from torchrl.envs import TransformedEnv
        >>> from morl_trl.envs import make_env, context_space
        >>> env = TransformedEnv(make_env("MOLunarLanderDefault-v0", num_envs=2),
        ...                      DomainRandomization(context_space("MOLunarLanderDR-v0"), seed=0))  # doctest: +SKIP
        >>> env.reset()["context"].shape                                                 # doctest: +SKIP
        torch.Size([2, 7])
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
        self.context_space = context_space
        self.sampler = sampler
        self.context_key = context_key
        self.fixed = {context_space.names[context_space.index(k)]: float(v) for k, v in (fixed or {}).items()}
        self.generator = torch.Generator()
        self.set_seed(seed)

    def set_seed(self, seed: int | None) -> None:
        """Re-seed the context sampler (``None``: from torch's global generator)."""
        if seed is None:
            seed = int(torch.randint(0, 2**31 - 1, (1,)).item())
        self.generator.manual_seed(int(seed))

    def sample(self, n: int) -> torch.Tensor:
        """Draw ``n`` validated contexts ``[n, c]`` on the CPU."""
        if self.sampler is None:
            ctx = self.context_space.sample(n, generator=self.generator)
        else:
            ctx = torch.as_tensor(self.sampler(n, self.generator), dtype=torch.float32)
            if ctx.shape != (n, self.context_space.dim):
                raise ValueError(
                    f"context sampler returned shape {tuple(ctx.shape)}; expected ({n}, {self.context_space.dim})"
                )
        for name, value in self.fixed.items():
            ctx[:, self.context_space.index(name)] = value
        # fixed values may legitimately sit outside the DR range; the sampled ones may not
        free = [i for i, nm in enumerate(self.context_space.names) if nm not in self.fixed]
        if self.sampler is not None and free:
            sub = ContextSpace(
                tuple(self.context_space.names[i] for i in free),
                tuple(self.context_space.default[i] for i in free),
                tuple(self.context_space.low[i] for i in free),
                tuple(self.context_space.high[i] for i in free),
            )
            sub.validate(ctx[:, free], check_range=True)
        return self.context_space.validate(ctx)

    def _reset_env_preprocess(self, tensordict: TensorDictBase | None) -> TensorDictBase:
        parent = self.parent
        batch_size = parent.batch_size
        device = parent.device
        if tensordict is None:
            tensordict = TensorDict(batch_size=batch_size, device=device)
        reset = tensordict.get("_reset", None)
        if reset is None:
            mask = torch.ones(batch_size, dtype=torch.bool, device=device)
        else:
            mask = reset.reshape(batch_size).to(torch.bool)
        n = int(mask.sum())
        current = tensordict.get(self.context_key, None)
        if current is None:
            base = parent.base_env
            current = getattr(base, "_context", None)
            if current is None:
                current = self.context_space.default_tensor().expand(*batch_size, self.context_space.dim)
        context = current.to(device=device, dtype=torch.float32).clone()
        if n:
            context[mask] = self.sample(n).to(device)
        return tensordict.set(self.context_key, context)

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        return tensordict_reset

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict
