"""Where each cell of a grid stands, read from the files (so any process can ask, at any time).

Layout of a grid directory::

    grid.json                 the spec the grid was last run with
    runs/<cell>/              each cell's run directory (a normal ``morl-trl train`` run)
    cells/<cell>.json         what the grid knows of a cell: status, attempts, error, wall time
    status.json               the last status of every cell (written while the grid runs)
    tune/                     Ray Tune's own experiment records
    report.md, report/        ``morl-trl grid report``: the table, learning curves per domain

A cell is *done* when its newest checkpoint reached its frames (as ``morl-trl train
--resume`` decides there is nothing left to do), *failed* when its last attempt raised (the
error is kept) or its worker died more often than allowed, *running* while an attempt is under
way, *started* when it has a run directory but no attempt is under way (a killed grid: the next
run resumes it), *pending* otherwise.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ["CellState", "cell_state", "grid_status", "write_cell_record", "read_cell_record", "format_status",
           "STATUSES"]

STATUSES = ("done", "running", "failed", "started", "pending")


@dataclass
class CellState:
    """A cell's status, frames reached (newest checkpoint or newer logged episode) and target."""

    name: str
    status: str
    frames: int
    target: int | None
    error: str | None = None
    attempts: int = 0
    wall_s: float | None = None

    def as_dict(self) -> dict:
        return dict(name=self.name, status=self.status, frames=self.frames, target=self.target, error=self.error,
                    attempts=self.attempts, wall_s=self.wall_s)


def _checkpoint_frames(run_dir: Path) -> int | None:
    """The newest complete checkpoint's frames, from ``checkpoints/latest`` (cheap: not verified)."""
    latest = run_dir / "checkpoints" / "latest"
    try:
        name = latest.read_text().strip()
    except OSError:
        return None
    if not (run_dir / "checkpoints" / name / "manifest.json").is_file():
        return None
    try:
        return int(name.split("_")[-1])
    except ValueError:
        return None


def _last_logged_frames(run_dir: Path) -> int:
    """The frame of the last training episode logged (``train/episodes.csv``'s last line)."""
    path = run_dir / "train" / "episodes.csv"
    try:
        with path.open("rb") as fh:
            fh.seek(0, os.SEEK_END)
            size = fh.tell()
            fh.seek(max(size - 4096, 0))
            lines = fh.read().splitlines()
    except OSError:
        return 0
    for line in reversed(lines):
        try:
            return int(float(line.split(b",", 1)[0]))
        except ValueError:
            continue
    return 0


def read_cell_record(grid_dir: str | Path, name: str) -> dict:
    """``cells/<name>.json``, its fields checked: a damaged or hand-edited record (not JSON, not
    an object, a field of the wrong type) loses the bad fields, never crashes ``grid status`` or
    ``grid start`` (the run directory itself says how far the cell got)."""
    path = Path(grid_dir) / "cells" / f"{name}.json"
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(record, dict):
        return {}
    checks = {"status": lambda v: v in STATUSES,
              "attempts": lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0,
              "wall_s": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0,
              "error": lambda v: isinstance(v, str), "traceback": lambda v: isinstance(v, str),
              "pid": lambda v: isinstance(v, int) and not isinstance(v, bool), "host": lambda v: isinstance(v, str),
              "updated": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool)}
    return {k: v for k, v in record.items() if k not in checks or v is None or checks[k](v)}


def write_cell_record(grid_dir: str | Path, name: str, **values) -> dict:
    """Update ``cells/<name>.json`` atomically with ``values``; returns the record."""
    folder = Path(grid_dir) / "cells"
    folder.mkdir(parents=True, exist_ok=True)
    record = {**read_cell_record(grid_dir, name), **values, "updated": time.time()}
    from morl_trl.runs.atomic import atomic_write_text

    atomic_write_text(folder / f"{name}.json", json.dumps(record, indent=1, sort_keys=True))
    return record


def _attempt_alive(record: dict) -> bool:
    """Whether the process of a cell's running attempt may still be alive (``False`` only when it
    ran on this host and its pid is gone: a killed grid leaves ``"running"`` records behind)."""
    pid = record.get("pid")
    if record.get("host") != os.uname().nodename or not isinstance(pid, int):
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def cell_state(grid_dir: str | Path, name: str, target: int | None, *, running: bool | None = None) -> CellState:
    """The state of cell ``name`` (``target``: its frames; ``running``: what the scheduler knows,
    ``None`` to trust the cell's record)."""
    run_dir = Path(grid_dir) / "runs" / name
    record = read_cell_record(grid_dir, name)
    ckpt = _checkpoint_frames(run_dir)
    frames = max(ckpt or 0, _last_logged_frames(run_dir))
    if target is None and (run_dir / "config.json").is_file():
        try:
            target = int(json.loads((run_dir / "config.json").read_text())["frames"])
        except (OSError, ValueError, KeyError, TypeError):
            target = None
    common = dict(attempts=int(record.get("attempts", 0)), wall_s=record.get("wall_s"))
    if ckpt is not None and target is not None and ckpt >= target and record.get("status") != "failed":
        return CellState(name, "done", ckpt, target, **common)
    recorded = record.get("status")
    if running or (running is None and recorded == "running" and _attempt_alive(record)):
        return CellState(name, "running", frames, target, **common)
    if recorded == "failed":
        return CellState(name, "failed", frames, target, error=record.get("error"), **common)
    if run_dir.exists():
        return CellState(name, "started", frames, target, **common)
    return CellState(name, "pending", 0, target, **common)


def grid_status(grid_dir: str | Path, cells=None, *, running: set[str] | None = None) -> list[CellState]:
    """Every cell's :class:`CellState` (``cells``: the spec's :class:`~morl_trl.grid.Cell` list with
    their targets; default the cells of ``grid.json``)."""
    grid_dir = Path(grid_dir)
    if cells is None:
        from morl_trl.grid.spec import GridSpec

        spec_file = grid_dir / "grid.json"
        if not spec_file.is_file():
            raise ValueError(f"{str(grid_dir)!r} is not a grid directory (no grid.json)")
        try:
            data = json.loads(spec_file.read_text())
        except (OSError, ValueError) as err:
            raise ValueError(f"{str(spec_file)!r} does not parse ({err}); run the grid again with its spec file to "
                             f"rewrite it") from None
        spec = GridSpec.from_dict(data, str(spec_file))
        cells = [(c.name, None) for c in spec.cells()]
    out = []
    for name, target in cells:
        run = None if running is None else name in running
        out.append(cell_state(grid_dir, name, target, running=run))
    return out


def format_status(states: list[CellState], elapsed: float | None = None, *, per_cell: bool = True) -> str:
    """One summary line (done / running / failed / started / pending), then a line per cell."""
    counts = {s: sum(1 for c in states if c.status == s) for s in STATUSES}
    head = f"grid: {counts['done']}/{len(states)} done, {counts['running']} running, {counts['failed']} failed"
    rest = counts["started"] + counts["pending"]
    head += f", {rest} to run" + (f" ({counts['started']} started)" if counts["started"] else "")
    if elapsed is not None:
        head += f" [{elapsed:,.0f} s]"
    lines = [head]
    if per_cell:
        width = max((len(c.name) for c in states), default=0)
        for c in states:
            target = f"{c.target:,}" if c.target is not None else "?"
            line = f"  {c.name:<{width}}  {c.status:<8} {c.frames:>11,} / {target} frames"
            if c.error:
                line += f"  error: {c.error.splitlines()[0][:160]}"
            lines.append(line)
    return "\n".join(lines)
