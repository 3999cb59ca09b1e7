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
from tensordict import TensorDict, TensorDictBase, is_tensor_collection
from tensordict.utils import unravel_key
from torchrl.data import ConsumingSampler, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import PrioritizedSampler
from torchrl.data.replay_buffers.writers import RoundRobinWriter, TensorDictRoundRobinWriter
from torchrl.data.replay_buffers.storages import TensorStorage

from morl_trl._torchrl_compat import (collate_id, new_tensordict_unsafe, plain_round_robin, record_round_robin_write,
                                      storage_data, tensordict_entries, writer_cursor)

__all__ = ["LeanTensorDictReplayBuffer", "extend_selected"]

# the writers whose extend sets the batch's "index" as TensorDictReplayBuffer.extend does afterwards
# (and any sampler but a consuming one: TorchRL's _extend then is the writer's and the sampler's extend)
_ROUND_ROBIN = (RoundRobinWriter, TensorDictRoundRobinWriter)
# storages whose get(index) is the stored tensordict indexed (a memmap one's leaves are memory maps)
_PLAIN_STORAGES = (TensorStorage, LazyTensorStorage)


def tensordict_layout(td) -> dict | None:
    """``{name: None (a tensor) or the sub-tensordict's layout}`` of a plain nested :class:`TensorDict`
    (``None`` for anything else: lazy stacks, tensorclasses, non-tensor data)."""
    if type(td) is not TensorDict:
        return None
    out = {}
    for name, value in tensordict_entries(td).items():
        if isinstance(value, torch.Tensor) and not is_tensor_collection(value):
            out[name] = None
        else:
            sub = tensordict_layout(value)
            if sub is None:
                return None
            out[name] = sub
    return out


def layout_keys(layout: dict, prefix: tuple = ()):
    """The leaf keys of a :func:`tensordict_layout`, nested ones as tuples (``unravel_key``'s form)."""
    for name, sub in layout.items():
        if sub is None:
            yield prefix + (name,) if prefix else name
        else:
            yield from layout_keys(sub, prefix + (name,))


def gather_leaves(td, layout: dict, index: torch.Tensor, batch_size: torch.Size):
    """``td[index]`` of a plain nested tensordict: each leaf indexed, the tree rebuilt as is."""
    src = tensordict_entries(td)
    out = {name: src[name][index] if sub is None else gather_leaves(src[name], sub, index, batch_size)
           for name, sub in layout.items()}
    return new_tensordict_unsafe(out, batch_size=batch_size, device=td.device)


