"""The SAC baseline's losses: TorchRL's ``SACLoss`` / ``DiscreteSACLoss`` with the three parts apart.

The paper's SAC baseline learns from the domain's scalar reward with TorchRL's own losses. These
subclasses change nothing in them (same parameters, same state dict, :meth:`forward` as
TorchRL's) and add what a step that updates critics, actor and temperature one after the other
needs (:meth:`~morl_trl.training.agent.Agent.actor_critic_step`, the authors' order), with the
names of :class:`~morl_trl.objectives.MOSACLoss`:

* ``qvalue_loss(td) -> (loss, {"td_error"})``: the critics' loss alone (TorchRL's
  ``qvalue_v2_loss`` / ``qvalue_loss``), writing the priority as :meth:`forward` does;
* ``actor_loss(td) -> (loss, {"log_prob"})``: TorchRL's, unchanged;
* ``temperature_loss(td, log_prob=None)``: the temperature loss on ``log_prob`` or on a fresh
  sample of the current actor, in the form ``alpha_loss_form`` names (``"alpha"``:
  ``-alpha (log pi + target)``, the authors' CleanRL-style SAC: ``sac_continuous_action.py``'s
  ``alpha_loss = (-log_alpha.exp() * (log_pi + target_entropy)).mean()``; ``"log_alpha"``:
  TorchRL's ``-log_alpha (...)``). :meth:`forward` keeps TorchRL's ``-log_alpha`` form.

Example:
    >>> import torch
    >>> from tensordict import TensorDict
    >>> from torchrl.data import Bounded
    >>> from morl_trl.objectives.networks import make_gaussian_actor, make_vector_critic
    >>> spec = Bounded(-1.0, 1.0, (2,))
    >>> loss = SACLoss(make_gaussian_actor(5, spec, 1, num_cells=(16,), preference_key=None),
    ...                make_vector_critic(5, 2, 1, num_cells=(16,), preference_key=None), action_spec=spec,
    ...                alpha_loss_form="alpha")
    >>> B = 4
    >>> data = TensorDict({"observation": torch.randn(B, 5), "action": spec.rand((B,)),
    ...     ("next", "observation"): torch.randn(B, 5), ("next", "reward"): torch.randn(B, 1),
    ...     ("next", "done"): torch.zeros(B, 1, dtype=torch.bool),
    ...     ("next", "terminated"): torch.zeros(B, 1, dtype=torch.bool)}, [B])
    >>> loss_q, meta = loss.qvalue_loss(data)
    >>> data["td_error"].shape, loss_q.shape
    (torch.Size([4]), torch.Size([]))
    >>> loss.temperature_loss(data, torch.full((B,), 1.0))  # -alpha (1 + target entropy -2), alpha = 1
    tensor(1., grad_fn=<MeanBackward0>)
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torch import Tensor
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives import DiscreteSACLoss as _TorchRLDiscreteSACLoss
from torchrl.objectives import SACLoss as _TorchRLSACLoss
from torchrl.objectives.sac import compute_rsample_log_prob

from morl_trl._torchrl_compat import (priority_weight, reduce_loss, sac_alpha, sac_detached_qvalue_params,
                                      sac_vmap_qvalue)
from morl_trl.objectives.actor_critic_parts import check_alpha_loss_form, temperature_objective

__all__ = ["SACLoss", "DiscreteSACLoss"]


class _TemperaturePart:
    """``temperature_loss`` and ``alpha_loss_form`` over TorchRL's SAC losses."""

    alpha_loss_form: str = "log_alpha"

    def _fresh_log_prob(self, tensordict: TensorDictBase, dist=None) -> Tensor:  # pragma: no cover - overridden
        raise NotImplementedError

    def temperature_loss(self, tensordict: TensorDictBase, log_prob: Tensor | None = None, dist=None) -> Tensor:
        """The temperature loss alone, reduced as :meth:`forward` reduces it, on ``log_prob`` or, when
        ``None``, on a fresh sample of the current actor (from ``dist``, ``actor_dist``, when given;
        no gradient to the actor)."""
        if log_prob is None:
            with torch.no_grad():
                log_prob = self._fresh_log_prob(tensordict, dist)
        sac_alpha(self)  # clamps log_alpha to [min_alpha, max_alpha] as TorchRL's forward does
        loss = temperature_objective(self.log_alpha, log_prob.detach(), self.target_entropy, self.alpha_loss_form)
        return reduce_loss(self, loss, tensordict, priority_weight(self, tensordict))


