"""The end-of-run report: NHGR per evaluation context, against the specialists, a random policy,
the domain's floor (the best trivial policy, :mod:`morl_trl.reporting.floors`) and (with the
published data) the paper's baselines; Pareto-front and NHGR plots."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from morl_trl.reporting.budget import count_label
from morl_trl.reporting.fsorl import run_section

__all__ = ["write_report", "published_baselines", "floor_column", "learning_curves", "training_curves"]


def _fmt(v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, int):
        return str(v)
    return f"{v:.3f}" if abs(v) < 1e4 else f"{v:.4g}"


def published_baselines(reference_dir: str | Path, domain: str) -> dict[str, dict[str, float]]:
    """``{algorithm label: {context: mean NHGR over seeds}}`` recomputed from the published fronts."""
    from morl_trl.reporting.reference import load_domain_reference, load_generalist_fronts
    from morl_trl.reporting.table import domain_rows

    ref = load_domain_reference(reference_dir, domain)
    rows = domain_rows(ref, load_generalist_fronts(reference_dir, domain, ref.contexts), eugr=False)
    return {r.label: dict(zip(r.contexts, r.nhgr.mean(0).tolist())) for r in rows}


def _random_rows(result, random_result, contexts: list[str]) -> list[str]:
    """A table of hypervolume and EUM, ours beside the uniformly random policy's, per context."""
    metrics = [m for m in ("hypervolume", "hv_ratio", "eum", "igd")
               if any(v is not None for v in result.metric(m).values())]
    if not metrics:
        return []
    head = " | ".join(f"{m} (ours) | {m} (random)" for m in metrics)
    lines = ["## Against a uniformly random policy", "", f"| context | {head} |", "|---|" + "---|" * (2 * len(metrics))]
    for c in contexts + [None]:
        ours = result.aggregate if c is None else result.per_context[c].metrics
        rand = random_result.aggregate if c is None else random_result.per_context[c].metrics
        cells = " | ".join(f"{_fmt(ours.get(m))} | {_fmt(rand.get(m))}" for m in metrics)
        lines.append(f"| {'**mean**' if c is None else c} | {cells} |")
    return lines + [""]


def foreign_nhgr_note(spec, ref_point=None) -> str:
    """Why a run on a foreign env (one env, no contexts) reports no NHGR, and what it reports instead,
    with the hypervolume's reference point (``ref_point``, the run's, else the env's) and its source."""
    extra = ", IGD and the ratio of its hypervolume to the true front's" if spec.true_front is not None else ""
    return (f"NHGR: unavailable. {spec.train_id} is one environment without contexts: NHGR and EUGR measure "
            f"generalization across contexts against specialists trained per context, which has no meaning here; "
            f"this report gives hypervolume (reference point {reference_point_text(spec, ref_point)}), EUM{extra}, "
            f"beside a uniformly random policy's (the floor).")


def hv_ratio_note(results, episodes: int) -> str | None:
    """Why an ``hv_ratio`` above 1 can happen (``None`` when none of ``results`` has one): the true
    front is one of expected returns, each evaluated point the mean of ``episodes`` episodes."""
    above = sorted({round(float(v), 3) for r in results if r is not None
                    for v in r.metric("hv_ratio").values() if v is not None and v > 1})
    if not above:
        return None
    return (f"hv_ratio above 1 ({', '.join(f'{v:.3f}' for v in above)}): the true front (MO-Gymnasium's "
            f"pareto_front) holds the expected returns of the best policies, while each evaluated point is the mean "
            f"return of {episodes} episode{'s' if episodes != 1 else ''} per weight. In an env with random outcomes "
            f"(resource-gathering's enemies, minecart's ore) a lucky episode lies beyond the expected front, and "
            f"minecart's front is itself an approximation (MO-Gymnasium's word); more eval_episodes bring the points "
            f"to their expectations.")


def reference_point_text(spec, ref_point=None) -> str:
    """``[0.0, -25.0] (MORL-Baselines examples/pql_dst.py)``: the run's hypervolume reference point
    (``ref_point`` when the user gave one, else the env's) and where it comes from."""
    if ref_point is not None:
        return f"{[float(v) for v in ref_point]} (given with --ref-point / ref_point=)"
    source = getattr(spec, "hv_ref_point_source", None)
    return f"{list(spec.hv_ref_point or [])}" + (f" ({source})" if source else "")


