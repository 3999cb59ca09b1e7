"""The parity benchmark's report: IQM with bootstrap CIs per library from the per-seed JSON files,
and the cases not run yet named (no MORL-Baselines needed)."""

import importlib.util
import sys
from pathlib import Path

import pytest

PARITY = Path(__file__).resolve().parents[2] / "benchmarks" / "parity"


@pytest.fixture
def parity(monkeypatch):
    monkeypatch.syspath_prepend(str(PARITY))
    spec = importlib.util.spec_from_file_location("run_parity", PARITY / "run_parity.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("common", None)


def test_results_md_from_seed_files(parity, tmp_path):
    from common import result_path, write_result

    out = tmp_path / "results"
    for lib, hv in (("ours", [100.0, 110.0, 120.0]), ("mb", [90.0, 90.0, 90.0])):
        for seed, v in enumerate(hv):
            curve = [dict(frames=0, hypervolume=10.0, eum=0.0, igd=5.0, hv_ratio=0.1),
                     dict(frames=100, hypervolume=v, eum=1.0, igd=1.0, hv_ratio=v / 200)]
            write_result(result_path(out, "gpi_ls-dst", lib, seed),
                         dict(case="gpi_ls-dst", lib=lib, seed=seed, curve=curve, frames=100, train_fps=50.0))
    text = parity.write_results(out, [0, 1, 2], "cmd").read_text()
    assert "Seeds done: mb [0, 1, 2], ours [0, 1, 2]" in text
    # IQM of 3 runs is their trimmed mean; MB's constant runs give a zero-width interval
    assert "| final hypervolume | 90.000 [90.000, 90.000] | 110.000 [" in text
    assert "## envelope-dst\n\n`envelope`" in text and "Not run yet." in text
    assert "pcn-fruit-tree" in text  # the cases without a runner are named
    assert (tmp_path / "gpi_ls-dst.png").is_file()


def test_summary_row_compares_cis_and_frames_per_second(parity, tmp_path):
    from common import result_path, write_result

    out = tmp_path / "results"
    for lib, hv, fps in (("ours", [120.0, 121.0, 122.0], 30.0), ("mb", [90.0, 90.0, 90.0], 60.0)):
        for seed, v in enumerate(hv):
            curve = [dict(frames=0, hypervolume=0.0), dict(frames=100, hypervolume=v)]
            write_result(result_path(out, "pcn-dst", lib, seed),
                         dict(case="pcn-dst", lib=lib, seed=seed, curve=curve, frames=100, train_fps=fps))
    text = parity.write_results(out, [0, 1, 2], "cmd").read_text()
    # the CIs do not overlap (ours above MB's) and ours trains at half MB's frames/s
    assert "| pcn-dst | 3 / 3 | 121.00 [" in text
    assert "| 90.00 [90.00, 90.00] | ours higher | 30 | 60 | 0.50x |" in text
    assert "| gpi_ls-dst | 0 / 0 | - |" in text  # a case without results is listed, not dropped


def test_mb_multi_policy_acts_with_member_of_nearest_weight(monkeypatch):
    """The MB runner's evaluation rule for MORL/D and PGMORL is ours: the member whose weight is
    nearest to the evaluation weight acts (the first on ties)."""
    monkeypatch.syspath_prepend(str(PARITY))
    spec = importlib.util.spec_from_file_location("mb_runner", PARITY / "mb_runner.py")
    mb_runner = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mb_runner)

    class Member:
        def __init__(self, w, name):
            self.w, self.name = w, name

        def eval(self, obs, w):
            return self.name

    members = [Member([1.0, 0.0], "a"), Member([0.5, 0.5], "b"), Member([0.5, 0.5], "c"), Member([0.0, 1.0], "d")]
    act = mb_runner._nearest(members, lambda m: m.w)
    assert [act(None, w) for w in ([0.9, 0.1], [0.6, 0.4], [0.5, 0.5], [0.2, 0.8])] == ["a", "b", "b", "d"]
    sys.modules.pop("common", None)


@pytest.mark.slow
def test_smoke_run_of_our_side_writes_a_curve(tmp_path):
    """PARITY_SMOKE=1: a 200-frame run of our PCN on deep-sea-treasure-v0 through the harness."""
    import json
    import os
    import subprocess

    env = {**os.environ, "PARITY_SMOKE": "1", "PYTHONPATH": str(PARITY.parents[1])}
    subprocess.run([sys.executable, str(PARITY / "run_parity.py"), "--cases", "pcn-dst", "--seeds", "0", "--libs",
                    "ours", "--nice", "0", "--out", str(tmp_path / "results")], env=env, check=True, timeout=600)
    data = json.loads((tmp_path / "results" / "pcn-dst" / "ours_s0.json").read_text())
    assert data["frames"] == data["curve"][-1]["frames"] >= 200
    assert data["train_fps"] > 0 and data["curve"][-1]["hypervolume"] >= 0.0
    assert "pcn-dst" in (tmp_path / "RESULTS.md").read_text()
