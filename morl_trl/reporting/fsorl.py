"""The paper's "Scalar reward is not enough" analysis: f_SORL in run and grid reports.

f_SORL is a domain's original scalar reward (the one its SAC baseline trains on; the env's ``"original_reward"``,
:class:`~morl_trl.envs.SORLReward` says what it is in terms of the vector reward). At every evaluation the
evaluator records, per context, the f_SORL return of every evaluation weight's episode, the max over weights and
the weight that gave it (the run's ``eval/sorl.csv`` and the ``sorl_*`` columns of ``eval/metrics.csv``). This
module turns those files into:

* the run report's section (:func:`run_section`): f_SORL-max against frames per evaluation
  context (``report_fsorl.png``) and the table of best weights per context at the last
  evaluation (the paper's Fig. 4 table);
* the grid report's section (:func:`grid_section`): per domain, one panel per context with every method's
  f_SORL-max against frames (mean ± standard error over seeds) and SAC beside them (``report/fsorl_<domain>.png``,
  the paper's appendix figures), and the table of which methods beat SAC at the end and by how much (paired over
  seeds, bootstrap CI; ``report/fsorl_summary.csv``, :func:`sac_comparison`).

An env without an original scalar reward has no f_SORL: its section says so, once.

Example:
    >>> from morl_trl.reporting.fsorl import sac_comparison
    >>> finals = {"sac": {0: {"Room": 5.0}, 1: {"Room": 6.0}},
    ...           "morld": {0: {"Room": 10.0}, 1: {"Room": 12.0}}}
    >>> row = sac_comparison(finals, reps=2000)[0]
    >>> row.method, row.difference, row.ci, row.verdict
    ('morld', 5.5, (5.0, 6.0), 'beats SAC')
"""

from __future__ import annotations

import csv
import json
import math
import re
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["SacComparison", "grid_runs", "grid_section", "ignores_weights", "plot_domain", "run_section",
           "sac_comparison", "sorl_curves"]

#: why a context's discounted f_SORL max can exceed its undiscounted one (the run report says it under the table)
DISCOUNTED_NOTE = ("The discounted row can be the larger: γ^t shrinks late rewards, and where an episode ends in "
                   "penalties (a crash's -100, fuel, time) the discounted sum loses less of them; each row also "
                   "takes its own max over the weights (docs/fsorl.md).")

#: the algorithm that is the single-objective baseline (it ignores the weight)
BASELINE = "sac"


def ignores_weights(algo: str) -> bool:
    """Whether ``algo`` is the single-objective SAC baseline (its evaluation episodes differ only
    by chance, so its f_SORL max is the best of as many episodes as there are weights)."""
    return re.sub(r"[^a-z0-9]", "", algo.lower()) == BASELINE


def _short(context: str) -> str:
    return re.sub(r"-v\d+$", "", context)


def _labels(contexts: list[str]) -> dict[str, str]:
    """Short names: version and the domain's common prefix dropped (``"MOLavaGridRoom-v0"`` ->
    ``"Room"``), cut where every name goes on with a capital or a digit.

    Example:
        >>> list(_labels(["MOLunarLanderHighGravity-v0", "MOLunarLanderHard-v0"]).values())
        ['HighGravity', 'Hard']
    """
    names = [_short(c) for c in contexts]
    n = len(names[0]) if len(names) > 1 else 0
    for name in names[1:]:
        n = min(n, len(name))
        while name[:n] != names[0][:n]:
            n -= 1
    while n > 0 and not all(len(x) > n and (x[n].isupper() or x[n].isdigit()) for x in names):
        n -= 1
    return {c: x[n:].lstrip("-") or x for c, x in zip(contexts, names)}


def _formula(spec) -> str:
    """``f_SORL = ...`` as the paper writes it and, where it differs, as measured."""
    sorl = getattr(spec, "sorl", None)
    if sorl is None:
        return "f_SORL = the env's `original_reward` (the paper gives no formula for this domain)"
    if sorl.paper:
        text = f"f_SORL = {sorl.paper} (the paper's appendix)"
    else:
        text = "f_SORL = " + " + ".join(f"{w:g} {o}" for w, o in zip(sorl.weights, spec.objective_names) if w)
    return text + (f". Note: {sorl.note}" if sorl.note else "")


