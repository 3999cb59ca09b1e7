"""Unit tests of morl_trl.metrics with hand-computed values, and the bad-input contract."""

import numpy as np
import pytest
import torch

from morl_trl.metrics import (
    Bounds,
    cardinality,
    eugr,
    eum,
    hypervolume,
    interquartile_mean,
    nhgr,
    normalize,
    normalized_hypervolume,
    optimality_gap,
    pareto_front,
    sparsity,
    stratified_bootstrap_ci,
)


# ----------------------------------------------------------------------------- pareto front
def test_pareto_front_removes_dominated_and_duplicates_keeping_order():
    pts = np.array([[1.0, 0.0], [0.5, 0.5], [0.2, 0.2], [0.0, 1.0], [0.5, 0.5], [1.0, 0.0]])
    np.testing.assert_array_equal(pareto_front(pts), [[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]])


def test_pareto_front_keeps_torch_type_dtype():
    pts = torch.tensor([[3.0, 1.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 5.0]], dtype=torch.float32)
    out = pareto_front(pts)
    assert isinstance(out, torch.Tensor) and out.dtype == torch.float32
    assert out.tolist() == [[3.0, 1.0, 0.0], [0.0, 0.0, 5.0]]


def test_weakly_dominated_point_is_removed():
    # (1, 1) is weakly dominated by (1, 2): equal in one objective, worse in the other
    assert pareto_front(np.array([[1.0, 1.0], [1.0, 2.0]])).tolist() == [[1.0, 2.0]]


# ----------------------------------------------------------------------------- hypervolume
def test_hypervolume_2d_staircase_by_hand():
    # boxes from ref (0,0): (1,3), (2,2), (3,1) -> 3 + 2 + 1 - overlaps = 6
    assert hypervolume([[1, 3], [2, 2], [3, 1]], [0, 0]) == pytest.approx(6.0)


def test_hypervolume_3d_by_hand_and_torch_input():
    pts = torch.tensor([[1.0, 1.0, 1.0], [2.0, 0.5, 0.5]])
    # unit cube + the part of [0,2]x[0,.5]x[0,.5] outside it: 1 + 1*.5*.5
    assert hypervolume(pts, torch.zeros(3)) == pytest.approx(1.25)


def test_hypervolume_4d_single_box_and_scalar_ref():
    assert hypervolume([[2.0, 3.0, 4.0, 5.0]], ref_point=1.0) == pytest.approx(1 * 2 * 3 * 4)


def test_hypervolume_points_on_ref_boundary_add_nothing():
    assert hypervolume([[0.0, 5.0], [1.0, 1.0]], [0.0, 0.0]) == pytest.approx(1.0)


def test_hypervolume_drop_unbounded_ignores_points_below_ref():
    pts = [[2.0, 2.0], [5.0, -1.0]]
    assert hypervolume(pts, [0.0, 0.0], drop_unbounded=True) == pytest.approx(4.0)
    assert hypervolume([[-1.0, 5.0]], [0.0, 0.0], drop_unbounded=True) == 0.0


def test_normalized_hypervolume_clips_and_scales():
    # (20, 5) clips to (10, 5) -> (1, .5); (-3, 10) clips to (0, 10) -> (0, 1): no volume
    assert normalized_hypervolume([[20.0, 5.0], [-3.0, 10.0]], [0.0, 0.0], [10.0, 10.0]) == pytest.approx(0.5)
    np.testing.assert_allclose(normalize([[5.0, 15.0]], [0.0, 10.0], [10.0, 20.0]), [[0.5, 0.5]])


# ----------------------------------------------------------------------------- nhgr / eum / eugr
def test_nhgr_ratio_and_cap():
    opt = [[1.0, 0.5], [0.5, 1.0]]  # normalized HV 0.75
    assert nhgr([[0.5, 0.5]], opt, [0, 0], [1, 1]) == pytest.approx(0.25 / 0.75)
    assert nhgr([[1.0, 1.0]], opt, [0, 0], [1, 1]) == 1.0  # better than the "optimal" front: capped


