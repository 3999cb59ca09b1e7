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
