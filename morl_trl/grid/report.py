"""The grid's report: the paper's table from our runs, beside the paper's values and the floors,
and the learning curves per domain (``morl-trl grid report DIR``).

The table is :mod:`morl_trl.reporting.table`'s (the code of ``morl-trl reference-table``): each finished cell's
last front per evaluation context is scored against the domain's frozen bounds and specialist fronts (NHGR mean ±
population std over seeds × contexts, IQM, optimality gap, EUGR on the runs' energy weights), one row per algorithm
and domain, with the paper's value where the paper has that algorithm. Each domain ends with its floor (the best
trivial policy): the shipped ``floors.json`` when the runs used the paper's number of evaluation weights, else the
trivial policies evaluated here at the runs' number of weights and contexts (cached in ``report/floors.json``),
since a floor is only comparable at the same weights.

Written into the grid directory: ``report.md``, ``report/table.txt``, ``report/table.csv`` and
``report/curves_<domain>.png`` (NHGR, mean over contexts, against frames: mean over seeds with
the seeds' range shaded, the floor dashed, the paper's value dotted).
"""

from __future__ import annotations

import csv
import json
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

__all__ = ["grid_report", "grid_rows", "paper_label", "run_fronts"]

# our algorithm names -> the paper's labels (reporting.table.PAPER_NHGR's keys), by their
# letters only (so "gpi_ls", "gpi-ls" and "GPILS" all match)
_PAPER_LABELS = {"envelope": "Envelope", "capql": "CAPQL", "pcn": "PCN", "pgmorl": "PGMORL", "gpils": "GPI-LS",
                 "gpipd": "GPI-PD", "sac": "SAC", "morld": "MORL/D SB", "morldsb": "MORL/D SB",
                 "morldsbpsa": "MORL/D SB+PSA", "morldpsa": "MORL/D SB+PSA"}


def paper_label(algo: str) -> str:
    """The paper's name of one of our algorithms (``"envelope"`` -> ``"Envelope"``); the name itself when the paper
    has no such algorithm (MOSAC alone is not the paper's SAC baseline, which ignores the preference, nor MORL/D).

    Example:
        >>> paper_label("envelope"), paper_label("gpi_ls"), paper_label("mosac")
        ('Envelope', 'GPI-LS', 'mosac')
    """
    return _PAPER_LABELS.get(re.sub(r"[^a-z0-9]", "", algo.lower()), algo)


def run_fronts(run_dir: str | Path) -> tuple[int, dict[str, np.ndarray]]:
    """``(frames, {context: front})`` of a run's last evaluation (``fronts/frames_<N>.csv``)."""
    files = sorted(Path(run_dir, "fronts").glob("frames_*.csv"))
    if not files:
        raise ValueError(f"{str(run_dir)!r} has no fronts/frames_*.csv (no evaluation yet)")
    path = files[-1]
    points: dict[str, list[list[float]]] = defaultdict(list)
    with path.open() as fh:
        reader = csv.reader(fh)
        header = next(reader)
        for row in reader:
            points[row[0]].append([float(v) for v in row[1:]])
    if header[0] != "context":
        raise ValueError(f"{path}: expected a 'context' column first, found {header[:1]}")
    return int(path.stem.split("_")[-1]), {c: np.asarray(p, dtype=np.float64) for c, p in points.items()}


def _done_runs(grid_dir: Path, states) -> dict[str, dict[str, dict[int, Path]]]:
    """``{train_id: {algo: {seed: run_dir}}}`` of the finished cells."""
    from morl_trl.envs import domain_of

    out: dict = defaultdict(lambda: defaultdict(dict))
    for s in states:
        if s.status != "done":
            continue
        run_dir = grid_dir / "runs" / s.name
        cfg = json.loads((run_dir / "config.json").read_text())
        out[domain_of(cfg["env_id"]).train_id][cfg["algo"]][int(cfg["seed"])] = run_dir
    return out


def _restricted(ref, contexts):
    from morl_trl.reporting import DomainReference

    return DomainReference(ref.domain, {c: ref.bounds[c] for c in contexts},
                           {c: ref.specialist_fronts[c] for c in contexts})


