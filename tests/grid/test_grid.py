"""The experiment grid on a local Ray: a tiny 2 algorithms × 1 domain × 2 seeds grid whose first
run has a killed worker and a failing cell, a re-run that resumes, and the report."""

from __future__ import annotations

import csv
import io
import json
import os
import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from morl_trl.grid import QUICK_GRID, GridSpec, load_grid_spec
from tests.runs._helpers import TINY

ROOT = Path(__file__).resolve().parents[2]
ENVELOPE_0, ENVELOPE_1 = "envelope__MOLavaGridDR-v0__s0", "envelope__MOLavaGridDR-v0__s1"
SAC_0, SAC_1 = "mosac_discrete__MOLavaGridDR-v0__s0", "mosac_discrete__MOLavaGridDR-v0__s1"
SPEC = {"name": "tiny", "algorithms": ["envelope", "mosac_discrete"], "domains": ["MOLavaGridDR-v0"],
        "seeds": [0, 1], "overrides": dict(TINY)}


# ---------------------------------------------------------------- the spec (no Ray)
def test_spec_lists_every_cell_with_its_overrides_and_resources():
    spec = GridSpec.from_dict({**SPEC, "resources": {"cpus": 0.5},
                               "cell": [{"algorithm": "envelope", "seed": 1, "overrides": {"lr": 1e-3},
                                         "resources": {"cpus": 2}}]})
    cells = {c.name: c for c in spec.cells()}
    assert list(cells) == [ENVELOPE_0, ENVELOPE_1, SAC_0, SAC_1]
    assert cells[ENVELOPE_1].config().lr == 1e-3 and cells[ENVELOPE_0].config().lr == 3e-4
    assert (cells[ENVELOPE_1].cpus, cells[SAC_0].cpus) == (2.0, 0.5)
    assert (cells[ENVELOPE_1].config().num_threads, cells[SAC_0].config().num_threads) == (2, 1)
    cfg = cells[SAC_1].config("/tmp/x")
    assert (cfg.algo, cfg.seed, cfg.frames, cfg.run_dir, cfg.progress) == ("mosac_discrete", 1, 512, "/tmp/x", False)


def test_a_run_with_a_gpu_share_trains_on_cuda():
    (cell,) = GridSpec.from_dict({**SPEC, "algorithms": ["envelope"], "seeds": [0],
                                  "resources": {"cpus": 1, "gpus": 0.25}}).cells()
    assert (cell.cpus, cell.gpus) == (1.0, 0.25)
    assert cell.config(check_device=False).device == "cpu"  # what a driver without the GPU checks
    import torch

    if torch.cuda.is_available():
        assert cell.config().device == "cuda"
    else:
        with pytest.raises(ValueError, match="config key 'device' .* is 'cuda'"):
            cell.config()


@pytest.mark.parametrize("change, message", [
    ({"algorithms": ["envelope", "nope"]}, r"algorithm\(s\) \['nope'\] are not available; valid: \['envelope'"),
    ({"domains": ["MOLavaGridDR-v9"]}, "MOLavaGridDR-v9"),
    ({"seeds": [-1]}, "seeds is \\[-1\\]; valid: a non-empty list of ints"),
    ({"colour": 1}, r"unknown key\(s\) \['colour'\]"),
    ({"resources": {"gpus": -1}}, "resources.gpus is -1; valid: a number >= 0"),
    ({"overrides": {"lr": 1e-3, "seed": 3}}, r"overrides may not set \['seed'\]"),
    ({"overrides": {"lrr": 1}}, r"unknown config key 'lrr' \(did you mean 'lr'\?\)"),
    ({"cell": [{"domain": "MOHopperDR-v5", "overrides": {"lr": 1e-3}}]}, "matches no cell of the grid"),
    ({"block": 5}, r"block is 5; valid: \[\[block\]\] tables, each with algorithms and domains"),
    ({"cell": "x"}, r"cell is 'x'; valid: \[\[cell\]\] tables"),
    ({"seeds": [2**32]}, r"seeds is \[4294967296\]; valid: a non-empty list of ints in \[0, 2\*\*32 - 1\]"),
])
def test_bad_specs_are_refused_naming_the_fault(change, message):
    with pytest.raises(ValueError, match=message):
        GridSpec.from_dict({**SPEC, **change})


