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


def test_tcp_histograms_stay_readable_when_the_mean_is_far_from_the_nominal(tmp_path, monkeypatch):
    """Issue 24: a calibrated robot's draws sit 0.85 mm from the nominal, 50x their spread; the panels are drawn
    about the mean, so the draws fill each panel, and the nominal is named where it is off the panel."""
    import robotcal.plots.tcp as tcp_figures

    rng = np.random.default_rng(1)
    draws = ROBOT.nominal[None] + rng.normal(0.0, 1e-5, (400, ROBOT.n_joints, 5)) * ~ROBOT.structurally_fixed
    draws[:, 1, 2] += 0.85  # J2.a 0.85 mm longer in every draw
    result = propagate_to_tcp(ROBOT, draws, np.deg2rad([10.0, -80.0, 100.0, 20.0, 50.0, -30.0]), keep_draws=True)
    offset = result.summary.mean[0, :3] - result.nominal[0, :3]
    assert np.linalg.norm(offset) > 0.5  # the case of the issue: far from the nominal
    drawn = []
    monkeypatch.setattr(tcp_figures, "save_figure", lambda figure, path: drawn.append(figure) or path)
    tcp_figures.plot_tcp_histograms(result, tmp_path / "histograms.png")
    scale = np.array([1.0, 1.0, 1.0, *([180.0 / np.pi] * 3)])
    for k, axes in enumerate(drawn[0].axes[:6]):
        values = result.draws[:, 0, k] * scale[k]
        low, high = axes.get_xlim()
        assert np.ptp(values) / (high - low) > 0.6, (k, np.ptp(values), high - low)  # the draws fill the panel
        nominal_drawn = any(line.get_label() == "nominal" for line in axes.get_lines())
        assert nominal_drawn or "nominal" in axes.get_title(), k
    # the coordinate the J2.a error moves most: its nominal lies far outside the draws, named in the title, not drawn
    k = int(np.argmax(np.abs(offset) / np.ptp(result.draws[:, 0, :3], axis=0)))
    assert abs(offset[k]) > 5 * np.ptp(result.draws[:, 0, k])
    assert not any(line.get_label() == "nominal" for line in drawn[0].axes[k].get_lines())
    assert f"{-offset[k]:+.3g} mm" in drawn[0].axes[k].get_title()
