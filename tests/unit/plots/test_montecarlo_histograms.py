"""Histograms of the Monte Carlo draws (robotcal.plots.montecarlo): a figure per joint with identified parameters,
each panel carrying that parameter's histogram (checked against numpy's), the result's mean, its interval for the
measurand and the draws' own interval, the noise-free value and the linearised normal density (checked against
scipy's)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from figure_layout import assert_y_labels_fit
from matplotlib.patches import StepPatch
from scipy.stats import norm

import robotcal.plots.montecarlo as histograms
from robotcal.api import monte_carlo
from robotcal.io import load_scenario
from robotcal.kinematics.model import ANGLE_KINDS, PARAMETER_KINDS


@pytest.fixture(scope="module")
def result():
    return monte_carlo(load_scenario("thesis-laser-tracker"), draws=400, rng=11)


def test_one_png_per_joint_with_identified_parameters(result, tmp_path):
    written = histograms.write_histograms(result, tmp_path)
    joints = [j for j in range(result.robot.n_joints) if result.identified[j].any()]
    assert [path.name for path in written] == [f"hist_J{j + 1}.png" for j in joints]
    assert all(path.read_bytes().startswith(b"\x89PNG\r\n\x1a\n") for path in written)


def test_each_panel_shows_its_parameter(result, tmp_path, monkeypatch):
    figures = []
    monkeypatch.setattr(histograms, "save_figure", lambda figure, path: figures.append(figure) or path)
    histograms.write_histograms(result, tmp_path)
    joints = [j for j in range(result.robot.n_joints) if result.identified[j].any()]
    low, high = result.interval()
    draws_low, draws_high = result.draws_interval()
    for joint, figure in zip(joints, figures, strict=True):
        columns = np.flatnonzero(result.identified[joint])
        axes = [axis for axis in figure.axes if axis.get_visible() and axis.axison]
        assert len(axes) == columns.size
        for axis, column in zip(axes, columns, strict=True):
            kind = PARAMETER_KINDS[column]
            scale = math.degrees(1.0) if kind in ANGLE_KINDS else 1.0
            values = result.draws[:, joint, column] * scale
            counts, edges = np.histogram(values, bins=histograms._bins(values.size))
            stairs = next(patch for patch in axis.patches if isinstance(patch, StepPatch))
            np.testing.assert_array_equal(stairs.get_data().edges, edges)
            # density = counts / (n * width): the drawn heights times the widths give back the counts
            np.testing.assert_allclose(stairs.get_data().values * np.diff(edges) * values.size, counts, atol=1e-9)
            lines = {line.get_label(): line for line in axis.lines}
            for label, value in (
                ("mean", result.summary.mean[joint, column]),
                ("95% interval", low[joint, column]),
                ("noise-free CPA", result.noise_free_values[joint, column]),
                ("draws' 95% interval", draws_low[joint, column]),
                ("estimate", result.centre[joint, column]),  # issue 29: the value stated (deployed, when given)
            ):
                np.testing.assert_allclose(lines[label].get_xdata(), [value * scale] * 2, rtol=1e-14)
            upper = [line for line in axis.lines if line.get_linestyle() == "--"][-1]
            np.testing.assert_allclose(upper.get_xdata(), [high[joint, column] * scale] * 2, rtol=1e-14)
            draws_upper = [line for line in axis.lines if line.get_linestyle() == "-."][-1]
            np.testing.assert_allclose(draws_upper.get_xdata(), [draws_high[joint, column] * scale] * 2, rtol=1e-14)
            x, y = lines["linearised (GUM)"].get_data()
            sigma = result.linearised.std_uncertainty[joint, column] * scale
            centre = result.linearised.estimate[joint, column] * scale
            np.testing.assert_allclose(y, norm.pdf(x, centre, sigma), rtol=1e-12)
            unit = "deg" if kind in ANGLE_KINDS else "mm"
            assert axis.get_xlabel() == f"J{joint + 1}.{kind} [{unit}]"
            assert axis.get_ylabel() == f"density [1/{unit}]"
        assert figure.get_suptitle() == f"J{joint + 1}: {result.n_draws:,} Monte Carlo draws"
        labels = [text.get_text() for legend in figure.legends for text in legend.get_texts()]
        assert labels == ["mean", "estimate", "95% interval", "draws' 95% interval", "noise-free CPA", "linearised (GUM)"]


def test_the_refined_model_names_its_noise_free_value_and_draws_no_density_it_has_not(result, tmp_path, monkeypatch):
    """A refined Monte Carlo run without the linearised comparison (robotcal run's): its noise-free value is the
    refinement's, not CPA's, and no GUM density is drawn (issue 30)."""
    figures = []
    monkeypatch.setattr(histograms, "save_figure", lambda figure, path: figures.append(figure) or path)
    refined = dataclasses.replace(result, model="refined", linearised=None)
    histograms.write_histograms(refined, tmp_path)
    for figure in figures:
        labels = [text.get_text() for legend in figure.legends for text in legend.get_texts()]
        assert labels == ["mean", "estimate", "95% interval", "draws' 95% interval", "noise-free refinement"]


def test_y_labels_stay_inside_the_figure_for_large_densities(result, tmp_path, monkeypatch):
    """A narrow distribution (a refined model's: u of a few µm) has densities in the thousands per unit: the
    wide tick labels push the y label out of a fixed margin (issue 30: "density [1/deg]" clipped)."""
    figures = []
    monkeypatch.setattr(histograms, "save_figure", lambda figure, path: figures.append(figure) or path)
    mean = result.draws.mean(axis=0)
    narrow = dataclasses.replace(result, draws=mean + (result.draws - mean) * 1e-3)
    histograms.write_histograms(result, tmp_path)
    histograms.write_histograms(narrow, tmp_path)
    assert len(figures) > 2
    for figure in figures:
        assert_y_labels_fit(figure)


def test_histograms_drawn_by_a_pool_are_those_of_one_call(result, tmp_path):
    """Issue 31: the command draws its histograms in worker processes (a share of the joints each) while it writes
    the data files; the files are byte for byte those of one call."""
    from robotcal.pipeline.figures import draw_histograms

    serial, pooled = tmp_path / "serial", tmp_path / "pooled"
    serial.mkdir(), pooled.mkdir()
    expected = histograms.write_histograms(result, serial)
    written = []
    paths = draw_histograms(
        result, pooled, workers=2, plot=histograms.write_histograms, write_files=lambda: written.append(True)
    )
    assert written == [True]
    assert [path.name for path in paths] == [path.name for path in expected]
    for path in expected:
        assert (pooled / path.name).read_bytes() == path.read_bytes()
    assert histograms.write_histograms(result, tmp_path, joints=[1])[0].name == "hist_J2.png"
