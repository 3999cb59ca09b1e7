"""morl_trl.preferences: the one simplex check, the samplers and the evaluation weight sets."""

import numpy as np
import pytest
import torch

from morl_trl.preferences import (
    PREFERENCE_DISTRIBUTIONS,
    SIMPLEX_ATOL,
    check_simplex,
    energy_weights,
    extreme_weights,
    pymoo_energy_weights,
    sample_preferences,
    uniform_weights,
)


# ----------------------------------------------------------------------------- the simplex check
def test_one_tolerance_boundary_for_tensors_arrays_and_lists():
    assert SIMPLEX_ATOL == 1e-4
    inside = [[0.5, 0.5], [0.5, 0.5 + 0.5 * SIMPLEX_ATOL]]
    outside = [[0.5, 0.5], [0.5, 0.5 + 2 * SIMPLEX_ATOL]]
    for make in (lambda x: x, np.array, lambda x: torch.tensor(x, dtype=torch.float64)):
        check_simplex(make(inside), 2)
        with pytest.raises(ValueError, match=r"preference row 1 = \[0.5, 0.5002\] sums to 1.0002; weights must lie"):
            check_simplex(make(outside), 2)
    # a slightly negative entry within the tolerance passes, beyond it fails
    check_simplex([1.0 + 0.5 * SIMPLEX_ATOL, -0.5 * SIMPLEX_ATOL], 2)
    with pytest.raises(ValueError, match=r"preference = \[1.0002, -0.0002\] has a negative weight -0.0002"):
        check_simplex([1.0 + 2 * SIMPLEX_ATOL, -2 * SIMPLEX_ATOL], 2)


def test_check_returns_the_input_kind():
    t = torch.tensor([[0.25, 0.75]])
    assert check_simplex(t, 2) is t
    assert check_simplex(torch.tensor([[1, 0]]), 2).dtype == torch.float32  # integer corners
    arr = check_simplex([[0.25, 0.75]], 2)
    assert isinstance(arr, np.ndarray) and arr.dtype == np.float64 and arr.tolist() == [[0.25, 0.75]]


@pytest.mark.parametrize(
    "w, k, match",
    [
        ([[0.2, 0.3, 0.5]], 2, r"weights has shape \(1, 3\); expected \[\.\.\., 2\] \(one weight per objective\)"),
        ([[0.5, 0.5], [float("nan"), 1.0]], 2, r"weights row 1 = \[nan, 1.0\] is not finite"),
        ([[1.5, -0.5], [0.5, 0.6]], 2, r"weights row 0 = \[1.5, -0.5\] has a negative weight -0.5; .*"
                                        r"\(2 of 2 rows are off the simplex\)"),
        ("abc", 2, "must be numbers"),
    ],
)
def test_bad_weights_name_the_row_and_what_is_valid(w, k, match):
    with pytest.raises(ValueError, match=match):
        check_simplex(w, k, name="weights")


def test_batched_index_is_reported_in_full():
    w = torch.full((2, 3, 2), 0.5)
    w[1, 2] = torch.tensor([0.9, 0.9])
    with pytest.raises(ValueError, match=r"preference row \[1, 2\] = \[0.9, 0.9\] sums to 1.8"):
        check_simplex(w, 2)


# ----------------------------------------------------------------------------- sampling
def test_dirichlet_draws_are_bit_identical_to_the_transform_stream():
    # the values PreferenceConditioning's sampler (morl_trl.transforms.preference.sample_dirichlet)
    # gave before it moved here, same seed: exponential_ in float64 for alpha = 1 ...
    g = torch.Generator().manual_seed(0)
    assert sample_preferences(2, 3, generator=g).tolist() == [
        [0.6553019881248474, 0.22981715202331543, 0.11488088220357895],
        [0.4935063123703003, 0.20161862671375275, 0.30487507581710815],
    ]
    # ... and Marsaglia-Tsang gammas otherwise
    g = torch.Generator().manual_seed(0)
    assert sample_preferences(2, 2, alpha=torch.tensor([0.5, 2.0]), generator=g).tolist() == [
        [0.490492582321167, 0.509507417678833],
        [0.0033361073583364487, 0.9966638684272766],
    ]


