"""Reference data for the generalization metrics: normalization bounds and specialist fronts.

The published data of the paper (SPEC §3) lies in a folder with this layout::

    <root>/minmax_values/<DomainId>.json                     {context: {"0": [min, max], ...}}
    <root>/specialist_fronts/<DomainId>/<context>.csv         header objective_1..objective_k
    <root>/generalist_fronts/<DomainId>/<algo>/seed_<s>/<context>.csv

:func:`load_domain_reference` reads one domain into a :class:`DomainReference` (the frozen
bounds and the specialist front of every evaluation context) and :func:`load_generalist_fronts`
the final fronts of the published runs. The same types are built from our own runs
(:meth:`DomainReference.from_fronts`) and written back in the same layout
(:meth:`DomainReference.save`), so new domains get reference data the same way.
"""

from __future__ import annotations

import csv
import json
import re
import shutil
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from morl_trl.metrics import Bounds, normalized_hypervolume, pareto_front
from morl_trl.metrics._arrays import as_points
from morl_trl.metrics.generalization import eugr as _eugr
from morl_trl.metrics.generalization import nhgr as _nhgr

__all__ = [
    "DomainReference",
    "read_front_csv",
    "write_front_csv",
    "list_reference_domains",
    "load_domain_reference",
    "load_reference",
    "load_generalist_fronts",
    "pack_reference",
    "PACKAGED_REFERENCE",
]


# --------------------------------------------------------------------------- fronts on disk
def read_front_csv(path: str | Path) -> np.ndarray:
    """Read a front CSV (a header row, then one point per row) as a ``[n, k]`` float64 array."""
    path = Path(path)
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise ValueError(f"{path} is empty (expected a header row objective_1..objective_k)")
    k = len(rows[0])
    body = [r for r in rows[1:] if r]
    try:
        arr = np.array(body, dtype=np.float64).reshape(-1, k)
    except ValueError as e:
        raise ValueError(f"{path}: malformed front ({e})") from None
    return as_points(arr, str(path), allow_empty=True)


def write_front_csv(path: str | Path, front) -> None:
    """Write a ``[n, k]`` front with the header ``objective_1..objective_k``."""
    arr = as_points(front, "front")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"objective_{i + 1}" for i in range(arr.shape[1])])
        w.writerows([[repr(float(v)) for v in row] for row in arr])