# ---------------------------------------------------------------------------------- reading
def sorl_curves(run_dir: str | Path, *, discounted: bool = False) -> dict[str, dict[int, float]]:
    """``{context: {frames: f_SORL max over weights}}`` of every evaluation of a run (its
    ``eval/metrics.csv``); empty when the run recorded no f_SORL."""
    path = Path(run_dir) / "eval" / "metrics.csv"
    column = "sorl_discounted_return_max" if discounted else "sorl_return_max"
    out: dict[str, dict[int, float]] = defaultdict(dict)
    if not path.is_file():
        return {}
    with path.open() as fh:
        for row in csv.DictReader(fh):
            value = row.get(column)
            if value in (None, "", "None"):
                continue
            out[row["context"]][int(float(row["frames"]))] = float(value)
    return dict(out)


def _final(curves: dict[str, dict[int, float]]) -> dict[str, float]:
    """``{context: value at the run's last evaluation}``."""
    return {c: pts[max(pts)] for c, pts in curves.items() if pts}


def grid_runs(grid_dir: str | Path) -> dict[str, dict[str, dict[int, Path]]]:
    """``{train_id: {algo: {seed: run_dir}}}`` of every run of a grid directory that has
    evaluated at least once (``runs/*/eval/metrics.csv``), finished or not."""
    from morl_trl.envs import domain_of

    out: dict = defaultdict(lambda: defaultdict(dict))
    for cfg_path in sorted(Path(grid_dir, "runs").glob("*/config.json")):
        run_dir = cfg_path.parent
        if not (run_dir / "eval" / "metrics.csv").is_file():
            continue
        cfg = json.loads(cfg_path.read_text())
        out[domain_of(cfg["env_id"]).train_id][cfg["algo"]][int(cfg["seed"])] = run_dir
    return {d: dict(a) for d, a in out.items()}


# ---------------------------------------------------------------------------------- the run report
def _plot_run(curves: dict[str, dict[int, float]], contexts: list[str], title: str, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = math.ceil(len(contexts) / 4)  # at most 4 panels a row, rows filled evenly (6 -> 2 x 3)
    cols = math.ceil(len(contexts) / rows)
    labels = _labels(contexts)
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 2.7 * rows + 0.4), squeeze=False)
    for k, (ax, c) in enumerate(zip(axes.flat, contexts)):
        pts = sorted(curves.get(c, {}).items())
        if pts:
            x, y = zip(*pts)
            ax.plot(x, y, marker="o", ms=3, lw=1.3, color="C0")
        ax.set_title(labels[c], fontsize=9)
        ax.tick_params(labelsize=7)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 4))
        if k % cols == 0:
            ax.set_ylabel("f_SORL return (max over weights)", fontsize=7)
        if k // cols == rows - 1:
            ax.set_xlabel("frames", fontsize=8)
    for ax in list(axes.flat)[len(contexts):]:
        ax.axis("off")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _fmt(v: float) -> str:
    return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.4g}"


