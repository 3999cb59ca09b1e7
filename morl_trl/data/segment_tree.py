"""Vectorised sum and min segment trees in pure torch (any device).

They mirror the interface of TorchRL's C++ ``SumSegmentTreeFp32`` /
``MinSegmentTreeFp32`` (``tree[index]``, ``tree[index] = value``,
``query(l, r)``, ``scan_lower_bound(mass)``) so that TorchRL's
:class:`~torchrl.data.PrioritizedSampler` logic can run on them unchanged.
Updates and searches are batched: one call touches ``log2(capacity)`` levels
with a few tensor ops each, whatever the number of indices. On the CPU the same
level-by-level arithmetic runs on a NumPy view of the tree (a few microseconds
per level instead of a torch dispatch per op: a one-env run writes and samples
the trees every frame); the values are bit for bit those of the torch ops
(IEEE float32 / float64 addition and minimum in both).
"""

from __future__ import annotations

import math

import numpy as np
import torch

__all__ = ["MinSegmentTree", "SumSegmentTree", "assign_unchecked_all"]


class _SegmentTree:
    """A complete binary tree over ``capacity`` leaves stored in one ``[2 * size]`` tensor."""

    neutral: float

    def __init__(self, capacity: int, device: torch.device | str | None = None, dtype: torch.dtype = torch.float32) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}.")
        self.capacity = int(capacity)
        self._size = 1 << max(0, (self.capacity - 1).bit_length())
        self._levels = int(math.log2(self._size))
        self._tree = torch.full((2 * self._size,), self.neutral, dtype=dtype, device=device)
        # One past the largest leaf ever written: leaves beyond it hold the neutral
        # value, so a query over [0, r) with r >= _written is the root.
        self._written = 0

    @property
    def device(self) -> torch.device:
        return self._tree.device

    @property
    def dtype(self) -> torch.dtype:
        return self._tree.dtype

    def __len__(self) -> int:
        return self.capacity

    def size(self) -> int:
        return self.capacity

    def _combine(self, left: torch.Tensor, right: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    _combine_np: staticmethod

    @staticmethod
    def _combine_py(left: float, right: float) -> float:
        """``_combine_np`` of two Python floats (the same value once stored in the tree's dtype)."""
        raise NotImplementedError

    def _host_array(self) -> np.ndarray | None:
        """A NumPy view of the tree when it lives on the CPU and no graph is being traced (else ``None``)."""
        if self._tree.device.type != "cpu" or torch.compiler.is_compiling():
            return None
        return self._tree.numpy()

    def _written_subtree(self, written: int) -> tuple[int, int]:
        """``(m, node)``: the left-most subtree of ``2 ** m`` leaves that holds leaves ``[0, written)``, and its node.

        Every leaf at or past ``written`` holds the neutral value, so above ``node`` each
        ancestor's right child is neutral and its value is ``node``'s exactly (``x + 0.0`` and
        ``min(x, inf)`` are ``x``): a write recombines the ``m`` levels below ``node`` and copies
        its value up the chain, and a search starts at ``node`` (from the root it would turn left
        at every level above, its mass unchanged). A buffer holding few of its capacity's items
        (a one-env run's first frames of a million-item buffer) walks ``m`` levels, not
        ``log2(capacity)``."""
        m = min(max(0, (written - 1).bit_length()), self._levels)
        return m, 1 << (self._levels - m)

    def _write_host(self, tree: np.ndarray, index: np.ndarray, value: np.ndarray) -> None:
        """``tree[index] = value`` (unique indices) and the parents recombined level by level."""
        if index.size == 1:  # (one new transition per frame: Python floats, rounded where stored)
            # a float32 sum computed in float64 and rounded once is the float32 sum (53 >= 2 * 24 + 2 bits)
            combine, item = self._combine_py, tree.item
            leaf = int(index[0])
            m, top = self._written_subtree(max(self._written, leaf + 1))
            node = leaf + self._size
            tree[node] = value[0]
            for _ in range(m):
                node >>= 1
                tree[node] = combine(item(2 * node), item(2 * node + 1))
            self._copy_up(tree, top)
            return
        m, top = self._written_subtree(max(self._written, int(index.max()) + 1))
        node = index + self._size
        tree[node] = value
        if (1 << m) <= 4096 * m:
            # a subtree of up to 2 ** 16 leaves: every node of it recombined, one strided ufunc call per
            # level (32 indices: 22 us over 2,000 written leaves, 37 us over 30,000, against 57 and ~130 us
            # for the indices' ancestors level by level; even at 2 ** 17); a node is the same function
            # of its children either way, so the tree is the same bit for bit
            combine = self._combine_np
            for depth in range(m - 1, -1, -1):
                lo, hi = top << depth, (top + 1) << depth
                combine(tree[2 * lo:2 * hi:2], tree[2 * lo + 1:2 * hi:2], out=tree[lo:hi])
            self._copy_up(tree, top)
            return
        # a larger one: the indices' ancestors, level by level. Row p of the pairs view holds the children
        # (2p, 2p + 1) of node p: one gather and one two-element reduction (one addition / minimum) per level
        pairs, reduce = tree.reshape(-1, 2), self._combine_np.reduce
        for _ in range(m):
            node >>= 1  # repeated parents receive identical values: duplicates are harmless
            tree[node] = reduce(pairs[node], axis=1)
        self._copy_up(tree, top)

    def _copy_up(self, tree: np.ndarray, top: int) -> None:
        """The ancestors of the left-chain node ``top`` set to its value (see :meth:`_written_subtree`)."""
        if top > 1:
            chain = self.__dict__.get("_chains", {}).get(top)
            if chain is None:
                chain = self.__dict__.setdefault("_chains", {})[top] = top >> np.arange(1, top.bit_length())
            tree[chain] = tree[top]

    @staticmethod
    def _last_writes(index: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The unique indices with the value of each one's last occurrence (a sequential write)."""
        unique, last_reversed = np.unique(index[::-1], return_index=True)
        if unique.size == index.size:
            return index, value
        return unique, value[index.size - 1 - last_reversed]

    def _as_index(self, index) -> torch.Tensor:
        index = torch.as_tensor(index, dtype=torch.long, device=self.device).reshape(-1)
        if index.numel() and (int(index.min()) < 0 or int(index.max()) >= self.capacity):
            raise IndexError(
                f"segment tree index out of range [0, {self.capacity}): min {int(index.min())}, max {int(index.max())}."
            )
        return index

    def __getitem__(self, index) -> torch.Tensor:
        scalar = isinstance(index, int)
        values = self._tree[self._as_index(index) + self._size]
        return values[0] if scalar else values

    def _set_host(self, host: np.ndarray, index, value) -> None:
        """``tree[index] = value`` on a CPU tree, in NumPy from the start (no torch op per call)."""
        idx = (index.numpy() if isinstance(index, torch.Tensor) else np.asarray(index)).reshape(-1)
        if not idx.size:
            return
        if idx.dtype.kind not in "iu":
            idx = torch.as_tensor(idx, dtype=torch.long).numpy()  # (as _as_index converts)
        lo, hi = (int(idx[0]),) * 2 if idx.size == 1 else (int(idx.min()), int(idx.max()))
        if lo < 0 or hi >= self.capacity:
            raise IndexError(f"segment tree index out of range [0, {self.capacity}): min {lo}, max {hi}.")
        if isinstance(value, torch.Tensor):
            val = value.detach().to(self.dtype).numpy().reshape(-1)
        else:
            val = np.asarray(value, dtype=host.dtype).reshape(-1)
        if val.size != idx.size:
            val = np.broadcast_to(val, idx.shape)
        if idx.size > 1:
            idx, val = self._last_writes(idx, val)
        self._write_host(host, idx, val)
        self._written = max(self._written, hi + 1)

    def __setitem__(self, index, value) -> None:
        host = self._host_array()
        if host is not None:
            self._set_host(host, index, value)
            return
        index = self._as_index(index)
        if index.numel() == 0:
            return
        value = torch.as_tensor(value, dtype=self.dtype, device=self.device).reshape(-1).expand(index.shape)
        if index.numel() > 1:
            # Keep the last write of a repeated index (what a sequential update does).
            unique, inverse = torch.unique(index, return_inverse=True)
            if unique.numel() != index.numel():
                position = torch.arange(index.numel(), device=self.device)
                last = torch.full_like(unique, -1).scatter_reduce(0, inverse, position, reduce="amax")
                index, value = unique, value[last]
        node = index + self._size
        self._tree[node] = value
        self._written = max(self._written, int(index.max()) + 1)
        for _ in range(self._levels):
            # Repeated parents receive identical values, so duplicates are harmless.
            node = node // 2
            self._tree[node] = self._combine(self._tree[2 * node], self._tree[2 * node + 1])

    def assign_unchecked(self, index: torch.Tensor, value: torch.Tensor) -> None:
        """``tree[index] = value`` with no host read (capturable in a CUDA graph, no synchronisation).

        ``index`` (``[n]`` long, on the tree's device) must hold leaves in range that were
        written before (e.g. indices this tree's sampler drew); nothing checks it. A repeated
        index keeps its last write, as ``tree[index] = value`` does: every occurrence writes the
        last one's value (an ``[n, n]`` comparison instead of ``torch.unique``, whose output size
        the host would have to read). Parents are recombined level by level, as there.
        """
        host = self._host_array()
        if host is not None:
            idx, val = self._last_writes(index.numpy().reshape(-1), value.detach().reshape(-1).to(self.dtype).numpy())
            self._write_host(host, idx, val)
            return
        position = torch.arange(index.numel(), device=index.device)
        last = torch.where(index.unsqueeze(0) == index.unsqueeze(1), position, -1).amax(1)
        value = value.reshape(-1).to(self.dtype)[last]
        node = index + self._size
        self._tree[node] = value
        for _ in range(self._levels):
            node = node // 2
            self._tree[node] = self._combine(self._tree[2 * node], self._tree[2 * node + 1])

    def leaf_values_unchecked(self, index: torch.Tensor) -> torch.Tensor:
        """``tree[index]`` with no range check (no host read)."""
        return self._tree[index + self._size]

    def query(self, start=0, end=None) -> torch.Tensor:
        """Reduction over the leaves ``[start, end)`` (a 0-d tensor)."""
        start = int(start)
        end = self.capacity if end is None else int(end)
        if start == 0 and end >= self._written:
            return self._tree[1]
        acc = torch.tensor(self.neutral, dtype=self.dtype, device=self.device)
        lo, hi = start + self._size, end + self._size
        while lo < hi:
            if lo & 1:
                acc = self._combine(acc, self._tree[lo])
                lo += 1
            if hi & 1:
                hi -= 1
                acc = self._combine(acc, self._tree[hi])
            lo //= 2
            hi //= 2
        return acc

    def state_dict(self) -> dict:
        return {"capacity": self.capacity, "tree": self._tree.clone(), "written": self._written}

    def load_state_dict(self, state: dict) -> None:
        if state["capacity"] != self.capacity:
            raise ValueError(f"capacity mismatch: saved {state['capacity']}, this tree {self.capacity}.")
        self._tree.copy_(state["tree"])
        self._written = int(state["written"])

    def leaves(self) -> torch.Tensor:
        """A view of the ``capacity`` leaf values."""
        return self._tree[self._size : self._size + self.capacity]

    def set_leaves(self, values: torch.Tensor) -> None:
        """Overwrites every leaf and rebuilds the tree bottom-up (one op per level)."""
        values = torch.as_tensor(values, dtype=self.dtype, device=self.device).reshape(-1)
        if values.numel() != self.capacity:
            raise ValueError(f"expected {self.capacity} leaf values, got {values.numel()}.")
        self._tree.fill_(self.neutral)
        self._tree[self._size : self._size + self.capacity] = values
        written = (values != self.neutral).nonzero()
        self._written = int(written.max()) + 1 if written.numel() else 0
        for level in range(self._levels - 1, -1, -1):
            lo, hi = 1 << level, 1 << (level + 1)
            self._tree[lo:hi] = self._combine(self._tree[2 * lo : 2 * hi : 2], self._tree[2 * lo + 1 : 2 * hi : 2])

    def __repr__(self) -> str:
        return f"{type(self).__name__}(capacity={self.capacity}, device={self.device}, dtype={self.dtype})"


class SumSegmentTree(_SegmentTree):
    """Sum tree: ``query`` sums and ``scan_lower_bound`` inverts the cumulative sum.

    Examples:
        >>> tree = SumSegmentTree(5)
        >>> tree[torch.arange(5)] = torch.tensor([1.0, 0.0, 2.0, 0.0, 1.0])
        >>> float(tree.query(0, 5)), float(tree.query(1, 3))
        (4.0, 2.0)
        >>> tree.scan_lower_bound(torch.tensor([0.5, 1.0, 2.9, 3.5]))
        tensor([0, 2, 2, 4])
    """

    neutral = 0.0
    _combine_np = staticmethod(np.add)

    @staticmethod
    def _combine_py(left: float, right: float) -> float:
        return left + right

    def _combine(self, left, right):
        return left + right

    def scan_lower_bound(self, mass) -> torch.Tensor:
        """For each ``mass`` in ``[0, total)``, the leaf whose cumulative-sum interval holds it.

        Leaves with zero value are never returned while the total is positive.
        """
        host = self._host_array()
        if host is not None:
            mass_np = torch.as_tensor(mass, dtype=self.dtype).reshape(-1).numpy().copy()
            m, top = self._written_subtree(self._written)  # (from the root: left, mass unchanged, down to top)
            node_np = np.full(mass_np.shape, top, dtype=np.int64)
            pairs = host.reshape(-1, 2)  # row p: the children (2p, 2p + 1) of node p
            for _ in range(m):
                children = pairs[node_np]
                left_sum = children[:, 0]
                go_right = (mass_np >= left_sum) & (children[:, 1] > 0)
                np.subtract(mass_np, left_sum, out=mass_np, where=go_right)
                node_np <<= 1
                node_np += go_right
            return torch.from_numpy(node_np - self._size)
        mass = torch.as_tensor(mass, dtype=self.dtype, device=self.device).reshape(-1).clone()
        node = torch.ones(mass.shape, dtype=torch.long, device=self.device)
        for _ in range(self._levels):
            left = 2 * node
            left_sum = self._tree[left]
            go_right = (mass >= left_sum) & (self._tree[left + 1] > 0)
            mass = torch.where(go_right, mass - left_sum, mass)
            node = torch.where(go_right, left + 1, left)
        return node - self._size


class MinSegmentTree(_SegmentTree):
    """Min tree (``query`` is the minimum; unwritten leaves are ``+inf``).

    Examples:
        >>> tree = MinSegmentTree(4)
        >>> tree[torch.tensor([0, 1, 2])] = torch.tensor([3.0, 1.0, 2.0])
        >>> float(tree.query(0, 3)), float(tree.query(2, 3))
        (1.0, 2.0)
    """

    neutral = math.inf
    _combine_np = staticmethod(np.minimum)

    @staticmethod
    def _combine_py(left: float, right: float) -> float:
        return left if left < right or left != left else right  # np.minimum's choice, NaN and signed zeros included

    def _combine(self, left, right):
        return torch.minimum(left, right)


def assign_unchecked_all(trees, index: torch.Tensor, value: torch.Tensor) -> None:
    """``tree.assign_unchecked(index, value)`` for each of ``trees`` (a prioritized sampler's sum and min
    trees take the same writes); on CPU trees of one dtype the repeated indices are resolved once for all."""
    hosts = [tree._host_array() for tree in trees]
    if any(host is None for host in hosts) or len({tree.dtype for tree in trees}) != 1:
        for tree in trees:
            tree.assign_unchecked(index, value)
        return
    idx, val = _SegmentTree._last_writes(index.numpy().reshape(-1), value.detach().reshape(-1).to(trees[0].dtype).numpy())
    for tree, host in zip(trees, hosts):
        tree._write_host(host, idx, val)
