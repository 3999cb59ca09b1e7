"""The report never compares unlike with like unlabelled: every NHGR column names its weights and
frames, the paper's go to their own table (and off the chart) when the run's budget is not theirs;
constant training series are said, not plotted; fronts of 3+ objectives get a page per context."""

from pathlib import Path
from types import SimpleNamespace

import pytest

from morl_trl.reporting.budget import budget_label, count_label, same_budget
from morl_trl.reporting.fsorl import DISCOUNTED_NOTE
from morl_trl.reporting.report import headline, split_constant


def test_budget_labels_and_the_papers_budget():
    assert [count_label(n) for n in (60_032, 60_000, 3_000_000, 2_500_000, 999)] == ["60,032", "60k", "3M", "2.5M",
                                                                                    "999"]
    assert budget_label("envelope", "ours", weights=8, frames=60_032) == "envelope (ours, 8 weights, 60,032 frames)"
    assert budget_label("GPI-LS", "paper", weights=100, frames=5_000_000) == "GPI-LS (paper, 100 weights, 5M frames)"
    assert not same_budget("MOLunarLanderDR-v0", frames=60_032, weights=8)
    assert not same_budget("MOLunarLanderDR-v0", frames=3_000_000, weights=8)       # the frames, not the weights
    assert same_budget("MOLunarLanderDR-v0", frames=2_999_808, weights=100)         # (a last partial batch)
    assert same_budget("MOSuperMarioBrosZeroShot-v2", frames=3_000_000, weights=32)
    assert not same_budget("MODmcCheetahRun-v0", frames=10**7, weights=100)        # not in the paper


def test_constant_training_series_are_split_off():
    curves = {"loss_qvalue": [(64, 2.0), (128, 1.5)], "homotopy_lambda": [(64, 0.95), (128, 0.95)],
              "return lava": [(64, -3.0), (128, -3.0)], "epsilon": [(64, 0.5)]}
    varying, constant = split_constant(curves)
    assert constant == {"homotopy_lambda": 0.95}
    assert set(varying) == {"loss_qvalue", "return lava", "epsilon"}  # (returns and single points stay)


def test_headline_is_one_line_with_the_floor():
    cfg = SimpleNamespace(algo="envelope", env_id="MOLavaGridDR-v0")
    line = headline(cfg, {"frames": 4_032, "nhgr_mean": 0.5, "aggregate": {}},
                    ("floor: noop (8 weights)", {"A": 0.1, "B": 0.3}), Path("r/report.md"))
    assert line == ("envelope on MOLavaGridDR-v0: 4,032 frames, mean NHGR 0.500 (floor: noop (8 weights) 0.200); "
                    "report: r/report.md")
    line = headline(cfg, {"frames": 64, "nhgr_mean": float("nan"), "aggregate": {"hypervolume": 12.5, "eum": -1.0}},
                    None, Path("r/report.md"))
    assert line == "envelope on MOLavaGridDR-v0: 64 frames, mean hypervolume 12.5, mean eum -1; report: r/report.md"


@pytest.fixture(scope="module")
def lava_result():
    from morl_trl.evaluation import MultiContextEvaluator
    from morl_trl.reporting import load_domain_reference

    ref = load_domain_reference("MOLavaGridDR-v0")
    ev = MultiContextEvaluator("random", "MOLavaGridDR-v0", weights=2, reference=ref, seed=0)
    return ev.evaluate(), ref


def _log(tmp_path, result, ref, reference_dir, frames):
    from morl_trl.envs import domain_of

    cfg = SimpleNamespace(algo="envelope", env_id="MOLavaGridDR-v0", seed=0, reference_dir=str(reference_dir),
                          eval_interval=30_000)
    (tmp_path / "eval").mkdir(exist_ok=True)
    (tmp_path / "eval" / "metrics.csv").write_text(
        "frames,context,nhgr\n" + "".join(f"{f},{c},0.2\n" for f in (0, frames) for c in result.context_names))
    (tmp_path / "train").mkdir(exist_ok=True)
    (tmp_path / "train" / "losses.csv").write_text(
        "frames,loss,homotopy_lambda\n" + "".join(f"{f},{1.0 / f},0.95\n" for f in (64, 128, 192)))
    notes = []
    return SimpleNamespace(last_result=result, cfg=cfg, spec=domain_of("MOLavaGridDR-v0"), out_dir=tmp_path,
                           reference=ref, random_result=None, echo_report=False, note=notes.append), notes


def test_a_quick_run_keeps_the_papers_columns_apart_and_labelled(tmp_path, reference_dir, lava_result, capsys):
    from morl_trl.reporting.report import write_report

    result, ref = lava_result
    log, _ = _log(tmp_path, result, ref, reference_dir, 60_032)
    path = write_report(log, {"frames": 60_032, "nhgr_mean": 0.2, "aggregate": {}}, fps=None)
    text = path.read_text()
    lines = text.splitlines()
    ours = next(line for line in lines if line.startswith("| context | envelope (ours"))
    assert ours.startswith("| context | envelope (ours, 2 weights, 60,032 frames) | floor: ")
    assert "(paper" not in ours                                       # the paper is not in our table
    assert "## The paper's generalists (not this run's budget)" in lines
    paper = lines[lines.index("## The paper's generalists (not this run's budget)") + 2]
    assert "| Envelope (paper, 100 weights, 5M frames) |" in paper
    assert "this run: 2 weights, 60,032 frames" in text
    assert "Constant over the run, so not plotted: `homotopy_lambda` 0.950." in text
    assert "from computed" not in text and ".." not in text.replace("...", "")
    # one line on stdout, not the tables
    out = capsys.readouterr().out.strip().splitlines()
    assert out == [f"envelope on MOLavaGridDR-v0: 60,032 frames, mean NHGR 0.200 (floor: forward (2 weights) 0.020); "
                   f"report: {path}"]


def test_at_the_papers_budget_the_columns_share_one_table(tmp_path, reference_dir, lava_result):
    from morl_trl.reporting.report import write_report

    result, ref = lava_result
    result = SimpleNamespace(**{k: getattr(result, k) for k in ("context_names", "per_context", "aggregate",
                                                               "metric", "front")},
                             weights=result.weights.new_zeros(100, 2), has_sorl=False)  # (as if at 100 weights)
    log, _ = _log(tmp_path, result, ref, reference_dir, 5_000_000)
    text = write_report(log, {"frames": 5_000_000, "nhgr_mean": 0.2, "aggregate": {}}, fps=None).read_text()
    header = next(line for line in text.splitlines() if line.startswith("| context | envelope (ours"))
    assert "| Envelope (paper, 100 weights, 5M frames) |" in header
    assert "## The paper's generalists" not in text


def test_discounted_fsorl_above_undiscounted_is_explained():
    assert DISCOUNTED_NOTE.startswith("The discounted row can be the larger: γ^t shrinks late rewards")
