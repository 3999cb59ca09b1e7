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
