"""Monte Carlo figures: histograms of the parameter draws (thesis Figs 5.11/5.12)."""

from __future__ import annotations

import math
import multiprocessing
import os
import sys
from pathlib import Path

import numpy as np
from matplotlib.patches import StepPatch
from matplotlib.ticker import MaxNLocator

from robotcal.kinematics.model import ANGLE_KINDS, KIND_UNITS, PARAMETER_KINDS
from robotcal.plots.figures import new_figure, save_figure
from robotcal.uncertainty.montecarlo import MonteCarloResult

__all__ = ["write_histograms"]


#: Draw joints with the same panel grid on one figure (False: a new figure each; the tests compare both).
_REUSE_FIGURES = True

#: Processes drawing the figures (the calling one included): at most this many, at most the CPU count.
#: A figure costs ~0.2 s of drawing and PNG encoding; on two cores, two processes halve the wall time.
MAX_PROCESSES = 2

#: What the forked drawing processes draw from (set just before the fork, cleared after).
_SHARED: tuple | None = None


def _bins(n_draws: int) -> int:
    return int(np.clip(round(2.0 * n_draws ** (1.0 / 3.0)), 20, 120))  # Rice rule, bounded


def _add_stairs(axis, density: np.ndarray, edges: np.ndarray) -> None:
    """``axis.stairs(density, edges, fill=True, ...)`` with the data limits set from the bin edges.

    ``ax.stairs`` (``add_patch``) finds the limits by walking the outline's Bezier segments, ~10 ms a
    panel; a step outline's extremes are its first and last edge, 0 and the largest density.
    """
    patch = StepPatch(density, edges, baseline=0.0, fill=True, color="#8fb4d9", linewidth=0)
    axis.add_artist(patch)
    patch.sticky_edges.y.append(0.0)
    axis.update_datalim([(edges[0], 0.0), (edges[-1], float(np.max(density)))])


def _empty(figure, axes) -> None:
    """Remove what a joint's panels added, so that the next joint draws as on a new figure (same PNG bytes)."""
    for legend in list(figure.legends):
        legend.remove()
    for axis in axes.ravel():
        for artist in [*axis.lines, *axis.collections, *axis.texts, *axis.patches]:
            artist.remove()
        axis.set_xlabel("")
        axis.set_ylabel("")
        axis.relim()
        axis.ignore_existing_data_limits = True
        axis.set_autoscale_on(True)
        axis.autoscale_view()


def write_histograms(result: MonteCarloResult, folder: str | Path, *, processes: int | None = None) -> list[Path]:
    """One PNG per joint, ``hist_J<i>.png``, a panel per identified parameter.

    Each panel shows the draws as a density histogram, the mean (solid), the coverage interval
    chosen in the settings (dashed), the linearised (GUM) normal density when available, and the
    value CPA gives for the noise-free capture (dotted). Angles in degrees, lengths in mm.

    Joints with the same panel grid are drawn on one figure, emptied in between (creating the axes and
    their tick objects again cost about a quarter of the drawing time; the PNG bytes are the same).

    ``processes`` (default: ``MAX_PROCESSES``, at most the CPU count and the number of figures) share
    the joints: the others are forked from this one where the platform forks (they inherit matplotlib
    and the draws, so nothing is pickled), each writes its own files (atomically), and a joint whose
    process failed is drawn again here, so that an error surfaces in this process. The files are the
    same whatever the number of processes. Returns the paths in joint order.
    """
    global _SHARED
    if result.draws is None:
        raise ValueError("the result holds no draws (run with keep_draws=True)")
    folder = Path(folder)
    joints = [joint for joint in range(result.robot.n_joints) if np.any(result.identified[joint])]
    if processes is None:
        processes = min(MAX_PROCESSES, os.cpu_count() or 1)
    processes = max(1, min(processes, len(joints)))
    if processes == 1 or "fork" not in multiprocessing.get_all_start_methods():
        return _draw_joints(result, folder, joints)
    shares = [joints[index::processes] for index in range(processes)]
    context = multiprocessing.get_context("fork")
    started, left = [], list(shares[0])
    _SHARED = (result, folder)
    try:
        for share in shares[1:]:
            child = context.Process(target=_draw_forked, args=(share,), daemon=True)
            try:
                child.start()
            except (AssertionError, OSError):  # a daemonic process may not have children; no process left
                left.extend(share)
            else:
                started.append((child, share))
        try:
            _draw_joints(result, folder, sorted(left))
        finally:
            for child, _ in started:
                child.join()
    finally:
        _SHARED = None
    for child, share in started:
        if child.exitcode != 0:  # draw them here: the same error, if any, is raised in this process
            _draw_joints(result, folder, share)
    return [folder / f"hist_J{joint + 1}.png" for joint in joints]


