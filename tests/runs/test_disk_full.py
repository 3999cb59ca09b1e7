"""A full disk, met for real (issue 44, finding 4): a run on a 5 MB tmpfs fills it while torch
writes a checkpoint (torch's zip writer turns ``OSError(ENOSPC)`` into ``RuntimeError: [enforce
fail at inline_container.cc] ... unexpected pos``). One line, exit 1, the previous checkpoint
intact, ``log.txt`` ending with why and how to resume. Needs root to mount the tmpfs (skipped,
with the reason, elsewhere); ``test_safety.py`` keeps the patched cases."""

from __future__ import annotations

import subprocess

import pytest

from morl_trl.recipes import load_policy
from morl_trl.runs import DiskFullError, find_checkpoint, verify_checkpoint
from tests.runs._helpers import cli, train_tiny, write_config


@pytest.fixture
def small_disk(tmp_path):
    mnt = tmp_path / "small"
    mnt.mkdir()
    out = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=5m", "tmpfs", str(mnt)], capture_output=True, text=True)
    if out.returncode != 0:
        pytest.skip(f"cannot mount a 5 MB tmpfs here ({out.stderr.strip() or out.returncode}): needs root")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def test_a_run_that_fills_the_disk_while_torch_writes_a_checkpoint_prints_one_line(small_disk, tmp_path):
    run = small_disk / "b"
    config = write_config(tmp_path / "c.toml", frames=512)
    out = cli("train", "envelope", "MOLavaGridDR-v0", "--run-dir", run, "--logger", "none", "--config", config)
    assert out.returncode == 1, out.stderr[-3000:]
    assert "Traceback" not in out.stderr and "enforce fail" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    ckpt, skipped = find_checkpoint(run)
    assert ckpt is not None and verify_checkpoint(ckpt) is None and not skipped  # the previous one is intact
    assert lines[0].startswith("morl-trl train: error: [Errno 28] stopped: disk full while writing checkpoint ")
    assert lines[0].endswith(f"; the last good checkpoint is {ckpt.name}; once the cause is fixed, resume with: "
                             f"morl-trl train envelope MOLavaGridDR-v0 --resume {run}")
    assert " (No space left on device) at " in lines[0]
    assert not list((run / "checkpoints").glob(".tmp*"))  # the half-written one is gone
    last = (run / "log.txt").read_text().strip().splitlines()[-1]
    assert last.split(" ", 2)[2] == lines[0].removeprefix("morl-trl train: error: [Errno 28] ")
    assert load_policy(run).frames == int(ckpt.name.split("_")[-1])  # (what it keeps loads)


def test_an_export_to_a_full_disk_is_one_error_and_leaves_nothing(small_disk, tmp_path):

    run = tmp_path / "run"
    train_tiny(run, frames=256)
    policy = load_policy(run)
    (small_disk / "filler").write_bytes(b"\0" * (5 * 2**20 - 8 * 2**10))  # (8 KiB left: less than the export)
    with pytest.raises(DiskFullError) as err:
        policy.save(small_disk / "policy.pt")
    assert str(err.value).startswith(f"[Errno 28] disk full while writing {small_disk / 'policy.pt'} (No space left "
                                     f"on device)")
    assert sorted(p.name for p in small_disk.iterdir()) == ["filler"]
