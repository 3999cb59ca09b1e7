"""A TD(0) value estimator for vector (multi-objective) rewards.

TorchRL's :class:`~torchrl.objectives.value.TD0Estimator` requires ``reward``,
``next_value`` and ``terminated`` to share one shape, so a ``[*B, k]`` reward
against a ``[*B, 1]`` termination flag raises. :class:`VectorTD0Estimator`
broadcasts the flag over the objectives instead and never reduces them.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, dispatch
from torchrl.envs.utils import step_mdp
from torchrl.objectives.utils import hold_out_net
from torchrl.objectives.value import ValueEstimatorBase

__all__ = ["VectorTD0Estimator", "vector_td0_return_estimate"]


def _flag_like(flag: torch.Tensor, reward: torch.Tensor, name: str) -> torch.Tensor:
    """Returns a ``[*B, 1]`` boolean flag that broadcasts against a ``[*B, k]`` reward."""
    batch = reward.shape[:-1]
    if flag.shape == batch:
        flag = flag.unsqueeze(-1)
    if flag.shape[:-1] != batch or flag.shape[-1] != 1:
        raise ValueError(
            f"{name} has shape {tuple(flag.shape)}; with a reward of shape "
            f"{tuple(reward.shape)} it must be {tuple(batch)} or {tuple(batch) + (1,)}."
        )
    return flag.bool()


def vector_td0_return_estimate(
    gamma: float | torch.Tensor,
    next_state_value: torch.Tensor,
    reward: torch.Tensor,
    terminated: torch.Tensor,
) -> torch.Tensor:
    """One-step return ``r + gamma * (1 - terminated) * V(s')`` for vector rewards.

    Args:
        gamma: discount, a scalar or a tensor broadcasting to ``reward``.
        next_state_value: ``[*B, k]`` value of the next state, one entry per objective.
        reward: ``[*B, k]`` vector reward.
        terminated: ``[*B, 1]`` or ``[*B]`` termination flag (not ``done``: a
            truncated episode still bootstraps).

    Returns:
        The ``[*B, k]`` one-step target.

    Examples:
        >>> r = torch.tensor([[1.0, 2.0]])
        >>> v = torch.tensor([[10.0, 20.0]])
        >>> vector_td0_return_estimate(0.5, v, r, torch.tensor([[False]]))
        tensor([[ 6., 12.]])
    """
    if next_state_value.shape != reward.shape:
        raise ValueError(
            f"next_state_value has shape {tuple(next_state_value.shape)} but the reward has "
            f"shape {tuple(reward.shape)}; both must be [*B, k]."
        )
    not_terminated = (~_flag_like(terminated, reward, "terminated")).to(reward.dtype)
    return reward + gamma * not_terminated * next_state_value


class VectorTD0Estimator(ValueEstimatorBase):
    """TD(0) targets and advantages for ``[*B, k]`` vector rewards.

    It reads the reward, ``done`` and ``terminated`` flags under ``"next"`` like
    TorchRL's estimators and broadcasts the ``[*B, 1]`` flags over the ``k``
    objectives. The multi-objective losses of :mod:`morl_trl.objectives` build it
    from ``make_value_estimator(ValueEstimators.TD0, gamma=...)``.

    Keyword Args:
        gamma (float): discount factor.
        value_network (TensorDictModule, optional): a module writing the
            ``[*B, k]`` state value under the ``value`` key. Without one, the
            values are read from the input (``value`` and ``("next", value)``)
            or passed to :meth:`value_estimate` as ``next_value``.
        differentiable (bool): whether gradients flow through the target. Defaults to ``False``.
        skip_existing (bool, optional): see :class:`~torchrl.objectives.value.ValueEstimatorBase`.
        device (torch.device, optional): device of the ``gamma`` buffer.

    Examples:
        >>> from tensordict import TensorDict
        >>> est = VectorTD0Estimator(gamma=0.5)
        >>> td = TensorDict({
        ...     "state_value": torch.zeros(3, 2),
        ...     ("next", "state_value"): torch.ones(3, 2),
        ...     ("next", "reward"): torch.tensor([[1.0, 0.0], [0.0, 1.0], [2.0, 2.0]]),
        ...     ("next", "done"): torch.tensor([[False], [True], [False]]),
        ...     ("next", "terminated"): torch.tensor([[False], [True], [False]]),
        ... }, [3])
        >>> est(td)["value_target"]
        tensor([[1.5000, 0.5000],
                [0.0000, 1.0000],
                [2.5000, 2.5000]])
    """

    def __init__(
        self,
        *,
        gamma: float | torch.Tensor,
        value_network: TensorDictModule | None = None,
        differentiable: bool = False,
        skip_existing: bool | None = None,
        device: torch.device | None = None,
        **kwargs,
    ) -> None:
        # ``kwargs`` swallows the estimator options TorchRL's loss plumbing may
        # forward (``deactivate_vmap``, ...) that have no meaning here.
        unknown = set(kwargs) - {"deactivate_vmap", "shifted", "average_rewards"}
        if unknown:
            raise TypeError(f"VectorTD0Estimator got unexpected arguments {sorted(unknown)}.")
        if kwargs.get("shifted") or kwargs.get("average_rewards"):
            raise ValueError("VectorTD0Estimator supports neither shifted=True nor average_rewards=True.")
        super().__init__(
            value_network=value_network,
            differentiable=differentiable,
            skip_existing=skip_existing,
            device=device,
        )
        self.register_buffer("gamma", torch.as_tensor(gamma, dtype=torch.float32, device=device))

    @dispatch
    def forward(
        self,
        tensordict: TensorDictBase,
        *,
        params: TensorDictBase | None = None,
        target_params: TensorDictBase | None = None,
    ) -> TensorDictBase:
        """Writes ``value_target`` and ``advantage`` (both ``[*B, k]``) into ``tensordict``."""
        with torch.set_grad_enabled(self.differentiable):
            if self.value_network is not None:
                td = tensordict.select(*self.value_network.in_keys, strict=False)
                ctx = params.to_module(self.value_network, preserve_module_state=False) if params is not None else hold_out_net(self.value_network)
                with ctx:
                    value = self.value_network(td).get(self.tensor_keys.value)
            else:
                value = tensordict.get(self.tensor_keys.value)
            value_target = self.value_estimate(tensordict, target_params=target_params)
        tensordict.set(self.tensor_keys.advantage, value_target - value)
        tensordict.set(self.tensor_keys.value_target, value_target)
        return tensordict

    def value_estimate(
        self,
        tensordict: TensorDictBase,
        target_params: TensorDictBase | None = None,
        next_value: torch.Tensor | None = None,
        **kwargs,
    ) -> torch.Tensor:
        """The ``[*B, k]`` one-step target; ``next_value`` overrides the value network."""
        reward = tensordict.get(("next", self.tensor_keys.reward))
        gamma = self.gamma.to(reward.device)
        steps = tensordict.get(self.tensor_keys.steps_to_next_obs, None)
        if steps is not None:
            gamma = gamma ** _flag_shape(steps, reward).to(reward.dtype)
        if next_value is None:
            if self.value_network is not None:
                step_td = step_mdp(tensordict, keep_other=False)
                ctx = (
                    target_params.to_module(self.value_network, preserve_module_state=False)
                    if target_params is not None
                    else hold_out_net(self.value_network)
                )
                with ctx:
                    next_value = self.value_network(step_td).get(self.tensor_keys.value)
            else:
                next_value = tensordict.get(("next", self.tensor_keys.value))
        done = tensordict.get(("next", self.tensor_keys.done))
        terminated = tensordict.get(("next", self.tensor_keys.terminated), default=done)
        return vector_td0_return_estimate(gamma, next_value, reward, terminated)


def _flag_shape(x: torch.Tensor, reward: torch.Tensor) -> torch.Tensor:
    return x.unsqueeze(-1) if x.shape == reward.shape[:-1] else x