def _draw_forked(joints: list[int]) -> None:
    """Forked process: draw ``joints`` from ``_SHARED``; exit status 1 (silently) on any error."""
    try:
        result, folder = _SHARED
        _draw_joints(result, folder, joints)
    except BaseException:  # noqa: BLE001 - the parent draws these joints again and reports the error
        sys.exit(1)


def _draw_joints(result: MonteCarloResult, folder: Path, joints: list[int]) -> list[Path]:
    """Draw and write the histogram figures of ``joints`` (each with at least one identified parameter)."""
    low, high = result.interval()
    written = []
    grids: dict[tuple[int, int], tuple] = {}  # (panels, columns) -> (figure, axes), reused
    for joint in joints:
        columns = np.flatnonzero(result.identified[joint])
        if columns.size == 0:
            continue
        n_cols = min(3, columns.size)
        n_rows = math.ceil(columns.size / n_cols)
        width, height = 3.3 * n_cols, 2.6 * n_rows + 0.4
        key = (columns.size, n_cols)
        if key in grids and _REUSE_FIGURES:
            figure, axes = grids[key]
            _empty(figure, axes)
        else:
            # fixed margins [in] instead of constrained layout, which costs about half the drawing time
            figure, axes = new_figure(n_rows, n_cols, width_in=width, height_in=height, squeeze=False, layout=None)
            grids[key] = figure, axes
        figure.subplots_adjust(
            left=0.62 / width,
            right=1.0 - 0.3 / width,
            bottom=0.95 / height,
            top=1.0 - 0.3 / height,
            wspace=0.7 / (3.3 - 0.7),
            hspace=0.75 / (2.6 - 0.75),
        )
        for panel, column in enumerate(columns):
            axis = axes[panel // n_cols][panel % n_cols]
            kind = PARAMETER_KINDS[column]
            scale = 180.0 / math.pi if kind in ANGLE_KINDS else 1.0
            unit = KIND_UNITS[kind]
            values = result.draws[:, joint, column] * scale
            # counts by numpy, drawn as one filled step artist (ax.hist makes a patch per bin: ~3x slower)
            density, edges = np.histogram(values, bins=_bins(values.size), density=True)
            _add_stairs(axis, density, edges)
            mean = result.summary.mean[joint, column] * scale
            axis.axvline(mean, color="#1f4e79", lw=1.5, label="mean")
            axis.axvline(
                low[joint, column] * scale,
                color="#c0392b",
                ls="--",
                lw=1.2,
                label=f"{result.settings.coverage:.0%} interval",
            )
            axis.axvline(high[joint, column] * scale, color="#c0392b", ls="--", lw=1.2)
            axis.axvline(
                result.noise_free_values[joint, column] * scale, color="#444444", ls=":", lw=1.2, label="noise-free CPA"
            )
            if result.linearised is not None:
                sigma = result.linearised.std_uncertainty[joint, column] * scale
                centre = result.linearised.estimate[joint, column] * scale
                if sigma > 0:
                    grid = np.linspace(values.min(), values.max(), 200)
                    density = np.exp(-0.5 * ((grid - centre) / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi))
                    axis.plot(grid, density, color="#e67e22", lw=1.2, label="linearised (GUM)")
            axis.set_xlabel(f"J{joint + 1}.{kind} [{unit}]")
            axis.set_ylabel(f"density [1/{unit}]")
            axis.ticklabel_format(axis="x", useOffset=False)
            axis.xaxis.set_major_locator(MaxNLocator(4))  # fewer tick labels: quicker layout, no overlaps
            axis.yaxis.set_major_locator(MaxNLocator(4))
            axis.tick_params(axis="x", labelrotation=20)
            axis.autoscale_view()  # the limits ax.stairs would request: its patch is added without them
        for panel in range(columns.size, n_rows * n_cols):
            axes[panel // n_cols][panel % n_cols].axis("off")
        handles, labels = axes[0][0].get_legend_handles_labels()
        figure.suptitle(f"J{joint + 1}: {result.n_draws:,} Monte Carlo draws", fontsize="medium")
        figure.legend(handles, labels, loc="lower center", ncols=4, fontsize="small", frameon=False)
        written.append(save_figure(figure, folder / f"hist_J{joint + 1}.png"))
    return written
