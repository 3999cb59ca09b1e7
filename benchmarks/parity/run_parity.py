"""Parity with MORL-Baselines: ours and MB 1.3.0 on the same env, hyperparameters, networks,
frame budget and evaluation; learning curves, final IQM with bootstrap CIs, frames/s.

    python benchmarks/parity/run_parity.py                       # every runnable case, this round's seeds (100-104)
    python benchmarks/parity/run_parity.py --cases gpi_ls-dst --round 1 --libs ours,mb   # round 1's seeds, 0-4
    python benchmarks/parity/run_parity.py --report-only         # RESULTS.md + PNGs from what is done
    python benchmarks/parity/run_parity.py --report-only --commit SHA   # ... from one commit's runs (others listed)
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
import contextlib
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

from common import (CASES, EVAL_EPISODES, EVAL_WEIGHTS, MB_VERSION, PENDING, REFERENCES, QEstimateLog,  # noqa: E402
                    SET_ASIDE, best_floor, case_eval_weights, case_floor, case_metric, context_means, current_commit,
                    made_at, paper_floor, reference_of, result_path, set_aside, short_commit, write_result)
from verdict import ALPHA, INFORMATIVE, MARGIN_OF_GAIN, floor_words, learning, round_seeds, verdict  # noqa: E402

MB_DEPS = ["wandb", "cvxpy", "pycddlib==2.1.6", "sortedcontainers", "fire", "seaborn", "moviepy"]
#: what MB's modules import of MB_DEPS, by import name (its GPI-LS / GPI-PD: cdd, cvxpy, seaborn at module level)
MB_IMPORTS = ["morl_baselines", "wandb", "cvxpy", "cdd", "sortedcontainers", "fire", "seaborn", "moviepy"]
# per-case findings written under the case's table (what learned, why the libraries differ)
NOTES: dict[str, str] = {}
METRICS = (("hypervolume", "hypervolume"), ("eum", "EUM"), ("igd", "IGD"), ("hv_ratio", "HV / true front's HV"),
           ("nhgr", "NHGR"), ("normalized_hypervolume", "normalized HV"),
           ("sorl_return_max", "f_SORL return (best of the evaluation's episodes)"))
#: how a case's metric is named in the summary and the plots (a paper-domain case's: the mean over its contexts)
METRIC_NAMES = {"hypervolume": "hypervolume", "nhgr": "NHGR (mean over the paper's contexts)",
                "sorl_return_max": "f_SORL return (the original scalar reward, best of the evaluation's 16 episodes)"}


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


class FixedPreferencePolicy:
    """``policy`` acting with ``weight`` as its preference whatever the evaluation weight (restored in the output):
    a preference-conditioned policy trained for one fixed weight, evaluated as MB's single-policy learners are
    (their ``eval(obs, w)`` ignores ``w``)."""

    def __init__(self, policy, weight) -> None:
        import torch

        self.policy, self.weight = policy, torch.as_tensor(weight, dtype=torch.float32)

    def __call__(self, td):
        given = td.get("preference")
        td.set("preference", self.weight.to(given.device).expand_as(given).clone())
        out = self.policy(td)
        out.set("preference", given)
        return out


@contextlib.contextmanager
def fixed_preference(weight):
    """Our actor-critic loop (``algorithms.actor_critic.recipe``: CAPQL, MOSAC, SAC) trained and evaluated for one
    fixed ``weight`` (``None``: as it is): the training env's :class:`~morl_trl.transforms.PreferenceConditioning`
    gives every episode ``weight`` (its ``"cycle"`` mode over the one-row weight set ``[weight]``, instead of a
    Dirichlet draw), and the evaluator's policy reads ``weight`` (:class:`FixedPreferencePolicy`). What a case with
    ``weight`` runs, so that ours solves the task of MB's fixed-weight MOSAC; the library has no such key."""
    if weight is None:
        yield
        return
    import torch

    from morl_trl.algorithms.actor_critic import recipe
    from morl_trl.preferences import check_simplex
    from morl_trl.transforms.preference import PreferenceConditioning

    make_env, make_evaluator = recipe.make_training_env, recipe.make_evaluator
    rows = torch.as_tensor([weight], dtype=torch.float32)

    def fixed_env(cfg, device):
        env = make_env(cfg, device)
        found = [t for t in getattr(env.transform, "transforms", [env.transform]) if isinstance(t, PreferenceConditioning)]
        if len(found) != 1:
            raise RuntimeError(f"fixed_preference: expected one PreferenceConditioning in the training env, found {found}")
        found[0].mode, found[0].weights = "cycle", check_simplex(rows, found[0].num_objectives, name="weight set")
        return env

    def fixed_evaluator(cfg, agent, spec, reference=None):
        ev = make_evaluator(cfg, agent, spec, reference)
        ev.policy = FixedPreferencePolicy(ev.policy, rows[0])
        return ev

    recipe.make_training_env, recipe.make_evaluator = fixed_env, fixed_evaluator
    try:
        yield
    finally:
        recipe.make_training_env, recipe.make_evaluator = make_env, make_evaluator


