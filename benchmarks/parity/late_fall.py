"""Issue 48's late-fall check on a parity case's cached runs (default gpi_ls-dst-30k, seeds 100-109): per library the
mean final HV ratio with a bootstrap 95 % CI of the mean (2,000 resamples, seed 0), and per seed its final value, its
peak and two readings of "falling more than 0.1 below its own peak in the last third of training":

* ``below peak``: the largest gap, at an evaluation in the last third, below the best value so far (the peak may lie
  earlier: a run that fell in the middle third and stayed flat counts);
* ``fall within``: the largest drop between two evaluations of the last third (from the best value at or after the
  third's first evaluation): a fall that happens late, the symptom issue 48 describes (0.836 -> 0.495 in the last
  10k frames).

    python benchmarks/parity/late_fall.py [CASE]
"""

import json
import sys
from pathlib import Path
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import short_commit  # noqa: E402

CASE = sys.argv[1] if len(sys.argv) > 1 else "gpi_ls-dst-30k"
SEEDS = range(100, 110)  # (issue 48: seeds 100-109)
d = Path(__file__).resolve().parent / "results" / CASE
res = {}
for lib in ("ours", "mb"):
    for s in SEEDS:
        f = d / f"{lib}_s{s}.json"
        if not f.exists():
            continue
        j = json.loads(f.read_text()); c = j["curve"]
        ratios = [p["hv_ratio"] for p in c]; frames = [p["frames"] for p in c]
        drop = within = 0.0
        last = [i for i, fr in enumerate(frames) if fr >= 2 * frames[-1] / 3]
        for i in last:
            drop = max(drop, max(ratios[:i + 1]) - ratios[i])
            within = max(within, max(ratios[last[0]:i + 1]) - ratios[i])
        res.setdefault(lib, []).append((s, ratios[-1], max(ratios), (drop, within), short_commit(j["commit"]), round(j["train_seconds"] / 60, 2)))
rng = np.random.default_rng(0)
for lib, r in res.items():
    finals = np.array([x[1] for x in r])
    boots = rng.choice(finals, size=(2000, finals.size)).mean(1)
    lo, hi = np.percentile(boots, [2.5, 97.5])
    print(f"{lib}: seeds {[x[0] for x in r]} mean final HV ratio {finals.mean():.3f} [{lo:.3f}, {hi:.3f}] (bootstrap 95% CI of the mean)")
    for s, fin, peak, (drop, within), commit, mins in r:
        print(f"   seed {s}: final {fin:.3f} peak {peak:.3f}; in the last third: below peak {drop:.3f}, fall within "
              f"{within:.3f}  ({commit}, {mins} min train)")
    print(f"   largest: below peak {max(x[3][0] for x in r):.3f}, fall within {max(x[3][1] for x in r):.3f}")