def run_section(result, run_dir: str | Path, algo: str, spec=None, env_id: str = "") -> list[str]:
    """The f_SORL section of a run's ``report.md`` (Markdown lines; writes ``report_fsorl.png``).

    ``result`` is the run's last :class:`~morl_trl.evaluation.EvaluationResult`, ``run_dir`` the
    directory with its ``eval/metrics.csv``, ``spec`` the domain's
    :class:`~morl_trl.envs.DomainSpec` (``None`` for an env outside the registry)."""
    run_dir = Path(run_dir)
    lines = ["## f_SORL: the single-objective return (\"Scalar reward is not enough\")", ""]
    if not result.has_sorl:
        name = env_id or "this env"
        return lines + [f"No f_SORL: {name} emits no original scalar reward (`original_reward`), the reward "
                        "a single-objective agent would be trained on, so there is nothing to compare with.", ""]
    contexts = list(result.context_names)
    labels = _labels(contexts)
    W = len(result.weights)
    curves = sorl_curves(run_dir)
    best = result.sorl_best()
    baseline = ignores_weights(algo)
    lines += [_formula(spec).rstrip(".") + ".", ""]
    how = (f"the best of its {W} evaluation episodes per context (SAC ignores the weight)" if baseline else
           f"the max over the {W} evaluation weights' episodes per context")
    each = "episode" if baseline else "weight"
    lines += [f"The f_SORL return (undiscounted, the env's `original_reward` summed over the episode) is {how}, at "
              f"every evaluation (every {each}'s value: `eval/sorl.csv`).", ""]
    if curves:
        png = _plot_run(curves, contexts, f"{algo} on {env_id}: f_SORL max over {W} weights", run_dir /
                        "report_fsorl.png")
        lines += [f"![f_SORL max against frames per context]({png.name})", ""]
    frames = max(max(p) for p in curves.values()) if curves else None
    at = f" at {frames:,} frames" if frames is not None else ""
    lines += [f"f_SORL max per context{at} (undiscounted; discounted with γ = {result.gamma:g}):", ""]
    lines += ["| | " + " | ".join(labels[c] for c in contexts) + " |", "|---|" + "---|" * len(contexts)]
    lines.append("| f_SORL max | " + " | ".join(_fmt(best[c]["return_max"]) for c in contexts) + " |")
    lines.append("| discounted | " + " | ".join(_fmt(best[c]["discounted_return_max"]) for c in contexts) + " |")
    lines.append("")
    lines += [DISCOUNTED_NOTE, ""]
    if baseline:
        return lines + ["No table of best weights: SAC does not read the weight.", ""]
    lines += [f"The weight that gave each context's f_SORL max{at} (the paper's Fig. 4 table; the largest "
              "component in bold; the first weight on ties):", ""]
    lines += ["| objective | " + " | ".join(labels[c] for c in contexts) + " |", "|---|" + "---|" * len(contexts)]
    for o in result.objective_names:
        cells = []
        for c in contexts:
            w = best[c]["best_weight"]
            cell = f"{w[o]:.2f}"
            cells.append(f"**{cell}**" if w[o] == max(w.values()) else cell)
        lines.append(f"| {o} | " + " | ".join(cells) + " |")
    lines.append("| weight index | " + " | ".join(str(best[c]["best_weight_index"]) for c in contexts) + " |")
    lines.append("")
    if re.sub(r"[^a-z0-9]", "", algo.lower()) == "pcn":
        lines += ["PCN does not read the weight: evaluation weight i stands for command i (the return and length of "
                  "the i-th best replay episode, SPEC §2), so the table names commands, not trade-offs.", ""]
    return lines


# ---------------------------------------------------------------------------------- grid statistics
@dataclass
class SacComparison:
    """One method against SAC in one context, at the end of the runs.

    Attributes:
        context: the evaluation context.
        method: our algorithm name.
        mean, se: the method's final f_SORL max, mean and standard error over its seeds.
        seeds: its number of seeds.
        sac_mean, sac_se, sac_seeds: the same for SAC (``None`` without SAC runs).
        difference: mean over the seeds both have of (method - SAC).
        ci: 95% percentile bootstrap interval of that mean (``None`` with fewer than 2 paired seeds).
        paired: the number of seeds both have.
        verdict: ``"beats SAC"`` (the interval above 0), ``"below SAC"`` (under 0), ``"no
            clear difference"``, or why there is none.
    """

    context: str
    method: str
    mean: float
    se: float
    seeds: int
    sac_mean: float | None
    sac_se: float | None
    sac_seeds: int
    difference: float | None
    ci: tuple[float, float] | None
    paired: int
    verdict: str

    def as_dict(self) -> dict[str, object]:
        return {"context": self.context, "method": self.method, "mean": self.mean, "se": self.se,
                "seeds": self.seeds, "sac_mean": self.sac_mean, "sac_se": self.sac_se, "sac_seeds": self.sac_seeds,
                "difference": self.difference, "ci_low": None if self.ci is None else self.ci[0],
                "ci_high": None if self.ci is None else self.ci[1], "paired_seeds": self.paired,
                "verdict": self.verdict}


def _mean_se(values: list[float]) -> tuple[float, float]:
    a = np.asarray(values, dtype=np.float64)
    se = float(a.std(ddof=1) / math.sqrt(len(a))) if len(a) > 1 else 0.0
    return float(a.mean()), se


