"""A population of MOSAC policies as ONE batched module (MORL/D's population, trained in one pass).

MORL-Baselines' MORL/D keeps a Python list of ``MOSAC`` agents and steps them one at a time. Here the ``P``
members' networks are stacked: every linear layer holds ``[P, in, out]`` weights and runs as one ``baddbmm``
(:class:`~morl_trl.objectives.batched.BatchedMLP`), so one forward, one backward and one optimizer step update all
``P`` members. :class:`PopulationMOSACLoss` is, member by member, exactly :class:`~morl_trl.objectives.MOSACLoss`
(continuous) or :class:`~morl_trl.objectives.DiscreteMOSACLoss` (discrete) with a fixed preference ``w_p`` and
networks that do not read the preference (MORL/D's): the batch is ``[P, B]`` (member ``p`` learns from row ``p``),
each member has its own temperature, and the losses are summed over members (each member's gradient is that of its
own loss; Adam is elementwise, so one Adam over the stacked parameters is ``P`` independent Adams).
``tests/objectives/test_population.py`` checks one batched update against ``P`` separate ``MOSACLoss`` updates from
the same state.

Example:
    >>> import torch
    >>> from tensordict import TensorDict
    >>> from torchrl.data import Bounded
    >>> from torchrl.objectives import SoftUpdate
    >>> P, B = 3, 8
    >>> actor = make_population_gaussian_actor(P, 5, Bounded(-1.0, 1.0, (2,)), num_cells=(16,))
    >>> critic = make_population_critic(P, 5, 2, 2, num_cells=(16,))
    >>> loss = PopulationMOSACLoss(actor, critic, weights=torch.tensor([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]))
    >>> _ = loss.make_value_estimator(gamma=0.99)
    >>> data = TensorDict({"observation": torch.randn(P, B, 5), "action": torch.rand(P, B, 2) * 2 - 1,
    ...     ("next", "observation"): torch.randn(P, B, 5), ("next", "reward"): torch.randn(P, B, 2),
    ...     ("next", "done"): torch.zeros(P, B, 1, dtype=torch.bool),
    ...     ("next", "terminated"): torch.zeros(P, B, 1, dtype=torch.bool)}, [P, B])
    >>> out = loss(data)
    >>> sorted(out.keys()), out["alpha"].shape
    (['alpha', 'entropy', 'loss_actor', 'loss_alpha', 'loss_qvalue'], torch.Size([3]))
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase, TensorDictParams
from tensordict.nn import TensorDictModule, dispatch
from tensordict.utils import NestedKey
from torch import Tensor, nn
from torchrl.data import Bounded, Categorical, TensorSpec
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import ProbabilisticActor
from torchrl.objectives.sac import compute_rsample_log_prob, rsample_and_log_prob

from morl_trl._torchrl_compat import cache_values, clear_weakrefs
from morl_trl.objectives.batched import BatchedMLP
from morl_trl.objectives.actor_critic_parts import (check_alpha_loss_form, expected_log_prob,
                                                    expected_soft_actor_objective, expected_soft_next_value,
                                                    scalarized_min, soft_actor_objective, soft_next_value,
                                                    temperature_objective)
from morl_trl.objectives.common import MultiObjectiveLossModule, check_preference
from morl_trl.objectives.envelope import action_index
from morl_trl.objectives.networks import DEFAULT_NUM_CELLS, categorical_actor, gaussian_head, tanh_normal_actor

__all__ = ["PopulationMOSACLoss", "MemberRouter", "NearestMemberRouter", "make_population_gaussian_actor",
           "make_population_categorical_actor", "make_population_critic", "make_population_q_network", "nearest_member"]


# ---------------------------------------------------------------------- routing of sub-envs to members
def nearest_member(preference: Tensor, weights: Tensor) -> Tensor:
    """Index of the member whose weight is nearest (squared Euclidean) to each preference row.

    Example:
        >>> nearest_member(torch.tensor([[0.9, 0.1], [0.2, 0.8]]), torch.tensor([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]))
        tensor([0, 2])
    """
    d = (preference.unsqueeze(-2) - weights.to(preference)).pow(2).sum(-1)
    return d.argmin(-1)


class MemberRouter(nn.Module):
    """Acting in the training env: sub-env ``i`` of ``P * N`` is driven by member ``i // N``.

    Reshapes the ``[P * N, ...]`` inputs to ``[P, N, ...]``, runs the population network and
    flattens its outputs back.
    """

    def __init__(self, net: nn.Module, population: int) -> None:
        super().__init__()
        self.net, self.population = net, population

    def forward(self, *inputs: Tensor):
        n = inputs[0].shape[0]
        if n % self.population:
            raise ValueError(f"the training env has {n} sub-envs; MORL/D needs a multiple of the population "
                             f"size {self.population} (each member owns num_envs of them)")
        out = self.net(*(x.reshape(self.population, n // self.population, *x.shape[1:]) for x in inputs))
        if isinstance(out, tuple):
            return tuple(o.reshape(n, *o.shape[2:]) for o in out)
        return out.reshape(n, *out.shape[2:])


class NearestMemberRouter(nn.Module):
    """Acting under a given preference (the evaluator's): each row is driven by the member whose
    weight is nearest to its ``preference`` (the authors' MORL/D evaluation).

    All members run on all rows (``[P, *B, ...]``) and each row keeps its member's output. ``weights`` is the
    population's ``[P, k]`` weight buffer (shared with the loss, so weight adaptation is seen at once).
    """

    def __init__(self, net: nn.Module, weights: Tensor) -> None:
        super().__init__()
        self.net = net
        self.weights = weights  # a reference to the loss's buffer (not registered: not a second copy)

    def forward(self, *inputs: Tensor):
        *obs, preference = inputs
        batch = preference.shape[:-1]
        idx = nearest_member(preference.reshape(-1, preference.shape[-1]), self.weights)
        m = idx.shape[0]
        p = self.weights.shape[0]
        flat = [x.reshape(m, *x.shape[len(batch):]) for x in obs]
        out = self.net(*(x.unsqueeze(0).expand(p, *x.shape) for x in flat))

        def pick(o: Tensor) -> Tensor:
            g = idx.view(1, m, *([1] * (o.ndim - 2))).expand(1, m, *o.shape[2:])
            return o.gather(0, g).squeeze(0).reshape(*batch, *o.shape[2:])

        return tuple(pick(o) for o in out) if isinstance(out, tuple) else pick(out)


# ---------------------------------------------------------------------- builders
def make_population_gaussian_actor(population: int, obs_dim: int, action_spec: Bounded, *,
                                   num_cells: Sequence[int] = DEFAULT_NUM_CELLS, scale: str = "softplus",
                                   log_std_bounds: tuple[float, float] | None = None,
                                   observation_key: NestedKey = "observation",
                                   action_key: NestedKey = "action") -> ProbabilisticActor:
    """``P`` tanh-Gaussian actors ``pi_p(a | s)`` reading ``[P, *B, obs]`` (the loss's view).

    The population network is ``actor.module[0].module.net`` (see :func:`population_policies` for the acting
    views). Parameter names match :func:`~morl_trl.objectives.make_gaussian_actor`'s with ``preference_key=None``.
    """
    mlp = BatchedMLP(population, obs_dim, 2 * action_spec.shape[-1], num_cells=num_cells)
    return tanh_normal_actor(gaussian_head(mlp, scale, log_std_bounds), [observation_key], action_spec, action_key)


def make_population_categorical_actor(population: int, obs_dim: int, num_actions: int, *,
                                      num_cells: Sequence[int] = DEFAULT_NUM_CELLS,
                                      action_spec: TensorSpec | None = None, observation_key: NestedKey = "observation",
                                      action_key: NestedKey = "action") -> ProbabilisticActor:
    """``P`` categorical actors ``pi_p(. | s)`` reading ``[P, *B, obs]``."""
    mlp = BatchedMLP(population, obs_dim, num_actions, num_cells=num_cells)
    spec = action_spec if action_spec is not None else Categorical(num_actions)
    return categorical_actor(mlp, [observation_key], spec, action_key)


def make_population_critic(population: int, obs_dim: int, action_dim: int, num_objectives: int, *,
                           num_cells: Sequence[int] = DEFAULT_NUM_CELLS, observation_key: NestedKey = "observation",
                           action_key: NestedKey = "action",
                           out_key: NestedKey = "state_action_value") -> TensorDictModule:
    """``P`` vector critics ``Q_p(s, a) -> [P, *B, k]`` (MORL/D's MOSAC critics do not read ``w``)."""
    net = BatchedMLP(population, obs_dim + action_dim, num_objectives, num_cells=num_cells)
    net.num_objectives = num_objectives
    return TensorDictModule(net, in_keys=[observation_key, action_key], out_keys=[out_key])


def make_population_q_network(population: int, obs_dim: int, num_actions: int, num_objectives: int, *,
                              num_cells: Sequence[int] = DEFAULT_NUM_CELLS, observation_key: NestedKey = "observation",
                              out_key: NestedKey = "action_value") -> TensorDictModule:
    """``P`` vector Q-networks ``Q_p(s, .) -> [P, *B, |A|, k]`` (discrete MORL/D)."""
    net = BatchedMLP(population, obs_dim, (num_actions, num_objectives), num_cells=num_cells)
    net.num_objectives, net.num_actions = num_objectives, num_actions
    return TensorDictModule(net, in_keys=[observation_key], out_keys=[out_key])


def population_policies(actor: ProbabilisticActor, weights: Tensor) -> tuple[ProbabilisticActor, ProbabilisticActor]:
    """``(explore, evaluate)`` views of a population actor sharing its parameters.

    ``explore`` acts in a ``[P * N]`` training env (sub-env ``i``: member ``i // N``, :class:`MemberRouter`);
    ``evaluate`` reads ``"preference"`` and lets the nearest member act (:class:`NearestMemberRouter`).
    """
    tdm = actor.module[0]
    head = tdm.module
    population = weights.shape[0]
    spec = actor.spec
    action_key = actor.module[-1].out_keys[0]
    action_spec = spec[action_key]
    make = tanh_normal_actor if "loc" in tdm.out_keys else categorical_actor
    explore = make(MemberRouter(head, population), tdm.in_keys, action_spec, action_key)
    evaluate = make(NearestMemberRouter(head, weights), [*tdm.in_keys, "preference"], action_spec, action_key)
    return explore, evaluate


# ---------------------------------------------------------------------- the loss
class PopulationMOSACLoss(MultiObjectiveLossModule):
    r"""MORL/D's population of MOSAC learners (continuous or discrete) as one loss.

    Member ``p`` has the fixed weight ``weights[p]`` and, on row ``p`` of a ``[P, B]`` batch,
    the losses of :class:`~morl_trl.objectives.MOSACLoss` (``num_actions=None``: a tanh-Gaussian
    actor, critics ``Q(s, a)``) or :class:`~morl_trl.objectives.DiscreteMOSACLoss` (``num_actions``
    given: a categorical actor, critics ``Q(s, .)``) with ``critic_min="scalarized"``,
    ``critic_loss="scalarized"``, L2: critics regress ``w^T Q_i`` onto ``w^T (r + gamma (1 - term) (Q^-_min(s', a') -
    alpha_p log pi_p(a'|s')))``, the actor minimises ``alpha_p log pi_p(a|s) - w^T Q_min(s, a)`` and ``alpha_p``
    follows the target entropy. Each output ``loss_*`` is the sum over members of the member's batch mean;
    ``alpha`` is ``[P]``. :meth:`set_weights` changes the weights (MORL/D's weight adaptation).

    Args:
        actor_network: a population actor, e.g. :func:`make_population_gaussian_actor`.
        qvalue_network: a population critic, e.g. :func:`make_population_critic` /
            :func:`make_population_q_network`; expanded to ``num_qvalue_nets`` independently
            initialised copies (TorchRL's SAC ensemble), parameters ``[n, P, ...]``.

    Keyword Args:
        weights (Tensor): ``[P, k]`` member weights on the simplex.
        num_actions (int, optional): discrete actions ``|A|``; ``None`` for continuous actions.
        num_qvalue_nets (int): critics per member. Defaults to 2.
        alpha_init (float): initial temperature of every member. Defaults to 1.
        fixed_alpha (bool): keep the temperatures (no ``loss_alpha``). Defaults to ``False``.
        target_entropy (float or "auto"): ``"auto"``: minus the action dimension (continuous,
            from ``action_spec`` or the actor's spec) or ``target_entropy_weight * log |A|``.
        target_entropy_weight (float): discrete ``"auto"`` scale. Defaults to 0.98.
        action_spec (TensorSpec, optional): for the continuous ``"auto"`` target entropy.
        alpha_loss_form (str): ``"log_alpha"`` (default) or ``"alpha"``, as
            :class:`~morl_trl.objectives.MOSACLoss`'s.

    :meth:`qvalue_loss`, :meth:`actor_loss` and :meth:`temperature_loss` compute the three parts
    alone, as :class:`~morl_trl.objectives.MOSACLoss`'s. Inside :meth:`only_member` they are one
    member's alone, on a ``[1, B]`` batch (MORL/D's round robin).
    """

    @dataclass
    class _AcceptedKeys:
        """Configurable tensordict keys (``loss.set_keys(name=key)``): ``action``, ``state_action_value`` (continuous
        critic output), ``action_value`` (discrete critic output), ``value_target``, ``priority``, ``preference``
        (unused: the weights are the members'), ``reward``, ``done``, ``terminated``."""

        action: NestedKey = "action"
        state_action_value: NestedKey = "state_action_value"
        action_value: NestedKey = "action_value"
        preference: NestedKey = "preference"
        value_target: NestedKey = "value_target"
        priority: NestedKey = "td_error"
        priority_weight: NestedKey = "priority_weight"
        reward: NestedKey = "reward"
        done: NestedKey = "done"
        terminated: NestedKey = "terminated"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    actor_network: ProbabilisticActor
    qvalue_network: TensorDictModule
    actor_network_params: TensorDictParams
    qvalue_network_params: TensorDictParams
    target_actor_network_params: TensorDictParams
    target_qvalue_network_params: TensorDictParams

    def __init__(self, actor_network: ProbabilisticActor, qvalue_network: TensorDictModule, *, weights: Tensor,
                 num_actions: int | None = None, num_qvalue_nets: int = 2, alpha_init: float = 1.0,
                 fixed_alpha: bool = False, target_entropy: float | str = "auto", target_entropy_weight: float = 0.98,
                 action_spec: TensorSpec | None = None, alpha_loss_form: str = "log_alpha") -> None:
        self._in_keys = None
        super().__init__()
        self.alpha_loss_form = check_alpha_loss_form(alpha_loss_form)
        self._only_member: int | None = None  # (only_member)
        weights = torch.as_tensor(weights, dtype=torch.float32)
        if weights.ndim != 2:
            raise ValueError(f"weights must be [P, k] (one weight per member), got shape {tuple(weights.shape)}")
        self.population, self.num_objectives = weights.shape
        check_preference(weights, self.num_objectives, name="weights")
        self.num_actions = num_actions
        self.num_qvalue_nets = int(num_qvalue_nets)
        self.fixed_alpha = fixed_alpha
        self.convert_to_functional(actor_network, "actor_network", create_target_params=False)
        self.convert_to_functional(qvalue_network, "qvalue_network", self.num_qvalue_nets, create_target_params=True,
                                   compare_against=list(actor_network.parameters()))
        device = next(iter(self.qvalue_network_params.values(True, True))).device
        self.register_buffer("weights", weights.to(device).clone())
        log_alpha = torch.full((self.population,), math.log(alpha_init), device=device)
        if fixed_alpha:
            self.register_buffer("log_alpha", log_alpha)
        else:
            self.register_parameter("log_alpha", nn.Parameter(log_alpha))
        if target_entropy == "auto":
            if fixed_alpha:
                target_entropy = 0.0
            elif num_actions is not None:
                target_entropy = target_entropy_weight * math.log(num_actions)
            else:
                spec = action_spec if action_spec is not None else actor_network.spec[self.tensor_keys.action]
                target_entropy = -float(spec.shape[-1:].numel())
        self.register_buffer("target_entropy", torch.tensor(float(target_entropy), device=device))

    # ------------------------------------------------------------------ weights
    def set_weights(self, weights: Tensor) -> None:
        """Replace the ``[P, k]`` member weights in place (the acting views see them at once)."""
        weights = torch.as_tensor(weights, dtype=self.weights.dtype, device=self.weights.device)
        if weights.shape != self.weights.shape:
            raise ValueError(f"weights must have shape {tuple(self.weights.shape)}, got {tuple(weights.shape)}")
        check_preference(weights, self.num_objectives, name="weights")
        self.weights.copy_(weights)

    @torch.no_grad()
    def load_members(self, losses: Sequence[MultiObjectiveLossModule]) -> None:
        """Copy ``P`` single-policy MOSAC losses (networks without preference input) into the
        population: actor, critics, target critics and temperatures of ``losses[p]`` become member ``p``."""
        if len(losses) != self.population:
            raise ValueError(f"load_members needs {self.population} losses (one per member), got {len(losses)}")
        for name, dim in (("actor_network_params", 0), ("qvalue_network_params", 1),
                          ("target_qvalue_network_params", 1)):
            mine = getattr(self, name)
            for key, value in mine.items(True, True):
                stacked = torch.stack([getattr(l, name).get(key).data for l in losses], dim)
                # nn.Linear's [out, in] weight and [out] bias -> BatchedLinear's [in, out] and [1, out]
                stacked = stacked.transpose(-1, -2) if key[-1] == "weight" else stacked.unsqueeze(-2)
                value.data.copy_(stacked)
        self.log_alpha.data.copy_(torch.stack([l.log_alpha.data.reshape(()) for l in losses]))

    # ------------------------------------------------------------------ one member alone
    @contextmanager
    def only_member(self, member: int) -> Iterator[PopulationMOSACLoss]:
        """Within it the losses are member ``member``'s alone, on a ``[1, B]`` batch: its slices of
        the stacked parameters, target critics, weight and temperature run (``1 / P`` of the work of
        the whole population's update); the gradient reaches its slices only (the other members'
        are zero). Continuous actions draw the noise of the whole population's sample and keep the
        member's rows, so its update is, to float rounding, that of an update of all members with
        the others masked out (MORL/D's round robin, ``tests/recipes/test_morld_round_robin.py``).

        Example:
            >>> actor = make_population_categorical_actor(3, 4, 2, num_cells=(8,))
            >>> loss = PopulationMOSACLoss(actor, make_population_q_network(3, 4, 2, 2, num_cells=(8,)),
            ...                            weights=torch.tensor([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]), num_actions=2)
            >>> _ = loss.make_value_estimator(gamma=0.9)
            >>> P, B = 3, 5
            >>> data = TensorDict({"observation": torch.randn(P, B, 4), "action": torch.randint(2, (P, B)),
            ...     ("next", "observation"): torch.randn(P, B, 4), ("next", "reward"): torch.randn(P, B, 2),
            ...     ("next", "done"): torch.zeros(P, B, 1, dtype=torch.bool),
            ...     ("next", "terminated"): torch.zeros(P, B, 1, dtype=torch.bool)}, [P, B])
            >>> alone = []
            >>> for p in range(P):
            ...     with loss.only_member(p):
            ...         alone.append(loss.qvalue_loss(data[p:p + 1])[0])
            >>> torch.allclose(sum(alone), loss.qvalue_loss(data)[0])  # the population's: the sum of its members'
            True
        """
        if not 0 <= int(member) < self.population:
            raise ValueError(f"member={member}; valid: 0 .. {self.population - 1}")
        previous, self._only_member = self._only_member, int(member)
        try:
            yield self
        finally:
            self._only_member = previous

    def _member_slice(self, x, dim: int = 0):
        """``x`` (a tensor or TensorDict of stacked members along ``dim``) as it is, or inside
        :meth:`only_member` its member's ``[1]`` slice (a view: the gradient reaches ``x``)."""
        m = self._only_member
        if m is None:
            return x
        if isinstance(x, Tensor):
            return x.narrow(dim, m, 1)
        return x.apply(lambda t: t.narrow(dim, m, 1))

    @property
    def _members(self) -> int:
        return self.population if self._only_member is None else 1

    def _rsample(self, dist) -> tuple[Tensor, Tensor]:
        """``(action, log_prob)`` reparameterised; inside :meth:`only_member`, the rows of the member in a
        draw for the whole population (the noise a population-wide sample gives it)."""
        if self._only_member is None:
            return compute_rsample_log_prob(dist)
        action, log_prob = rsample_and_log_prob(dist, (self.population,))
        return action[self._only_member], log_prob[self._only_member]

    # ------------------------------------------------------------------ pieces
    @property
    def _alpha(self) -> Tensor:
        with torch.no_grad():
            return self._member_slice(self.log_alpha).exp()

    @property
    @cache_values
    def _cached_detached_qvalue_params(self):
        return self.qvalue_network_params.detach()

    def _critics(self, td: TensorDictBase, params, key: NestedKey) -> Tensor:
        """``[n, P, B, ...]``: every critic of the ensemble (a loop of ``n`` calls, each batched over members)."""
        values = []
        for i in range(self.num_qvalue_nets):
            with params[i].to_module(self.qvalue_network, preserve_module_state=False):
                values.append(self.qvalue_network.module(*(td.get(k) for k in self.qvalue_network.in_keys)))
        return torch.stack(values)

    def _actor(self, data: TensorDictBase):
        with self._member_slice(self.actor_network_params).to_module(self.actor_network, preserve_module_state=False):
            return self.actor_network.get_dist(data.select(*self.actor_network.in_keys, strict=False))

    def _w(self, extra_dims: int) -> Tensor:
        """``[P, 1, (1,)*extra_dims, k]``: member weights broadcast over the batch."""
        return self._member_slice(self.weights).view(self._members, 1, *([1] * extra_dims), self.num_objectives)

    def _per_member(self, x: Tensor) -> Tensor:
        """Sum over members of each member's batch mean (``x``: ``[P, B]``)."""
        return x.mean(1).sum()

    def _alpha_objective(self, log_prob: Tensor) -> Tensor:
        """``[P, B]`` temperature losses on a detached ``log_prob`` (``alpha_loss_form``, as MOSAC's)."""
        return temperature_objective(self._member_slice(self.log_alpha).view(-1, 1), log_prob, self.target_entropy,
                                     self.alpha_loss_form)

    # ------------------------------------------------------------------ the three parts
    def _checked(self, tensordict: TensorDictBase) -> TensorDictBase:
        if tensordict.ndim != 2 or tensordict.shape[0] != self._members:
            raise ValueError(f"{type(self).__name__} takes a [P, B] batch with P = {self._members} (row p for "
                             f"member p), got batch size {tuple(tensordict.shape)}")
        self._check_inputs(tensordict, needs_preference=False)
        return tensordict

    @property
    def fresh_temperature_sample(self) -> bool:
        """Whether the temperature step draws a fresh sample (continuous, as MOSAC) or reuses the actor
        step's probabilities (discrete, as ``MOSACDiscrete``)."""
        return self.num_actions is None

    def qvalue_loss(self, tensordict: TensorDictBase) -> tuple[Tensor, dict[str, Tensor]]:
        """The critics' loss alone (:meth:`forward`'s ``loss_qvalue``); writes the ``[P, B]`` priority."""
        data = self._checked(tensordict)
        loss, td_error = (self._continuous_qvalue if self.num_actions is None else self._discrete_qvalue)(data)
        tensordict.set(self.tensor_keys.priority, td_error)
        return self._per_member(loss), {"td_error": td_error}

    def actor_dist(self, tensordict: TensorDictBase):
        """The current actors' distribution on ``tensordict`` (with gradient), to share between
        :meth:`temperature_loss` and :meth:`actor_loss` (as :meth:`MOSACLoss.actor_dist <morl_trl.objectives.MOSACLoss.actor_dist>`)."""
        with set_exploration_type(ExplorationType.RANDOM):
            return self._actor(self._checked(tensordict))

    def actor_loss(self, tensordict: TensorDictBase, dist=None) -> tuple[Tensor, dict[str, Tensor]]:
        """The actors' loss alone (:meth:`forward`'s ``loss_actor``: no target computation), from
        ``dist`` (:meth:`actor_dist`) when given; the metadata's ``log_prob`` is ``[P, B]`` (discrete:
        ``sum_a pi log pi``), detached."""
        data = self._checked(tensordict)
        loss, log_prob = (self._continuous_actor if self.num_actions is None else self._discrete_actor)(data, dist)
        return self._per_member(loss), {"log_prob": log_prob.detach()}

    def temperature_loss(self, tensordict: TensorDictBase, log_prob: Tensor | None = None, dist=None) -> Tensor:
        """The temperatures' loss alone, on ``log_prob`` or (``None``) a fresh sample of the current
        actors (from ``dist`` when given)."""
        data = self._checked(tensordict)
        if log_prob is None:
            with torch.no_grad():
                log_prob = self._sample_log_prob(data, dist)
        return self._per_member(self._alpha_objective(log_prob.detach()))

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Computes ``loss_qvalue``, ``loss_actor`` and (unless ``fixed_alpha``) ``loss_alpha`` on a
        ``[P, B]`` batch."""
        data = self._checked(tensordict)
        if self.num_actions is None:
            (loss_qvalue, td_error), (loss_actor, neg_entropy) = self._continuous_qvalue(data), self._continuous_actor(data)
        else:
            (loss_qvalue, td_error), (loss_actor, neg_entropy) = self._discrete_qvalue(data), self._discrete_actor(data)
        losses = {"loss_actor": self._per_member(loss_actor), "loss_qvalue": self._per_member(loss_qvalue),
                  "loss_alpha": self._per_member(self._alpha_objective(neg_entropy.detach()))}
        tensordict.set(self.tensor_keys.priority, td_error)
        if self.fixed_alpha:
            losses.pop("loss_alpha")
        out = TensorDict({**losses, "alpha": self._alpha, "entropy": -neg_entropy.detach().mean(1)}, batch_size=[])
        clear_weakrefs(self, tensordict, out, "actor_network_params", "qvalue_network_params",
                       "target_qvalue_network_params")
        return out

    def _critic_loss(self, q: Tensor, target: Tensor, w: Tensor) -> tuple[Tensor, Tensor]:
        sq, st = (q * w).sum(-1), (target * w).sum(-1)  # [n, P, B], [P, B]
        td = sq - st
        return td.pow(2).sum(0), td.detach().abs().max(0).values

    def _continuous_qvalue(self, data: TensorDictBase) -> tuple[Tensor, Tensor]:
        w = self._w(0)
        alpha = self._alpha.view(-1, 1)
        with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
            next_data = data.get("next")
            next_action, next_log_prob = self._rsample(self._actor(next_data))
            td = next_data.select(*self.qvalue_network.in_keys, strict=False)
            td.set(self.tensor_keys.action, next_action)
            q_next = self._critics(td, self._member_slice(self.target_qvalue_network_params, 1),
                                   self.tensor_keys.state_action_value)
            next_value = soft_next_value(scalarized_min(q_next, w), next_log_prob, alpha)
            target = self.value_estimator.value_estimate(data, next_value=next_value)
        q = self._critics(data, self._member_slice(self.qvalue_network_params, 1), self.tensor_keys.state_action_value)
        return self._critic_loss(q, target, w)

    def _continuous_actor(self, data: TensorDictBase, dist=None) -> tuple[Tensor, Tensor]:
        w = self._w(0)
        with set_exploration_type(ExplorationType.RANDOM):
            action, log_prob = self._rsample(self._actor(data) if dist is None else dist)
        td = data.select(*self.qvalue_network.in_keys, strict=False)
        td.set(self.tensor_keys.action, action)
        q_pi = self._critics(td, self._member_slice(self._cached_detached_qvalue_params, 1),
                             self.tensor_keys.state_action_value)
        return soft_actor_objective(log_prob, scalarized_min(q_pi, w), w, self._alpha.view(-1, 1)), log_prob

    def _discrete_qvalue(self, data: TensorDictBase) -> tuple[Tensor, Tensor]:
        w = self._w(1)  # over the actions
        alpha = self._alpha.view(-1, 1, 1)
        key = self.tensor_keys.action_value
        with torch.no_grad():
            next_data = data.get("next")
            dist = self._actor(next_data)
            probs, log_probs = dist.probs, dist.logits
            q_next = scalarized_min(self._critics(next_data, self._member_slice(self.target_qvalue_network_params, 1),
                                                  key), w)
            next_value = expected_soft_next_value(probs, log_probs, q_next, alpha)
            target = self.value_estimator.value_estimate(data, next_value=next_value)
        q = self._critics(data, self._member_slice(self.qvalue_network_params, 1), key)  # [n, P, B, |A|, k]
        n, p, b, a, k = q.shape
        action = data.get(self.tensor_keys.action)
        index = action_index(action.reshape(p * b, *action.shape[2:]), p * b, a).view(1, p, b, 1, 1)
        q_taken = q.gather(-2, index.expand(n, p, b, 1, k)).squeeze(-2)
        return self._critic_loss(q_taken, target, self._w(0))

    def _discrete_actor(self, data: TensorDictBase, dist=None) -> tuple[Tensor, Tensor]:
        w = self._w(1)
        dist = self._actor(data) if dist is None else dist
        probs, log_probs = dist.probs, dist.logits
        q_pi = scalarized_min(self._critics(data, self._member_slice(self._cached_detached_qvalue_params, 1),
                                            self.tensor_keys.action_value), w)
        loss_actor = expected_soft_actor_objective(probs, log_probs, q_pi, w, self._alpha.view(-1, 1, 1))
        return loss_actor, expected_log_prob(probs, log_probs)

    def _sample_log_prob(self, data: TensorDictBase, dist=None) -> Tensor:
        """``[P, B]`` log-probabilities of fresh actions of the current actors (discrete: ``sum_a pi log pi``)."""
        dist = self._actor(data) if dist is None else dist
        if self.num_actions is None:
            with set_exploration_type(ExplorationType.RANDOM):
                return self._rsample(dist)[1]
        return expected_log_prob(dist.probs, dist.logits)

    @property
    def out_keys(self) -> list[str]:
        keys = ["loss_actor", "loss_qvalue"]
        if not self.fixed_alpha:
            keys.append("loss_alpha")
        return [*keys, "alpha", "entropy"]

    def _set_in_keys(self) -> None:
        net_keys = [k for k in (*self.actor_network.in_keys, *self.qvalue_network.in_keys)
                    if k != self.tensor_keys.action]
        keys = [self.tensor_keys.action, ("next", self.tensor_keys.reward), ("next", self.tensor_keys.done),
                ("next", self.tensor_keys.terminated), *net_keys, *[("next", k) for k in net_keys]]
        self._in_keys = list(dict.fromkeys(keys))
