"""Runs are safe to stop, to share and to run twice: locks, overwrite by swap, disk full, Ctrl-C, export."""

from __future__ import annotations

import errno
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

import morl_trl.runs.checkpoint as checkpoint_module
from morl_trl.recipes import TrainConfig, load_policy, resolve_config, train
from morl_trl.recipes.policy import export_policy
from morl_trl.runs import DiskFullError, RunLock, RunLockedError, find_checkpoint, latest_checkpoint
from morl_trl.runs.atomic import atomic_write_text
from tests.runs._helpers import CWD, TINY, env, train_tiny, write_config

SMALL = {**TINY, "frames": 256}


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("safety") / "run"
    return train_tiny(run, logger="csv", frames=256)


@pytest.fixture
def run(finished, tmp_path) -> Path:
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(finished, copy)
    return copy


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
            and p.name != ".lock"}


# ---------------------------------------------------------------- locks
def _hold_lock(run: Path, what: str) -> subprocess.Popen:
    code = ("import sys, time; from morl_trl.runs import RunLock; RunLock(sys.argv[1], sys.argv[2]).acquire(); "
            "print('held', flush=True); time.sleep(60)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(run), what], stdout=subprocess.PIPE, text=True, env=env())
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_a_second_writer_is_refused_naming_the_holder(run):
    holder = _hold_lock(run, "training")
    try:
        before = _files(run)
        cfg = TrainConfig.load(run / "config.json")
        cfg.frames = 512
        message = re.escape(f"'{run}' is in use by process {holder.pid} (training); wait for it to finish or stop it")
        with pytest.raises(RunLockedError, match=message):
            train(cfg, resume=run)
        with pytest.raises(RunLockedError, match=message):
            train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), **SMALL), overwrite=True)
        from morl_trl.recipes import evaluate_run

        with pytest.raises(RunLockedError, match=message):
            evaluate_run(run)
        assert _files(run) == before  # nothing written, no row appended
        # a reader is never refused: the newest complete checkpoint
        assert load_policy(run).frames == 256
    finally:
        holder.kill()
        holder.wait()
    with RunLock(run, "test"):  # the OS dropped the killed holder's lock
        pass


def test_a_reader_finds_the_newest_complete_checkpoint_while_checkpoints_are_pruned(run, monkeypatch):
    """A training deletes and prunes older checkpoints while a reader verifies them: the reader
    looks again instead of saying there is no intact checkpoint."""
    newest = latest_checkpoint(run)
    real = checkpoint_module.verify_checkpoint
    calls = []

    def racing(path, only=None):  # the first look: the writer pruned / deleted everything under the reader
        calls.append(path)
        return f"{'state.pt'} is missing" if len(calls) <= 2 else real(path, only)

    monkeypatch.setattr(checkpoint_module, "verify_checkpoint", racing)
    found, _ = find_checkpoint(run, only=("state.pt",))
    assert found is None  # (nothing changed on disk: the skips are real)
    calls.clear()
    state = {"n": 0}

    def candidates_change(run_dir, _orig=checkpoint_module._candidates):
        state["n"] += 1
        got = _orig(run_dir)
        return got if state["n"] > 1 else got[::-1]  # a new listing after the first look

    monkeypatch.setattr(checkpoint_module, "_candidates", candidates_change)
    found, _ = find_checkpoint(run, only=("state.pt",))
    assert found == newest


# ---------------------------------------------------------------- overwrite
@pytest.mark.parametrize("override, message", [
    ({"compile": True, "compile_mode": "bogus"}, "config key 'compile_mode' (compile) is 'bogus'; valid: "),
    ({"buffer_size": 10**13}, "config key 'buffer_size' (buffer) is 10,000,000,000,000; its transitions need about"),
])
def test_overwrite_with_a_run_that_cannot_start_loses_nothing(run, override, message):
    before = _files(run)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), **{**SMALL, **override}),
              overwrite=True)
    assert _files(run) == before
    assert not [p for p in run.parent.iterdir() if p.name.startswith(".")]  # no staging left behind


def test_overwrite_keeps_the_old_run_until_the_new_one_has_its_first_checkpoint(run, monkeypatch):
    before = _files(run)
    real = checkpoint_module.save_checkpoint

    def first_checkpoint_fails(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    import morl_trl.runs.run as off_policy  # (where the run writes its checkpoints)

    monkeypatch.setattr(off_policy, "save_checkpoint", first_checkpoint_fails)
    with pytest.raises(OSError):
        train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), **SMALL), overwrite=True)
    assert _files(run) == before  # put back
    monkeypatch.setattr(off_policy, "save_checkpoint", real)
    train(resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), **{**SMALL, "frames": 128}), overwrite=True)
    assert TrainConfig.load(run / "config.json").frames == 128
    assert not [p for p in run.parent.iterdir() if p.name.startswith(".")]


