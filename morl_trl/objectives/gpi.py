"""GPI-LS / GPI-PD (Alegre et al., AAMAS 2023): the vector Q ensemble, GPI action selection and the loss.

* :class:`GPIQNetwork`: ``E`` preference-conditioned vector Q-networks as one batched module,
  the authors' ``QNet``: ``relu(W_s s) * relu(W_w w)`` then ``Linear -> Dropout -> LayerNorm
  -> ReLU`` blocks and a ``Linear`` to ``|A| * k`` (orthogonal init, zero biases).
* :func:`gpi_action`: ``argmax_a max_{w_i in M} w . Q(s, a, w_i)`` over a weight support ``M``.
* :class:`GPIPolicy`: that selection as a TensorDict module (what GPI-LS acts and is evaluated with).
* :class:`GPILoss`: the authors' update (``GPIPD.update``): half the batch under the current
  weight, half under weights drawn from the support; target from the minimum over the target
  ensemble; loss the authors' thresholded Huber of the vector TD error averaged over members;
  PER priority ``max(|w . TD|, min_priority)`` from the member-wise maximum TD error, with
  GPI-PD's GPI target (the envelope over a few support weights) in place of the TD target.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase, dispatch
from tensordict.utils import NestedKey
from torch import nn
from torch.nn import functional as F

from morl_trl._torchrl_compat import clear_weakrefs
from morl_trl.objectives.batched import (BatchedLayerNorm, BatchedLinear, batched_linear, hidden_block,
                                         linear_dropout_norm_relu)
from morl_trl.objectives.common import MultiObjectiveLossModule, argmin_along
from morl_trl.objectives.envelope import action_index
from morl_trl.objectives.networks import NatureCNN, orthogonal_init_
from morl_trl.objectives.value import vector_td0_return_estimate

__all__ = ["GPIQNetwork", "GPIPolicy", "GPILoss", "gpi_action", "thresholded_huber", "GPIActor", "GPIVectorCritic",
           "GPIContinuousPolicy", "GPIContinuousLoss"]


class GPIQNetwork(nn.Module):
    """``E`` vector Q-networks ``Q_e(s, ., w)`` ``[E, *B, |A|, k]`` as one batched module.

    Args:
        obs_dim: flat observation width, or an image shape ``(C, H, W)`` (one ``NatureCNN`` per member
            gives the state features; the authors' Mario).
        num_actions: ``|A|``.
        num_objectives: ``k``.
        hidden: widths; the first is the state/preference feature width (the authors: ``[256] * 4``).
        num_nets: ``E`` (the authors: 2).
        dropout: dropout rate after each hidden ``Linear`` but the features (the authors: 0.01).
        layer_norm: LayerNorm after it (the authors: on, but Mario).

    Example:
        >>> q = GPIQNetwork(6, 3, 2, hidden=(16, 16))
        >>> q(torch.zeros(5, 6), torch.full((5, 2), 0.5)).shape
        torch.Size([2, 5, 3, 2])
        >>> q(torch.zeros(5, 6), torch.full((5, 2), 0.5), members=slice(0, 1)).shape
        torch.Size([1, 5, 3, 2])
    """

    def __init__(self, obs_dim, num_actions: int, num_objectives: int, *, hidden=(256, 256, 256, 256),
                 num_nets: int = 2, dropout: float = 0.01, layer_norm: bool = True) -> None:
        super().__init__()
        obs_shape = (int(obs_dim),) if isinstance(obs_dim, int) else tuple(int(d) for d in obs_dim)
        if len(obs_shape) not in (1, 3):
            raise ValueError(f"obs_dim must be a width or an image shape (C, H, W), got {obs_dim!r}")
        self.obs_shape = obs_shape
        if not hidden:
            raise ValueError("hidden must hold at least one width (the feature width)")
        if num_nets < 1:
            raise ValueError(f"num_nets must be >= 1, got {num_nets}")
        if not 0.0 <= dropout < 1.0:
            raise ValueError(f"dropout must lie in [0, 1), got {dropout}")
        self.num_actions, self.num_objectives, self.num_nets = num_actions, num_objectives, num_nets
        self.dropout = dropout
        h0 = hidden[0]
        if len(obs_shape) == 1:
            self.state_features = BatchedLinear(num_nets, obs_shape[0], h0)
        else:  # images: one NatureCNN per member (the authors'), features of width hidden[0]
            # with the authors' layer_init on its Conv2d and Linear layers (gpi_pd.py:69)
            self.state_features = nn.ModuleList(orthogonal_init_(NatureCNN(obs_shape, h0)) for _ in range(num_nets))
        self.weight_features = BatchedLinear(num_nets, num_objectives, h0)
        self.hidden = nn.ModuleList(BatchedLinear(num_nets, a, b) for a, b in zip(hidden[:-1], hidden[1:]))
        self.norms = nn.ModuleList(BatchedLayerNorm(num_nets, b) for b in hidden[1:]) if layer_norm else None
        self.out = BatchedLinear(num_nets, hidden[-1], num_actions * num_objectives)

    def forward(self, observation: torch.Tensor, preference: torch.Tensor, members: slice | None = None) -> torch.Tensor:
        return self.forward_with(None, observation, preference, members)

    @property
    def supports_forward_with(self) -> bool:
        """Whether :meth:`forward_with` takes given parameters: flat observations (no ``NatureCNN``)."""
        return not isinstance(self.state_features, nn.ModuleList)

    def forward_with(self, params: TensorDictBase | None, observation: torch.Tensor, preference: torch.Tensor,
                     members: slice | None = None, *, of_rows: int | None = None) -> torch.Tensor:
        """:meth:`forward` with the parameters taken from ``params`` (a TensorDict shaped as
        ``TensorDict.from_module(self)``, e.g. a loss's functional or target parameters; ``None``: the
        module's own), nothing swapped into the module: the same operations at a fraction of
        ``TensorDict.to_module``'s cost. Flat observations only (:attr:`supports_forward_with`).

        ``of_rows``: the ``N`` rows given (``preference``'s leading dims, flattened) are the first
        ``N`` of a batch of ``of_rows``; the dropout masks are drawn for all of them, so each row
        comes out as it does when the whole batch is run (rows are independent through the
        network): what a caller that uses only the first rows of a result computes instead.

        Example:
            >>> from tensordict import TensorDict
            >>> q = GPIQNetwork(6, 3, 2, hidden=(16, 16)).eval()
            >>> params = TensorDict.from_module(q).detach()
            >>> x, w = torch.randn(5, 6), torch.full((5, 2), 0.5)
            >>> torch.equal(q.forward_with(params, x, w), q(x, w))
            True
        """
        if params is None:
            get = lambda *path: functools.reduce(getattr, path, self)  # noqa: E731
        else:
            if not self.supports_forward_with:
                raise ValueError("forward_with takes parameters for flat observations only (this network has a "
                                 "NatureCNN per member)")
            get = lambda *path: params.get(path)  # noqa: E731

        def tensors(*path):
            w, b = get(*path, "weight"), get(*path, "bias")
            return (w, b) if members is None else (w[members], b[members])

        lead = preference.shape[:-1]
        chosen = range(self.num_nets) if members is None else range(self.num_nets)[members]
        e = len(chosen)
        dtype = self.out.weight.dtype
        if isinstance(self.state_features, nn.ModuleList):
            pixels = observation.reshape(-1, *self.obs_shape)
            sf = torch.stack([self.state_features[i](pixels) for i in chosen])
        else:
            s = observation.reshape(1, -1, observation.shape[-1]).to(dtype).expand(e, -1, -1)
            sf = batched_linear(s, *tensors("state_features"))
        w = preference.to(dtype).reshape(1, -1, preference.shape[-1]).expand(e, -1, -1)
        # relu in place on the fresh matmul outputs (their backward keeps the inputs, not the outputs)
        x = sf.relu_() * batched_linear(w, *tensors("weight_features")).relu_()
        for i in range(len(self.hidden)):
            norm = None if self.norms is None else (*tensors("norms", str(i)), self.norms[i].eps)
            x = hidden_block(x, *tensors("hidden", str(i)), norm, self.dropout, self.training, of_rows)
        return batched_linear(x, *tensors("out")).reshape(e, *lead, self.num_actions, self.num_objectives)


def gpi_action(q: torch.Tensor, preference: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """GPI over a support: ``q`` ``[*B, M, |A|, k]`` (``Q(s, a, w_i)`` for the ``M`` support weights),
    ``preference`` ``[*B, k]``; returns ``(action [*B], policy index [*B])`` maximising ``w . Q(s, a, w_i)``
    over ``(i, a)`` (ties: the lowest policy index, then the lowest action: ``argmax``'s first maximum).

    Example:
        >>> q = torch.tensor([[[[1.0, 0.0], [0.0, 0.0]], [[0.0, 0.0], [0.0, 2.0]]]])  # [B=1, M=2, A=2, k=2]
        >>> gpi_action(q, torch.tensor([[0.5, 0.5]]))
        (tensor([1]), tensor([1]))
    """
    scores = torch.einsum("...mak,...k->...ma", q, preference.to(q.dtype))
    best_a = scores.max(-1)  # per policy: max_a
    policy = best_a.values.argmax(-1)
    action = best_a.indices.gather(-1, policy.unsqueeze(-1)).squeeze(-1)
    return action, policy


class GPIPolicy(TensorDictModuleBase):
    """Acts by GPI over the weight support ``support`` ``[M, k]`` with the first member of the ensemble (as the authors).

    Reads ``observation`` and ``preference`` ``[*B, k]``; writes ``action`` (categorical index
    ``[*B]``) and ``policy_index``. ``include_preference`` adds each row's own ``w`` to the
    support (always the case with an empty support). ``dropout``: whether the Q-network's dropout
    is active (the authors: while acting in training, ``True``; not at evaluation, ``False``).

    Example:
        >>> from tensordict import TensorDict
        >>> policy = GPIPolicy(GPIQNetwork(4, 3, 2, hidden=(8, 8)), support=torch.eye(2))
        >>> td = policy(TensorDict(observation=torch.zeros(5, 4), preference=torch.full((5, 2), 0.5), batch_size=[5]))
        >>> td["action"].shape
        torch.Size([5])
    """

    def __init__(self, qnet: GPIQNetwork, support: torch.Tensor | None = None, *, include_preference: bool = False,
                 dropout: bool = True, observation_key: NestedKey = "observation",
                 preference_key: NestedKey = "preference", action_key: NestedKey = "action") -> None:
        super().__init__()
        self.qnet = qnet
        self.include_preference = include_preference
        self.dropout = dropout  # the authors: on while acting in training, off at evaluation (q_net.eval())
        self.support = torch.zeros(0, qnet.num_objectives) if support is None else torch.as_tensor(support).float()
        self.in_keys = [observation_key, preference_key]
        self.out_keys = [action_key, "policy_index"]

    def set_support(self, support) -> None:
        """Replace the support ``[M, k]`` (the policies GPI combines)."""
        self.support = torch.as_tensor(support, dtype=torch.float32)

    @torch.no_grad()
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        obs, w = tensordict.get(self.in_keys[0]), tensordict.get(self.in_keys[1])
        lead = w.shape[:-1]
        support = self.support.to(w.device, torch.float32).expand(*lead, -1, -1)
        if self.include_preference or support.shape[-2] == 0:
            support = torch.cat([support, w.unsqueeze(-2).float()], -2)
        m = support.shape[-2]
        obs_m = obs.unsqueeze(len(lead)).expand(*lead, m, *obs.shape[len(lead):])
        cached = self.__dict__.get("_qnet_modules")  # (qnet, its modules): the structure is fixed once built
        if cached is None or cached[0] is not self.qnet:
            cached = self.__dict__["_qnet_modules"] = (self.qnet, list(self.qnet.modules()))
        if all(m.training == self.dropout for m in cached[1]):  # (already in the mode: no switch and back)
            q = self.qnet(obs_m, support, members=slice(0, 1))[0]  # [*B, M, A, k]
        else:
            was = self.qnet.training
            self.qnet.train(self.dropout)
            try:
                q = self.qnet(obs_m, support, members=slice(0, 1))[0]
            finally:
                self.qnet.train(was)
        action, policy = gpi_action(q, w)
        tensordict.set(self.out_keys[0], action)
        tensordict.set(self.out_keys[1], policy)
        return tensordict


def thresholded_huber(x: torch.Tensor, threshold: float) -> torch.Tensor:
    """The authors' ``huber(|td|, min_priority)``: ``0.5 x^2`` below ``threshold``, ``threshold * x`` above; mean."""
    return torch.where(x < threshold, 0.5 * x.pow(2), threshold * x).mean()


class GPILoss(MultiObjectiveLossModule):
    r"""The GPI-LS / GPI-PD loss on a batch of transitions with ``[*B, k]`` rewards.

    The weights come from the loss's state (set them with :meth:`set_weights` at each weight-support iteration),
    not from the batch, as in the authors' ``update(weight)``: with a support of ``M > 1`` weights the batch is
    doubled, the first half under the current weight ``w``, the second under weights drawn uniformly from the
    support. Target: :math:`r + \gamma (1 - d)\, Q^-_{e^*}(s', a^*, w)` with :math:`e^*` the member of the target
    ensemble with the lowest :math:`w \cdot Q^-_e(s', a, w)` (per action) and :math:`a^*` its greedy action. Loss:
    the mean over members of :func:`thresholded_huber` of :math:`|Q_e(s, a, w) - y|` (threshold ``min_priority``).

    The priority written under ``"td_error"`` for the first ``B`` rows (the real batch) is :math:`\max(|w \cdot
    \max_e |Q_e - y||, \text{min\_priority})`; with ``gpi_pd=True`` the target is the GPI target :math:`y^{GPI}`:
    the best (support weight, action) pair under ``w`` over ``w`` and 4 support weights drawn at random (the whole
    support when it has at most 5), with the same minimum over target members. The prioritized sampler raises it to
    its ``alpha`` (the authors store ``priority ** alpha``). Importance weights are not applied (the authors' PER
    buffer has none).

    Args:
        value_network: a :class:`GPIQNetwork`.
        gpi_pd: GPI priorities. Defaults to ``False`` (GPI-LS).
        min_priority: Huber threshold and minimum priority. Defaults to 0.01.
        gpi_samples: support weights drawn for the GPI target besides ``w``. Defaults to 4.

    Example:
        >>> q = GPIQNetwork(6, 3, 2, hidden=(32, 32))
        >>> loss = GPILoss(q, gpi_pd=True)
        >>> loss.make_value_estimator(gamma=0.99)  # doctest: +ELLIPSIS
        GPILoss(...)
        >>> loss.set_weights(torch.tensor([0.5, 0.5]), torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]]))
        >>> B = 8
        >>> data = TensorDict({
        ...     "observation": torch.randn(B, 6), "action": torch.randint(3, (B,)),
        ...     ("next", "observation"): torch.randn(B, 6), ("next", "reward"): torch.randn(B, 2),
        ...     ("next", "done"): torch.zeros(B, 1, dtype=torch.bool),
        ...     ("next", "terminated"): torch.zeros(B, 1, dtype=torch.bool)}, [B])
        >>> out = loss(data)
        >>> out["loss_qvalue"].backward()
        >>> data["td_error"].shape
        torch.Size([8])
    """

    @dataclass
    class _AcceptedKeys:
        """Configurable tensordict keys (``loss.set_keys(name=key)``)."""

        observation: NestedKey = "observation"
        action: NestedKey = "action"
        preference: NestedKey = "preference"
        value_target: NestedKey = "value_target"
        priority: NestedKey = "td_error"
        reward: NestedKey = "reward"
        done: NestedKey = "done"
        terminated: NestedKey = "terminated"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    value_network: TensorDictModule
    value_network_params: TensorDictBase
    target_value_network_params: TensorDictBase

    def __init__(self, value_network: GPIQNetwork, *, gpi_pd: bool = False, min_priority: float = 0.01,
                 gpi_samples: int = 4) -> None:
        self._in_keys = None
        super().__init__()
        if not isinstance(value_network, GPIQNetwork):
            raise ValueError(f"value_network must be a GPIQNetwork, got {type(value_network).__name__}")
        if min_priority <= 0:
            raise ValueError(f"min_priority must be > 0, got {min_priority}")
        self.num_objectives = value_network.num_objectives
        self.num_nets = value_network.num_nets
        self.gpi_pd = gpi_pd
        self.min_priority = float(min_priority)
        self.gpi_samples = int(gpi_samples)
        module = TensorDictModule(value_network, in_keys=["observation", "preference"], out_keys=["action_value"])
        self.convert_to_functional(module, "value_network", create_target_params=True)
        k, device = self.num_objectives, next(value_network.parameters()).device
        # on the network's device: the recipe does not move the loss (found by the first GPU run)
        self.register_buffer("current_weight", torch.full((k,), 1.0 / k, device=device))
        self.register_buffer("weight_support", torch.full((1, k), 1.0 / k, device=device))

    def set_weights(self, weight: torch.Tensor, support: torch.Tensor) -> None:
        """The iteration's weight ``w`` ``[k]`` and the weight support ``M`` ``[m, k]``."""
        weight = torch.as_tensor(weight, dtype=torch.float32).reshape(-1)
        support = torch.as_tensor(support, dtype=torch.float32).reshape(-1, self.num_objectives)
        if weight.shape[0] != self.num_objectives or support.shape[0] == 0:
            raise ValueError(f"weight must be [{self.num_objectives}] and support a non-empty [m, {self.num_objectives}], "
                             f"got {tuple(weight.shape)} and {tuple(support.shape)}")
        self.current_weight = weight.to(self.current_weight.device)
        self.weight_support = support.to(self.current_weight.device)

    def _load_from_state_dict(self, state_dict, prefix, *args, **kwargs):
        saved = state_dict.get(prefix + "weight_support")
        if saved is not None:  # the support's size changes over a run: take the saved one's
            self.weight_support = torch.empty_like(saved, device=self.weight_support.device)
        # (named, not super(): GPIContinuousLoss borrows this method, and a zero-argument super()
        # inside it would refuse an instance that is not a GPILoss)
        MultiObjectiveLossModule._load_from_state_dict(self, state_dict, prefix, *args, **kwargs)

    def _set_in_keys(self) -> None:
        k = self.tensor_keys
        self._in_keys = [k.observation, k.action, ("next", k.observation), ("next", k.reward), ("next", k.done),
                         ("next", k.terminated)]

    @property
    def out_keys(self) -> list[str]:
        return ["loss_qvalue", "td_error_mean", "scalarized_q"]

    # ---------------------------------------------------------------- pieces
    def _q(self, params, obs: torch.Tensor, w: torch.Tensor, members: slice | None = None) -> torch.Tensor:
        net = self.value_network.module
        if net.supports_forward_with:  # the same operations, without swapping the parameters in and out
            return net.forward_with(params.get("module"), obs, w, members)
        with params.to_module(self.value_network, preserve_module_state=False):
            return net(obs, w, members=members)

    def _q_first_rows(self, params, obs: torch.Tensor, w: torch.Tensor, rows: int) -> torch.Tensor:
        """``_q(params, obs, w)[:, :rows]`` (rows of ``obs``'s first dim), each row as the whole batch's run gives it
        (the same dropout draws), computing only those rows where the network takes given parameters."""
        net = self.value_network.module
        if rows >= obs.shape[0]:
            return self._q(params, obs, w)
        if not net.supports_forward_with:
            return self._q(params, obs, w)[:, :rows]
        per_row = w[0].numel() // w.shape[-1]  # rows of the network per row of obs (e.g. support weights)
        return net.forward_with(params.get("module"), obs[:rows], w[:rows], of_rows=obs.shape[0] * per_row)

    @torch.no_grad()
    def _min_member(self, q: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
        """``[E, *B, A, k]`` -> ``[*B, A, k]``: per action the member with the lowest ``w . Q``."""
        scal = torch.einsum("e...ak,...k->e...a", q, w)
        idx = argmin_along(scal, 0, keepdim=True).unsqueeze(-1).expand(1, *q.shape[1:])
        return q.gather(0, idx).squeeze(0)

    @torch.no_grad()
    def td_target_value(self, next_obs: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
        """``[B, k]``: ``Q^-_{e*}(s', a*, w)``, the min-member target's greedy value under ``w``."""
        q = self._min_member(self._q(self.target_value_network_params, next_obs, w), w)  # [B, A, k]
        best = torch.einsum("bak,bk->ba", q, w).argmax(-1)
        return q.gather(1, best.view(-1, 1, 1).expand(-1, 1, q.shape[-1])).squeeze(1)

    @torch.no_grad()
    def gpi_target_value(self, next_obs: torch.Tensor, w: torch.Tensor, sampled: torch.Tensor,
                         rows: int | None = None) -> torch.Tensor:
        """``[B, k]``: the GPI target over the support weights ``sampled`` ``[P, k]`` (the authors' ``_envelope_target``).

        ``rows``: only the first ``rows`` of it, computed alone (``[rows, k]``), each as in the whole
        (:meth:`GPIQNetwork.forward_with`'s ``of_rows``): what the loss reads (the priorities of the real batch)."""
        b, p = next_obs.shape[0], sampled.shape[0]
        obs = next_obs.unsqueeze(1).expand(b, p, *next_obs.shape[1:])
        W = sampled.unsqueeze(0).expand(b, p, sampled.shape[-1])
        if rows is not None and rows < b:
            q = self._q_first_rows(self.target_value_network_params, obs, W, rows)  # [E, rows, P, A, k]
            b, w = rows, w[:rows]
        else:
            q = self._q(self.target_value_network_params, obs, W)  # [E, B, P, A, k]
        scal = torch.einsum("ebpak,bk->ebpa", q, w)
        idx = argmin_along(scal, 0, keepdim=True).unsqueeze(-1).expand(1, *q.shape[1:])
        q = q.gather(0, idx).squeeze(0)  # [B, P, A, k]
        action, policy = gpi_action(q, w)
        k = q.shape[-1]
        q_pol = q.gather(1, policy.view(b, 1, 1, 1).expand(b, 1, q.shape[2], k)).squeeze(1)
        return q_pol.gather(1, action.view(b, 1, 1).expand(b, 1, k)).squeeze(1)

    def _sampled_support(self) -> torch.Tensor:
        support = self.weight_support
        if support.shape[0] > self.gpi_samples + 1:
            pick = torch.randperm(support.shape[0], device=support.device)[: self.gpi_samples]
            return torch.cat([self.current_weight.unsqueeze(0), support[pick]])
        return support

    @torch.no_grad()
    def priorities(self, tensordict: TensorDictBase) -> torch.Tensor:
        """``[B]`` priorities of stored transitions under the current weight (the authors' ``_reset_priorities``,
        run at each new iteration): ``max(|w . (r + gamma (1 - d) y' - Q_0(s, a, w))|, min_priority)`` with ``y'``
        the GPI target over the whole support (GPI-PD) or the double-DQN value of member 0."""
        data = tensordict.reshape(-1)
        keys, b = self.tensor_keys, data.shape[0]
        obs, next_obs = data.get(keys.observation), data.get(("next", keys.observation))
        w = self.current_weight.expand(b, -1)
        action = action_index(data.get(keys.action), b, self.value_network.module.num_actions)
        q = self._q(self.value_network_params, obs, w, members=slice(0, 1))[0]
        q_a = q.gather(1, action.view(b, 1, 1).expand(b, 1, q.shape[-1])).squeeze(1)
        if self.gpi_pd:
            nxt = self.gpi_target_value(next_obs, w, self.weight_support)
        else:
            best = torch.einsum("bak,bk->ba", self._q(self.value_network_params, next_obs, w, slice(0, 1))[0], w).argmax(-1)
            qt = self._q(self.target_value_network_params, next_obs, w, slice(0, 1))[0]
            nxt = qt.gather(1, best.view(b, 1, 1).expand(b, 1, qt.shape[-1])).squeeze(1)
        reward = data.get(("next", keys.reward))
        terminated = data.get(("next", keys.terminated)).reshape(b, 1)
        td = vector_td0_return_estimate(self.value_estimator.gamma, nxt, reward, terminated) - q_a
        return torch.einsum("bk,bk->b", w, td).abs().clamp(min=self.min_priority)

    # ---------------------------------------------------------------- forward
    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """The loss on ``B`` transitions; writes the ``[B]`` priorities under ``tensor_keys.priority``."""
        self._check_inputs(tensordict, needs_preference=False)
        data = tensordict.reshape(-1)
        keys = self.tensor_keys
        b = data.shape[0]
        obs, next_obs = data.get(keys.observation), data.get(("next", keys.observation))
        action = action_index(data.get(keys.action), b, self.value_network.module.num_actions)
        reward = data.get(("next", keys.reward))
        terminated = data.get(("next", keys.terminated)).reshape(b, 1)
        w_now = self.current_weight.expand(b, -1)
        support = self.weight_support
        if support.shape[0] > 1:  # half under w, half under support weights
            drawn = support[torch.randint(support.shape[0], (b,), device=support.device)]
            w = torch.cat([w_now, drawn])
            obs, next_obs, action = torch.cat([obs, obs]), torch.cat([next_obs, next_obs]), action.repeat(2)
            reward, terminated = reward.repeat(2, 1), terminated.repeat(2, 1)
        else:
            w = w_now
        gamma = self.value_estimator.gamma
        target = vector_td0_return_estimate(gamma, self.td_target_value(next_obs, w), reward, terminated)
        if self.gpi_pd:  # (for the real batch's priorities: the first b rows, computed alone)
            gpi_value = self.gpi_target_value(next_obs, w, self._sampled_support(), rows=b)
            gpi_target = vector_td0_return_estimate(gamma, gpi_value, reward[:b], terminated[:b])

        q = self._q(self.value_network_params, obs, w)  # [E, 2B, A, k]
        k = q.shape[-1]
        q_taken = q.gather(2, action.view(1, -1, 1, 1).expand(q.shape[0], -1, 1, k)).squeeze(2)  # [E, 2B, k]
        td = (q_taken - target).abs()
        loss = torch.stack([thresholded_huber(td[e], self.min_priority) for e in range(td.shape[0])]).mean()
        err = ((q_taken[:, :b] - gpi_target).abs() if self.gpi_pd else td[:, :b]).detach().max(0).values
        priority = torch.einsum("bk,bk->b", w[:b], err).abs().clamp(min=self.min_priority)
        tensordict.set(keys.priority, priority.reshape(tensordict.shape))
        out = TensorDict({"loss_qvalue": loss, "td_error_mean": td.detach().mean(),
                          "scalarized_q": torch.einsum("ebk,bk->eb", q_taken.detach(), w).mean()}, batch_size=[])
        clear_weakrefs(self, tensordict, out, "value_network_params", "target_value_network_params")
        return out


# ============================================================================ continuous actions
class GPIActor(nn.Module):
    """The authors' continuous ``Policy``: ``tanh(MLP(s, w))`` rescaled to ``[low, high]`` (ReLU MLP, orthogonal init).

    ``forward(observation, preference, noise=None, noise_clip=None)``: with ``noise``, Gaussian noise
    of that std clipped to ``+-noise_clip`` is added before the rescaling, then clamped to ``[-1, 1]``.

    Example:
        >>> actor = GPIActor(5, 2, 3, low=-torch.ones(3), high=torch.ones(3), hidden=(8, 8))
        >>> actor(torch.zeros(4, 5), torch.full((4, 2), 0.5)).shape
        torch.Size([4, 3])
    """

    def __init__(self, obs_dim: int, num_objectives: int, action_dim: int, *, low, high, hidden=(256, 256)) -> None:
        super().__init__()
        layers, width = [], obs_dim + num_objectives
        for h in hidden:
            layers += [nn.Linear(width, h), nn.ReLU()]
            width = h
        self.latent = nn.Sequential(*layers)
        self.mean = nn.Linear(width, action_dim)
        for m in self.modules():
            if isinstance(m, nn.Linear):
                nn.init.orthogonal_(m.weight)
                nn.init.zeros_(m.bias)
        low, high = torch.as_tensor(low, dtype=torch.float32), torch.as_tensor(high, dtype=torch.float32)
        self.register_buffer("action_scale", (high - low) / 2)
        self.register_buffer("action_bias", (high + low) / 2)
        self.num_objectives = num_objectives

    def forward(self, observation, preference, noise: float | None = None, noise_clip: float | None = None):
        x = torch.cat([observation.to(self.mean.weight.dtype), preference.to(self.mean.weight.dtype)], -1)
        a = torch.tanh(self.mean(self.latent(x)))
        if noise:
            a = (a + (torch.randn_like(a) * noise).clamp(-noise_clip, noise_clip)).clamp(-1, 1)
        return a * self.action_scale + self.action_bias


class GPIVectorCritic(nn.Module):
    """``E`` vector critics ``Q_e(s, a, w)`` ``[E, *B, k]`` as one batched module (the authors' continuous
    ``QNetwork``: ``MLP(s, a, w)`` with Linear-Dropout-LayerNorm-ReLU blocks).

    Example:
        >>> GPIVectorCritic(5, 3, 2, hidden=(8, 8))(torch.zeros(4, 5), torch.zeros(4, 3), torch.full((4, 2), .5)).shape
        torch.Size([2, 4, 2])
    """

    def __init__(self, obs_dim: int, action_dim: int, num_objectives: int, *, hidden=(256, 256), num_nets: int = 2,
                 dropout: float = 0.01, layer_norm: bool = True) -> None:
        super().__init__()
        widths = (obs_dim + action_dim + num_objectives, *hidden)
        self.layers = nn.ModuleList(BatchedLinear(num_nets, a, b) for a, b in zip(widths[:-1], widths[1:]))
        self.norms = nn.ModuleList(BatchedLayerNorm(num_nets, b) for b in hidden) if layer_norm else None
        self.out = BatchedLinear(num_nets, widths[-1], num_objectives)
        self.dropout, self.num_nets, self.num_objectives = dropout, num_nets, num_objectives

    def forward(self, observation, action, preference):
        lead = observation.shape[:-1]
        x = torch.cat([observation, action, preference], -1).to(self.out.weight.dtype)
        x = x.reshape(1, -1, x.shape[-1]).expand(self.num_nets, -1, -1)
        for i, layer in enumerate(self.layers):
            x = linear_dropout_norm_relu(x, layer, None if self.norms is None else self.norms[i], self.dropout,
                                         self.training)
        return self.out(x).reshape(self.num_nets, *lead, self.num_objectives)


class GPIContinuousPolicy(TensorDictModuleBase):
    """Acts with the actor for the row's ``w`` (``noise``: the authors' exploration, ``policy_noise`` clipped), or,
    with ``gpi=True``, by GPI over the support: the candidate actions ``a_j = pi(s, w_j)`` scored by
    ``w . Q_0(s, a_j, w_i)``, the best ``(i, j)`` acting (the authors' ``eval``; the critic's dropout
    stays as its mode is: the authors never switch it off).

    ``context_table`` ``[E, c]`` (the evaluation contexts, in the evaluator's order) reproduces the authors'
    vectorised evaluator (``gpi_pd_continuous_action.py:510-526``): for a row whose ``"context"`` is evaluation
    context ``e`` of ``E``, the critic's conditioning weight of candidate row ``i`` is ``w_floor((e * M + i) / E)``
    instead of ``w_i`` (their ``repeat_interleave(M * num_envs)``; a slip, SPEC §6). Without it (or a ``"context"``
    entry) every row uses ``w_i``, as their single-env path.

    Example:
        >>> from tensordict import TensorDict
        >>> actor = GPIActor(4, 2, 3, low=-torch.ones(3), high=torch.ones(3), hidden=(8,))
        >>> policy = GPIContinuousPolicy(actor, GPIVectorCritic(4, 3, 2, hidden=(8,)), support=torch.eye(2), gpi=True)
        >>> policy(TensorDict(observation=torch.zeros(5, 4), preference=torch.full((5, 2), .5), batch_size=[5]))["action"].shape
        torch.Size([5, 3])
    """

    def __init__(self, actor: GPIActor, critic: GPIVectorCritic | None = None, support=None, *, gpi: bool = False,
                 noise: float | None = None, noise_clip: float | None = None,
                 context_table: torch.Tensor | None = None) -> None:
        super().__init__()
        self.actor, self.critic, self.gpi = actor, critic, gpi
        self.noise, self.noise_clip = noise, noise_clip
        self.support = torch.zeros(0, actor.num_objectives) if support is None else torch.as_tensor(support).float()
        self.context_table = None if context_table is None else torch.as_tensor(context_table, dtype=torch.float32)
        self.in_keys, self.out_keys = ["observation", "preference"], ["action"]

    def conditioning(self, tensordict: TensorDictBase, lead, m: int) -> torch.Tensor:
        """``[*B, m, k]``: the critic's conditioning weight of each candidate row ``i`` (see the class)."""
        support = self.support.to(tensordict.device or "cpu")
        ctx = tensordict.get("context", None) if self.context_table is not None else None
        if ctx is None or ctx.shape[-1] == 0:  # (an env without context parameters: its one context)
            return support.expand(*lead, m, support.shape[-1])
        table = self.context_table.to(ctx.device)
        e = torch.cdist(ctx.float().reshape(-1, ctx.shape[-1]), table).argmin(-1).reshape(lead)  # [*B]
        index = (e.unsqueeze(-1) * m + torch.arange(m, device=e.device)) // table.shape[0]  # [*B, m]
        return support.to(e.device)[index]

    def set_support(self, support) -> None:
        self.support = torch.as_tensor(support, dtype=torch.float32)

    @torch.no_grad()
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        obs, w = tensordict.get("observation"), tensordict.get("preference").float()
        if not self.gpi or self.support.shape[0] == 0:
            tensordict.set("action", self.actor(obs, w, self.noise, self.noise_clip))
            return tensordict
        lead, m = w.shape[:-1], self.support.shape[0]
        M = self.support.to(w.device).expand(*lead, m, w.shape[-1])
        obs_m = obs.unsqueeze(-2).expand(*lead, m, obs.shape[-1])
        actions = self.actor(obs_m, M)  # [*B, m(j), act]
        cond = self.conditioning(tensordict, lead, m).to(w.device)  # [*B, m(i), k]: w_i (or the authors' slip)
        # Q_0(s, a_j, w_i): [*B, i, j, k]
        q = self.critic(obs_m.unsqueeze(-3).expand(*lead, m, m, obs.shape[-1]),
                        actions.unsqueeze(-3).expand(*lead, m, m, actions.shape[-1]),
                        cond.unsqueeze(-2).expand(*lead, m, m, w.shape[-1]))[0]
        best_j = gpi_action(q, w)[0]  # gpi_action's "action" axis is the candidate j
        tensordict.set("action", actions.gather(-2, best_j[..., None, None].expand(*lead, 1, actions.shape[-1])).squeeze(-2))
        return tensordict


class GPIContinuousLoss(MultiObjectiveLossModule):
    r"""The authors' continuous GPI-LS / GPI-PD update (TD3 with vector critics conditioned on ``w``).

    Weights as :class:`GPILoss` (half the batch under ``w``, half under support weights). Critic:
    target action :math:`\pi^-(s', w)` plus clipped noise (``policy_noise``, ``noise_clip``), target the
    member of the target critics with the lowest :math:`w \cdot Q^-_e`, loss the mean over members of
    the MSE. Actor: :math:`-w \cdot \frac1E \sum_e Q_e(s, \pi(s, w), w)` (critics held fixed).
    Priority: :math:`\max(|w \cdot 0.05\,|Q_0 - y||, \text{min\_priority})` on the first ``B`` rows.
    ``loss_actor`` is for a summed backward; the authors step the critics first and then the actor
    against the updated critics: :meth:`actor_loss` after the critic step does that.

    Example:
        >>> actor = GPIActor(5, 2, 3, low=-torch.ones(3), high=torch.ones(3), hidden=(16,))
        >>> loss = GPIContinuousLoss(actor, GPIVectorCritic(5, 3, 2, hidden=(16,)))
        >>> loss.make_value_estimator(gamma=0.99)  # doctest: +ELLIPSIS
        GPIContinuousLoss(...)
        >>> td = TensorDict({"observation": torch.randn(8, 5), "action": torch.rand(8, 3) * 2 - 1,
        ...     ("next", "observation"): torch.randn(8, 5), ("next", "reward"): torch.randn(8, 2),
        ...     ("next", "done"): torch.zeros(8, 1, dtype=torch.bool),
        ...     ("next", "terminated"): torch.zeros(8, 1, dtype=torch.bool)}, [8])
        >>> out = loss(td)
        >>> sorted(k for k in out.keys() if k.startswith("loss_"))
        ['loss_actor', 'loss_qvalue']
    """

    _AcceptedKeys = GPILoss._AcceptedKeys
    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    actor_network: TensorDictModule
    actor_network_params: TensorDictBase
    target_actor_network_params: TensorDictBase
    qvalue_network: TensorDictModule
    qvalue_network_params: TensorDictBase
    target_qvalue_network_params: TensorDictBase

    def __init__(self, actor: GPIActor, critic: GPIVectorCritic, *, policy_noise: float = 0.2, noise_clip: float = 0.5,
                 min_priority: float = 0.1) -> None:
        self._in_keys = None
        super().__init__()
        self.num_objectives = critic.num_objectives
        self.policy_noise, self.noise_clip, self.min_priority = policy_noise, noise_clip, float(min_priority)
        self.convert_to_functional(TensorDictModule(actor, in_keys=["observation", "preference"], out_keys=["action"]),
                                   "actor_network", create_target_params=True)
        self.convert_to_functional(TensorDictModule(critic, in_keys=["observation", "action", "preference"],
                                                    out_keys=["state_action_value"]),
                                   "qvalue_network", create_target_params=True)
        k, device = self.num_objectives, next(critic.parameters()).device
        self.register_buffer("current_weight", torch.full((k,), 1.0 / k, device=device))
        self.register_buffer("weight_support", torch.full((1, k), 1.0 / k, device=device))

    set_weights = GPILoss.set_weights
    _load_from_state_dict = GPILoss._load_from_state_dict
    _set_in_keys = GPILoss._set_in_keys

    @property
    def out_keys(self) -> list[str]:
        return ["loss_qvalue", "loss_actor", "scalarized_q"]

    def actor_loss(self) -> torch.Tensor:
        """The actor loss on the (doubled) batch of the last :meth:`forward`, with the critics as they are now:
        a trainer that steps the critics first and the actor after (the authors' order) calls it after the step."""
        obs, w = self.last_actor_inputs
        pi = self._actor(self.actor_network_params, obs, w)
        q_pi = self._critic(self.qvalue_network_params.detach().clone(), obs, pi, w).mean(0)
        return -torch.einsum("bk,bk->b", q_pi, w).mean()

    def _actor(self, params, obs, w, noise=None):
        with params.to_module(self.actor_network, preserve_module_state=False):
            return self.actor_network.module(obs, w, noise, self.noise_clip)

    def _critic(self, params, obs, a, w):
        with params.to_module(self.qvalue_network, preserve_module_state=False):
            return self.qvalue_network.module(obs, a, w)

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        self._check_inputs(tensordict, needs_preference=False)
        data, keys = tensordict.reshape(-1), self.tensor_keys
        b = data.shape[0]
        obs, next_obs = data.get(keys.observation), data.get(("next", keys.observation))
        action, reward = data.get(keys.action).reshape(b, -1), data.get(("next", keys.reward))
        terminated = data.get(("next", keys.terminated)).reshape(b, 1)
        w = self.current_weight.expand(b, -1)
        support = self.weight_support
        if support.shape[0] > 1:
            w = torch.cat([w, support[torch.randint(support.shape[0], (b,), device=support.device)]])
            obs, next_obs, action = obs.repeat(2, 1), next_obs.repeat(2, 1), action.repeat(2, 1)
            reward, terminated = reward.repeat(2, 1), terminated.repeat(2, 1)
        with torch.no_grad():
            next_a = self._actor(self.target_actor_network_params, next_obs, w, self.policy_noise)
            qt = self._critic(self.target_qvalue_network_params, next_obs, next_a, w)  # [E, 2B, k]
            idx = argmin_along(torch.einsum("ebk,bk->eb", qt, w), 0).view(1, -1, 1).expand(1, *qt.shape[1:])
            target = vector_td0_return_estimate(self.value_estimator.gamma, qt.gather(0, idx)[0], reward, terminated)
        q = self._critic(self.qvalue_network_params, obs, action, w)
        loss_q = torch.stack([F.mse_loss(q[e], target) for e in range(q.shape[0])]).mean()
        err = ((q[0] - target).detach().abs() * 0.05)[:b]
        tensordict.set(keys.priority, torch.einsum("bk,bk->b", err, w[:b]).clamp(min=self.min_priority)
                       .reshape(tensordict.shape))
        self.last_actor_inputs = (obs.detach(), w.detach())
        loss_actor = self.actor_loss()
        out = TensorDict({"loss_qvalue": loss_q, "loss_actor": loss_actor,
                          "scalarized_q": torch.einsum("bk,bk->b", q[0].detach(), w).mean()}, batch_size=[])
        clear_weakrefs(self, tensordict, out, "actor_network_params", "target_actor_network_params",
                       "qvalue_network_params", "target_qvalue_network_params")
        return out