class SACLoss(_TemperaturePart, _TorchRLSACLoss):
    """TorchRL's ``SACLoss`` (continuous actions) with :meth:`qvalue_loss` and :meth:`temperature_loss`
    (see the module docstring); ``alpha_loss_form`` (keyword, default ``"log_alpha"``) picks the
    temperature loss's form; every other argument is TorchRL's."""

    #: the authors' SAC draws a fresh sample after the actor step for the temperature
    fresh_temperature_sample = True

    def __init__(self, *args, alpha_loss_form: str = "log_alpha", **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.alpha_loss_form = check_alpha_loss_form(alpha_loss_form)

    def qvalue_loss(self, tensordict: TensorDictBase) -> tuple[Tensor, dict[str, Tensor]]:
        """TorchRL's ``qvalue_v2_loss``, writing the priority into ``tensordict`` as :meth:`forward` does."""
        loss, metadata = self.qvalue_v2_loss(tensordict)
        tensordict.set(self.tensor_keys.priority, metadata["td_error"])
        return loss, metadata

    def actor_dist(self, tensordict: TensorDictBase):
        """The current actor's distribution on ``tensordict`` (with gradient), to share between
        :meth:`temperature_loss` and :meth:`actor_loss`: one network forward for the temperature's
        fresh sample and the next actor step's sample, drawn in that order."""
        return self._current_dist(tensordict)

    def _current_dist(self, tensordict: TensorDictBase):
        with set_exploration_type(ExplorationType.RANDOM), self.actor_network_params.to_module(
                self.actor_network, preserve_module_state=False):
            return self.actor_network.get_dist(tensordict)

    def actor_loss(self, tensordict: TensorDictBase, dist=None) -> tuple[Tensor, dict[str, Tensor]]:
        """TorchRL's ``actor_loss``; from ``dist`` (:meth:`actor_dist`) when given, with TorchRL's
        arithmetic (``tests/recipes/test_actor_critic_step.py`` checks both give the same loss)."""
        if dist is None:
            return super().actor_loss(tensordict)
        with set_exploration_type(ExplorationType.RANDOM):
            action, log_prob = compute_rsample_log_prob(dist)
        td_q = tensordict.select(*self.qvalue_network.in_keys, strict=False)
        td_q.set(self.tensor_keys.action, action)
        q = sac_vmap_qvalue(self)(td_q, sac_detached_qvalue_params(self)).get(self.tensor_keys.state_action_value)
        loss = sac_alpha(self) * log_prob - q.min(0)[0].squeeze(-1)
        loss = reduce_loss(self, loss, tensordict, priority_weight(self, tensordict))
        return loss, {"log_prob": log_prob.detach()}

    def _fresh_log_prob(self, tensordict: TensorDictBase, dist=None) -> Tensor:
        dist = self._current_dist(tensordict) if dist is None else dist
        with set_exploration_type(ExplorationType.RANDOM):
            return compute_rsample_log_prob(dist)[1]


class DiscreteSACLoss(_TemperaturePart, _TorchRLDiscreteSACLoss):
    """TorchRL's ``DiscreteSACLoss`` with :meth:`qvalue_loss` writing the priority and
    :meth:`temperature_loss` (see the module docstring); ``alpha_loss_form`` as :class:`SACLoss`'s."""

    #: the authors' discrete SAC reuses the actor step's probabilities for the temperature (CleanRL's
    #: ``sac_atari.py``: "re-use action probabilities for temperature loss")
    fresh_temperature_sample = False

    def __init__(self, *args, alpha_loss_form: str = "log_alpha", **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.alpha_loss_form = check_alpha_loss_form(alpha_loss_form)

    def qvalue_loss(self, tensordict: TensorDictBase) -> tuple[Tensor, dict[str, Tensor]]:
        """TorchRL's ``qvalue_loss``, writing the priority into ``tensordict`` as :meth:`forward` does."""
        loss, metadata = super().qvalue_loss(tensordict)
        tensordict.set(self.tensor_keys.priority, metadata["td_error"])
        return loss, metadata

    def _fresh_log_prob(self, tensordict: TensorDictBase, dist=None) -> Tensor:
        if dist is None:
            with self.actor_network_params.to_module(self.actor_network, preserve_module_state=False):
                dist = self.actor_network.get_dist(tensordict.clone(False))
        return (dist.probs * dist.logits).sum(-1)
