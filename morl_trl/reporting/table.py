"""The paper's NHGR table recomputed from published (or our own) fronts (``morl-trl reference-table``).

For every domain under a reference folder (layout in :mod:`morl_trl.reporting.reference`) and every algorithm with
final fronts there, build the ``[seeds, contexts]`` matrix of NHGR (frozen bounds with clipping, origin reference,
specialist combined front as denominator, capped at 1) and report its mean ± population std over all entries, IQM
and optimality gap (rliable's definitions), optionally stratified-bootstrap CIs, and EUGR on the energy weights.
Each domain's block ends with its floor: the best trivial policy's NHGR (mean ± std over the
contexts, one seed) from the shipped ``floors.json`` (:mod:`morl_trl.reporting.floors`).

Example:
    $ morl-trl reference-table ../shared/reference
    $ morl-trl reference-table ../shared/reference --domain MOHopperDR-v5 --ci --reps 50000
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from morl_trl.metrics import interquartile_mean, optimality_gap, stratified_bootstrap_ci
from morl_trl.preferences import energy_weights
from morl_trl.reporting.paper import PAPER_NHGR, PAPER_ORDER, domain_name
from morl_trl.reporting.reference import (DomainReference, list_reference_domains, load_domain_reference,
                                          load_generalist_fronts)

__all__ = ["TableRow", "PAPER_ORDER", "PAPER_NHGR", "domain_name", "domain_rows", "reference_table", "format_table"]

_ALGO_LABELS = {"MORL-D(MOSACDiscrete)-SB": "MORL/D SB", "MORL-D(MOSACDiscrete)-SB+PSA": "MORL/D SB+PSA",
                "MORL-D(MOSAC)-SB": "MORL/D SB", "MORL-D(MOSAC)-SB+PSA": "MORL/D SB+PSA",
                "GPI-LS Continuous Action": "GPI-LS", "GPI-PD Continuous Action": "GPI-PD",
                "PCN continuous action": "PCN", "SAC Discrete Action": "SAC", "SAC Continuous Action": "SAC"}



def algorithm_label(folder: str) -> str:
    """The paper's short name of a published algorithm folder (``"MORL-D(MOSAC)-SB"`` -> ``"MORL/D SB"``)."""
    return _ALGO_LABELS.get(folder, folder)


@dataclass
class TableRow:
    """One (domain, algorithm) line of the table; ``nhgr``/``eugr`` are the ``[seeds, contexts]`` matrices."""

    domain: str
    algorithm: str
    label: str
    seeds: tuple[int, ...]
    contexts: tuple[str, ...]
    nhgr: np.ndarray
    eugr: np.ndarray | None
    iqm_ci: tuple[float, float] | None = None
    og_ci: tuple[float, float] | None = None

    @property
    def mean(self) -> float:
        return float(self.nhgr.mean())

    @property
    def std(self) -> float:
        """Population std (ddof=0) over all seed × context entries, as the paper reports."""
        return float(self.nhgr.std())

    @property
    def iqm(self) -> float:
        return interquartile_mean(self.nhgr)

    @property
    def optimality_gap(self) -> float:
        return optimality_gap(self.nhgr)

    @property
    def paper(self) -> tuple[float, float] | None:
        return PAPER_NHGR.get(self.domain, {}).get(self.label)

    @property
    def matches_paper(self) -> bool | None:
        p = self.paper
        if p is None:
            return None
        return f"{self.mean:.2f} ± {self.std:.2f}" == f"{p[0]:.2f} ± {p[1]:.2f}"

    def as_dict(self) -> dict[str, object]:
        d = {"domain": self.domain, "algorithm": self.algorithm, "label": self.label, "entries": int(self.nhgr.size),
             "nhgr_mean": self.mean, "nhgr_std": self.std, "nhgr_iqm": self.iqm,
             "nhgr_optimality_gap": self.optimality_gap,
             "eugr_mean": None if self.eugr is None else float(self.eugr.mean()),
             "eugr_std": None if self.eugr is None else float(self.eugr.std()),
             "paper_nhgr_mean": None if self.paper is None else self.paper[0],
             "paper_nhgr_std": None if self.paper is None else self.paper[1]}
        if self.iqm_ci is not None:
            d.update(iqm_ci_low=self.iqm_ci[0], iqm_ci_high=self.iqm_ci[1])
        if self.og_ci is not None:
            d.update(og_ci_low=self.og_ci[0], og_ci_high=self.og_ci[1])
        return d