def test_a_bad_value_is_refused_before_anything_runs():
    with pytest.raises(ValueError, match="cell envelope__MOLavaGridDR-v0__s0: config key 'frames'"):
        GridSpec.from_dict({**SPEC, "overrides": {**TINY, "frames": -5}}).check()


def test_shipped_grid_files():
    paper = load_grid_spec(ROOT / "examples/grid/paper.toml")
    cells = paper.check()
    assert len(cells) == 39 * 5 and paper.seeds == (0, 1, 2, 3, 4)  # the paper's 39 table entries
    from morl_trl.grid.report import paper_label
    from morl_trl.reporting.table import PAPER_NHGR

    pairs = {(c.env_id, paper_label(c.algo)) for c in cells}
    assert pairs == {(d, a) for d, row in PAPER_NHGR.items() for a in row}
    mario = [c for c in cells if c.env_id == "MOSuperMarioBrosZeroShot-v2"]
    assert len(mario) == 4 * 5 and {c.cpus for c in mario} == {2.0}
    assert {c.algo for c in mario} == {"envelope", "gpi_ls", "pcn", "sac"}
    assert load_grid_spec(ROOT / "examples/grid/quick.toml") == GridSpec.from_dict(QUICK_GRID)


@pytest.mark.parametrize("args, message", [
    ([], "give a grid spec file, --quick, or --algos and --domains"),
    (["--quick", "--algos", "envelope"], "--algos and --domains go together"),
    (["--quick", "--seeds", "0,x"], "--seeds '0,x': give comma-separated ints"),
    (["--algos", "envelope", "--domains", "MOLavaGridDR-v0", "--set", "lr=-1"], "cell envelope__MOLavaGridDR-v0__s0: "
     "config key 'lr'"),
    (["no/such/spec.toml"], "grid spec 'no/such/spec.toml' does not exist"),
    (["--quick", "--max-failures", "-1"], "--max-failures (max_failures) is -1; valid: a number >= 0"),
    (["--quick", "--max-concurrent", "-2"], "--max-concurrent (max_concurrent) is -2; valid: a number >= 1"),
    (["--quick", "--max-concurrent", "0"], "--max-concurrent (max_concurrent) is 0; valid: a number >= 1"),
    (["--quick", "--num-cpus", "2", "--cpus-per-run", "3"], "reserves cpus = 3 but this machine's Ray has 2: it "
     "would wait forever; lower --cpus-per-run / resources.cpus"),
    (["--quick", "--num-gpus", "0", "--gpus-per-run", "0.5"], "reserves gpus = 0.5 but this machine's Ray has 0"),
    (["--quick", "--seeds", "4294967296"], "seeds is [4294967296]; valid: a non-empty list of ints in [0, 2**32 - 1]"),
])
def test_grid_command_refuses_bad_input_before_running(capsys, tmp_path, args, message):
    from morl_trl.cli import main

    assert main(["grid", *args, "--dir", str(tmp_path / "g")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "g").exists()


@pytest.mark.parametrize("text", ["{", "[1, 2]", '"running"', '{"status": 5, "attempts": "x", "wall_s": "y", '
                                  '"error": 3}', ""])
def test_a_corrupted_cell_record_does_not_break_status_or_start(tmp_path, text, capsys):
    from morl_trl.cli import main
    from morl_trl.grid.status import read_cell_record, write_cell_record

    spec = GridSpec.from_dict(SPEC)
    (tmp_path / "grid.json").write_text(json.dumps(spec.to_dict()))
    name = spec.cells()[0].name
    (tmp_path / "cells").mkdir()
    (tmp_path / "cells" / f"{name}.json").write_text(text)
    assert main(["grid", "status", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert re.search(rf"{name}\s+pending", out)
    assert read_cell_record(tmp_path, name) == {}  # the bad fields are dropped
    assert write_cell_record(tmp_path, name, status="running", attempts=1)["attempts"] == 1  # (grid start writes it)
    (tmp_path / "grid.json").write_text("{")
    assert main(["grid", "status", str(tmp_path)]) == 2
    assert "grid.json' does not parse" in capsys.readouterr().err


# ---------------------------------------------------------------- on Ray
@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    """Run the tiny grid three times: with a worker killed and a cell failing, again, and once more."""
    ray = pytest.importorskip("ray")
    from morl_trl.grid import run_grid
    from tests.grid._cells import flaky_run_cell

    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"PYTHONPATH": path, "OMP_NUM_THREADS": "1"}})
    grid_dir = tmp_path_factory.mktemp("grid")
    spec = GridSpec.from_dict(SPEC)
    outs = [io.StringIO() for _ in range(3)]
    try:
        first = run_grid(spec, grid_dir, run_cell=flaky_run_cell, max_failures=1, stream=outs[0],
                         progress_interval=2)
        stamps = {n: _stamps(grid_dir / "runs" / n) for n in (ENVELOPE_0, ENVELOPE_1, SAC_0)}
        second = run_grid(spec, grid_dir, stream=outs[1])
        third = run_grid(spec, grid_dir, stream=outs[2])
    finally:
        ray.shutdown()
    yield SimpleNamespace(dir=grid_dir, states=[{s.name: s for s in r} for r in (first, second, third)],
                          out=[o.getvalue() for o in outs], stamps=stamps)


