"""benchmarks/bench_train.py --one-env: ours vs MORL-Baselines end to end on the parity cases,
runnable on the CPU with a tiny budget and without MB (its column says so)."""

from __future__ import annotations

from tests.benchmarks._helpers import ROOT, load_benchmark


def _module():
    return load_benchmark("bench_train")


def test_one_env_row_without_mb_says_so(capsys, tmp_path, single_thread):
    bt = _module()
    table = tmp_path / "table.tsv"
    assert bt.main(["--one-env", "envelope-dst", "--one-env-frames", "6", "--mb-python", str(tmp_path / "no-python"),
                    "--table", str(table)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "peer: none (no MORL-Baselines python" in out[0]
    row = out[-1].split()
    assert row[:2] == ["envelope-dst", "deep-sea-treasure-v0"] and float(row[2]) > 0 and row[3:] == ["none", "-"]
    stage, case, device, _, unit, fps, peer, ratio, env = table.read_text().rstrip("\n").split("\t")
    assert (stage, case, unit, peer, ratio, env) == ("train-one-env", "envelope-dst", "frames/s", "", "",
                                                     "deep-sea-treasure-v0")
    assert float(fps) > 0


def test_ours_counts_the_frames_of_the_loop_only(single_thread):
    bt = _module()
    r = bt.ours_one_env("gpi_ls-dst", 8)
    assert (r["frames"], r["algo"], r["env"]) == (8, "gpi_ls", "deep-sea-treasure-v0") and r["fps"] > 0


def test_ours_counts_frames_as_mb_does_where_the_case_scales_them(single_thread, monkeypatch):
    """A case with ``ours_frame_scale`` (PGMORL: ours counts one member's steps, MB every member's):
    ours trains ``frames / scale`` of its own frames and reports them, and its rate, in MB's count."""
    bt = _module()
    case = bt._parity_case

    def scaled(name, frames):
        c = case(name, frames)
        c["ours_frame_scale"] = 2
        return c

    monkeypatch.setattr(bt, "_parity_case", scaled)
    r = bt.ours_one_env("gpi_ls-dst", 8)
    assert (r["frames"], r["algo"]) == (8, "gpi_ls") and r["fps"] > 0
    monkeypatch.setattr(bt, "_parity_case", case)
    assert bt.ours_one_env("gpi_ls-dst", 4)["frames"] == 4  # (the same 4 frames of ours, unscaled)


def test_the_default_one_env_cases_cover_every_method():
    bt = _module()
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks" / "parity"))
    from common import CASES

    algos = [CASES[c]["algo"] for c in bt.ONE_ENV_CASES]
    assert sorted(algos) == ["capql", "envelope", "gpi_ls", "gpi_pd", "morld", "pcn", "pgmorl"]


def test_one_env_seeds_print_a_row_per_seed_and_the_medians(capsys, tmp_path, monkeypatch):
    bt = _module()
    import sys

    ours = {0: 60.0, 1: 40.0, 2: 70.0}
    mb = {0: 100.0, 1: 90.0, 2: 40.0}
    seen = []

    def fake_ours(case, frames, seed=0):
        seen.append(("ours", seed))
        return {"fps": ours[seed], "env": "deep-sea-treasure-v0", "frames": frames, "algo": "gpi_pd"}

    def fake_mb(case, frames, python, seed=0, clock="wall"):
        seen.append(("mb", seed))
        return {"fps": mb[seed], "frames": frames}

    monkeypatch.setattr(bt, "ours_one_env", fake_ours)
    monkeypatch.setattr(bt, "mb_one_env", fake_mb)
    table = tmp_path / "table.tsv"
    assert bt.main(["--one-env", "gpi_pd-dst", "--one-env-seeds", "0", "1", "2", "--mb-python", sys.executable,
                    "--table", str(table)]) == 0
    out = [line.split() for line in capsys.readouterr().out.splitlines()]
    rows = {tuple(r[:2]): r[3:] for r in out if r and r[0] == "gpi_pd-dst"}
    assert rows[("gpi_pd-dst", "s0")] == ["60.0", "100.0", "0.60x"]
    assert rows[("gpi_pd-dst", "s1")] == ["40.0", "90.0", "0.44x"]
    assert rows[("gpi_pd-dst", "s2")] == ["70.0", "40.0", "1.75x"]
    # medians: ours 60, MB 90, and the median of the per-seed ratios (0.44, 0.60, 1.75), not 60 / 90 = 0.67
    assert rows[("gpi_pd-dst", "median")] == ["60.0", "90.0", "0.60x"]
    assert seen == [("ours", 0), ("mb", 0), ("ours", 1), ("mb", 1), ("ours", 2), ("mb", 2)]
    fields = table.read_text().rstrip("\n").split("\t")
    assert fields[5:] == ["60.0", "90.0", "0.60x", "deep-sea-treasure-v0; median over seeds 0 1 2"]


def test_mb_one_env_runs_a_prelude_before_mbs_run_and_returns_its_extra(tmp_path, monkeypatch):
    """The code MB's python gets: the prelude first, then the parity runner, then EXTRA written beside its result
    (a stand-in for MB's process runs the code's last step with the runner replaced)."""
    bt = _module()
    import json
    import subprocess

    seen = {}

    def fake_run(cmd, env, capture_output, text, cwd):
        code = cmd[2]
        seen["code"] = code
        compile(code, "<mb>", "exec")
        assert code.index("EXTRA = {}") < code.index("EXTRA['n'] = 3") < code.index("import mb_runner")
        (Path(cwd) / "mb.json").write_text(json.dumps({"train_fps": 50.0, "frames": 100}))
        (Path(cwd) / "extra.json").write_text(json.dumps({"n": 3}))
        return subprocess.CompletedProcess(cmd, 0, "", "")

    from pathlib import Path

    monkeypatch.setattr(subprocess, "run", fake_run)
    r = bt.mb_one_env("gpi_pd-dst", 100, Path("python"), seed=2, clock="cpu", prelude="EXTRA['n'] = 3")
    assert r == {"fps": 50.0, "frames": 100, "extra": {"n": 3}}
    assert "time.perf_counter = time.process_time" in seen["code"] and "'gpi_pd-dst', 2," in seen["code"]
