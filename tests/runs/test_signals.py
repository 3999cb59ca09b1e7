"""SIGTERM and SIGHUP stop a run as Ctrl-C does (issue 44, finding 3): a checkpoint at the end of
the batch, a line in log.txt, the resume command, exit 143 / 129; a second signal exits at once
naming the last checkpoint. Each run is a real ``morl-trl train`` process sent a real signal."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

from morl_trl.recipes import TrainConfig, train
from morl_trl.runs import latest_checkpoint
from tests.runs._helpers import CWD, env, write_config

COMMAND = "morl-trl train envelope MOLavaGridDR-v0 --resume"


def _start(tmp_path: Path, **overrides) -> tuple[subprocess.Popen, Path]:
    """A long run (100,000 frames), once its first checkpoint is written (it is then in its loop)."""
    run = tmp_path / "run"
    config = write_config(tmp_path / "c.toml", frames=100_000, checkpoint_interval=100_000, eval_interval=100_000,
                          **overrides)
    proc = subprocess.Popen([sys.executable, "-m", "morl_trl.cli", "train", "envelope", "MOLavaGridDR-v0",
                             "--run-dir", str(run), "--logger", "none", "--config", str(config)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env(), cwd=CWD)
    deadline = time.time() + 120
    while not (run / "checkpoints" / "frames_000000000000").is_dir():
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        assert time.time() < deadline, "the run did not start within 120 s"
        time.sleep(0.02)
    return proc, run


def _last_log_line(run: Path) -> str:
    return (run / "log.txt").read_text().strip().splitlines()[-1].split(" ", 2)[2]  # (after the time stamp)


def test_sigterm_checkpoints_logs_and_the_run_resumes_from_it(tmp_path):
    proc, run = _start(tmp_path)
    while not (run / "train" / "losses.csv").is_file():  # (some learning done: frames past the first checkpoint)
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err[-2000:]
    assert "Traceback" not in err
    ckpt = latest_checkpoint(run)
    n = int(ckpt.name.split("_")[-1])
    assert n > 0
    assert err.strip().splitlines()[-1] == (f"morl-trl train: interrupted at {n:,} frames; checkpointed in "
                                            f"{ckpt.name}; resume with: {COMMAND} {run}")
    assert "SIGTERM: stopping after this batch and writing a checkpoint (send SIGTERM again to exit at once)" in out
    assert _last_log_line(run) == (f"stopped by SIGTERM: interrupted at {n:,} frames; checkpointed in {ckpt.name}; "
                                   f"resume with: {COMMAND} {run}")
    # the resume continues from that checkpoint (not from frame 0)
    cfg = TrainConfig.load(run / "config.json").replace(frames=n + 64)
    assert train(cfg, resume=run)["frames"] == n + 64
    log = (run / "log.txt").read_text()
    assert f"resumed from {ckpt.name} at {n} frames" in log
    assert _last_log_line(run).startswith(f"finished: {n + 64:,} frames, ")


def test_sighup_exits_129_with_a_checkpoint(tmp_path):
    proc, run = _start(tmp_path)
    proc.send_signal(signal.SIGHUP)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 129, err[-2000:]
    ckpt = latest_checkpoint(run)
    assert int(ckpt.name.split("_")[-1]) > 0
    assert _last_log_line(run).startswith(f"stopped by SIGHUP: interrupted at ")


def test_a_second_sigterm_exits_at_once_naming_the_last_checkpoint(tmp_path):
    proc, run = _start(tmp_path, init_random_frames=0, updates_per_batch=3000)  # (batches of seconds: the second signal lands in one)
    proc.send_signal(signal.SIGTERM)
    time.sleep(0.3)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err[-2000:]
    assert "Traceback" not in err
    last = latest_checkpoint(run).name
    assert err.strip().splitlines()[-1] == (f"morl-trl train: interrupted; the last checkpoint is {last}; resume "
                                            f"with: {COMMAND} {run}")
    assert _last_log_line(run) == (f"stopped by a second SIGTERM: interrupted; the last checkpoint is {last}; "
                                   f"resume with: {COMMAND} {run}")