def sac_comparison(finals: dict[str, dict[int, dict[str, float]]], *, reps: int = 10_000,
                   confidence: float = 0.95, seed: int = 0) -> list[SacComparison]:
    """Which methods beat SAC on f_SORL, per context, and by how much.

    ``finals`` is ``{algo: {seed: {context: final f_SORL max}}}``. For every context and every
    method but SAC: its mean ± standard error over seeds, SAC's, and the difference paired by seed (the grid runs
    every method with the same seeds, and the seed also drives the evaluation) with a percentile bootstrap interval
    of its mean over the seeds both have (:func:`~morl_trl.metrics.stratified_bootstrap_ci`, one task).
    """
    from morl_trl.metrics import stratified_bootstrap_ci

    sac_algo = next((a for a in finals if ignores_weights(a)), None)
    sac = finals.get(sac_algo, {}) if sac_algo is not None else {}
    contexts = list(dict.fromkeys(c for by_seed in finals.values() for per in by_seed.values() for c in per))
    out = []
    for c in contexts:
        sac_vals = {s: per[c] for s, per in sac.items() if c in per}
        sac_mean, sac_se = _mean_se(list(sac_vals.values())) if sac_vals else (None, None)
        for algo, by_seed in finals.items():
            if algo == sac_algo:
                continue
            vals = {s: per[c] for s, per in by_seed.items() if c in per}
            if not vals:
                continue
            mean, se = _mean_se(list(vals.values()))
            common = sorted(set(vals) & set(sac_vals))
            diff, ci = None, None
            if not sac_vals:
                verdict = "no SAC runs"
            elif not common:
                verdict = "no seed in common with SAC"
            else:
                d = np.array([vals[s] - sac_vals[s] for s in common])
                diff = float(d.mean())
                if len(common) < 2:
                    verdict = "1 paired seed: no interval"
                else:
                    _, lo, hi = stratified_bootstrap_ci(d[:, None], "mean", reps=reps, confidence=confidence, seed=seed)
                    ci = (lo, hi)
                    verdict = "beats SAC" if lo > 0 else "below SAC" if hi < 0 else "no clear difference"
            out.append(SacComparison(c, algo, mean, se, len(vals), sac_mean, sac_se, len(sac_vals), diff, ci,
                                     len(common), verdict))
    return out


# ---------------------------------------------------------------------------------- grid figures
def _seed_curves(by_seed: dict[int, Path], contexts: list[str]):
    """``{context: (frames, [seeds, frames] values)}`` at the frames every seed evaluated."""
    curves = [sorl_curves(d) for d in by_seed.values()]
    out = {}
    for c in contexts:
        per = [cv.get(c, {}) for cv in curves]
        common = sorted(set.intersection(*(set(p) for p in per))) if per else []
        if common:
            out[c] = (np.array(common), np.array([[p[f] for f in common] for p in per]))
    return out


