"""Layout checks of a drawn matplotlib figure, shared by the figure tests of this folder (issue 30: a y label
clipped at the figure's edge, a y label written over its tick labels)."""

from __future__ import annotations

from matplotlib.backends.backend_agg import FigureCanvasAgg


def draw(figure):
    """Draw ``figure`` on an Agg canvas (as savefig does) and return its renderer."""
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return canvas.get_renderer()


def assert_y_labels_fit(figure) -> None:
    """Every panel's y label lies inside the figure, clear of its own tick labels and of every other panel, and
    every y tick label inside the figure."""
    renderer = draw(figure)
    width, height = figure.bbox.width, figure.bbox.height
    panels = [axis for axis in figure.axes if axis.get_visible() and axis.axison]
    for axis in panels:
        label = axis.yaxis.label.get_window_extent(renderer)
        assert label.x0 >= 0 and label.x1 <= width and label.y0 >= 0 and label.y1 <= height, axis.get_ylabel()
        for tick in axis.get_yticklabels():
            if tick.get_visible() and tick.get_text():
                box = tick.get_window_extent(renderer)
                assert box.x0 >= 0, (axis.get_ylabel(), tick.get_text())
                assert not box.overlaps(label), (axis.get_ylabel(), tick.get_text())
        for other in panels:
            if other is not axis:
                assert not other.get_window_extent(renderer).overlaps(label), axis.get_ylabel()
