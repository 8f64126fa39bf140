"""Monte Carlo figures: histograms of the parameter draws (thesis Figs 5.11/5.12)."""

from __future__ import annotations

import math
import multiprocessing
import os
import sys
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.patches import StepPatch
from matplotlib.ticker import MaxNLocator
from matplotlib.transforms import Bbox

from robotcal.kinematics.model import ANGLE_KINDS, KIND_UNITS, PARAMETER_KINDS
from robotcal.plots.figures import new_figure, render_rgba, save_figure
from robotcal.uncertainty.montecarlo import MonteCarloResult

__all__ = ["write_histograms", "prepare_histograms"]


#: Draw joints with the same panel grid on one figure (False: a new figure each; the tests compare both).
_REUSE_FIGURES = True

#: Processes drawing the figures (the calling one included): at most this many, at most the CPU count.
#: A page costs ~0.1 s of drawing and PNG encoding (prepared, see prepare_histograms); on two cores, two processes
#: nearly halve the wall time.
MAX_PROCESSES = 2

#: What the forked drawing processes draw from (set just before the fork, cleared after).
_SHARED: tuple | None = None


def _bins(n_draws: int) -> int:
    return int(np.clip(round(2.0 * n_draws ** (1.0 / 3.0)), 20, 120))  # Rice rule, bounded


#: Colours and styles of a panel's lines (also those of the legend, which shows the first panel's).
_STAIRS_COLOUR = "#8fb4d9"
_MEAN_STYLE = {"color": "#1f4e79", "lw": 1.5}
_INTERVAL_STYLE = {"color": "#c0392b", "ls": "--", "lw": 1.2}
_NOISE_FREE_STYLE = {"color": "#444444", "ls": ":", "lw": 1.2}
_GUM_STYLE = {"color": "#e67e22", "lw": 1.2}


class _Panel:
    """One histogram panel's artists, made once and given each joint's data in turn.

    Made in the order the figure has always drawn them (filled stairs, mean, interval ends, noise-free
    value, linearised density), so that the axes draw them in that order. Moving an artist's data costs
    nothing like making it again (an ``axvline`` is ~1 ms of transforms and properties); the data limits
    are set here as ``add_artist``/``add_line`` would set them for new artists, from the same numbers.
    """

    def __init__(self, axis, interval_label: str):
        self.axis = axis
        # one filled step artist from counts by numpy (ax.hist makes a patch per bin: ~3x slower); added
        # as a plain artist: ``ax.stairs``/``add_patch`` find the limits by walking the outline, ~10 ms
        self.stairs = StepPatch([0.0], [0.0, 1.0], baseline=0.0, fill=True, color=_STAIRS_COLOUR, linewidth=0)
        axis.add_artist(self.stairs)
        self.stairs.sticky_edges.y.append(0.0)
        self.mean = axis.axvline(0.0, label="mean", **_MEAN_STYLE)
        self.low = axis.axvline(0.0, label=interval_label, **_INTERVAL_STYLE)
        self.high = axis.axvline(0.0, **_INTERVAL_STYLE)
        self.noise_free = axis.axvline(0.0, label="noise-free CPA", **_NOISE_FREE_STYLE)
        (self.gum,) = axis.plot([0.0, 1.0], [0.0, 1.0], label="linearised (GUM)", **_GUM_STYLE)
        axis.ticklabel_format(axis="x", useOffset=False)
        axis.xaxis.set_major_locator(MaxNLocator(4))  # fewer tick labels: quicker layout, no overlaps
        axis.yaxis.set_major_locator(MaxNLocator(4))
        axis.tick_params(axis="x", labelrotation=20)

    def show(
        self,
        density: np.ndarray,
        edges: np.ndarray,
        lines: tuple[float, float, float, float],
        gum: tuple[np.ndarray, np.ndarray] | None,
        xlabel: str,
        ylabel: str,
    ) -> None:
        """This panel's histogram (``density`` over ``edges``), its vertical lines (mean, interval ends,
        noise-free value), the linearised density curve ``(x, y)`` or None, and its axis labels."""
        axis = self.axis
        self.stairs.set_data(density, edges, baseline=0.0)
        for line, x in zip((self.mean, self.low, self.high, self.noise_free), lines, strict=True):
            line.set_xdata([x, x])
        self.gum.set_visible(gum is not None)
        if gum is not None:
            self.gum.set_data(*gum)
        # the data limits new artists would set: the stairs' extremes (first and last edge, 0 and the largest
        # density), the vertical lines' x, the curve's points (add_line: ~1 ms a line of transforms)
        axis.dataLim.set_points(Bbox.null().get_points())
        axis.ignore_existing_data_limits = True
        axis.update_datalim([(edges[0], 0.0), (edges[-1], float(np.max(density)))])
        for x in lines:  # an axvline's x in data, its y in axes coordinates: x only
            axis.dataLim.update_from_data_x([x, x], ignore=False)
        if gum is not None:
            axis.update_datalim(np.column_stack(gum))
        axis.set_xlabel(xlabel)
        axis.set_ylabel(ylabel)
        axis.autoscale_view()