def _ordered(domains: list[str]) -> list[str]:
    known = [d for d in PAPER_ORDER if d in domains]
    return known + sorted(d for d in domains if d not in PAPER_ORDER)


def _eval_weights(domain: str) -> int:
    """The paper's number of evaluation weights for ``domain`` (its spec's; 100 for an unknown domain)."""
    from morl_trl.envs import domain_of

    try:
        return domain_of(domain).eval_weights
    except ValueError:
        return 100


def domain_rows(ref: DomainReference, runs: dict[str, dict[int, dict[str, np.ndarray]]], *,
                num_weights: int | None = None, eugr: bool = True, ci_reps: int = 0, seed: int = 0) -> list[TableRow]:
    """The table rows of one domain from its reference and ``{algo: {seed: {context: front}}}``."""
    n_w = num_weights or _eval_weights(ref.domain)
    weights = energy_weights(ref.num_objectives, n_w).numpy() if eugr else None
    ctxs = ref.contexts
    denom_nhv = {c: ref.specialist_normalized_hypervolume(c) for c in ctxs}
    rows = []
    for algo, by_seed in runs.items():
        seeds = tuple(by_seed)
        nh = np.empty((len(seeds), len(ctxs)))
        eu = np.empty_like(nh) if eugr else None
        for i, s in enumerate(seeds):
            for j, c in enumerate(ctxs):
                if c not in by_seed[s]:
                    raise ValueError(f"{ref.domain}/{algo}/seed_{s}: no front for context {c!r}")
                front = by_seed[s][c]
                if denom_nhv[c] <= 0:
                    raise ValueError(f"{ref.domain}: the specialist front of {c} has zero normalized hypervolume")
                nh[i, j] = min(ref.normalized_hypervolume(c, front) / denom_nhv[c], 1.0)
                if eugr:
                    eu[i, j] = ref.eugr(c, front, weights)
        row = TableRow(ref.domain, algo, algorithm_label(algo), seeds, ctxs, nh, eu)
        if ci_reps:
            _, lo, hi = stratified_bootstrap_ci(nh, "iqm", reps=ci_reps, seed=seed)
            row.iqm_ci = (lo, hi)
            _, lo, hi = stratified_bootstrap_ci(nh, "optimality_gap", reps=ci_reps, seed=seed)
            row.og_ci = (lo, hi)
        rows.append(row)
    return rows


def reference_table(root: str | Path, domains: list[str] | None = None, *, eugr: bool = True, ci_reps: int = 0,
                    seed: int = 0, manifest="published") -> list[TableRow]:
    """Recompute the NHGR table from the reference folder ``root`` (see the module docstring).

    Raises a ``ValueError`` when there is nothing to show (no domain with generalist fronts), and for any malformed
    file or (``manifest``, see :func:`~morl_trl.reporting.reference.load_domain_reference`) a published file that
    is truncated or altered.

    Example:
        >>> rows = reference_table("../shared/reference", ["MOLunarLanderDR-v0"])   # doctest: +SKIP
        >>> [f"{r.mean:.2f} ± {r.std:.2f}" for r in rows if r.label == "GPI-LS"]     # doctest: +SKIP
        ['0.66 ± 0.06']
    """
    available = list_reference_domains(root)
    if domains:
        unknown = [d for d in domains if d not in available]
        if unknown:
            raise ValueError(f"unknown domain(s) {unknown}; {root} has {available}")
    else:
        gen = Path(root) / "generalist_fronts"
        available = [d for d in available if (gen / d).is_dir()]
    rows = []
    for d in _ordered(list(domains or available)):
        ref = load_domain_reference(root, d, manifest=manifest)
        runs = load_generalist_fronts(root, d, ref.contexts, manifest=manifest)
        rows += domain_rows(ref, runs, eugr=eugr, ci_reps=ci_reps, seed=seed)
    if not rows:
        looked = f"domains {list(domains)}" if domains else f"the domains with bounds {list_reference_domains(root)}"
        raise ValueError(
            f"{root}: nothing to show: no generalist fronts (looked for "
            f"generalist_fronts/<domain>/<algorithm>/seed_<n>/<context>.csv for {looked})"
        )
    return rows


