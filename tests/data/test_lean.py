"""The short paths of :class:`~morl_trl.data.lean.LeanTensorDictReplayBuffer` and of the CPU segment
trees (a search and a write over the written leaves' subtree only) compute exactly what TorchRL's
buffer and the full-depth tree walk do."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

from morl_trl.data import MinSegmentTree, RunningMaxPrioritizedSampler, SumSegmentTree, TorchPrioritizedSampler
from morl_trl.data.lean import LeanTensorDictReplayBuffer, leaf_pairs


def _transition(g: torch.Generator, n: int = 1) -> TensorDict:
    return TensorDict({"observation": torch.randn(n, 2, generator=g), "action": torch.randint(4, (n,), generator=g),
                       "next": TensorDict({"reward": torch.randn(n, 2, generator=g),
                                           "done": torch.zeros(n, 1, dtype=torch.bool)}, [n])}, [n], device="cpu")


@pytest.mark.parametrize("sampler", [RunningMaxPrioritizedSampler, TorchPrioritizedSampler, None])
def test_lean_buffer_is_torchrls(sampler, monkeypatch):
    generic_extends = []
    original = TensorDictReplayBuffer.extend

    def counted(self, *args, **kwargs):
        if type(self) is LeanTensorDictReplayBuffer:
            generic_extends.append(len(self))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(TensorDictReplayBuffer, "extend", counted)

    def build(cls):
        kw = {} if sampler is None else dict(sampler=sampler(500, alpha=0.6, beta=0.4), priority_key="td_error")
        return cls(storage=LazyTensorStorage(500), batch_size=16, **kw)

    ours, theirs = build(LeanTensorDictReplayBuffer), build(TensorDictReplayBuffer)
    g = torch.Generator().manual_seed(0)
    for step in range(120):
        x = _transition(g, 1 if step % 4 else 3)
        xa, xb = x.clone(), x.clone()
        assert torch.equal(ours.extend(xa), theirs.extend(xb))
        assert list(xa.keys(True, True)) == list(x.keys(True, True))  # the caller's batch left as it was
        if step < 10:
            continue
        torch.manual_seed(step)
        a = ours.sample()
        torch.manual_seed(step)
        b = theirs.sample()
        assert list(a.keys(True, True)) == list(b.keys(True, True))
        for key in a.keys(True, True):
            assert a.get(key).dtype == b.get(key).dtype and torch.equal(a.get(key), b.get(key)), key
        if sampler is not None:
            e = torch.rand(16, generator=g)
            a["td_error"], b["td_error"] = e.clone(), e.clone()
            ours.update_tensordict_priority(a)
            theirs.update_tensordict_priority(b)
    assert ours._lean()  # (the short paths were the ones compared)
    assert generic_extends == [0]  # (TorchRL's extend only for the first batch, which initialises the storage)
    n = len(theirs)
    assert len(ours) == n and ours._writer._cursor == theirs._writer._cursor
    assert (ours.storage._storage[:n] == theirs.storage._storage[:n]).all()
    if sampler is not None:
        assert torch.equal(ours._sampler._sum_tree._tree, theirs._sampler._sum_tree._tree)
        assert torch.equal(ours._sampler._min_tree._tree, theirs._sampler._min_tree._tree)


@pytest.mark.parametrize("rows", [1, 3])
def test_extend_from_writes_what_extend_of_the_selection_writes(rows):
    """``extend_from(batch, keys)`` (a collector's ``[envs, 1]`` batch with entries the loss does not read)
    stores, indexes and marks exactly what ``extend(batch.select(*keys).reshape(-1))`` does, across the
    buffer's wrap-around; a batch that lacks a stored key or has another shape takes TorchRL's path."""
    keys = ["observation", "action", ("next", "reward"), ("next", "done"), "preference"]  # ("preference": absent)

    def build(cls):
        return cls(storage=LazyTensorStorage(37), batch_size=8, priority_key="td_error",
                   sampler=RunningMaxPrioritizedSampler(37, alpha=0.6, beta=0.4))

    ours, theirs = build(LeanTensorDictReplayBuffer), build(LeanTensorDictReplayBuffer)
    g = torch.Generator().manual_seed(3)
    for step in range(40):
        x = _transition(g, rows).unsqueeze(-1)  # [rows, 1], as TorchRL's collector
        x["episode_return"] = torch.randn(rows, 1, 2, generator=g)  # (not a replay key: left out)
        before = sorted(map(str, x.keys(True, True)))
        assert torch.equal(ours.extend_from(x, keys), theirs.extend(x.select(*keys, strict=False).reshape(-1)))
        assert sorted(map(str, x.keys(True, True))) == before
        if step > 2:
            torch.manual_seed(step)
            a = ours.sample()
            torch.manual_seed(step)
            b = theirs.sample()
            assert (a == b).all() and torch.equal(a["index"], b["index"])
            a["td_error"] = b["td_error"] = torch.rand(8, generator=g)
            ours.update_tensordict_priority(a)
            theirs.update_tensordict_priority(b)
    assert ours._write_layout(x, keys) is not None  # (the leaf-by-leaf write was the one compared)
    assert ours._writer._cursor == theirs._writer._cursor == (40 * rows) % 37 and len(ours) == len(theirs) == 37
    assert ours._writer._write_count == theirs._writer._write_count == 40 * rows
    assert (ours.storage._storage == theirs.storage._storage).all()
    assert torch.equal(ours._sampler._sum_tree._tree, theirs._sampler._sum_tree._tree)
    # a batch with a stored key missing, or with a key the storage lacks: TorchRL's extend (which refuses
    # or adds as it does)
    missing = _transition(g, 1).unsqueeze(-1).exclude("action")
    layout = ours._write_layout(missing, keys)
    assert layout is not None and leaf_pairs(ours.storage._storage, layout, missing, 2) is None
    x = _transition(g, 1).unsqueeze(-1)
    x["preference"] = torch.ones(1, 1, 2)
    assert ours._write_layout(x, keys) is None


def test_lean_buffer_other_cases_are_torchrls():
    """With a transform the buffer is TorchRL's own (extend, sample)."""
    from torchrl.envs import RenameTransform

    rb = LeanTensorDictReplayBuffer(storage=LazyTensorStorage(10), batch_size=2,
                                    transform=RenameTransform(["observation"], ["obs"]))
    rb.extend(_transition(torch.Generator().manual_seed(0), 4))
    assert not rb._lean() and "obs" in rb.sample().keys()


@pytest.mark.parametrize("cls", [SumSegmentTree, MinSegmentTree])
@pytest.mark.parametrize("capacity, prefill", [(1, 0), (3, 0), (1000, 0), (1 << 16, 0), (1 << 16, 40_000),
                                               (1 << 18, 200_000)])
def test_host_tree_walks_only_the_written_subtree_exactly(cls, capacity, prefill, monkeypatch):
    """The CPU tree (writes and searches over the written leaves' subtree, its value copied up; a batch
    written into a subtree of up to 2 ** 16 leaves by recombining the whole subtree, into a larger one
    along the indices' ancestors) holds the same tree, and finds the same leaves, as the full-depth torch walk."""
    host, full = cls(capacity), cls(capacity)
    g = torch.Generator().manual_seed(capacity)
    cursor = prefill
    if prefill:
        first = torch.rand(prefill, generator=g)
        host[torch.arange(prefill)] = first
        full.set_leaves(torch.cat([first, torch.full((capacity - prefill,), cls.neutral)]))
    for step in range(150):
        n = 1 if step % 3 else int(torch.randint(1, 20, (1,), generator=g))
        if step % 2:
            index = torch.arange(cursor, cursor + n) % capacity
            cursor += n
        else:
            index = torch.randint(0, max(1, min(capacity, full._written)), (n,), generator=g)
        value = torch.rand(n, generator=g)
        host[index] = value
        with monkeypatch.context() as m:
            m.setattr(cls, "_host_array", lambda self: None)
            full[index] = value
        assert torch.equal(host._tree, full._tree) and host._written == full._written
        if cls is SumSegmentTree:
            mass = torch.rand(32, generator=g) * host._tree[1]
            with monkeypatch.context() as m:
                m.setattr(cls, "_host_array", lambda self: None)
                expected = full.scan_lower_bound(mass)
            assert torch.equal(host.scan_lower_bound(mass), expected)
