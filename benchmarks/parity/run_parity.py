"""Parity with MORL-Baselines: ours and MB 1.3.0 on the same env, hyperparameters, networks,
frame budget and evaluation; learning curves, final IQM with bootstrap CIs, frames/s.

    python benchmarks/parity/run_parity.py                       # every runnable case, this round's seeds (100-104)
    python benchmarks/parity/run_parity.py --cases gpi_ls-dst --round 1 --libs ours,mb   # round 1's seeds, 0-4
    python benchmarks/parity/run_parity.py --report-only         # RESULTS.md + PNGs from what is done
    python benchmarks/parity/run_parity.py --mb-venv /tmp/mbvenv --mb-venv-only   # MB's venv only (the speed benchmarks' peer)

MB runs in its own virtual environment (``--mb-venv``, default ``~/.cache/morl_trl/mb-1.3.0``),
created here with ``--system-site-packages`` (it reuses our torch), ``morl-baselines==1.3.0`` and
the packages its modules import (``MB_DEPS``) when absent or incomplete; it is never a dependency of morl_trl. Each (case, library, seed) is one process
and one JSON file under ``--out`` (written atomically): a rerun skips the finished ones, so the
benchmark resumes where it stopped. Run it in the background with ``nice``; it takes minutes
to hours per seed on a 2-core CPU.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(ROOT))  # morl_trl from this checkout (the script's folder is not the repository root)

from common import (CASES, EVAL_EPISODES, EVAL_WEIGHTS, MB_VERSION, PENDING, QEstimateLog, case_eval_weights,  # noqa: E402
                    case_floor, case_metric, context_means, result_path, write_result)
from verdict import ALPHA, INFORMATIVE, MARGIN_OF_GAIN, learning, round_seeds, verdict  # noqa: E402

MB_DEPS = ["wandb", "cvxpy", "pycddlib==2.1.6", "sortedcontainers", "fire", "seaborn", "moviepy"]
#: what MB's modules import of MB_DEPS, by import name (its GPI-LS / GPI-PD: cdd, cvxpy, seaborn at module level)
MB_IMPORTS = ["morl_baselines", "wandb", "cvxpy", "cdd", "sortedcontainers", "fire", "seaborn", "moviepy"]
# per-case findings written under the case's table (what learned, why the libraries differ)
NOTES: dict[str, str] = {}
METRICS = (("hypervolume", "hypervolume"), ("eum", "EUM"), ("igd", "IGD"), ("hv_ratio", "HV / true front's HV"),
           ("nhgr", "NHGR"), ("normalized_hypervolume", "normalized HV"))
#: how a case's metric is named in the summary and the plots (a paper-domain case's: the mean over its contexts)
METRIC_NAMES = {"hypervolume": "hypervolume", "nhgr": "NHGR (mean over the paper's contexts)"}


# ---------------------------------------------------------------------- MB's venv
def ensure_mb_venv(venv: Path) -> Path:
    """MORL-Baselines' python in ``venv``: created (``--system-site-packages``: it reuses our torch) with
    MB itself when absent, and :data:`MB_DEPS` installed when any of :data:`MB_IMPORTS` does not import
    (a venv made by hand with MB alone, say), our torch pinned so that nothing replaces it. The one place
    the benchmarks' MB venv is made (``run_parity.py --mb-venv DIR --mb-venv-only``)."""
    python = venv / "bin" / "python"
    if not python.exists():
        print(f"creating MORL-Baselines {MB_VERSION}'s venv in {venv}", flush=True)
        subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    if subprocess.run([str(python), "-c", "import morl_baselines"], capture_output=True).returncode != 0:
        # --no-deps for MB itself: its pins must not replace our torch / gymnasium in the shared site-packages
        subprocess.run([str(python), "-m", "pip", "install", "--no-deps", f"morl-baselines=={MB_VERSION}"], check=True)
    if subprocess.run([str(python), "-c", "import " + ", ".join(MB_IMPORTS)], capture_output=True).returncode != 0:
        import tempfile

        import torch

        with tempfile.NamedTemporaryFile("w", suffix=".txt") as pin:
            pin.write(f"torch=={torch.__version__}\n")
            pin.flush()
            subprocess.run([str(python), "-m", "pip", "install", "-c", pin.name, *MB_DEPS], check=True)
    return python


