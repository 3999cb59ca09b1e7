"""Reference data for the generalization metrics: normalization bounds and specialist fronts.

The published data of the paper (SPEC §3) lies in a folder with this layout::

    <root>/minmax_values/<DomainId>.json                     {context: {"0": [min, max], ...}}
    <root>/specialist_fronts/<DomainId>/<context>.csv         header objective_1..objective_k
    <root>/generalist_fronts/<DomainId>/<algo>/seed_<s>/<context>.csv

:func:`load_domain_reference` reads one domain into a :class:`DomainReference` (the frozen bounds and the
specialist front of every evaluation context) and :func:`load_generalist_fronts` the final fronts of the published
runs. The same types are built from our own runs (:meth:`DomainReference.from_fronts`) and written back in the same
layout (:meth:`DomainReference.save`), so new domains get reference data the same way.

Every file the loaders read is checked: a malformed file raises a ``ValueError`` naming the file and what is wrong,
and a file whose path (relative to the folder) is listed in the reference manifest (``reference_manifest.json``,
shipped with the package: the row count and SHA-256 of every published file, made by ``morl-trl reference-manifest
DIR --write``) must have the listed row count and content, so a truncated or altered copy of the published data is
an error rather than a silently different table. Pass ``manifest=None`` to read other data in the same layout
without that check.
"""

from __future__ import annotations

import csv
import functools
import hashlib
import io
import json
import re
import shutil
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from morl_trl.metrics import Bounds, as_points, normalized_hypervolume, pareto_front
from morl_trl.metrics.generalization import eugr as _eugr
from morl_trl.metrics.generalization import nhgr as _nhgr

__all__ = ["DomainReference", "read_front_csv", "write_front_csv", "list_reference_domains", "load_domain_reference",
           "load_reference", "load_generalist_fronts", "pack_reference", "PACKAGED_REFERENCE", "MANIFEST_PATH",
           "build_manifest", "load_manifest", "verify_reference"]

#: the manifest of the published reference data, shipped with the package
MANIFEST_PATH = Path(__file__).with_name("reference_manifest.json")
_MANIFEST_FORMAT = "morl_trl-reference-manifest/1"
_PUBLISHED = "published"  # the default ``manifest`` argument: the shipped manifest


# --------------------------------------------------------------------------- fronts on disk
def read_front_csv(path: str | Path) -> np.ndarray:
    """Read a front CSV (a header row, then one point per row) as a ``[n, k]`` float64 array."""
    path = Path(path)
    return _parse_front(path, _read_text(path))


def _read_text(path: Path, data: bytes | None = None) -> str:
    try:
        data = path.read_bytes() if data is None else data
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: not a UTF-8 text file ({e})") from None
    except OSError as e:
        raise ValueError(f"{path}: cannot be read ({e.strerror or e})") from None


def _csv_rows(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text, newline="")))


def _parse_front(path: Path, text: str) -> np.ndarray:
    try:
        rows = _csv_rows(text)
    except csv.Error as e:
        raise ValueError(f"{path}: malformed CSV ({e})") from None
    if not rows:
        raise ValueError(f"{path} is empty (expected a header row objective_1..objective_k)")
    k = len(rows[0])
    header = [h.strip() for h in rows[0]]
    if header != [f"objective_{i + 1}" for i in range(k)]:
        raise ValueError(f"{path}: the header row is {rows[0]}; expected objective_1..objective_k")
    body = [r for r in rows[1:] if r]
    for line, r in enumerate(body, start=2):
        if len(r) != k:
            raise ValueError(f"{path}: row {line} has {len(r)} values, the header {k} (is the file cut short?)")
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
        bounds: evaluation context id -> :class:`Bounds`. Its keys, in order, are the domain's evaluation contexts.
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
            fronts[c] = as_points(self.specialist_fronts[c], f"specialist front of {c}",
                                  dim=self.bounds[c].num_objectives)
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
    def from_fronts(cls, domain: str, specialist_fronts: Mapping[str, object],
                    other_fronts: Iterable[Mapping[str, object]] = ()) -> "DomainReference":
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


# --------------------------------------------------------------------------- the manifest
def _rel(root: Path, path: Path) -> str:
    return path.relative_to(root).as_posix()


def _count_rows(path: Path, text: str) -> int:
    """Data rows of a front CSV (non-empty rows after the header) or contexts of a bounds JSON."""
    if path.suffix == ".json":
        raw = _parse_json(path, text)
        return len(raw)
    return max(sum(1 for r in _csv_rows(text) if r) - 1, 0)


