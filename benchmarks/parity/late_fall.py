"""Issue 48's late-fall check on a parity case's cached runs (default gpi_ls-dst-30k, seeds 100-109): per library the
mean final HV ratio with a bootstrap 95 % CI of the mean (2,000 resamples, seed 0), and per seed its final value, its
peak and the largest drop below the peak so far at an evaluation in the last third of training.

    python benchmarks/parity/late_fall.py [CASE]
"""

import json
import sys
from pathlib import Path
import numpy as np
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
        drop = 0.0
        for i, (fr, r) in enumerate(zip(frames, ratios)):
            if fr >= 20000:
                drop = max(drop, max(ratios[:i + 1]) - r)
        res.setdefault(lib, []).append((s, ratios[-1], max(ratios), drop, j["commit"][:7] + ("+dirty" if j["commit"].endswith("dirty") else ""), round(j["train_seconds"] / 60, 2)))
rng = np.random.default_rng(0)
for lib, r in res.items():
    finals = np.array([x[1] for x in r])
    boots = rng.choice(finals, size=(2000, finals.size)).mean(1)
    lo, hi = np.percentile(boots, [2.5, 97.5])
    print(f"{lib}: seeds {[x[0] for x in r]} mean final HV ratio {finals.mean():.3f} [{lo:.3f}, {hi:.3f}] (bootstrap 95% CI of the mean)")
    for s, fin, peak, drop, commit, mins in r:
        print(f"   seed {s}: final {fin:.3f} peak {peak:.3f} largest drop below the peak so far in the last third {drop:.3f}  ({commit}, {mins} min train)")
