"""Issue 48's Envelope value check on a parity case's cached runs (default envelope-dst-mb, seeds 100-109): per library
and seed, the largest greedy scalarized estimate ``max_a w.Q`` and the largest batch mean of it over the run (what the
harness records in each run's ``q_check``: ``run_parity`` for ours, ``mb_runner`` for MB), beside the largest
discounted return the env allows (``common.q_bounds``: value iteration per objective over deep-sea-treasure's grid),
the final HV ratio, the commit, the machine and the training CPU time.

    python benchmarks/parity/q_check.py [CASE]

Every seed found is listed (none dropped); a library's summary counts the seeds whose estimates exceed the bound, and
with at least two seeds a side, a two-sided Mann-Whitney U test compares the two libraries' largest estimates.
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import result_path, short_commit  # noqa: E402

SEEDS = range(100, 110)  # (issue 48: seeds 100-109)
RESULTS = Path(__file__).resolve().parent / "results"


def rows(case: str, results: Path | None = None, seeds=SEEDS) -> dict[str, list[dict]]:
    """Per library (``"ours"``, ``"mb"``), one dict per cached run of ``case`` among ``seeds`` that has a ``q_check``
    (under ``results``, default :data:`RESULTS`)."""
    results = RESULTS if results is None else results
    out: dict[str, list[dict]] = {}
    for lib in ("ours", "mb"):
        for s in seeds:
            f = result_path(results, case, lib, s)
            if not f.exists():
                continue
            j = json.loads(f.read_text())
            q = j.get("q_check")
            if not q:
                continue
            out.setdefault(lib, []).append(dict(
                seed=s, max_q=q["max_scalarized_q"], max_mean_q=q["max_mean_scalarized_q"], bound=q["bound_any_state"],
                exceeds=bool(q["exceeds_bound"]), mean_exceeds=bool(q["mean_exceeds_bound"]),
                final_hv_ratio=j["curve"][-1].get("hv_ratio"), commit=short_commit(j.get("commit", "")),
                machine=j.get("machine") or j.get("machine_note") or "not recorded",
                cpu_minutes=(j["train_cpu_seconds"] / 60 if j.get("train_cpu_seconds") else None)))
    return out


def table(by_lib: dict[str, list[dict]]) -> str:
    """A markdown table of :func:`rows`, then one summary line per library."""
    lines = ["| library | seed | final HV ratio | max w.Q | max batch mean | bound | commit | machine | CPU min |",
             "|---|---|---|---|---|---|---|---|---|"]
    for lib, rs in by_lib.items():
        for r in rs:
            cpu = "-" if r["cpu_minutes"] is None else f"{r['cpu_minutes']:.1f}"
            ratio = "-" if r["final_hv_ratio"] is None else f"{r['final_hv_ratio']:.3f}"
            lines.append(f"| {lib} | {r['seed']} | {ratio} | {r['max_q']:.1f} | {r['max_mean_q']:.1f} | {r['bound']:.1f} "
                         f"| `{r['commit']}` | {r['machine']} | {cpu} |")
    for lib, rs in by_lib.items():
        n_exceed = sum(r["exceeds"] for r in rs)
        n_mean = sum(r["mean_exceeds"] for r in rs)
        lines.append(f"\n{lib}: {len(rs)} seeds ({', '.join(str(r['seed']) for r in rs)}); the largest estimate exceeds "
                     f"the bound on {n_exceed}, the largest batch mean on {n_mean}; max w.Q from "
                     f"{min(r['max_q'] for r in rs):.1f} to {max(r['max_q'] for r in rs):.1f}")
    if len(by_lib.get("ours", [])) >= 2 and len(by_lib.get("mb", [])) >= 2:
        from scipy import stats

        for key, name in (("max_q", "max w.Q"), ("max_mean_q", "max batch mean")):
            ours, mb = [r[key] for r in by_lib["ours"]], [r[key] for r in by_lib["mb"]]
            p = stats.mannwhitneyu(ours, mb, alternative="two-sided").pvalue
            lines.append(f"{name}: median ours {statistics.median(ours):.1f} (mean {statistics.fmean(ours):.1f}), "
                         f"MB {statistics.median(mb):.1f} (mean {statistics.fmean(mb):.1f}); "
                         f"Mann-Whitney U two-sided p {p:.2g}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    case = argv[0] if argv else "envelope-dst-mb"
    by_lib = rows(case)
    if not by_lib:
        print(f"no run of {case!r} with a q_check under {RESULTS / case}")
        return 1
    print(table(by_lib))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
