"""Monte Carlo figures: histograms of the parameter draws (thesis Figs 5.11/5.12)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.ticker import MaxNLocator

from robotcal.kinematics.model import ANGLE_KINDS, KIND_UNITS, PARAMETER_KINDS
from robotcal.plots.figures import new_figure, save_figure, set_margins, y_label_room
from robotcal.uncertainty.montecarlo import MonteCarloResult

__all__ = ["write_histograms"]


def _bins(n_draws: int) -> int:
    return int(np.clip(round(2.0 * n_draws ** (1.0 / 3.0)), 20, 120))  # Rice rule, bounded


def write_histograms(result: MonteCarloResult, folder: str | Path, *, joints=None, deployed=None) -> list[Path]:
    """One PNG per joint, ``hist_J<i>.png``, a panel per identified parameter; returns the paths in joint order.

    ``joints`` (0-based, default every joint) draws only those joints' figures, each the same as in a call for
    every joint: a process pool draws a run's figures in parallel, a share of the joints per worker
    (:func:`robotcal.pipeline.figures.draw_histograms`).

    Each panel shows the draws as a density histogram, the mean (solid), the coverage interval for the
    measurand (dashed: the draws' interval of the kind chosen in the settings moved by twice the bias,
    :meth:`~robotcal.uncertainty.montecarlo.MonteCarloResult.interval`), the draws' own
    interval (dash-dot, thin), the linearised (GUM) normal density when the result has the linearised comparison
    (``result.linearised``; a refined Monte Carlo has it only when asked for), and the value the model gives for
    the noise-free capture (dotted): CPA's, or the refinement's for ``result.model == "refined"``, and the value
    stated (solid, green): ``deployed`` (a ParameterSet: the values deployed, the estimate corrected for the bias,
    the centre of the interval for the measurand), else the estimate the draws were simulated at
    (:attr:`~robotcal.uncertainty.montecarlo.MonteCarloResult.centre`). Angles in degrees, lengths in mm.
    """
    if result.draws is None:
        raise ValueError("the result holds no draws (run with keep_draws=True)")
    folder = Path(folder)
    low, high = result.interval()
    draws_low, draws_high = result.draws_interval()
    noise_free = "noise-free refinement" if result.model == "refined" else "noise-free CPA"
    stated, stated_label = (result.centre, "estimate") if deployed is None else (deployed.values, "deployed")
    written = []
    for joint in range(result.robot.n_joints) if joints is None else sorted(joints):
        columns = np.flatnonzero(result.identified[joint])
        if columns.size == 0:
            continue
        n_cols = min(3, columns.size)
        n_rows = math.ceil(columns.size / n_cols)
        width, height = 3.3 * n_cols, 2.6 * n_rows + 0.4
        figure, axes = new_figure(n_rows, n_cols, width_in=width, height_in=height, squeeze=False, layout=None)
        for axis in axes.ravel()[columns.size :]:
            axis.axis("off")
        for axis, column in zip(axes.ravel(), columns, strict=False):
            kind = PARAMETER_KINDS[column]
            scale = 180.0 / math.pi if kind in ANGLE_KINDS else 1.0
            unit = KIND_UNITS[kind]
            values = result.draws[:, joint, column] * scale
            density, edges = np.histogram(values, bins=_bins(values.size), density=True)
            axis.stairs(density, edges, fill=True, color="#8fb4d9", linewidth=0)
            axis.axvline(result.summary.mean[joint, column] * scale, color="#1f4e79", lw=1.5, label="mean")
            axis.axvline(stated[joint, column] * scale, color="#1e8449", lw=1.8, label=stated_label)
            interval = f"{result.settings.coverage:.0%} interval"
            axis.axvline(low[joint, column] * scale, color="#c0392b", ls="--", lw=1.2, label=interval)
            axis.axvline(high[joint, column] * scale, color="#c0392b", ls="--", lw=1.2)
            for end, label in ((draws_low, f"draws' {interval}"), (draws_high, None)):
                axis.axvline(end[joint, column] * scale, color="#7f8c8d", ls="-.", lw=0.9, label=label)
            axis.axvline(
                result.noise_free_values[joint, column] * scale, color="#444444", ls=":", lw=1.2, label=noise_free
            )
            if result.linearised is not None:
                sigma = result.linearised.std_uncertainty[joint, column] * scale
                centre = result.linearised.estimate[joint, column] * scale
                if sigma > 0:
                    grid = np.linspace(values.min(), values.max(), 200)
                    gum = np.exp(-0.5 * ((grid - centre) / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi))
                    axis.plot(grid, gum, color="#e67e22", lw=1.2, label="linearised (GUM)")
            axis.ticklabel_format(axis="x", useOffset=False)
            axis.xaxis.set_major_locator(MaxNLocator(4))  # few tick labels: no overlaps
            axis.yaxis.set_major_locator(MaxNLocator(4))
            axis.tick_params(axis="x", labelrotation=20)
            axis.set_xlabel(f"J{joint + 1}.{kind} [{unit}]")
            axis.set_ylabel(f"density [1/{unit}]")
        # fixed margins [in] (no constrained layout pass), wide enough for the widest y tick labels drawn: a
        # narrow distribution has densities in the thousands per unit
        room = max(y_label_room(axis) for axis in axes.ravel()[: columns.size])
        left, gap = max(0.62, room + 0.08), max(0.7, room + 0.25)
        set_margins(
            figure,
            left=left,
            right=0.3,
            bottom=0.95,
            top=0.3,
            wspace=gap,
            hspace=0.75,
            cell=((width - left - 0.3 + gap) / n_cols, 2.6),
        )
        figure.suptitle(f"J{joint + 1}: {result.n_draws:,} Monte Carlo draws", fontsize="medium")
        handles, labels = axes[0, 0].get_legend_handles_labels()
        figure.legend(handles, labels, loc="lower center", ncols=6, fontsize="small", frameon=False)
        written.append(save_figure(figure, folder / f"hist_J{joint + 1}.png"))
    return written