def test_eum_by_hand():
    front = [[1.0, 0.0], [0.0, 1.0], [0.6, 0.6]]
    w = [[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]
    # max per weight: 1, 0.6, 1 -> mean 2.6/3
    assert eum(front, w) == pytest.approx(2.6 / 3)


def test_eugr_ratio_and_clipping():
    w = [[1.0, 0.0], [0.0, 1.0]]
    opt = [[2.0, 0.0], [0.0, 2.0]]  # EUM 2
    assert eugr([[1.0, 1.0]], opt, w) == pytest.approx(0.5)
    assert eugr([[-5.0, -5.0]], opt, w) == 0.0
    assert eugr([[4.0, 4.0]], opt, w) == 1.0


def test_sparsity_pgmorl_definition_and_cardinality():
    front = [[0.0, 3.0], [1.0, 1.0], [3.0, 0.0]]
    # objective 0 sorted 0,1,3: gaps 1,2 -> 5; objective 1 sorted 0,1,3 -> 5; / (3 - 1)
    assert sparsity(front) == pytest.approx(5.0)
    assert sparsity([[1.0, 1.0]]) == 0.0
    # a dominated point and a duplicate do not count
    assert sparsity(front + [[0.5, 0.5], [1.0, 1.0]]) == pytest.approx(5.0)
    assert cardinality(front + [[0.5, 0.5], [1.0, 1.0]]) == 3


# ----------------------------------------------------------------------------- aggregates
def test_iqm_matches_scipy_trim_mean():
    scipy_stats = pytest.importorskip("scipy.stats")
    x = np.random.default_rng(0).random((5, 8))
    assert interquartile_mean(x) == pytest.approx(scipy_stats.trim_mean(x, 0.25, axis=None))
    assert interquartile_mean([[0.0, 1.0, 2.0, 3.0], [4.0, 5.0, 6.0, 100.0]]) == pytest.approx(3.5)


def test_optimality_gap_caps_scores_at_target():
    assert optimality_gap([[0.5, 1.5], [0.8, 0.9]]) == pytest.approx(1 - (0.5 + 1 + 0.8 + 0.9) / 4)


def test_stratified_bootstrap_resamples_within_tasks():
    # every task (column) is constant across runs: a stratified bootstrap cannot move the mean,
    # a pooled one would
    scores = np.array([[0.0, 1.0]] * 5)
    est, lo, hi = stratified_bootstrap_ci(scores, "mean", reps=2000)
    assert est == lo == hi == 0.5


def test_stratified_bootstrap_interval_brackets_estimate_and_is_seeded():
    x = np.random.default_rng(1).random((5, 8))
    a = stratified_bootstrap_ci(x, "iqm", reps=5000, seed=0)
    assert a == stratified_bootstrap_ci(x, "iqm", reps=5000, seed=0)
    est, lo, hi = a
    assert lo < est < hi and hi - lo < 0.5
    # a callable statistic gives the same interval as the vectorized one
    c = stratified_bootstrap_ci(x, lambda m: interquartile_mean(m), reps=500, seed=0)
    v = stratified_bootstrap_ci(x, "iqm", reps=500, seed=0)
    assert c == pytest.approx(v)


# ----------------------------------------------------------------------------- bad input
GOOD = [[1.0, 2.0], [2.0, 1.0]]


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: hypervolume(np.zeros((0, 2)), [0, 0]), "empty"),
        (lambda: hypervolume([[1.0, float("nan")]], [0, 0]), "finite"),
        (lambda: hypervolume(GOOD, [0, 0, 0]), "shape"),
        (lambda: hypervolume(GOOD, [0, float("nan")]), "finite"),
        (lambda: hypervolume(GOOD, [1.5, 0.0]), "does not bound"),
        (lambda: hypervolume([1.0, 2.0, 3.0], [0.0, 0.0]), "shape"),
        (lambda: hypervolume(np.zeros((2, 2, 2)), [0, 0]), r"\[n, k\]"),
        (lambda: normalized_hypervolume(GOOD, [0, 0], [1, 0]), "upper must be > lower"),
        (lambda: normalized_hypervolume(GOOD, [0, 2], [1, 1]), "upper must be > lower"),
        (lambda: normalized_hypervolume(GOOD, [0, 0], [1, 1, 1]), "shape"),
        (lambda: normalized_hypervolume([], [0, 0], [1, 1]), "empty|shape"),
        (lambda: nhgr(GOOD, np.zeros((0, 2)), [0, 0], [3, 3]), "empty"),
        (lambda: nhgr(GOOD, [[1.0, 2.0, 3.0]], [0, 0], [3, 3]), "objectives"),
        (lambda: nhgr(GOOD, [[0.0, 0.0]], [0, 0], [3, 3]), "zero normalized hypervolume"),
        (lambda: eum(GOOD, [[0.5, 0.6]]), r"weights row 0 = \[0.5, 0.6\] sums to 1.1; weights must lie on the simplex"),
        (lambda: eum(GOOD, [[1.5, -0.5]]), "negative"),
        (lambda: eum(GOOD, [[1.0, 0.0, 0.0]]), "objectives"),
        (lambda: eum(GOOD, [[float("nan"), 1.0]]), "finite"),
        (lambda: eugr(GOOD, [[-1.0, -1.0]], [[0.5, 0.5]]), "meaningless"),
        (lambda: sparsity(np.zeros((0, 3))), "empty"),
        (lambda: cardinality([[float("inf"), 0.0]]), "finite"),
        (lambda: pareto_front([[1.0, float("nan")]]), "finite"),
        (lambda: Bounds([0.0, 1.0], [1.0, 1.0]), "upper must be > lower"),
        (lambda: interquartile_mean([]), "empty"),
        (lambda: optimality_gap([[0.5, float("nan")]]), "NaN"),
        (lambda: stratified_bootstrap_ci([[0.5]], "nope"), "unknown statistic"),
        (lambda: pareto_front("abc"), "numeric"),
    ],
)
def test_bad_input_raises_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_error_names_the_offending_value():
    with pytest.raises(ValueError, match=r"point 1 has objective 0 = -2\.0 < -1\.0"):
        hypervolume([[0.0, 0.0], [-2.0, 0.0]], [-1.0, -1.0])
