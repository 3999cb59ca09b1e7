"""The short paths of :class:`~morl_trl.data.lean.LeanTensorDictReplayBuffer` and of the CPU segment
trees (a search and a write over the written leaves' subtree only) compute exactly what TorchRL's
buffer and the full-depth tree walk do."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

from morl_trl.data import MinSegmentTree, RunningMaxPrioritizedSampler, SumSegmentTree, TorchPrioritizedSampler
from morl_trl.data.lean import LeanTensorDictReplayBuffer


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


def test_lean_buffer_other_cases_are_torchrls():
    """With a transform the buffer is TorchRL's own (extend, sample)."""
    from torchrl.envs import RenameTransform

    rb = LeanTensorDictReplayBuffer(storage=LazyTensorStorage(10), batch_size=2,
                                    transform=RenameTransform(["observation"], ["obs"]))
    rb.extend(_transition(torch.Generator().manual_seed(0), 4))
    assert not rb._lean() and "obs" in rb.sample().keys()


@pytest.mark.parametrize("cls", [SumSegmentTree, MinSegmentTree])
@pytest.mark.parametrize("capacity", [1, 3, 1000, 1 << 16])
def test_host_tree_walks_only_the_written_subtree_exactly(cls, capacity, monkeypatch):
    """The CPU tree (writes and searches over the written leaves' subtree, its value copied up) holds
    the same tree, and finds the same leaves, as the full-depth torch walk."""
    host, full = cls(capacity), cls(capacity)
    g = torch.Generator().manual_seed(capacity)
    cursor = 0
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
            m.setattr(cls, "_host", lambda self: None)
            full[index] = value
        assert torch.equal(host._tree, full._tree) and host._written == full._written
        if cls is SumSegmentTree:
            mass = torch.rand(32, generator=g) * host._tree[1]
            with monkeypatch.context() as m:
                m.setattr(cls, "_host", lambda self: None)
                expected = full.scan_lower_bound(mass)
            assert torch.equal(host.scan_lower_bound(mass), expected)
