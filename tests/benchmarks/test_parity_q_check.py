"""benchmarks/parity/q_check.py: issue 48's Envelope value check lists every cached seed with its largest
estimates beside the bound, and counts the seeds that exceed it."""

from __future__ import annotations

import json

from ._helpers import load_benchmark

Q = load_benchmark("parity/q_check", "parity_q_check")


def _run(path, seed: int, max_q: float, max_mean: float, *, commit: str = "abcdef0123", cpu: float | None = 120.0):
    q = dict(max_scalarized_q=max_q, max_mean_scalarized_q=max_mean, bound_any_state=23.7, bound_start=19.78,
             exceeds_bound=max_q > 23.7, mean_exceeds_bound=max_mean > 23.7, points=[], updates=100)
    doc = dict(curve=[dict(frames=0, hv_ratio=0.047), dict(frames=100, hv_ratio=0.9)], q_check=q, commit=commit,
               machine="Test CPU, 2 cores")
    if cpu is not None:
        doc["train_cpu_seconds"] = cpu
    path.write_text(json.dumps(doc))


def test_every_seed_with_a_q_check_is_listed_and_the_exceeding_ones_counted(tmp_path):
    case = tmp_path / "envelope-dst-mb"
    case.mkdir()
    _run(case / "ours_s100.json", 100, 40.0, 20.0)
    _run(case / "ours_s101.json", 101, 22.0, 10.0, cpu=None)
    _run(case / "mb_s100.json", 100, 69.3, 41.4, commit="1234567+dirty")
    (case / "mb_s101.json").write_text(json.dumps(dict(curve=[dict(frames=0, hv_ratio=0.0)])))  # no q_check: skipped
    _run(case / "ours_s99.json", 99, 500.0, 500.0)  # outside seeds 100-109

    by_lib = Q.rows("envelope-dst-mb", tmp_path)
    assert [r["seed"] for r in by_lib["ours"]] == [100, 101]
    assert [r["seed"] for r in by_lib["mb"]] == [100]
    assert by_lib["mb"][0]["commit"] == "1234567+dirty"
    text = Q.table(by_lib)
    assert "| ours | 100 | 0.900 | 40.0 | 20.0 | 23.7 | `abcdef0` | Test CPU, 2 cores | 2.0 |" in text
    assert "| ours | 101 | 0.900 | 22.0 | 10.0 | 23.7 | `abcdef0` | Test CPU, 2 cores | - |" in text
    assert ("ours: 2 seeds (100, 101); the largest estimate exceeds the bound on 1, the largest batch mean on 0; "
            "max w.Q from 22.0 to 40.0") in text
    assert "mb: 1 seeds (100); the largest estimate exceeds the bound on 1, the largest batch mean on 1" in text
    assert "Mann-Whitney" not in text  # (one MB seed: no test)


def test_two_seeds_a_side_compare_the_libraries_by_mann_whitney(tmp_path):
    case = tmp_path / "envelope-dst-mb"
    case.mkdir()
    for s, q in ((100, 30.0), (101, 40.0), (102, 50.0)):
        _run(case / f"ours_s{s}.json", s, q, q / 2)
    for s, q in ((100, 60.0), (101, 70.0), (102, 80.0)):
        _run(case / f"mb_s{s}.json", s, q, q / 2)
    text = Q.table(Q.rows("envelope-dst-mb", tmp_path))
    # every ours value below every MB value: U = 0, exact two-sided p = 2 / C(6, 3) = 0.1
    assert "max w.Q: median ours 40.0 (mean 40.0), MB 70.0 (mean 70.0); Mann-Whitney U two-sided p 0.1" in text
    assert "max batch mean: median ours 20.0 (mean 20.0), MB 35.0 (mean 35.0); Mann-Whitney U two-sided p 0.1" in text


def test_a_case_without_runs_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(Q, "RESULTS", tmp_path)
    assert Q.main(["envelope-dst-mb"]) == 1
    assert "no run of 'envelope-dst-mb' with a q_check" in capsys.readouterr().out
