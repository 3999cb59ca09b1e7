"""CAPQL (Lu, Herman & Yu, ICLR 2023) as a TorchRL loss."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import ProbabilisticTensorDictSequential, TensorDictModule
from torch import Tensor

from morl_trl.objectives.actor_critic_parts import (LOG_PROB_FORMS, ContinuousSoftActorCriticBase, draw, draw_clamped,
                                                    elementwise_min, soft_actor_objective, soft_next_value,
                                                    vector_critic_loss)

__all__ = ["CAPQLLoss"]


class CAPQLLoss(ContinuousSoftActorCriticBase):
    r"""Concave-augmented Pareto Q-learning: one preference-conditioned SAC for all preferences.

    A preference-conditioned actor :math:`\pi(a | s, w)` and two vector critics
    :math:`Q_{1,2}(s, a, w) \in \mathbb R^k` are trained for every preference at once, each transition on
    the preference :math:`w` stored with it, as the authors' runs do (drawn every env step from a 22.5-degree
    cone, :func:`~morl_trl.preferences.sample_cone_preferences`); ``resample_preferences=True``: a fresh
    one (uniform on the simplex) at every call.

    * Value estimate (:meth:`_value_target`): with :math:`a' \sim \pi(\cdot | s', w)`,

      .. math::

          y = r + \gamma (1 - d) \big(\min_{i} Q^-_i(s', a', w) - \alpha \log\pi(a'|s', w)\,\mathbf 1\big),

      the minimum over the target critics taken per objective.
    * Critic loss (:meth:`_critic_loss`): each critic's squared error to :math:`y`, averaged over the
      objectives and summed over the critics; the priority is :math:`|w^\top (Q_i - y)|`, largest over the critics.
    * Actor loss (:meth:`_actor_loss`): :math:`\alpha \log\pi(a|s,w) - w^\top \min_i Q_i(s, a, w)`,
      :math:`a \sim \pi(\cdot|s, w)`, with a fixed :math:`\alpha` (0.2 in the paper's runs).

    :math:`\log\pi` is the authors' (``log_prob_form="clamped"``, :func:`~morl_trl.objectives.actor_critic_parts.draw_clamped`):
    the pre-squash Normal's log-density minus :math:`\sum \log(s (1 - \tanh^2 x) + 10^{-6})`, clamped to
    :math:`[-1000, 1000]`; ``"exact"``: TorchRL's ``TanhNormal`` (the exact Jacobian, unbounded where ``tanh``
    saturates).

    The three parts are computed alone by :meth:`qvalue_loss` and :meth:`actor_loss` (the authors'
    critic step, then the actor step) and together by :meth:`forward`.

    Args:
        actor_network: e.g. :func:`~morl_trl.objectives.networks.make_gaussian_actor`.
        qvalue_network: e.g. :func:`~morl_trl.objectives.networks.make_vector_critic`. Its parameters
            are expanded to ``num_qvalue_nets`` independently initialised copies, as in TorchRL's SAC.

    Keyword Args:
        alpha (float): entropy coefficient. Defaults to 0.2.
        resample_preferences (bool): fresh preferences per sample instead of the batch's
            stored ones. Defaults to ``False`` (stored, as the authors).
        num_objectives (int, optional): ``k``; read from networks made by the builders.
        num_qvalue_nets (int): size of the critic ensemble. Defaults to 2.
        preference_distribution (str): ``"dirichlet"`` (default) or ``"gaussian"``, for resampling.
        loss_function (str): ``"l2"`` (default), ``"l1"`` or ``"smooth_l1"``.
        delay_qvalue (bool): keep target critic parameters (``SoftUpdate``). Defaults to ``True``.
        reduction (str): ``"mean"`` (default), ``"sum"`` or ``"none"``.
        use_prioritized_weights (bool or "auto"): weight samples by ``"priority_weight"``.
        deactivate_vmap (bool): loop over the critics instead of ``vmap``. Defaults to ``False``.
        log_prob_form (str): ``"clamped"`` (the authors', the default) or ``"exact"`` (TorchRL's ``TanhNormal``);
            see above.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl.data import Bounded
        >>> from morl_trl.objectives.networks import make_gaussian_actor, make_vector_critic
        >>> spec = Bounded(-1.0, 1.0, (3,))
        >>> from torchrl.objectives import SoftUpdate
        >>> loss = CAPQLLoss(make_gaussian_actor(7, spec, 2, num_cells=(32,)), make_vector_critic(7, 3, 2, num_cells=(32,)))
        >>> updater = SoftUpdate(loss, tau=0.005)
        >>> B = 8
        >>> data = TensorDict({
        ...     "observation": torch.randn(B, 7), "action": spec.rand((B,)), "preference": torch.full((B, 2), 0.5),
        ...     ("next", "observation"): torch.randn(B, 7), ("next", "reward"): torch.randn(B, 2),
        ...     ("next", "done"): torch.zeros(B, 1, dtype=torch.bool),
        ...     ("next", "terminated"): torch.zeros(B, 1, dtype=torch.bool)}, [B])
        >>> sorted(loss(data).keys())
        ['alpha', 'entropy', 'loss_actor', 'loss_qvalue']
    """

    def __init__(self, actor_network: ProbabilisticTensorDictSequential, qvalue_network: TensorDictModule, *,
                 alpha: float = 0.2, resample_preferences: bool = False, num_objectives: int | None = None,
                 num_qvalue_nets: int = 2, preference_distribution: str = "dirichlet", loss_function: str = "l2",
                 delay_qvalue: bool = True, reduction: str = "mean", use_prioritized_weights: str | bool = "auto",
                 deactivate_vmap: bool = False, log_prob_form: str = "clamped") -> None:
        if log_prob_form not in LOG_PROB_FORMS:
            raise ValueError(f"log_prob_form={log_prob_form!r}; valid values are {LOG_PROB_FORMS}.")
        super().__init__(actor_network, qvalue_network, num_objectives=num_objectives, num_qvalue_nets=num_qvalue_nets,
                         preference=None, resample_preferences=resample_preferences,
                         preference_distribution=preference_distribution, loss_function=loss_function,
                         alpha_init=alpha, min_alpha=None, max_alpha=None, fixed_alpha=True, delay_qvalue=delay_qvalue,
                         reduction=reduction, use_prioritized_weights=use_prioritized_weights,
                         deactivate_vmap=deactivate_vmap, alpha_loss_form="log_alpha")
        # the temperature is fixed: no target entropy is used (kept as the state's entry)
        self.register_buffer("target_entropy", torch.tensor(0.0, device=self.log_alpha.device))
        self.log_prob_form = log_prob_form
        self._draw = draw_clamped if log_prob_form == "clamped" else draw

    # ------------------------------------------------------------ value estimate
    @torch.no_grad()
    def _value_target(self, data: TensorDictBase, w: Tensor) -> Tensor:
        """``[B, k]``: ``r + gamma (1 - d) (min_i Q^-_i(s', a', w) - alpha log pi(a'|s', w))``, ``a' ~ pi(.|s', w)``."""
        next_data = data.get("next")
        next_action, next_log_prob = self._draw(self._policy_dist(next_data, w))
        q_next = self._critics(next_data, w, next_action, params="target")
        next_value = soft_next_value(elementwise_min(q_next), next_log_prob, self._alpha)
        return self.value_estimator.value_estimate(data, next_value=next_value)

    # ------------------------------------------------------------ critic loss
    def _critic_loss(self, data: TensorDictBase, w: Tensor) -> tuple[Tensor, Tensor]:
        """Per-sample critic loss (vector squared error, summed over the critics) and priority."""
        target = self._value_target(data, w)
        q = self._critics(data, w)
        return vector_critic_loss(q, target, w, self.loss_function)

    # ------------------------------------------------------------ actor loss
    def _actor_loss(self, data: TensorDictBase, w: Tensor, dist=None) -> tuple[Tensor, Tensor]:
        """Per-sample actor loss and the sampled actions' log-probabilities (critics without gradient)."""
        action, log_prob = self._draw(self._policy_dist(data, w) if dist is None else dist)
        q = self._critics(data, w, action, params="detached")
        return soft_actor_objective(log_prob, elementwise_min(q), w, self._alpha), log_prob