# --------------------------------------------------------------------------- types
@dataclass
class DomainReference:
    """Frozen normalization bounds and specialist (approximately optimal) fronts of one domain.

    Args:
        domain: the domain's id, e.g. ``"MOLunarLanderDR-v0"``.
        bounds: evaluation context id -> :class:`Bounds`. Its keys, in order, are the
            domain's evaluation contexts.
        specialist_fronts: context id -> ``[n, k]`` front (one for every context in ``bounds``).

    Example:
        >>> ref = DomainReference.from_fronts("ToyDR-v0", {"Toy-v0": [[2.0, 0.0], [0.0, 2.0], [1.5, 1.5]]})
        >>> ref.bounds["Toy-v0"].upper.tolist()
        [2.0, 2.0]
        >>> ref.nhgr("Toy-v0", [[0.75, 0.75]])
        0.25
        >>> ref.contexts
        ('Toy-v0',)
    """

    domain: str
    bounds: dict[str, Bounds]
    specialist_fronts: dict[str, np.ndarray] = field(repr=False)

    def __post_init__(self) -> None:
        self.bounds = {c: b if isinstance(b, Bounds) else Bounds(*b) for c, b in self.bounds.items()}
        if not self.bounds:
            raise ValueError(f"{self.domain}: a DomainReference needs at least one context")
        missing = [c for c in self.bounds if c not in self.specialist_fronts]
        if missing:
            raise ValueError(f"{self.domain}: contexts {missing} have bounds but no specialist front")
        fronts = {}
        for c in self.bounds:
            fronts[c] = as_points(
                self.specialist_fronts[c], f"specialist front of {c}", dim=self.bounds[c].num_objectives
            )
        self.specialist_fronts = fronts

    @property
    def contexts(self) -> tuple[str, ...]:
        """The evaluation contexts, in order."""
        return tuple(self.bounds)

    @property
    def num_objectives(self) -> int:
        return next(iter(self.bounds.values())).num_objectives

    def _context(self, context: str) -> str:
        if context not in self.bounds:
            raise ValueError(f"{self.domain} has no reference for context {context!r}; valid: {list(self.bounds)}")
        return context

    def normalized_hypervolume(self, context: str, front) -> float:
        b = self.bounds[self._context(context)]
        return normalized_hypervolume(front, b.lower, b.upper)

    def specialist_normalized_hypervolume(self, context: str) -> float:
        return self.normalized_hypervolume(context, self.specialist_fronts[context])

    def nhgr(self, context: str, front) -> float:
        """NHGR of ``front`` in ``context`` (frozen bounds with clipping, specialist denominator)."""
        b = self.bounds[self._context(context)]
        return _nhgr(front, self.specialist_fronts[context], b.lower, b.upper)

    def eugr(self, context: str, front, weights) -> float:
        """EUGR of ``front`` in ``context`` against the specialist front (unnormalized, as the paper)."""
        return _eugr(front, self.specialist_fronts[self._context(context)], weights)

    # ---------------------------------------------------------------- from our own runs
    @classmethod
    def from_fronts(
        cls,
        domain: str,
        specialist_fronts: Mapping[str, object],
        other_fronts: Iterable[Mapping[str, object]] = (),
    ) -> "DomainReference":
        """Build a reference from specialist runs (and, optionally, the fronts of the methods compared).

        ``specialist_fronts`` maps each context to one front or a list of fronts (one per
        specialist run); they are merged into their non-dominated union ("combined front").
        The bounds are the per-objective min and max over that union and every front in
        ``other_fronts`` (each a ``context -> front`` mapping), which is how the published
        bounds were made. Freeze them once built: adding a new method later must reuse them
        (with clipping), or every earlier score changes.
        """
        combined = {}
        for c, fronts in specialist_fronts.items():
            arrs = _as_front_list(fronts, f"specialist front of {c}")
            combined[c] = pareto_front(np.concatenate(arrs, axis=0))
        others = [dict(o) for o in other_fronts]
        bounds = {}
        for c, front in combined.items():
            extra = [a for o in others if c in o for a in _as_front_list(o[c], f"front of {c}")]
            bounds[c] = Bounds.from_points(front, *extra)
        return cls(domain, bounds, combined)

    def save(self, root: str | Path) -> None:
        """Write the bounds and specialist fronts under ``root`` in the published layout."""
        root = Path(root)
        (root / "minmax_values").mkdir(parents=True, exist_ok=True)
        with (root / "minmax_values" / f"{self.domain}.json").open("w") as fh:
            json.dump({c: b.to_json_entry() for c, b in self.bounds.items()}, fh)
        for c, front in self.specialist_fronts.items():
            write_front_csv(root / "specialist_fronts" / self.domain / f"{c}.csv", front)


def _as_front_list(fronts, name: str) -> list[np.ndarray]:
    if isinstance(fronts, (list, tuple)) and fronts and not np.isscalar(fronts[0]) and np.ndim(fronts[0]) == 2:
        return [as_points(f, name) for f in fronts]
    return [as_points(fronts, name)]


# --------------------------------------------------------------------------- loading
def _root(root: str | Path) -> Path:
    root = Path(root)
    if not (root / "minmax_values").is_dir():
        raise ValueError(
            f"{root} is not a reference data folder: it has no minmax_values/ "
            "(expected minmax_values/, specialist_fronts/ and generalist_fronts/)"
        )
    return root


#: the metric's constants shipped with the package: bounds and specialist fronts (data/SOURCE.txt)
PACKAGED_REFERENCE = Path(__file__).with_name("data")


def list_reference_domains(root: str | Path) -> list[str]:
    """The domain ids that have bounds under ``root``."""
    return sorted(p.stem for p in _root(root).joinpath("minmax_values").glob("*.json"))


