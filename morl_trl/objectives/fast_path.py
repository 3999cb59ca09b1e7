"""Evaluating the losses' networks from their functional parameters without swapping them in.

TorchRL's losses call a network with functional parameters (current, target, detached, one
member of an ensemble) by swapping them into the module (``TensorDict.to_module``) for each
call: a Python walk over every submodule, about 0.2 ms per call on a CPU core, eight or more
calls per SAC update. For the networks :mod:`morl_trl.objectives.networks` builds, the losses
instead read the parameter leaves once per update and run
:meth:`~morl_trl.objectives.networks.PreferenceConditionedMLP.forward_with`: the same tensor
operations in the same order (bit-identical results on the loop path), no module state touched.

Any other network (a custom module, an encoder in front) takes TorchRL's generic path;
``loss.fast_networks = False`` forces it.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import ProbabilisticTensorDictModule, TensorDictModule, TensorDictParams
from tensordict.utils import NestedKey
from torch import Tensor

from morl_trl._torchrl_compat import module_kwargs, tensordict_entries, tensordict_params_data
from morl_trl.objectives.networks import PreferenceConditionedMLP

__all__ = ["FunctionalNetwork", "GaussianActorPlan"]


def _keys(prefix: tuple[str, ...], module: torch.nn.Module) -> list[tuple[str, ...]]:
    return [(*prefix, *name.split(".")) for name, _ in module.named_parameters()]


def _covers(params: TensorDictBase, keys: list[tuple[str, ...]]) -> bool:
    leaves = list(params.keys(True, True))
    return len(leaves) == len(keys) and all(params.get(k, None) is not None for k in keys)


@dataclass
class FunctionalNetwork:
    """A :class:`PreferenceConditionedMLP` reached through ``prefix`` in a parameter TensorDict.

    Attributes:
        net: the MLP (its own parameters are TorchRL's meta placeholders; never read).
        keys: the parameter leaves' keys in the TensorDict, in ``net.named_parameters()`` order.
        in_keys: the TensorDict keys of the network's positional inputs.

    Example:
        >>> from tensordict import TensorDict
        >>> from morl_trl.objectives import make_vector_critic
        >>> critic = make_vector_critic(5, 2, 3, num_cells=(16,))
        >>> params = TensorDict.from_module(critic)
        >>> plan = FunctionalNetwork.of(critic, params)
        >>> x, a, w = torch.randn(4, 5), torch.rand(4, 2), torch.full((4, 3), 1 / 3)
        >>> torch.equal(plan(plan.leaves(params), [x, a, w]), critic.module(x, a, w))
        True
    """

    net: PreferenceConditionedMLP
    keys: list[tuple[str, ...]]
    in_keys: list[NestedKey]

    @classmethod
    def of(cls, module: TensorDictModule, params: TensorDictBase, prefix: tuple[str, ...] = ("module",)):
        """The plan for a plain positional ``TensorDictModule(PreferenceConditionedMLP)``, else ``None``."""
        if type(module) is not TensorDictModule or module_kwargs(module):
            return None
        net = module.module
        if not isinstance(net, PreferenceConditionedMLP) or not net.supports_forward_with:
            return None
        keys = _keys(prefix, net)
        if not _covers(params, keys):
            return None
        return cls(net, keys, list(module.in_keys))

    def leaves(self, params: TensorDictBase) -> list[Tensor]:
        """``[params.get(key) for key in keys]``; of a ``TensorDictParams`` without get hooks (a loss's
        parameters), read from its tensordict's entries directly (the same tensors: its ``get`` is a nested
        lookup through two wrappers per leaf, which cost as much as a small network's layer, three times an update)."""
        data = tensordict_params_data(params) if type(params) is TensorDictParams else None
        if data is not None:
            out = []
            for key in self.keys:
                node = data
                for name in key:
                    if type(node) is not TensorDict:
                        return [params.get(k) for k in self.keys]
                    node = tensordict_entries(node).get(name)
                if node is None or not isinstance(node, Tensor):
                    return [params.get(k) for k in self.keys]
                out.append(node)
            return out
        return [params.get(k) for k in self.keys]

    def __call__(self, leaves: list[Tensor], inputs: list[Tensor]) -> Tensor:
        return self.net._forward_with(leaves, *inputs)  # structure checked when the plan was made


@dataclass
class GaussianActorPlan:
    """:func:`~morl_trl.objectives.networks.make_gaussian_actor`'s actor: MLP, loc/scale head, distribution."""

    mlp: FunctionalNetwork
    head: torch.nn.Module
    dist_module: ProbabilisticTensorDictModule

    @classmethod
    def of(cls, actor, params: TensorDictBase):
        """The plan for ``ProbabilisticActor(TensorDictModule(head(MLP)), TanhNormal)``, else ``None``."""
        modules = getattr(actor, "module", None)
        if not isinstance(modules, torch.nn.ModuleList) or len(modules) != 2:
            return None
        body, dist_module = modules
        if type(body) is not TensorDictModule or module_kwargs(body):
            return None
        if not isinstance(dist_module, ProbabilisticTensorDictModule):
            return None
        head = body.module
        net = getattr(head, "net", None)
        if not hasattr(head, "head") or not isinstance(net, PreferenceConditionedMLP) or not net.supports_forward_with:
            return None
        if list(body.out_keys) != list(dist_module.in_keys) or len(body.out_keys) != 2:
            return None
        keys = _keys(("module", "0", "module", "net"), net)
        if not _covers(params, keys):
            return None
        return cls(FunctionalNetwork(net, keys, list(body.in_keys)), head, dist_module)

    def dist(self, leaves: list[Tensor], inputs: list[Tensor]):
        """The action distribution, built as ``ProbabilisticTensorDictModule.get_dist`` builds it."""
        params = self.head.head(self.mlp(leaves, inputs))
        kwargs = {}
        for dist_key, value in zip(self.dist_module.dist_keys, params):
            kwargs[dist_key[-1] if isinstance(dist_key, tuple) else dist_key] = value
        return self.dist_module.distribution_class(**kwargs, **dict(self.dist_module.distribution_kwargs))
