"""Property tests (hypothesis) of the metrics."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from morl_trl.metrics import eum, hypervolume, nhgr, normalized_hypervolume, pareto_front
from morl_trl.preferences import uniform_weights

SETTINGS = settings(max_examples=60, deadline=None)
coord = st.floats(min_value=0.0, max_value=10.0, allow_nan=False, width=32)


def point_sets(k, min_size=1, max_size=12):
    return st.integers(min_size, max_size).flatmap(lambda n: arrays(np.float64, (n, k), elements=coord))


def staircase_area(points):
    """Area dominated by 2-D points above (0, 0), by sweeping x from right to left."""
    pts = sorted(map(tuple, points), key=lambda p: (-p[0], -p[1]))
    area, best_y = 0.0, 0.0
    for x, y in pts:
        if y > best_y:
            area += x * (y - best_y)
            best_y = y
    return area


def dominates(a, b):
    return np.all(a >= b) and np.any(a > b)


@SETTINGS
@given(point_sets(2))
def test_hv_2d_equals_staircase_area(points):
    assert hypervolume(points, [0.0, 0.0]) == pytest.approx(staircase_area(points), rel=1e-9, abs=1e-9)


@SETTINGS
@given(st.integers(2, 4).flatmap(point_sets), st.data())
def test_hv_ignores_dominated_points(points, data):
    k = points.shape[1]
    base = points[data.draw(st.integers(0, len(points) - 1))]
    shrink = data.draw(arrays(np.float64, (k,), elements=st.floats(0.0, 1.0)))
    dominated = base * shrink  # <= base everywhere (coordinates are >= 0)
    with_it = np.vstack([points, dominated[None]])
    assert hypervolume(with_it, np.zeros(k)) == pytest.approx(hypervolume(points, np.zeros(k)), rel=1e-12, abs=1e-12)
    assert hypervolume(pareto_front(points), np.zeros(k)) == pytest.approx(hypervolume(points, np.zeros(k)), rel=1e-12)


@SETTINGS
@given(st.integers(2, 4).flatmap(point_sets), st.data())
def test_hv_never_decreases_when_a_point_is_added(points, data):
    k = points.shape[1]
    new = data.draw(arrays(np.float64, (k,), elements=coord))
    before = hypervolume(points, np.zeros(k))
    after = hypervolume(np.vstack([points, new[None]]), np.zeros(k))
    assert after >= before - 1e-9 * max(1.0, before)


@SETTINGS
@given(
    st.integers(1, 4).flatmap(lambda k: point_sets(k).map(lambda p: p * 4 - 15)),
    st.data(),
)
def test_normalized_hv_is_in_unit_interval(points, data):
    k = points.shape[1]
    lower = data.draw(arrays(np.float64, (k,), elements=st.floats(-20, 20)))
    width = data.draw(arrays(np.float64, (k,), elements=st.floats(1e-3, 40)))
    v = normalized_hypervolume(points, lower, lower + width)
    assert 0.0 <= v <= 1.0 + 1e-12


@SETTINGS
@given(st.integers(2, 4).flatmap(lambda k: point_sets(k, min_size=1)))
def test_nhgr_of_the_optimal_front_is_one(front):
    k = front.shape[1]
    lower, upper = np.full(k, -1.0), np.full(k, 11.0)
    assume(normalized_hypervolume(front, lower, upper) > 0)
    assert nhgr(front, front, lower, upper) == pytest.approx(1.0)
    # and a subset of it never beats it
    assert nhgr(front[:1], front, lower, upper) <= 1.0


@SETTINGS
@given(st.integers(2, 4).flatmap(point_sets))
def test_pareto_front_is_nondominated_and_dominates_the_rest(points):
    front = pareto_front(points)
    assert len(np.unique(front, axis=0)) == len(front)
    for i, a in enumerate(front):
        assert not any(dominates(b, a) for j, b in enumerate(front) if j != i)
    for p in points:
        assert any(np.all(f >= p) for f in front)


@SETTINGS
@given(st.integers(2, 4).flatmap(point_sets))
def test_eum_ignores_dominated_points(points):
    w = uniform_weights(points.shape[1], 20, seed=0)
    assert eum(pareto_front(points), w) == pytest.approx(eum(points, w), rel=1e-12, abs=1e-12)