# ---------------------------------------------------------------------- one run of ours
def ours_budget(case: dict) -> tuple[int, int, int]:
    """``(frames, eval_interval, scale)`` for ``morl_trl.train``: a case counts frames as MB does; ours
    counts one PGMORL member's (the authors' count), ``1 / ours_frame_scale`` of MB's."""
    scale = case.get("ours_frame_scale", 1)
    return case["frames"] // scale, case["eval_every"] // scale, scale


def run_ours(case_name: str, seed: int, out: Path) -> None:
    import tempfile

    import torch

    import morl_trl
    from morl_trl.evaluation import MultiContextEvaluator

    case = CASES[case_name]
    torch.set_num_threads(1)
    eval_seconds = [0.0]
    evaluate = MultiContextEvaluator.evaluate

    qlog = QEstimateLog() if case["algo"] == "envelope" else None

    def timed(self, *args, **kwargs):  # training time = wall time minus the evaluations
        t = time.perf_counter()
        try:
            return evaluate(self, *args, **kwargs)
        finally:
            eval_seconds[0] += time.perf_counter() - t
            if qlog is not None:
                qlog.mark(-1)  # (the frames are the curve's, filled in below)

    from morl_trl.runs.run import Run

    started = [None]
    start = Run.start

    def start_clock(self, *args, **kwargs):  # training time starts once env, agent and collector are built
        out = start(self, *args, **kwargs)
        started[0] = time.perf_counter()
        return out

    from morl_trl.objectives.envelope import EnvelopeQLoss

    q_values = EnvelopeQLoss._q_values

    def logged_q_values(self, data, w, params):  # the online forward the loss's gradient goes through
        q = q_values(self, data, w, params)
        if params is self.value_network_params and torch.is_grad_enabled():
            qlog.record(w, q)
        return q

    from morl_trl.runs.run_log import RunLog

    report = RunLog.report
    paper = bool(case.get("paper"))

    def no_report(self, *args, **kwargs):  # (a paper-domain run's report.md computes the floor: the harness does, once)
        return None

    MultiContextEvaluator.evaluate, Run.start = timed, start_clock
    if paper:
        RunLog.report = no_report
    if qlog is not None:
        EnvelopeQLoss._q_values = logged_q_values
    try:
        with tempfile.TemporaryDirectory() as tmp:
            frames, eval_every, scale = ours_budget(case)
            extra_cfg = dict(history_len=case["history_len"]) if paper else {}
            run = morl_trl.train(case["algo"], env=case["env"], seed=seed, frames=frames,
                                 eval_interval=eval_every, eval_weights=case_eval_weights(case),
                                 eval_episodes=EVAL_EPISODES, gamma=case["gamma"], eval_random_baseline=False,
                                 progress=False, run_dir=f"{tmp}/run", **extra_cfg, **case["ours"])
            wall = time.perf_counter() - started[0]
            with open(Path(run.run_dir) / "eval" / "metrics.csv") as fh:
                curve = curve_from_rows(list(csv.DictReader(fh)))
            for point in curve:
                point["frames"] *= scale
    finally:
        MultiContextEvaluator.evaluate, Run.start, EnvelopeQLoss._q_values = evaluate, start, q_values
        RunLog.report = report
    train_s = wall - eval_seconds[0]  # (the evaluation at frame 0 runs after start: it is subtracted too)
    frames = int(curve[-1]["frames"])
    extra = {}
    if qlog is not None:
        if len(qlog.points) == len(curve):
            for point, row in zip(qlog.points, curve):
                point["frames"] = int(row["frames"])
        extra["q_check"] = qlog.result(case["env"], case["gamma"])
    write_result(out, dict(case=case_name, lib="ours", seed=seed, version=f"morl_trl {morl_trl.__version__}",
                           curve=curve, frames=frames, train_seconds=train_s, eval_seconds=eval_seconds[0],
                           train_fps=frames / train_s,
                           eval_episodes=EVAL_EPISODES, **extra))


def curve_from_rows(rows: list[dict]) -> list[dict]:
    """A run's curve from its ``eval/metrics.csv`` rows: one point per evaluation. A run evaluated on one context
    (MO-Gymnasium's envs) has one row per evaluation; one evaluated on a domain's suite (a paper-domain case) has a
    row per context, reduced to their means (``common.context_means``, the same reduction as MB's side)."""

    def num(v):
        return float(v) if v not in ("", "None", None) else None

    by_frames: dict[float, dict[str, dict]] = {}
    for row in rows:
        by_frames.setdefault(num(row["frames"]), {})[row.get("context", "")] = row
    curve = []
    for frames, per in by_frames.items():
        if len(per) == 1:
            point = {k: num(v) for k, v in next(iter(per.values())).items() if k != "context"}
        else:
            point = context_means({c: {k: num(v) for k, v in r.items() if k not in ("context", "frames")}
                                   for c, r in per.items()})
        point["frames"] = frames
        curve.append(point)
    return curve


