"""Histogram pages of the Monte Carlo draws (robotcal.plots.montecarlo): the artists made once per page carry each
joint's data (checked against numpy's histogram, the result's statistics and the normal density of scipy), the
pages prepared ahead while the draws run and the pages reused for other joints and results draw the same PNG
bytes as a new figure per joint, and ``compute_uncertainty`` asks a renderer to prepare them before the draws."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.stats import norm

import robotcal.plots.figures as figures
import robotcal.plots.montecarlo as histograms
from robotcal.io import load_scenario
from robotcal.kinematics.model import ANGLE_KINDS, PARAMETER_KINDS
from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo
from robotcal.workflow import scenario_monte_carlo


@pytest.fixture(scope="module")
def laser():
    return scenario_monte_carlo(load_scenario("thesis-laser-tracker"))


@pytest.fixture(scope="module")
def result(laser):
    return run_monte_carlo(laser, MonteCarloSettings(iterations=400, block_size=400, batch_size=400), seed=11)


def _plain_matplotlib_bytes(result, folder):
    """The pages drawn the plain matplotlib way, the independent reference: a new figure per joint, ``ax.stairs``,
    ``axvline``, ``plot`` and ``figure.legend``, the data limits and view as matplotlib sets them for new artists."""
    from matplotlib.ticker import MaxNLocator

    from robotcal.kinematics.model import KIND_UNITS
    from robotcal.plots.figures import new_figure, save_figure

    folder.mkdir()
    low, high = result.interval()
    files = {}
    for joint in range(result.robot.n_joints):
        columns = np.flatnonzero(result.identified[joint])
        if columns.size == 0:
            continue
        n_cols = min(3, columns.size)
        n_rows = math.ceil(columns.size / n_cols)
        width, height = 3.3 * n_cols, 2.6 * n_rows + 0.4
        figure, axes = new_figure(n_rows, n_cols, width_in=width, height_in=height, squeeze=False, layout=None)
        figure.subplots_adjust(
            left=0.62 / width, right=1.0 - 0.3 / width, bottom=0.95 / height, top=1.0 - 0.3 / height,
            wspace=0.7 / 2.6, hspace=0.75 / 1.85,
        )  # fmt: skip
        for panel, column in enumerate(columns):
            axis = axes[panel // n_cols][panel % n_cols]
            kind = PARAMETER_KINDS[column]
            scale = math.degrees(1.0) if kind in ANGLE_KINDS else 1.0
            values = result.draws[:, joint, column] * scale
            density, edges = np.histogram(values, bins=histograms._bins(values.size), density=True)
            axis.stairs(density, edges, fill=True, color="#8fb4d9", linewidth=0, baseline=0.0)
            axis.axvline(result.summary.mean[joint, column] * scale, color="#1f4e79", lw=1.5, label="mean")
            label = f"{result.settings.coverage:.0%} interval"
            axis.axvline(low[joint, column] * scale, color="#c0392b", ls="--", lw=1.2, label=label)
            axis.axvline(high[joint, column] * scale, color="#c0392b", ls="--", lw=1.2)
            noise_free = result.noise_free_values[joint, column] * scale
            axis.axvline(noise_free, color="#444444", ls=":", lw=1.2, label="noise-free CPA")
            if result.linearised is not None and result.linearised.std_uncertainty[joint, column] > 0:
                sigma = result.linearised.std_uncertainty[joint, column] * scale
                centre = result.linearised.estimate[joint, column] * scale
                grid = np.linspace(values.min(), values.max(), 200)
                curve = np.exp(-0.5 * ((grid - centre) / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi))
                axis.plot(grid, curve, color="#e67e22", lw=1.2, label="linearised (GUM)")
            unit = KIND_UNITS[kind]
            axis.set_xlabel(f"J{joint + 1}.{kind} [{unit}]")
            axis.set_ylabel(f"density [1/{unit}]")
            axis.ticklabel_format(axis="x", useOffset=False)
            axis.xaxis.set_major_locator(MaxNLocator(4))
            axis.yaxis.set_major_locator(MaxNLocator(4))
            axis.tick_params(axis="x", labelrotation=20)
        for panel in range(columns.size, n_rows * n_cols):
            axes[panel // n_cols][panel % n_cols].axis("off")
        handles, labels = axes[0][0].get_legend_handles_labels()
        figure.suptitle(f"J{joint + 1}: {result.n_draws:,} Monte Carlo draws", fontsize="medium")
        figure.legend(handles, labels, loc="lower center", ncols=4, fontsize="small", frameon=False)
        path = save_figure(figure, folder / f"hist_J{joint + 1}.png")
        files[path.name] = path.read_bytes()
    return files


def _bytes(paths):
    return {path.name: path.read_bytes() for path in paths}


def test_prepared_and_reused_pages_draw_the_bytes_of_plain_matplotlib(result, tmp_path, monkeypatch):
    monkeypatch.setattr(histograms, "_PAGES", {})
    expected = _plain_matplotlib_bytes(result, tmp_path / "plain")
    assert len(expected) >= 2 and len(set(expected.values())) == len(expected)  # different pages: the check can fail
    histograms.prepare_histograms(result.identified, result.settings.coverage)
    assert len(histograms._PAGES) == len({int(n) for n in np.count_nonzero(result.identified, axis=1) if n})
    figures._GLYPHS.clear()
    for attempt in ("prepared", "reused"):
        (tmp_path / attempt).mkdir()
        assert _bytes(histograms.write_histograms(result, tmp_path / attempt, processes=1)) == expected, attempt
        if figures._CAN_KEEP_GLYPHS and attempt == "prepared":
            kept = len(figures._GLYPHS)
            assert kept > 100  # the glyphs were drawn from kept bitmaps: the second time from those alone
    if figures._CAN_KEEP_GLYPHS:
        assert len(figures._GLYPHS) == kept
    (tmp_path / "new").mkdir()
    monkeypatch.setattr(histograms, "_REUSE_FIGURES", False)
    assert _bytes(histograms.write_histograms(result, tmp_path / "new", processes=1)) == expected


def test_a_page_reused_after_other_results_draws_their_own_bytes(laser, result, tmp_path, monkeypatch):
    """Pages kept from other results leave nothing behind: another coverage (another legend label: its own page),
    no linearised result (three legend lines, no density curve), a density curve higher than the histogram and
    noise-free values outside the draws (the curve and the lines set the view), in any order."""
    monkeypatch.setattr(histograms, "_PAGES", {})
    other = run_monte_carlo(
        laser, MonteCarloSettings(iterations=300, block_size=300, batch_size=300, coverage=0.9), seed=12
    )
    spread = result.summary.maximum - result.summary.minimum
    cases = {
        "result": result,
        "other": other,
        "no-linearised": dataclasses.replace(result, linearised=None),
        "narrow-curve": dataclasses.replace(
            result,
            linearised=dataclasses.replace(result.linearised, std_uncertainty=result.linearised.std_uncertainty / 4),
        ),
        "noise-free-outside": dataclasses.replace(result, noise_free_values=result.summary.maximum + 0.5 * spread),
    }
    expected = {name: _plain_matplotlib_bytes(value, tmp_path / f"plain-{name}") for name, value in cases.items()}
    assert len({tuple(files.values()) for files in expected.values()}) == len(cases)  # every case draws its own
    for attempt, name in enumerate(
        ["result", "other", "no-linearised", "narrow-curve", "noise-free-outside", "result"]
    ):
        folder = tmp_path / f"kept-{attempt}"
        folder.mkdir()
        assert _bytes(histograms.write_histograms(cases[name], folder, processes=1)) == expected[name], (attempt, name)
    assert {key[2] for key in histograms._PAGES} == {"95% interval", "90% interval"}


def test_pages_kept_under_other_rcparams_are_not_reused(result, tmp_path, monkeypatch):
    """A caller's style context gets pages of its own: the same bytes as plain matplotlib under that style."""
    import matplotlib

    monkeypatch.setattr(histograms, "_PAGES", {})
    (tmp_path / "default").mkdir()
    default = _bytes(histograms.write_histograms(result, tmp_path / "default", processes=1))
    with matplotlib.rc_context({"axes.edgecolor": "red", "font.size": 8.0, "lines.dash_capstyle": "round"}):
        expected = _plain_matplotlib_bytes(result, tmp_path / "plain")
        (tmp_path / "styled").mkdir()
        styled = _bytes(histograms.write_histograms(result, tmp_path / "styled", processes=1))
    assert styled == expected and styled != default
    assert len({key[3] for key in histograms._PAGES}) == 2