def test_gaussian_draws_are_non_negative_and_sum_to_one():
    g = torch.Generator().manual_seed(1)
    w = sample_preferences((500, 2), 4, distribution="gaussian", generator=g)
    assert w.shape == (500, 2, 4) and w.dtype == torch.float32
    assert (w >= 0).all()
    torch.testing.assert_close(w.sum(-1), torch.ones(500, 2))
    # |N(0, 1)| normalised: exchangeable, mean 1/k
    torch.testing.assert_close(w.mean((0, 1)), torch.full((4,), 0.25), atol=0.02, rtol=0)
    # the global RNG when no generator: torch.manual_seed reproduces it
    torch.manual_seed(3)
    a = sample_preferences(4, 3, distribution="gaussian")
    torch.manual_seed(3)
    assert torch.equal(a, sample_preferences(4, 3, distribution="gaussian"))


def test_dirichlet_statistics():
    g = torch.Generator().manual_seed(0)
    uniform = sample_preferences(40000, 3, generator=g)
    # Dir(1,1,1): each marginal is Beta(1, 2): mean 1/3, P(w < 1/2) = 3/4
    assert torch.allclose(uniform.mean(0), torch.full((3,), 1 / 3), atol=0.01)
    assert abs((uniform[:, 0] < 0.5).float().mean().item() - 0.75) < 0.01
    skewed = sample_preferences(40000, 3, alpha=torch.tensor([1.0, 2.0, 3.0]), generator=g)
    assert torch.allclose(skewed.mean(0), torch.tensor([1 / 6, 2 / 6, 3 / 6]), atol=0.01)
    sparse = sample_preferences(40000, 2, alpha=0.2, generator=g)  # alpha < 1: mass near the corners
    assert torch.allclose(sparse.mean(0), torch.full((2,), 0.5), atol=0.01)
    assert (sparse.max(-1).values > 0.95).float().mean() > 0.5
    assert torch.allclose(sparse.sum(-1), torch.ones(40000))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(distribution="beta"), r"distribution='beta'; valid values are \('dirichlet', 'gaussian', 'cone'\)"),
        (dict(alpha=-1.0), "alpha must be a positive"),
        (dict(alpha=[1.0, 2.0]), r"alpha has 2 entries; expected 3"),
        (dict(distribution="gaussian", alpha=2.0), "dirichlet' only"),
    ],
)
def test_bad_sampling_arguments(kwargs, match):
    assert PREFERENCE_DISTRIBUTIONS == ("dirichlet", "gaussian", "cone")
    with pytest.raises(ValueError, match=match):
        sample_preferences(2, 3, **kwargs)
    with pytest.raises(ValueError, match="num_objectives must be a positive int, got 0"):
        sample_preferences(2, 0)


# ----------------------------------------------------------------------------- weight sets
def test_energy_weights_are_the_papers_and_cover_the_corners():
    w = energy_weights(2, 100)
    assert w.shape == (100, 2) and w.dtype == torch.float64
    # rows of pymoo's get_reference_directions("energy", 2, 100, seed=42)
    np.testing.assert_allclose(w[:2].numpy(), [[0.0, 1.0], [0.00997283524824734, 0.9900271647517526]], atol=1e-12)
    torch.testing.assert_close(w.sum(-1), torch.ones(100, dtype=torch.float64))
    assert (w == 1.0).any(dim=0).all()  # both corners are in
    np.testing.assert_allclose(energy_weights(3, 32)[1].numpy(), [0.0, 0.17458524, 0.82541476], atol=1e-8)


@pytest.mark.slow  # pymoo's energy optimization takes seconds per shape
@pytest.mark.parametrize("k, n", [(2, 100), (3, 32), (3, 100), (4, 100), (5, 100), (6, 100)])
def test_precomputed_energy_weights_match_pymoo(k, n):
    np.testing.assert_allclose(energy_weights(k, n).numpy(), pymoo_energy_weights(k, n, 42), atol=1e-12)