# ---------------------------------------------------------------------- the report
def _load(out: Path, case: str) -> dict[str, list[dict]]:
    runs: dict[str, list[dict]] = {}
    for path in sorted((out / case).glob("*.json")):
        data = json.loads(path.read_text())
        runs.setdefault(data["lib"], []).append(data)
    return runs


def _iqm_ci(values: list[float]) -> tuple[float, float, float]:
    import numpy as np

    from morl_trl.metrics import stratified_bootstrap_ci

    scores = np.asarray(values, dtype=float)[:, None]  # [runs, tasks = 1]
    return stratified_bootstrap_ci(scores, "iqm", reps=2000, seed=0)


def _plot(case: str, runs: dict[str, list[dict]], path: Path, floor: dict | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    metrics = [(m, label) for m, label in METRICS
               if any(r["curve"][0].get(m) is not None for rs in runs.values() for r in rs)]
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.2 * len(metrics), 3.2), squeeze=False)
    for ax, (metric, label) in zip(axes.flat, metrics):
        for i, (lib, rs) in enumerate(sorted(runs.items())):
            # each evaluation point over the runs that have it, by its frame count (runs made before MB's
            # frame-0 evaluation start at the first evaluation: matched by frames, not by position)
            frames = sorted({p["frames"] for r in rs for p in r["curve"]})
            at = [[p[metric] for r in rs for p in r["curve"] if p["frames"] == f and p.get(metric) is not None]
                  for f in frames]
            frames, at = [f for f, v in zip(frames, at) if v], [np.asarray(v, dtype=float) for v in at if v]
            name = "morl_trl (ours)" if lib == "ours" else f"MORL-Baselines {MB_VERSION}"
            ax.plot(frames, [v.mean() for v in at], color=f"C{i}", label=f"{name} ({len(rs)} seeds)")
            ax.fill_between(frames, [v.min() for v in at], [v.max() for v in at], color=f"C{i}", alpha=0.2)
        if floor is not None and metric == "nhgr":
            ax.axhline(floor["mean"], color="k", linestyle="--", linewidth=1, label=f"floor: {floor['policy']}")
        ax.set_xlabel("frames")
        ax.set_ylabel(label)
    axes.flat[0].legend(fontsize=7)
    fig.suptitle(f"{case}: mean over seeds, band min-max", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _num(value) -> str:
    return "-" if value is None else f"{value:,.0f}"


def write_results(out: Path, seeds: list[int], command: str) -> Path:
    import platform

    import torch

    lines = ["# Parity with MORL-Baselines", "",
             f"Ours (morl_trl) and MORL-Baselines {MB_VERSION} (in its own venv) on the same env, hyperparameters, "
             f"networks, frame budget and evaluation: morl_trl's evaluator, {EVAL_WEIGHTS} weights x "
             f"{EVAL_EPISODES} episode, the case's discount, the env's reference point "
             "(`morl_trl.envs.foreign.MO_GYMNASIUM_REF_POINTS`), IGD and the HV ratio against MO-Gymnasium's "
             "`pareto_front(gamma)`. Final values: IQM over seeds with 95 % stratified-bootstrap CIs "
             "(rliable's method, `morl_trl.metrics.stratified_bootstrap_ci`, 2000 replicates). frames/s: "
             "training only (wall time minus the evaluations), one torch thread, on the machine below.", "",
             f"Command: `{command}`", "",
             f"Versions: Python {platform.python_version()}, torch {torch.__version__}, morl-baselines {MB_VERSION}; "
             f"machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (timings are noisy).", ""]
    summary = ["## Summary", "",
               "Final hypervolume (IQM over seeds, 95 % CI; a paper-domain case's: its NHGR, the mean over the paper's "
               "evaluation contexts, beside the floor of trivial policies at the same weights), the case's verdict (`benchmarks/parity/verdict.py`: "
               "on the case's metric (hypervolume unless the case names another): "
               f"each library learns when a one-sided paired t-test of final - frame 0 over its seeds gives p < {ALPHA}; "
               "both at parity when Welch's two one-sided tests put the difference of final means within "
               f"{MARGIN_OF_GAIN:g} of MB's mean gain, p < {ALPHA}; better / worse when Welch's t-test gives p < "
               f"{ALPHA}), and training frames/s "
               "(mean over seeds; ours / MB is issue 31's end-to-end comparison: both libraries' own training "
               "loops on the same env and budget).", "",
               "The verdict is computed on the round's seeds "
               f"({', '.join(map(str, seeds))}: `verdict.round_seeds`) where both libraries have at least 2 of them, "
               "else on every seed run (the seeds used are named); every seed run is in the case's tables. "
               "MB learns: whether the reference learns on its own at the case's budget (the same paired test, on "
               "the verdict's seeds: mean gain of final - frame-0 hypervolume, one-sided p); a case whose reference "
               "does not learn says nothing about ours.", "",
               "| case | seeds ours / MB | final HV ours | final HV MB | verdict | MB learns | frames/s ours | frames/s MB "
               "| ours / MB |",
               "|---|---|---|---|---|---|---|---|---|"]
    per_method: dict[str, list[tuple[str, str]]] = {}
    ref_learns_by_case: dict[str, str] = {}
    commits: dict[str, int] = {}
    body = []
    for case in CASES:
        runs = _load(out, case)
        for rs in runs.values():
            for r in rs:
                commits[r.get("commit", "not recorded")] = commits.get(r.get("commit", "not recorded"), 0) + 1
        spec = CASES[case]
        body += [f"## {case}", "",
                 f"`{spec['algo']}` on `{spec['env']}`, {spec['frames']:,} frames, evaluated every "
                 f"{spec['eval_every']:,}, gamma {spec['gamma']}; ours: `{spec['ours']}`, MB: `{spec['mb']}`"
                 + (f", MB train(): `{spec['mb_train']}`" if spec["mb_train"] else ""), ""]
        done = {lib: sorted(r["seed"] for r in rs) for lib, rs in runs.items()}
        if not runs:
            body += ["Not run yet.", ""]
            summary.append(f"| {case} | 0 / 0 | - | - | - | - | - | - | - |")
            continue
        body += [f"Seeds done: " + ", ".join(f"{lib} {s}" for lib, s in sorted(done.items()))
                 + f" (target: {len(seeds)} per library)", ""]
        body += ["| metric | " + " | ".join(f"{lib} IQM [95% CI]" for lib in sorted(runs)) + " |",
                 "|---|" + "---|" * len(runs)]
        ci: dict[str, tuple[float, float, float]] = {}
        metric_of_case = case_metric(spec)
        for metric, label in METRICS:
            cells = []
            for lib in sorted(runs):
                vals = [r["curve"][-1].get(metric) for r in runs[lib]]
                if any(v is None for v in vals):
                    cells.append("-")
                    continue
                m, lo, hi = _iqm_ci(vals)
                if metric == metric_of_case:
                    ci[lib] = (m, lo, hi)
                cells.append(f"{m:.3f} [{lo:.3f}, {hi:.3f}]")
            if any(c != "-" for c in cells):
                body.append(f"| final {label} | " + " | ".join(cells) + " |")
        fps = {}
        for lib, rs in sorted(runs.items()):
            # the first runs of ours (marked build_in_train_seconds) also timed building env, agent and
            # collector: left out of the mean when others exist
            timed = ([r for r in rs if r.get("train_fps") and not r.get("build_in_train_seconds")]
                     or [r for r in rs if r.get("train_fps")])
            if timed:
                fps[lib] = sum(r["train_fps"] for r in timed) / len(timed)
        body += [f"| training frames/s (mean) | " + " | ".join(f"{lib} {v:,.0f}" for lib, v in fps.items()) + " |", ""]
        body += q_check_lines(runs)
        floor = case_floor(case, out) if spec.get("paper") else None
        body += floor_lines(spec, runs, floor)
        png = out.parent / f"{case}.png"
        _plot(case, runs, png, floor)
        body += [f"![{case}]({png.name})", ""]
        if case in NOTES:
            body += [NOTES[case], ""]
        if metric_of_case == "hypervolume":
            hv = {lib: f"{m:.2f} [{lo:.2f}, {hi:.2f}]" for lib, (m, lo, hi) in ci.items()}
        else:  # (a paper-domain case: its metric named, beside the floor of trivial policies)
            beside = f", floor {floor['mean']:.3f}" if floor else ""
            hv = {lib: f"{m:.3f} [{lo:.3f}, {hi:.3f}] {metric_of_case.upper()}{beside}" for lib, (m, lo, hi) in ci.items()}
        judged, used = verdict_runs(runs, seeds)
        said = case_verdict(judged, metric_of_case) if "ours" in runs and "mb" in runs else "-"
        if said != "-":
            n_used = min(len(judged["ours"]), len(judged["mb"]))
            said += f" (seeds {used}" + (f"; < {len(seeds)} seeds" if n_used < len(seeds) else "") + ")"
        ref_learns = library_learning(judged["mb"], metric_of_case) if "mb" in judged else "-"
        per_method.setdefault(spec["algo"], []).append((case, said))
        ref_learns_by_case[case] = ref_learns
        ratio = f"{fps['ours'] / fps['mb']:.2f}x" if "ours" in fps and "mb" in fps else "-"
        summary.append(f"| {case} | {len(done.get('ours', []))} / {len(done.get('mb', []))} | {hv.get('ours', '-')} "
                       f"| {hv.get('mb', '-')} | {said} | {ref_learns} | {_num(fps.get('ours'))} | {_num(fps.get('mb'))} "
                       f"| {ratio} |")
    methods = ["## Verdicts per method", "",
               "A case counts as evidence of learning only where at least one library learns at its budget; "
               "the reference learns in the cases listed under \"MB learns\".", "",
               "| method | informative cases | MB learns | every case |", "|---|---|---|---|"]
    for algo, cases in per_method.items():
        good = [f"{c}: {v}" for c, v in cases if v.split(" (")[0] in INFORMATIVE]
        ref = [c for c, _ in cases if ref_learns_by_case.get(c, "").startswith("learns")]
        methods.append(f"| {algo} | {'; '.join(good) or 'none'} | {', '.join(ref) or 'none'} | "
                       + "; ".join(f"{c}: {v}" for c, v in cases) + " |")
    made = ", ".join(f"`{c}` ({n} files)" for c, n in sorted(commits.items(), key=lambda kv: (-kv[1], kv[0])))
    lines += [f"Results made by: {made or 'none yet'}"
              + (" -- **more than one commit: regenerate from one commit's runs before quoting**"
                 if len(commits) > 1 else ""), ""]
    lines += methods + [""] + summary + [""] + body
    notes = out.parent / "NOTES.md"  # hand-written findings (kept across regenerations)
    if notes.exists():
        lines += [notes.read_text()]
    if PENDING:
        lines += ["## Not run yet", "", "These cases of issue 29 have no runner or no results yet: "
                  + ", ".join(PENDING) + ".", ""]
    path = out.parent / "RESULTS.md"
    path.write_text("\n".join(lines))
    return path


def floor_lines(spec: dict, runs: dict[str, list[dict]], floor: dict | None) -> list[str]:
    """A paper-domain case's metric beside the floor of trivial policies (``common.case_floor``): per library the
    mean over seeds at frame 0 and at the end, per context the floor and each library's final mean."""
    if not spec.get("paper"):
        return []
    import numpy as np

    metric = case_metric(spec)
    if floor is None:
        return [f"Floor: not computed (no reference data for {spec['env']}).", ""]
    lines = [f"Floor of trivial policies (`morl_trl.reporting.floors.floor_at_weights`, the code of a run's "
             f"report_floors.json; {case_eval_weights(spec)} weights, the paper's {len(floor['nhgr'])} contexts, seed 0): "
             f"best **{floor['policy']}**, {metric.upper()} {floor['mean']:.3f} (mean over contexts). Mean over seeds:", "",
             "| library | frame 0 | final | final above the floor (seeds) |", "|---|---|---|---|"]
    finals: dict[str, dict[str, float]] = {}
    for lib, rs in sorted(runs.items()):
        start = [r["curve"][0].get(metric) for r in rs if r["curve"] and r["curve"][0]["frames"] == 0]
        final = [r["curve"][-1].get(metric) for r in rs]
        above = sum(v is not None and v > floor["mean"] for v in final)
        lines.append(f"| {lib} | {np.mean(start):.3f} | {np.mean(final):.3f} | {above} of {len(final)} |" if start
                     else f"| {lib} | - | {np.mean(final):.3f} | {above} of {len(final)} |")
        per = [r["curve"][-1].get("per_context") or {} for r in rs]
        finals[lib] = {c: float(np.mean([p[c][metric] for p in per if c in p and p[c].get(metric) is not None]))
                       for c in floor["nhgr"] if any(c in p for p in per)}
    libs = sorted(finals)
    lines += ["", "| context | floor | " + " | ".join(f"{lib} final (mean)" for lib in libs) + " |",
              "|---|---|" + "---|" * len(libs)]
    for c, v in floor["nhgr"].items():
        lines.append(f"| {c} | {v:.3f} | " + " | ".join(f"{finals[lib][c]:.3f}" if c in finals[lib] else "-"
                                                        for lib in libs) + " |")
    return lines + [""]


def q_check_lines(runs: dict[str, list[dict]]) -> list[str]:
    """The Q-estimate check of a case's Envelope runs (``q_check``, issue 48): per library and seed the largest
    greedy ``w . Q`` estimate of its updates' batches and the largest batch mean, beside the env's bound."""
    checked = {lib: sorted((r for r in rs if r.get("q_check")), key=lambda r: r["seed"]) for lib, rs in runs.items()}
    checked = {lib: rs for lib, rs in checked.items() if rs}
    if not checked:
        return []
    first = next(iter(checked.values()))[0]["q_check"]
    if first.get("bound_any_state") is None:
        return []
    lines = [f"Q estimates (issue 48): the largest greedy w.Q of any update's batch / the largest batch mean, against "
             f"the largest discounted return the env allows, {first['bound_any_state']:.2f} from any state "
             f"({first['bound_start']:.2f} from the start state; `common.q_bounds`):", "",
             "| library | seed | max w.Q | max batch-mean w.Q | above the bound | final HV ratio |", "|---|---|---|---|---|---|"]
    for lib, rs in sorted(checked.items()):
        for r in rs:
            q = r["q_check"]
            lines.append(f"| {lib} | {r['seed']} | {q['max_scalarized_q']:.1f} | {q['max_mean_scalarized_q']:.1f} | "
                         f"{'max' if q['exceeds_bound'] else 'no'}{', mean' if q.get('mean_exceeds_bound') else ''} | "
                         f"{r['curve'][-1].get('hv_ratio', float('nan')):.3f} |")
        above = sum(bool(r["q_check"]["exceeds_bound"]) for r in rs)
        lines_mean = sum(bool(r["q_check"].get("mean_exceeds_bound")) for r in rs)
        lines.append(f"| {lib} | seeds above | {above} of {len(rs)} | {lines_mean} of {len(rs)} | | |")
    return lines + [""]


def _values(rs: list[dict], metric: str) -> tuple[list[float] | None, list[float]]:
    """``(frame-0 values or None where a run lacks its frame-0 point, final values)``, by seed."""
    rs = sorted(rs, key=lambda r: r["seed"])
    final = [r["curve"][-1][metric] for r in rs]
    start = [r["curve"][0][metric] for r in rs if r["curve"] and r["curve"][0]["frames"] == 0]
    return (start if len(start) == len(rs) else None), final


def verdict_runs(runs: dict[str, list[dict]], seeds: list[int]) -> tuple[dict[str, list[dict]], str]:
    """The runs a case's verdict is computed from, and which seeds those are: the round's ``seeds`` where both
    libraries have at least 2 of them (the seed rule: a round's seeds are fixed before running); otherwise every
    seed run (a case not run in this round keeps the verdict of the seeds it has). Every seed stays in the tables."""
    chosen = {lib: [r for r in rs if r["seed"] in seeds] for lib, rs in runs.items()}
    if all(len(chosen.get(lib, [])) >= 2 for lib in ("ours", "mb")):
        runs = chosen
    used = sorted({r["seed"] for rs in runs.values() for r in rs})
    text = ("none" if not used else str(used[0]) if len(used) == 1 else f"{used[0]}-{used[-1]}"
            if used == list(range(used[0], used[-1] + 1)) else ", ".join(map(str, used)))
    return runs, text


def case_verdict(runs: dict[str, list[dict]], metric: str = "hypervolume") -> str:
    """:func:`verdict.verdict` of ours against MB on ``metric``, each seed's frame-0 and final values paired
    (a library without a frame-0 evaluation in every run: "no frame-0 evaluation")."""
    (o0, o1), (m0, m1) = _values(runs["ours"], metric), _values(runs["mb"], metric)
    return verdict(o0, o1, m0, m1, higher_is_better=metric != "igd")


def library_learning(rs: list[dict], metric: str = "hypervolume") -> str:
    """:func:`verdict.learning` of one library's runs on ``metric`` (does it learn at this budget on its own)."""
    start, final = _values(rs, metric)
    return learning(start, final, higher_is_better=metric != "igd")


# ---------------------------------------------------------------------- main
def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", default=",".join(CASES))
    p.add_argument("--seeds", default=None, help="e.g. 0-4 or 100,101 (default: --round's seeds)")
    p.add_argument("--round", type=int, default=2,
                   help="the seed rule's round (verdict.round_seeds, fixed before running, never used for tuning): "
                        "1 -> seeds 0-4 (issue 29), 2 -> 100-104 (issue 48, the default)")
    p.add_argument("--libs", default="mb,ours")
    p.add_argument("--out", type=Path, default=HERE / "results")
    p.add_argument("--mb-venv", type=Path, default=Path.home() / ".cache" / "morl_trl" / f"mb-{MB_VERSION}")
    p.add_argument("--report-only", action="store_true")
    p.add_argument("--mb-venv-only", action="store_true",
                   help="make (or complete) MB's venv in --mb-venv and exit: what bench_losses / bench_train use")
    p.add_argument("--round-seeds", type=int, default=2, help="seeds per round (see main)")
    p.add_argument("--nice", type=int, default=15, help="niceness of each run (0: none)")
    p.add_argument("--no-report", action="store_true",
                   help="run only: no RESULTS.md or plots after each case (--report-only makes them later)")
    p.add_argument("--one", nargs=4, metavar=("LIB", "CASE", "SEED", "OUT"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.one:  # LIB CASE SEEDS OUT_DIR: several seeds in one process (the imports are paid once)
        lib, case, seed_list, out = args.one
        for seed in (int(x) for x in seed_list.split(",")):
            path = result_path(Path(out), case, lib, seed)
            if not path.exists():
                run_ours(case, seed, path)
        return 0
    if args.mb_venv_only:
        print(ensure_mb_venv(args.mb_venv))
        return 0
    seeds, cases = (_seeds(args.seeds) if args.seeds else round_seeds(args.round)), args.cases.split(",")
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        raise SystemExit(f"unknown case(s) {unknown}; runnable: {list(CASES)}; not yet: {PENDING}")
    command = "python benchmarks/parity/run_parity.py " + " ".join(argv if argv is not None else sys.argv[1:])
    if not args.report_only:
        env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
        mb_python = ensure_mb_venv(args.mb_venv) if "mb" in args.libs.split(",") else None
        # seeds in rounds of --round-seeds, every case in each round before the next round: all cases get
        # their first seeds first. Within a case both libraries run at once, each in one process over the
        # round's seeds, so that their frames/s are measured under the same load.
        libs = args.libs.split(",")
        rounds = [seeds[i:i + args.round_seeds] for i in range(0, len(seeds), args.round_seeds)]
        nice = ["nice", "-n", str(args.nice)] if args.nice else []
        for seeds_now in rounds:
            for case in cases:
                procs = []
                for lib in libs:
                    todo = [s for s in seeds_now if not result_path(args.out, case, lib, s).exists()]
                    if not todo:
                        continue
                    arg = ",".join(map(str, todo))
                    cmd = nice + ([str(mb_python), str(HERE / "mb_runner.py"), case, arg, str(args.out)] if lib == "mb"
                                  else [sys.executable, str(HERE / "run_parity.py"), "--one", lib, case, arg, str(args.out)])
                    log = args.out / case / f"{lib}.log"
                    log.parent.mkdir(parents=True, exist_ok=True)
                    print(f"run {lib} {case} seeds {arg} (log {log})", flush=True)
                    procs.append((lib, todo, time.perf_counter(), subprocess.Popen(cmd, env=env, stdout=open(log, "a"),
                                                                                   stderr=subprocess.STDOUT, cwd=log.parent)))
                for lib, todo, t, proc in procs:
                    rc = proc.wait()
                    print(f"  {lib} {case} seeds {todo}: {'done' if rc == 0 else f'FAILED (exit {rc})'} "
                          f"in {time.perf_counter() - t:,.0f} s", flush=True)
                if not args.no_report:
                    write_results(args.out, seeds, command)
    if args.no_report and not args.report_only:
        return 0
    print(write_results(args.out, seeds, command))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