def leaf_pairs(td, layout: dict, batch, dims: int, *, target_dims: int = 1, skip_index: bool = True) -> list | None:
    """``[(td's leaf, batch's leaf)]`` for every leaf of ``td`` (but its root ``"index"`` with
    ``skip_index``); ``None`` when ``batch`` lacks one or holds one of another shape (after its first
    ``dims`` dims, against ``td``'s leaf after its first ``target_dims``)."""
    pairs = []

    def collect(dst, lay, src) -> bool:
        for name, sub in lay.items():
            if skip_index and name == "index" and dst is td:
                continue
            value = tensordict_entries(src).get(name) if type(src) is TensorDict else None
            if value is None:
                return False
            if sub is None:
                if type(value) is not torch.Tensor:  # (a plain tensor: anything else takes TorchRL's path)
                    return False
                target = tensordict_entries(dst)[name]
                if value.shape[dims:] != target.shape[target_dims:]:
                    return False
                pairs.append((target, value))
            elif not collect(tensordict_entries(dst)[name], sub, value):
                return False
        return True

    return pairs if collect(td, layout, batch) else None


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

    def _plain_extend(self, batch) -> bool:
        """Whether an ``extend`` of ``batch`` is the writer's and the sampler's ``extend`` alone (a batch
        without priorities, a round-robin writer, no consuming sampler, the short paths' conditions)."""
        return (isinstance(batch, TensorDictBase) and self.priority_key not in batch.keys()
                and type(self._writer) in _ROUND_ROBIN and not isinstance(self._sampler, ConsumingSampler)
                and self._lean())

    def _storage_layout(self) -> dict | None:
        """:func:`tensordict_layout` of the storage's tensordict (``None``: not a plain one), computed once per
        storage tensordict."""
        storage = self._storage
        td = storage_data(storage)
        cached = self.__dict__.get("_layout_cache")
        if cached is None or cached[0] is not td:
            cached = self._layout_cache = (td, tensordict_layout(td) if type(storage) in _PLAIN_STORAGES else None)
        return cached[1]

    def extend(self, tensordicts: TensorDictBase, *, update_priority: bool | None = None) -> torch.Tensor:
        if not self._plain_extend(tensordicts):
            return super().extend(tensordicts, update_priority=update_priority)
        if self._transform is not None:  # (TorchRL's empty transform's inv: a shallow copy gets the "index")
            tensordicts = tensordicts.copy()
        with self._replay_lock, self._write_lock:  # (TorchRL's _extend: no consuming sampler, a round-robin writer)
            index = self._writer.extend(tensordicts)  # (it sets the batch's "index", as _set_index_in_td would)
            self._sampler.extend(index)
        return index

    def extend_from(self, batch: TensorDictBase, keys) -> torch.Tensor:
        """``extend(batch.select(*keys, strict=False).reshape(-1))``: the same indices, storage write and
        sampler update, without building the selected, reshaped copy when the storage is an initialized
        plain tensordict holding exactly the ``keys`` that ``batch`` has (then each of its leaves is
        written from ``batch``'s, a slice where the write does not wrap) -- a one-env run stores a
        transition per frame."""
        layout = self._write_layout(batch, keys)
        storage, dims = self._storage, batch.batch_dims
        pairs = None if layout is None else leaf_pairs(storage_data(storage), layout, batch, dims)
        if pairs is None:
            return self.extend(batch.select(*keys, strict=False).reshape(-1))
        writer = self._writer
        n = batch.batch_size.numel()
        with self._replay_lock, self._write_lock:
            start = writer_cursor(writer)
            capacity = storage.max_size
            index = torch.arange(start, start + n, dtype=torch.long, device=batch.device or "cpu") % capacity
            where = slice(start, start + n) if start + n <= capacity else index
            for target, value in pairs:
                target[where] = value.reshape(-1, *value.shape[dims:])
            stored_index = tensordict_entries(storage_data(storage))["index"]
            stored_index[where] = index.to(stored_index.device)
            record_round_robin_write(writer, storage, index, n)  # (RoundRobinWriter.extend's and TensorStorage.set's rest)
            self._sampler.extend(index)
        return index

    def _write_layout(self, batch, keys) -> dict | None:
        """The storage's layout when :meth:`extend_from` may write ``batch`` leaf by leaf: a plain extend
        into a plain round-robin storage holding the replay ``keys`` (the ones ``batch`` has), else ``None``."""
        if type(batch) is not TensorDict or not self._plain_extend(batch):
            return None
        storage = self._storage
        if not plain_round_robin(self._writer, storage):
            return None
        layout = self._storage_layout()
        if layout is None or layout.get("index", 0) is not None:
            return None
        cached = self.__dict__.get("_absent_cache")
        if cached is None or cached[0] is not layout or cached[1] != keys:
            held = set(layout_keys(layout)) - {"index"}
            wanted = {unravel_key(k) for k in keys}
            # (None: the storage holds a leaf the keys lack; else the keys the batch must lack, as the first write did)
            cached = self._absent_cache = (layout, list(keys), [k for k in wanted if k not in held] if held <= wanted else None)
        absent = cached[2]
        if absent is None or any(batch.get(k, None) is not None for k in absent):
            return None
        return layout

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
            data = self._get(index)
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

    def _get(self, index: torch.Tensor) -> TensorDictBase:
        """``storage.get(index)``: of a plain nested tensordict, each leaf indexed and the tree rebuilt
        (the same values; TorchRL's tensordict indexing costs more than the gathers in a one-env run)."""
        layout = self._storage_layout()
        if layout is None or not isinstance(index, torch.Tensor) or index.ndim != 1 or index.dtype != torch.long:
            return self._storage.get(index)
        return gather_leaves(storage_data(self._storage), layout, index, torch.Size([index.shape[0]]))

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


def extend_selected(buffer, batch: TensorDictBase, keys) -> torch.Tensor:
    """``buffer.extend(batch.select(*keys, strict=False).reshape(-1))``: a
    :class:`LeanTensorDictReplayBuffer`'s :meth:`~LeanTensorDictReplayBuffer.extend_from` (no selected copy),
    any other buffer's ``extend`` of the selection (select first: fewer leaves to reshape)."""
    extend_from = getattr(buffer, "extend_from", None)
    if extend_from is not None:
        return extend_from(batch, keys)
    return buffer.extend(batch.select(*keys, strict=False).reshape(-1))
