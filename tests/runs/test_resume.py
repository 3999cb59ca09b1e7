"""Runs survive a kill: a resumed run's files equal an uninterrupted run's, byte for byte."""

from __future__ import annotations

import pytest

import csv
from pathlib import Path

import torch

from morl_trl.recipes import resolve_config, train
from morl_trl.runs import load_checkpoint
from tests.runs._helpers import TINY, cli, run_and_kill, write_config

# the files that must come out the same (log.txt, report.md and the frames/s curve hold times)
def _outputs(run: Path) -> dict[str, bytes]:
    files = [run / "eval" / "metrics.csv", run / "eval" / "episodes.csv", run / "train" / "episodes.csv",
             *sorted((run / "fronts").glob("*.csv")),
             *sorted(p for p in (run / "logs").rglob("*.csv") if p.name != "frames_per_second.csv")]
    return {str(f.relative_to(run)): f.read_bytes() for f in files}


def _latest_frames(run: Path) -> int:
    latest = run / "checkpoints" / "latest"
    return int(latest.read_text().split("_")[-1]) if latest.is_file() else -1


def _last_eval_frames(run: Path) -> int:
    path = run / "eval" / "metrics.csv"
    if not path.is_file():
        return -1
    with path.open() as fh:
        rows = list(csv.reader(fh))
    return max((int(r[0]) for r in rows[1:] if r and r[0].isdigit()), default=-1)


@pytest.mark.slow  # (~36 s; SIGTERM and resume stay covered by tests/runs/test_signals.py)
def test_kill_and_resume_gives_the_files_of_an_uninterrupted_run(tmp_path):
    # 4 sub-envs x 384 steps: training episodes end (truncation at 256) on both sides of the kill
    settings = dict(frames=1536, num_envs=4, checkpoint_interval=512, eval_interval=256)
    cfg = write_config(tmp_path / "cfg.toml", **settings)
    args = ["train", "envelope", "MOLavaGridDR-v0", "--config", cfg, "--logger", "csv"]
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(whole), logger="csv", **{**TINY, **settings}))

    # kill after a checkpoint and after an evaluation past it: the logs hold rows beyond the checkpoint
    def ready() -> bool:
        ckpt = _latest_frames(killed)
        return 512 <= ckpt < 1536 and _last_eval_frames(killed) > ckpt

    run_and_kill([*args, "--run-dir", killed], ready)
    killed_at = _latest_frames(killed)
    assert _last_eval_frames(killed) > killed_at  # what the resume must cut
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", killed)
    assert out.returncode == 0, out.stderr[-2000:]
    log = (killed / "log.txt").read_text()
    assert f"resumed from frames_{killed_at:012d} at {killed_at} frames" in log
    assert "fresh episodes" not in log  # MO-LavaGrid continues its episodes exactly

    a, b = _outputs(whole), _outputs(killed)
    assert sorted(a) == sorted(b)
    assert a["train/episodes.csv"].count(b"\n") == 5  # header + 4 episodes, truncated at step 256 (frame 1024)
    assert len([k for k in a if k.startswith("fronts")]) == 7  # 0, 256, ..., 1536
    for name in a:
        assert a[name] == b[name], f"{name} differs after the resume"
    with (killed / "eval" / "metrics.csv").open() as fh:
        frames = [int(r["frames"]) for r in csv.DictReader(fh)]
    assert frames == [f for f in range(0, 1537, 256) for _ in range(2)]  # each evaluation once, in order
    state = load_checkpoint(killed / "checkpoints" / "frames_000000001536")
    assert state["finished"] and state["frames"] == 1536

    # resuming a finished run changes nothing
    before = _outputs(killed)
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--resume", killed)
    assert out.returncode == 0
    assert "already reached 1,536 frames (frames = 1,536): nothing to do" in out.stdout
    assert _outputs(killed) == before
