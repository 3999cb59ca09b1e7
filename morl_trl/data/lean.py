"""A TorchRL replay buffer whose per-update calls take a short path in the common case.

:class:`LeanTensorDictReplayBuffer` is :class:`torchrl.data.TensorDictReplayBuffer` (same
constructor, storage, sampler, writer, state, checkpoints) whose :meth:`sample` and
:meth:`update_tensordict_priority` call the sampler and the storage directly when nothing of
TorchRL's generality is in use (no transform, sample unit, prefetching, pinned memory or
generation tracking; a 1-d storage): the same sampler call (hence the same random draws and
indices), the same ``storage.get``, the same ``"priority_weight"`` / ``"index"`` entries, the
same ``sampler.update_priority`` -- without TorchRL's wrappers around them (the delayed-init
and pin-memory decorators, the ``return_info`` round trip through ``tree_map``, the entry-by-entry
metadata copy, the priority vector's reshape and reduction over one column): about a fifth of a
one-transition-per-frame run's sampling (``benchmarks/torchrl_overheads.py``). Its :meth:`extend`
of a batch without priorities likewise calls the writer's ``extend`` and the sampler's ``extend``
(the same indices, the same storage write and the same ``"index"`` entry in the batch) without the
wrappers, the consuming-sampler and priority checks around them. Any other case is TorchRL's own
method.

Example:
    >>> from tensordict import TensorDict
    >>> from torchrl.data import LazyTensorStorage
    >>> from morl_trl.data import TorchPrioritizedSampler
    >>> rb = LeanTensorDictReplayBuffer(storage=LazyTensorStorage(100), batch_size=4,
    ...                                 sampler=TorchPrioritizedSampler(100, alpha=0.6, beta=0.4))
    >>> _ = rb.extend(TensorDict({"obs": torch.arange(10.0)}, [10]))
    >>> sample = rb.sample()
    >>> sorted(sample.keys())
    ['index', 'obs', 'priority_weight']
    >>> sample["td_error"] = torch.rand(4)
    >>> rb.update_tensordict_priority(sample)
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.data import ConsumingSampler, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import PrioritizedSampler
from torchrl.data.replay_buffers.writers import RoundRobinWriter, TensorDictRoundRobinWriter
from torchrl.data.replay_buffers.storages import TensorStorage

from morl_trl._torchrl_compat import collate_id

__all__ = ["LeanTensorDictReplayBuffer"]

# the writers whose extend sets the batch's "index" as TensorDictReplayBuffer.extend does afterwards
# (and any sampler but a consuming one: TorchRL's _extend then is the writer's and the sampler's extend)
_ROUND_ROBIN = (RoundRobinWriter, TensorDictRoundRobinWriter)


class LeanTensorDictReplayBuffer(TensorDictReplayBuffer):
    """:class:`~torchrl.data.TensorDictReplayBuffer` with short ``sample`` / ``update_tensordict_priority``
    paths (see the module docstring); every argument is TorchRL's."""

    def _lean(self) -> bool:
        """Whether the short paths compute exactly what TorchRL's methods would."""
        if self._delayed_init and not self.initialized:
            self._init()
        transform = self._transform
        storage = self._storage
        return (not self._prefetch and (transform is None or not len(transform)) and self._sample_unit is None
                and not self._pin_memory and self._sample_dependency is None and not self._service_shutdown
                and not self._writer.tracks_generations and isinstance(storage, TensorStorage)
                and storage.initialized and storage.ndim == 1 and self.dim_extend == 0
                and self._collate_fn is collate_id)

    def extend(self, tensordicts: TensorDictBase, *, update_priority: bool | None = None) -> torch.Tensor:
        if (not isinstance(tensordicts, TensorDictBase) or self.priority_key in tensordicts.keys()
                or type(self._writer) not in _ROUND_ROBIN or isinstance(self._sampler, ConsumingSampler)
                or not self._lean()):
            return super().extend(tensordicts, update_priority=update_priority)
        if self._transform is not None:  # (TorchRL's empty transform's inv: a shallow copy gets the "index")
            tensordicts = tensordicts.copy()
        with self._replay_lock, self._write_lock:  # (TorchRL's _extend: no consuming sampler, a round-robin writer)
            index = self._writer.extend(tensordicts)  # (it sets the batch's "index", as _set_index_in_td would)
            self._sampler.extend(index)
        return index

    def sample(self, batch_size: int | None = None, return_info: bool = False,
               include_info: bool | None = None) -> TensorDictBase:
        if return_info or include_info is not None or not self._lean():
            return super().sample(batch_size, return_info=return_info, include_info=include_info)
        if batch_size is None:
            batch_size = self._batch_size
        elif self._batch_size is not None and batch_size != self._batch_size:
            return super().sample(batch_size)  # (TorchRL warns once about the conflict)
        if batch_size is None:
            return super().sample(batch_size)  # (TorchRL's error)
        with self._replay_lock, self._write_lock:
            index, info = self._sampler.sample(self._storage, batch_size)
            data = self._storage.get(index)
        info["index"] = index
        device = data.device
        for key, val in info.items():  # (as TensorDictReplayBuffer.sample: the sampler's entries, then "index")
            if isinstance(val, torch.Tensor):
                if device is not None and val.device != device:
                    val = val.to(device)
                if val.ndim < data.ndim:
                    val = val.reshape(*val.shape, *(1,) * (data.ndim - val.ndim)).expand(data.shape)
            else:
                val = torch.as_tensor(val, device=device)
            data.set(key, val)
        return data

    def update_tensordict_priority(self, data: TensorDictBase) -> None:
        if not isinstance(self._sampler, PrioritizedSampler):
            return
        if data.ndim == 1 and self._lean():
            priority = data.get(self.priority_key, None)
            index = data.get("index", None)
            if (isinstance(priority, torch.Tensor) and isinstance(index, torch.Tensor) and priority.ndim == 1
                    and index.shape == priority.shape and not priority.requires_grad):
                with self._replay_lock, self._write_lock:
                    self._sampler.update_priority(index, priority, storage=self._storage)
                return
        return super().update_tensordict_priority(data)