def floor_column(domain: str, floors: dict | None = None) -> tuple[str, dict[str, float]] | None:
    """``("floor: <policy>", {context: NHGR})`` of the domain's best trivial policy in the shipped
    floors file (or ``floors``), ``None`` when the domain has none."""
    from morl_trl.reporting.floors import best_floor, load_floors

    best = best_floor(load_floors() if floors is None else floors, domain)
    if best is None:
        return None
    return f"floor: {best.policy}", dict(best.nhgr)


def _plot_fronts(result, reference, path: Path, objectives: tuple[str, ...], contexts=None) -> Path | None:
    """Pareto fronts, ours on top of the specialist's, one legend for the figure. Two objectives:
    one scatter per context (``contexts``, default all). Three or more: one panel per pair of
    objectives (every pairwise projection) of each context (:func:`_plot_fronts_per_context`
    calls it once per context: a page each)."""
    import itertools

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(result.context_names if contexts is None else contexts)
    pairs = list(itertools.combinations(range(len(objectives)), 2))
    cells = [(name, pair) for name in names for pair in pairs]
    cols = min(4, len(cells)) if len(pairs) == 1 else min(3, len(pairs))
    rows = math.ceil(len(cells) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 3.0 * rows + 0.4), squeeze=False)
    for ax, (name, (i, j)) in zip(axes.flat, cells):
        front = result.front(name)
        shown = [front[:, [i, j]]]
        if reference is not None and name in reference.specialist_fronts:
            spec = reference.specialist_fronts[name]
            ax.scatter(spec[:, i], spec[:, j], s=10, c="0.6", label="specialist front", zorder=2)
            shown.append(spec[:, [i, j]])
        if reference is not None and name in reference.bounds:  # the normalization box: a fixed frame
            b = reference.bounds[name]
            shown.append(np.array([[b.lower[i], b.lower[j]], [b.upper[i], b.upper[j]]]))
        ax.scatter(front[:, i], front[:, j], s=30, c="C3", edgecolors="k", linewidths=0.5, label="ours", zorder=4)
        _frame(ax, np.concatenate(shown))
        ax.set_title(_short(name) if len(pairs) == 1 or len(names) > 1 else f"{objectives[i]} / {objectives[j]}",
                     fontsize=9)
        ax.set_xlabel(objectives[i], fontsize=8)
        ax.set_ylabel(objectives[j], fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(cells):]:
        ax.axis("off")
    _figure_legend(fig, axes.flat[0], title=None if len(pairs) == 1 or len(names) > 1 else _short(names[0]))
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _plot_fronts_per_context(result, reference, run_dir: Path, objectives: tuple[str, ...]) -> list[tuple[str, Path]]:
    """Every pairwise projection of each context's front, one figure per context
    (``report_fronts_<context>.png``, a page at most); returns ``[(context, path), ...]``."""
    return [(c, _plot_fronts(result, reference, run_dir / f"report_fronts_{_short(c)}.png", objectives, [c]))
            for c in result.context_names]


def _figure_legend(fig, ax, title: str | None = None) -> None:
    """One legend for the whole figure, above its panels (from ``ax``'s labelled artists)."""
    handles, labels = ax.get_legend_handles_labels()
    # fixed margins in inches, not tight_layout (a second draw of every panel: half the plotting time
    # of a report, which is most of the end of a run)
    w, h = fig.get_size_inches()
    room = 0.45 + (0.25 if title else 0.0)  # above the panels, for the legend
    grid = fig.axes[0].get_gridspec()
    fig.subplots_adjust(left=0.75 / w, right=1 - 0.15 / w, bottom=0.6 / h, top=1 - (room + 0.3) / h,
                        wspace=0.9 / (w / grid.ncols), hspace=1.0 / (h / grid.nrows))
    if handles:
        fig.legend(handles, labels, loc="upper center", ncol=len(labels), fontsize=8, frameon=False,
                   title=title, title_fontsize=9)


def _short(name: str) -> str:
    return name.replace("-v0", "").replace("-v5", "").replace("-v2", "")


