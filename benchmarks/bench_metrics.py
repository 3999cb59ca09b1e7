"""Speed of the metrics: exact hypervolume, Pareto filtering, and the whole paper table.

Measured in one run, with the peer beside each figure:

* hypervolume of 1,000 random 4-objective points (ours: ``morl_trl.metrics.hypervolume``,
  moocore underneath, input checks included) against pymoo's ``HV`` indicator (what the
  authors' evaluator used), on two point sets: uniform in a cube (few are non-dominated) and
  on the positive unit sphere (all 1,000 are non-dominated, the hard case). pymoo >= 0.6.2
  calls moocore too, so this ratio is the cost of our input checks (goal: about 1x);
* the Pareto front of 10,000 random 4-objective points against a vectorized NumPy
  all-pairs dominance check (the usual hand-written filter);
* ``morl-trl reference-table`` on the published data (all 6 domains, 40 algorithms,
  1,310 fronts), end to end, if the data folder exists.

    python benchmarks/bench_metrics.py [--reference ../shared/reference] [--repeat 5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from morl_trl.metrics import hypervolume, pareto_front  # noqa: E402


def best_of(fn, repeat: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def numpy_pareto(points: np.ndarray) -> np.ndarray:
    ge = (points[:, None, :] >= points[None, :, :]).all(-1)
    gt = (points[:, None, :] > points[None, :, :]).any(-1)
    dominated = (ge & gt).any(0)
    return np.unique(points[~dominated], axis=0)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reference", type=Path, default=ROOT.parent / "shared" / "reference")
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args(argv)
    rng = np.random.default_rng(0)

    from pymoo.indicators.hv import HV

    print("hypervolume, 1,000 points, 4 objectives (best of", args.repeat, "runs)")
    cube = rng.random((1000, 4))
    sphere = np.abs(rng.standard_normal((1000, 4)))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    for name, pts in (("uniform cube", cube), ("unit sphere (all non-dominated)", sphere)):
        ref = np.zeros(4)
        t_ours, v_ours = best_of(lambda: hypervolume(pts, ref), args.repeat)
        indicator = HV(ref_point=-ref)
        t_peer, v_peer = best_of(lambda: indicator(-pts), args.repeat)
        assert abs(v_ours - v_peer) <= 1e-9 * max(1.0, abs(v_peer)), (v_ours, v_peer)
        print(
            f"  {name:<32} ours {t_ours * 1e3:8.2f} ms   pymoo HV {t_peer * 1e3:8.2f} ms   "
            f"ratio {t_peer / t_ours:5.2f}x   (HV {v_ours:.6f}, equal)"
        )

    pts = rng.random((10_000, 4))
    t_ours, f_ours = best_of(lambda: pareto_front(pts), args.repeat)
    t_peer, f_peer = best_of(lambda: numpy_pareto(pts[:2000]), 1)
    # the all-pairs filter is O(n^2) in memory: time it on 2,000 points, scale by (10,000/2,000)^2
    t_peer_full = t_peer * 25
    assert len(numpy_pareto(pts[:2000])) == len(pareto_front(pts[:2000]))
    print(
        f"Pareto front, 10,000 points, 4 objectives: ours {t_ours * 1e3:.2f} ms ({len(f_ours)} points)   "
        f"NumPy all-pairs ~{t_peer_full * 1e3:.0f} ms (2,000 points x 25)   ratio ~{t_peer_full / t_ours:.0f}x"
    )

    if (args.reference / "minmax_values").is_dir():
        from morl_trl.reporting.table import reference_table

        t, rows = best_of(lambda: reference_table(args.reference, eugr=True), 1)
        n_fronts = sum(r.nhgr.size for r in rows)
        print(f"reference table (NHGR + EUGR): {len(rows)} algorithm rows, {n_fronts} fronts in {t:.2f} s")
        t, rows = best_of(lambda: reference_table(args.reference, eugr=False, ci_reps=50_000), 1)
        print(f"reference table with 50,000-replicate bootstrap CIs (IQM and OG): {t:.2f} s")
    else:
        print(f"reference data not found at {args.reference}: table timing skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
