"""Envelope Q-learning (Yang, Sun & Narasimhan, NeurIPS 2019) as a TorchRL loss."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase, TensorDictParams
from tensordict.nn import TensorDictModule, dispatch
from tensordict.utils import NestedKey
from torch import nn
from torchrl.objectives.utils import distance_loss

from morl_trl._torchrl_compat import clear_weakrefs, priority_weight, reduce_loss
from morl_trl.objectives.common import MultiObjectiveLossModule, expanded_selection, module_output
from morl_trl.objectives.fast_path import FunctionalNetwork

__all__ = ["EnvelopeQLoss"]


def action_index(action: torch.Tensor, batch: int, num_actions: int) -> torch.Tensor:
    """``[B]`` integer indices from integer (``[B]``/``[B, 1]``) or one-hot (``[B, A]``) actions."""
    if not (torch.is_floating_point(action) or action.dtype == torch.bool) and action.numel() == batch:
        return action.reshape(batch).long()
    if action.shape == (batch, num_actions):
        return action.argmax(-1)
    raise ValueError(
        f"action has shape {tuple(action.shape)} and dtype {action.dtype}; expected integer indices "
        f"of shape [{batch}] or [{batch}, 1], or one-hot actions of shape [{batch}, {num_actions}]."
    )


class EnvelopeQLoss(MultiObjectiveLossModule):
    r"""Envelope multi-objective Q-learning loss.

    A vector Q-network :math:`Q(s, \cdot, w) \in \mathbb{R}^{|A| \times k}` conditioned on the
    preference :math:`w` is regressed, for each transition :math:`j` and each of ``N`` sampled
    preferences :math:`w_i`, onto the envelope target

    .. math::

        y_{ij} = r_j + \gamma (1 - d_j)\, Q^{-}(s'_j, a^*, w^*), \quad
        (a^*, w^*) = \arg\max_{a',\, w' \in W_j} w_i^\top Q(s'_j, a', w')

    (:math:`W_j` the sampled preferences; the argmax by the online network, the value by the target
    network :math:`Q^-`). The loss is the homotopy :math:`(1-\lambda) L_A + \lambda L_B` of the vector
    regression :math:`L_A = \|Q(s, a, w) - y\|^2` and its scalarisation :math:`L_B = (w^\top Q - w^\top y)^2`.
    The preference dimension is folded into the batch: one forward per network over ``B * N`` rows
    (MORL-Baselines evaluates ``B * N * N``). The per-transition TD error is written under
    ``tensor_keys.priority`` for :meth:`TensorDictReplayBuffer.update_tensordict_priority`.

    Args:
        value_network (TensorDictModule or nn.Module): reads the observation keys and the preference,
            writes ``"action_value"`` ``[*B, |A|, k]`` (an ``nn.Module`` is wrapped with
            ``in_keys=["observation", "preference"]``; :func:`~morl_trl.objectives.networks.make_vector_q_network`).

    Keyword Args:
        num_objectives (int, optional): ``k``; read from networks made by the builders.
        num_preference_samples (int): ``N`` per transition. Defaults to 8.
        shared_preferences (bool): one set of ``N`` for the whole batch (the paper, MORL-Baselines) rather
            than one per transition. Defaults to ``True``.
        include_batch_preference (bool): the batch's own ``"preference"`` replaces each transition's first
            sample. Defaults to ``False``.
        preference_distribution (str): ``"gaussian"`` (``|N(0, I)|`` normalised, MORL-Baselines'; default)
            or ``"dirichlet"`` (uniform on the simplex).
        envelope (bool): the envelope target; ``False``: the scalarised double-DQN target per preference.
        double_dqn (bool): the target's argmax by the online network. Defaults to ``True``.
        homotopy_lambda (float): the initial :math:`\lambda` (or set ``loss.homotopy_lambda``). Defaults to 0.
        final_homotopy_lambda (float): :math:`\lambda` after ``homotopy_steps`` (:meth:`update_homotopy`).
        homotopy_steps (int, optional): the linear schedule's length; ``None`` keeps :math:`\lambda` fixed.
        loss_function (str): ``"l2"`` (default), ``"l1"`` or ``"smooth_l1"``.
        delay_value (bool): keep target parameters (``HardUpdate`` / ``SoftUpdate``). Defaults to ``True``.
        reduction (str): ``"mean"`` (default), ``"sum"`` or ``"none"``.
        use_prioritized_weights (bool or "auto"): weight samples by a prioritized sampler's
            ``"priority_weight"`` (MORL-Baselines applies none: the recipe passes ``per_importance_weights``).
        priority (str): the TD error written for prioritized replay: ``"first"`` (default, as MORL-Baselines
            and the paper's runs) :math:`|w_0^\top (Q(s_j, a_j, w_0) - y_{0j})|` under the first sampled
            preference only; ``"mean"``: its mean over the ``N`` preferences.

    Examples:
        >>> from tensordict import TensorDict
        >>> from morl_trl.objectives.networks import make_vector_q_network
        >>> q = make_vector_q_network(6, 3, 2, num_cells=(32, 32))
        >>> from torchrl.objectives import HardUpdate
        >>> loss = EnvelopeQLoss(q, num_preference_samples=4, homotopy_lambda=0.95)
        >>> loss.make_value_estimator(gamma=0.99)  # doctest: +ELLIPSIS
        EnvelopeQLoss(...)
        >>> updater = HardUpdate(loss, value_network_update_interval=1000)  # call updater.step() per update
        >>> B = 16
        >>> data = TensorDict({
        ...     "observation": torch.randn(B, 6),
        ...     "action": torch.randint(3, (B,)),
        ...     ("next", "observation"): torch.randn(B, 6),
        ...     ("next", "reward"): torch.randn(B, 2),
        ...     ("next", "done"): torch.zeros(B, 1, dtype=torch.bool),
        ...     ("next", "terminated"): torch.zeros(B, 1, dtype=torch.bool),
        ... }, [B])
        >>> out = loss(data)
        >>> sorted(out.keys())
        ['homotopy_lambda', 'loss_qvalue', 'scalarized_loss', 'scalarized_q', 'vector_loss']
        >>> out["loss_qvalue"].backward()
        >>> data["td_error"].shape
        torch.Size([16])
    """

    @dataclass
    class _AcceptedKeys:
        """Configurable tensordict keys (``loss.set_keys(name=key)``): the network's output
        ``[*B, |A|, k]``, the action (integer or one-hot), the preference ``[*B, k]``, the estimator's
        target, where the TD error is written, the importance weights, and under ``"next"`` the vector
        reward ``[*B, k]`` and the done and terminated flags."""

        action_value: NestedKey = "action_value"
        action: NestedKey = "action"
        preference: NestedKey = "preference"
        value_target: NestedKey = "value_target"
        priority: NestedKey = "td_error"
        priority_weight: NestedKey = "priority_weight"
        reward: NestedKey = "reward"
        done: NestedKey = "done"
        terminated: NestedKey = "terminated"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    #: evaluate the networks :func:`~morl_trl.objectives.networks.make_vector_q_network` builds from their
    #: parameter leaves (:mod:`morl_trl.objectives.fast_path`: the same values); ``False``: TorchRL's ``to_module``
    fast_networks: bool = True
    _schedulable_buffers = frozenset({"homotopy_lambda"})

    value_network: TensorDictModule
    value_network_params: TensorDictParams
    target_value_network_params: TensorDictParams

    def __init__(self, value_network: TensorDictModule | nn.Module, *, num_objectives: int | None = None,
                 num_preference_samples: int = 8, shared_preferences: bool = True,
                 include_batch_preference: bool = False, preference_distribution: str = "gaussian",
                 envelope: bool = True, double_dqn: bool = True, homotopy_lambda: float = 0.0,
                 final_homotopy_lambda: float = 1.0, homotopy_steps: int | None = None, loss_function: str = "l2",
                 delay_value: bool = True, reduction: str = "mean", use_prioritized_weights: str | bool = "auto",
                 priority: str = "first") -> None:
        self._in_keys = None
        super().__init__()
        if not isinstance(value_network, TensorDictModule):
            value_network = TensorDictModule(value_network, in_keys=["observation", "preference"], out_keys=["action_value"])
        if double_dqn and not delay_value:
            raise ValueError("double_dqn=True requires delay_value=True.")
        if num_preference_samples < 1:
            raise ValueError(f"num_preference_samples must be >= 1, got {num_preference_samples}.")
        for name, lam in (("homotopy_lambda", homotopy_lambda), ("final_homotopy_lambda", final_homotopy_lambda)):
            if not 0.0 <= lam <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1], got {lam}.")
        if reduction not in ("mean", "sum", "none"):
            raise ValueError(f"reduction={reduction!r}; valid values are 'mean', 'sum', 'none'.")
        if priority not in ("first", "mean"):
            raise ValueError(f"priority={priority!r}; valid values are 'first', 'mean'.")
        self.priority = priority
        self.num_objectives = self._resolve_num_objectives(num_objectives, value_network)
        self.num_preference_samples = int(num_preference_samples)
        self.shared_preferences = shared_preferences
        self.include_batch_preference = include_batch_preference
        self.preference_distribution = self._check_distribution(preference_distribution)
        self.envelope = envelope
        self.double_dqn = double_dqn
        self.delay_value = delay_value
        self.loss_function = loss_function
        self.reduction = reduction
        self.use_prioritized_weights = use_prioritized_weights
        self.convert_to_functional(value_network, "value_network", create_target_params=delay_value)
        device = next(iter(self.value_network_params.values(True, True))).device
        self.register_buffer("homotopy_lambda", torch.tensor(float(homotopy_lambda), device=device))
        self.initial_homotopy_lambda = float(homotopy_lambda)
        self.final_homotopy_lambda = float(final_homotopy_lambda)
        self.homotopy_steps = homotopy_steps

    # -------------------------------------------------------------- schedule
    def update_homotopy(self, step: int) -> float:
        r"""Sets and returns :math:`\lambda = \lambda_0 + (\lambda_1 - \lambda_0)\min(1, \text{step} /
        \text{homotopy\_steps})` (without ``homotopy_steps``: unchanged)."""
        if self.homotopy_steps is None:
            return float(self.homotopy_lambda)
        frac = min(1.0, max(0.0, step / max(1, self.homotopy_steps)))
        lam = self.initial_homotopy_lambda + frac * (self.final_homotopy_lambda - self.initial_homotopy_lambda)
        self.homotopy_lambda = lam
        return lam

    # ------------------------------------------------------------------ keys
    @property
    def _network_input_keys(self) -> list[NestedKey]:
        return [key for key in self.value_network.in_keys if key != self.tensor_keys.preference]

    def _set_in_keys(self) -> None:
        keys = [self.tensor_keys.action, *[("next", k) for k in (self.tensor_keys.reward, self.tensor_keys.done,
                                                                self.tensor_keys.terminated)],
                *self._network_input_keys, *[("next", key) for key in self._network_input_keys]]
        if self.include_batch_preference:
            keys.append(self.tensor_keys.preference)
        self._in_keys = list(dict.fromkeys(keys))

    @property
    def out_keys(self) -> list[str]:
        return ["loss_qvalue", "vector_loss", "scalarized_loss", "homotopy_lambda", "scalarized_q"]

    # --------------------------------------------------------------- forward
    def _preferences(self, data: TensorDictBase) -> torch.Tensor:
        """``[B, N, k]``: the preferences each transition is trained on."""
        batch, n, k = data.shape[0], self.num_preference_samples, self.num_objectives
        device = data.get(("next", self.tensor_keys.reward)).device
        if self.shared_preferences and not self.include_batch_preference:
            return self._sample_preferences((n,), device).expand(batch, n, k)
        w = self._sample_preferences((batch, n), device)
        if self.include_batch_preference:
            w = torch.cat([data.get(self.tensor_keys.preference).unsqueeze(1).to(w.dtype), w[:, 1:]], 1)
        return w

    def _fast_plan(self) -> FunctionalNetwork | None:
        """The network's :class:`~morl_trl.objectives.fast_path.FunctionalNetwork` (the networks
        :func:`~morl_trl.objectives.networks.make_vector_q_network` builds), else ``None``."""
        if not self.fast_networks:
            return None
        cache = self.__dict__.get("_fast_plan_cache")
        if cache is None:
            cache = self.__dict__["_fast_plan_cache"] = FunctionalNetwork.of(self.value_network,
                                                                             self.value_network_params) or False
        return cache or None

    def _q_values(self, data: TensorDictBase, w: torch.Tensor, params: TensorDictBase) -> torch.Tensor:
        """Runs the network once on every (transition, preference) pair: ``[B, N, |A|, k]``."""
        batch, n = w.shape[:2]
        plan = self._fast_plan()
        if plan is not None:  # the same operations on the parameter leaves, nothing swapped into the module
            pref = self.tensor_keys.preference
            inputs = []
            for key in plan.in_keys:
                if key == pref:
                    inputs.append(w)
                else:
                    x = data.get(key)
                    inputs.append(x.unsqueeze(1).expand(batch, n, *x.shape[1:]))
            return plan(plan.leaves(params), inputs)
        pairs = data.select(*self._network_input_keys).unsqueeze(1).expand(batch, n)
        pairs.set(self.tensor_keys.preference, w)
        with params.to_module(self.value_network, preserve_module_state=False):
            return module_output(self.value_network, pairs, self.tensor_keys.action_value)

    @torch.no_grad()
    def _envelope_next_value(self, next_data: TensorDictBase, w: torch.Tensor) -> torch.Tensor:
        """``[B, N, k]`` target-network value of the envelope-maximising (action, preference)."""
        batch, n, k = w.shape
        q_target = self._q_values(next_data, w, self.target_value_network_params)
        # (under no_grad the parameters themselves give the values of their detached copies)
        online = self.value_network_params if self._fast_plan() is not None else self.value_network_params.data
        q_select = self._q_values(next_data, w, online) if self.double_dqn else q_target
        num_actions = q_target.shape[-2]
        if self.envelope:
            # scores[b, i, m, a] = w_i . Q(s'_b, a, w_m): every candidate (w_m, a) under every w_i.
            scores = torch.einsum("bik,bmak->bima", w, q_select).reshape(batch, n, n * num_actions)
            best = scores.argmax(-1)
            return q_target.reshape(batch, n * num_actions, k).gather(1, best.unsqueeze(-1).expand(batch, n, k))
        scores = (w.unsqueeze(2) * q_select).sum(-1)
        best = scores.argmax(-1)
        return q_target.gather(2, best[..., None, None].expand(batch, n, 1, k)).squeeze(2)

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """The Envelope loss of a batch of transitions with ``[*B, k]`` rewards; writes the TD error."""
        self._check_inputs(tensordict, needs_preference=self.include_batch_preference)
        data = tensordict.reshape(-1) if tensordict.ndim != 1 else tensordict
        batch, n = data.shape[0], self.num_preference_samples
        w = self._preferences(data)

        q = self._q_values(data, w, self.value_network_params)
        num_actions = q.shape[-2]
        index = action_index(data.get(self.tensor_keys.action), batch, num_actions)
        q_taken = q.gather(2, index.view(batch, 1, 1, 1).expand(batch, n, 1, self.num_objectives)).squeeze(2)

        next_value = self._envelope_next_value(data.get("next"), w)
        target_keys = [("next", key) for key in (self.tensor_keys.reward, self.tensor_keys.done, self.tensor_keys.terminated)]
        target_keys.append(self.value_estimator.tensor_keys.steps_to_next_obs)  # n-step returns (MultiStep)
        target_data = expanded_selection(data, target_keys, batch, n)
        target = self.value_estimator.value_estimate(target_data, next_value=next_value).detach()

        vector_loss = distance_loss(q_taken, target, self.loss_function).mean(-1)
        scalar_q, scalar_target = (w * q_taken).sum(-1), (w * target).sum(-1)
        scalarized_loss = distance_loss(scalar_q, scalar_target, self.loss_function)
        lam = self.homotopy_lambda
        per_sample = ((1 - lam) * vector_loss + lam * scalarized_loss).mean(-1)

        scalar_td = (scalar_q - scalar_target).detach().abs()  # [B, N]
        td_error = scalar_td[:, 0] if self.priority == "first" else scalar_td.mean(-1)
        tensordict.set(self.tensor_keys.priority, td_error.reshape(tensordict.shape))

        weights = priority_weight(self, data)
        if weights is not None:
            weights = weights.reshape(batch)
        loss = reduce_loss(self, per_sample, data, weights)
        if self.reduction == "none":
            shape = tensordict.shape
            out = TensorDict({"loss_qvalue": loss.reshape(shape), "vector_loss": vector_loss.mean(-1).detach().reshape(
                shape), "scalarized_loss": scalarized_loss.mean(-1).detach().reshape(shape)}, batch_size=shape)
        else:
            out = TensorDict({"loss_qvalue": loss, "vector_loss": vector_loss.detach().mean(),
                              "scalarized_loss": scalarized_loss.detach().mean(), "homotopy_lambda": lam.detach().clone(),
                              "scalarized_q": scalar_q.detach().mean()}, batch_size=[])
        clear_weakrefs(self, tensordict, out, "value_network_params", "target_value_network_params")
        return out

