"""Checkpoints that hold everything a run needs to continue.

A checkpoint is a directory ``checkpoints/frames_<N>/`` with ``state.pt`` (networks,
optimizers, target params, schedules, transform generators, RNG states, counters) and
``buffer/`` (the replay buffer, TorchRL's own ``dumps`` format). It is written to a temporary
directory and renamed into place, so a kill mid-write leaves the previous checkpoint intact;
``latest`` points at the newest complete one.
"""

from __future__ import annotations

import os
import random
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import torch

__all__ = ["save_checkpoint", "load_checkpoint", "latest_checkpoint", "rng_state", "set_rng_state"]


def rng_state() -> dict[str, Any]:
    """Python's, NumPy's and torch's global generator states."""
    state = {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state()}
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def set_rng_state(state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])


def save_checkpoint(run_dir: str | Path, frames: int, state: dict[str, Any], replay_buffer=None, keep: int = 2) -> Path:
    """Atomically write a checkpoint at ``frames`` and prune all but the ``keep`` newest."""
    root = Path(run_dir) / "checkpoints"
    root.mkdir(parents=True, exist_ok=True)
    final = root / f"frames_{frames:012d}"
    tmp = root / f".tmp_frames_{frames:012d}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    torch.save(state, tmp / "state.pt")
    if replay_buffer is not None:
        replay_buffer.dumps(tmp / "buffer")
    shutil.rmtree(final, ignore_errors=True)
    os.replace(tmp, final)
    latest = root / "latest"
    tmp_link = root / ".latest_tmp"
    tmp_link.write_text(final.name)
    os.replace(tmp_link, latest)
    for old in sorted(p for p in root.glob("frames_*") if p.is_dir())[:-keep]:
        shutil.rmtree(old, ignore_errors=True)
    return final


def latest_checkpoint(run_dir: str | Path) -> Path | None:
    """The newest complete checkpoint directory of a run, or ``None``."""
    root = Path(run_dir) / "checkpoints"
    latest = root / "latest"
    if latest.is_file():
        path = root / latest.read_text().strip()
        if (path / "state.pt").is_file():
            return path
    done = sorted(p for p in root.glob("frames_*") if (p / "state.pt").is_file())
    return done[-1] if done else None


def load_checkpoint(path: str | Path, replay_buffer=None) -> dict[str, Any]:
    """Read ``state.pt`` (and refill ``replay_buffer`` in place, if given)."""
    path = Path(path)
    state = torch.load(path / "state.pt", weights_only=False)
    if replay_buffer is not None and (path / "buffer").exists():
        replay_buffer.loads(path / "buffer")
    return state
