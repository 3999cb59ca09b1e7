"""What a grid is: algorithms × domains × seeds, each cell a ``morl-trl train`` run.

A grid spec is a TOML (or JSON) file or the same keys in Python::

    name = "paper"
    seeds = [0, 1, 2, 3, 4]
    quick = false                      # the --quick preset for every cell
    overrides = { logger = "csv" }     # config keys for every cell (any TrainConfig key)
    resources = { cpus = 1, gpus = 0 } # what Ray reserves per run (gpus may be a fraction: 0.25)

    [[block]]                          # one cartesian product (several blocks: their union)
    algorithms = ["envelope"]
    domains = ["MOLunarLanderDR-v0", "MOLavaGridDR-v0"]

    [[cell]]                           # per-cell overrides: every cell matching the given fields
    algorithm = "envelope"             # (omitted fields match every cell)
    domain = "MOLavaGridDR-v0"
    overrides = { frames = 2_000_000 }
    resources = { gpus = 0.5 }

Top-level ``algorithms`` / ``domains`` are one block. Algorithm names are those of
:data:`morl_trl.recipes.config.ALGORITHMS` (an algorithm added there is available here); an
unknown name, domain, key or value raises a ``ValueError`` naming it and what is valid, before
anything runs (every cell's config is resolved and checked).

Example:
    >>> spec = GridSpec.from_dict({"algorithms": ["envelope", "mosac_discrete"],
    ...                            "domains": ["MOLavaGridDR-v0"], "seeds": [0, 1]})
    >>> [c.name for c in spec.cells()]        # doctest: +NORMALIZE_WHITESPACE
    ['envelope__MOLavaGridDR-v0__s0', 'envelope__MOLavaGridDR-v0__s1',
     'mosac_discrete__MOLavaGridDR-v0__s0', 'mosac_discrete__MOLavaGridDR-v0__s1']
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["Cell", "GridSpec", "load_grid_spec", "read_grid_file", "QUICK_GRID"]

_TOP_KEYS = ("name", "seeds", "quick", "overrides", "resources", "algorithms", "domains", "block", "cell")
_RESOURCE_KEYS = ("cpus", "gpus")

#: the built-in ``--quick`` grid (``examples/grid/quick.toml``): 2 algorithms × MO-LunarLander ×
#: 2 seeds, each a shortened ``--quick`` run (16k frames, 8 evaluation weights: about a minute
#: of one CPU core each)
QUICK_GRID: dict[str, Any] = {
    "name": "quick",
    "algorithms": ["envelope", "mosac_discrete"],
    "domains": ["MOLunarLanderDR-v0"],
    "seeds": [0, 1],
    "quick": True,
    "overrides": {"frames": 16_000, "eval_interval": 4_000, "checkpoint_interval": 4_000},
}


@dataclass(frozen=True)
class Cell:
    """One run of the grid: ``morl-trl train <algo> <env_id> --seed <seed>`` with ``overrides``."""

    algo: str
    env_id: str
    seed: int
    overrides: dict = field(default_factory=dict, compare=False, hash=False)
    cpus: float = 1.0
    gpus: float = 0.0
    quick: bool = False

    @property
    def name(self) -> str:
        """The cell's run directory name under ``<grid>/runs/``."""
        return f"{self.algo}__{self.env_id}__s{self.seed}"

    def config(self, run_dir: str | Path | None = None, *, check_device: bool = True):
        """The cell's resolved :class:`~morl_trl.recipes.TrainConfig` (``resolve_config`` with
        its overrides, no progress bar; ``device="cuda"`` when it asks for a GPU and names no
        device; ``num_threads`` = its whole CPUs when it reserves more than one and names none).

        ``check_device=False`` resolves with ``device="cpu"`` (to check a cell on a driver
        without the GPU its worker will have)."""
        from morl_trl.recipes import resolve_config

        values = {"progress": False, **self.overrides}
        if self.cpus >= 2 and "num_threads" not in self.overrides:
            values["num_threads"] = int(self.cpus)
        if self.gpus > 0 and "device" not in self.overrides:
            values["device"] = "cuda"
        if not check_device:
            values["device"] = "cpu"
        if run_dir is not None:
            values["run_dir"] = str(run_dir)
        return resolve_config(self.algo, self.env_id, quick=self.quick, seed=self.seed, **values)