# ---------------------------------------------------------------- disk full
def test_a_full_disk_stops_the_run_with_a_clear_error_and_keeps_the_last_good_checkpoint(tmp_path, monkeypatch):
    real = checkpoint_module._save_pt
    calls = {"n": 0}

    def disk_full_at_the_third_file(obj, path):  # frame 0: state.pt; frame 256: state.pt, then buffer.pt fails
        calls["n"] += 1
        if calls["n"] == 3:
            with path.open("wb") as fh:
                fh.write(b"half")
            raise OSError(errno.ENOSPC, "No space left on device")
        real(obj, path)

    monkeypatch.setattr(checkpoint_module, "_save_pt", disk_full_at_the_third_file)
    run = tmp_path / "run"
    cfg = resolve_config("envelope", "MOLavaGridDR-v0", run_dir=str(run), **{**TINY, "frames": 512})
    with pytest.raises(DiskFullError) as info:
        train(cfg)
    msg = str(info.value)
    assert msg.startswith("[Errno 28] stopped: disk full while writing checkpoint ")
    assert "frames_000000000256 (No space left on device) at 256 frames; the last good checkpoint is " \
           "frames_000000000000; once the cause is fixed, resume with: morl-trl train envelope MOLavaGridDR-v0 " \
           f"--resume {run}" in msg
    assert latest_checkpoint(run).name == "frames_000000000000"
    assert not list((run / "checkpoints").glob(".tmp*"))  # the half-written one is gone
    assert "**Run stopped early.** stopped: disk full while writing checkpoint" in (run / "report.md").read_text()
    assert "stopped: disk full" in (run / "log.txt").read_text()
    monkeypatch.setattr(checkpoint_module, "_save_pt", real)
    assert train(cfg, resume=run)["frames"] == 512  # space freed: it resumes


def test_config_json_is_replaced_atomically(tmp_path, monkeypatch):
    path = tmp_path / "config.json"
    atomic_write_text(path, "old")

    def fail(*args):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", fail)
    with pytest.raises(DiskFullError, match=f"disk full while writing {path}"):
        atomic_write_text(path, "new")
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["config.json"]


# ---------------------------------------------------------------- Ctrl-C
def _start(args, run: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "morl_trl.cli", *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env(), cwd=CWD)


def _wait_for(cond, proc, deadline_s=600):
    deadline = time.time() + deadline_s
    while not cond():
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        assert time.time() < deadline, "timed out"
        time.sleep(0.02)


def test_ctrl_c_checkpoints_and_prints_the_resume_command(tmp_path):
    run = tmp_path / "run"
    config = write_config(tmp_path / "c.toml", frames=100_000, checkpoint_interval=100_000, eval_interval=100_000)
    args = ["train", "envelope", "MOLavaGridDR-v0", "--run-dir", run, "--logger", "none", "--config", config]
    proc = _start(args, run)
    _wait_for(lambda: (run / "checkpoints" / "frames_000000000000").is_dir(), proc)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=600)  # (a hang guard)
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    frames = latest_checkpoint(run).name
    n = int(frames.split("_")[-1])
    assert n > 0
    assert last == (f"morl-trl train: interrupted at {n:,} frames; checkpointed in {frames}; resume with: "
                    f"morl-trl train envelope MOLavaGridDR-v0 --resume {run}")
    assert "Ctrl-C: stopping after this batch and writing a checkpoint (press Ctrl-C again to exit at once)" in out


def test_a_second_ctrl_c_exits_at_once(tmp_path):
    run = tmp_path / "run"
    config = write_config(tmp_path / "c.toml", frames=100_000, checkpoint_interval=100_000, eval_interval=100_000,
                          eval_weights=64)
    args = ["train", "envelope", "MOLavaGridDR-v0", "--run-dir", run, "--logger", "none", "--config", config]
    proc = _start(args, run)
    _wait_for(lambda: (run / "checkpoints" / "frames_000000000000").is_dir(), proc)
    proc.send_signal(signal.SIGINT)
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    # at once: long before the 100,000 frames the run would take otherwise (a hang guard, not a speed limit)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode in (130, -signal.SIGINT), err[-2000:]  # (our one line, or the default handler's exit)
    assert "Traceback" not in err


# ---------------------------------------------------------------- export
def test_export_is_small_and_acts_as_the_run(run, tmp_path):
    out = export_policy(run, tmp_path / "policy.pt")
    state = latest_checkpoint(run) / "state.pt"
    assert out.stat().st_size < state.stat().st_size / 2  # networks only: no optimizer state, no buffer
    torch.load(out, weights_only=True)  # tensors and plain data
    from_run, from_export = load_policy(run), load_policy(out)
    assert (from_export.frames, from_export.env_id, from_export.objective_names) == (256, "MOLavaGridDR-v0",
                                                                                     ("lava", "time"))
    td = TensorDict(observation=torch.linspace(-1, 1, 250).reshape(2, 125),
                    preference=torch.tensor([[0.7, 0.3], [0.2, 0.8]]), batch_size=[2])
    assert torch.equal(from_run(td.clone())["action_value"], from_export(td.clone())["action_value"])
    again = tmp_path / "again.pt"
    from_export.save(again)
    assert load_policy(again).frames == 256
    with pytest.raises(ValueError, match="is not a policy export"):
        torch.save({"a": torch.zeros(1)}, tmp_path / "x.pt")
        load_policy(tmp_path / "x.pt")
    with pytest.raises(ValueError, match="is a folder; give a file name"):
        export_policy(run, tmp_path)
