"""Linear support: corner weights against hand-computed ones, and the GPI-LS queue."""

import numpy as np
import pytest

from morl_trl.preferences.linear_support import LinearSupport, corner_weights, unique_weights


def test_two_objectives_three_values():
    # w = (a, 1-a): values 3a, 2, 3(1-a); 3a = 2 at a = 2/3, 2 = 3(1-a) at a = 1/3
    got = corner_weights(np.array([[3.0, 0.0], [2.0, 2.0], [0.0, 3.0]]))
    np.testing.assert_allclose(got, [[0, 1], [1 / 3, 2 / 3], [2 / 3, 1 / 3], [1, 0]], atol=1e-9)


def test_dominated_value_adds_no_corner():
    got = corner_weights(np.array([[3.0, 0.0], [2.0, 2.0], [0.0, 3.0], [1.0, 1.0]]))
    np.testing.assert_allclose(got, [[0, 1], [1 / 3, 2 / 3], [2 / 3, 1 / 3], [1, 0]], atol=1e-9)


def test_single_value_gives_the_simplex_corners():
    np.testing.assert_allclose(corner_weights(np.array([[1.0, 2.0, 3.0]])), [[0, 0, 1], [0, 1, 0], [1, 0, 0]])


def test_three_objectives_unit_vectors_and_a_balanced_value():
    # e_i . w = w_i; (.6,.6,.6) . w = .6: the balanced value wins wherever every w_i < .6,
    # so it meets plane i on the edges at w_i = .6 (six points); the simplex corners stay
    V = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0.6, 0.6, 0.6]])
    want = [[0, 0, 1], [0, 0.4, 0.6], [0, 0.6, 0.4], [0, 1, 0], [0.4, 0, 0.6], [0.4, 0.6, 0],
            [0.6, 0, 0.4], [0.6, 0.4, 0], [1, 0, 0]]
    np.testing.assert_allclose(corner_weights(V), want, atol=1e-9)


def test_three_objectives_unit_vectors_meet_at_the_centre():
    got = corner_weights(2 * np.eye(3))
    assert len(got) == 7
    assert any(np.allclose(w, [1 / 3, 1 / 3, 1 / 3]) for w in got)
    assert any(np.allclose(w, [0.5, 0.5, 0]) for w in got)


def test_corners_are_where_the_upper_surface_bends():
    # every corner has k active constraints among value planes (at the max) and faces w_j = 0
    rng = np.random.default_rng(0)
    V = rng.uniform(0, 10, (6, 3)).round(4)
    for w in corner_weights(V):
        scores = V @ w
        active = np.sum(np.isclose(scores, scores.max(), atol=1e-7)) + np.sum(np.isclose(w, 0, atol=1e-9))
        assert active >= 3, (w, scores)


def test_bad_values_raise():
    with pytest.raises(ValueError, match="non-empty"):
        corner_weights(np.zeros((0, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        corner_weights(np.array([[np.nan, 1.0]]))


def test_extrema_first_then_gpi_priority():
    ls = LinearSupport(2, seed=0)
    w1 = ls.next_weight()
    np.testing.assert_array_equal(w1, [1, 0])
    ls.add_solution(np.array([3.0, 0.0]), w1)
    w2 = ls.next_weight()  # one value: corners e_1 (visited, skipped by OLS) and e_2 (unbounded optimistic gap)
    np.testing.assert_array_equal(w2, [0, 1])
    ls.add_solution(np.array([0.0, 3.0]), w2)
    # corners (0,1), (.5,.5), (1,0); GPI values improving only at the middle corner
    G = np.array([[0.0, 3.0], [2.0, 2.0], [3.0, 0.0]])
    w3 = ls.next_weight(gpi_values=G)
    np.testing.assert_allclose(w3, [0.5, 0.5])  # priority 2 - 1.5 = .5; others 0
    assert ls.get_corner_weights() and all(np.allclose(p, 0) for p, _ in ls.queue)


def test_add_solution_drops_values_no_longer_optimal():
    ls = LinearSupport(2)
    ls.add_solution(np.array([1.0, 0.0]), np.array([1.0, 0.0]))
    ls.add_solution(np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    ls.add_solution(np.array([2.0, 2.0]), np.array([0.5, 0.5]))  # better at every visited weight
    assert len(ls.ccs) == 1 and np.allclose(ls.ccs[0], [2, 2])
    assert ls.is_dominated(np.array([0.5, 0.5]))


def test_ols_priority_is_the_optimistic_gap():
    ls = LinearSupport(2)
    ls.add_solution(np.array([1.0, 0.0]), np.array([1.0, 0.0]))
    ls.add_solution(np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    # at w = (.5,.5): the optimistic value (1, 1) gives 1; the CCS gives .5
    assert ls.ols_priority(np.array([0.5, 0.5])) == pytest.approx(0.5)


def test_unique_weights_keeps_first():
    got = unique_weights([np.array([1.0, 0.0]), np.array([1.0, 1e-9]), np.array([0.0, 1.0])])
    np.testing.assert_array_equal(got, [[1, 0], [0, 1]])
