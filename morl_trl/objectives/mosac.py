"""Multi-objective soft actor-critic losses (continuous and discrete actions).

Vector critics ``Q(s, a[, w]) -> [*B, k]``, an actor and a temperature trained on the preference-scalarised
objective. With a fixed preference per policy this is MORL/D's MOSAC building block; with ``k = 1`` it is plain
SAC. The formulas are the functions of :mod:`morl_trl.objectives.actor_critic_parts`, shared with
:class:`~morl_trl.objectives.capql.CAPQLLoss` and MORL/D's population (:mod:`morl_trl.objectives.population`);
``critic_min`` and ``critic_loss`` pick among them.

The paper's SAC baseline (trained on the scalar ``original_reward``) is ``MOSACLoss(actor, critic,
num_objectives=1, preference=torch.ones(1))`` after ``loss.set_keys(reward="original_reward")``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDictBase
from tensordict.nn import ProbabilisticTensorDictSequential, TensorDictModule
from tensordict.utils import NestedKey
from torch import Tensor
from torchrl.data import Composite, TensorSpec

from morl_trl.objectives.actor_critic_parts import (ALPHA_LOSS_FORMS, ContinuousSoftActorCriticBase,
                                                    SoftActorCriticBase, check_alpha_loss_form, draw, elementwise_min,
                                                    expected_log_prob, expected_soft_actor_objective,
                                                    expected_soft_next_value, scalarized_critic_loss, scalarized_min,
                                                    soft_actor_objective, soft_next_value, temperature_objective,
                                                    vector_critic_loss)
from morl_trl.objectives.envelope import action_index

__all__ = ["DiscreteMOSACLoss", "MOSACLoss", "ALPHA_LOSS_FORMS", "check_alpha_loss_form", "temperature_objective"]

#: ``critic_min``: the pessimistic value over the critic ensemble, the vector of the critic with the lowest
#: ``w . Q`` (MORL/D) or the per-objective minimum (CAPQL's)
PESSIMISTIC_VALUES = {"scalarized": scalarized_min, "elementwise": elementwise_min}
#: ``critic_loss``: the critics regress the scalarised values (MORL/D) or the vectors (CAPQL's)
CRITIC_LOSSES = {"scalarized": scalarized_critic_loss, "vector": vector_critic_loss}
CRITIC_MIN_MODES = tuple(PESSIMISTIC_VALUES)
CRITIC_LOSS_MODES = tuple(CRITIC_LOSSES)


def check_choice(name: str, value: str, choices) -> None:
    """A ``ValueError`` naming the valid values unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"{name}={value!r}; valid values are {tuple(choices)}.")