def _manifest_files(root: Path) -> list[Path]:
    files = sorted((root / "minmax_values").glob("*.json"))
    for sub in ("specialist_fronts", "generalist_fronts"):
        if (root / sub).is_dir():
            files += sorted((root / sub).rglob("*.csv"))
    return files


def build_manifest(root: str | Path) -> dict:
    """The manifest of a reference folder: for every bounds JSON and front CSV (path relative
    to ``root``), its row count (CSV data rows; JSON contexts) and SHA-256."""
    root = _root(root)
    files = {}
    for path in _manifest_files(root):
        data = path.read_bytes()
        files[_rel(root, path)] = {"rows": _count_rows(path, _read_text(path, data)),
                                   "sha256": hashlib.sha256(data).hexdigest()}
    if not files:
        raise ValueError(f"{root}: no reference files found (looked for minmax_values/*.json, "
                         "specialist_fronts/**/*.csv and generalist_fronts/**/*.csv)")
    return {"format": _MANIFEST_FORMAT, "files": files}


def write_manifest(manifest: dict, path: str | Path = MANIFEST_PATH) -> Path:
    """Write ``manifest`` as JSON, one file per line (readable diffs)."""
    path = Path(path)
    lines = [f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in manifest["files"].items()]
    path.write_text('{"format": ' + json.dumps(manifest["format"]) + ', "files": {\n' + ",\n".join(lines) + "\n}}\n")
    return path


@functools.lru_cache(maxsize=4)
def _load_manifest_file(path: str) -> dict:
    p = Path(path)
    try:
        raw = json.loads(_read_text(p))
    except json.JSONDecodeError as e:
        raise ValueError(f"{p}: the reference manifest is not valid JSON ({e})") from None
    if not isinstance(raw, dict) or raw.get("format") != _MANIFEST_FORMAT or not isinstance(raw.get("files"), dict):
        raise ValueError(f"{p}: not a reference manifest (expected {{'format': {_MANIFEST_FORMAT!r}, 'files': {{...}}}})")
    return raw


def load_manifest(manifest=_PUBLISHED) -> dict | None:
    """The manifest named by a loader's ``manifest`` argument: ``"published"`` (the shipped
    :data:`MANIFEST_PATH`), a path, a dict (as :func:`build_manifest` returns), or ``None``."""
    if manifest is None or isinstance(manifest, dict):
        return manifest
    path = MANIFEST_PATH if manifest == _PUBLISHED else Path(manifest)
    if manifest == _PUBLISHED and not path.is_file():  # a source tree without the generated file
        return None
    return _load_manifest_file(str(path))


def _check_file(root: Path, path: Path, data: bytes, rows: int, manifest: dict | None) -> None:
    """Compare a loaded file with its manifest entry, if any (see the module docstring)."""
    if manifest is None:
        return
    entry = manifest["files"].get(_rel(root, path))
    if entry is None:
        return
    unit = "contexts" if path.suffix == ".json" else "rows"
    if rows != entry["rows"]:
        raise ValueError(
            f"{path}: expected {entry['rows']} {unit} (the published file, per the reference manifest), "
            f"found {rows}: the file is truncated or altered"
        )
    digest = hashlib.sha256(data).hexdigest()
    if digest != entry["sha256"]:
        raise ValueError(
            f"{path}: its content differs from the published file ({rows} {unit} as expected, but SHA-256 "
            f"{digest[:12]}... instead of {entry['sha256'][:12]}...); pass manifest=None to read other data"
        )


def verify_reference(root: str | Path, manifest=_PUBLISHED) -> list[str]:
    """Every difference between the folder ``root`` and ``manifest`` (missing files, row counts,
    contents), one line each; empty when the folder holds exactly the published data."""
    root = _root(root)
    manifest = load_manifest(manifest)
    if manifest is None:
        raise ValueError(f"no reference manifest at {MANIFEST_PATH} (generate it: morl-trl reference-manifest DIR --write)")
    problems = []
    for rel in manifest["files"]:
        path = root / rel
        if not path.is_file():
            problems.append(f"{path}: missing")
            continue
        data = path.read_bytes()
        try:
            _check_file(root, path, data, _count_rows(path, _read_text(path, data)), manifest)
        except ValueError as e:
            problems.append(str(e))
    known = set(manifest["files"])
    problems += [f"{p}: not in the manifest" for p in _manifest_files(root) if _rel(root, p) not in known]
    return problems


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


