"""PGMORL's building blocks (Xu et al. 2020): a population of PPO agents as ONE batched module,
and the vector GAE its scalarized PPO loss needs.

The authors (MORL-Baselines ``single_policy/ser/mo_ppo.py``) train each member with PPO whose critic predicts a
vector value ``V(s) [k]``; GAE runs per objective and the advantage is scalarized with the member's weight, ``A =
A_vec . w``, before TorchRL's :class:`ClipPPOLoss` (which takes a scalar advantage) sees it.

* :func:`ppo_population_mlp`: ``P`` independent MLPs (a :class:`~morl_trl.objectives.batched.BatchedMLP`:
  tanh, orthogonal init with gains sqrt(2) and the output's: 1 for the critic, 0.01 for the actor
  mean, as the authors) evaluated with one batched matmul per layer; inputs ``[P * B, in]``
  (member-major) or ``[P, B, in]``.
* :func:`make_population_ppo_actor` / :func:`make_population_value_network`: TorchRL's
  ``ProbabilisticActor`` (``IndependentNormal`` with a state-independent log-std per member,
  initialised at 0: :class:`PPOGaussianHead`) and ``ValueOperator`` (``state_value [..., k]``) on them.
* :func:`vector_gae`: TorchRL's ``generalized_advantage_estimate`` per objective.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.modules import IndependentNormal, ProbabilisticActor, ValueOperator
from torchrl.objectives.value.functional import generalized_advantage_estimate

from morl_trl.objectives.batched import BatchedMLP

__all__ = ["PPOGaussianHead", "ppo_population_mlp", "make_population_ppo_actor", "make_population_value_network",
           "vector_gae", "scalarize_advantage"]


class PPOGaussianHead(nn.Module):
    """``obs -> (loc, scale)``: the population's mean :class:`BatchedMLP` and a state-independent
    log-std per member and action dim (initialised at 0, as the authors).

    Example:
        >>> head = PPOGaussianHead(BatchedMLP(2, 3, 1, num_cells=(8,)), action_dim=1)
        >>> loc, scale = head(torch.zeros(2 * 4, 3))
        >>> loc.shape, scale.tolist()[0]
        (torch.Size([8, 1]), [1.0])
    """

    def __init__(self, mean: BatchedMLP, action_dim: int) -> None:
        super().__init__()
        self.mean = mean
        self.log_std = nn.Parameter(torch.zeros(mean.members, 1, action_dim))

    def forward(self, obs: torch.Tensor):
        loc = self.mean(obs)
        per_member = loc.reshape(self.mean.members, -1, loc.shape[-1])
        return loc, self.log_std.exp().expand_as(per_member).reshape(loc.shape)

    member_state = BatchedMLP.member_state
    load_member_state = BatchedMLP.load_member_state


def ppo_population_mlp(population: int, in_features: int, out_features: int, num_cells: Sequence[int] = (64, 64),
                       *, out_gain: float = 1.0) -> BatchedMLP:
    """``P`` PPO MLPs as the authors' MO-PPO: tanh, orthogonal init with gain sqrt(2) on the hidden
    layers and ``out_gain`` on the output (1 for the critic, 0.01 for the actor mean), zero biases.

    Example:
        >>> net = ppo_population_mlp(3, in_features=4, out_features=2, num_cells=(8,))
        >>> net(torch.zeros(3 * 5, 4)).shape, net(torch.zeros(3, 5, 4)).shape
        (torch.Size([15, 2]), torch.Size([3, 5, 2]))
    """
    return BatchedMLP(population, in_features, out_features, num_cells=num_cells, activation=nn.Tanh,
                      init="orthogonal", gain=math.sqrt(2), out_gain=out_gain)


def make_population_ppo_actor(population: int, obs_dim: int, action_dim: int, num_cells: Sequence[int] = (64, 64)):
    """The population's Gaussian policy as TorchRL's ``ProbabilisticActor`` (writes ``action`` and its log-prob).

    Example:
        >>> from tensordict import TensorDict
        >>> actor = make_population_ppo_actor(2, obs_dim=3, action_dim=1, num_cells=(8,))
        >>> actor(TensorDict({"observation": torch.zeros(2 * 4, 3)}, [8]))["action"].shape
        torch.Size([8, 1])
    """
    head = PPOGaussianHead(ppo_population_mlp(population, obs_dim, action_dim, num_cells, out_gain=0.01), action_dim)
    module = TensorDictModule(head, in_keys=["observation"], out_keys=["loc", "scale"])
    return ProbabilisticActor(module, in_keys=["loc", "scale"], distribution_class=IndependentNormal,
                              return_log_prob=True)


def make_population_value_network(population: int, obs_dim: int, num_objectives: int,
                                  num_cells: Sequence[int] = (64, 64)):
    """The population's vector state-value critic ``state_value [..., k]`` as TorchRL's ``ValueOperator``.

    Example:
        >>> from tensordict import TensorDict
        >>> critic = make_population_value_network(2, obs_dim=3, num_objectives=2, num_cells=(8,))
        >>> critic(TensorDict({"observation": torch.zeros(2, 4, 3)}, [2, 4]))["state_value"].shape
        torch.Size([2, 4, 2])
    """
    return ValueOperator(ppo_population_mlp(population, obs_dim, num_objectives, num_cells, out_gain=1.0),
                         in_keys=["observation"])


def vector_gae(gamma: float, lmbda: float, value: torch.Tensor, next_value: torch.Tensor, reward: torch.Tensor,
               done: torch.Tensor, terminated: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-objective GAE with TorchRL's ``generalized_advantage_estimate``: ``(advantage, value_target)``
    ``[*B, T, k]`` from values and rewards ``[*B, T, k]`` and ``done``/``terminated`` ``[*B, T, 1]``
    (terminated: no bootstrap; done: the trace stops).

    Example:
        >>> r = torch.tensor([[[1.0, 0.0], [1.0, 2.0]]])                      # one trajectory, T=2, k=2
        >>> v, nv = torch.zeros(1, 2, 2), torch.zeros(1, 2, 2)
        >>> d = torch.tensor([[[False], [True]]])
        >>> adv, target = vector_gae(0.5, 1.0, v, nv, r, d, d)
        >>> adv                                                                # A_0 = r_0 + 0.5 r_1
        tensor([[[1.5000, 1.0000],
                 [1.0000, 2.0000]]])
    """
    k = reward.shape[-1]
    done = done.expand(*done.shape[:-1], k)
    terminated = terminated.expand(*terminated.shape[:-1], k)
    return generalized_advantage_estimate(gamma, lmbda, value, next_value, reward, done, terminated, time_dim=-2)


def scalarize_advantage(advantage: torch.Tensor, weights: torch.Tensor, *, normalize_dims: tuple[int, ...] | None = None):
    """``advantage [P, ..., k] . weights [P, k]`` -> ``[P, ..., 1]``; with ``normalize_dims``, standardised
    over those dims per member (the authors normalise each member's minibatch)."""
    P, k = weights.shape
    w = weights.reshape(P, *([1] * (advantage.ndim - 2)), k).to(advantage.dtype)
    a = (advantage * w).sum(-1, keepdim=True)
    if normalize_dims:
        a = (a - a.mean(normalize_dims, keepdim=True)) / (a.std(normalize_dims, keepdim=True) + 1e-8)
    return a