def test_a_page_shows_the_joint_data(result, tmp_path, monkeypatch):
    """The artists of the last page drawn carry the last joint's histogram, lines, density curve and labels."""
    monkeypatch.setattr(histograms, "_PAGES", {})
    pages = []
    monkeypatch.setattr(histograms, "save_figure", lambda figure, path: pages.append(figure) or path)
    joints = [joint for joint in range(result.robot.n_joints) if result.identified[joint].any()]
    histograms.write_histograms(result, tmp_path, processes=1)
    joint = joints[-1]
    page = next(page for page in histograms._PAGES.values() if page.figure is pages[-1])
    low, high = result.interval()
    columns = np.flatnonzero(result.identified[joint])
    assert len(page.panels) == columns.size
    for panel, column in zip(page.panels, columns, strict=True):
        kind = PARAMETER_KINDS[column]
        scale = math.degrees(1.0) if kind in ANGLE_KINDS else 1.0
        values = result.draws[:, joint, column] * scale
        counts, edges = np.histogram(values, bins=histograms._bins(values.size))
        density, drawn_edges = panel.stairs.get_data().values, panel.stairs.get_data().edges
        np.testing.assert_array_equal(drawn_edges, edges)
        # density = counts / (n * width): the drawn heights times the widths give back the counts
        np.testing.assert_allclose(density * np.diff(edges) * values.size, counts, rtol=1e-12, atol=1e-9)
        for line, value in (
            (panel.mean, result.summary.mean[joint, column]),
            (panel.low, low[joint, column]),
            (panel.high, high[joint, column]),
            (panel.noise_free, result.noise_free_values[joint, column]),
        ):
            np.testing.assert_allclose(line.get_xdata(), [value * scale] * 2, rtol=1e-14)
        sigma = result.linearised.std_uncertainty[joint, column] * scale
        centre = result.linearised.estimate[joint, column] * scale
        x, y = panel.gum.get_data()
        assert panel.gum.get_visible() and x[0] == values.min() and x[-1] == values.max()
        np.testing.assert_allclose(y, norm.pdf(x, centre, sigma), rtol=1e-12)
        unit = "deg" if kind in ANGLE_KINDS else "mm"
        assert panel.axis.get_xlabel() == f"J{joint + 1}.{kind} [{unit}]"
        assert panel.axis.get_ylabel() == f"density [1/{unit}]"
        # the view holds the histogram and every line (data limits as new artists would set them)
        left, right = panel.axis.get_xlim()
        assert left <= min(edges[0], low[joint, column] * scale) and right >= max(
            edges[-1], high[joint, column] * scale
        )
        assert panel.axis.get_ylim()[0] == 0.0 and panel.axis.get_ylim()[1] >= max(density.max(), y.max())
    assert page.figure.get_suptitle() == f"J{joint + 1}: {result.n_draws:,} Monte Carlo draws"
    labels = [text.get_text() for text in page.legend.get_texts()]
    assert labels == ["mean", "95% interval", "noise-free CPA", "linearised (GUM)"]


def test_compute_uncertainty_has_the_pages_prepared_before_the_draws(monkeypatch):
    import robotcal.uncertainty.montecarlo as engine
    from robotcal.pipeline.uncertainty import PREPARE_HISTOGRAMS, compute_uncertainty

    events = []

    class Renderer:
        def submit(self, job, *args):
            events.append(("submit", job, args))

    def run(problem, settings, *, seed, progress=None):
        events.append(("draws", problem.identified))
        return "result"

    monkeypatch.setattr(engine, "run_monte_carlo", run)
    settings = MonteCarloSettings(iterations=100, coverage=0.9)
    assert compute_uncertainty(load_scenario("kr5-demo"), settings, seed=1, renderer=Renderer()) == "result"
    (kind, job, args), (after, identified) = events
    assert (kind, job, after) == ("submit", PREPARE_HISTOGRAMS, "draws")
    np.testing.assert_array_equal(args[0], identified)
    assert args[1] == 0.9
    module, name = job.split(":")
    assert getattr(__import__(module, fromlist=[name]), name) is histograms.prepare_histograms
