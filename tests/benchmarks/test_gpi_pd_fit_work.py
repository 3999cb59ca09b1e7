"""benchmarks/gpi_pd_fit_work.py: GPI-PD's one-env run with the dynamics fits' minibatch steps and CPU time counted."""

from __future__ import annotations

import pytest

from tests.benchmarks._helpers import load_benchmark


def _module():
    return load_benchmark("gpi_pd_fit_work")


def test_ours_counts_only_the_fits_steps_and_puts_the_recipe_back():
    work = _module()
    import morl_trl.algorithms.gpi.recipe as recipe
    import morl_trl.objectives.dynamics as dynamics

    fit, nll = recipe.fit_dynamics, dynamics.DynamicsLoss.nll
    r = work.ours("gpi_pd-dst", 300, 0)
    # one fit, at frame 250 (MB's dynamics_train_freq); 225 training rows of the 250 (a 10 % holdout) make one
    # minibatch of 256 per epoch, and early stopping (patience 5) runs at least 6 epochs
    assert r["fits"] == 1
    assert r["steps"] >= 6
    assert 0 < r["fit_s"] < 300 / r["fps"]
    assert recipe.fit_dynamics is fit and dynamics.DynamicsLoss.nll is nll


def test_frames_per_second_outside_the_fits():
    work = _module()
    # 2,000 frames at 100 f/s is 20 s, of which 10 s in the fits: 200 f/s outside them
    assert work.outside_fits({"fps": 100.0, "fit_s": 10.0}, 2_000) == pytest.approx(200.0)


def test_mb_side_code_is_valid_python_for_a_case():
    work = _module()
    compile(work._MB_PRELUDE, "<mb>", "exec")
