"""The TCP histograms (robotcal.plots.tcp.plot_tcp_histograms) keep their y labels inside the figure when the
counts run into the thousands (many draws), issue 30."""

from __future__ import annotations

import numpy as np
from figure_layout import assert_y_labels_fit

import robotcal.plots.tcp as tcp_figures
from robotcal.io import load_robot
from robotcal.uncertainty.tcp import propagate_to_tcp


def test_y_labels_fit_with_counts_in_the_thousands(tmp_path, monkeypatch):
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    rng = np.random.default_rng(2)
    draws = robot.nominal[None] + rng.normal(0.0, 1e-3, (100_000, robot.n_joints, 5)) * ~robot.structurally_fixed
    result = propagate_to_tcp(robot, draws, np.deg2rad([10.0, -80.0, 100.0, 20.0, 50.0, -30.0]), keep_draws=True)
    drawn = []
    monkeypatch.setattr(tcp_figures, "save_figure", lambda figure, path: drawn.append(figure) or path)
    tcp_figures.plot_tcp_histograms(result, tmp_path / "histograms.png")
    assert max(patch.get_data().values.max() for axes in drawn[0].axes for patch in axes.patches) > 5000
    assert_y_labels_fit(drawn[0])