def _floor_line(domain: str, floors: dict) -> str | None:
    from morl_trl.reporting.floors import best_floor

    best = best_floor(floors, domain)
    if best is None:
        return None
    n = len(best.nhgr)
    label = f"floor: {best.policy}"
    return (f"  {label:<15} {f'{best.mean:.2f} ± {best.std:.2f}':<16}  "
            f"(best trivial policy; over {n} contexts, 1 seed; morl-trl floors)")


def format_table(rows: list[TableRow], floors: dict | None = None, *, paper_match: bool = True) -> str:
    """Plain-text table, one block per domain, each ending with the domain's floor row.

    ``floors``: a loaded floors file (default the shipped one; ``{}`` for no floor rows).
    ``paper_match``: mark each paper value ``(match)`` or ``(DIFFERS)`` (for the published
    fronts, which must reproduce it; off for our own runs, which are not expected to).
    """
    from morl_trl.reporting.floors import load_floors

    floors = load_floors() if floors is None else floors
    out = []
    has_ci = any(r.iqm_ci is not None for r in rows)
    has_eugr = any(r.eugr is not None for r in rows)
    domain = None
    for r in rows:
        if r.domain != domain:
            if domain is not None and (fl := _floor_line(domain, floors)):
                out.append(fl)
            domain = r.domain
            n_ctx = len(r.contexts)
            out.append("")
            out.append(f"{domain_name(domain)} ({domain}): {n_ctx} contexts, NHGR over seeds x contexts")
            head = f"  {'algorithm':<15} {'NHGR mean ± std':<16} {'IQM':>6} {'OG':>6}"
            if has_ci:
                head += f"  {'IQM 95% CI':<15} {'OG 95% CI':<15}"
            if has_eugr:
                head += f"  {'EUGR mean ± std':<16}"
            head += "  paper"
            out.append(head)
        line = f"  {r.label:<15} {f'{r.mean:.2f} ± {r.std:.2f}':<16} {r.iqm:6.3f} {r.optimality_gap:6.3f}"
        if has_ci:
            ci = "" if r.iqm_ci is None else f"[{r.iqm_ci[0]:.3f}, {r.iqm_ci[1]:.3f}]"
            og = "" if r.og_ci is None else f"[{r.og_ci[0]:.3f}, {r.og_ci[1]:.3f}]"
            line += f"  {ci:<15} {og:<15}"
        if has_eugr:
            eu = "" if r.eugr is None else f"{r.eugr.mean():.2f} ± {r.eugr.std():.2f}"
            line += f"  {eu:<16}"
        p = r.paper
        if p is None:
            line += "  (not in the paper)"
        else:
            line += f"  {p[0]:.2f} ± {p[1]:.2f}"
            if paper_match:
                line += " (match)" if r.matches_paper else " (DIFFERS)"
        out.append(line)
    if domain is not None and (fl := _floor_line(domain, floors)):
        out.append(fl)
    if has_eugr:
        out.append("")
        out.append(
            "EUGR uses the energy weights (100; Mario 32), unnormalized fronts, clipped to [0, 1]; the paper's EUGR "
            "used other (random) weights, so it can differ by a few hundredths."
        )
    return "\n".join(out).lstrip("\n")
