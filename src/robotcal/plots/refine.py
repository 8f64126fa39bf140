"""Convergence figure of the least-squares refinement (thesis Figs 4.24/4.25): cost vs iteration."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.ticker import MaxNLocator

from robotcal.plots.figures import new_figure, save_figure

__all__ = ["plot_convergence"]


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
    figure, axes = new_figure(
        1, max(len(criteria), 1), width_in=4.2 * max(len(criteria), 1), height_in=3.6, squeeze=False
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
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("iteration (Jacobian evaluation)")
        ax.set_ylabel("RMS residual [mm]")
        ax.set_title(titles.get(criterion, criterion), fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(figure, path)