def _algorithms() -> tuple[str, ...]:
    from morl_trl.recipes.config import ALGORITHMS

    return tuple(ALGORITHMS)


def _str_list(value, key: str, source: str) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, (list, tuple)) or not value or not all(isinstance(v, str) and v for v in value):
        raise ValueError(f"{source}: {key} is {value!r}; valid: a non-empty list of names")
    return tuple(dict.fromkeys(value))


def _seeds(value, source: str) -> tuple[int, ...]:
    if isinstance(value, int) and not isinstance(value, bool):
        value = [value]
    ok = isinstance(value, (list, tuple)) and value and all(
        isinstance(s, int) and not isinstance(s, bool) and 0 <= s < 2**63 for s in value)
    if not ok:
        raise ValueError(f"{source}: seeds is {value!r}; valid: a non-empty list of ints in [0, 2**63 - 1]")
    return tuple(dict.fromkeys(value))


def _resources(value, source: str) -> dict[str, float]:
    if not isinstance(value, dict):
        raise ValueError(f"{source}: resources is {value!r}; valid: a table with keys {list(_RESOURCE_KEYS)}")
    unknown = sorted(set(value) - set(_RESOURCE_KEYS))
    if unknown:
        raise ValueError(f"{source}: unknown resource key(s) {unknown}; valid: {list(_RESOURCE_KEYS)}")
    out = {}
    for k, v in value.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise ValueError(f"{source}: resources.{k} is {v!r}; valid: a number >= 0 (a fraction shares a device)")
        out[k] = float(v)
    if out.get("cpus", 1.0) == 0 and out.get("gpus", 0.0) == 0:
        raise ValueError(f"{source}: resources reserve nothing (cpus = 0 and gpus = 0); give cpus > 0 or gpus > 0")
    return out


def _table(value, key: str, source: str) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{source}: {key} is {value!r}; valid: a table of config keys")
    from morl_trl.recipes.config import config_values

    flat = config_values(value, f"{source}: {key}")
    bad = sorted(set(flat) & {"algo", "env_id", "seed", "run_dir"})
    if bad:
        raise ValueError(f"{source}: {key} may not set {bad}: the grid sets them per cell")
    return flat


