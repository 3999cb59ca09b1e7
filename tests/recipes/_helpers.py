"""What the recipe-equivalence tests share: comparing two runs' checkpoints and logs, and a run
interrupted by Ctrl-C and resumed."""

from __future__ import annotations

import csv

import numpy as np
import pytest
import torch
from tensordict import TensorDictBase

from morl_trl.recipes import train
from morl_trl.runs import latest_checkpoint, load_checkpoint
from morl_trl.runs.interrupt import RunInterrupted
from morl_trl.runs.run import Run

#: every entry of a checkpoint that the training writes (the rest is bookkeeping: paths, versions)
CHECKPOINT_KEYS = ("agent", "env", "carrier", "rng", "frames", "updates", "next_eval", "next_ckpt", "last_eval")


def equal(a, b) -> bool:
    """Exact equality through nested dicts, lists, TensorDicts, tensors and arrays."""
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and np.array_equal(a, b)
    if isinstance(a, TensorDictBase):
        return equal(a.to_dict(), b.to_dict())
    if torch.is_tensor(a):
        return torch.is_tensor(b) and a.shape == b.shape and torch.equal(a, b)
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(equal(x, y) for x, y in zip(a, b))
    return a == b


def csv_rows(path) -> list[dict]:
    """A log's rows without the frame rate (the machine's)."""
    with path.open() as fh:
        return [{k: v for k, v in row.items() if k != "frames_per_second"} for row in csv.DictReader(fh)]


def last_checkpoints(*run_dirs) -> tuple[dict, ...]:
    return tuple(load_checkpoint(latest_checkpoint(d)) for d in run_dirs)


def assert_checkpoints_equal(a: dict, b: dict) -> None:
    for key in CHECKPOINT_KEYS:
        assert equal(a[key], b[key]), key


def assert_logs_equal(a_dir, b_dir) -> None:
    """The two runs' metrics.csv and losses.csv have the same (non-empty) rows."""
    for rel in ("eval/metrics.csv", "train/losses.csv"):
        rows = csv_rows(a_dir / rel)
        assert rows and rows == csv_rows(b_dir / rel), rel


def interrupt_then_resume(monkeypatch, cfg, at: int) -> None:
    """Train ``cfg`` with a Ctrl-C after the batch that ends at ``at`` frames (a checkpoint, then
    :class:`RunInterrupted`), then resume the run to its end."""
    step = Run.step

    def ctrl_c(run, *args, **kw):
        if run.frames == at:
            run._session["interrupt"].requested = True  # (what the first Ctrl-C's handler does)
        return step(run, *args, **kw)

    monkeypatch.setattr(Run, "step", ctrl_c)
    with pytest.raises(RunInterrupted, match=f"interrupted at {at} frames"):
        train(cfg)
    monkeypatch.setattr(Run, "step", step)
    train(resume=cfg.run_dir)