@pytest.mark.slow
def test_energy_weights_of_other_shapes_come_from_pymoo():
    w = energy_weights(3, 6)  # not shipped: computed by pymoo
    np.testing.assert_allclose(w.numpy(), pymoo_energy_weights(3, 6, 42), atol=1e-12)
    np.testing.assert_allclose(w[:2].numpy(), [[0.0, 0.0, 1.0], [0.0, 0.5, 0.5]], atol=1e-6)


def test_uniform_weights_seeded_on_simplex():
    a, b = uniform_weights(4, 1000, seed=3), uniform_weights(4, 1000, seed=3)
    torch.testing.assert_close(a, b)
    assert (a >= 0).all()
    torch.testing.assert_close(a.sum(-1), torch.ones(1000, dtype=torch.float64))
    # flat Dirichlet: each marginal has mean 1/k
    torch.testing.assert_close(a.mean(0), torch.full((4,), 0.25, dtype=torch.float64), atol=0.02, rtol=0)
    assert not torch.equal(a, uniform_weights(4, 1000, seed=4))
    assert torch.equal(extreme_weights(3), torch.eye(3, dtype=torch.float64))



@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: energy_weights(0, 10), "num_objectives"),
        (lambda: energy_weights(4, 3), "n >= num_objectives"),
        (lambda: uniform_weights(2, 0), "positive"),
    ],
)
def test_bad_weight_set_arguments(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_the_energy_weights_file_ships_with_the_package():
    from importlib.resources import files

    assert files("morl_trl.preferences").joinpath("energy_weights.json").is_file()


# ---------------------------------------------------------------- the authors' CAPQL cone
@pytest.mark.parametrize("k", [2, 3, 4])
def test_capql_cone_sampler_stays_within_22_5_degrees_of_the_equal_weight_direction(k):
    from morl_trl.preferences import CONE_ANGLE_DEGREES, sample_cone_preferences

    g = torch.Generator().manual_seed(k)
    w, c = sample_cone_preferences(20_000, k, generator=g, return_centre=True)
    assert CONE_ANGLE_DEGREES == 22.5
    assert w.shape == c.shape == (20_000, k)
    assert (w >= 0).all() and torch.allclose(w.sum(-1), torch.ones(20_000), atol=1e-6)
    torch.testing.assert_close(c, torch.full((20_000, k), k ** -0.5))  # the authors' fixed axis ones / sqrt(k)
    angle = torch.rad2deg(torch.arccos(((w * c).sum(-1) / w.norm(dim=-1)).clamp(max=1.0).double()))
    assert angle.max() <= 22.5 + 1e-3
    assert angle.max() > 22.4  # the cone is used up to its edge
    # theta ~ U(0, 22.5 degrees) (the authors'), not uniform on the cap: a quarter of the draws within 5.625
    assert abs(float((angle < 22.5 / 4).double().mean()) - 0.25) < 0.02
    if k <= 3:  # the component ranges the record derives: [0.293, 0.707] (k = 2), [0.138, 0.529] (k = 3)
        lo, hi = {2: (0.2929, 0.7071), 3: (0.1381, 0.5286)}[k]
        assert lo - 1e-3 <= float(w.min()) < lo + 0.01 and hi - 0.01 < float(w.max()) <= hi + 1e-3
    # the same generator state gives the same draws; sample_preferences(distribution="cone") is this sampler
    again = sample_preferences(20_000, k, distribution="cone", generator=torch.Generator().manual_seed(k))
    assert torch.equal(again, w)


def test_cone_sampler_narrow_angle_and_bad_arguments():
    from morl_trl.preferences import sample_cone_preferences

    w, c = sample_cone_preferences(100, 3, angle=0.0, generator=torch.Generator().manual_seed(0), return_centre=True)
    torch.testing.assert_close(w, c / c.sum(-1, keepdim=True))  # angle 0: the centre itself, on the simplex
    assert torch.equal(sample_cone_preferences(4, 1), torch.ones(4, 1))
    with pytest.raises(ValueError, match=r"angle must lie in \[0, 90\]"):
        sample_cone_preferences(2, 3, angle=120.0)
