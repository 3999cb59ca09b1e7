"""``benchmarks/gpu/check.sh --device cpu --tiny``: the GPU check's dry run, so that its first run
on a GPU machine is not its first run."""

from __future__ import annotations

import pytest

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow  # (~37 s on a 2-core Intel machine: run with -m slow before a GPU session)
def test_the_gpu_check_runs_every_stage_on_the_cpu(tmp_path):
    env = {**os.environ, "OUT": str(tmp_path), "PYTHON": os.environ.get("PYTHON", "python")}
    done = subprocess.run(["bash", str(ROOT / "benchmarks/gpu/check.sh"), "--device", "cpu", "--tiny"], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=2400)  # (a hang guard: its stages' own)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    rows = [line.split("\t") for line in (tmp_path / "table.tsv").read_text().splitlines()]
    stages = {r[1]: r[5] for r in rows if r[0] == "stage"}
    assert stages == {"tests": "ok", "losses": "ok", "train envelope:MOLavaGridDR-v0": "ok", "train one-env": "ok"}
    tests = [r[5] for r in rows if r[0] == "tests"]
    assert any("2 passed" in t for t in tests) and not any("failed" in t for t in tests), tests
    losses = {r[1]: float(r[5]) for r in rows if r[0] == "losses" and r[3] == "eager"}
    assert set(losses) >= {"Envelope", "CAPQL"} and all(v > 0 for v in losses.values()), losses
    train = [float(r[5]) for r in rows if r[0] == "train"]
    assert len(train) == 1 and train[0] > 0
    one_env = [r for r in rows if r[0] == "train-one-env"]  # (issue 47: one MO-Gymnasium env, end to end)
    assert [r[1] for r in one_env] == ["envelope-dst"] and float(one_env[0][5]) > 0, one_env
    summary = (tmp_path / "summary.txt").read_text()
    assert summary.startswith("benchmarks/gpu/check.sh --device cpu") and "Envelope" in summary
    assert summary in done.stdout  # the one table, printed at the end
    assert sorted(p.name for p in tmp_path.iterdir()) == ["env.txt", "losses.log", "summary.txt", "table.tsv",
                                                           "tests.log", "train.log"]
