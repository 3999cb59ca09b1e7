"""``log.txt`` ends every run with exactly one line: finished, or why it stopped and how to resume
(issue 44, finding 8). The signals, the full disk and the non-finite loss have theirs in
``test_signals.py``, ``test_disk_full.py`` and ``tests/recipes/test_training.py``."""

from __future__ import annotations

import pytest

from morl_trl.runs import Run
from tests.runs._helpers import train_tiny

ENDINGS = ("finished:", "stopped")


def _lines(run) -> list[str]:
    return [line.split(" ", 2)[2] for line in (run / "log.txt").read_text().strip().splitlines()]


def test_a_finished_run_ends_with_one_finished_line(tmp_path):
    run = tmp_path / "run"
    train_tiny(run, frames=256)
    lines = _lines(run)
    assert lines[-1] == "finished: 256 frames, 6 updates; the final checkpoint is frames_000000000256"
    assert [line for line in lines if line.startswith(ENDINGS)] == [lines[-1]]


def test_a_run_stopped_by_an_error_ends_with_why_and_how_to_resume(tmp_path, monkeypatch):
    run = tmp_path / "run"
    real = Run.batch_done

    def fails_at_192_frames(self, *args, **kwargs):
        if self.frames == 192:
            raise RuntimeError("the simulator lost its connection\nand a second line")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Run, "batch_done", fails_at_192_frames)
    with pytest.raises(RuntimeError, match="the simulator lost its connection"):
        train_tiny(run)
    lines = _lines(run)
    assert lines[-1] == ("stopped: RuntimeError: the simulator lost its connection (at 192 frames); the last "
                         "checkpoint is frames_000000000000; once the cause is fixed, resume with: morl-trl train "
                         f"envelope MOLavaGridDR-v0 --resume {run}")
    assert [line for line in lines if line.startswith(ENDINGS)] == [lines[-1]]
