"""The convergence figure of the refinement (robotcal.plots.refine): its y axis, log scale, must show where each
refinement ended (a Levenberg-Marquardt refinement from CPA converges in one or two iterations, so the curves are
flat from there on), and its labels must be readable: the y label clear of the tick labels and inside the figure
(issue 30)."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

import robotcal.plots.refine as refine

#: The demo's refinements (robotcal demo, seed 1): RMS per coordinate [mm] at the start and after each iteration.
HISTORIES = {
    "points": {"criterion": "points", "rms_mm": [0.1345, 0.0115385, 0.0115385, 0.0115385]},
    "geometric": {"criterion": "points", "rms_mm": [0.1345, 0.0312, 0.0312, 0.0312]},
    "distances": {"criterion": "distances", "rms_mm": [0.0812, 0.01387, 0.01387, 0.01387, 0.01387]},
}


@pytest.fixture
def drawn(tmp_path, monkeypatch):
    """``(figure, renderer)`` of the convergence figure of ``histories``, drawn as savefig draws it."""

    def draw(histories):
        figures = []
        monkeypatch.setattr(refine, "save_figure", lambda figure, path: figures.append(figure) or path)
        refine.plot_convergence(histories, tmp_path / "convergence.png")
        (figure,) = figures
        canvas = FigureCanvasAgg(figure)
        canvas.draw()
        return figure, canvas.get_renderer()

    return draw


def _tick_labels(axes):
    """``(value, label Text)`` of the labelled y ticks inside the axes' limits."""
    low, high = sorted(axes.get_ylim())
    return [
        (tick.get_loc(), tick.label1)
        for tick in axes.yaxis.get_major_ticks()
        if low <= tick.get_loc() <= high and tick.label1.get_visible() and tick.label1.get_text()
    ]


def test_the_y_label_is_clear_of_the_tick_labels_and_inside_the_figure(drawn):
    figure, renderer = drawn(HISTORIES)
    assert len(figure.axes) == 2
    for axes in figure.axes:
        label = axes.yaxis.label.get_window_extent(renderer)
        assert label.x0 >= 0 and label.y0 >= 0 and label.x1 <= figure.bbox.width and label.y1 <= figure.bbox.height
        boxes = [text.get_window_extent(renderer) for _, text in _tick_labels(axes)]
        assert boxes
        for box in boxes:
            assert not box.overlaps(label), axes.get_ylabel()
            assert box.x0 >= 0
        for k, box in enumerate(boxes):  # nor do the tick labels overlap one another
            assert not any(box.overlaps(other) for other in boxes[k + 1 :])


def test_the_y_axis_labels_the_final_values(drawn):
    """Each refinement's final RMS is a labelled tick of its panel (its value readable on the axis), in the
    colour of its curve."""
    figure, _ = drawn(HISTORIES)
    panels = {"points": figure.axes[0], "distances": figure.axes[1]}
    for label, entry in HISTORIES.items():
        axes = panels[entry["criterion"]]
        final = entry["rms_mm"][-1]
        ticks = [(value, text) for value, text in _tick_labels(axes) if np.isclose(value, final, rtol=1e-9)]
        assert ticks, (label, [t.get_text() for _, t in _tick_labels(axes)])
        value, text = ticks[0]
        assert float(text.get_text()) == pytest.approx(final, rel=5e-3)
        line = next(line for line in axes.get_lines() if line.get_label() == label)
        assert text.get_color() == line.get_color()
    for axes in figure.axes:
        assert axes.get_yscale() == "log"
        # the other labels are plain numbers of a 1-2-5 sequence, no power notation
        assert all("×" not in t.get_text() and "^" not in t.get_text() for _, t in _tick_labels(axes))


def test_close_final_values_do_not_overlap(drawn):
    """Two refinements that end a few per cent apart: their labels share the place of one (no overlap)."""
    histories = {
        "points": {"criterion": "points", "rms_mm": [0.13, 0.0115, 0.0115]},
        "geometric": {"criterion": "points", "rms_mm": [0.13, 0.0118, 0.0118]},
    }
    figure, renderer = drawn(histories)
    boxes = [text.get_window_extent(renderer) for _, text in _tick_labels(figure.axes[0])]
    for k, box in enumerate(boxes):
        assert not any(box.overlaps(other) for other in boxes[k + 1 :])
    values = [value for value, _ in _tick_labels(figure.axes[0])]
    assert any(np.isclose(v, 0.0115) for v in values)


def test_the_png_is_written(tmp_path):
    path = refine.plot_convergence(HISTORIES, tmp_path / "convergence.png")
    assert path.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
