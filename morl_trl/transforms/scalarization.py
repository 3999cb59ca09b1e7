"""Linear scalarization of the vector reward: ``w . r`` with fixed or per-episode weights."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.data import Bounded, Composite, Unbounded
from torchrl.envs.transforms import Transform

from morl_trl.transforms._utils import fmt

__all__ = ["LinearScalarization"]


class LinearScalarization(Transform):
    """Writes the scalar reward ``w . r`` ``[*B, 1]`` next to (or instead of) the vector reward.

    ``w`` is either fixed (``weights=[...]``) or read, per sub-env, from ``preference_key``
    (written by :class:`PreferenceConditioning`): unlike TorchRL's ``LineariseRewards``, the
    weights may change from episode to episode.

    Keys: by default the scalar goes to ``("next", "scalar_reward")``, registered as a second
    reward in the reward spec, and the vector ``"reward"`` is kept: single-objective losses
    read it with ``loss.set_keys(reward="scalar_reward")`` while evaluators still see every
    objective. ``out_key="reward"`` replaces the vector reward instead (its spec becomes
    ``[*B, 1]``). Used offline (``forward``, e.g. as a replay-buffer transform after
    relabelling preferences), it recomputes ``("next", out_key)`` from ``("next", in_key)``
    and the stored preference.

    Args:
        weights: fixed weights ``[k]``; ``None`` reads ``preference_key``.
        in_key: the vector reward.
        out_key: the scalar reward.
        preference_key: where per-episode weights are read.

    Example:
        >>> import torch
        >>> from torchrl.envs import TransformedEnv
        >>> from morl_trl.envs.toy import ToyContextEnv
        >>> env = TransformedEnv(ToyContextEnv(num_envs=1), LinearScalarization([0.25, 0.75]))
        >>> td = env.step(env.reset().set("action", torch.tensor([1])))
        >>> td["next", "reward"], td["next", "scalar_reward"]   # reward [speed*1 + bias, -1]
        (tensor([[ 1., -1.]]), tensor([[-0.5000]]))
    """

    def __init__(
        self,
        weights=None,
        *,
        in_key: str = "reward",
        out_key: str = "scalar_reward",
        preference_key: str = "preference",
    ) -> None:
        super().__init__(in_keys=[in_key], out_keys=[out_key])
        if weights is not None:
            weights = torch.as_tensor(weights, dtype=torch.float32)
            if weights.ndim != 1 or weights.numel() == 0 or not torch.isfinite(weights).all():
                raise ValueError(f"weights must be a finite [k] vector, got {fmt(weights)}")
        self.weights = weights
        self.preference_key = preference_key

    @property
    def in_key(self):
        return self.in_keys[0]

    @property
    def out_key(self):
        return self.out_keys[0]

    def _scalarize(self, reward: torch.Tensor, w: torch.Tensor | None) -> torch.Tensor:
        if w is None:
            raise KeyError(
                f"LinearScalarization found no {self.preference_key!r} in the TensorDict: put a "
                "PreferenceConditioning transform before it, or pass fixed weights="
            )
        if w.shape[-1] != reward.shape[-1]:
            raise ValueError(
                f"{reward.shape[-1]} objectives in {self.in_key!r} but {w.shape[-1]} weights"
            )
        return (w.to(reward.dtype) * reward).sum(-1, keepdim=True)

    def _weights(self, *tds: TensorDictBase) -> torch.Tensor | None:
        if self.weights is not None:
            return self.weights
        for td in tds:
            w = td.get(self.preference_key, None) if td is not None else None
            if w is not None:
                return w
        return None

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        reward = next_tensordict.get(self.in_key)
        w = self._weights(next_tensordict, tensordict)
        if self.weights is not None and self.weights.device != reward.device:
            self.weights = self.weights.to(reward.device)
            w = self.weights
        next_tensordict.set(self.out_key, self._scalarize(reward, w))
        return next_tensordict

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        nxt = tensordict.get("next", None)
        if nxt is not None and self.in_key in nxt.keys():
            reward = nxt.get(self.in_key)
            nxt.set(self.out_key, self._scalarize(reward, self._weights(tensordict, nxt)))
        else:
            reward = tensordict.get(self.in_key)
            tensordict.set(self.out_key, self._scalarize(reward, self._weights(tensordict)))
        return tensordict

    def transform_reward_spec(self, reward_spec: Composite) -> Composite:
        spec = reward_spec[self.in_key]
        batch, k = spec.shape[:-1], spec.shape[-1]
        if self.weights is not None and self.weights.numel() != k:
            raise ValueError(f"{k} objectives in {self.in_key!r} but {self.weights.numel()} weights: "
                             f"{fmt(self.weights)}")
        if isinstance(spec, Bounded):
            low, high = spec.space.low.expand(spec.shape), spec.space.high.expand(spec.shape)
            if self.weights is not None:
                w = self.weights.to(low.device, low.dtype)
                lo = (w.clamp(min=0) * low + w.clamp(max=0) * high).sum(-1, keepdim=True)
                hi = (w.clamp(min=0) * high + w.clamp(max=0) * low).sum(-1, keepdim=True)
            else:  # w on the simplex: a convex combination
                lo, hi = low.min(-1, keepdim=True).values, high.max(-1, keepdim=True).values
            out = Bounded(low=lo, high=hi, shape=(*batch, 1), dtype=spec.dtype, device=spec.device)
        else:
            out = Unbounded(shape=(*batch, 1), dtype=spec.dtype, device=spec.device)
        reward_spec[self.out_key] = out
        return reward_spec

    def __repr__(self) -> str:
        w = self.weights.tolist() if self.weights is not None else repr(self.preference_key)
        return f"{type(self).__name__}(weights={w}, in_key={self.in_key!r}, out_key={self.out_key!r})"
