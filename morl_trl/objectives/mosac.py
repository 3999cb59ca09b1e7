"""Multi-objective soft actor-critic losses (continuous and discrete actions).

Vector critics ``Q(s, a[, w]) -> [*B, k]``, an actor and a temperature trained
on the preference-scalarised objective. With a fixed preference per policy this
is MORL/D's MOSAC building block; with ``k = 1`` it is plain SAC; with
preference-conditioned networks and fresh preferences it is CAPQL
(:class:`~morl_trl.objectives.capql.CAPQLLoss`).

The paper's SAC baseline (trained on the scalar ``original_reward``) is
``MOSACLoss(actor, critic, num_objectives=1, preference=torch.ones(1))`` after
``loss.set_keys(reward="original_reward")``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase, TensorDictParams
from tensordict.nn import ProbabilisticTensorDictSequential, TensorDictModule, composite_lp_aggregate, dispatch
from tensordict.utils import NestedKey
from torch import Tensor
from torchrl.data import Composite, TensorSpec
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives.sac import compute_rsample_log_prob
from torchrl.objectives.utils import distance_loss

from morl_trl._torchrl_compat import cache_values, clear_weakrefs, priority_weight, reduce_loss, vmap_func
from morl_trl.objectives.common import MultiObjectiveLossModule, argmin_along, check_preference, module_output
from morl_trl.objectives.envelope import action_index
from morl_trl.objectives.fast_path import FunctionalNetwork, GaussianActorPlan

__all__ = ["DiscreteMOSACLoss", "MOSACLoss", "ALPHA_LOSS_FORMS", "check_alpha_loss_form", "temperature_objective"]

CRITIC_MIN_MODES = ("scalarized", "elementwise")
CRITIC_LOSS_MODES = ("scalarized", "vector")
#: the temperature loss: ``-log_alpha (log pi + target)`` (TorchRL's SACLoss; MORL-Baselines' continuous MOSAC,
#: ``mosac_continuous_action.py:470`` in MB 1.3.0) or ``-alpha (log pi + target)`` (CleanRL's SAC,
#: ``sac_continuous_action.py``: ``-log_alpha.exp()``; MORL-Baselines' ``MOSACDiscrete``, ``mosac_discrete_action.py:492``)
ALPHA_LOSS_FORMS = ("log_alpha", "alpha")


def check_alpha_loss_form(form: str) -> str:
    """``form`` if it is one of :data:`ALPHA_LOSS_FORMS`, else a ``ValueError`` naming the valid ones."""
    if form not in ALPHA_LOSS_FORMS:
        raise ValueError(f"alpha_loss_form={form!r}; valid values are {ALPHA_LOSS_FORMS}.")
    return form


def temperature_objective(log_alpha: Tensor, log_prob: Tensor, target_entropy, form: str) -> Tensor:
    """Per-sample temperature loss ``-s (log_prob + target_entropy)``, ``s = alpha`` (``form="alpha"``)
    or ``log alpha`` (``"log_alpha"``); ``log_prob`` is taken as given (detach it first)."""
    scale = log_alpha.exp() if form == "alpha" else log_alpha
    return -scale * (log_prob + target_entropy)


class _MOSACBase(MultiObjectiveLossModule):
    """Preferences, temperature and the critic ensemble shared by both MOSAC losses."""

    actor_network: ProbabilisticTensorDictSequential
    qvalue_network: TensorDictModule
    actor_network_params: TensorDictParams
    qvalue_network_params: TensorDictParams
    target_actor_network_params: TensorDictParams
    target_qvalue_network_params: TensorDictParams

    _schedulable_buffers = frozenset({"log_alpha"})
    critic_ensemble_mode: str = "auto"
    #: Evaluate networks built by :mod:`morl_trl.objectives.networks` from the parameter
    #: leaves (:mod:`morl_trl.objectives.fast_path`): the same operations without swapping
    #: parameters into the modules. ``False`` forces TorchRL's generic path.
    fast_networks: bool = True

    def _setup(
        self,
        actor_network,
        qvalue_network,
        *,
        num_objectives,
        num_qvalue_nets,
        preference,
        resample_preferences,
        preference_distribution,
        critic_min,
        critic_loss,
        loss_function,
        alpha_init,
        min_alpha,
        max_alpha,
        fixed_alpha,
        delay_qvalue,
        reduction,
        use_prioritized_weights,
        deactivate_vmap,
        alpha_loss_form,
    ) -> None:
        self.alpha_loss_form = check_alpha_loss_form(alpha_loss_form)
        if critic_min not in CRITIC_MIN_MODES:
            raise ValueError(f"critic_min={critic_min!r}; valid values are {CRITIC_MIN_MODES}.")
        if critic_loss not in CRITIC_LOSS_MODES:
            raise ValueError(f"critic_loss={critic_loss!r}; valid values are {CRITIC_LOSS_MODES}.")
        if reduction not in ("mean", "sum", "none"):
            raise ValueError(f"reduction={reduction!r}; valid values are 'mean', 'sum', 'none'.")
        if preference is not None and resample_preferences:
            raise ValueError("Pass either a fixed preference or resample_preferences=True, not both.")
        self.num_objectives = self._resolve_num_objectives(num_objectives, qvalue_network, actor_network)
        self.num_qvalue_nets = int(num_qvalue_nets)
        self.resample_preferences = resample_preferences
        self.preference_distribution = self._check_distribution(preference_distribution)
        self.critic_min = critic_min
        self.critic_loss = critic_loss
        self.loss_function = loss_function
        self.reduction = reduction
        self.use_prioritized_weights = use_prioritized_weights
        self.deactivate_vmap = deactivate_vmap
        self.fixed_alpha = fixed_alpha
        self.delay_qvalue = delay_qvalue

        self.convert_to_functional(actor_network, "actor_network", create_target_params=False)
        self.convert_to_functional(
            qvalue_network,
            "qvalue_network",
            self.num_qvalue_nets,
            create_target_params=delay_qvalue,
            compare_against=list(actor_network.parameters()),
        )
        device = next(iter(self.qvalue_network_params.values(True, True))).device

        if preference is not None:
            preference = torch.as_tensor(preference, dtype=torch.float32, device=device)
            check_preference(preference, self.num_objectives, name="preference")
            if preference.ndim != 1:
                raise ValueError(f"a fixed preference must have shape [{self.num_objectives}], got {tuple(preference.shape)}.")
            self.register_buffer("fixed_preference", preference.clone())
        else:
            self.fixed_preference = None

        if min_alpha is not None and max_alpha is not None and min_alpha > max_alpha:
            raise ValueError(f"min_alpha={min_alpha} exceeds max_alpha={max_alpha}.")
        self.min_log_alpha = math.log(min_alpha) if min_alpha else None
        self.max_log_alpha = math.log(max_alpha) if max_alpha else None
        log_alpha = torch.tensor(math.log(alpha_init), device=device)
        if fixed_alpha:
            self.register_buffer("log_alpha", log_alpha)
        else:
            self.register_parameter("log_alpha", torch.nn.Parameter(log_alpha))
        self._vmap_qnetworkN0 = vmap_func(self.qvalue_network, (None, 0), randomness=self.vmap_randomness)

    # ------------------------------------------------------------ preference
    def set_preference(self, preference: Tensor) -> None:
        """Replaces the fixed preference (MORL/D's weight adaptation); requires one set at construction."""
        if self.fixed_preference is None:
            raise ValueError("this loss reads preferences from the batch; it has no fixed preference to set.")
        preference = torch.as_tensor(preference, dtype=self.fixed_preference.dtype, device=self.fixed_preference.device)
        check_preference(preference, self.num_objectives, name="preference")
        if preference.shape != self.fixed_preference.shape:
            raise ValueError(f"preference must have shape {tuple(self.fixed_preference.shape)}, got {tuple(preference.shape)}.")
        self.fixed_preference.copy_(preference)

    @property
    def _reads_batch_preference(self) -> bool:
        return self.fixed_preference is None and not self.resample_preferences

    def _batch_preferences(self, data: TensorDictBase) -> Tensor:
        batch = data.shape[0]
        if self.fixed_preference is not None:
            return self.fixed_preference.expand(batch, self.num_objectives)
        if self.resample_preferences:
            device = data.get(("next", self.tensor_keys.reward)).device
            return self._sample_preferences((batch,), device)
        return data.get(self.tensor_keys.preference)

    def _with_preference(self, data: TensorDictBase, w: Tensor) -> TensorDictBase:
        """A shallow copy of the batch whose root and ``"next"`` hold the preference ``w``."""
        next_data = data.get("next").copy()
        next_data.set(self.tensor_keys.preference, w)
        data = data.copy()
        data.set(self.tensor_keys.preference, w)
        data.set("next", next_data)
        return data

    # ----------------------------------------------------------- temperature
    @property
    def _alpha(self) -> Tensor:
        if self.min_log_alpha is not None or self.max_log_alpha is not None:
            self.log_alpha.data.clamp_(self.min_log_alpha, self.max_log_alpha)
        with torch.no_grad():
            return self.log_alpha.exp()

    def _alpha_objective(self, log_prob: Tensor) -> Tensor:
        """Per-sample temperature loss on a detached ``log_prob`` (``alpha_loss_form``)."""
        return temperature_objective(self.log_alpha, log_prob, self.target_entropy, self.alpha_loss_form)

    # ------------------------------------------------- the three parts (TorchRL's SACLoss style)
    #: the temperature step draws a fresh sample of the (just updated) actor (continuous: the authors'
    #: ``with no_grad: _, log_pi, _ = actor.get_action(obs)`` after the actor step) rather than reusing the
    #: actor step's log-probabilities (discrete: ``mosac_discrete_action.py:490-492`` reuses them)
    fresh_temperature_sample: bool = True

    def _flat(self, tensordict: TensorDictBase) -> TensorDictBase:
        self._check_inputs(tensordict, needs_preference=self._reads_batch_preference)
        return tensordict.reshape(-1) if tensordict.ndim != 1 else tensordict

    def qvalue_loss(self, tensordict: TensorDictBase) -> tuple[Tensor, dict[str, Tensor]]:
        """The critic loss alone (:meth:`forward`'s ``loss_qvalue``, the same computation): the target
        from the target critics and a sampled next action, the critics' regression. Writes the priority
        into ``tensordict`` as :meth:`forward` does. Returns ``(loss, {"td_error": ...})``."""
        data = self._flat(tensordict)
        loss, td_error = self._qvalue_part(data, self._batch_preferences(data))
        tensordict.set(self.tensor_keys.priority, td_error.reshape(tensordict.shape))
        return self._reduce(loss, data), {"td_error": td_error}

    def actor_dist(self, tensordict: TensorDictBase):
        """The current actor's distribution on ``tensordict`` (with gradient), as a handle that
        :meth:`temperature_loss` and then :meth:`actor_loss` can share: one network forward for the
        temperature's fresh sample and the next actor step's sample, drawn in that order (the same
        draws as two forwards, the network being unchanged in between)."""
        data = self._flat(tensordict)
        w = self._batch_preferences(data)
        return self._policy_dist(data, w), w

    def actor_loss(self, tensordict: TensorDictBase, dist=None) -> tuple[Tensor, dict[str, Tensor]]:
        """The actor loss alone (:meth:`forward`'s ``loss_actor``): a sampled action scored by the
        current critics (no target computation), from ``dist`` (:meth:`actor_dist`) when given.
        Returns ``(loss, {"log_prob": ...})`` (discrete: the per-state ``sum_a pi log pi``), detached."""
        data = self._flat(tensordict)
        dist, w = (None, self._batch_preferences(data)) if dist is None else dist
        loss, log_prob = self._actor_part(data, w, dist)
        return self._reduce(loss, data), {"log_prob": log_prob.detach()}

    def temperature_loss(self, tensordict: TensorDictBase, log_prob: Tensor | None = None, dist=None) -> Tensor:
        """The temperature loss alone (``alpha_loss_form``), on ``log_prob`` or, when ``None``, on a
        fresh sample of the current actor (from ``dist``, :meth:`actor_dist`, when given; no gradient)."""
        data = self._flat(tensordict)
        if log_prob is None:
            with torch.no_grad():
                d, w = (None, self._batch_preferences(data)) if dist is None else dist
                log_prob = self._sample_log_prob(data, w, d)
        return self._reduce(self._alpha_objective(log_prob.detach()), data)

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Computes ``loss_qvalue``, ``loss_actor`` and (unless ``fixed_alpha``) ``loss_alpha``: the three
        parts on one preference draw, the temperature on the actor loss's log-probabilities."""
        data = self._flat(tensordict)
        w = self._batch_preferences(data)
        loss_qvalue, td_error = self._qvalue_part(data, w)
        loss_actor, log_prob = self._actor_part(data, w)
        losses = {
            "loss_actor": self._reduce(loss_actor, data),
            "loss_qvalue": self._reduce(loss_qvalue, data),
            "loss_alpha": self._reduce(self._alpha_objective(log_prob.detach()), data),
        }
        return self._output(tensordict, losses, log_prob, td_error)

    # ---------------------------------------------------------------- critic
    @property
    @cache_values
    def _cached_detached_qvalue_params(self):
        return self.qvalue_network_params.detach()

    def _ensemble_mode(self, device: torch.device) -> str:
        mode = self.critic_ensemble_mode
        if mode == "auto":
            mode = "loop" if self.deactivate_vmap or device.type == "cpu" else "vmap"
        return mode

    def _fast_critics(self, plan: FunctionalNetwork, leaves: list[Tensor], inputs: list[Tensor]) -> Tensor:
        """``[n, *B, ...]``: :meth:`_critic_ensemble` on the fast path (``leaves`` stacked over the ensemble)."""
        if self._ensemble_mode(leaves[0].device) == "vmap":
            return plan(leaves, inputs)
        # unbind, not leaf[i]: one backward node per leaf that stacks the members' gradients, where a
        # select per member scatters each into a zero-filled copy of the whole ensemble, then sums them
        members = zip(*(leaf.unbind(0) for leaf in leaves))
        return torch.stack([plan(list(member), inputs) for member in members])

    def _critic_ensemble(self, td: TensorDictBase, params: TensorDictBase, key: NestedKey) -> Tensor:
        """``[n, *B, ...]``: every critic of the ensemble on ``td``.

        ``vmap`` batches the critics into ``bmm`` calls, which pays on accelerators; on
        CPU one plain call per critic is faster (``bmm`` runs ~20% slower than two
        ``addmm`` of the same size there). ``critic_ensemble_mode`` picks: ``"auto"``
        (loop on CPU or with ``deactivate_vmap=True``, ``vmap`` elsewhere), ``"loop"`` or ``"vmap"``.
        """
        if self._ensemble_mode(next(iter(params.values(True, True))).device) == "vmap":
            return self._vmap_qnetworkN0(td, params).get(key)
        values = []
        for i in range(self.num_qvalue_nets):
            with params[i].to_module(self.qvalue_network, preserve_module_state=False):
                values.append(module_output(self.qvalue_network, td, key))
        return torch.stack(values)

    def _select_min(self, q: Tensor, w: Tensor) -> Tensor:
        """Pessimistic vector value over the critic ensemble ``q`` (``[n, B, ..., k]``).

        ``"elementwise"`` takes the minimum per objective (CAPQL); ``"scalarized"``
        takes the whole vector of the critic with the lowest ``w . Q`` (MORL/D).
        """
        if self.critic_min == "elementwise":
            return q.min(0).values
        w = w.reshape(w.shape[0], *([1] * (q.ndim - 3)), w.shape[-1])
        worst = argmin_along((q * w).sum(-1), 0, keepdim=True)
        return q.gather(0, worst.unsqueeze(-1).expand(1, *q.shape[1:])).squeeze(0)

    def _critic_objective(self, q: Tensor, target: Tensor, w: Tensor) -> tuple[Tensor, Tensor]:
        """Per-sample critic loss summed over the ensemble and the ``|w . TD|`` priority, from ``[n, B, k]`` values."""
        target = target.expand_as(q)
        scalar_td = ((q - target) * w).sum(-1)
        if self.critic_loss == "vector":
            loss = distance_loss(q, target, self.loss_function).mean(-1).sum(0)
        else:
            loss = distance_loss((q * w).sum(-1), (target * w).sum(-1), self.loss_function).sum(0)
        return loss, scalar_td.detach().abs().max(0).values

    def _reduce(self, loss: Tensor, data: TensorDictBase) -> Tensor:
        weights = priority_weight(self, data)
        if weights is not None:
            weights = weights.reshape(loss.shape)
        return reduce_loss(self, loss, data, weights)

    def _output(self, tensordict, losses: dict, log_prob: Tensor, td_error: Tensor) -> TensorDict:
        tensordict.set(self.tensor_keys.priority, td_error.reshape(tensordict.shape))
        if self.fixed_alpha:
            losses.pop("loss_alpha")
        if self.reduction == "none":
            out = TensorDict({k: v.reshape(tensordict.shape) for k, v in losses.items()}, batch_size=tensordict.shape)
        else:
            out = TensorDict({**losses, "alpha": self._alpha, "entropy": -log_prob.detach().mean()}, batch_size=[])
        clear_weakrefs(
            self, tensordict, out, "actor_network_params", "qvalue_network_params", "target_qvalue_network_params"
        )
        return out

    @property
    def out_keys(self) -> list[str]:
        keys = ["loss_actor", "loss_qvalue"]
        if not self.fixed_alpha:
            keys.append("loss_alpha")
        return [*keys, "alpha", "entropy"]

    def _set_in_keys(self) -> None:
        pref = self.tensor_keys.preference
        net_keys = [k for k in (*self.actor_network.in_keys, *self.qvalue_network.in_keys) if k not in (pref, self.tensor_keys.action)]
        keys = [
            self.tensor_keys.action,
            ("next", self.tensor_keys.reward),
            ("next", self.tensor_keys.done),
            ("next", self.tensor_keys.terminated),
            *net_keys,
            *[("next", key) for key in net_keys],
        ]
        if self._reads_batch_preference:
            keys.append(pref)
        self._in_keys = list(dict.fromkeys(keys))


class MOSACLoss(_MOSACBase):
    r"""Multi-objective SAC for continuous actions: vector critics, scalarised actor.

    For each transition with preference :math:`w`, the ``num_qvalue_nets`` vector
    critics regress onto

    .. math::

        y = r + \gamma (1 - d) \big(Q^-_{\min}(s', a', w) - \alpha \log\pi(a' | s', w)\,\mathbf 1\big),
        \quad a' \sim \pi(\cdot | s', w)

    and the actor minimises :math:`\alpha \log\pi(a|s,w) - w^\top Q_{\min}(s, a, w)`.
    :math:`Q_{\min}` is the vector of the critic with the lowest :math:`w^\top Q`
    (``critic_min="scalarized"``, MORL/D) or the per-objective minimum
    (``"elementwise"``, CAPQL). The critic loss is the squared error of the
    scalarised values (``critic_loss="scalarized"``, MORL/D) or of the vectors
    (``"vector"``, CAPQL). :math:`\alpha` is tuned towards ``target_entropy``
    unless ``fixed_alpha``.

    Where the preference comes from: a fixed ``preference`` (one MORL/D policy;
    change it with :meth:`set_preference`), fresh draws per sample
    (``resample_preferences=True``) or the batch's ``"preference"`` entry.
    Networks that do not read the preference (MORL/D's) are fine: the
    preference then only scalarises.

    Args:
        actor_network (ProbabilisticTensorDictSequential): stochastic actor, e.g.
            :func:`~morl_trl.objectives.networks.make_gaussian_actor`.
        qvalue_network (TensorDictModule): vector critic writing ``"state_action_value"``
            ``[*B, k]``, e.g. :func:`~morl_trl.objectives.networks.make_vector_critic`.
            Its parameters are expanded to ``num_qvalue_nets`` independently
            initialised copies, as in TorchRL's SAC.

    Keyword Args:
        num_objectives (int, optional): ``k``; read from networks made by the builders.
        num_qvalue_nets (int): size of the critic ensemble. Defaults to 2.
        preference (Tensor, optional): a fixed ``[k]`` preference.
        resample_preferences (bool): draw a fresh preference per sample at every call. Defaults to ``False``.
        preference_distribution (str): ``"dirichlet"`` (default) or ``"gaussian"``, for resampling.
        critic_min (str): ``"scalarized"`` (default) or ``"elementwise"``.
        critic_loss (str): ``"scalarized"`` (default) or ``"vector"``.
        loss_function (str): ``"l2"`` (default), ``"l1"`` or ``"smooth_l1"``.
        alpha_init (float): initial temperature. Defaults to 1.
        min_alpha, max_alpha (float, optional): temperature bounds.
        fixed_alpha (bool): keep :math:`\alpha` at ``alpha_init`` (no ``loss_alpha`` output). Defaults to ``False``.
        target_entropy (float or "auto"): ``"auto"`` is minus the action dimension, read
            from ``action_spec`` or the actor's spec.
        action_spec (TensorSpec, optional): the action spec, for ``target_entropy="auto"``.
        delay_qvalue (bool): keep target critic parameters (``SoftUpdate``). Defaults to ``True``.
        reduction (str): ``"mean"`` (default), ``"sum"`` or ``"none"``.
        use_prioritized_weights (bool or "auto"): weight samples by ``"priority_weight"``.
        deactivate_vmap (bool): loop over the critics instead of ``vmap``. Defaults to ``False``.
        alpha_loss_form (str): the temperature loss, ``"log_alpha"`` (``-log alpha (log pi + target)``,
            TorchRL's and MORL-Baselines' continuous MOSAC; default) or ``"alpha"`` (``-alpha (...)``,
            CleanRL's SAC and MORL-Baselines' discrete MOSAC).

    :meth:`qvalue_loss`, :meth:`actor_loss` and :meth:`temperature_loss` compute the three parts
    alone (TorchRL's ``SACLoss`` style), for a step that updates the critics, the actor and the
    temperature one after the other (the authors'; :meth:`~morl_trl.training.agent.Agent.actor_critic_step`).

    Examples:
        >>> from tensordict import TensorDict
        >>> from torchrl.data import Bounded
        >>> from morl_trl.objectives.networks import make_gaussian_actor, make_vector_critic
        >>> spec = Bounded(-1.0, 1.0, (2,))
        >>> actor = make_gaussian_actor(5, spec, 3, num_cells=(32,))
        >>> critic = make_vector_critic(5, 2, 3, num_cells=(32,))
        >>> from torchrl.objectives import SoftUpdate
        >>> loss = MOSACLoss(actor, critic, preference=torch.tensor([0.2, 0.3, 0.5]))
        >>> updater = SoftUpdate(loss, tau=0.005)
        >>> B = 8
        >>> data = TensorDict({
        ...     "observation": torch.randn(B, 5), "action": spec.rand((B,)),
        ...     ("next", "observation"): torch.randn(B, 5), ("next", "reward"): torch.randn(B, 3),
        ...     ("next", "done"): torch.zeros(B, 1, dtype=torch.bool),
        ...     ("next", "terminated"): torch.zeros(B, 1, dtype=torch.bool)}, [B])
        >>> out = loss(data)
        >>> sorted(out.keys())
        ['alpha', 'entropy', 'loss_actor', 'loss_alpha', 'loss_qvalue']
    """

    @dataclass
    class _AcceptedKeys:
        """Configurable tensordict keys (``loss.set_keys(name=key)``).

        Attributes:
            action: the action. Defaults to ``"action"``.
            state_action_value: critic output ``[*B, k]``. Defaults to ``"state_action_value"``.
            preference: preference ``[*B, k]`` (read, or written for the networks). Defaults to ``"preference"``.
            log_prob: log-probability entry of the actor. Defaults to TorchRL's sample log-prob key.
            value_target: key of the estimator's target. Defaults to ``"value_target"``.
            priority: where the per-sample TD error is written. Defaults to ``"td_error"``.
            priority_weight: importance weights of prioritized replay. Defaults to ``"priority_weight"``.
            reward: ``[*B, k]`` vector reward under ``"next"``. Defaults to ``"reward"``.
            done: done flag under ``"next"``. Defaults to ``"done"``.
            terminated: termination flag under ``"next"``. Defaults to ``"terminated"``.
        """

        action: NestedKey = "action"
        state_action_value: NestedKey = "state_action_value"
        preference: NestedKey = "preference"
        log_prob: NestedKey | None = None
        value_target: NestedKey = "value_target"
        priority: NestedKey = "td_error"
        priority_weight: NestedKey = "priority_weight"
        reward: NestedKey = "reward"
        done: NestedKey = "done"
        terminated: NestedKey = "terminated"

        def __post_init__(self):
            if self.log_prob is None:
                self.log_prob = "sample_log_prob" if composite_lp_aggregate(nowarn=True) else "action_log_prob"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys

    def __init__(
        self,
        actor_network: ProbabilisticTensorDictSequential,
        qvalue_network: TensorDictModule,
        *,
        num_objectives: int | None = None,
        num_qvalue_nets: int = 2,
        preference: Tensor | None = None,
        resample_preferences: bool = False,
        preference_distribution: str = "dirichlet",
        critic_min: str = "scalarized",
        critic_loss: str = "scalarized",
        loss_function: str = "l2",
        alpha_init: float = 1.0,
        min_alpha: float | None = None,
        max_alpha: float | None = None,
        fixed_alpha: bool = False,
        target_entropy: float | str = "auto",
        action_spec: TensorSpec | None = None,
        delay_qvalue: bool = True,
        reduction: str = "mean",
        use_prioritized_weights: str | bool = "auto",
        deactivate_vmap: bool = False,
        alpha_loss_form: str = "log_alpha",
    ) -> None:
        self._in_keys = None
        super().__init__()
        self._setup(
            actor_network,
            qvalue_network,
            num_objectives=num_objectives,
            num_qvalue_nets=num_qvalue_nets,
            preference=preference,
            resample_preferences=resample_preferences,
            preference_distribution=preference_distribution,
            critic_min=critic_min,
            critic_loss=critic_loss,
            loss_function=loss_function,
            alpha_init=alpha_init,
            min_alpha=min_alpha,
            max_alpha=max_alpha,
            fixed_alpha=fixed_alpha,
            delay_qvalue=delay_qvalue,
            reduction=reduction,
            use_prioritized_weights=use_prioritized_weights,
            deactivate_vmap=deactivate_vmap,
            alpha_loss_form=alpha_loss_form,
        )
        self.register_buffer(
            "target_entropy",
            torch.tensor(self._resolve_target_entropy(target_entropy, action_spec, actor_network), device=self.log_alpha.device),
        )

    def _resolve_target_entropy(self, target_entropy, action_spec, actor_network) -> float:
        if target_entropy != "auto":
            return float(target_entropy)
        if self.fixed_alpha:
            return 0.0  # unused
        spec = action_spec if action_spec is not None else getattr(actor_network, "spec", None)
        if isinstance(spec, Composite):
            leaves = [key for key in spec.keys(True, True) if spec.get(key) is not None]
            key = self.tensor_keys.action if self.tensor_keys.action in leaves or len(leaves) != 1 else leaves[0]
            spec = spec.get(key, None)
        if spec is None:
            raise ValueError("target_entropy='auto' needs the action spec: pass action_spec= or target_entropy=.")
        return -float(spec.shape[-1:].numel())

    # ---------------------------------------------------------------- pieces
    def _actor_dist(self, data: TensorDictBase, params):
        with set_exploration_type(ExplorationType.RANDOM), params.to_module(self.actor_network, preserve_module_state=False):
            return self.actor_network.get_dist(data.select(*self.actor_network.in_keys, strict=False))

    @staticmethod
    def _draw(dist) -> tuple[Tensor, Tensor]:
        with set_exploration_type(ExplorationType.RANDOM):
            return compute_rsample_log_prob(dist)

    def _actor_sample(self, data: TensorDictBase, params) -> tuple[Tensor, Tensor]:
        return self._draw(self._actor_dist(data, params))

    def _critics(self, data: TensorDictBase, action: Tensor | None, params) -> Tensor:
        """``[n, B, k]`` values of all critics."""
        td = data.select(*self.qvalue_network.in_keys, strict=False)
        if action is not None:
            td.set(self.tensor_keys.action, action)
        return self._critic_ensemble(td, params, self.tensor_keys.state_action_value)

    @torch.no_grad()
    def _target(self, data: TensorDictBase, w: Tensor) -> Tensor:
        next_data = data.get("next")
        next_action, next_log_prob = self._actor_sample(next_data, self.actor_network_params)
        q_next = self._critics(next_data, next_action, self.target_qvalue_network_params)
        next_value = self._select_min(q_next, w) - self._alpha * next_log_prob.unsqueeze(-1)
        return self.value_estimator.value_estimate(data, next_value=next_value)

    def _fast_plans(self):
        """``(actor plan, critic plan)`` when both networks take the fast path, else ``None``."""
        if not self.fast_networks:
            return None
        cache = self.__dict__.get("_fast_plans_cache")
        if cache is None:
            actor = GaussianActorPlan.of(self.actor_network, self.actor_network_params)
            critic = FunctionalNetwork.of(self.qvalue_network, self.qvalue_network_params)
            cache = self.__dict__["_fast_plans_cache"] = (actor, critic) if actor and critic else False
        return cache or None

    def _inputs(self, in_keys, data: TensorDictBase, w: Tensor, action: Tensor | None = None) -> list[Tensor]:
        """A network's positional inputs from ``data``, with the preference ``w`` (and ``action``) substituted."""
        keys = self.tensor_keys
        return [w if key == keys.preference else action if action is not None and key == keys.action else data.get(key)
                for key in in_keys]

    def _qvalue_part(self, data: TensorDictBase, w: Tensor) -> tuple[Tensor, Tensor]:
        """Per-sample critic loss and priority (:meth:`qvalue_loss`), on the fast path where it applies."""
        plans = self._fast_plans()
        if plans is None:
            data_w = self._with_preference(data, w)
            target = self._target(data_w, w)
            q = self._critics(data_w, None, self.qvalue_network_params)
            return self._critic_objective(q, target, w)
        actor, critic = plans
        next_data = data.get("next")
        with torch.no_grad():
            next_action, next_log_prob = compute_rsample_log_prob(
                actor.dist(actor.mlp.leaves(self.actor_network_params), self._inputs(actor.mlp.in_keys, next_data, w)))
            q_next = self._fast_critics(critic, critic.leaves(self.target_qvalue_network_params),
                                        self._inputs(critic.in_keys, next_data, w, next_action))
            next_value = self._select_min(q_next, w) - self._alpha * next_log_prob.unsqueeze(-1)
            target = self.value_estimator.value_estimate(data, next_value=next_value)
        q = self._fast_critics(critic, critic.leaves(self.qvalue_network_params), self._inputs(critic.in_keys, data, w))
        return self._critic_objective(q, target, w)

    def _policy_dist(self, data: TensorDictBase, w: Tensor):
        """The current actor's distribution on ``data`` under the preference ``w`` (on the fast path where it applies)."""
        plans = self._fast_plans()
        if plans is None:
            return self._actor_dist(self._with_preference(data, w), self.actor_network_params)
        actor = plans[0]
        return actor.dist(actor.mlp.leaves(self.actor_network_params), self._inputs(actor.mlp.in_keys, data, w))

    def _actor_part(self, data: TensorDictBase, w: Tensor, dist=None) -> tuple[Tensor, Tensor]:
        """Per-sample actor loss and the sampled actions' log-probabilities (:meth:`actor_loss`)."""
        action, log_prob = self._draw(self._policy_dist(data, w) if dist is None else dist)
        plans = self._fast_plans()
        if plans is None:
            q_pi = self._critics(self._with_preference(data, w), action, self._cached_detached_qvalue_params)
        else:
            critic = plans[1]
            q_pi = self._fast_critics(critic, [leaf.detach() for leaf in critic.leaves(self.qvalue_network_params)],
                                      self._inputs(critic.in_keys, data, w, action))
        return self._alpha * log_prob - (self._select_min(q_pi, w) * w).sum(-1), log_prob

    def _sample_log_prob(self, data: TensorDictBase, w: Tensor, dist=None) -> Tensor:
        """Log-probabilities of freshly sampled actions of the current actor (:meth:`temperature_loss`)."""
        return self._draw(self._policy_dist(data, w) if dist is None else dist)[1]


class DiscreteMOSACLoss(_MOSACBase):
    r"""Multi-objective SAC for discrete actions (MORL/D's ``MOSACDiscrete``).

    The critics output ``[*B, |A|, k]``; expectations over the next action are
    exact: :math:`y = r + \gamma(1-d)\sum_{a'} \pi(a'|s',w)\big(Q^-_{\min}(s',a',w) - \alpha\log\pi(a'|s',w)\mathbf 1\big)`
    and the actor minimises :math:`\sum_a \pi(a|s,w)\big(\alpha\log\pi(a|s,w) - w^\top Q_{\min}(s,a,w)\big)`.
    Options are those of :class:`MOSACLoss`; ``target_entropy="auto"`` is
    ``target_entropy_weight * log |A|`` (MORL/D's LunarLander runs use 0.3).

    Args:
        actor_network (ProbabilisticTensorDictSequential): categorical actor, e.g.
            :func:`~morl_trl.objectives.networks.make_categorical_actor`.
        qvalue_network (TensorDictModule): writes ``"action_value"`` ``[*B, |A|, k]``, e.g.
            :func:`~morl_trl.objectives.networks.make_vector_q_network`.

    Keyword Args:
        num_actions (int, optional): ``|A|``; read from networks made by the builders.
        target_entropy_weight (float): scale of the automatic target entropy. Defaults to 0.98.
        **others: as :class:`MOSACLoss` (``action_spec`` excepted).

    Examples:
        >>> from tensordict import TensorDict
        >>> from morl_trl.objectives.networks import make_categorical_actor, make_vector_q_network
        >>> actor = make_categorical_actor(6, 4, 2, num_cells=(32,))
        >>> critic = make_vector_q_network(6, 4, 2, num_cells=(32,))
        >>> from torchrl.objectives import HardUpdate
        >>> loss = DiscreteMOSACLoss(actor, critic, target_entropy_weight=0.3)
        >>> updater = HardUpdate(loss, value_network_update_interval=2000)
        >>> B = 8
        >>> data = TensorDict({
        ...     "observation": torch.randn(B, 6), "action": torch.randint(4, (B,)),
        ...     "preference": torch.full((B, 2), 0.5),
        ...     ("next", "observation"): torch.randn(B, 6), ("next", "reward"): torch.randn(B, 2),
        ...     ("next", "done"): torch.zeros(B, 1, dtype=torch.bool),
        ...     ("next", "terminated"): torch.zeros(B, 1, dtype=torch.bool)}, [B])
        >>> sorted(loss(data).keys())
        ['alpha', 'entropy', 'loss_actor', 'loss_alpha', 'loss_qvalue']
    """

    @dataclass
    class _AcceptedKeys:
        """Configurable tensordict keys (``loss.set_keys(name=key)``).

        Attributes:
            action: the action (integer or one-hot). Defaults to ``"action"``.
            action_value: critic output ``[*B, |A|, k]``. Defaults to ``"action_value"``.
            preference: preference ``[*B, k]``. Defaults to ``"preference"``.
            value_target: key of the estimator's target. Defaults to ``"value_target"``.
            priority: where the per-sample TD error is written. Defaults to ``"td_error"``.
            priority_weight: importance weights of prioritized replay. Defaults to ``"priority_weight"``.
            reward: ``[*B, k]`` vector reward under ``"next"``. Defaults to ``"reward"``.
            done: done flag under ``"next"``. Defaults to ``"done"``.
            terminated: termination flag under ``"next"``. Defaults to ``"terminated"``.
        """

        action: NestedKey = "action"
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

    def __init__(
        self,
        actor_network: ProbabilisticTensorDictSequential,
        qvalue_network: TensorDictModule,
        *,
        num_actions: int | None = None,
        num_objectives: int | None = None,
        num_qvalue_nets: int = 2,
        preference: Tensor | None = None,
        resample_preferences: bool = False,
        preference_distribution: str = "dirichlet",
        critic_min: str = "scalarized",
        critic_loss: str = "scalarized",
        loss_function: str = "l2",
        alpha_init: float = 1.0,
        min_alpha: float | None = None,
        max_alpha: float | None = None,
        fixed_alpha: bool = False,
        target_entropy_weight: float = 0.98,
        target_entropy: float | str = "auto",
        delay_qvalue: bool = True,
        reduction: str = "mean",
        use_prioritized_weights: str | bool = "auto",
        deactivate_vmap: bool = False,
        alpha_loss_form: str = "log_alpha",
    ) -> None:
        self._in_keys = None
        super().__init__()
        self._setup(
            actor_network,
            qvalue_network,
            num_objectives=num_objectives,
            num_qvalue_nets=num_qvalue_nets,
            preference=preference,
            resample_preferences=resample_preferences,
            preference_distribution=preference_distribution,
            critic_min=critic_min,
            critic_loss=critic_loss,
            loss_function=loss_function,
            alpha_init=alpha_init,
            min_alpha=min_alpha,
            max_alpha=max_alpha,
            fixed_alpha=fixed_alpha,
            delay_qvalue=delay_qvalue,
            reduction=reduction,
            use_prioritized_weights=use_prioritized_weights,
            deactivate_vmap=deactivate_vmap,
            alpha_loss_form=alpha_loss_form,
        )
        if num_actions is None:
            num_actions = getattr(qvalue_network, "num_actions", None)
        self.num_actions = num_actions
        if target_entropy == "auto":
            if fixed_alpha:
                target_entropy = 0.0
            elif num_actions is None:
                raise ValueError("target_entropy='auto' needs num_actions=.")
            else:
                target_entropy = target_entropy_weight * math.log(num_actions)
        self.register_buffer("target_entropy", torch.tensor(float(target_entropy), device=self.log_alpha.device))

    def _policy(self, data: TensorDictBase, params) -> tuple[Tensor, Tensor]:
        """Action probabilities and log-probabilities, ``[B, |A|]`` each."""
        with params.to_module(self.actor_network, preserve_module_state=False):
            dist = self.actor_network.get_dist(data.select(*self.actor_network.in_keys, strict=False))
        return dist.probs, dist.logits

    def _critics(self, data: TensorDictBase, params) -> Tensor:
        """``[n, B, |A|, k]`` values of all critics."""
        td = data.select(*self.qvalue_network.in_keys, strict=False)
        return self._critic_ensemble(td, params, self.tensor_keys.action_value)

    @torch.no_grad()
    def _target(self, data: TensorDictBase, w: Tensor) -> Tensor:
        next_data = data.get("next")
        probs, log_probs = self._policy(next_data, self.actor_network_params)
        q_next = self._select_min(self._critics(next_data, self.target_qvalue_network_params), w)
        next_value = (probs.unsqueeze(-1) * (q_next - self._alpha * log_probs.unsqueeze(-1))).sum(-2)
        return self.value_estimator.value_estimate(data, next_value=next_value)

    fresh_temperature_sample = False  # the actor step's probabilities (mosac_discrete_action.py:490-492)

    def _qvalue_part(self, data: TensorDictBase, w: Tensor) -> tuple[Tensor, Tensor]:
        data_w = self._with_preference(data, w)
        batch, k = data.shape[0], self.num_objectives
        target = self._target(data_w, w)
        q = self._critics(data_w, self.qvalue_network_params)
        index = action_index(data.get(self.tensor_keys.action), batch, q.shape[-2])
        q_taken = q.gather(-2, index.view(1, batch, 1, 1).expand(q.shape[0], batch, 1, k)).squeeze(-2)
        return self._critic_objective(q_taken, target, w)

    def _policy_dist(self, data: TensorDictBase, w: Tensor):
        with self.actor_network_params.to_module(self.actor_network, preserve_module_state=False):
            return self.actor_network.get_dist(self._with_preference(data, w).select(*self.actor_network.in_keys,
                                                                                      strict=False))

    def _actor_part(self, data: TensorDictBase, w: Tensor, dist=None) -> tuple[Tensor, Tensor]:
        """Per-state actor loss (exact expectation over the actions) and ``sum_a pi log pi``."""
        data_w = self._with_preference(data, w)
        probs, log_probs = (self._policy(data_w, self.actor_network_params) if dist is None
                            else (dist.probs, dist.logits))
        q_pi = self._select_min(self._critics(data_w, self._cached_detached_qvalue_params), w)
        scalar_q_pi = (q_pi * w.unsqueeze(-2)).sum(-1)
        loss_actor = (probs * (self._alpha * log_probs - scalar_q_pi)).sum(-1)
        return loss_actor, (probs * log_probs).sum(-1)

    def _sample_log_prob(self, data: TensorDictBase, w: Tensor, dist=None) -> Tensor:
        dist = self._policy_dist(data, w) if dist is None else dist
        return (dist.probs * dist.logits).sum(-1)