def plot_domain(domain: str, runs: dict[str, dict[int, Path]], path: str | Path,
                contexts: list[str] | None = None) -> Path | None:
    """The paper's appendix figure for one domain: one panel per evaluation context, every
    method's f_SORL max against frames (mean over seeds, ± standard error shaded), SAC in black
    dashed. ``runs`` is ``{algo: {seed: run_dir}}``; ``None`` when no run recorded f_SORL."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from morl_trl.envs import domain_of

    data = {a: _seed_curves(by, contexts or _contexts_of(by)) for a, by in runs.items()}
    data = {a: d for a, d in data.items() if d}
    if not data:
        return None
    if contexts is None:
        contexts = list(dict.fromkeys(c for d in data.values() for c in d))
    rows = math.ceil(len(contexts) / 4)  # at most 4 panels a row, rows filled evenly (6 -> 2 x 3)
    cols = math.ceil(len(contexts) / rows)
    labels = _labels(contexts)
    fig, axes = plt.subplots(rows, cols, figsize=(3.5 * cols, 2.8 * rows + 0.9), squeeze=False)
    order = sorted(data, key=lambda a: (ignores_weights(a), a))  # SAC drawn last, on top
    handles = {}
    for k, (ax, c) in enumerate(zip(axes.flat, contexts)):
        color_i = 0
        for algo in order:
            if c not in data[algo]:
                continue
            frames, ys = data[algo][c]
            mean = ys.mean(0)
            se = ys.std(0, ddof=1) / math.sqrt(len(ys)) if len(ys) > 1 else np.zeros_like(mean)
            if ignores_weights(algo):
                style = dict(color="k", ls="--", lw=1.6)
            else:
                style = dict(color=f"C{color_i % 10}", lw=1.4)
                color_i += 1
            (line,) = ax.plot(frames, mean, marker="o", ms=2.5, **style)
            ax.fill_between(frames, mean - se, mean + se, color=style["color"], alpha=0.18, lw=0)
            handles.setdefault(f"{algo} ({len(ys)} seeds)", line)
        ax.set_title(labels[c], fontsize=9)
        ax.tick_params(labelsize=7)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 4))
        if k % cols == 0:
            ax.set_ylabel("f_SORL return (max over weights)", fontsize=7)
        if k // cols == rows - 1:
            ax.set_xlabel("frames", fontsize=8)
    for ax in list(axes.flat)[len(contexts):]:
        ax.axis("off")
    try:
        name = domain_of(domain).name
    except ValueError:
        name = domain
    fig.suptitle(f"{name}: f_SORL return on each evaluation context (mean ± s.e. over seeds)", fontsize=9)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=min(5, len(handles)), fontsize=7,
               frameon=False)
    fig.tight_layout(rect=(0, 0.07 if rows > 1 else 0.1, 1, 1))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _contexts_of(by_seed: dict[int, Path]) -> list[str]:
    return list(dict.fromkeys(c for d in by_seed.values() for c in sorl_curves(d)))


def grid_section(runs: dict[str, dict[str, dict[int, Path]]], out_dir: str | Path, *, reps: int = 10_000) -> list[str]:
    """The f_SORL section of the grid's ``report.md`` (Markdown lines); writes
    ``fsorl_<domain>.png`` and ``fsorl_summary.csv`` into ``out_dir`` (the grid's ``report/``).

    ``runs`` is ``{train_id: {algo: {seed: run_dir}}}`` (the finished cells)."""
    out_dir = Path(out_dir)
    lines = ["## f_SORL: MORL against SAC on SAC's own reward (\"Scalar reward is not enough\")", "",
             "Per domain and evaluation context, every method's f_SORL return (the domain's original scalar "
             "reward, the one SAC trains on), max over the evaluation weights' episodes (SAC: the best of as many "
             "episodes), against frames: mean ± standard error over seeds. The table compares the last "
             "evaluations: the difference to SAC is paired by seed, with a 95% percentile bootstrap interval of "
             "its mean over the seeds both have.", ""]
    all_rows = []
    for domain, by_algo in runs.items():
        finals = {a: {s: _final(sorl_curves(d)) for s, d in by_seed.items()} for a, by_seed in by_algo.items()}
        finals = {a: {s: f for s, f in by.items() if f} for a, by in finals.items()}
        finals = {a: by for a, by in finals.items() if by}
        if not finals:
            lines += [f"- {domain}: no f_SORL: its runs recorded none (the env emits no original scalar reward).",
                      ""]
            continue
        contexts = list(dict.fromkeys(c for by in finals.values() for f in by.values() for c in f))
        png = plot_domain(domain, {a: by_algo[a] for a in finals}, out_dir / f"fsorl_{domain}.png", contexts)
        lines += [f"### {domain}", ""]
        if png is not None:
            lines += [f"![f_SORL against frames, {domain}](report/{png.name})", ""]
        comparison = sac_comparison(finals, reps=reps)
        labels = _labels(contexts)
        if not any(ignores_weights(a) for a in finals):
            lines += ["No SAC run in this grid for this domain: the methods' final f_SORL max only.", ""]
        lines += ["| context | method | f_SORL max (mean ± s.e., seeds) | SAC | method - SAC [95% CI] | verdict |",
                  "|---|---|---|---|---|---|"]
        for r in comparison:
            sac = "-" if r.sac_mean is None else f"{_fmt(r.sac_mean)} ± {_fmt(r.sac_se)} ({r.sac_seeds})"
            diff = "-" if r.difference is None else _fmt(r.difference)
            if r.ci is not None:
                diff += f" [{_fmt(r.ci[0])}, {_fmt(r.ci[1])}]"
            lines.append(f"| {labels[r.context]} | {r.method} | {_fmt(r.mean)} ± {_fmt(r.se)} ({r.seeds}) | {sac} "
                         f"| {diff} | {r.verdict} |")
            all_rows.append({"domain": domain, **r.as_dict()})
        beats = sorted({r.method for r in comparison if r.verdict == "beats SAC"})
        lines += ["", f"Beat SAC in at least one context: {', '.join(beats) if beats else 'none'}.", ""]
        few = min((r.paired for r in comparison if r.ci is not None), default=None)
        if few is not None and few < 5:
            lines += [f"With {few} paired seeds the bootstrap interval cannot be wider than the seeds' own range of "
                      "differences: a description of these runs, not a test (the paper ran 5 seeds).", ""]
        from morl_trl.envs import domain_of

        try:
            lines += [_formula(domain_of(domain)) + ".", ""]
        except ValueError:
            pass
    if all_rows:
        out_dir.mkdir(parents=True, exist_ok=True)
        with (out_dir / "fsorl_summary.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(all_rows[0]))
            w.writeheader()
            w.writerows(all_rows)
        lines += ["Table as CSV: `report/fsorl_summary.csv`.", ""]
    return lines