def _parse_json(path: Path, text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON ({e})") from None


def _load_bounds(root: Path, path: Path, manifest: dict | None) -> dict[str, Bounds]:
    data = path.read_bytes()
    raw = _parse_json(path, _read_text(path, data))
    layout = 'an object {context: {"0": [min, max], "1": [min, max], ...}}'
    if not isinstance(raw, dict):
        raise ValueError(f"{path}: expected {layout}, got a JSON {type(raw).__name__}")
    if not raw:
        raise ValueError(f"{path}: no contexts (expected {layout})")
    _check_file(root, path, data, len(raw), manifest)
    bounds = {}
    for c, e in raw.items():
        if not isinstance(e, dict):
            raise ValueError(f"{path}: context {c!r} maps to a JSON {type(e).__name__}; expected {layout}")
        for key, pair in e.items():
            if not (isinstance(pair, list) and len(pair) == 2
                    and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in pair)):
                raise ValueError(f"{path}: context {c!r}, objective {key!r} is {pair!r}; expected [min, max] numbers")
        try:
            bounds[c] = Bounds.from_json_entry(e)
        except (ValueError, TypeError, IndexError) as err:
            raise ValueError(f"{path}: context {c!r}: {err}") from None
    return bounds


def _load_front(root: Path, path: Path, manifest: dict | None) -> np.ndarray:
    data = path.read_bytes()
    text = _read_text(path, data)
    front = _parse_front(path, text)
    _check_file(root, path, data, _count_rows(path, text), manifest)
    return front


def load_domain_reference(root: str | Path | None, domain: str | None = None, *,
                          manifest=_PUBLISHED) -> DomainReference:
    """Read the frozen bounds and specialist fronts of ``domain`` from ``root``.

    ``load_domain_reference(domain)`` (or ``root=None``) reads the copies shipped with the package
    (:data:`PACKAGED_REFERENCE`), so NHGR works on any install. The evaluation contexts are the keys of the bounds
    file, in its order (the specialist folder may hold extra contexts, e.g. LunarLander's StartLow, which are not
    loaded). Files listed in ``manifest`` (default: the published data's) are checked against it.

    Example:
        >>> ref = load_domain_reference("MOLunarLanderDR-v0")      # the shipped constants
        >>> len(ref.contexts), ref.num_objectives
        (8, 4)
    """
    if domain is None:
        root, domain = None, root
    root = _root(PACKAGED_REFERENCE if root is None else root)
    manifest = load_manifest(manifest)
    path = root / "minmax_values" / f"{domain}.json"
    if not path.is_file():
        raise ValueError(f"no bounds for domain {domain!r} under {root}; available: {list_reference_domains(root)}")
    bounds = _load_bounds(root, path, manifest)
    fronts = {}
    for c in bounds:
        p = root / "specialist_fronts" / domain / f"{c}.csv"
        if not p.is_file():
            raise ValueError(f"{domain}: missing specialist front {p}")
        fronts[c] = _load_front(root, p, manifest)
    try:
        return DomainReference(domain, bounds, fronts)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None


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


def load_reference(root: str | Path, *, manifest=_PUBLISHED) -> dict[str, DomainReference]:
    """Every domain under ``root``: domain id -> :class:`DomainReference`."""
    return {d: load_domain_reference(root, d, manifest=manifest) for d in list_reference_domains(root)}


_SEED = re.compile(r"^seed_(\d+)$")


def load_generalist_fronts(root: str | Path, domain: str, contexts: Iterable[str] | None = None, *,
                           manifest=_PUBLISHED) -> dict[str, dict[int, dict[str, np.ndarray]]]:
    """Final fronts of the published runs: ``{algorithm: {seed: {context: [n, k] front}}}``.

    Only the top-level algorithm folders are read (the paper's data; e.g. MuJoCo's ``no_history/`` folder holds
    other runs). ``contexts`` restricts (and orders) the contexts; by default every CSV found is read. Files listed
    in ``manifest`` (default: the published data's) are checked against it.
    """
    root = _root(root)
    manifest = load_manifest(manifest)
    base = root / "generalist_fronts" / domain
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
                fronts[c] = _load_front(root, p, manifest)
            seeds[int(m.group(1))] = fronts
        if seeds:
            out[algo_dir.name] = dict(sorted(seeds.items()))
    return out
