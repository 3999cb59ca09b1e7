import numpy as np
import pytest
import torch
from scipy.stats import chi2
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, PrioritizedSampler, TensorDictReplayBuffer

from morl_trl.data import (
    MinSegmentTree,
    SumSegmentTree,
    TorchPrioritizedSampler,
    native_prioritized_sampler_available,
    prioritized_sampler,
)

DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


@pytest.mark.parametrize("device", DEVICES)
def test_trees_match_brute_force_with_repeated_indices(device):
    g = torch.Generator().manual_seed(0)
    cap = 37  # not a power of two
    s, m = SumSegmentTree(cap, device=device, dtype=torch.float64), MinSegmentTree(cap, device=device, dtype=torch.float64)
    ref = torch.zeros(cap, dtype=torch.float64)
    written = torch.zeros(cap, dtype=torch.bool)
    for _ in range(20):
        idx = torch.randint(cap, (15,), generator=g)
        val = torch.rand(15, generator=g, dtype=torch.float64)
        s[idx.to(device)] = val.to(device)
        m[idx.to(device)] = val.to(device)
        for i, v in zip(idx.tolist(), val.tolist()):  # sequential semantics: the last write wins
            ref[i] = v
            written[i] = True
        torch.testing.assert_close(s.leaves().cpu(), ref)
        for lo, hi in [(0, cap), (3, 20), (10, 11), (0, 1)]:
            torch.testing.assert_close(s.query(lo, hi).cpu(), ref[lo:hi].sum())
            mins = torch.where(written[lo:hi], ref[lo:hi], torch.inf)
            torch.testing.assert_close(m.query(lo, hi).cpu(), mins.min())


@pytest.mark.parametrize("device", DEVICES)
def test_scan_lower_bound_inverts_the_cumulative_sum_and_skips_zeros(device):
    values = torch.tensor([0.0, 2.0, 0.0, 0.0, 1.0, 3.0, 0.0], dtype=torch.float64)
    tree = SumSegmentTree(7, device=device, dtype=torch.float64)
    tree[torch.arange(7)] = values
    mass = torch.linspace(0, 6 - 1e-9, 1001, dtype=torch.float64)
    expected = torch.searchsorted(values.cumsum(0), mass, right=True)
    got = tree.scan_lower_bound(mass.to(device)).cpu()
    assert torch.equal(got, expected)
    assert set(got.tolist()) == {1, 4, 5}


def chi_square_ok(counts: torch.Tensor, probs: torch.Tensor) -> tuple[float, float]:
    expected = probs * counts.sum()
    stat = float(((counts - expected) ** 2 / expected).sum())
    return stat, float(chi2.ppf(0.999, df=len(probs) - 1))


def filled_buffer(size, priorities=None, alpha=1.0, beta=0.5, capacity=None, device="cpu", batch_size=256):
    rb = TensorDictReplayBuffer(
        storage=LazyTensorStorage(capacity or size, device=device),
        sampler=TorchPrioritizedSampler(capacity or size, alpha=alpha, beta=beta),
        batch_size=batch_size,
    )
    rb.extend(TensorDict({"obs": torch.arange(size, dtype=torch.float32)}, [size]))
    if priorities is not None:
        rb.update_priority(torch.arange(size), priorities)
    return rb


@pytest.mark.parametrize("alpha", [1.0, 0.6, 0.0])
@pytest.mark.parametrize("device", DEVICES)
def test_sampling_frequencies_follow_priorities(alpha, device):
    torch.manual_seed(0)
    priorities = torch.tensor([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 0.5, 20.0])
    rb = filled_buffer(10, priorities, alpha=alpha, device=device)
    counts = torch.zeros(10)
    for _ in range(80):
        counts += torch.bincount(rb.sample()["index"].cpu(), minlength=10)
    probs = (priorities + 1e-8) ** alpha
    stat, critical = chi_square_ok(counts, probs / probs.sum())
    assert stat < critical, (stat, critical, counts)


def test_importance_weights_are_normalised_by_the_minimum_priority():
    torch.manual_seed(0)
    priorities = torch.tensor([1.0, 4.0, 16.0, 64.0])
    rb = filled_buffer(4, priorities, alpha=0.5, beta=0.5)
    sample = rb.sample()
    p = (priorities + 1e-8) ** 0.5
    expected = (p[sample["index"]] / p.min()) ** -0.5
    torch.testing.assert_close(sample["priority_weight"], expected)
    assert sample["priority_weight"].max() <= 1.0


def test_update_priority_and_new_items_get_the_max_priority():
    torch.manual_seed(0)
    rb = filled_buffer(6, capacity=10)
    sampler = rb.sampler
    torch.testing.assert_close(sampler._sum_tree.leaves()[:6], torch.ones(6))  # default priority 1
    rb.update_priority(torch.tensor([2, 4]), torch.tensor([5.0, 0.25]))
    torch.testing.assert_close(sampler._sum_tree.leaves()[:6], torch.tensor([1.0, 1.0, 5.0, 1.0, 0.25, 1.0]))
    rb.extend(TensorDict({"obs": torch.tensor([6.0, 7.0])}, [2]))  # written with the max priority so far
    torch.testing.assert_close(sampler._sum_tree.leaves()[6:8], torch.tensor([5.0, 5.0]))
    assert float(sampler._min_tree.query(0, 8)) == pytest.approx(0.25)
    # a dominant priority dominates the draws
    rb.update_priority(torch.tensor([7]), torch.tensor([1e6]))
    assert (rb.sample()["index"] == 7).float().mean() > 0.95


