"""The parity benchmark's verdicts (benchmarks/parity/verdict.py): computed from per-seed values, with
concrete cases for each outcome, and the seed rule."""

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "parity_verdict", Path(__file__).resolve().parents[2] / "benchmarks" / "parity" / "verdict.py")
V = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(V)

FLAT0 = [0.0] * 5


def test_learning_is_a_paired_gain_over_the_seeds():
    assert V.learns(FLAT0, [0.8, 0.9, 0.85, 0.7, 0.95])
    assert not V.learns(FLAT0, [0.1, -0.1, 0.05, -0.05, 0.0])  # mean gain 0
    assert not V.learns(FLAT0, [0.9, -0.8, 0.7, -0.6, 0.1])  # positive mean (0.06), far from significant
    assert V.learns([0.2, 0.3], [0.5, 0.6])  # every seed gained 0.3 (no variance)
    assert not V.learns([0.4, 0.4], [0.4, 0.4])
    with pytest.raises(ValueError, match="got 2 and 3"):
        V.learns([0.0, 0.0], [1.0, 1.0, 1.0])


def test_welch_difference_and_degrees_of_freedom():
    diff, se, df = V.welch([1.0, 2.0, 3.0], [2.0, 2.0, 2.0, 2.0])
    assert diff == 0.0 and se == pytest.approx((1.0 / 3) ** 0.5) and df == pytest.approx(2.0)


@pytest.mark.parametrize("ours, ref, want", [
    ([80, 84, 82, 81, 83], [82, 80, 83, 81, 84], "both learn, at parity"),       # same means, margin 8.2
    ([95, 96, 97, 95, 96], [80, 82, 81, 79, 83], "both learn, ours better"),     # +15: beyond the margin, p < 0.05
    ([60, 62, 61, 63, 59], [80, 82, 81, 79, 83], "both learn, ours worse"),
    ([70, 90, 75, 95, 80], [80, 82, 81, 79, 83], "both learn, inconclusive"),    # wide: neither equal nor different
    ([0.1, -0.1, 0, 0.05, -0.05], [80, 82, 81, 79, 83], "only the reference learns"),
    ([80, 82, 81, 79, 83], [0.1, -0.1, 0, 0.05, -0.05], "only ours learns"),
    ([0.1, -0.1, 0, 0.05, -0.05], [0.0, 0.1, -0.1, 0.02, -0.02], "neither learns at this budget"),
])
def test_each_verdict(ours, ref, want):
    assert V.verdict(FLAT0, ours, FLAT0, ref) == want


def test_two_flat_runs_are_not_parity_and_a_missing_frame0_is_said():
    # the old "CIs overlap" called this parity: both stay at their start value
    assert V.verdict([3.0] * 5, [3.0, 3.1, 2.9, 3.0, 3.0], [3.0] * 5, [3.0] * 5) == "neither learns at this budget"
    assert V.verdict(None, [1.0, 2.0], FLAT0[:2], [1.0, 2.0]) == "no frame-0 evaluation"
    assert V.verdict(FLAT0[:1], [1.0], FLAT0[:1], [1.0]) == "fewer than 2 seeds"


def test_lower_is_better_metrics_learn_downwards():
    igd0, igd1 = [5.0] * 4, [1.0, 1.2, 0.9, 1.1]
    assert V.verdict(igd0, igd1, igd0, igd1, higher_is_better=False) == "both learn, at parity"
    assert V.verdict(igd0, igd1, igd0, igd1) == "neither learns at this budget"


def test_the_seed_rule():
    assert V.round_seeds(1) == [0, 1, 2, 3, 4]
    assert V.round_seeds(2) == [100, 101, 102, 103, 104]
    assert V.round_seeds(3, 10) == list(range(200, 210))
    with pytest.raises(ValueError, match="rounds count from 1"):
        V.round_seeds(0)


def test_one_librarys_learning_in_words():
    assert V.learning(FLAT0, [0.8, 0.9, 0.85, 0.7, 0.95]).startswith("learns (gain 0.84, p ")
    assert V.learning([3.0] * 3, [3.0, 3.1, 2.9]) == "does not learn (gain 0, p 0.5)"
    assert V.learning([5.0] * 2, [1.0, 2.0], higher_is_better=False).startswith("learns (gain 3.5")  # IGD falls
    assert V.learning(None, [1.0, 2.0]) == "no frame-0 evaluation" and V.learning([0.0], [1.0]) == "fewer than 2 seeds"
    assert V.gain_test([0.0, 0.0], [1.0, 1.0]) == (1.0, 0.0)