def grid_rows(grid_dir: str | Path, *, reference_dir: str | Path | None = None, ci_reps: int = 0):
    """The table rows (:class:`~morl_trl.reporting.table.TableRow`) of the finished cells, with
    notes (what was left out) and ``{train_id: (weights, contexts)}`` of the runs."""
    from morl_trl.grid.status import grid_status
    from morl_trl.reporting.reference import PACKAGED_REFERENCE, list_reference_domains, load_domain_reference
    from morl_trl.reporting.table import PAPER_ORDER, domain_rows

    grid_dir = Path(grid_dir)
    states = grid_status(grid_dir)
    runs = _done_runs(grid_dir, states)
    notes, rows, protocol = [], [], {}
    not_done = [s for s in states if s.status != "done"]
    if not_done:
        notes.append(f"{len(not_done)} of {len(states)} cells not finished and left out of the table: "
                     + ", ".join(f"{s.name} ({s.status})" for s in not_done))
    root = reference_dir or PACKAGED_REFERENCE
    known = list_reference_domains(root)
    order = [d for d in PAPER_ORDER if d in runs] + sorted(d for d in runs if d not in PAPER_ORDER)
    for domain in order:
        if domain not in known:
            notes.append(f"{domain}: no reference data (bounds, specialist fronts): no NHGR")
            continue
        ref = load_domain_reference(root, domain)
        fronts, weights = {}, {}
        for algo, by_seed in runs[domain].items():
            for seed, run_dir in by_seed.items():
                fronts.setdefault(algo, {})[seed] = run_fronts(run_dir)[1]
                weights[algo] = json.loads((run_dir / "config.json").read_text())["eval_weights"]
        evaluated = set.intersection(*(set(f) for by in fronts.values() for f in by.values()))
        contexts = [c for c in ref.contexts if c in evaluated]
        if not contexts:
            notes.append(f"{domain}: the runs share no evaluation context with the reference")
            continue
        if len(contexts) < len(ref.contexts):
            notes.append(f"{domain}: over {len(contexts)} of the suite's {len(ref.contexts)} contexts "
                         f"({', '.join(contexts)}), those every run evaluated")
        sub = _restricted(ref, contexts)
        for algo in fronts:
            for row in domain_rows(sub, {algo: fronts[algo]}, num_weights=weights[algo], ci_reps=ci_reps):
                row.label = paper_label(algo)
                rows.append(row)
        protocol[domain] = (sorted(set(weights.values())), contexts)
        from morl_trl.envs import domain_of

        if protocol[domain][0] != [domain_of(domain).eval_weights]:
            notes.append(f"{domain}: EUGR on the runs' {', '.join(map(str, protocol[domain][0]))} energy weights "
                         f"(the paper's protocol: {domain_of(domain).eval_weights})")
    return rows, notes, protocol


def _floors(grid_dir: Path, protocol: dict, reference_dir, mode: str) -> tuple[dict, list[str]]:
    """A floors dict (the shipped file's layout) at the runs' weights and contexts, and notes."""
    from morl_trl.envs import domain_of
    from morl_trl.reporting.floors import evaluate_floor, load_floors, trivial_policies, update_floors_file
    from morl_trl.reporting.reference import PACKAGED_REFERENCE, load_domain_reference

    if mode == "none":
        return {}, ["no floors (--floors none)"]
    shipped = load_floors()
    cache_path = grid_dir / "report" / "floors.json"
    cache_path.parent.mkdir(parents=True, exist_ok=True)
    cache = load_floors(cache_path)
    out: dict = {"domains": {}}
    notes = []
    for domain, (weights, contexts) in protocol.items():
        paper_w = domain_of(domain).eval_weights
        ship = shipped.get("domains", {}).get(domain)
        if len(weights) != 1:
            notes.append(f"{domain}: the runs used different numbers of evaluation weights {weights}: no floor")
            continue
        w = weights[0]
        if ship is not None and ship.get("weights") == w and mode in ("auto", "shipped"):
            src = ship
            notes.append(f"{domain}: floor from the shipped floors.json ({w} weights, seed 0)")
        elif mode == "shipped":
            notes.append(f"{domain}: no shipped floor at {w} weights (the shipped one is at {paper_w}): no floor")
            continue
        else:
            have = cache.get("domains", {}).get(domain, {})
            policies = list(trivial_policies(domain))
            need = [p for p in policies if have.get("weights") != w
                    or not set(contexts) <= set(have.get("policies", {}).get(p, {}).get("nhgr", {}))]
            if need:
                import time

                ref = load_domain_reference(reference_dir or PACKAGED_REFERENCE, domain)
                for p in policies:
                    t = time.perf_counter()
                    floor = evaluate_floor(domain, p, _restricted(ref, contexts), weights=w, seed=0, contexts=contexts)
                    cache = update_floors_file(cache_path, floor, weights=w, seed=0, gamma=domain_of(domain).gamma,
                                               command=f"morl-trl grid report (floors at {w} weights)",
                                               seconds=time.perf_counter() - t, all_policies=policies)
            src = cache["domains"][domain]
            notes.append(f"{domain}: floor evaluated here at the runs' {w} weights (the paper's: {paper_w}) and "
                         f"{len(contexts)} contexts, seed 0 (cached in report/floors.json)")
        out["domains"][domain] = {"weights": w, "policies": {
            p: {"nhgr": {c: e["nhgr"][c] for c in contexts if c in e["nhgr"]}} for p, e in src["policies"].items()}}
    return out, notes