def _plot_parallel(result, reference, path: Path, objectives: tuple[str, ...]) -> Path:
    """Fronts of three or more objectives as parallel coordinates: one panel per context, one
    vertical axis per objective, one line per point of the front (ours red, the specialist's
    grey), each objective scaled to the context's normalization bounds (else to the points' range)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(result.context_names)
    k = len(objectives)
    cols = min(4, len(names))
    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.8 * cols, 2.9 * rows), squeeze=False)
    x = np.arange(k)
    for ax, name in zip(axes.flat, names):
        front = np.asarray(result.front(name), dtype=np.float64)
        spec = None
        if reference is not None and name in reference.specialist_fronts:
            spec = np.asarray(reference.specialist_fronts[name], dtype=np.float64)
        if reference is not None and name in reference.bounds:
            lo = np.asarray(reference.bounds[name].lower, dtype=np.float64)
            hi = np.asarray(reference.bounds[name].upper, dtype=np.float64)
        else:
            pts = front if spec is None else np.concatenate([front, spec])
            lo, hi = pts.min(0), pts.max(0)
        span = np.where(hi > lo, hi - lo, 1.0)
        if spec is not None:
            for n, row in enumerate((spec - lo) / span):
                ax.plot(x, row, color="0.6", lw=0.6, alpha=0.6, zorder=2, label="specialist front" if n == 0 else None)
        for n, row in enumerate((front - lo) / span):
            ax.plot(x, row, color="C3", lw=1.2, marker="o", ms=3, zorder=4, label="ours" if n == 0 else None)
        ax.set_xticks(x, list(objectives), fontsize=7, rotation=20)
        ax.set_ylabel("scaled to bounds" if reference is not None else "scaled", fontsize=7)
        ax.set_title(_short(name), fontsize=9)
        ax.tick_params(labelsize=7)
        for xi in x:
            ax.axvline(xi, color="k", lw=0.5)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    _figure_legend(fig, axes.flat[0])
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _frame(ax, points: np.ndarray) -> None:
    """Axis limits covering ``points`` ``[n, 2]`` with a margin, also when they collapse to one
    point (matplotlib then zooms onto a lone dot on unreadable autoscaled ticks)."""
    lo, hi = points.min(0), points.max(0)
    span = hi - lo
    pad = np.where(span > 0, 0.08 * span, 0.05 * np.maximum(np.abs(hi), 1.0))
    ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
    ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
    ax.ticklabel_format(style="sci", scilimits=(-3, 4), useOffset=False)


_CURVES = (("nhgr", "NHGR"), ("normalized_hypervolume", "normalized HV"), ("hypervolume", "hypervolume"),
           ("hv_ratio", "HV / true front's HV"), ("eum", "EUM"), ("igd", "IGD"))


def learning_curves(metrics_csv: str | Path) -> dict[str, dict[str, list[tuple[int, float]]]]:
    """``{metric: {context: [(frames, value), ...]}}`` from a run's ``eval/metrics.csv`` (every
    evaluation, frame 0 included), for the metrics of :data:`_CURVES` that it holds."""
    import csv

    curves: dict[str, dict[str, list[tuple[int, float]]]] = {}
    path = Path(metrics_csv)
    if not path.is_file():
        return curves
    with path.open() as fh:
        for row in csv.DictReader(fh):
            for metric, _ in _CURVES:
                value = row.get(metric)
                if value in (None, "", "None"):
                    continue
                curves.setdefault(metric, {}).setdefault(row["context"], []).append((int(row["frames"]), float(value)))
    return curves


def _plot_learning(curves, contexts: list[str], path: Path, floor: tuple[str, dict[str, float]] | None) -> Path:
    """One panel per metric: a line per context against frames; the floor's NHGR per context dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = [(m, label) for m, label in _CURVES if m in curves
               and not (m == "hypervolume" and "normalized_hypervolume" in curves)]  # (one HV panel)
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.4 * len(metrics), 3.3), squeeze=False)
    for ax, (metric, label) in zip(axes.flat, metrics):
        for k, c in enumerate(contexts):
            pts = sorted(curves[metric].get(c, []))
            if not pts:
                continue
            x, y = zip(*pts)
            short = c.replace("-v0", "").replace("-v5", "").replace("-v2", "")
            ax.plot(x, y, marker="o", ms=3, lw=1.2, color=f"C{k % 10}", label=short)
            if metric == "nhgr" and floor is not None and c in floor[1]:
                ax.axhline(floor[1][c], color=f"C{k % 10}", ls="--", lw=0.8, alpha=0.7)
        ax.set_xlabel("frames", fontsize=8)
        ax.set_ylabel(label, fontsize=8)
        if metric in ("nhgr", "normalized_hypervolume", "hv_ratio"):
            ax.set_ylim(0, 1.02)
        ax.tick_params(labelsize=7)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 4))
    axes.flat[0].legend(fontsize=6, ncol=2)
    if floor is not None:
        axes.flat[0].set_title(f"dashed: {floor[0]}", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def training_curves(run_dir: str | Path) -> dict[str, list[tuple[int, float]]]:
    """``{series: [(frames, value), ...]}`` of a run's training: every column of
    ``train/losses.csv`` (losses, ε or α, frames per second) and the undiscounted return per
    objective of ``train/episodes.csv`` (``return <objective>``, one point per episode)."""
    import csv

    out: dict[str, list[tuple[int, float]]] = {}
    run_dir = Path(run_dir)
    for rel, prefix in (("train/losses.csv", ""), ("train/episodes.csv", "return_")):
        path = run_dir / rel
        if not path.is_file():
            continue
        with path.open() as fh:
            for row in csv.DictReader(fh):
                for key, value in row.items():
                    if key == "frames" or value in (None, "") or not key.startswith(prefix):
                        continue
                    try:
                        v = float(value)
                    except ValueError:
                        continue
                    name = f"return {key[len(prefix):]}" if prefix else key
                    out.setdefault(name, []).append((int(float(row["frames"])), v))
    return out


def split_constant(curves: dict[str, list[tuple[int, float]]]) -> tuple[dict, dict[str, float]]:
    """``(varying, constant)``: the training series that change over the run (plotted) and the
    value of each that does not (e.g. Envelope's ``homotopy_lambda`` 0.95: said, not plotted).

    Example:
        >>> split_constant({"loss": [(1, 2.0), (2, 1.0)], "homotopy_lambda": [(1, 0.95), (2, 0.95)]})
        ({'loss': [(1, 2.0), (2, 1.0)]}, {'homotopy_lambda': 0.95})
    """
    varying, constant = {}, {}
    for name, pts in curves.items():
        values = {v for _, v in pts}
        if len(pts) > 1 and len(values) == 1 and not name.startswith("return "):
            constant[name] = pts[0][1]
        else:
            varying[name] = pts
    return varying, constant


def _plot_training(curves: dict[str, list[tuple[int, float]]], path: Path) -> Path:
    """One panel per loss / schedule / throughput series, and one panel of the training returns
    per objective (a running mean over episodes), against frames."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    returns = {k: v for k, v in curves.items() if k.startswith("return ")}
    others = {k: v for k, v in curves.items() if not k.startswith("return ")}
    panels = list(others) + (["returns per objective"] if returns else [])
    cols = min(4, len(panels))
    rows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.8 * cols, 2.8 * rows), squeeze=False)
    for ax, name in zip(axes.flat, panels):
        if name == "returns per objective":
            for n, (label, pts) in enumerate(sorted(returns.items())):
                x, y = (np.array(v, dtype=np.float64) for v in zip(*sorted(pts)))
                w = max(1, min(50, len(y) // 10))
                smooth = np.convolve(y, np.ones(w) / w, mode="valid")
                ax.plot(x[w - 1:], smooth, lw=1.2, color=f"C{n % 10}", label=label.removeprefix("return "))
            ax.legend(fontsize=6)
            ax.set_title("training return per objective (running mean)", fontsize=8)
        else:
            x, y = zip(*sorted(others[name]))
            ax.plot(x, y, lw=1.0)
            ax.set_title(name, fontsize=8)
        ax.set_xlabel("frames", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 4))
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _plot_nhgr(table: dict[str, dict[str, float]], contexts: list[str], path: Path,
               floor: tuple[str, dict[str, float]] | None = None) -> Path:
    """Bars per series and context; ``floor`` (label, per-context NHGR) as a dashed line across each context."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    series = list(table)
    width = 0.8 / max(len(series), 1)
    fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(contexts)), 3.4))
    x = np.arange(len(contexts))
    for s, name in enumerate(series):
        vals = [table[name].get(c, np.nan) for c in contexts]
        ax.bar(x + s * width - 0.4 + width / 2, vals, width, label=name)
    if floor is not None:
        label, values = floor
        for i, c in enumerate(contexts):
            if c in values:
                ax.hlines(values[c], x[i] - 0.45, x[i] + 0.45, colors="k", linestyles="--", linewidth=1.2,
                          label=label if i == 0 or not any(cc in values for cc in contexts[:i]) else None)
    ax.set_xticks(x, [c.replace("-v0", "").replace("-v5", "").replace("-v2", "") for c in contexts],
                  rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("NHGR")
    ax.set_ylim(0, 1.05)
    # (right of the axes: the labels name their budgets and would cover the bars)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def _run_floor(log, result, reference, contexts, random_result):
    """``((label, {context: NHGR}) or None, where it comes from)``: the floor at the run's weights."""
    from morl_trl.reporting.floors import floor_at_weights

    weights = int(result.weights.shape[0])
    known = None
    if random_result is not None and getattr(log.cfg, "seed", None) == 0:  # the same protocol, seed 0
        rn = random_result.metric("nhgr")
        if all(rn.get(c) is not None for c in contexts):
            known = {"random": {c: float(rn[c]) for c in contexts}}
    try:
        best, where = floor_at_weights(log.spec.train_id, weights, contexts, reference,
                                       cache=log.out_dir / "report_floors.json", known=known)
    except (ValueError, ImportError) as err:  # e.g. a context outside the reference data
        return None, f"the floor could not be computed ({err})"
    if best is None:
        return None, where
    return (f"floor: {best.policy} ({weights} weights)", dict(best.nhgr)), where


def _nhgr_table(title: str, cols: dict[str, dict[str, float]], contexts: list[str]) -> list[str]:
    """A Markdown table of NHGR per context (and the mean) with one column per entry of ``cols``."""
    lines = [title, "", "| context | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    for c in contexts:
        lines.append(f"| {c} | " + " | ".join(_fmt(col.get(c)) for col in cols.values()) + " |")
    means = [np.mean([col[c] for c in contexts if c in col]) if col else float("nan") for col in cols.values()]
    lines.append("| **mean** | " + " | ".join(_fmt(float(m)) for m in means) + " |")
    return lines + [""]


def _paper_columns(baselines: dict[str, dict[str, float]], domain: str) -> dict[str, dict[str, float]]:
    """The paper's NHGR columns, each named with the budget it was measured at."""
    from morl_trl.reporting.budget import budget_label
    from morl_trl.reporting.paper import paper_budget

    frames, weights = paper_budget(domain) or (None, None)
    return {budget_label(k, "paper", frames=frames, weights=weights): v for k, v in baselines.items()}


def headline(cfg, summary: dict, floor: tuple[str, dict[str, float]] | None, path: Path) -> str:
    """The report in one line (what ``morl_trl.train`` prints instead of its tables).

    Example:
        >>> from types import SimpleNamespace
        >>> cfg = SimpleNamespace(algo="envelope", env_id="MOLavaGridDR-v0")
        >>> print(headline(cfg, {"frames": 4_032, "nhgr_mean": 0.41, "aggregate": {}},
        ...                ("floor: noop (8 weights)", {"A": 0.2, "B": 0.3}), Path("runs/x/report.md")))
        envelope on MOLavaGridDR-v0: 4,032 frames, mean NHGR 0.410 (floor: noop (8 weights) 0.250); report: runs/x/report.md
    """
    what = f"{cfg.algo} on {cfg.env_id}: {summary.get('frames', 0):,} frames"
    nhgr = summary.get("nhgr_mean", float("nan"))
    if nhgr == nhgr:
        what += f", mean NHGR {nhgr:.3f}"
        if floor is not None and floor[1]:
            what += f" ({floor[0]} {float(np.mean(list(floor[1].values()))):.3f})"
    else:
        agg = summary.get("aggregate", {})
        shown = [f"mean {m} {agg[m]:.4g}" for m in ("hypervolume", "eum") if agg.get(m) is not None]
        what += (", " + ", ".join(shown)) if shown else ""
    return f"{what}; report: {path}"


def write_report(log, summary: dict, fps: float | None) -> Path:
    """Write ``report.md`` (+ PNGs) into the run directory and print its table (or, when
    ``log.echo_report`` is false, its one-line :func:`headline`)."""
    from morl_trl.reporting.budget import budget_label, same_budget
    from morl_trl.reporting.paper import paper_budget

    result = log.last_result
    cfg, spec, run_dir = log.cfg, log.spec, log.out_dir
    contexts = list(result.context_names)
    reference = getattr(log, "reference", None)
    weights = int(result.weights.shape[0])
    frames = int(summary.get("frames") or 0)
    nhgr_cols: dict[str, dict[str, float]] = {}
    ours = result.metric("nhgr")
    if any(v is not None for v in ours.values()):
        nhgr_cols[budget_label(cfg.algo, "ours", weights=weights, frames=frames)] = {
            c: v for c, v in ours.items() if v is not None}
    random_result = getattr(log, "random_result", None)
    if random_result is not None:
        rn = random_result.metric("nhgr")
        if any(v is not None for v in rn.values()):
            nhgr_cols[f"random policy ({weights} weights)"] = {
                c: v for c, v in rn.items() if v is not None}
    baselines = {}
    baseline_note = None
    if reference is None and "reference" in log.__dict__:  # no data for the domain: said below, once
        pass
    elif cfg.reference_dir:
        try:
            baselines = published_baselines(cfg.reference_dir, spec.train_id)
        except ValueError as err:  # no published runs for this domain
            log.note(f"no published baselines: {err}")
            baseline_note = f"No paper baselines: {err}"
    else:
        baseline_note = ("No paper baselines: their published fronts are not shipped; pass the folder that holds "
                         "them with `--reference DIR` (config `reference_dir`) to add a column per algorithm.")
    floor, floor_where = None, None
    if nhgr_cols:
        floor, floor_where = _run_floor(log, result, reference, contexts, random_result)
    if floor is not None:
        nhgr_cols[floor[0]] = floor[1]
    paper_cols = _paper_columns(baselines, spec.train_id)
    # (a domain outside the paper has no budget to compare with: its columns stay in one table)
    comparable = same_budget(spec.train_id, frames=frames, weights=weights) or paper_budget(spec.train_id) is None

    lines = [f"# {cfg.algo} on {cfg.env_id} (seed {cfg.seed})", ""]
    lines.append(f"Frames: {summary.get('frames')}" + (f" · frames/s: {fps:,.0f}" if fps else "")
                 + f" · evaluation weights: {weights}")
    lines.append("")
    metric_names = ["nhgr", "normalized_hypervolume", "hypervolume", "hv_ratio", "eum", "eugr", "igd", "cardinality",
                    "sparsity"]
    present = [m for m in metric_names if any(v is not None for v in result.metric(m).values())]
    lines.append("| context | " + " | ".join(present) + " |")
    lines.append("|---|" + "---|" * len(present))
    for c in contexts:
        lines.append(f"| {c} | " + " | ".join(_fmt(result.per_context[c].metrics.get(m)) for m in present) + " |")
    lines.append("| **mean** | " + " | ".join(_fmt(result.aggregate.get(m)) for m in present) + " |")
    lines.append("")
    if random_result is not None and not nhgr_cols:  # no NHGR: the random policy beside ours
        lines.extend(_random_rows(result, random_result, contexts))
    if getattr(spec, "foreign", False) and "nhgr" not in present:
        lines.append(foreign_nhgr_note(spec, cfg.ref_point))
        lines.append("")
        above = hv_ratio_note([result, random_result], cfg.eval_episodes)
        if above:
            lines.extend([above, ""])
    elif reference is None and "nhgr" not in present:
        lines.append(f"NHGR: unavailable. NHGR and EUGR need, per evaluation context, the normalization bounds and "
                     f"the specialist front of agents trained on that context alone; the authors published none for "
                     f"{spec.train_id} (they did not run this domain), and none are shipped, so this report gives "
                     f"hypervolume and EUM only, beside a uniformly random policy's.")
        lines.append("")
    if nhgr_cols:
        if comparable:  # the paper's budget: one table, one chart
            nhgr_cols.update(paper_cols)
        lines += _nhgr_table("## NHGR per context", nhgr_cols, contexts)
        bars = {k: v for k, v in nhgr_cols.items() if floor is None or k != floor[0]}
        if baseline_note is not None:
            lines.append(baseline_note)
            lines.append("")
        png = _plot_nhgr(bars, contexts, run_dir / "report_nhgr.png", floor=floor)
        lines.append(f"![NHGR per context]({png.name})")
        lines.append("")
        if floor is not None:
            lines.append(f"`{floor[0]}`: the NHGR of the best trivial policy (a constant action or random) "
                         f"at this run's {weights} evaluation weights; a score near it is no evidence of learning. "
                         f"Dashed on the plot. Source: {floor_where}.")
            lines.append("")
        elif floor_where:
            lines.append(f"No floor: {floor_where}.")
            lines.append("")
        if paper_cols and not comparable and paper_budget(spec.train_id) is not None:
            lines += _nhgr_table("## The paper's generalists (not this run's budget)", paper_cols, contexts)
            paper_frames, paper_weights = paper_budget(spec.train_id)
            lines.append(f"The paper's runs: {paper_weights} weights, {count_label(paper_frames)} frames each, "
                         f"mean over 5 seeds; this run: {weights} weights, {count_label(frames)} frames. NHGR grows "
                         f"with training and depends on the number of evaluation weights, so these columns are "
                         f"not a comparison with this run (and are not on its chart); `morl-trl train "
                         f"{cfg.algo} {cfg.env_id}` without `--quick` runs at the paper's budget.")
            lines.append("")
    curves = learning_curves(run_dir / "eval" / "metrics.csv")
    if curves:
        png = _plot_learning(curves, contexts, run_dir / "report_learning.png", floor)
        evals = len({f for per in curves.values() for pts in per.values() for f, _ in pts})
        lines.append("## Learning curves")
        lines.append("")
        lines.append(f"![NHGR, normalized HV and EUM per context against frames]({png.name})")
        lines.append("")
        lines.append(f"Every evaluation of the run ({evals}, every {cfg.eval_interval:,} frames), frame 0 "
                     "(the untrained policy) included" + ("; dashed: the floor's NHGR per context." if floor is not None
                                                           else "."))
        lines.append("")
    train_curves = training_curves(run_dir)
    if train_curves:
        varying, constant = split_constant(train_curves)
        lines.append("## Training curves")
        lines.append("")
        if varying:
            png = _plot_training(varying, run_dir / "report_training.png")
            lines.append(f"![Losses, exploration, frames per second and training returns against frames]({png.name})")
            lines.append("")
        lines.append("From `train/losses.csv` (losses, ε or α, frames per second) and `train/episodes.csv` "
                     "(undiscounted return per objective of every training episode, under its training preference)."
                     + (" Constant over the run, so not plotted: "
                        + ", ".join(f"`{k}` {_fmt(v)}" for k, v in constant.items()) + "." if constant else ""))
        lines.append("")
    objectives = tuple(spec.objective_names)
    lines.append("## Pareto fronts")
    lines.append("")
    if len(objectives) > 2:
        png = _plot_parallel(result, reference, run_dir / "report_fronts_parallel.png", objectives)
        lines.append(f"![Pareto fronts per context, parallel coordinates]({png.name})")
        lines.append("")
        lines.append(f"Parallel coordinates: one line per point of the front over all {len(objectives)} objectives "
                     "(ours red, on top; the specialist's grey), each objective scaled to the context's normalization "
                     "bounds. Every pairwise projection, one figure per context (the fronts are non-dominated in all "
                     "objectives, not in each projection; fronts/*.csv hold the points): "
                     + ", ".join(f"[{_short(c)}]({p.name})" for c, p in _plot_fronts_per_context(
                         result, reference, run_dir, objectives)) + ".")
        lines.append("")
    else:
        png = _plot_fronts(result, reference, run_dir / "report_fronts.png", objectives)
        lines.append(f"![Pareto fronts per context]({png.name})")
        lines.append("")
    lines += run_section(result, run_dir, cfg.algo, spec, cfg.env_id)  # f_SORL (reporting/fsorl.py)
    path = run_dir / "report.md"
    path.write_text("\n".join(lines) + "\n")
    from tqdm.auto import tqdm  # (above a training run's progress bar, never through it)

    if not getattr(log, "echo_report", True):
        tqdm.write(headline(cfg, summary, floor, path))
        return path
    tqdm.write("\n".join(lines[: lines.index("") + 1 + len(contexts) + 4]))
    if nhgr_cols:
        start = lines.index("## NHGR per context")
        tqdm.write("\n".join(lines[start : start + 4 + len(contexts) + 1]))
    elif "## Against a uniformly random policy" in lines:
        start = lines.index("## Against a uniformly random policy")
        tqdm.write("\n".join(lines[start : start + 4 + len(contexts) + 1]))
    tqdm.write("\n".join(line for line in lines if line.startswith("NHGR: unavailable")))
    tqdm.write(f"report: {path}")
    return path
