"""robotcal's Agg canvas (text layouts and extents kept for the process) draws the pixels of matplotlib's
own Agg canvas, on a first draw and when every string comes from the caches; mathtext goes to Agg."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import robotcal.plots.figures as figures


def _texts_figure(canvas_class) -> Figure:
    figure = Figure(figsize=(6.0, 4.0), dpi=figures.DPI)
    canvas_class(figure)
    axes = figure.subplots(1, 2)
    for axis, rotation in zip(axes, (0, 20), strict=True):
        axis.plot([0.0, 1.0, 2.0], [3.0, 1.0, 2.0], label="forward")
        axis.set_xlabel("joint reading [deg]")
        axis.set_ylabel("backlash [µm]")
        axis.set_title("J1: above noise (floor 1.2 µm)", fontsize="medium")
        axis.tick_params(axis="x", labelrotation=rotation)
        axis.text(0.5, 0.5, "Δx ±σ\nsecond line", transform=axis.transAxes, fontsize=7, weight="bold")
        axis.text(0.1, 0.2, "joint reading [deg]", transform=axis.transAxes, fontsize=6)  # the x label, smaller
    axes[1].set_ylabel(r"$\sigma_{x}$ [mm]")  # mathtext: Agg's own path
    figure.suptitle("Backlash per coordinate (return − forward)")
    figure.legend(loc="lower center", fontsize="small")
    return figure


def _pixels(figure: Figure) -> np.ndarray:
    figure.canvas.draw()
    return np.asarray(figure.canvas.buffer_rgba()).copy()


@pytest.mark.skipif(not figures._CAN_CACHE_TEXT, reason="this matplotlib lacks the Agg internals the cache uses")
def test_cached_text_draws_agg_pixels(monkeypatch):
    monkeypatch.setattr(figures, "_LAYOUTS", {})
    monkeypatch.setattr(figures, "_EXTENTS", {})
    monkeypatch.setattr(figures, "_GLYPHS", {})
    expected = _pixels(_texts_figure(FigureCanvasAgg))
    first = _pixels(_texts_figure(figures.TextCacheCanvas))  # fills the caches
    assert figures._LAYOUTS and figures._EXTENTS
    assert figures._GLYPHS or not figures._CAN_KEEP_GLYPHS  # rotated labels and ticks included
    layouts, extents, glyphs = dict(figures._LAYOUTS), dict(figures._EXTENTS), dict(figures._GLYPHS)
    second = _pixels(_texts_figure(figures.TextCacheCanvas))  # a new renderer: every string from the caches
    assert figures._LAYOUTS.keys() == layouts.keys() and figures._EXTENTS.keys() == extents.keys()
    assert figures._GLYPHS.keys() == glyphs.keys()  # every glyph drawn from a kept bitmap
    np.testing.assert_array_equal(first, expected)
    np.testing.assert_array_equal(second, expected)


@pytest.mark.skipif(not figures._CAN_CACHE_TEXT, reason="this matplotlib lacks the Agg internals the cache uses")
def test_line_metrics_are_those_of_the_font_tables_and_kept_for_one_draw():
    """The renderer's line metrics are those Text._get_layout reads from the font's tables when a renderer has
    none (checked here through the pixels above); they are kept for one draw only."""
    figure = _texts_figure(figures.TextCacheCanvas)
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    assert renderer.heights == {}  # a new draw starts without them
    figure.canvas.draw()
    assert renderer.heights  # filled by that draw's layouts
    ascent, descent, gap = next(iter(renderer.heights.values()))
    assert ascent > 0 and descent > 0 and gap >= 0


def test_cache_is_bounded(monkeypatch):
    monkeypatch.setattr(figures, "_CACHE_SIZE", 3)
    cache: dict = {}
    for number in range(7):
        figures._remember(cache, (number,), number)
        assert len(cache) <= 3
    assert cache[(6,)] == 6


def test_figures_are_on_the_caching_canvas_and_outside_pyplot():
    figure, axis = figures.new_figure(1, 1, layout=None)
    assert isinstance(figure.canvas, figures.TextCacheCanvas)
    assert figure.get_dpi() == figures.DPI
    assert isinstance(figures.blank_figure(2.0, 1.0).canvas, figures.TextCacheCanvas)
    assert not figures.plt.get_fignums()  # pyplot (imported here on first use) holds none of them
