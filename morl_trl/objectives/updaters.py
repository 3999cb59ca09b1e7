"""Target-network updaters."""

from __future__ import annotations

import torch
from torch import Tensor
from torchrl.objectives import HardUpdate, SoftUpdate
from torchrl.objectives.utils import TargetNetUpdater

from morl_trl._torchrl_compat import target_updater_params

__all__ = ["PeriodicHardUpdate", "PolyakUpdate", "polyak_"]


def polyak_(targets, sources, tau: float) -> None:
    r"""In place, in one ``foreach`` lerp: :math:`\theta^- \leftarrow \theta^- + \tau(\theta - \theta^-)` for
    paired lists (or TensorDicts) of target and source parameters.

    Example:
        >>> t, s = [torch.zeros(2)], [torch.ones(2)]
        >>> polyak_(t, s, 0.25)
        >>> t[0]
        tensor([0.2500, 0.2500])
    """
    if not isinstance(targets, (list, tuple)):
        targets, sources = list(targets.values(True, True)), list(sources.values(True, True))
    with torch.no_grad():
        torch._foreach_lerp_([t.data for t in targets], [x.data for x in sources], tau)


class PolyakUpdate(SoftUpdate):
    r"""TorchRL's :class:`~torchrl.objectives.SoftUpdate` stepping every target leaf in one ``foreach`` lerp.

    The same arithmetic (:math:`\theta^- \leftarrow \theta^- + \tau(\theta - \theta^-)`, the
    ``lerp_`` ``SoftUpdate`` runs, bit-identical results), without building TensorDicts of the
    parameters at every step: about 0.06 ms instead of 0.45 ms per step for two 4 x 256 critics
    on a CPU core, and one kernel launch on an accelerator. :meth:`leaves` gives the
    ``(sources, targets)`` lists, e.g. for a masked step inside a captured update.

    Example:
        >>> from torchrl.data import Bounded
        >>> from morl_trl.objectives import CAPQLLoss, make_gaussian_actor, make_vector_critic
        >>> loss = CAPQLLoss(make_gaussian_actor(4, Bounded(-1.0, 1.0, (2,)), 2, num_cells=(8,)),
        ...                  make_vector_critic(4, 2, 2, num_cells=(8,)))
        >>> updater = PolyakUpdate(loss, tau=0.5)
        >>> sources, targets = updater.leaves()
        >>> _ = [t.data.zero_() for t in targets]
        >>> updater.step()
        >>> torch.equal(targets[0], 0.5 * sources[0].detach())
        True
    """

    def leaves(self) -> tuple[list[Tensor], list[Tensor]]:
        """``(sources, targets)``: the online and target parameter tensors, paired in order."""
        pairs = self.__dict__.get("_leaf_pairs")
        if pairs is None:
            target_names, source_params, target_params = target_updater_params(self)
            for name in target_names:
                getattr(self.loss_module, name)
            sources, targets = [], []
            for key, source in source_params.items():
                target = target_params.get(f"target_{key}")
                for leaf in source.keys(True, True):
                    sources.append(source.get(leaf))
                    targets.append(target.get(leaf))
            pairs = self.__dict__["_leaf_pairs"] = (sources, targets)
        return pairs

    def step(self) -> None:
        if not self.initialized:
            raise Exception(f"{type(self).__name__} must be initialized (`{type(self).__name__}.init_()`) "
                            "before calling step()")
        sources, targets = self.leaves()
        polyak_(targets, sources, 1 - self.eps)


class PeriodicHardUpdate(HardUpdate):
    r"""A hard copy of the online parameters into the target ones on every ``value_network_update_interval``-th
    :meth:`step`: MORL-Baselines' ``global_step % target_net_update_freq == 0`` with one step per update.

    TorchRL's :class:`~torchrl.objectives.HardUpdate` copies when its counter, which runs
    ``0, 1, ..., n``, equals ``n``: every ``n + 1`` steps. With ``n = 1`` (a copy per call, as GPI's
    recipe steps it once per ``target_update_period`` frames) that is every *second* call, which
    doubled GPI's target period; with ``n = 200`` (Envelope) it was 201 updates (issue 48). Here the
    counter runs ``0 .. n - 1`` and the copy happens when it wraps. ``counter`` keeps TorchRL's name,
    so checkpoints carry it as before (a saved counter at or past ``n`` copies at the next step).

    Example:
        >>> from morl_trl.objectives import GPILoss, GPIQNetwork
        >>> loss = GPILoss(GPIQNetwork(2, 4, 2, hidden=(8, 8)))
        >>> updater = PeriodicHardUpdate(loss, value_network_update_interval=2)
        >>> copied = []
        >>> for _ in range(4):
        ...     _ = [p.data.add_(1.0) for p in loss.value_network_params.values(True, True)]
        ...     updater.step()
        ...     copied.append(all(torch.equal(a, b) for a, b in zip(loss.value_network_params.values(True, True),
        ...                                                           loss.target_value_network_params.values(True, True))))
        >>> copied
        [False, True, False, True]
    """

    def __init__(self, loss_module, *, value_network_update_interval: int = 1000) -> None:
        if int(value_network_update_interval) < 1:
            raise ValueError(f"value_network_update_interval must be >= 1, got {value_network_update_interval}")
        super().__init__(loss_module, value_network_update_interval=int(value_network_update_interval))

    def _step(self, p_source: Tensor, p_target: Tensor) -> None:
        p_target.data.copy_(p_source.data)

    def step(self) -> None:
        self.counter += 1
        if self.counter >= self.value_network_update_interval:
            self.counter = 0
            TargetNetUpdater.step(self)  # (the initialised check, then _step on every parameter: the copy)
