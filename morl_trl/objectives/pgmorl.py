"""PGMORL's building blocks (Xu et al. 2020): a population of PPO agents as ONE batched module,
and the vector GAE its scalarized PPO loss needs.

The authors (MORL-Baselines ``single_policy/ser/mo_ppo.py``) train each member with PPO whose
critic predicts a vector value ``V(s) [k]``; GAE runs per objective and the advantage is
scalarized with the member's weight, ``A = A_vec . w``, before TorchRL's :class:`ClipPPOLoss`
(which takes a scalar advantage) sees it.

* :class:`PopulationMLP`: ``P`` independent MLPs (tanh, orthogonal init with gains sqrt(2) and
  the output's: 1 for the critic, 0.01 for the actor mean, as the authors) evaluated with one
  batched matmul per layer; inputs ``[P * B, in]`` (member-major) or ``[P, B, in]``.
* :func:`make_population_actor` / :func:`make_population_critic`: TorchRL's
  ``ProbabilisticActor`` (``IndependentNormal`` with a state-independent log-std per member,
  initialised at 0) and ``ValueOperator`` (``state_value [..., k]``) on them.
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

__all__ = ["PopulationMLP", "make_population_actor", "make_population_critic", "vector_gae", "scalarize_advantage"]


class _MemberStates:
    """``member_state`` / ``load_member_state`` for a module whose every parameter has the population first."""

    def member_state(self, p: int) -> dict[str, torch.Tensor]:
        """A copy of member ``p``'s parameters (name -> tensor without the population dim)."""
        return {name: t[p].detach().clone() for name, t in self.named_parameters()}

    def load_member_state(self, p: int, state: dict[str, torch.Tensor]) -> None:
        """Overwrite member ``p``'s parameters with ``state`` (from :meth:`member_state`)."""
        with torch.no_grad():
            for name, t in self.named_parameters():
                t[p].copy_(state[name])


class PopulationMLP(_MemberStates, nn.Module):
    """``P`` MLPs with their own weights, run as one batched module.

    Example:
        >>> net = PopulationMLP(3, in_features=4, out_features=2, num_cells=(8,))
        >>> net(torch.zeros(3 * 5, 4)).shape, net(torch.zeros(3, 5, 4)).shape
        (torch.Size([15, 2]), torch.Size([3, 5, 2]))
        >>> net.member_state(1)["weights.0"].shape
        torch.Size([4, 8])
    """

    def __init__(self, population: int, in_features: int, out_features: int, num_cells: Sequence[int] = (64, 64),
                 *, out_gain: float = 1.0) -> None:
        super().__init__()
        if population < 1:
            raise ValueError(f"population must be >= 1, got {population}")
        self.population, self.in_features, self.out_features = population, in_features, out_features
        sizes = [in_features, *num_cells, out_features]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
            w = torch.empty(population, b, a)
            gain = out_gain if i == len(sizes) - 2 else math.sqrt(2)
            for p in range(population):
                nn.init.orthogonal_(w[p], gain)
            self.weights.append(nn.Parameter(w.transpose(1, 2).contiguous()))
            self.biases.append(nn.Parameter(torch.zeros(population, 1, b)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        lead = x.shape[:-1]
        h = x.reshape(self.population, -1, x.shape[-1]).to(self.weights[0].dtype)
        n = len(self.weights)
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = torch.baddbmm(b, h, w)
            if i < n - 1:
                h = torch.tanh(h)
        return h.reshape(*lead, self.out_features)


class _GaussianHead(_MemberStates, nn.Module):
    """``obs -> (loc, scale)``: the population's mean MLP and a log-std per member and action dim."""

    def __init__(self, mean: PopulationMLP, action_dim: int) -> None:
        super().__init__()
        self.mean = mean
        self.log_std = nn.Parameter(torch.zeros(mean.population, 1, action_dim))

    def forward(self, obs: torch.Tensor):
        loc = self.mean(obs)
        per_member = loc.reshape(self.mean.population, -1, loc.shape[-1])
        return loc, self.log_std.exp().expand_as(per_member).reshape(loc.shape)


def make_population_actor(population: int, obs_dim: int, action_dim: int, num_cells: Sequence[int] = (64, 64)):
    """The population's Gaussian policy as TorchRL's ``ProbabilisticActor`` (writes ``action`` and its log-prob).

    Example:
        >>> from tensordict import TensorDict
        >>> actor = make_population_actor(2, obs_dim=3, action_dim=1, num_cells=(8,))
        >>> actor(TensorDict({"observation": torch.zeros(2 * 4, 3)}, [8]))["action"].shape
        torch.Size([8, 1])
    """
    head = _GaussianHead(PopulationMLP(population, obs_dim, action_dim, num_cells, out_gain=0.01), action_dim)
    module = TensorDictModule(head, in_keys=["observation"], out_keys=["loc", "scale"])
    return ProbabilisticActor(module, in_keys=["loc", "scale"], distribution_class=IndependentNormal,
                              return_log_prob=True)


def make_population_critic(population: int, obs_dim: int, num_objectives: int, num_cells: Sequence[int] = (64, 64)):
    """The population's vector critic ``state_value [..., k]`` as TorchRL's ``ValueOperator``."""
    return ValueOperator(PopulationMLP(population, obs_dim, num_objectives, num_cells, out_gain=1.0),
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
