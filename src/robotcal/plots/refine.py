"""Convergence figure of the least-squares refinement (thesis Figs 4.24/4.25): cost vs iteration."""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.ticker import LogFormatterSciNotation, MaxNLocator

from robotcal.plots.figures import new_figure, save_figure, set_margins

__all__ = ["plot_convergence"]

_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079")
_TIMES = "\u00d7"
_MATH_LABEL = re.compile(r"\$\\mathdefault\{(?:(-?[0-9.e+-]+)\\times)?(-?[0-9.]+)\^\{(-?[0-9]+)\}\}\$")


class PlainLogFormatter(LogFormatterSciNotation):
    """Matplotlib's log-axis labels (the same ticks labelled: ``10^-2``, ``4x10^-2``) as plain text with
    Unicode superscripts, ``10⁻²`` and ``4×10⁻²``, instead of mathtext: mathtext is parsed again on every new
    figure (its cache belongs to the renderer), a fifth of the convergence figure's time. Any other label
    is kept as matplotlib writes it."""

    def __call__(self, x, pos=None):
        label = super().__call__(x, pos)
        match = _MATH_LABEL.fullmatch(label)
        if match is None:
            return label
        coefficient, base, exponent = match.groups()
        return (coefficient + _TIMES if coefficient else "") + base + exponent.translate(_SUPERSCRIPT)


def plot_convergence(histories: Mapping[str, Mapping[str, np.ndarray]], path) -> Path:
    """Plot the RMS residual per iteration of each refinement, log scale, one panel per criterion.

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
    figure, axes = new_figure(1, n_panels, width_in=4.2 * n_panels, height_in=3.6, squeeze=False, layout=None)
    # fixed margins [in] (constrained layout would dominate this figure's time): room for the log axis'
    # labels ("4x10^-2"), the two-line titles and the x label
    set_margins(
        figure, left=0.72, right=0.1, bottom=0.48, top=0.42, wspace=0.9, cell=(4.2 + (0.9 - 0.72 - 0.1) / n_panels, 3.6)
    )
    titles = {
        "points": "points criterion (eq. 4-101):\nRMS of |T p - m| per coordinate",
        "distances": "distances criterion (eq. 4-102):\nRMS of pair-distance errors",
    }
    for ax, criterion in zip(axes[0], criteria, strict=False):
        for label, entry in histories.items():
            if entry["criterion"] != criterion:
                continue
            rms = np.maximum(np.asarray(entry["rms_mm"], dtype=float), 1e-16)
            ax.semilogy(np.arange(rms.size), rms, marker="o", label=label)
        ax.yaxis.set_major_formatter(PlainLogFormatter())
        ax.yaxis.set_minor_formatter(PlainLogFormatter())
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("iteration (Jacobian evaluation)")
        ax.set_ylabel("RMS residual [mm]")
        ax.set_title(titles.get(criterion, criterion), fontsize=9, y=1.0)  # fixed: no title-overlap search
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(figure, path)