def _stamps(run_dir: Path) -> dict[str, float]:
    return {str(p.relative_to(run_dir)): p.stat().st_mtime_ns for p in run_dir.rglob("*") if p.is_file()}


def _record(grid_dir: Path, name: str) -> dict:
    return json.loads((grid_dir / "cells" / f"{name}.json").read_text())


def _eval_frames(run_dir: Path) -> list[int]:
    with (run_dir / "eval" / "metrics.csv").open() as fh:
        return [int(r["frames"]) for r in csv.DictReader(fh)]


def test_a_failing_cell_is_reported_and_the_grid_goes_on(grid):
    first = grid.states[0]
    assert {n: s.status for n, s in first.items()} == {ENVELOPE_0: "done", ENVELOPE_1: "done", SAC_0: "done",
                                                       SAC_1: "failed"}
    assert first[SAC_1].error == "NonFiniteLossError: injected: a non-finite loss after the checkpoint at 256 frames"
    assert first[SAC_1].frames == 256 and first[ENVELOPE_0].frames == 512
    assert "grid: 3/4 done, 0 running, 1 failed, 0 to run" in grid.out[0]


def test_a_killed_worker_resumes_its_run_from_the_last_checkpoint(grid):
    run = grid.dir / "runs" / ENVELOPE_1
    assert f"grid: {ENVELOPE_1}: its worker failed; retrying from its newest checkpoint" in grid.out[0]
    assert _record(grid.dir, ENVELOPE_1)["attempts"] == 2
    assert "resumed from frames_000000000256 at 256 frames" in (run / "log.txt").read_text()
    assert _eval_frames(run) == [0, 0, 256, 256, 512, 512]  # 2 contexts per evaluation, none twice


def test_rerunning_skips_finished_cells_and_resumes_unfinished_ones(grid):
    assert grid.out[1].splitlines()[0].endswith(
        "3 finished (skipped), 1 to run (1 resume from their checkpoints)")
    assert all(s.status == "done" and s.frames == 512 for s in grid.states[1].values())
    for name, stamps in grid.stamps.items():  # the finished cells were not touched
        assert _stamps(grid.dir / "runs" / name) == stamps, name
    run = grid.dir / "runs" / SAC_1
    assert "resumed from frames_000000000256 at 256 frames" in (run / "log.txt").read_text()
    assert _eval_frames(run) == [0, 0, 256, 256, 512, 512]
    assert _record(grid.dir, SAC_1)["attempts"] == 2 and _record(grid.dir, SAC_1)["status"] == "done"
    assert grid.out[2].splitlines()[0].endswith("4 finished (skipped), 0 to run")


