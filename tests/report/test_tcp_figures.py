"""TCP figures refuse a result without draws with the package's InputError; the joint figures drawn on
one reused figure are the same PNG bytes as on separate figures, and show the noise floor."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.api import simulate
from robotcal.diagnostics import analyze_joints, fit_harmonics
from robotcal.errors import InputError
from robotcal.io import load_robot, load_scenario
from robotcal.plots.tcp import plot_tcp_histograms, plot_tcp_scatter
from robotcal.uncertainty.tcp import propagate_to_tcp

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")


@pytest.mark.parametrize("plot", [plot_tcp_scatter, plot_tcp_histograms])
def test_figures_of_draws_need_keep_draws(plot, tmp_path):
    rng = np.random.default_rng(0)
    draws = ROBOT.nominal[None] + rng.normal(0.0, 1e-3, (20, ROBOT.n_joints, 5)) * ~ROBOT.structurally_fixed
    result = propagate_to_tcp(ROBOT, draws, np.deg2rad([10.0, -80.0, 100.0, 20.0, 50.0, -30.0]))
    with pytest.raises(InputError, match="keep_draws=True"):
        plot(result, tmp_path / "figure.png")
    assert not (tmp_path / "figure.png").exists()


def test_joint_figures_are_written_and_show_the_noise_floor(tmp_path, monkeypatch):
    import robotcal.plots.joints as joints_figures

    demo = load_scenario("kr5-demo")
    diagnostics = analyze_joints(simulate(demo, rng=3))
    model = fit_harmonics(diagnostics, order=2)
    written = joints_figures.write_joint_figures(diagnostics, tmp_path, model=model)
    assert [path.name for path in written] == list(joints_figures.FIGURE_NAMES)
    assert all(path.read_bytes().startswith(b"\x89PNG") for path in written)
    # the noise floor is drawn (a dashed line per joint with pairs) and labelled in the figure legend
    drawn = []
    monkeypatch.setattr(joints_figures, "save_figure", lambda figure, path: drawn.append(figure) or path)
    joints_figures.plot_backlash_magnitude(diagnostics, tmp_path / "unused.png")
    figure = drawn[0]
    labels = [text.get_text() for legend in figure.legends for text in legend.get_texts()]
    assert "noise floor (instrument alone)" in labels
    floors = {round(c.backlash_noise_floor * 1000.0, 9) for c in diagnostics.circles}
    dashed = {round(line.get_ydata()[0], 9) for axis in figure.axes for line in axis.lines if line.get_linestyle() == "--"}
    assert floors <= dashed
