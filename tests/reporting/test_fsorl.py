"""The f_SORL report sections on synthetic runs: which methods beat SAC, by how much, and the figures."""

import csv
import json

import pytest

from morl_trl.reporting.fsorl import grid_runs, grid_section, plot_domain, sac_comparison, sorl_curves

CONTEXTS = ("MOLavaGridRoom-v0", "MOLavaGridMaze-v0")


def test_sac_comparison_on_synthetic_finals():
    finals = {
        "sac": {0: {"A": 5.0, "B": 10.0}, 1: {"A": 6.0, "B": 12.0}, 2: {"A": 7.0, "B": 11.0}},
        "morld": {0: {"A": 10.0, "B": 9.0}, 1: {"A": 12.0, "B": 8.0}, 2: {"A": 11.0, "B": 13.0}},
        "envelope": {0: {"A": 5.0}, 1: {"A": 6.0}},
    }
    rows = {(r.context, r.method): r for r in sac_comparison(finals, reps=5000)}
    a = rows["A", "morld"]
    assert (a.mean, a.seeds, a.sac_mean, a.paired) == (11.0, 3, 6.0, 3)
    assert a.se == pytest.approx(1 / 3**0.5)  # std (ddof=1) 1 over sqrt(3)
    # paired differences 5, 6, 4: mean 5; every bootstrap mean lies in [4, 6]
    assert a.difference == 5.0 and 4.0 <= a.ci[0] < 5.0 < a.ci[1] <= 6.0
    assert a.verdict == "beats SAC"
    b = rows["B", "morld"]  # differences -1, -4, 2: the interval spans 0
    assert b.difference == pytest.approx(-1.0) and b.ci[0] < 0 < b.ci[1] and b.verdict == "no clear difference"
    e = rows["A", "envelope"]  # differences 0, 0 over the 2 seeds it shares with SAC
    assert (e.difference, e.ci, e.paired, e.verdict) == (0.0, (0.0, 0.0), 2, "no clear difference")
    assert ("B", "envelope") not in rows and ("A", "sac") not in rows


def test_verdicts_without_enough_data():
    rows = sac_comparison({"sac": {0: {"A": 1.0}}, "pcn": {0: {"A": 3.0}}, "gpi_ls": {5: {"A": 3.0}}})
    by = {r.method: r for r in rows}
    assert by["pcn"].difference == 2.0 and by["pcn"].ci is None and by["pcn"].verdict == "1 paired seed: no interval"
    assert by["gpi_ls"].verdict == "no seed in common with SAC"
    lone = sac_comparison({"pcn": {0: {"A": 3.0}, 1: {"A": 5.0}}})[0]
    assert (lone.mean, lone.sac_mean, lone.verdict) == (4.0, None, "no SAC runs")
    below = sac_comparison({"sac": {0: {"A": 9.0}, 1: {"A": 8.0}}, "pcn": {0: {"A": 1.0}, 1: {"A": 2.0}}})[0]
    assert below.verdict == "below SAC" and below.difference == -7.0


def _fake_run(root, algo, seed, curves, sorl=True):
    """A run directory with config.json and eval/metrics.csv: curves = {context: {frames: max}}."""
    run = root / "runs" / f"{algo}_s{seed}"
    (run / "eval").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"algo": algo, "env_id": "MOLavaGridDR-v0", "seed": seed}))
    with (run / "eval" / "metrics.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frames", "context", "eum"] + (["sorl_return_max"] if sorl else []))
        for c, pts in curves.items():
            for f, v in pts.items():
                w.writerow([f, c, -1.0] + ([v] if sorl else []))
    return run


def test_grid_section_writes_the_figure_and_the_table(tmp_path):
    def curves(a, b):
        return {CONTEXTS[0]: {0: 0.0, 1000: a}, CONTEXTS[1]: {0: 0.0, 1000: b}}

    _fake_run(tmp_path, "sac", 0, curves(-90.0, -60.0))
    _fake_run(tmp_path, "sac", 1, curves(-80.0, -62.0))
    _fake_run(tmp_path, "morld", 0, curves(-50.0, -70.0))
    _fake_run(tmp_path, "morld", 1, curves(-40.0, -72.0))
    runs = grid_runs(tmp_path)
    assert set(runs) == {"MOLavaGridDR-v0"} and set(runs["MOLavaGridDR-v0"]["morld"]) == {0, 1}
    assert sorl_curves(runs["MOLavaGridDR-v0"]["morld"][1])[CONTEXTS[0]] == {0: 0.0, 1000: -40.0}
    lines = grid_section(runs, tmp_path / "report", reps=2000)
    text = "\n".join(lines)
    png = tmp_path / "report" / "fsorl_MOLavaGridDR-v0.png"
    assert png.stat().st_size > 10_000 and f"(report/{png.name})" in text
    # Room: differences +40, +40 -> beats SAC; Maze: -10, -10 -> below
    assert "| Room | morld | -45 ± 5 (2) | -85 ± 5 (2) | 40 [40, 40] | beats SAC |" in text
    assert "| Maze | morld | -71 ± 1 (2) | -61 ± 1 (2) | -10 [-10, -10] | below SAC |" in text
    assert "Beat SAC in at least one context: morld." in text
    rows = list(csv.DictReader((tmp_path / "report" / "fsorl_summary.csv").open()))
    assert [(r["context"], r["verdict"]) for r in rows] == [(CONTEXTS[0], "beats SAC"), (CONTEXTS[1], "below SAC")]


def test_a_domain_without_f_sorl_says_so_once(tmp_path):
    _fake_run(tmp_path, "envelope", 0, {CONTEXTS[0]: {0: 1.0}}, sorl=False)
    lines = grid_section(grid_runs(tmp_path), tmp_path / "report")
    said = [line for line in lines if "no f_SORL" in line]
    assert said == ["- MOLavaGridDR-v0: no f_SORL: its runs recorded none (the env emits no original scalar reward)."]
    assert not (tmp_path / "report" / "fsorl_summary.csv").exists()
    assert plot_domain("MOLavaGridDR-v0", grid_runs(tmp_path)["MOLavaGridDR-v0"], tmp_path / "x.png") is None


def test_the_example_script_draws_a_domain_of_a_grid_dir(tmp_path, capsys):
    import runpy
    import sys
    from pathlib import Path

    for algo, v in (("sac", -80.0), ("morld", -40.0)):
        for seed in (0, 1):
            _fake_run(tmp_path, algo, seed, {CONTEXTS[0]: {0: -100.0, 1000: v + seed}})
    script = Path(__file__).resolve().parents[2] / "examples" / "fsorl" / "hopper_figure.py"
    out = tmp_path / "fig.png"
    argv = sys.argv
    sys.argv = [str(script), str(tmp_path), "--domain", "MOLavaGridDR-v0", "--out", str(out)]
    try:
        runpy.run_path(str(script), run_name="__main__")
    finally:
        sys.argv = argv
    assert out.stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert "morld" in printed and "+40.0 [40.0, 40.0]" in printed and "beats SAC" in printed