def test_report_is_the_reference_table_of_the_runs(grid, capsys):
    from morl_trl.cli import main
    from morl_trl.grid.report import grid_rows

    rows, notes, _ = grid_rows(grid.dir)
    by_label = {r.label: r for r in rows}
    assert sorted(by_label) == ["Envelope", "mosac_discrete"]
    env = by_label["Envelope"]
    assert env.seeds == (0, 1) and env.contexts == ("MOLavaGridSnake-v0", "MOLavaGridRoom-v0")
    assert env.paper == (0.02, 0.05) and by_label["mosac_discrete"].paper is None
    for i, seed in enumerate(env.seeds):  # the same NHGR the run's own last evaluation logged
        with (grid.dir / "runs" / f"envelope__MOLavaGridDR-v0__s{seed}" / "eval" / "metrics.csv").open() as fh:
            logged = {r["context"]: float(r["nhgr"]) for r in csv.DictReader(fh) if r["frames"] == "512"}
        assert env.nhgr[i].tolist() == pytest.approx([logged[c] for c in env.contexts], abs=1e-12)
    assert main(["grid", "report", str(grid.dir)]) == 0
    out = capsys.readouterr().out
    assert "MO-LavaGrid (MOLavaGridDR-v0): 2 contexts" in out
    assert f"Envelope        {env.mean:.2f} ± {env.std:.2f}" in out and "0.02 ± 0.05" in out
    assert "(not in the paper)" in out and "floor: " in out and "DIFFERS" not in out
    assert "floor evaluated here at the runs' 3 weights (the paper's: 100)" in out
    assert (grid.dir / "report" / "curves_MOLavaGridDR-v0.png").stat().st_size > 1000
    assert "report/curves_MOLavaGridDR-v0.png" in (grid.dir / "report.md").read_text()
    assert main(["grid", "status", str(grid.dir)]) == 0
    assert capsys.readouterr().out.startswith("grid: 4/4 done, 0 running, 0 failed, 0 to run")


# ---------------------------------------------------------------- the whole command killed
@pytest.mark.slow
def test_a_killed_grid_command_resumes_when_run_again(tmp_path):
    """SIGKILL ``morl-trl grid`` (its whole process group: driver, Ray, the worker) mid-run; the same
    command then resumes the cell from its newest checkpoint and finishes it."""
    import signal
    import subprocess
    import sys
    import time

    pytest.importorskip("ray")
    from tests.runs._helpers import env

    spec = tmp_path / "grid.json"
    spec.write_text(json.dumps({"name": "killed", "algorithms": ["envelope"], "domains": ["MOLavaGridDR-v0"],
                                "seeds": [0], "overrides": {**TINY, "frames": 4096, "eval_interval": 1024,
                                                            "checkpoint_interval": 512}}))
    grid_dir = tmp_path / "g"
    cmd = [sys.executable, "-m", "morl_trl.cli", "grid", str(spec), "--dir", str(grid_dir), "--num-cpus", "1",
           "--no-report", "--progress-interval", "5"]
    proc = subprocess.Popen(cmd, env=env(), cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    latest = grid_dir / "runs" / "envelope__MOLavaGridDR-v0__s0" / "checkpoints" / "latest"
    deadline = time.time() + 600  # (a hang guard)
    try:
        while time.time() < deadline and proc.poll() is None:
            if latest.is_file() and latest.read_text().strip() not in ("", "frames_000000000000"):
                break
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    killed_at = int(latest.read_text().strip().split("_")[-1])
    assert 0 < killed_at < 4096
    time.sleep(2)
    again = subprocess.run(cmd, env=env(), cwd=ROOT, capture_output=True, text=True, timeout=900)  # (a hang guard)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "0 finished (skipped), 1 to run (1 resume from their checkpoints)" in again.stdout
    log = (grid_dir / "runs" / "envelope__MOLavaGridDR-v0__s0" / "log.txt").read_text()
    (resumed,) = re.findall(r"resumed from frames_(\d+) at", log)
    assert killed_at <= int(resumed) < 4096  # (the killed driver's worker may outlive it by a checkpoint)
    run = grid_dir / "runs" / "envelope__MOLavaGridDR-v0__s0"
    assert _eval_frames(run) == [f for f in (0, 1024, 2048, 3072, 4096) for _ in range(2)]


def test_one_cell_is_written_by_one_process_at_a_time(tmp_path):
    from morl_trl.grid.runner import _lock_cell

    held = _lock_cell(tmp_path, "envelope__MOLavaGridDR-v0__s0")
    with pytest.raises(RuntimeError, match="another process still holds cell envelope__MOLavaGridDR-v0__s0"):
        _lock_cell(tmp_path, "envelope__MOLavaGridDR-v0__s0", wait_s=0.3)
    held.close()
    _lock_cell(tmp_path, "envelope__MOLavaGridDR-v0__s0", wait_s=0.3).close()
