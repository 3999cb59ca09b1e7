"""A :class:`~tensordict.nn.TensorDictSequential` whose call runs its modules with less plumbing.

A one-env run calls its policy once per frame, and the policy is a chain of small modules (the
Q-network, the greedy choice, ε-greedy on top): TensorDict's wrappers around each call (the
dispatch and ``skip_existing`` decorators of the chain and of each ``TensorDictModule``, and the
chain's final ``update`` of the tensordict from itself) cost several times the network's own
arithmetic. :class:`LeanSequential` computes exactly what ``TensorDictSequential`` computes --
the same modules called in the same order on the same entries, hence the same values and random
draws -- reading each plain ``TensorDictModule``'s inputs and writing its outputs directly, when
nothing else is asked of it (no ``tensordict_out``, keyword arguments, output selection, partial
tolerance, hooks, or a non-default module option). Any other call is ``TensorDictSequential``'s.

Example:
    >>> import torch
    >>> from tensordict import TensorDict
    >>> from tensordict.nn import TensorDictModule
    >>> double = TensorDictModule(lambda x: 2 * x, in_keys=["x"], out_keys=["y"])
    >>> plus_one = TensorDictModule(lambda y: y + 1, in_keys=["y"], out_keys=["z"])
    >>> LeanSequential(double, plus_one)(TensorDict(x=torch.ones(2), batch_size=[2]))["z"]
    tensor([3., 3.])
"""

from __future__ import annotations

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential, skip_existing
from torch.nn.modules import module as _module

from morl_trl._torchrl_compat import module_kwargs

__all__ = ["LeanSequential"]


def _hooked(m: torch.nn.Module) -> bool:
    return bool(m._forward_hooks or m._forward_pre_hooks or m._backward_hooks or m._backward_pre_hooks)


def _global_hooks() -> bool:
    return bool(_module._global_forward_hooks or _module._global_forward_pre_hooks
                or _module._global_backward_hooks or _module._global_backward_pre_hooks)


def _plain_module(m) -> bool:
    """A ``TensorDictModule`` whose call is ``module(*entries)`` written to its ``out_keys``."""
    return (type(m) is TensorDictModule and module_kwargs(m) is None and m.method is None and not m.method_kwargs
            and not getattr(m, "_get_kwargs", None) and m.inplace is True and not m.strict and list(m.out_keys) == list(m.out_keys_source)
            and "_" not in m.out_keys and not _hooked(m))


class LeanSequential(TensorDictSequential):
    """:class:`~tensordict.nn.TensorDictSequential` with a short call path (see the module docstring);
    every argument is TensorDict's.

    Example:
        >>> from morl_trl.objectives import MOQValueModule, make_vector_q_network
        >>> qnet = make_vector_q_network(4, num_actions=3, num_objectives=2, num_cells=(8,))
        >>> policy = LeanSequential(qnet, MOQValueModule())
        >>> td = TensorDict(observation=torch.zeros(5, 4), preference=torch.full((5, 2), 0.5), batch_size=[5])
        >>> policy(td)["action"].shape
        torch.Size([5])
    """

    def lean_call_applies(self) -> bool:
        """Whether a call with a tensordict alone takes the short path (nothing but the modules' own work)."""
        return (self.inplace in (None, True) and not self._select_before_return and not self.partial_tolerant
                and not _hooked(self) and not _global_hooks() and not skip_existing())

    def __call__(self, tensordict=None, *args, **kwargs):
        if args or kwargs or type(tensordict) is not TensorDict or not self.lean_call_applies():
            return super().__call__(tensordict, *args, **kwargs)
        return self._lean_forward(tensordict)

    def _lean_forward(self, tensordict: TensorDict) -> TensorDict:
        source = tensordict
        for m in self._module_iter():
            if _plain_module(m):
                out = m.module(*(tensordict.get(key, None) for key in m.in_keys))
                if isinstance(out, torch.Tensor):
                    out = (out,)
                elif out is None:
                    out = ()
                if len(out) != len(m.out_keys):
                    raise RuntimeError(f"{type(m.module).__name__} returned {len(out)} tensors for out_keys {m.out_keys}")
                for key, value in zip(m.out_keys, out):
                    tensordict.set(key, value)
            elif type(m) is LeanSequential and m.lean_call_applies():
                tensordict = m._lean_forward(tensordict)
            else:
                tensordict = m(tensordict)
        if tensordict is not source and self.inplace is True:  # (TensorDictSequential: the outputs written into the input)
            source.update(tensordict, keys_to_update=self.out_keys)
            return source
        return tensordict