def load_domain_reference(root: str | Path | None, domain: str | None = None) -> DomainReference:
    """Read the frozen bounds and specialist fronts of ``domain`` from ``root``.

    ``load_domain_reference(domain)`` (or ``root=None``) reads the copies shipped with the
    package (:data:`PACKAGED_REFERENCE`), so NHGR works on any install. The evaluation
    contexts are the keys of the bounds file, in its order (the specialist folder may hold
    extra contexts, e.g. LunarLander's StartLow, which are not loaded).

    Example:
        >>> ref = load_domain_reference("MOLunarLanderDR-v0")      # the shipped constants
        >>> len(ref.contexts), ref.num_objectives
        (8, 4)
    """
    if domain is None:
        root, domain = None, root
    root = _root(PACKAGED_REFERENCE if root is None else root)
    path = root / "minmax_values" / f"{domain}.json"
    if not path.is_file():
        raise ValueError(f"no bounds for domain {domain!r} under {root}; available: {list_reference_domains(root)}")
    with path.open() as fh:
        raw = json.load(fh)
    bounds = {c: Bounds.from_json_entry(e) for c, e in raw.items()}
    fronts = {}
    for c in bounds:
        p = root / "specialist_fronts" / domain / f"{c}.csv"
        if not p.is_file():
            raise ValueError(f"{domain}: missing specialist front {p}")
        fronts[c] = read_front_csv(p)
    return DomainReference(domain, bounds, fronts)


def pack_reference(source: str | Path, destination: str | Path = PACKAGED_REFERENCE) -> list[Path]:
    """Copy the bounds and the evaluation contexts' specialist fronts of every domain under
    ``source`` (the published layout) to ``destination`` (default: the package's own copy);
    every domain is loaded first, so a damaged source changes nothing. Returns the files written."""
    source = _root(source)
    domains = list_reference_domains(source)
    refs = [load_domain_reference(source, d) for d in domains]  # validates before anything is written
    destination = Path(destination)
    written = []
    for domain, ref in zip(domains, refs):
        out = destination / "minmax_values" / f"{domain}.json"
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source / "minmax_values" / f"{domain}.json", out)
        written.append(out)
        for c in ref.contexts:
            out = destination / "specialist_fronts" / domain / f"{c}.csv"
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source / "specialist_fronts" / domain / f"{c}.csv", out)
            written.append(out)
    return written


def load_reference(root: str | Path) -> dict[str, DomainReference]:
    """Every domain under ``root``: domain id -> :class:`DomainReference`."""
    return {d: load_domain_reference(root, d) for d in list_reference_domains(root)}


_SEED = re.compile(r"^seed_(\d+)$")


def load_generalist_fronts(
    root: str | Path, domain: str, contexts: Iterable[str] | None = None
) -> dict[str, dict[int, dict[str, np.ndarray]]]:
    """Final fronts of the published runs: ``{algorithm: {seed: {context: [n, k] front}}}``.

    Only the top-level algorithm folders are read (the paper's data; e.g. MuJoCo's
    ``no_history/`` folder holds other runs). ``contexts`` restricts (and orders) the
    contexts; by default every CSV found is read.
    """
    base = _root(root) / "generalist_fronts" / domain
    if not base.is_dir():
        raise ValueError(f"no generalist fronts for domain {domain!r} under {base.parent}")
    wanted = None if contexts is None else list(contexts)
    out: dict[str, dict[int, dict[str, np.ndarray]]] = {}
    for algo_dir in sorted(p for p in base.iterdir() if p.is_dir()):
        seeds = {}
        for seed_dir in sorted(algo_dir.iterdir()):
            m = _SEED.match(seed_dir.name)
            if not (seed_dir.is_dir() and m):
                continue
            names = wanted if wanted is not None else sorted(p.stem for p in seed_dir.glob("*.csv"))
            fronts = {}
            for c in names:
                p = seed_dir / f"{c}.csv"
                if not p.is_file():
                    raise ValueError(f"{domain}/{algo_dir.name}/{seed_dir.name}: missing front for context {c!r} ({p})")
                fronts[c] = read_front_csv(p)
            seeds[int(m.group(1))] = fronts
        if seeds:
            out[algo_dir.name] = dict(sorted(seeds.items()))
    return out
