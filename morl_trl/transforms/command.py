"""Return-and-horizon commands (Pareto Conditioned Networks): what a PCN policy is conditioned on."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.data import Composite, Unbounded
from torchrl.envs.transforms import Transform

from morl_trl.transforms._utils import reset_mask

__all__ = ["DesiredReturnConditioning"]


class DesiredReturnConditioning(Transform):
    """Writes a desired return ``[*B, k]`` and a desired horizon ``[*B, 1]`` per sub-env and
    updates them as the episode goes, as PCN's authors (Reymond et al. 2022; MORL-Baselines'
    ``PCN._run_episode``) do.

    At each reset a sub-env takes the current command (:meth:`set_command`; the same for
    every episode until it is changed, as the authors run ``num_step_episodes`` episodes per
    command). After each step with vector reward ``r``:
    ``desired_return = min(desired_return - r, max_return)`` and
    ``desired_horizon = max(desired_horizon - 1, 1)``. The values live in the TensorDict and
    in the observation and state specs (like :class:`DiscountedVectorReturn`), so the
    collector stores, for every transition, the command the action was chosen with.

    Args:
        num_objectives: ``k``.
        max_return: the upper clip of the desired return, a float or ``[k]`` (the authors'
            default: 100 per objective).
        return_key, horizon_key: output keys.

    Example:
        >>> import torch
        >>> from torchrl.envs import TransformedEnv
        >>> from morl_trl.envs.toy import ToyContextEnv
        >>> t = DesiredReturnConditioning(2, max_return=[5.0, 5.0])
        >>> t.set_command(torch.tensor([3.0, 1.0]), 4.0)
        >>> env = TransformedEnv(ToyContextEnv(num_envs=1), t)
        >>> td = env.rollout(2, lambda td: td.set("action", torch.tensor([1])))
        >>> td["desired_return"][0], td["desired_horizon"][0, :, 0]   # rewards [1, -1] per step
        (tensor([[3., 1.],
                [2., 2.]]), tensor([4., 3.]))
    """

    def __init__(self, num_objectives: int, *, max_return=100.0, return_key: str = "desired_return",
                 horizon_key: str = "desired_horizon") -> None:
        if isinstance(num_objectives, bool) or not isinstance(num_objectives, int) or num_objectives < 1:
            raise ValueError(f"num_objectives must be a positive int, got {num_objectives!r}")
        super().__init__(in_keys=["reward"], out_keys=[return_key, horizon_key])
        k = num_objectives
        mr = torch.as_tensor(max_return, dtype=torch.float32).flatten()
        if mr.numel() == 1:
            mr = mr.expand(k).clone()
        if mr.numel() != k or not torch.isfinite(mr).all():
            raise ValueError(f"max_return must be a finite float or {k} floats, got {max_return!r}")
        self.num_objectives = k
        self.return_key, self.horizon_key = return_key, horizon_key
        self.register_buffer("max_return", mr)
        self.register_buffer("command_return", torch.zeros(k))
        self.register_buffer("command_horizon", torch.ones(1))

    def set_command(self, desired_return, desired_horizon) -> None:
        """The command the next episodes start with."""
        r = torch.as_tensor(desired_return, dtype=torch.float32).flatten()
        if r.numel() != self.num_objectives or not torch.isfinite(r).all():
            raise ValueError(f"desired_return must be {self.num_objectives} finite floats, got {desired_return!r}")
        h = float(desired_horizon)
        self.command_return.copy_(r)
        self.command_horizon.fill_(h)

    def _specs(self, batch, device) -> dict:
        k = self.num_objectives
        return {self.return_key: Unbounded(shape=(*batch, k), device=device),
                self.horizon_key: Unbounded(shape=(*batch, 1), device=device)}

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        for key, spec in self._specs(observation_spec.shape, observation_spec.device).items():
            observation_spec[key] = spec
        return observation_spec

    def transform_input_spec(self, input_spec: Composite) -> Composite:
        state = input_spec["full_state_spec"]
        if state is None:
            state = Composite(shape=input_spec.shape, device=input_spec.device)
        for key, spec in self._specs(input_spec.shape, input_spec.device).items():
            state[key] = spec
        input_spec["full_state_spec"] = state
        return input_spec

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        batch, device = tensordict_reset.batch_size, tensordict_reset.device
        fresh = reset_mask(tensordict, batch, device).unsqueeze(-1)
        new_r = self.command_return.to(device).expand(*batch, self.num_objectives)
        new_h = self.command_horizon.to(device).expand(*batch, 1)
        for key, new in ((self.return_key, new_r), (self.horizon_key, new_h)):
            old = tensordict.get(key, None) if tensordict is not None else None
            value = new.clone() if old is None or old.shape != new.shape else torch.where(fresh, new, old)
            tensordict_reset.set(key, value)
        return tensordict_reset

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        reward = next_tensordict.get(self.in_keys[0]).to(torch.float32)
        desired = tensordict.get(self.return_key)
        horizon = tensordict.get(self.horizon_key)
        next_tensordict.set(self.return_key, torch.minimum(desired - reward, self.max_return.to(reward.device)))
        next_tensordict.set(self.horizon_key, (horizon - 1).clamp_min(1.0))
        return next_tensordict

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        raise NotImplementedError("DesiredReturnConditioning updates online: use it inside a TransformedEnv")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(num_objectives={self.num_objectives}, max_return={self.max_return.tolist()})"