def _curves(grid_dir: Path, domain: str, runs: dict[str, dict[int, Path]], contexts: list[str], floors: dict,
            out: Path) -> Path:
    """NHGR (mean over ``contexts``) against frames per algorithm: mean over seeds, range shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from morl_trl.reporting.floors import best_floor
    from morl_trl.reporting.report import learning_curves
    from morl_trl.reporting.table import PAPER_NHGR, domain_name

    fig, ax = plt.subplots(figsize=(5.6, 3.6))
    for k, (algo, by_seed) in enumerate(sorted(runs.items())):
        per_seed = []
        for run_dir in by_seed.values():
            nhgr = learning_curves(run_dir / "eval" / "metrics.csv").get("nhgr", {})
            frames = sorted(set.intersection(*(set(f for f, _ in nhgr.get(c, [])) for c in contexts))) if nhgr else []
            values = {c: dict(nhgr[c]) for c in contexts}
            per_seed.append({f: float(np.mean([values[c][f] for c in contexts])) for f in frames})
        common = sorted(set.intersection(*(set(s) for s in per_seed))) if per_seed else []
        if not common:
            continue
        ys = np.array([[s[f] for f in common] for s in per_seed])
        color = f"C{k % 10}"
        label = paper_label(algo)
        ax.plot(common, ys.mean(0), marker="o", ms=3, color=color, label=f"{label} ({len(per_seed)} seeds)")
        if len(per_seed) > 1:
            ax.fill_between(common, ys.min(0), ys.max(0), color=color, alpha=0.2)
        paper = PAPER_NHGR.get(domain, {}).get(label)
        if paper is not None:
            ax.axhline(paper[0], color=color, ls=":", lw=1.0, label=f"{label} (paper)")
    best = best_floor(floors, domain) if floors else None
    if best is not None:
        ax.axhline(best.mean, color="k", ls="--", lw=1.0, label=f"floor: {best.policy}")
    ax.set_xlabel("frames", fontsize=8)
    ax.set_ylabel(f"NHGR (mean over {len(contexts)} contexts)", fontsize=8)
    ax.set_ylim(0, 1.02)
    ax.set_title(domain_name(domain), fontsize=9)
    ax.tick_params(labelsize=7)
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 4))
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def grid_report(grid_dir: str | Path, *, reference_dir: str | Path | None = None, floors: str = "auto",
                ci_reps: int = 0, stream=None) -> Path:
    """Write the grid's ``report.md`` (see the module docstring), print the table; returns the path.

    ``floors``: ``"auto"`` (the shipped floors at the paper's weights, else evaluated at the
    runs'), ``"shipped"`` (only the shipped ones) or ``"none"``.
    """
    import sys

    from morl_trl.grid.status import format_status, grid_status
    from morl_trl.reporting.fsorl import grid_section
    from morl_trl.reporting.table import format_table

    if floors not in ("auto", "shipped", "none"):
        raise ValueError(f"floors is {floors!r}; valid: 'auto', 'shipped', 'none'")
    grid_dir = Path(grid_dir)
    states = grid_status(grid_dir)
    rows, notes, protocol = grid_rows(grid_dir, reference_dir=reference_dir, ci_reps=ci_reps)
    floor_dict, floor_notes = _floors(grid_dir, protocol, reference_dir, floors)
    out_dir = grid_dir / "report"
    out_dir.mkdir(parents=True, exist_ok=True)
    table = format_table(rows, floor_dict, paper_match=False) if rows else "(no finished cell with reference data)"
    (out_dir / "table.txt").write_text(table + "\n")
    if rows:
        dicts = [r.as_dict() for r in rows]
        with (out_dir / "table.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(dict.fromkeys(k for d in dicts for k in d)))
            w.writeheader()
            w.writerows(dicts)
    runs = _done_runs(grid_dir, states)
    lines = [f"# Grid {grid_dir.name}", "", "```", format_status(states), "```", "",
             "## The paper's table from these runs", "",
             "NHGR mean ± population std over seeds × contexts, IQM and optimality gap (OG), EUGR; `paper`: the "
             "paper's value for that algorithm and domain (SPEC §3); `floor`: the best trivial policy (random or a "
             "constant action) under the same protocol. The code is `morl-trl reference-table`'s.", "",
             "```", table, "```", ""]
    if notes or floor_notes:
        lines += [f"- {n}" for n in notes + floor_notes] + [""]
    for domain, (_, contexts) in protocol.items():
        png = _curves(grid_dir, domain, runs[domain], contexts, floor_dict, out_dir / f"curves_{domain}.png")
        lines += [f"![NHGR against frames, {domain}](report/{png.name})", ""]
    lines += grid_section(runs, out_dir)  # f_SORL against SAC (reporting/fsorl.py)
    failed = [s for s in states if s.status == "failed"]
    if failed:
        lines += ["## Failed cells", ""] + [f"- `{s.name}`: {s.error}" for s in failed] + [""]
    path = grid_dir / "report.md"
    path.write_text("\n".join(lines))
    if stream is not False:
        print(table, file=stream or sys.stdout, flush=True)
        for n in notes + floor_notes:
            print(f"note: {n}", file=stream or sys.stdout, flush=True)
        print(f"report: {path}", file=stream or sys.stdout, flush=True)
    return path