@dataclass
class GridSpec:
    """Algorithms × domains × seeds (one or more blocks), shared and per-cell overrides, resources.

    Build it with :meth:`from_dict` or :func:`load_grid_spec`; :meth:`cells` lists the runs.
    """

    blocks: list[tuple[tuple[str, ...], tuple[str, ...]]]
    seeds: tuple[int, ...]
    name: str = "grid"
    quick: bool = False
    overrides: dict = field(default_factory=dict)
    resources: dict = field(default_factory=dict)
    cell_rules: list[dict] = field(default_factory=list)

    @classmethod
    def from_dict(cls, data: dict, source: str = "grid spec") -> "GridSpec":
        if not isinstance(data, dict):
            raise ValueError(f"{source}: a grid spec is a table of keys, not {type(data).__name__}")
        unknown = sorted(set(data) - set(_TOP_KEYS))
        if unknown:
            raise ValueError(f"{source}: unknown key(s) {unknown}; valid: {list(_TOP_KEYS)}")
        blocks = []
        raw_blocks = list(data.get("block", []))
        if "algorithms" in data or "domains" in data:
            raw_blocks.insert(0, {"algorithms": data.get("algorithms"), "domains": data.get("domains")})
        if not raw_blocks:
            raise ValueError(f"{source}: no cells: give algorithms and domains (or [[block]] tables)")
        valid = _algorithms()
        from morl_trl.envs import load_domain_modules

        # a user's own domains (overrides.domain_modules, as --domain-module) before their ids are checked
        load_domain_modules(_table(data.get("overrides", {}), "overrides", source).get("domain_modules", ()))
        for i, b in enumerate(raw_blocks):
            where = f"{source}: block {i}"
            if not isinstance(b, dict) or set(b) - {"algorithms", "domains"}:
                raise ValueError(f"{where} is {b!r}; valid: a table with algorithms and domains")
            algos = _str_list(b.get("algorithms"), "algorithms", where)
            domains = _str_list(b.get("domains"), "domains", where)
            bad = [a for a in algos if a not in valid]
            if bad:
                raise ValueError(f"{where}: algorithm(s) {bad} are not available; valid: {list(valid)}")
            from morl_trl.envs import domain_of

            for d in domains:
                domain_of(d)  # raises naming the id and close matches
            blocks.append((algos, domains))
        seeds = _seeds(data.get("seeds", [0]), source)
        quick = data.get("quick", False)
        if not isinstance(quick, bool):
            raise ValueError(f"{source}: quick is {quick!r}; valid: true or false")
        name = data.get("name", "grid")
        if not isinstance(name, str) or not name:
            raise ValueError(f"{source}: name is {name!r}; valid: a non-empty string")
        rules = []
        for i, r in enumerate(data.get("cell", [])):
            where = f"{source}: cell {i}"
            if not isinstance(r, dict) or set(r) - {"algorithm", "domain", "seed", "overrides", "resources"}:
                raise ValueError(f"{where} is {r!r}; valid keys: algorithm, domain, seed, overrides, resources")
            rules.append({
                "algorithm": r.get("algorithm"), "domain": r.get("domain"), "seed": r.get("seed"),
                "overrides": _table(r.get("overrides", {}), "overrides", where),
                "resources": _resources(r.get("resources", {}), where),
            })
        spec = cls(blocks, seeds, name, quick, _table(data.get("overrides", {}), "overrides", source),
                   _resources(data.get("resources", {}), source), rules)
        for i, r in enumerate(rules):
            if not any(_matches(r, c) for c in spec._plain_cells()):
                raise ValueError(f"{source}: cell {i} ({_rule_text(r)}) matches no cell of the grid")
        return spec

    def _plain_cells(self) -> list[tuple[str, str, int]]:
        seen = {}
        for algos, domains in self.blocks:
            for a in algos:
                for d in domains:
                    for s in self.seeds:
                        seen[(a, d, s)] = None
        return list(seen)

    def cells(self) -> list[Cell]:
        """Every cell, block by block (duplicates once), with its overrides and resources."""
        out = []
        for a, d, s in self._plain_cells():
            overrides, resources = dict(self.overrides), {"cpus": 1.0, "gpus": 0.0, **self.resources}
            for r in self.cell_rules:
                if _matches(r, (a, d, s)):
                    overrides.update(r["overrides"])
                    resources.update(r["resources"])
            out.append(Cell(a, d, s, overrides, resources["cpus"], resources["gpus"], self.quick))
        return out

    def check(self) -> list[Cell]:
        """Resolve every cell's config (``ValueError`` naming the cell and the fault); returns the cells."""
        cells = self.cells()
        for c in cells:
            try:
                c.config(check_device=False)
            except ValueError as err:
                raise ValueError(f"cell {c.name}: {err}") from None
        return cells

    def to_dict(self) -> dict:
        return {
            "name": self.name, "seeds": list(self.seeds), "quick": self.quick,
            "overrides": {k: list(v) if isinstance(v, tuple) else v for k, v in self.overrides.items()},
            "resources": self.resources,
            "block": [{"algorithms": list(a), "domains": list(d)} for a, d in self.blocks],
            "cell": [{k: v for k, v in r.items() if v is not None} for r in self.cell_rules],
        }


def _matches(rule: dict, cell: tuple[str, str, int]) -> bool:
    a, d, s = cell
    return ((rule["algorithm"] is None or rule["algorithm"] == a) and (rule["domain"] is None or rule["domain"] == d)
            and (rule["seed"] is None or rule["seed"] == s))


def _rule_text(rule: dict) -> str:
    return ", ".join(f"{k}={rule[k]!r}" for k in ("algorithm", "domain", "seed") if rule[k] is not None) or "all"


def load_grid_spec(path: str | Path) -> GridSpec:
    """Read a grid spec from a ``.toml`` or ``.json`` file (see the module docstring)."""
    return GridSpec.from_dict(read_grid_file(path), f"grid spec {str(path)!r}")


def read_grid_file(path: str | Path) -> dict:
    """The raw table of a grid spec file (``ValueError`` if it is missing or does not parse)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"grid spec {str(path)!r} does not exist")
    try:
        if path.suffix == ".toml":
            data = tomllib.loads(path.read_text())
        elif path.suffix == ".json":
            data = json.loads(path.read_text())
        else:
            raise ValueError(f"grid spec {str(path)!r}: use a .toml or .json file")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"grid spec {str(path)!r} does not parse: {err}") from None
    return data
