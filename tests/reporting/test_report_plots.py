"""The run report shows learning: curves per context from every evaluation, readable front axes."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from morl_trl.reporting.report import _frame, _plot_learning, learning_curves


def test_learning_curves_read_every_evaluation_including_frame_0(tmp_path):
    csv = tmp_path / "metrics.csv"
    csv.write_text(
        "frames,context,nhgr,normalized_hypervolume,eum\n"
        "0,A,0.1,0.05,-3.0\n0,B,0.2,0.1,-2.0\n"
        "256,A,0.3,0.15,-1.0\n256,B,,0.2,-0.5\n"
    )
    curves = learning_curves(csv)
    assert curves["nhgr"] == {"A": [(0, 0.1), (256, 0.3)], "B": [(0, 0.2)]}
    assert curves["eum"]["B"] == [(0, -2.0), (256, -0.5)]
    png = _plot_learning(curves, ["A", "B"], tmp_path / "curves.png", ("floor: noop", {"A": 0.25, "B": 0.4}))
    assert png.stat().st_size > 5_000
    assert learning_curves(tmp_path / "missing.csv") == {}


def test_a_front_of_one_point_gets_a_readable_frame():
    fig, ax = plt.subplots()
    _frame(ax, np.array([[-12.5, 300.0]]))
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x0 < -12.5 < x1 and y0 < 300.0 < y1
    assert x1 - x0 >= 1.2 and y1 - y0 >= 29.9  # at least 10% of the value, not a zoom onto a dot
    _frame(ax, np.array([[0.0, 0.0], [10.0, 5.0]]))
    assert ax.get_xlim() == (-0.8, 10.8) and ax.get_ylim() == (-0.4, 5.4)
    plt.close(fig)


def test_training_curves_read_losses_schedules_and_returns_per_objective(tmp_path):
    from morl_trl.reporting.report import _plot_training, training_curves

    (tmp_path / "train").mkdir()
    (tmp_path / "train" / "losses.csv").write_text(
        "frames,loss_qvalue,frames_per_second,epsilon\n100,2.5,40.0,0.9\n200,1.5,42.0,0.8\n")
    (tmp_path / "train" / "episodes.csv").write_text(
        "frames,preference_lava,return_lava,return_time,discounted_return_lava\n"
        "64,0.5,-20.0,-30.0,-15.0\n128,0.5,-10.0,-25.0,-8.0\n")
    curves = training_curves(tmp_path)
    assert curves["loss_qvalue"] == [(100, 2.5), (200, 1.5)] and curves["epsilon"] == [(100, 0.9), (200, 0.8)]
    assert curves["frames_per_second"][-1] == (200, 42.0)
    # undiscounted returns per objective, by name; preferences and discounted returns are not curves
    assert curves["return lava"] == [(64, -20.0), (128, -10.0)] and curves["return time"][0] == (64, -30.0)
    assert set(curves) == {"loss_qvalue", "frames_per_second", "epsilon", "return lava", "return time"}
    assert _plot_training(curves, tmp_path / "t.png").stat().st_size > 5_000
    assert training_curves(tmp_path / "nothing") == {}


class _Bounds:
    def __init__(self, lower, upper):
        self.lower, self.upper = lower, upper


class _Ref:
    specialist_fronts = {"A": np.array([[1.0, 2.0, 3.0], [3.0, 1.0, 2.0]])}
    bounds = {"A": _Bounds([0.0, 0.0, 0.0], [4.0, 4.0, 4.0])}


class _Result:
    context_names = ("A", "B")

    def front(self, name):
        return np.array([[0.5, 1.0, 2.0], [2.0, 0.5, 1.0], [1.0, 1.0, 1.0]])


def test_fronts_of_three_objectives_get_parallel_coordinates_and_every_pairwise_projection(tmp_path):
    from pathlib import Path

    import pytest

    from morl_trl.reporting.report import _plot_fronts, _plot_parallel

    names = ("x", "y", "z")
    saved = {}
    real_savefig = plt.Figure.savefig

    def spy(fig, path, *a, **k):
        saved[Path(path).name] = [ax for ax in fig.axes if ax.axison]
        return real_savefig(fig, path, *a, **k)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plt.Figure, "savefig", spy)
        _plot_parallel(_Result(), _Ref(), tmp_path / "par.png", names)
        _plot_fronts(_Result(), _Ref(), tmp_path / "pairs.png", names)
    par = saved["par.png"]
    assert len(par) == 2                                  # one panel per context
    assert [t.get_text() for t in par[0].get_xticklabels()] == ["x", "y", "z"]
    # context A: 2 specialist lines + 3 of ours, scaled to the bounds [0, 4]
    ours = [ln for ln in par[0].lines if ln.get_color() == "C3"]
    assert len(ours) == 3 and list(ours[0].get_ydata()) == [0.125, 0.25, 0.5]
    pairs = saved["pairs.png"]
    assert len(pairs) == 2 * 3                            # 2 contexts x 3 pairs of objectives
    assert [(a.get_xlabel(), a.get_ylabel()) for a in pairs[:3]] == [("x", "y"), ("x", "z"), ("y", "z")]