def test_update_tensordict_priority_from_a_loss_style_entry():
    torch.manual_seed(0)
    rb = filled_buffer(32, alpha=0.7, batch_size=16)
    sample = rb.sample()
    sample["td_error"] = torch.linspace(0.1, 1.6, 16)
    rb.update_tensordict_priority(sample)
    last = {}
    for i, e in zip(sample["index"].tolist(), sample["td_error"].tolist()):
        last[i] = (e + 1e-8) ** 0.7
    got = rb.sampler._sum_tree[torch.tensor(list(last))]
    torch.testing.assert_close(got, torch.tensor(list(last.values())))


def test_state_dict_round_trip_reproduces_samples(tmp_path):
    torch.manual_seed(0)
    rb = filled_buffer(50, torch.rand(50) + 0.1, alpha=0.8, capacity=64)
    fresh = TensorDictReplayBuffer(storage=LazyTensorStorage(64), sampler=TorchPrioritizedSampler(64, alpha=0.1, beta=0.9), batch_size=256)
    fresh.load_state_dict(rb.state_dict())
    assert (fresh.sampler._alpha, fresh.sampler._beta) == (0.8, 0.5)
    torch.testing.assert_close(fresh.sampler._sum_tree.leaves(), rb.sampler._sum_tree.leaves())
    torch.manual_seed(1)
    a = rb.sample()
    torch.manual_seed(1)
    b = fresh.sample()
    assert torch.equal(a["index"], b["index"])
    torch.testing.assert_close(a["priority_weight"], b["priority_weight"])

    rb.dumps(tmp_path / "rb")
    loaded = TensorDictReplayBuffer(storage=LazyTensorStorage(64), sampler=TorchPrioritizedSampler(64, alpha=0.1, beta=0.9), batch_size=256)
    loaded.loads(tmp_path / "rb")
    torch.testing.assert_close(loaded.sampler._min_tree.leaves(), rb.sampler._min_tree.leaves())
    assert loaded.sampler.default_priority == pytest.approx(float(rb.sampler.default_priority))


def test_changing_alpha_retransforms_stored_priorities():
    rb = filled_buffer(4, torch.tensor([1.0, 4.0, 9.0, 16.0]), alpha=1.0)
    rb.sampler.alpha = 0.5
    torch.testing.assert_close(rb.sampler._sum_tree.leaves(), torch.tensor([1.0, 2.0, 3.0, 4.0]), rtol=1e-5, atol=1e-5)
    assert float(rb.sampler._sum_tree.query()) == pytest.approx(10.0, rel=1e-5)
    assert float(rb.sampler._min_tree.query()) == pytest.approx(1.0, rel=1e-5)


def test_empty_buffer_and_bad_arguments():
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(4), sampler=TorchPrioritizedSampler(4, 0.5, 0.5), batch_size=2)
    with pytest.raises(RuntimeError):
        rb.sample()
    with pytest.raises(ValueError, match="alpha"):
        TorchPrioritizedSampler(4, alpha=-1.0, beta=0.5)
    with pytest.raises(ValueError, match="max_capacity"):
        TorchPrioritizedSampler(0, alpha=1.0, beta=0.5)


def test_factory_falls_back_when_the_native_sampler_cannot_load():
    auto = prioritized_sampler(16, alpha=0.6, beta=0.4)
    assert isinstance(auto, PrioritizedSampler)
    assert isinstance(auto, TorchPrioritizedSampler) != native_prioritized_sampler_available()
    assert isinstance(prioritized_sampler(16, 0.6, 0.4, backend="torch"), TorchPrioritizedSampler)
    if not native_prioritized_sampler_available():
        with pytest.raises(RuntimeError, match="SumSegmentTreeFp32"):
            prioritized_sampler(16, 0.6, 0.4, backend="native")
    with pytest.raises(ValueError, match="backend"):
        prioritized_sampler(16, 0.6, 0.4, backend="c++")


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_multi_dimensional_storage():
    torch.manual_seed(0)
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(12, ndim=2), sampler=TorchPrioritizedSampler(12, 1.0, 0.5), batch_size=6)
    rb.extend(TensorDict({"obs": torch.arange(12.0).reshape(4, 3)}, [4, 3]))
    sample = rb.sample()
    index = sample["index"]
    assert index.shape == (6, 2)
    stored = rb.storage._storage["obs"]
    torch.testing.assert_close(sample["obs"], stored[index[:, 0], index[:, 1]])
    sample["td_error"] = torch.arange(1.0, 7.0)
    rb.update_tensordict_priority(sample)
    flat = index[:, 0] * stored.shape[1] + index[:, 1]
    last = {int(f): float(p) for f, p in zip(flat, sample["td_error"])}
    torch.testing.assert_close(rb.sampler._sum_tree[torch.tensor(list(last))], torch.tensor(list(last.values())))


