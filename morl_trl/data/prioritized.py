"""Prioritized experience replay without TorchRL's C++ extension.

TorchRL's :class:`~torchrl.data.PrioritizedSampler` stores priorities in C++
segment trees; where the extension does not load (``SumSegmentTreeFp32 is not
available``) the sampler cannot be built. :class:`TorchPrioritizedSampler` is
the same sampler on the pure-torch trees of :mod:`morl_trl.data.segment_tree`:
it subclasses TorchRL's class, so replay buffers treat it as prioritized
(``update_tensordict_priority``, ``mark_update`` on writes, ``"priority_weight"``
in samples), and it runs on any device. :func:`prioritized_sampler` returns the
native sampler when it loads and this one otherwise.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch
from torchrl.data.replay_buffers.samplers import prioritized as _native
from torchrl.data.replay_buffers.samplers.prioritized import PrioritizedSampler
from torchrl.data.replay_buffers.storages import Storage
from torchrl.data.replay_buffers.utils import unravel_index

from morl_trl._torchrl_compat import sampler_generator
from morl_trl.data.segment_tree import MinSegmentTree, SumSegmentTree, assign_unchecked_all

__all__ = ["TorchPrioritizedSampler", "RunningMaxPrioritizedSampler", "native_prioritized_sampler_available", "normalize_device", "prioritized_sampler"]

_EMPTY_STORAGE_ERROR = "Cannot sample from an empty storage."
_NON_POSITIVE = (
    "non-positive priorities: sum {sum}, min {min} over {n} stored items (were priorities set for the stored items?)."
)


def normalize_device(device: torch.device | str | None) -> torch.device | None:
    """``device`` in the form tensors report: ``"cpu:0"`` -> ``cpu``, ``"cuda"`` -> ``cuda:<current index>``.

    ``torch.device("cuda") != torch.device("cuda:0")`` and ``torch.device("cpu:0") !=
    torch.device("cpu")``, while a tensor created on either reports the second: compare
    devices only after this.

    Example:
        >>> normalize_device("cpu:0")
        device(type='cpu')
    """
    if device is None:
        return None
    device = torch.device(device)
    if device.type == "cpu":
        return torch.device("cpu")
    if device.index is None and device.type == "cuda":
        return torch.device("cuda", torch.cuda.current_device())
    return device


def native_prioritized_sampler_available(device: torch.device | str | None = None) -> bool:
    """Whether TorchRL's C++ segment trees (for ``device``) are importable."""
    cpu = _native.SumSegmentTreeFp32 is not None and _native.MinSegmentTreeFp32 is not None
    if device is not None and torch.device(device).type == "cuda":
        return cpu and _native.CudaSumSegmentTreeFp32 is not None
    return cpu


