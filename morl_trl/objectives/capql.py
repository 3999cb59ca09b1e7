"""CAPQL (Lu, Herman & Yu, ICLR 2023) as a TorchRL loss."""

from __future__ import annotations

from tensordict.nn import ProbabilisticTensorDictSequential, TensorDictModule

from morl_trl.objectives.mosac import MOSACLoss

__all__ = ["CAPQLLoss"]


class CAPQLLoss(MOSACLoss):
    r"""Concave-augmented Pareto Q-learning: one preference-conditioned SAC for all preferences.

    A preference-conditioned actor :math:`\pi(a | s, w)` and two vector critics
    :math:`Q_{1,2}(s, a, w) \in \mathbb R^k` are trained for every preference at
    once. Each transition is trained on the preference :math:`w` stored with it
    (the one its action was chosen with: the authors' runs draw a new one every
    env step from a 22.5-degree cone, see
    :func:`~morl_trl.preferences.sample_cone_preferences`); with
    ``resample_preferences=True`` it gets a fresh one (uniform on the simplex) at
    every call instead. The critics regress onto

    .. math::

        y = r + \gamma (1 - d) \big(\min_{i} Q^-_i(s', a', w) - \alpha \log\pi(a'|s', w)\,\mathbf 1\big),
        \quad a' \sim \pi(\cdot | s', w)

    with the minimum taken per objective, and the actor minimises the
    entropy-augmented scalarised objective
    :math:`\alpha \log\pi(a|s,w) - w^\top \min_i Q_i(s, a, w)` with a fixed
    :math:`\alpha` (0.2 in the paper's runs).

    This is :class:`~morl_trl.objectives.mosac.MOSACLoss` with
    ``critic_min="elementwise"``, ``critic_loss="vector"`` and ``fixed_alpha=True``,
    reading the batch's ``"preference"`` as the authors' runs do; pass
    ``resample_preferences=True`` to train on fresh preferences per sample instead
    (morl_trl's former default: every update covers the whole simplex).

    Args:
        actor_network: e.g. :func:`~morl_trl.objectives.networks.make_gaussian_actor`.
        qvalue_network: e.g. :func:`~morl_trl.objectives.networks.make_vector_critic`.

    Keyword Args:
        alpha (float): entropy coefficient. Defaults to 0.2.
        resample_preferences (bool): fresh preferences per sample instead of the batch's
            stored ones. Defaults to ``False`` (stored, as the authors).
        **kwargs: any other :class:`MOSACLoss` keyword.

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

    def __init__(
        self,
        actor_network: ProbabilisticTensorDictSequential,
        qvalue_network: TensorDictModule,
        *,
        alpha: float = 0.2,
        resample_preferences: bool = False,
        **kwargs,
    ) -> None:
        kwargs.setdefault("critic_min", "elementwise")
        kwargs.setdefault("critic_loss", "vector")
        kwargs.setdefault("fixed_alpha", True)
        super().__init__(
            actor_network,
            qvalue_network,
            alpha_init=alpha,
            resample_preferences=resample_preferences,
            **kwargs,
        )