# ---------------------------------------------------------------- device spellings (issue: "cuda" != "cuda:0")
SPELLINGS = ["cpu", "cpu:0"] + (["cuda", "cuda:0"] if torch.cuda.is_available() else [])


@pytest.mark.parametrize("device", SPELLINGS)
def test_priorities_survive_every_device_spelling(device):
    # With an unnormalized device TorchRL's storage check rebuilt empty trees on every call
    # (sum 0, min inf): importance weights became inf and the Envelope loss NaN.
    torch.manual_seed(0)
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(64, device=device),
                                sampler=TorchPrioritizedSampler(64, alpha=1.0, beta=0.4, device=device),
                                batch_size=16, priority_key="td_error")
    rb.extend(TensorDict({"obs": torch.arange(32.0)}, [32], device=device))
    sample = rb.sample()
    sample["td_error"] = torch.where(sample["obs"] < 8, 4.0, 1.0)
    rb.update_tensordict_priority(sample)
    sampler = rb._sampler
    assert sampler._sum_tree._written, "the trees kept their priorities"
    total = float(sampler._sum_tree.query(0, 32))
    assert total > 0 and float(sampler._min_tree.query(0, 32)) > 0
    for _ in range(3):
        weights = rb.sample()["priority_weight"]
        assert torch.isfinite(weights).all() and (weights > 0).all() and float(weights.max()) <= 1.0 + 1e-6
    assert float(sampler._sum_tree.query(0, 32)) == pytest.approx(total)


def test_normalize_device():
    from morl_trl.data import normalize_device

    assert normalize_device("cpu:0") == torch.device("cpu") == normalize_device(torch.device("cpu"))
    assert normalize_device(None) is None
    if torch.cuda.is_available():
        assert normalize_device("cuda") == torch.device("cuda", torch.cuda.current_device())


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_cpu_host_path_equals_the_torch_ops_bit_for_bit(dtype, monkeypatch):
    """The CPU trees do their level-by-level arithmetic on a NumPy view; the torch ops (the
    path of every other device) give the same tree, bit for bit, and the same scan."""
    g = torch.Generator().manual_seed(1)
    cap = 1_000  # 10 levels
    fast = [SumSegmentTree(cap, dtype=dtype), MinSegmentTree(cap, dtype=dtype)]
    slow = [SumSegmentTree(cap, dtype=dtype), MinSegmentTree(cap, dtype=dtype)]
    for t in slow:
        monkeypatch.setattr(t, "_host_array", lambda: None)
    for step in range(60):
        n = 1 if step % 3 == 0 else 32
        idx = torch.randint(cap, (n,), generator=g)
        val = torch.rand(n, generator=g, dtype=dtype) ** 3 * 7
        for a, b in zip(fast, slow):
            if step % 2:  # the sampler's sync-free write (repeated indices: the last one wins)
                a.assign_unchecked(idx, val)
                b.assign_unchecked(idx, val)
            else:
                a[idx] = val
                b[idx] = val
            assert torch.equal(a._tree, b._tree)
            assert a._written == b._written
        mass = torch.rand(64, generator=g, dtype=dtype) * fast[0].query(0, cap)
        assert torch.equal(fast[0].scan_lower_bound(mass), slow[0].scan_lower_bound(mass))
    assert fast[0]._host_array() is not None and float(fast[0].query(0, cap)) > 0


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_cpu_host_writes_take_every_index_and_value_form(dtype, monkeypatch):
    """Python int / list / tensor indices and broadcast values write what the torch path writes; an
    index out of range is refused with the range, leaving the tree as it was."""
    fast = [SumSegmentTree(100, dtype=dtype), MinSegmentTree(100, dtype=dtype)]
    slow = [SumSegmentTree(100, dtype=dtype), MinSegmentTree(100, dtype=dtype)]
    for t in slow:
        monkeypatch.setattr(t, "_host_array", lambda: None)
    writes = [(3, 0.25), ([1, 2, 2], [0.5, 1.5, 3.0]), (torch.tensor([7, 9]), torch.tensor(2.0)),
              (torch.tensor([99]), torch.tensor([1e-7], dtype=torch.float64)), (np.array([4, 5]), 0.125)]
    for index, value in writes:
        for a, b in zip(fast, slow):
            a[index] = value
            b[index] = value
            assert torch.equal(a._tree, b._tree) and a._written == b._written
    assert float(fast[0].query(0, 100)) == pytest.approx(0.25 + 0.5 + 3.0 + 4.0 + 1e-7 + 0.25, rel=1e-6)
    before = fast[0]._tree.clone()
    with pytest.raises(IndexError, match=r"\[0, 100\): min 5, max 100"):
        fast[0][[5, 100]] = 1.0
    assert torch.equal(fast[0]._tree, before)
