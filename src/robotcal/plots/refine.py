"""Convergence figure of the least-squares refinement (thesis Figs 4.24/4.25): RMS residual vs iteration."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.ticker import FixedLocator, MaxNLocator, NullFormatter

from robotcal.plots.figures import new_figure, save_figure, set_margins, y_label_room

__all__ = ["plot_convergence"]

#: Figure size per panel [in] and the fixed margins above and below the panels [in].
_PANEL_WIDTH, _HEIGHT, _BOTTOM, _TOP = 4.2, 3.6, 0.48, 0.42
_TITLES = {
    "points": "points criterion (eq. 4-101):\nRMS of |T p - m| per coordinate",
    "distances": "distances criterion (eq. 4-102):\nRMS of pair-distance errors",
}


def _plain(value: float) -> str:
    """A tick value as a plain decimal of 3 significant digits (``0.0115``, ``0.02``), no power notation."""
    return np.format_float_positional(value, precision=3, unique=True, fractional=False, trim="-")


def _y_ticks(low: float, high: float, finals: list[float], spacing: float) -> tuple[list[float], list[float]]:
    """Labelled ticks of a log axis from ``low`` to ``high``: every final value and the 1-2-5 values between
    the limits, none closer to another than ``spacing`` (decades; a label's height). Returns ``(finals kept,
    1-2-5 values kept)``: a final value closer than ``spacing`` to one kept before it shares that one's place."""
    kept: list[float] = []
    for value in finals:
        if all(abs(math.log10(value / other)) >= spacing for other in kept):
            kept.append(value)
    grid = [
        m * 10.0**d
        for d in range(math.floor(math.log10(low)), math.ceil(math.log10(high)) + 1)
        for m in (1.0, 2.0, 5.0)
        if low <= m * 10.0**d <= high
    ]
    round_values: list[float] = []
    for value in grid:
        if all(abs(math.log10(value / other)) >= spacing for other in kept + round_values):
            round_values.append(value)
    return kept, round_values


def plot_convergence(histories: Mapping[str, Mapping[str, np.ndarray]], path) -> Path:
    """Plot the RMS residual per iteration of each refinement, log scale, one panel per criterion.

    A refinement from CPA converges in one or two iterations, so each curve is flat from there on: the y axis
    labels each refinement's final value (in its curve's colour) beside round 1-2-5 values, as plain decimals
    in mm, so that where it ended can be read off the axis.

    Parameters
    ----------
    histories : mapping of label to {"criterion": str, "rms_mm": array_like}
        ``rms_mm`` is the RMS residual [mm] at the start (iteration 0) and after each iteration;
        ``criterion`` ("points" or "distances") picks the panel (the residuals of the two criteria
        are different quantities and are not drawn on one axis).
    path : path-like
        PNG file, written atomically.
    """
    criteria = sorted({str(entry["criterion"]) for entry in histories.values()}, key=["points", "distances"].index)
    n_panels = max(len(criteria), 1)
    figure, axes = new_figure(1, n_panels, width_in=_PANEL_WIDTH * n_panels, height_in=_HEIGHT, squeeze=False, layout=None)
    panel_height = _HEIGHT - _BOTTOM - _TOP
    for ax, criterion in zip(axes[0], criteria, strict=False):
        values, finals = [], []
        for label, entry in histories.items():
            if entry["criterion"] != criterion:
                continue
            rms = np.maximum(np.asarray(entry["rms_mm"], dtype=float), 1e-16)
            (line,) = ax.semilogy(np.arange(rms.size), rms, marker="o", label=label)
            values.append(rms)
            finals.append((float(rms[-1]), line.get_color()))
        every = np.concatenate(values) if values else np.array([1e-3, 1.0])
        low, high = float(every.min()) / 1.35, float(every.max()) * 1.35
        ax.set_ylim(low, high)
        font_size = ax.yaxis.get_major_ticks()[0].label1.get_fontsize()
        spacing = 1.3 * font_size / 72.0 / panel_height * math.log10(high / low)  # a label's height [decades]
        kept, round_values = _y_ticks(low, high, [value for value, _ in finals], spacing)
        locations = sorted(kept + round_values)
        ax.yaxis.set_major_locator(FixedLocator(locations))
        ax.yaxis.set_major_formatter(lambda value, _: _plain(value))
        ax.yaxis.set_minor_formatter(NullFormatter())
        colours = {value: colour for value, colour in reversed(finals)}  # the first curve's colour at a tie
        # the axis draws its k-th tick at the k-th location
        for tick, value in zip(ax.yaxis.get_major_ticks(len(locations)), locations, strict=True):
            if value in colours and value in kept:
                tick.label1.set_color(colours[value])
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("iteration (Jacobian evaluation)")
        ax.set_ylabel("RMS residual [mm]")
        ax.set_title(_TITLES.get(criterion, criterion), fontsize=9, y=1.0)  # fixed: no title-overlap search
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    # fixed margins [in] (constrained layout would dominate this figure's time), wide enough for the y tick
    # labels as drawn and the y label
    room = max(y_label_room(ax) for ax in axes[0][: len(criteria)]) if criteria else 0.72
    left, right, gap = room + 0.1, 0.1, room + 0.25
    set_margins(
        figure,
        left=left,
        right=right,
        bottom=_BOTTOM,
        top=_TOP,
        wspace=gap,
        cell=(_PANEL_WIDTH + (gap - left - right) / n_panels, _HEIGHT),
    )
    return save_figure(figure, path)
