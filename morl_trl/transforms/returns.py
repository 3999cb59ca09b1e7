"""The running discounted and undiscounted vector return of each sub-env's episode."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.data import Bounded, Composite, Unbounded
from torchrl.envs.transforms import Transform

from morl_trl.transforms._utils import reset_mask

__all__ = ["DiscountedVectorReturn"]


class DiscountedVectorReturn(Transform):
    """Accumulates ``sum_t r_t`` and ``sum_t gamma^t r_t`` per objective over the running episode.

    Like TorchRL's ``RewardSum`` (whose pattern it follows: the running values live in the
    TensorDict, in the observation and state specs), but for vector rewards and with the
    discounted sum the paper's fronts are made of. After each step,
    ``("next", return_key)`` and ``("next", discounted_key)`` ``[*B, k]`` hold the returns of
    the episode so far; at the step where a sub-env is done they are its episode returns.
    A reset zeroes them for the sub-envs being reset only. ``discount_key`` ``[*B, 1]`` holds
    ``gamma^t``, the factor of the next reward.

    Args:
        gamma: the discount, in ``[0, 1]`` (the paper: 0.99, 0.995 for MO-LavaGrid).
        in_key: the vector reward.
        return_key, discounted_key, discount_key: output keys.
        dtype: of the running sums (default: the reward's); ``torch.float64`` keeps long
            episodes' sums exact to float32 rewards (the evaluator uses it).

    Example:
        >>> import torch
        >>> from torchrl.envs import TransformedEnv
        >>> from morl_trl.envs.toy import ToyContextEnv
        >>> env = TransformedEnv(ToyContextEnv(num_envs=1), DiscountedVectorReturn(gamma=0.5))
        >>> td = env.rollout(2, lambda td: td.set("action", torch.tensor([1])))
        >>> td["next", "episode_discounted_return"][:, -1]   # [1 + 0.5 * 1, -1 - 0.5]
        tensor([[ 1.5000, -1.5000]])
    """

    def __init__(
        self,
        gamma: float = 0.99,
        *,
        in_key: str = "reward",
        return_key: str = "episode_return",
        discounted_key: str = "episode_discounted_return",
        discount_key: str = "episode_discount",
        dtype: torch.dtype | None = None,
    ) -> None:
        try:
            ok = 0.0 <= float(gamma) <= 1.0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"gamma must be a number in [0, 1], got {gamma!r}")
        super().__init__(in_keys=[in_key], out_keys=[return_key, discounted_key, discount_key])
        self.gamma = float(gamma)
        self.return_key = return_key
        self.discounted_key = discounted_key
        self.discount_key = discount_key
        if dtype is not None and not (isinstance(dtype, torch.dtype) and dtype.is_floating_point):
            raise ValueError(f"dtype must be a floating point torch.dtype, got {dtype!r}")
        self.dtype = dtype

    @property
    def in_key(self):
        return self.in_keys[0]

    def _reward_spec(self):
        parent = self.parent
        return parent.full_reward_spec[self.in_key]

    def _reward_shape_dtype(self) -> tuple[torch.Size, torch.dtype]:
        """The reward spec's shape and dtype, remembered from the last spec transform (reading
        ``self.parent`` walks the env stack, a large share of a partial reset's cost)."""
        cached = self.__dict__.get("_reward_shape_dtype_cache")
        if cached is None:
            spec = self._reward_spec()
            cached = self.__dict__["_reward_shape_dtype_cache"] = (spec.shape, spec.dtype)
        return cached

    def _specs(self) -> dict:
        r = self._reward_spec()
        self.__dict__["_reward_shape_dtype_cache"] = (r.shape, r.dtype)
        batch = r.shape[:-1]
        dtype = self.dtype or r.dtype
        vec = Unbounded(shape=r.shape, dtype=dtype, device=r.device)
        disc = Bounded(0.0, 1.0, shape=(*batch, 1), dtype=dtype, device=r.device)
        return {self.return_key: vec, self.discounted_key: vec.clone(), self.discount_key: disc}

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        for key, spec in self._specs().items():
            observation_spec[key] = spec
        return observation_spec

    def transform_input_spec(self, input_spec: Composite) -> Composite:
        state = input_spec["full_state_spec"]
        if state is None:
            state = Composite(shape=input_spec.shape, device=input_spec.device)
        for key, spec in self._specs().items():
            state[key] = spec
        input_spec["full_state_spec"] = state
        return input_spec

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        batch, device = tensordict_reset.batch_size, tensordict_reset.device
        shape, spec_dtype = self._reward_shape_dtype()
        keep = ~reset_mask(tensordict, batch, device).unsqueeze(-1)
        dtype = self.dtype or spec_dtype
        zeros = torch.zeros(shape, dtype=dtype, device=device)
        ones = torch.ones(*batch, 1, dtype=dtype, device=device)
        for key, fresh in ((self.return_key, zeros), (self.discounted_key, zeros), (self.discount_key, ones)):
            old = tensordict.get(key, None)
            value = fresh if old is None or old.shape != fresh.shape else torch.where(keep, old, fresh)
            tensordict_reset.set(key, value)
        return tensordict_reset

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        reward = next_tensordict.get(self.in_key)
        if self.dtype is not None:
            reward = reward.to(self.dtype)
        ret = tensordict.get(self.return_key, None)
        disc_ret = tensordict.get(self.discounted_key, None)
        discount = tensordict.get(self.discount_key, None)
        if ret is None:
            ret = torch.zeros_like(reward)
        if disc_ret is None:
            disc_ret = torch.zeros_like(reward)
        if discount is None:
            discount = torch.ones_like(reward[..., :1])
        next_tensordict.set(self.return_key, ret + reward)
        next_tensordict.set(self.discounted_key, disc_ret + discount * reward)
        next_tensordict.set(self.discount_key, discount * self.gamma)
        return next_tensordict

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        raise NotImplementedError(
            "DiscountedVectorReturn accumulates online: use it inside a TransformedEnv"
        )

    def __repr__(self) -> str:
        return f"{type(self).__name__}(gamma={self.gamma}, in_key={self.in_key!r})"