class _Page:
    """A histogram figure for one panel grid (``n_panels`` in ``n_cols`` columns): its axes, panels,
    title and legend, made once and redrawn for every joint with that grid."""

    def __init__(self, n_panels: int, n_cols: int, interval_label: str):
        n_rows = math.ceil(n_panels / n_cols)
        width, height = 3.3 * n_cols, 2.6 * n_rows + 0.4
        # fixed margins [in] instead of constrained layout, which costs about half the drawing time
        self.figure, axes = new_figure(n_rows, n_cols, width_in=width, height_in=height, squeeze=False, layout=None)
        self.figure.subplots_adjust(
            left=0.62 / width,
            right=1.0 - 0.3 / width,
            bottom=0.95 / height,
            top=1.0 - 0.3 / height,
            wspace=0.7 / (3.3 - 0.7),
            hspace=0.75 / (2.6 - 0.75),
        )
        flat = axes.ravel()
        self.panels = [_Panel(axis, interval_label) for axis in flat[:n_panels]]
        for axis in flat[n_panels:]:
            axis.axis("off")
        self.legend = None
        self.legend_labels: tuple[str, ...] = ()

    def show(self, title: str) -> None:
        """The title, and the legend of the first panel's drawn lines (made again only if they change)."""
        self.figure.suptitle(title, fontsize="medium")
        first = self.panels[0]
        handles = [first.mean, first.low, first.noise_free] + ([first.gum] if first.gum.get_visible() else [])
        labels = tuple(handle.get_label() for handle in handles)
        if labels != self.legend_labels:
            if self.legend is not None:
                self.legend.remove()
            self.legend = self.figure.legend(
                handles, list(labels), loc="lower center", ncols=4, fontsize="small", frameon=False
            )
            self.legend_labels = labels


def write_histograms(result: MonteCarloResult, folder: str | Path, *, processes: int | None = None) -> list[Path]:
    """One PNG per joint, ``hist_J<i>.png``, a panel per identified parameter.

    Each panel shows the draws as a density histogram, the mean (solid), the coverage interval
    chosen in the settings (dashed), the linearised (GUM) normal density when available, and the
    value CPA gives for the noise-free capture (dotted). Angles in degrees, lengths in mm.

    Joints with the same panel grid are drawn on one figure whose artists are made once and given each
    joint's data (making the axes, their ticks and lines again cost about half the drawing time; the PNG
    bytes are the same).

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


#: Pages kept by this process (with ``_REUSE_FIGURES``): (panels, columns, interval label, style) -> page. A page
#: takes matplotlib's rcParams when it is made: the style is part of the key, so a change of rcParams (a style
#: context of a caller) gets pages of its own. At most :data:`_PAGES_KEPT` (cleared beyond).
_PAGES: dict[tuple[int, int, str, str], _Page] = {}
_PAGES_KEPT = 16

#: Tick objects made ahead on every axis of a prepared page: ``MaxNLocator(4)`` places at most 6 in the view
#: and the axis keeps a tick for every location it returns, one beyond each end included.
_TICKS_AHEAD = 8


def _interval_label(coverage: float) -> str:
    return f"{coverage:.0%} interval"


def _style() -> str:
    """The rcParams as text (~1 ms): pages made under other rcParams are not reused."""
    return repr(sorted(matplotlib.rcParams.items()))


def _page(n_panels: int, interval_label: str, style: str) -> _Page:
    """The page for ``n_panels`` panels: this process's (``_REUSE_FIGURES``), else a new one."""
    key = (n_panels, min(3, n_panels), interval_label, style)
    if not _REUSE_FIGURES:
        return _Page(*key[:3])
    if key not in _PAGES:
        if len(_PAGES) >= _PAGES_KEPT:
            _PAGES.clear()
        _PAGES[key] = _Page(*key[:3])
    return _PAGES[key]