class MOSACLoss(ContinuousSoftActorCriticBase):
    r"""Multi-objective SAC for continuous actions: vector critics, scalarised actor.

    For each transition with preference :math:`w`, the ``num_qvalue_nets`` vector critics regress onto

    .. math::

        y = r + \gamma (1 - d) \big(Q^-_{\min}(s', a', w) - \alpha \log\pi(a' | s', w)\,\mathbf 1\big),
        \quad a' \sim \pi(\cdot | s', w)

    and the actor minimises :math:`\alpha \log\pi(a|s,w) - w^\top Q_{\min}(s, a, w)`. :math:`Q_{\min}` is the
    vector of the critic with the lowest :math:`w^\top Q` (``critic_min="scalarized"``, MORL/D) or the
    per-objective minimum (``"elementwise"``, CAPQL). The critic loss is the squared error of the scalarised values
    (``critic_loss="scalarized"``, MORL/D) or of the vectors (``"vector"``, CAPQL). :math:`\alpha` is tuned towards
    ``target_entropy`` unless ``fixed_alpha``.

    Where the preference comes from: a fixed ``preference`` (one MORL/D policy; change it with
    :meth:`set_preference`), fresh draws per sample (``resample_preferences=True``) or the batch's ``"preference"``
    entry. Networks that do not read the preference (MORL/D's) are fine: the preference then only scalarises.

    Args:
        actor_network (ProbabilisticTensorDictSequential): stochastic actor, e.g.
            :func:`~morl_trl.objectives.networks.make_gaussian_actor`.
        qvalue_network (TensorDictModule): vector critic writing ``"state_action_value"`` ``[*B, k]``, e.g.
            :func:`~morl_trl.objectives.networks.make_vector_critic`. Its parameters are expanded to
            ``num_qvalue_nets`` independently initialised copies, as in TorchRL's SAC.

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

    def __init__(self, actor_network: ProbabilisticTensorDictSequential, qvalue_network: TensorDictModule, *,
                 num_objectives: int | None = None, num_qvalue_nets: int = 2, preference: Tensor | None = None,
                 resample_preferences: bool = False, preference_distribution: str = "dirichlet",
                 critic_min: str = "scalarized", critic_loss: str = "scalarized", loss_function: str = "l2",
                 alpha_init: float = 1.0, min_alpha: float | None = None, max_alpha: float | None = None,
                 fixed_alpha: bool = False, target_entropy: float | str = "auto", action_spec: TensorSpec | None = None,
                 delay_qvalue: bool = True, reduction: str = "mean", use_prioritized_weights: str | bool = "auto",
                 deactivate_vmap: bool = False, alpha_loss_form: str = "log_alpha") -> None:
        check_choice("critic_min", critic_min, PESSIMISTIC_VALUES)
        check_choice("critic_loss", critic_loss, CRITIC_LOSSES)
        super().__init__(actor_network, qvalue_network, num_objectives=num_objectives, num_qvalue_nets=num_qvalue_nets,
                         preference=preference, resample_preferences=resample_preferences,
                         preference_distribution=preference_distribution, loss_function=loss_function,
                         alpha_init=alpha_init, min_alpha=min_alpha, max_alpha=max_alpha, fixed_alpha=fixed_alpha,
                         delay_qvalue=delay_qvalue, reduction=reduction,
                         use_prioritized_weights=use_prioritized_weights, deactivate_vmap=deactivate_vmap,
                         alpha_loss_form=alpha_loss_form)
        self.critic_min = critic_min
        self.critic_loss = critic_loss
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

    def _select_min(self, q: Tensor, w: Tensor) -> Tensor:
        """The pessimistic vector value over the critic ensemble ``q`` (``[n, B, ..., k]``), per ``critic_min``."""
        return PESSIMISTIC_VALUES[self.critic_min](q, w)

    # ------------------------------------------------------------ value estimate
    @torch.no_grad()
    def _value_target(self, data: TensorDictBase, w: Tensor) -> Tensor:
        """``[B, k]``: ``r + gamma (1 - d) (Q^-_min(s', a', w) - alpha log pi(a'|s', w))``, ``a' ~ pi(.|s', w)``."""
        next_data = data.get("next")
        next_action, next_log_prob = draw(self._policy_dist(next_data, w))
        q_next = self._critics(next_data, w, next_action, params="target")
        next_value = soft_next_value(self._select_min(q_next, w), next_log_prob, self._alpha)
        return self.value_estimator.value_estimate(data, next_value=next_value)

    # ------------------------------------------------------------ critic loss
    def _critic_loss(self, data: TensorDictBase, w: Tensor) -> tuple[Tensor, Tensor]:
        """Per-sample critic loss (``critic_loss``, summed over the critics) and priority."""
        target = self._value_target(data, w)
        q = self._critics(data, w)
        return CRITIC_LOSSES[self.critic_loss](q, target, w, self.loss_function)

    # ------------------------------------------------------------ actor loss
    def _actor_loss(self, data: TensorDictBase, w: Tensor, dist=None) -> tuple[Tensor, Tensor]:
        """Per-sample actor loss and the sampled actions' log-probabilities (critics without gradient)."""
        action, log_prob = draw(self._policy_dist(data, w) if dist is None else dist)
        q = self._critics(data, w, action, params="detached")
        return soft_actor_objective(log_prob, self._select_min(q, w), w, self._alpha), log_prob


