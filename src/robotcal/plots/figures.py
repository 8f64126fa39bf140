"""Shared matplotlib plumbing: one look for every figure, atomic PNG writes.

Figures are :class:`matplotlib.figure.Figure` objects made without pyplot (nothing to close: a figure goes
with its last reference) and written by ``savefig`` on the Agg canvas. PNG files are deflated at
:data:`PNG_COMPRESS_LEVEL` (Pillow's ``compress_level``): a plot is mostly runs of identical pixels, which
compress well at the fastest level, and the files are lossless at any level.
"""

from __future__ import annotations

import io
from functools import cache
from pathlib import Path

import matplotlib as mpl
from matplotlib.figure import Figure

from robotcal.io.atomic import atomic_write_bytes

__all__ = ["DPI", "PNG_COMPRESS_LEVEL", "new_figure", "save_figure", "set_margins", "y_label_room"]

DPI = 110
#: zlib level of the PNG data (0-9), given to Pillow through ``savefig(..., pil_kwargs=...)``.
PNG_COMPRESS_LEVEL = 1


def new_figure(n_rows: int = 1, n_cols: int = 1, *, width_in: float = 6.4, height_in: float = 4.0, **kwargs):
    """A figure with an ``n_rows x n_cols`` grid of axes (``Figure.subplots`` keywords; constrained layout
    unless ``layout=`` says otherwise, e.g. ``layout=None`` with :func:`set_margins`)."""
    figure = Figure(figsize=(width_in, height_in), dpi=DPI, layout=kwargs.pop("layout", "constrained"))
    if n_rows == 0:
        return figure, None
    return figure, figure.subplots(n_rows, n_cols, **kwargs)


def set_margins(
    figure: Figure,
    *,
    left: float,
    right: float,
    bottom: float,
    top: float,
    wspace: float = 0.0,
    hspace: float = 0.0,
    cell: tuple[float, float] = (1.0, 1.0),
) -> None:
    """Fixed margins and gaps between panels, in inches (``cell``: a panel's width and height with its gap,
    to turn the gaps into matplotlib's fractions of a panel)."""
    width, height = figure.get_size_inches()
    figure.subplots_adjust(
        left=left / width,
        right=1.0 - right / width,
        bottom=bottom / height,
        top=1.0 - top / height,
        wspace=wspace / max(cell[0] - wspace, 1e-6),
        hspace=hspace / max(cell[1] - hspace, 1e-6),
    )


@cache
def _text_renderer():
    """An Agg renderer for text metrics only (glyph extents at :data:`DPI`; nothing is drawn)."""
    from matplotlib.backends.backend_agg import RendererAgg

    return RendererAgg(1, 1, DPI)


def y_label_room(axes) -> float:
    """Inches an axes needs left of its frame for its y tick labels and its y label, as they will be drawn.

    The tick labels are those of the axes' locator and formatter at its current limits, measured with the
    font's glyph metrics; then the tick, its pad, the label pad and one line of the label's font. Cheap (no
    draw): for fixed margins (:func:`set_margins`) that fit the labels of the data at hand, where constrained
    layout would cost a layout pass.
    """
    renderer = _text_renderer()
    low, high = sorted(axes.get_ylim())
    locations = [v for v in axes.yaxis.get_major_locator()() if low <= v <= high]
    labels = axes.yaxis.get_major_formatter().format_ticks(locations) if locations else []
    ticks = axes.yaxis.get_major_ticks()
    font = ticks[0].label1.get_fontproperties() if ticks else axes.yaxis.label.get_fontproperties()
    widest = max((renderer.get_text_width_height_descent(t, font, ismath=False)[0] for t in labels if t), default=0)
    points = widest * 72.0 / DPI + mpl.rcParams["ytick.major.size"] + mpl.rcParams["ytick.major.pad"]
    if axes.get_ylabel():
        points += axes.yaxis.labelpad + 1.25 * axes.yaxis.label.get_fontsize()
    return points / 72.0


def save_figure(figure: Figure, path: str | Path) -> Path:
    """Write ``figure`` as PNG at :data:`DPI`, atomically (temp file + rename); returns the path."""
    path = Path(path)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI, pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})
    atomic_write_bytes(path, buffer.getvalue())
    return path