def run_ours(case_name: str, seed: int, out: Path) -> None:
    import tempfile

    import torch

    import morl_trl
    from morl_trl.evaluation import MultiContextEvaluator

    case = CASES[case_name]
    torch.set_num_threads(1)
    eval_seconds, eval_cpu = [0.0], [0.0]
    evaluate = MultiContextEvaluator.evaluate

    qlog = QEstimateLog() if case["algo"] == "envelope" else None

    def timed(self, *args, **kwargs):  # training time = wall time minus the evaluations
        t, c = time.perf_counter(), time.process_time()
        try:
            return evaluate(self, *args, **kwargs)
        finally:
            eval_seconds[0] += time.perf_counter() - t
            eval_cpu[0] += time.process_time() - c
            if qlog is not None:
                qlog.mark(-1)  # (the frames are the curve's, filled in below)

    from morl_trl.runs.run import Run

    started = [None]
    start = Run.start

    def start_clock(self, *args, **kwargs):  # training time starts once env, agent and collector are built
        out = start(self, *args, **kwargs)
        started[0] = (time.perf_counter(), time.process_time())
        return out

    from morl_trl.objectives.envelope import EnvelopeQLoss

    q_values = EnvelopeQLoss._q_values

    def logged_q_values(self, data, w, params):  # the online forward the loss's gradient goes through
        q = q_values(self, data, w, params)
        if params is self.value_network_params and torch.is_grad_enabled():
            qlog.record(w, q)
        return q

    from morl_trl.data.episode_replay import EpisodeReplay

    top_commands = EpisodeReplay.top_commands

    def side_effect_free_top_commands(self, n):
        # PCN's evaluation ranks the replay's episodes with nlargest, which stores the ranking as the priorities
        # (as MB's PCN.evaluate -> _nlargest does): an evaluation between two adds then changes which episode the
        # next add evicts. MB's runner puts MB's replay back after its evaluation (mb_runner._pcn_policy); the same
        # here, so that neither library's training depends on when the benchmark evaluates it
        saved = self.priority.clone()
        try:
            return top_commands(self, n)
        finally:
            self.priority = saved

    from morl_trl.runs.run_log import RunLog

    report = RunLog.report
    paper = bool(case.get("paper"))

    def no_report(self, *args, **kwargs):  # (a paper-domain run's report.md computes the floor: the harness does, once)
        return None

    MultiContextEvaluator.evaluate, Run.start = timed, start_clock
    EpisodeReplay.top_commands = side_effect_free_top_commands
    if paper:
        RunLog.report = no_report
    if qlog is not None:
        EnvelopeQLoss._q_values = logged_q_values
    try:
        with tempfile.TemporaryDirectory() as tmp, fixed_preference(case.get("weight")):
            frames, eval_every, scale = ours_budget(case)
            extra_cfg = dict(history_len=case["history_len"]) if paper else {}
            run = morl_trl.train(case["algo"], env=case["env"], seed=seed, frames=frames,
                                 eval_interval=eval_every, eval_weights=case_eval_weights(case),
                                 eval_episodes=EVAL_EPISODES, gamma=case["gamma"], eval_random_baseline=False,
                                 progress=False, run_dir=f"{tmp}/run", **extra_cfg, **case["ours"])
            wall, cpu = time.perf_counter() - started[0][0], time.process_time() - started[0][1]
            with open(Path(run.run_dir) / "eval" / "metrics.csv") as fh:
                curve = curve_from_rows(list(csv.DictReader(fh)))
            for point in curve:
                point["frames"] *= scale
    finally:
        MultiContextEvaluator.evaluate, Run.start, EnvelopeQLoss._q_values = evaluate, start, q_values
        EpisodeReplay.top_commands = top_commands
        RunLog.report = report
    train_s = wall - eval_seconds[0]  # (the evaluation at frame 0 runs after start: it is subtracted too)
    train_cpu = cpu - eval_cpu[0]  # (this process's CPU time: one torch thread)
    frames = int(curve[-1]["frames"])
    extra = {"pcn_eval_priorities_restored": True} if case["algo"] == "pcn" else {}
    if qlog is not None:
        if len(qlog.points) == len(curve):
            for point, row in zip(qlog.points, curve):
                point["frames"] = int(row["frames"])
        extra["q_check"] = qlog.result(case["env"], case["gamma"])
    write_result(out, dict(case=case_name, lib="ours", seed=seed, version=f"morl_trl {morl_trl.__version__}",
                           curve=curve, frames=frames, train_seconds=train_s, eval_seconds=eval_seconds[0],
                           train_fps=frames / train_s, train_cpu_seconds=train_cpu,
                           train_fps_cpu=frames / train_cpu if train_cpu > 0 else None,
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
def _load(out: Path, case: str, commit: str | None = None) -> tuple[dict[str, list[dict]], list[tuple[dict, str]]]:
    """A case's runs for its tables, by library, and the runs they leave out with where each is: those under
    ``earlier/`` and ``superseded/`` (:data:`common.SET_ASIDE`) and, with ``commit``, those made at another."""
    runs: dict[str, list[dict]] = {}
    left_out: list[tuple[dict, str]] = []
    for path in sorted((out / case).glob("*.json")):
        data = json.loads(path.read_text())
        if commit is None or made_at(data, commit):
            runs.setdefault(data["lib"], []).append(data)
        else:
            left_out.append((data, "another commit"))
    for folder in SET_ASIDE:
        for path in sorted((out / case / folder).glob("*.json")):
            data = json.loads(path.read_text())
            data["_mtime"] = path.stat().st_mtime  # (which of a seed's set-aside runs is the latest)
            left_out.append((data, f"`{folder}/`"))
    return runs, left_out


def _metric_name(metric: str) -> str:
    """A metric's short name on the page (:data:`METRICS`' label without its explanation: "NHGR", "f_SORL return")."""
    return dict(METRICS).get(metric, metric).split(" (")[0]


def left_out_lines(left_out: list[tuple[dict, str]], metric: str) -> list[str]:
    """The runs a case's tables do not use, one row each (none dropped from the page)."""
    if not left_out:
        return []
    name = _metric_name(metric)
    lines = ["Runs not in these tables (set aside under `earlier/` when their seed was run again at the page's commit, "
             "under `superseded/` when a library fix changed the method's trajectories, or made at another commit "
             "than `--commit`'s):", "", f"| library | seed | commit | frame 0 {name} | final {name} | where |",
             "|---|---|---|---|---|---|"]
    for r, where in sorted(left_out, key=lambda x: (x[0].get("lib", ""), x[0].get("seed", 0), x[0].get("commit", ""))):
        curve = r.get("curve") or [{}]
        first = curve[0].get(metric) if curve[0].get("frames") == 0 else None  # (no frame-0 evaluation: "-")
        last = curve[-1].get(metric)
        lines.append(f"| {r.get('lib', '?')} | {r.get('seed', '?')} | `{short_commit(str(r.get('commit', 'not recorded')))}` "
                     f"| {'-' if first is None else f'{first:.4g}'} | {'-' if last is None else f'{last:.4g}'} | {where} |")
    return lines + [""]


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
            name = "morl_trl (ours)" if lib == "ours" else REFERENCES.get(lib, lib)
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


def write_results(out: Path, seeds: list[int], command: str, compute_floors: bool = False,
                  commit: str | None = None, case_commits: dict[str, str] | None = None) -> Path:
    """RESULTS.md and the plots from the result files under ``out``; with ``commit``, the tables and verdicts use only
    the runs made at that commit (clean), and every other run is listed under its case. ``case_commits``
    (``{case: SHA}``, with ``commit``): those cases' tables use their own commit's runs instead, each case's still
    from one commit (after a library change that touches some methods only, their cases run again at it)."""
    case_commits = dict(case_commits or {})
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
               "loops on the same env and budget; in brackets the same ratio of frames per CPU-second of the training "
               "process, which the machine's load moves less than wall time, where every run of both recorded it).", "",
               "The verdict is computed on the round's seeds "
               f"({', '.join(map(str, seeds))}: `verdict.round_seeds`) where both libraries have at least 2 of them, "
               "else on every seed run (the seeds used are named); every seed run is in the case's tables. "
               "ref.: the reference, MORL-Baselines unless the case names another (`case (ref.: LIBRARY)`: "
               + "; ".join(f"`{k}` {v}" for k, v in REFERENCES.items() if k != "mb") + "). "
               "ref. learns: whether the reference learns on its own at the case's budget (the same paired test, on "
               "the verdict's seeds: mean gain of final - frame-0 hypervolume, one-sided p); a case whose reference "
               "does not learn says nothing about ours. Trivial floor: the best hypervolume of the trivial policies "
               "(the random policy and every constant action; continuous actions: the zero action) under the same "
               "evaluation at each verdict seed (`common.case_floor`, cached under `results/<case>/floor/`), "
               "mean over those seeds, and the policy that gives it most often: under this protocol (16 weights x 1 "
               "episode, the front of all returns) a random policy's spread of returns is itself a front, and a "
               "constant action can hold an objective's best value (the zero action's control cost). vs the floor: "
               f"the same paired test on final - floor per library (`verdict.above_floor`, p < {ALPHA}); a case "
               "whose reference learns but stays below the floor shows learning, not a useful policy.", "",
               "| case | seeds ours / ref. | final HV ours | final HV ref. | verdict | ref. learns | trivial floor "
               "| ours / ref. vs the floor | frames/s ours | frames/s ref. | ours / ref. |",
               "|---|---|---|---|---|---|---|---|---|---|---|"]
    per_method: dict[str, list[tuple[str, str]]] = {}
    ref_learns_by_case: dict[str, str] = {}
    commits: dict[str, int] = {}
    n_left_out = 0
    body = []
    page_commit = commit
    for case in CASES:
        commit = case_commits.get(case, page_commit)
        runs, left_out = _load(out, case, commit)
        n_left_out += len(left_out)
        for rs in runs.values():
            for r in rs:
                commits[r.get("commit", "not recorded")] = commits.get(r.get("commit", "not recorded"), 0) + 1
        spec = CASES[case]
        ref = reference_of(spec)
        row_name = case if ref == "mb" else f"{case} (ref.: {ref})"
        theirs = (f"MB: `{spec['mb']}`" + (f", MB train(): `{spec['mb_train']}`" if spec["mb_train"] else "")
                  if ref == "mb" else f"reference {REFERENCES.get(ref, ref)}: `{spec.get('ref', {})}`")
        body += [f"## {case}", "",
                 f"`{spec['algo']}` on `{spec['env']}`, {spec['frames']:,} frames, evaluated every "
                 f"{spec['eval_every']:,}, gamma {spec['gamma']}"
                 + (f", one fixed weight {[round(w, 4) for w in spec['weight']]}" if spec.get("weight") else "")
                 + f"; ours: `{spec['ours']}`, {theirs}", ""]
        done = {lib: sorted(r["seed"] for r in rs) for lib, rs in runs.items()}
        if not runs:
            body += ["Not run yet" + (f" at `{commit}`." if commit else "."), ""] + left_out_lines(left_out, case_metric(spec))
            said = "-"
            # what the runs of other commits said (not a verdict of this page): one run per (library, seed), the
            # one left in the case's folder, else the latest set aside under earlier/ (superseded/ ones: not read)
            latest: dict[tuple[str, int], dict] = {}
            for r, where in sorted(left_out, key=lambda x: (x[1] == "another commit", x[0].get("_mtime", 0.0))):
                if where != "`superseded/`":
                    latest[(r["lib"], r["seed"])] = r
            others: dict[str, list[dict]] = {}
            for (lib, _), r in sorted(latest.items()):
                others.setdefault(lib, []).append(r)
            if commit:
                said = f"not run at `{commit}`"
                if "ours" in others and ref in others:
                    judged, used = verdict_runs(others, seeds, ref)
                    said += (f" (other commits' runs, seeds {used}: "
                             f"{case_verdict(judged, case_metric(spec), ref=ref)})")
                per_method.setdefault(spec["algo"], []).append((case, said))
            summary.append(f"| {row_name} | 0 / 0 | - | - | {said} | - | - | - | - | - | - |")
            continue
        machines = sorted({r.get("machine", "not recorded") for rs in runs.values() for r in rs})
        body += ["Seeds done: " + ", ".join(f"{lib} {s}" for lib, s in sorted(done.items()))
                 + f" (target: {len(seeds)} per library); machine: " + "; ".join(machines), ""]
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
        fps, fps_cpu = {}, {}
        for lib, rs in sorted(runs.items()):
            cpu = [r["train_fps_cpu"] for r in rs if r.get("train_fps_cpu")]
            if cpu and len(cpu) == len(rs):  # (runs made before 2026-12-02's fourth sitting recorded wall time only)
                fps_cpu[lib] = sum(cpu) / len(cpu)
            # the first runs of ours (marked build_in_train_seconds) also timed building env, agent and
            # collector: left out of the mean when others exist
            timed = ([r for r in rs if r.get("train_fps") and not r.get("build_in_train_seconds")]
                     or [r for r in rs if r.get("train_fps")])
            if timed:
                fps[lib] = sum(r["train_fps"] for r in timed) / len(timed)
        body += ["| training frames/s (mean) | " + " | ".join(f"{lib} {v:,.0f}" for lib, v in fps.items()) + " |"]
        cost = {lib: [r["train_seconds"] + r.get("eval_seconds", 0.0) for r in rs if r.get("train_seconds") is not None]
                for lib, rs in sorted(runs.items())}
        if any(cost.values()):  # what a seed costs to run (the note's "what each run cost in time")
            body += ["| a run's time, training + evaluations (mean over seeds [min, max]) | " + " | ".join(
                f"{lib} {sum(c) / len(c):,.0f} s [{min(c):,.0f}, {max(c):,.0f}]" if c else "-" for lib, c in cost.items())
                + " |"]
        if fps_cpu:
            body += ["| training frames per CPU-second (mean) | "
                     + " | ".join(f"{lib} {fps_cpu[lib]:,.0f}" if lib in fps_cpu else "-" for lib in sorted(runs)) + " |"]
        body += [""]
        body += q_check_lines(runs)
        floor = paper_floor(case, out) if spec.get("paper") else None
        body += floor_lines(spec, runs, floor)
        body += left_out_lines(left_out, metric_of_case)
        png = out.parent / f"{case}.png"
        _plot(case, runs, png, floor)
        body += [f"![{case}]({png.name})", ""]
        if case in NOTES:
            body += [NOTES[case], ""]
        if metric_of_case == "hypervolume":
            hv = {lib: f"{m:.2f} [{lo:.2f}, {hi:.2f}]" for lib, (m, lo, hi) in ci.items()}
        else:  # (a paper-domain case: its metric named, beside the floor of trivial policies)
            beside = f", floor {floor['mean']:.3f}" if floor else ""
            hv = {lib: f"{m:.3f} [{lo:.3f}, {hi:.3f}] {_metric_name(metric_of_case)}{beside}" for lib, (m, lo, hi) in ci.items()}
        judged, used = verdict_runs(runs, seeds, ref)
        judged_seeds = sorted({r["seed"] for rs in judged.values() for r in rs})
        if spec.get("paper"):  # (the paper protocol's floor: one per case, the same at every seed)
            floors = ({} if floor is None else
                      {s: {"policies": {floor["policy"]: {metric_of_case: floor["mean"]}}} for s in judged_seeds})
        else:
            floors = load_floors(out, case, judged_seeds, compute_floors)
        said = case_verdict(judged, metric_of_case, ref=ref) if "ours" in runs and ref in runs else "-"
        if said != "-":
            n_used = min(len(judged["ours"]), len(judged[ref]))
            said += f" (seeds {used}" + (f"; < {len(seeds)} seeds" if n_used < len(seeds) else "") + ")"
        ref_learns = library_learning(judged[ref], metric_of_case) if ref in judged else "-"
        floor_said = [library_floor(judged.get(lib, []), floors, metric_of_case) for lib in ("ours", ref)]
        vs_floor = " / ".join(w or "-" for w in floor_said)
        short = [w.split(" the floor")[0] for w in floor_said]
        ref_name = "MB" if ref == "mb" else ref
        per_method.setdefault(spec["algo"], []).append(
            (case, said + (f" [vs the floor: ours {short[0]}, {ref_name} {short[1]}]" if all(short) else "")))
        ref_learns_by_case[case] = ref_learns
        ratio = f"{fps['ours'] / fps[ref]:.2f}x" if "ours" in fps and ref in fps else "-"
        if "ours" in fps_cpu and ref in fps_cpu:
            ratio += f" (CPU: {fps_cpu['ours'] / fps_cpu[ref]:.2f}x)"
        summary.append(f"| {row_name} | {len(done.get('ours', []))} / {len(done.get(ref, []))} | {hv.get('ours', '-')} "
                       f"| {hv.get(ref, '-')} | {said} | {ref_learns} | {floor_cell(floors, judged_seeds, metric_of_case)} "
                       f"| {vs_floor} | {_num(fps.get('ours'))} | {_num(fps.get(ref))} "
                       f"| {ratio} |")
    methods = ["## Verdicts per method", "",
               "A case counts as evidence of learning only where at least one library learns at its budget; "
               "the reference learns in the cases listed under \"ref. learns\". In brackets: whether each library's "
               "final values beat the trivial policies' floor (see the summary).", "",
               "| method | informative cases | ref. learns | every case |", "|---|---|---|---|"]
    for algo, cases in per_method.items():
        good = [f"{c}: {v}" for c, v in cases if v.split(" (")[0] in INFORMATIVE]
        ref = [c for c, _ in cases if ref_learns_by_case.get(c, "").startswith("learns")]
        methods.append(f"| {algo} | {'; '.join(good) or 'none'} | {', '.join(ref) or 'none'} | "
                       + "; ".join(f"{c}: {v}" for c, v in cases) + " |")
    commit = page_commit
    made = ", ".join(f"`{c}` ({n} files)" for c, n in sorted(commits.items(), key=lambda kv: (-kv[1], kv[0])))
    lines += [f"Results in the tables made by: {made or 'none yet'}"
              + (" -- **more than one commit: regenerate from one commit's runs before quoting**"
                 if len(commits) > 1 and not case_commits else ""), ""]
    if commit:
        own = "; ".join(f"`{c}` at `{sha}`" for c, sha in sorted(case_commits.items()))
        lines += [f"Only the runs made at `{commit}` (from a clean checkout) are in the tables and verdicts "
                  f"(`--commit`)" + (f", but for the cases run again at a later commit, each from that commit's runs "
                                     f"only (`--case-commit`): {own}" if own else "")
                  + f"; the {n_left_out} other runs are listed under their cases.", ""]
    elif n_left_out:
        lines += [f"{n_left_out} runs set aside (`earlier/`, `superseded/`) are listed under their cases, not used.", ""]
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
    """A paper-domain case's metric beside the floor of trivial policies (``common.paper_floor``): per library the
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


def verdict_runs(runs: dict[str, list[dict]], seeds: list[int], ref: str = "mb") -> tuple[dict[str, list[dict]], str]:
    """The runs a case's verdict is computed from, and which seeds those are: the round's ``seeds`` where both
    libraries have at least 2 of them (the seed rule: a round's seeds are fixed before running); otherwise every
    seed run (a case not run in this round keeps the verdict of the seeds it has). Every seed stays in the tables."""
    chosen = {lib: [r for r in rs if r["seed"] in seeds] for lib, rs in runs.items()}
    if all(len(chosen.get(lib, [])) >= 2 for lib in ("ours", ref)):
        runs = chosen
    used = sorted({r["seed"] for rs in runs.values() for r in rs})
    text = ("none" if not used else str(used[0]) if len(used) == 1 else f"{used[0]}-{used[-1]}"
            if used == list(range(used[0], used[-1] + 1)) else ", ".join(map(str, used)))
    return runs, text


def floor_values(rs: list[dict], floors: dict[int, dict] | None, metric: str = "hypervolume") -> list[float] | None:
    """The trivial policies' best ``metric`` at each run's seed (the runs in seed order, as :func:`_values`), or
    ``None`` where a seed's floor is not computed (then no floor is read for that library)."""
    if not floors:
        return None
    out = []
    for r in sorted(rs, key=lambda r: r["seed"]):
        best = best_floor(floors[r["seed"]], metric) if r["seed"] in floors else None
        if best is None:
            return None
        out.append(best[1])
    return out


def case_verdict(runs: dict[str, list[dict]], metric: str = "hypervolume", ref: str = "mb") -> str:
    """:func:`verdict.verdict` of ours against the reference ``ref`` (MB unless the case names another) on
    ``metric``, each seed's frame-0 and final values paired (a library without a frame-0 evaluation in every run:
    "no frame-0 evaluation")."""
    (o0, o1), (m0, m1) = _values(runs["ours"], metric), _values(runs[ref], metric)
    return verdict(o0, o1, m0, m1, higher_is_better=metric != "igd")


def library_learning(rs: list[dict], metric: str = "hypervolume") -> str:
    """:func:`verdict.learning` of one library's runs on ``metric`` (does it learn at this budget on its own)."""
    start, final = _values(rs, metric)
    return learning(start, final, higher_is_better=metric != "igd")


def library_floor(rs: list[dict], floors: dict[int, dict] | None, metric: str = "hypervolume") -> str:
    """:func:`verdict.floor_words` of one library's final values against the trivial floor at their seeds."""
    return floor_words(_values(rs, metric)[1], floor_values(rs, floors, metric)) if rs else ""


def load_floors(out: Path, case: str, seeds: list[int], compute: bool) -> dict[int, dict]:
    """The case's floor records for ``seeds`` (seed -> :func:`common.case_floor`), computed where missing when
    ``compute``."""
    got = {s: case_floor(out, case, s, compute=compute) for s in seeds}
    return {s: f for s, f in got.items() if f is not None}


def floor_cell(floors: dict[int, dict], seeds: list[int], metric: str = "hypervolume") -> str:
    """The floor's mean over ``seeds`` and which trivial policy gives it most often, for the tables."""
    best = [best_floor(floors[s], metric) for s in seeds if s in floors]
    best = [b for b in best if b is not None]
    if not best or len(best) < len(seeds):
        return "-"
    names = [n for n, _ in best]
    top = max(set(names), key=names.count)
    return f"{sum(v for _, v in best) / len(best):.2f} ({top})"


# ---------------------------------------------------------------------- main
#: the runner of each reference library other than MB (a script taking CASE SEEDS OUT_DIR, run in our python)
REFERENCE_RUNNERS = {"torchrl_sac": HERE / "torchrl_sac_runner.py"}


def runner_command(lib: str, case: str, seeds: str, out: Path, mb_python: Path | None) -> list[str]:
    """The command that runs ``lib``'s seeds ``seeds`` (``"100,101"``) of ``case`` into ``out``: ours through
    ``--one``, MB's runner in its venv, another reference's runner (:data:`REFERENCE_RUNNERS`) in our python."""
    if lib == "mb":
        if mb_python is None:
            raise SystemExit(f"{case}: MB's runs need its venv (--mb-venv)")
        return [str(mb_python), str(HERE / "mb_runner.py"), case, seeds, str(out)]
    if lib in REFERENCE_RUNNERS:
        return [sys.executable, str(REFERENCE_RUNNERS[lib]), case, seeds, str(out)]
    if lib != "ours":
        raise SystemExit(f"{case}: no runner for library {lib!r} (ours, mb, {', '.join(REFERENCE_RUNNERS)})")
    return [sys.executable, str(HERE / "run_parity.py"), "--one", lib, case, seeds, str(out)]

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
    p.add_argument("--no-floors", action="store_true",
                   help="do not evaluate the trivial policies' floors missing from the cache (the verdict of a seed "
                        "without one compares with frame 0 only)")
    p.add_argument("--mb-venv-only", action="store_true",
                   help="make (or complete) MB's venv in --mb-venv and exit: what bench_losses / bench_train use")
    p.add_argument("--round-seeds", type=int, default=2, help="seeds per round (see main)")
    p.add_argument("--nice", type=int, default=15, help="niceness of each run (0: none)")
    p.add_argument("--no-report", action="store_true",
                   help="run only: no RESULTS.md or plots after each case (--report-only makes them later)")
    p.add_argument("--commit", default=None, metavar="SHA",
                   help="one commit's runs: the report's tables and verdicts use only the runs made at SHA (the others "
                        "are listed under their cases); a run needs this checkout at SHA, clean, and runs again each "
                        "asked-for seed whose file another commit made (that file set aside under earlier/)")
    p.add_argument("--case-commit", action="append", default=[], metavar="CASE=SHA",
                   help="with --commit and --report-only: CASE's tables use the runs made at SHA instead (repeatable; "
                        "each case's runs still from one commit)")
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
    if args.commit is not None and (len(args.commit) < 7 or any(c not in "0123456789abcdef" for c in args.commit)):
        raise SystemExit(f"--commit {args.commit!r}: give at least 7 lowercase hex digits of a SHA (git rev-parse HEAD)")
    case_commits = {}
    for item in args.case_commit:
        case, _, sha = item.partition("=")
        if not (args.commit and args.report_only) or case not in CASES or len(sha) < 7 \
                or any(c not in "0123456789abcdef" for c in sha):
            raise SystemExit(f"--case-commit {item!r}: give CASE=SHA (a case of {list(CASES)}, 7+ lowercase hex "
                             "digits), with --commit and --report-only")
        case_commits[case] = sha
    if args.commit and not args.report_only:
        here = current_commit()
        if here.endswith("+dirty") or not made_at({"commit": here}, args.commit):
            raise SystemExit(f"--commit {args.commit}: this checkout is at {here}; run from a clean checkout of that "
                             f"commit (git worktree add DIR {args.commit}) with --out pointing at these results")
    if not args.report_only:
        env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
        # --libs names "ours" and "mb" (or "ref"): the case's reference, MB unless the case names another
        # (reference_of: e.g. torchrl_sac, run by its own runner in our python)
        libs = args.libs.split(",")
        needs_mb = any(reference_of(CASES[c]) == "mb" for c in cases) and ({"mb", "ref"} & set(libs))
        mb_python = ensure_mb_venv(args.mb_venv) if needs_mb else None
        # seeds in rounds of --round-seeds, every case in each round before the next round: all cases get
        # their first seeds first. Within a case both libraries run at once, each in one process over the
        # round's seeds, so that their frames/s are measured under the same load.
        rounds = [seeds[i:i + args.round_seeds] for i in range(0, len(seeds), args.round_seeds)]
        nice = ["nice", "-n", str(args.nice)] if args.nice else []
        for seeds_now in rounds:
            for case in cases:
                procs = []
                for lib in dict.fromkeys(reference_of(CASES[case]) if lib in ("mb", "ref") else lib for lib in libs):
                    if args.commit:  # a seed another commit made runs again; its file is kept under earlier/
                        for s in seeds_now:
                            path = result_path(args.out, case, lib, s)
                            if path.exists() and not made_at(json.loads(path.read_text()), args.commit):
                                print(f"  {lib} {case} seed {s}: made at another commit, set aside as "
                                      f"{set_aside(path).relative_to(args.out)}", flush=True)
                    todo = [s for s in seeds_now if not result_path(args.out, case, lib, s).exists()]
                    if not todo:
                        continue
                    arg = ",".join(map(str, todo))
                    cmd = nice + runner_command(lib, case, arg, args.out, mb_python)
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
                    write_results(args.out, seeds, command, compute_floors=not args.no_floors, commit=args.commit)
    if args.no_report and not args.report_only:
        return 0
    print(write_results(args.out, seeds, command, compute_floors=not args.no_floors, commit=args.commit,
                        case_commits=case_commits))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
