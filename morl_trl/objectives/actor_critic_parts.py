"""What CAPQL, MOSAC, discrete MOSAC and MORL/D's population share: soft actor-critic pieces.

The formulas are plain functions on tensors (``q``: the critic ensemble's values ``[n, *B, k]``,
``w``: the preferences ``[*B, k]``), each loss file composing its own value estimate, critic
loss and actor loss from them:

* the pessimistic value over the ensemble: :func:`elementwise_min` (per objective, CAPQL) or
  :func:`scalarized_min` (the whole vector of the critic with the lowest ``w . Q``, MORL/D);
* the soft next-state value :func:`soft_next_value` (a sampled action) and
  :func:`expected_soft_next_value` (discrete actions: the exact expectation);
* the critics' regression :func:`vector_critic_loss` / :func:`scalarized_critic_loss`, both with
  the ``|w . TD|`` priority;
* the actor objective :func:`soft_actor_objective` / :func:`expected_soft_actor_objective`;
* the temperature objective :func:`temperature_objective` (:data:`ALPHA_LOSS_FORMS`).

:class:`SoftActorCriticBase` is the TorchRL ``LossModule`` plumbing of the single-learner losses
(parameters, preferences, temperature, the three parts ``qvalue_loss`` / ``actor_loss`` /
``temperature_loss`` and ``forward`` over the per-sample losses a subclass defines, reduction,
priorities, keys); :class:`ContinuousSoftActorCriticBase` adds the evaluation of a continuous
actor and its critics, from the parameter leaves (:mod:`morl_trl.objectives.fast_path`) for the
networks :mod:`morl_trl.objectives.networks` builds, through TorchRL's parameter swapping for any
other network.

Example:
    >>> q = torch.tensor([[[1.0, 5.0]], [[2.0, 2.0]]])  # two critics, one sample, two objectives
    >>> w = torch.tensor([[0.5, 0.5]])
    >>> elementwise_min(q, w), scalarized_min(q, w)  # critic 1 has the lower w . Q (2 < 3)
    (tensor([[1., 2.]]), tensor([[2., 2.]]))
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase, TensorDictParams
from tensordict.nn import ProbabilisticTensorDictSequential, TensorDictModule, composite_lp_aggregate, dispatch
from tensordict.utils import NestedKey
from torch import Tensor
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives.sac import compute_rsample_log_prob
from torchrl.objectives.utils import distance_loss

from morl_trl._torchrl_compat import cache_values, clear_weakrefs, priority_weight, reduce_loss, vmap_func
from morl_trl.objectives.common import MultiObjectiveLossModule, argmin_along, check_preference, module_output
from morl_trl.objectives.fast_path import FunctionalNetwork, GaussianActorPlan

__all__ = [
    "ALPHA_LOSS_FORMS",
    "ContinuousSoftActorCriticBase",
    "LOG_PROB_FORMS",
    "SoftActorCriticBase",
    "check_alpha_loss_form",
    "draw",
    "draw_clamped",
    "elementwise_min",
    "expected_log_prob",
    "expected_soft_actor_objective",
    "expected_soft_next_value",
    "scalarized_critic_loss",
    "scalarized_min",
    "soft_actor_objective",
    "soft_next_value",
    "temperature_objective",
    "vector_critic_loss",
]

#: the temperature loss: ``-log_alpha (log pi + target)`` (TorchRL's SACLoss; MORL-Baselines' continuous MOSAC,
#: ``mosac_continuous_action.py:470`` in MB 1.3.0) or ``-alpha (log pi + target)`` (CleanRL's SAC,
#: ``sac_continuous_action.py``: ``-log_alpha.exp()``; MORL-Baselines' ``MOSACDiscrete``, ``mosac_discrete_action.py:492``)
ALPHA_LOSS_FORMS = ("log_alpha", "alpha")


# ---------------------------------------------------------------------- formulas
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


def draw(dist) -> tuple[Tensor, Tensor]:
    """A reparameterised action of ``dist`` and its log-probability (TorchRL's SAC draw)."""
    with set_exploration_type(ExplorationType.RANDOM):
        return compute_rsample_log_prob(dist)


#: how a tanh-Gaussian action's log-probability is computed: ``"exact"`` (TorchRL's ``TanhNormal``: the exact
#: Jacobian of the squashing) or ``"clamped"`` (the authors' CAPQL, :func:`draw_clamped`)
LOG_PROB_FORMS = ("clamped", "exact")


def draw_clamped(dist, eps: float = 1e-6, bound: float = 1000.0) -> tuple[Tensor, Tensor]:
    """A reparameterised action of the tanh-Gaussian ``dist`` (TorchRL's ``TanhNormal``) and its log-probability as
    the authors' CAPQL computes it: the Normal's log-density of the pre-squash draw ``x`` minus
    ``sum log(scale (1 - tanh(x)^2) + eps)``, clamped to ``[-bound, bound]``; the action is
    ``tanh(x) scale + bias`` (``hyperparameters.toml`` ``[capql.<domain>.network] log_prob``, their
    ``capql.py:149-155``; MORL-Baselines 1.3.0 ``capql.py:147-154``, ``EPSILON = 1e-6``). The draw is TorchRL's (the
    base Normal's ``rsample``: the same random numbers as :func:`draw`); where ``tanh`` saturates the ``eps`` bounds
    the Jacobian's term at ``log(1/eps)`` per dimension, where the exact form keeps growing.

    Example:
        >>> from torchrl.modules import TanhNormal
        >>> loc, scale = torch.tensor([[0.0, 12.0]]), torch.ones(1, 2)
        >>> _ = torch.manual_seed(0)
        >>> action, log_prob = draw_clamped(TanhNormal(loc, scale, low=-1.0, high=1.0))
        >>> _ = torch.manual_seed(0)
        >>> x = torch.distributions.Normal(loc, scale).rsample()
        >>> mb = torch.distributions.Normal(loc, scale).log_prob(x).sum(-1) - torch.log(1 - torch.tanh(x) ** 2 + 1e-6).sum(-1)
        >>> torch.equal(action, torch.tanh(x)), torch.allclose(log_prob, mb)
        (True, True)
    """
    base = dist.base_dist
    x = base.rsample()
    y = torch.tanh(x)
    half = (dist.high - dist.low) / 2
    log_prob = base.log_prob(x) - torch.log(half * (1 - y.pow(2)) + eps).sum(-1)
    return y * half + (dist.high + dist.low) / 2, log_prob.clamp(-bound, bound)


def elementwise_min(q: Tensor, w: Tensor | None = None) -> Tensor:
    """The per-objective minimum over the critic ensemble ``q`` (``[n, *B, k]`` -> ``[*B, k]``); ``w`` unused."""
    return q.min(0).values


def scalarized_min(q: Tensor, w: Tensor) -> Tensor:
    """The whole vector of the critic with the lowest ``w . Q`` (``q``: ``[n, B, ..., k]``, ``w``: ``[B, k]``
    or already broadcastable to ``q[0]``)."""
    w = w.reshape(w.shape[0], *([1] * (q.ndim - 3)), w.shape[-1])
    worst = argmin_along((q * w).sum(-1), 0, keepdim=True)
    return q.gather(0, worst.unsqueeze(-1).expand(1, *q.shape[1:])).squeeze(0)


def soft_next_value(q_min: Tensor, next_log_prob: Tensor, alpha: Tensor) -> Tensor:
    """``Q_min(s', a') - alpha log pi(a'|s') 1`` for a sampled next action (``alpha`` broadcast to ``next_log_prob``)."""
    return q_min - (alpha * next_log_prob).unsqueeze(-1)


def expected_soft_next_value(probs: Tensor, log_probs: Tensor, q_min: Tensor, alpha: Tensor) -> Tensor:
    """``sum_a' pi(a'|s') (Q_min(s', a') - alpha log pi(a'|s') 1)``: ``probs``/``log_probs`` ``[..., |A|]``,
    ``q_min`` ``[..., |A|, k]``."""
    return (probs.unsqueeze(-1) * (q_min - (alpha * log_probs).unsqueeze(-1))).sum(-2)


def soft_actor_objective(log_prob: Tensor, q_min: Tensor, w: Tensor, alpha: Tensor) -> Tensor:
    """Per-sample actor loss ``alpha log pi(a|s) - w . Q_min(s, a)`` for a sampled action."""
    return alpha * log_prob - (q_min * w).sum(-1)


def expected_soft_actor_objective(probs: Tensor, log_probs: Tensor, q_min: Tensor, w: Tensor,
                                  alpha: Tensor) -> Tensor:
    """Per-state actor loss ``sum_a pi(a|s) (alpha log pi(a|s) - w . Q_min(s, a))`` (``w`` broadcast over the actions)."""
    return (probs * (alpha * log_probs - (q_min * w).sum(-1))).sum(-1)


def expected_log_prob(probs: Tensor, log_probs: Tensor) -> Tensor:
    """``sum_a pi(a|s) log pi(a|s)`` (minus the entropy), what a discrete temperature step reads."""
    return (probs * log_probs).sum(-1)


def _priority(q: Tensor, target: Tensor, w: Tensor) -> Tensor:
    return ((q - target) * w).sum(-1).detach().abs().max(0).values


def vector_critic_loss(q: Tensor, target: Tensor, w: Tensor, loss_function: str = "l2") -> tuple[Tensor, Tensor]:
    """Per-sample loss of the vector values against the target (mean over objectives, summed over the
    ensemble) and the ``|w . TD|`` priority (largest over the ensemble); ``q``: ``[n, B, k]``, ``target``: ``[B, k]``."""
    target = target.expand_as(q)
    return distance_loss(q, target, loss_function).mean(-1).sum(0), _priority(q, target, w)


def scalarized_critic_loss(q: Tensor, target: Tensor, w: Tensor, loss_function: str = "l2") -> tuple[Tensor, Tensor]:
    """Per-sample loss of the scalarised values ``w . Q`` against ``w . target`` (summed over the ensemble)
    and the ``|w . TD|`` priority; shapes as :func:`vector_critic_loss`."""
    target = target.expand_as(q)
    loss = distance_loss((q * w).sum(-1), (target * w).sum(-1), loss_function).sum(0)
    return loss, _priority(q, target, w)


# ---------------------------------------------------------------------- the LossModule plumbing
class SoftActorCriticBase(MultiObjectiveLossModule):
    """Parameters, preferences, temperature and TorchRL's loss interface of a single soft actor-critic.

    A subclass defines the algorithm: ``_policy_dist(data, w)`` (the current actor's distribution),
    ``_critic_loss(data, w) -> (per-sample loss, priority)``, ``_actor_loss(data, w, dist) ->
    (per-sample loss, log_prob)`` and ``_fresh_log_prob(dist)`` (what the temperature step reads);
    this class runs them on a batch as :meth:`qvalue_loss`, :meth:`actor_loss`,
    :meth:`temperature_loss` and :meth:`forward`, reduces them, writes the priority and names the keys.
    """

    actor_network: ProbabilisticTensorDictSequential
    qvalue_network: TensorDictModule
    actor_network_params: TensorDictParams
    qvalue_network_params: TensorDictParams
    target_actor_network_params: TensorDictParams
    target_qvalue_network_params: TensorDictParams

    _schedulable_buffers = frozenset({"log_alpha"})
    critic_ensemble_mode: str = "auto"
    #: the temperature step draws a fresh sample of the (just updated) actor (continuous: the authors'
    #: ``with no_grad: _, log_pi, _ = actor.get_action(obs)`` after the actor step) rather than reusing the
    #: actor step's log-probabilities (discrete: ``mosac_discrete_action.py:490-492`` reuses them)
    fresh_temperature_sample: bool = True

    def __init__(
        self,
        actor_network,
        qvalue_network,
        *,
        num_objectives,
        num_qvalue_nets,
        preference,
        resample_preferences,
        preference_distribution,
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
        self._in_keys = None
        super().__init__()
        self.alpha_loss_form = check_alpha_loss_form(alpha_loss_form)
        if reduction not in ("mean", "sum", "none"):
            raise ValueError(f"reduction={reduction!r}; valid values are 'mean', 'sum', 'none'.")
        if preference is not None and resample_preferences:
            raise ValueError("Pass either a fixed preference or resample_preferences=True, not both.")
        self.num_objectives = self._resolve_num_objectives(num_objectives, qvalue_network, actor_network)
        self.num_qvalue_nets = int(num_qvalue_nets)
        self.resample_preferences = resample_preferences
        self.preference_distribution = self._check_distribution(preference_distribution)
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
        """``[B, k]``: the fixed preference, a fresh draw per sample or the batch's ``"preference"``."""
        batch = data.shape[0]
        if self.fixed_preference is not None:
            return self.fixed_preference.expand(batch, self.num_objectives)
        if self.resample_preferences:
            device = data.get(("next", self.tensor_keys.reward)).device
            return self._sample_preferences((batch,), device)
        return data.get(self.tensor_keys.preference)

    def _network_inputs(self, in_keys, data: TensorDictBase, w: Tensor, action: Tensor | None = None) -> TensorDictBase:
        """A network's input TensorDict from ``data``, with the preference ``w`` (and ``action``) substituted."""
        td = data.select(*in_keys, strict=False)
        if any(key == self.tensor_keys.preference for key in in_keys):
            td.set(self.tensor_keys.preference, w)
        if action is not None:
            td.set(self.tensor_keys.action, action)
        return td

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

    # ----------------------------------------------------------- critics
    @property
    @cache_values
    def _cached_detached_qvalue_params(self):
        return self.qvalue_network_params.detach()

    def _ensemble_mode(self, device: torch.device) -> str:
        mode = self.critic_ensemble_mode
        if mode == "auto":
            mode = "loop" if self.deactivate_vmap or device.type == "cpu" else "vmap"
        return mode

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

    def _critic_params(self, which: str) -> TensorDictBase:
        """The critics' ``"online"``, ``"target"`` or ``"detached"`` (online, no gradient: the actor's loss) parameters."""
        if which == "target":
            return self.target_qvalue_network_params
        return self._cached_detached_qvalue_params if which == "detached" else self.qvalue_network_params

    # ------------------------------------------------- the three parts (TorchRL's SACLoss style)
    def _flat(self, tensordict: TensorDictBase) -> TensorDictBase:
        self._check_inputs(tensordict, needs_preference=self._reads_batch_preference)
        return tensordict.reshape(-1) if tensordict.ndim != 1 else tensordict

    def _reduce(self, loss: Tensor, data: TensorDictBase) -> Tensor:
        weights = priority_weight(self, data)
        if weights is not None:
            weights = weights.reshape(loss.shape)
        return reduce_loss(self, loss, data, weights)

    def qvalue_loss(self, tensordict: TensorDictBase) -> tuple[Tensor, dict[str, Tensor]]:
        """The critic loss alone (:meth:`forward`'s ``loss_qvalue``, the same computation): the target
        from the target critics and the next action's values, the critics' regression. Writes the priority
        into ``tensordict`` as :meth:`forward` does. Returns ``(loss, {"td_error": ...})``."""
        data = self._flat(tensordict)
        loss, td_error = self._critic_loss(data, self._batch_preferences(data))
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
        """The actor loss alone (:meth:`forward`'s ``loss_actor``): the current actor scored by the
        current critics (no target computation), from ``dist`` (:meth:`actor_dist`) when given.
        Returns ``(loss, {"log_prob": ...})`` (discrete: the per-state ``sum_a pi log pi``), detached."""
        data = self._flat(tensordict)
        dist, w = (None, self._batch_preferences(data)) if dist is None else dist
        loss, log_prob = self._actor_loss(data, w, dist)
        return self._reduce(loss, data), {"log_prob": log_prob.detach()}

    def temperature_loss(self, tensordict: TensorDictBase, log_prob: Tensor | None = None, dist=None) -> Tensor:
        """The temperature loss alone (``alpha_loss_form``), on ``log_prob`` or, when ``None``, on a
        fresh sample of the current actor (from ``dist``, :meth:`actor_dist`, when given; no gradient)."""
        data = self._flat(tensordict)
        if log_prob is None:
            with torch.no_grad():
                d, w = (None, self._batch_preferences(data)) if dist is None else dist
                log_prob = self._fresh_log_prob(self._policy_dist(data, w) if d is None else d)
        return self._reduce(self._alpha_objective(log_prob.detach()), data)

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Computes ``loss_qvalue``, ``loss_actor`` and (unless ``fixed_alpha``) ``loss_alpha``: the three
        parts on one preference draw, the temperature on the actor loss's log-probabilities."""
        data = self._flat(tensordict)
        w = self._batch_preferences(data)
        loss_qvalue, td_error = self._critic_loss(data, w)
        loss_actor, log_prob = self._actor_loss(data, w)
        losses = {
            "loss_actor": self._reduce(loss_actor, data),
            "loss_qvalue": self._reduce(loss_qvalue, data),
            "loss_alpha": self._reduce(self._alpha_objective(log_prob.detach()), data),
        }
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


class ContinuousSoftActorCriticBase(SoftActorCriticBase):
    """:class:`SoftActorCriticBase` with a continuous actor ``pi(a | s, w)`` and critics ``Q(s, a, w) -> [*B, k]``.

    :meth:`_policy_dist` and :meth:`_critics` evaluate the networks. Those built by
    :func:`~morl_trl.objectives.networks.make_gaussian_actor` and
    :func:`~morl_trl.objectives.networks.make_vector_critic` are run from their parameter leaves
    (:mod:`morl_trl.objectives.fast_path`: the same operations as TorchRL's parameter swapping, bit for
    bit, ``tests/objectives/test_fast_path.py``); any other network (a custom module, an encoder in
    front) through TorchRL's parameter swapping; ``fast_networks = False`` forces the latter.
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

    #: evaluate the builders' networks from the parameter leaves (see the class docstring)
    fast_networks: bool = True
    fresh_temperature_sample = True

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

    def _fast_critics(self, plan: FunctionalNetwork, leaves: list[Tensor], inputs: list[Tensor]) -> Tensor:
        """``[n, *B, ...]``: :meth:`_critic_ensemble` on the fast path (``leaves`` stacked over the ensemble)."""
        if self._ensemble_mode(leaves[0].device) == "vmap":
            return plan(leaves, inputs)
        # unbind, not leaf[i]: one backward node per leaf that stacks the members' gradients, where a
        # select per member scatters each into a zero-filled copy of the whole ensemble, then sums them
        members = zip(*(leaf.unbind(0) for leaf in leaves))
        return torch.stack([plan(list(member), inputs) for member in members])

    def _policy_dist(self, data: TensorDictBase, w: Tensor):
        """The current actor's distribution on ``data`` under the preference ``w``."""
        plans = self._fast_plans()
        if plans is not None:
            actor = plans[0]
            return actor.dist(actor.mlp.leaves(self.actor_network_params), self._inputs(actor.mlp.in_keys, data, w))
        td = self._network_inputs(self.actor_network.in_keys, data, w)
        with set_exploration_type(ExplorationType.RANDOM), self.actor_network_params.to_module(
                self.actor_network, preserve_module_state=False):
            return self.actor_network.get_dist(td)

    def _critics(self, data: TensorDictBase, w: Tensor, action: Tensor | None = None, params: str = "online") -> Tensor:
        """``[n, B, k]``: every critic on ``data`` under ``w``, at ``action`` (default: the batch's), with the
        ``"online"``, ``"target"`` or ``"detached"`` parameters."""
        plans = self._fast_plans()
        if plans is None:
            td = self._network_inputs(self.qvalue_network.in_keys, data, w, action)
            return self._critic_ensemble(td, self._critic_params(params), self.tensor_keys.state_action_value)
        critic = plans[1]
        if params == "target":
            leaves = critic.leaves(self.target_qvalue_network_params)
        else:
            leaves = critic.leaves(self.qvalue_network_params)
            if params == "detached":
                leaves = [leaf.detach() for leaf in leaves]
        return self._fast_critics(critic, leaves, self._inputs(critic.in_keys, data, w, action))

    def _fresh_log_prob(self, dist) -> Tensor:
        return draw(dist)[1]