class DiscreteMOSACLoss(SoftActorCriticBase):
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

    def __init__(self, actor_network: ProbabilisticTensorDictSequential, qvalue_network: TensorDictModule, *,
                 num_actions: int | None = None, num_objectives: int | None = None, num_qvalue_nets: int = 2,
                 preference: Tensor | None = None, resample_preferences: bool = False,
                 preference_distribution: str = "dirichlet", critic_min: str = "scalarized",
                 critic_loss: str = "scalarized", loss_function: str = "l2", alpha_init: float = 1.0,
                 min_alpha: float | None = None, max_alpha: float | None = None, fixed_alpha: bool = False,
                 target_entropy_weight: float = 0.98, target_entropy: float | str = "auto", delay_qvalue: bool = True,
                 reduction: str = "mean", use_prioritized_weights: str | bool = "auto", deactivate_vmap: bool = False,
                 alpha_loss_form: str = "log_alpha") -> None:
        check_choice("critic_min", critic_min, PESSIMISTIC_VALUES)
        check_choice("critic_loss", critic_loss, CRITIC_LOSSES)
        super().__init__(actor_network, qvalue_network, num_objectives=num_objectives, num_qvalue_nets=num_qvalue_nets,
                         preference=preference, resample_preferences=resample_preferences,
                         preference_distribution=preference_distribution, loss_function=loss_function,
                         alpha_init=alpha_init, min_alpha=min_alpha, max_alpha=max_alpha, fixed_alpha=fixed_alpha,
                         delay_qvalue=delay_qvalue, reduction=reduction,
                         use_prioritized_weights=use_prioritized_weights, deactivate_vmap=deactivate_vmap,
                         alpha_loss_form=alpha_loss_form)
        self.critic_min = critic_min
        self.critic_loss = critic_loss
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

    fresh_temperature_sample = False  # the actor step's probabilities (mosac_discrete_action.py:490-492)

    def _select_min(self, q: Tensor, w: Tensor) -> Tensor:
        """The pessimistic vector values over the critic ensemble ``q`` (``[n, B, |A|, k]``), per ``critic_min``."""
        return PESSIMISTIC_VALUES[self.critic_min](q, w)

    def _policy_dist(self, data: TensorDictBase, w: Tensor):
        """The current actor's categorical distribution on ``data`` under the preference ``w``."""
        td = self._network_inputs(self.actor_network.in_keys, data, w)
        with self.actor_network_params.to_module(self.actor_network, preserve_module_state=False):
            return self.actor_network.get_dist(td)

    def _critics(self, data: TensorDictBase, w: Tensor, params: str = "online") -> Tensor:
        """``[n, B, |A|, k]``: every critic on ``data`` under ``w`` (``"online"``, ``"target"`` or ``"detached"``)."""
        td = self._network_inputs(self.qvalue_network.in_keys, data, w)
        return self._critic_ensemble(td, self._critic_params(params), self.tensor_keys.action_value)

    # ------------------------------------------------------------ value estimate
    @torch.no_grad()
    def _value_target(self, data: TensorDictBase, w: Tensor) -> Tensor:
        """``[B, k]``: ``r + gamma (1 - d) sum_a' pi(a'|s', w) (Q^-_min(s', a', w) - alpha log pi(a'|s', w))``."""
        next_data = data.get("next")
        dist = self._policy_dist(next_data, w)
        probs, log_probs = dist.probs, dist.logits
        q_next = self._select_min(self._critics(next_data, w, params="target"), w)
        next_value = expected_soft_next_value(probs, log_probs, q_next, self._alpha)
        return self.value_estimator.value_estimate(data, next_value=next_value)

    # ------------------------------------------------------------ critic loss
    def _critic_loss(self, data: TensorDictBase, w: Tensor) -> tuple[Tensor, Tensor]:
        """Per-sample critic loss of the taken actions' values (``critic_loss``) and priority."""
        batch, k = data.shape[0], self.num_objectives
        target = self._value_target(data, w)
        q = self._critics(data, w)
        index = action_index(data.get(self.tensor_keys.action), batch, q.shape[-2])
        q_taken = q.gather(-2, index.view(1, batch, 1, 1).expand(q.shape[0], batch, 1, k)).squeeze(-2)
        return CRITIC_LOSSES[self.critic_loss](q_taken, target, w, self.loss_function)

    # ------------------------------------------------------------ actor loss
    def _actor_loss(self, data: TensorDictBase, w: Tensor, dist=None) -> tuple[Tensor, Tensor]:
        """Per-state actor loss (exact expectation over the actions) and ``sum_a pi log pi``."""
        dist = self._policy_dist(data, w) if dist is None else dist
        probs, log_probs = dist.probs, dist.logits
        q_pi = self._select_min(self._critics(data, w, params="detached"), w)
        loss = expected_soft_actor_objective(probs, log_probs, q_pi, w.unsqueeze(-2), self._alpha)
        return loss, expected_log_prob(probs, log_probs)

    def _fresh_log_prob(self, dist) -> Tensor:
        return expected_log_prob(dist.probs, dist.logits)