def prepare_histograms(identified: np.ndarray, coverage: float) -> None:
    """Make the pages that :func:`write_histograms` will draw for ``identified`` (n_joints, 5) at ``coverage``,
    and draw each once into no file, with made-up data.

    Meant for a process that is otherwise idle while the draws are computed (``robotcal uncertainty``
    submits it to its figure worker before the draws): making the figure, its axes and tick objects,
    loading the fonts and laying out the legend's text are then done, and the pages drawn after the
    draws cost only their own data and text. Changes no file and no figure's pixels: a page draws the
    same bytes after any other page (the tests compare).
    """
    if not _REUSE_FIGURES:
        return
    label, style = _interval_label(coverage), _style()
    for n_panels in sorted({int(count) for count in np.count_nonzero(identified, axis=1) if count}):
        page = _page(n_panels, label, style)
        for panel in page.panels:
            for axis in (panel.axis.xaxis, panel.axis.yaxis):
                axis.get_major_ticks(_TICKS_AHEAD)
            panel.show(
                np.array([1.0, 2.0, 1.0]),
                np.array([0.0, 1.0, 2.0, 3.0]),
                (1.5, 0.5, 2.5, 1.5),
                (np.linspace(0.0, 3.0, 200), np.full(200, 1.0)),
                "J0.a [mm]",
                "density [1/mm]",
            )
        page.show("J0: 1 Monte Carlo draws")
        render_rgba(page.figure)


def _draw_forked(joints: list[int]) -> None:
    """Forked process: draw ``joints`` from ``_SHARED``; exit status 1 (silently) on any error."""
    try:
        result, folder = _SHARED
        _draw_joints(result, folder, joints)
    except BaseException:  # noqa: BLE001 - the parent draws these joints again and reports the error
        sys.exit(1)


def _draw_joints(result: MonteCarloResult, folder: Path, joints: list[int]) -> list[Path]:
    """Draw and write the histogram figures of ``joints`` (each with at least one identified parameter).

    Joints with the same panel grid are drawn on one :class:`_Page` (with ``_REUSE_FIGURES``), their data
    moved into its artists: the PNG bytes are those of a new figure per joint (the tests compare both).
    """
    low, high = result.interval()
    interval_label, style = _interval_label(result.settings.coverage), _style()
    written = []
    for joint in joints:
        columns = np.flatnonzero(result.identified[joint])
        if columns.size == 0:
            continue
        page = _page(columns.size, interval_label, style)
        for panel, column in zip(page.panels, columns, strict=True):
            kind = PARAMETER_KINDS[column]
            scale = 180.0 / math.pi if kind in ANGLE_KINDS else 1.0
            unit = KIND_UNITS[kind]
            values = result.draws[:, joint, column] * scale
            density, edges = np.histogram(values, bins=_bins(values.size), density=True)
            lines = (
                result.summary.mean[joint, column] * scale,
                low[joint, column] * scale,
                high[joint, column] * scale,
                result.noise_free_values[joint, column] * scale,
            )
            gum = None
            if result.linearised is not None:
                sigma = result.linearised.std_uncertainty[joint, column] * scale
                centre = result.linearised.estimate[joint, column] * scale
                if sigma > 0:
                    grid = np.linspace(values.min(), values.max(), 200)
                    gum = grid, np.exp(-0.5 * ((grid - centre) / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi))
            panel.show(density, edges, lines, gum, f"J{joint + 1}.{kind} [{unit}]", f"density [1/{unit}]")
        page.show(f"J{joint + 1}: {result.n_draws:,} Monte Carlo draws")
        written.append(save_figure(page.figure, folder / f"hist_J{joint + 1}.png"))
    return written