class TorchPrioritizedSampler(PrioritizedSampler):
    r"""Proportional prioritized sampler (Schaul et al., 2016) on pure-torch segment trees.

    Same arguments and behaviour as :class:`torchrl.data.PrioritizedSampler`:
    an item with priority :math:`p_i` is drawn with probability
    :math:`(p_i + \epsilon)^\alpha / \sum_j (p_j + \epsilon)^\alpha` and carries
    the importance weight :math:`(P_i / \min_j P_j)^{-\beta}` under
    ``"priority_weight"``; new items get the largest priority seen so far.
    Sampling uses the torch RNG (the buffer's generator if it has one), so
    ``torch.manual_seed`` makes it reproducible.

    Args:
        max_capacity (int): capacity of the buffer.
        alpha (float): priority exponent (0: uniform).
        beta (float): importance-sampling exponent.
        eps (float): added to priorities. Defaults to 1e-8.
        dtype (torch.dtype): tree dtype. Defaults to ``torch.float32``.
        reduction (str): how a multi-element priority entry is reduced by the
            buffer (``"max"``, ``"min"``, ``"mean"``, ``"median"``). Defaults to ``"max"``.
        max_priority_within_buffer (bool): track the largest priority among the
            stored items rather than since construction. Defaults to ``False``.
        device (torch.device, optional): device of the trees; by default a CUDA
            storage moves them to its device.

    Examples:
        >>> from tensordict import TensorDict
        >>> from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
        >>> rb = TensorDictReplayBuffer(
        ...     storage=LazyTensorStorage(100),
        ...     sampler=TorchPrioritizedSampler(100, alpha=1.0, beta=0.4),
        ...     batch_size=8,
        ... )
        >>> _ = rb.extend(TensorDict({"obs": torch.arange(10.0)}, [10]))
        >>> sample = rb.sample()
        >>> sample["td_error"] = torch.rand(8)
        >>> rb.update_tensordict_priority(sample)
        >>> sorted(sample.keys())
        ['index', 'obs', 'priority_weight', 'td_error']
    """

    def __init__(
        self,
        max_capacity: int,
        alpha: float,
        beta: float,
        eps: float = 1e-8,
        dtype: torch.dtype = torch.float,
        reduction: str = "max",
        max_priority_within_buffer: bool = False,
        device: torch.device | str | None = None,
    ) -> None:
        # TorchRL's __init__ builds C++ trees (and warns without them): set its state here instead.
        if alpha < 0:
            raise ValueError(f"alpha must be greater or equal than 0, got alpha={alpha}")
        if beta < 0:
            raise ValueError(f"beta must be greater or equal to 0, got beta={beta}")
        if int(max_capacity) < 1:
            raise ValueError(f"max_capacity must be >= 1, got {max_capacity}.")
        if dtype not in (torch.float32, torch.float64):
            raise ValueError(f"dtype must be torch.float32 or torch.float64, got {dtype}.")
        self._max_capacity = int(max_capacity)
        self._alpha = alpha
        self._beta = beta
        self._eps = eps
        self.reduction = reduction
        self.dtype = dtype
        self._max_priority_within_buffer = max_priority_within_buffer
        self._device = normalize_device(device)
        self._init()

    def _init(self) -> None:
        device = self._device if self._device is not None else torch.device("cpu")
        self._sum_tree = SumSegmentTree(self._max_capacity, device=device, dtype=self.dtype)
        self._min_tree = MinSegmentTree(self._max_capacity, device=device, dtype=self.dtype)
        self._max_priority = None

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(max_capacity={self._max_capacity}, alpha={self._alpha}, "
            f"beta={self._beta}, eps={self._eps}, reduction={self.reduction}, device={self.device})"
        )

    def _tree_device_from_storage(self, storage: Storage | None) -> torch.device | None:
        # Follow a CUDA storage only until priorities exist: moving later would drop them.
        if self._device is not None or self._sum_tree._written:
            return self._device
        return normalize_device(super()._tree_device_from_storage(storage))

    def _maybe_init_from_storage(self, storage: Storage | None) -> None:
        # TorchRL compares the devices as given ("cuda" != "cuda:0"), which rebuilt empty
        # trees on every call; compare normalized ones.
        device = self._tree_device_from_storage(storage)
        if device is not None and normalize_device(device) != normalize_device(self.device):
            self._device = normalize_device(device)
            self._init()

    def sample(self, storage: Storage, batch_size: int) -> tuple[torch.Tensor, dict]:
        self._maybe_init_from_storage(storage)
        n = len(storage)
        if n == 0:
            raise RuntimeError(_EMPTY_STORAGE_ERROR)
        p_sum = self._sum_tree.query(0, n)
        p_min = self._min_tree.query(0, n)
        if self.device.type == "cpu":
            if p_sum <= 0 or not torch.isfinite(p_min) or p_min <= 0:
                raise RuntimeError(_NON_POSITIVE.format(sum=float(p_sum), min=float(p_min), n=n))
        else:  # the same guard without a host synchronisation: a device-side assert
            torch._assert_async((p_sum > 0) & torch.isfinite(p_min) & (p_min > 0),
                                _NON_POSITIVE.format(sum="?", min="?", n=n))
        rng = sampler_generator(self)
        u = torch.rand(batch_size, generator=rng, device=rng.device if rng is not None else self.device)
        mass = u.to(device=self.device, dtype=self.dtype) * p_sum
        index = self._sum_tree.scan_lower_bound(mass).clamp_max_(n - 1)
        weight = torch.pow(self._sum_tree[index] / p_min, -self._beta)
        if storage.ndim > 1:
            index = unravel_index(index, storage.shape)
        return index, {"priority_weight": weight}

    # ----------------------------------------------- sync-free path (whole update in one graph)
    def supports_unchecked(self, storage: Storage) -> bool:
        """Whether :meth:`sample_unchecked` / :meth:`update_priority_unchecked` may stand in for
        ``sample`` / ``update_priority`` on ``storage``: a 1-d storage with items, the trees on
        their device, the largest priority tracked since construction (TorchRL's default)."""
        return (storage.ndim == 1 and len(storage) > 0 and not self._max_priority_within_buffer
                and self._sum_tree._written >= len(storage) and self._max_priority is not None
                and self._tree_device_from_storage(storage) in (None, self.device))

    def sample_unchecked(self, batch_size: int) -> tuple[torch.Tensor, torch.Tensor]:
        """``sample``'s ``(index, priority_weight)`` without reading the host: the same random
        draws and arithmetic (hence the same indices), minus the checks that read device values
        (positive total, indices in range: the descent never enters a zero-sum subtree, so every
        index lands on a written leaf) -- capturable in a CUDA graph."""
        rng = sampler_generator(self)
        u = torch.rand(batch_size, generator=rng, device=rng.device if rng is not None else self.device)
        return self.descend_unchecked(u)

    def descend_unchecked(self, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """:meth:`sample_unchecked` from its uniform draws ``u``: the tree walk and the weights
        (tensor operations only: what ``torch.compile`` fuses, the draws staying eager's)."""
        p_sum, p_min = self._sum_tree._tree[1], self._min_tree._tree[1]
        index = self._sum_tree.scan_lower_bound(u.to(device=self.device, dtype=self.dtype) * p_sum)
        weight = torch.pow(self._sum_tree.leaf_values_unchecked(index) / p_min, -self._beta)
        return index, weight

    def update_priority_unchecked(self, index: torch.Tensor, priority: torch.Tensor) -> None:
        """``update_priority(index, priority)`` for ``[n]`` indices this sampler drew, without
        reading the host: the running largest priority is kept in one device tensor (updated in
        place), the trees written with :meth:`~morl_trl.data.segment_tree.SumSegmentTree.assign_unchecked`."""
        self.write_priorities_unchecked(index, priority, self._pinned_max_priority())

    def write_priorities_unchecked(self, index: torch.Tensor, priority: torch.Tensor, top: torch.Tensor) -> None:
        """:meth:`update_priority_unchecked`'s tensor work, ``top`` the pinned largest priority
        (tensor operations only: what ``torch.compile`` fuses)."""
        priority = priority.detach().reshape(-1)
        top.copy_(torch.maximum(priority.max().to(top.dtype), top))
        value = torch.pow(priority + self._eps, self._alpha)
        assign_unchecked_all((self._sum_tree, self._min_tree), index, value)

    def _pinned_max_priority(self) -> torch.Tensor:
        """The largest priority as one persistent 0-d tensor on the trees' device (what a
        captured graph reads and writes), rebound into ``_max_priority`` after TorchRL's
        ``update_priority`` replaced it."""
        current = self._max_priority[0] if self._max_priority is not None else None
        pinned = getattr(self, "_max_priority_pinned", None)
        if pinned is None or pinned.device != self.device:
            pinned = self._max_priority_pinned = torch.ones((), dtype=torch.float32, device=self.device)
        if current is not None and current is not pinned:
            pinned.copy_(torch.as_tensor(current, dtype=pinned.dtype).to(self.device))
        self._max_priority = (pinned, None if self._max_priority is None else self._max_priority[1])
        return pinned

    def update_priority(self, index, priority, *, storage=None) -> None:
        super().update_priority(index, priority, storage=storage)
        if self._max_priority is not None and getattr(self, "_max_priority_pinned", None) is not None:
            self._pinned_max_priority()  # TorchRL rebinds the tuple: copy into the captured tensor

    def _tree_argmax(self) -> tuple[torch.Tensor, torch.Tensor]:
        return self._sum_tree.leaves().max(0)

    def _retransform_priority_trees(self, old_alpha: float, new_alpha: float) -> None:
        values = self._sum_tree.leaves()
        written = values > 0
        if not written.any():
            return
        if old_alpha == 0:
            return super()._retransform_priority_trees(old_alpha, new_alpha)
        raw = (values.double() ** (1.0 / old_alpha) - self._eps).clamp_min(0)
        new_values = torch.where(written, (raw + self._eps) ** new_alpha, 0.0).to(self.dtype)
        self._sum_tree.set_leaves(new_values)
        self._min_tree.set_leaves(torch.where(written, new_values, torch.inf))

    def state_dict(self) -> dict[str, Any]:
        return {
            "_schema_version": self._STATE_SCHEMA_VERSION,
            "_alpha": self._alpha,
            "_beta": self._beta,
            "_eps": self._eps,
            "_max_priority": _clone_max_priority(self._max_priority),
            "_sum_tree": self._sum_tree.state_dict(),
            "_min_tree": self._min_tree.state_dict(),
        }

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        self._alpha = state_dict["_alpha"]
        self._beta = state_dict["_beta"]
        self._eps = state_dict["_eps"]
        self._max_priority = _clone_max_priority(state_dict["_max_priority"])
        self._sum_tree.load_state_dict(state_dict["_sum_tree"])
        self._min_tree.load_state_dict(state_dict["_min_tree"])
        if self._max_priority is not None and getattr(self, "_max_priority_pinned", None) is not None:
            self._pinned_max_priority()

    def dumps(self, path) -> None:
        path = Path(path).absolute()
        path.mkdir(parents=True, exist_ok=True)
        torch.save({"sum": self._sum_tree.state_dict(), "min": self._min_tree.state_dict()}, path / "trees.pt")
        max_p, max_i = self._max_priority
        metadata = {
            "_schema_version": self._STATE_SCHEMA_VERSION,
            "_alpha": self._alpha,
            "_beta": self._beta,
            "_eps": self._eps,
            "_max_capacity": self._max_capacity,
            "_max_priority": [None if max_p is None else float(max_p), None if max_i is None else _to_py(max_i)],
        }
        with open(path / "sampler_metadata.json", "w") as file:
            json.dump(metadata, file)

    def loads(self, path) -> None:
        path = Path(path).absolute()
        with open(path / "sampler_metadata.json") as file:
            metadata = json.load(file)
        if metadata["_max_capacity"] != self._max_capacity:
            raise RuntimeError(
                f"max capacity of loaded metadata ({metadata['_max_capacity']}) differs from "
                f"self._max_capacity ({self._max_capacity})."
            )
        self._alpha = metadata["_alpha"]
        self._beta = metadata["_beta"]
        self._eps = metadata["_eps"]
        max_p, max_i = metadata["_max_priority"]
        self._max_priority = None if max_p is None else (torch.tensor(max_p), None if max_i is None else torch.tensor(max_i))
        trees = torch.load(path / "trees.pt", map_location=self.device, weights_only=True)
        self._sum_tree.load_state_dict(trees["sum"])
        self._min_tree.load_state_dict(trees["min"])


class RunningMaxPrioritizedSampler(TorchPrioritizedSampler):
    r"""MORL-Baselines' prioritized buffer rule, as the authors' Envelope ran it.

    An update with priorities :math:`p` (Envelope: :math:`|w \cdot \delta|` under the first sampled
    weight) writes :math:`(p + M)^\alpha`, where :math:`M` is the running maximum of the written
    values (``min_priority`` = 1e-5 at first), and then raises :math:`M` to the largest value
    written; new items are written at :math:`M` (no :math:`\alpha`). (MORL-Baselines' buffer calls
    it ``min_priority``; ``envelope.py:344-349``, ``prioritized_buffer.py:93,141,188-196``.) So
    every priority carries the largest one seen, which flattens them as the run goes, and items
    stored before the first update keep 1e-5. :class:`TorchPrioritizedSampler` is TorchRL's rule:
    :math:`(p + \epsilon)^\alpha`, new items at the largest raw priority.

    Example:
        >>> from tensordict import TensorDict
        >>> from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
        >>> sampler = RunningMaxPrioritizedSampler(10, alpha=0.5, beta=0.4)
        >>> rb = TensorDictReplayBuffer(storage=LazyTensorStorage(10), sampler=sampler, batch_size=2)
        >>> _ = rb.extend(TensorDict({"obs": torch.arange(3.0)}, [3]))
        >>> rb.update_priority(torch.tensor([0, 1]), torch.tensor([0.04, 0.25]))
        >>> _ = rb.extend(TensorDict({"obs": torch.arange(1.0)}, [1]))
        >>> [round(v, 4) for v in sampler._sum_tree.leaves()[:4].tolist()]
        [0.2, 0.5, 0.0, 0.5]
    """

    def __init__(self, max_capacity: int, alpha: float, beta: float, *, min_priority: float = 1e-5,
                 **kwargs) -> None:
        if not min_priority > 0:
            raise ValueError(f"min_priority must be > 0, got {min_priority}")
        self.min_priority = float(min_priority)
        super().__init__(max_capacity, alpha, beta, **kwargs)
        if self._max_priority_within_buffer:
            raise ValueError("RunningMaxPrioritizedSampler keeps the maximum since construction "
                             "(max_priority_within_buffer=False)")

    def _init(self) -> None:
        super()._init()
        self._max_priority = (torch.tensor(self.min_priority, device=self.device), None)

    def _index(self, index, storage) -> torch.Tensor:
        index = torch.as_tensor(index, dtype=torch.long, device=self.device)
        if index.ndim > 1:
            raise ValueError(f"{type(self).__name__} takes a 1-d storage, got index of shape {tuple(index.shape)}")
        index = index.reshape(-1)
        if index.device.type == "cpu" and (index.numel() == 0 or int(index.min()) >= 0):
            return index  # (nothing to drop: one reduction instead of a masked copy)
        return index[index >= 0]  # (TorchRL's MaxValueWriter marks items it keeps with -1)

    @torch.no_grad()
    def mark_update(self, index, *, storage=None) -> None:
        """New items: written at the running maximum :math:`M`."""
        self._maybe_init_from_storage(storage)
        index = self._index(index, storage)
        top = self._pinned_max_priority()
        self._sum_tree[index] = top
        self._min_tree[index] = top

    @torch.no_grad()
    def update_priority(self, index, priority, *, storage=None) -> None:
        """``(priority + M) ** alpha`` at ``index``, then ``M = max(M, written)``."""
        self._maybe_init_from_storage(storage)
        index = self._index(index, storage)
        if index.numel():
            priority = torch.as_tensor(priority, device=self.device).detach().reshape(-1)
            self.write_priorities_unchecked(index, priority.expand(index.shape), self._pinned_max_priority())

    def write_priorities_unchecked(self, index: torch.Tensor, priority: torch.Tensor, top: torch.Tensor) -> None:
        value = torch.pow(priority.detach().reshape(-1).to(top.dtype) + top, self._alpha)
        assign_unchecked_all((self._sum_tree, self._min_tree), index, value)
        top.copy_(torch.maximum(value.max(), top))

    def _retransform_priority_trees(self, old_alpha: float, new_alpha: float) -> None:
        raise NotImplementedError(f"{type(self).__name__} cannot change alpha after priorities are written")


def _to_py(x):
    return x.tolist() if isinstance(x, torch.Tensor) else x


def _clone_max_priority(value):
    if value is None:
        return None
    return tuple(v.clone() if isinstance(v, torch.Tensor) else v for v in value)


def prioritized_sampler(
    max_capacity: int,
    alpha: float,
    beta: float,
    *,
    backend: str = "auto",
    **kwargs,
) -> PrioritizedSampler:
    """A prioritized sampler: TorchRL's native one when its extension loads, else :class:`TorchPrioritizedSampler`.

    Args:
        max_capacity, alpha, beta: as :class:`torchrl.data.PrioritizedSampler`.
        backend: ``"auto"`` (default), ``"native"`` (TorchRL's, raising if it cannot
            load) or ``"torch"`` (always the pure-torch sampler).
        **kwargs: ``eps``, ``dtype``, ``reduction``, ``max_priority_within_buffer``, ``device``.

    Examples:
        >>> sampler = prioritized_sampler(1000, alpha=0.6, beta=0.4)
        >>> isinstance(sampler, PrioritizedSampler)
        True
    """
    if backend not in ("auto", "native", "torch"):
        raise ValueError(f"backend={backend!r}; valid values are 'auto', 'native', 'torch'.")
    if backend == "native" or (backend == "auto" and native_prioritized_sampler_available(kwargs.get("device"))):
        return PrioritizedSampler(max_capacity, alpha, beta, **kwargs)
    return TorchPrioritizedSampler(max_capacity, alpha, beta, **kwargs)
