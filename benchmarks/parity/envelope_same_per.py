"""MB 1.3.0's PrioritizedReplayBuffer and our RunningMaxPrioritizedSampler under the same writes: leaves and draws.

    PYTHONPATH=. /tmp/mbvenv/bin/python benchmarks/parity/envelope_same_per.py   # MB's venv (issue 48)

2,000 items added one at a time; from the 100th on, an update per step writes priorities to 256 distinct
random items (the 50 newest with 10x larger TD errors), MB's rule on MB's buffer ((p + M)^0.6, M the running
max), ours through ``update_priority``; then 200,000 draws from each. Printed on 2026-12-02: leaves equal to
1.9e-7 (relative); total variation to the exact leaf distribution MB 0.038, ours 0.040 (the sampling noise of
200k draws over 2,000 bins), ours to MB 0.057.
"""
import numpy as np, torch
from tensordict import TensorDict
from morl_baselines.common.prioritized_buffer import PrioritizedReplayBuffer
from morl_trl.data.prioritized import RunningMaxPrioritizedSampler
from morl_trl.data.lean import LeanTensorDictReplayBuffer
from torchrl.data import LazyTensorStorage
rng = np.random.default_rng(0)
n = 2000
mb = PrioritizedReplayBuffer((2,), 1, rew_dim=2, max_size=100_000, action_dtype=np.uint8)
ours = LeanTensorDictReplayBuffer(storage=LazyTensorStorage(100_000), sampler=RunningMaxPrioritizedSampler(100_000, alpha=0.6, beta=0.4), batch_size=256, priority_key="td_error")
for i in range(n):
    mb.add(np.zeros(2), 0, np.zeros(2), np.zeros(2), 0.0)
    ours.extend(TensorDict({"x": torch.zeros(1, 1)}, [1]))
    if i >= 100:  # an update per step: priorities of a random batch of 256 (no duplicates, for MB's unique())
        idx = rng.choice(i + 1, size=min(256, i + 1), replace=False)
        p = np.abs(rng.standard_normal(len(idx))) * (1 + 10 * (idx > i - 50))  # recent items larger TD
        mb.update_priorities(idx, (p + mb.min_priority) ** 0.6)
        ours.update_priority(torch.as_tensor(idx), torch.as_tensor(p, dtype=torch.float32))
leaf_mb = mb.tree.nodes[-1][:n]
leaf_ours = ours._sampler._sum_tree.leaves()[:n].double().numpy() if hasattr(ours._sampler._sum_tree, "leaves") else None
print("max |leaf diff| / leaf", float(np.max(np.abs(leaf_mb - leaf_ours) / leaf_mb)))
S = 200_000
f_mb = np.bincount(mb.tree.sample(S), minlength=n)[:n] / S
draws = torch.cat([ours.sample()["index"] for _ in range(S // 256)]).numpy()
f_ours = np.bincount(draws, minlength=n)[:n] / len(draws)
p_true = leaf_mb / leaf_mb.sum()
print("TV(mb, leaves)", 0.5 * np.abs(f_mb - p_true).sum(), "TV(ours, leaves)", 0.5 * np.abs(f_ours - p_true).sum(),
      "TV(ours, mb)", 0.5 * np.abs(f_ours - f_mb).sum())
