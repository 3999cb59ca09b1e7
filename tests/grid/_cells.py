"""Cells that misbehave once, for the grid's fault-tolerance tests (imported by the Ray workers).

``flaky_run_cell`` runs a cell as :func:`morl_trl.grid.runner.run_cell` does, except on the first
attempt of seed 1: right after the checkpoint at 256 frames it SIGKILLs its own worker (envelope:
a killed worker, which Ray Tune retries) or raises a ``NonFiniteLossError`` (any other algorithm:
a failing cell, recorded and not retried).
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

KILL_AT = 256


def flaky_run_cell(cell, run_dir: Path) -> dict:
    import morl_trl.runs.run as run_module  # (every checkpoint of a run is written through its Run)
    from morl_trl.grid.runner import run_cell
    from morl_trl.recipes import NonFiniteLossError

    marker = Path(run_dir).parent.parent / f"misbehaved_{cell.name}"
    if cell.seed != 1 or marker.exists():
        return run_cell(cell, run_dir)
    marker.write_text("")
    original = run_module.save_checkpoint

    def save_then_misbehave(run, frames, *args, **kwargs):
        path = original(run, frames, *args, **kwargs)
        if frames == KILL_AT:
            if cell.algo == "envelope":
                os.kill(os.getpid(), signal.SIGKILL)
            raise NonFiniteLossError(f"injected: a non-finite loss after the checkpoint at {frames} frames")
        return path

    run_module.save_checkpoint = save_then_misbehave
    try:
        return run_cell(cell, run_dir)
    finally:
        run_module.save_checkpoint = original
