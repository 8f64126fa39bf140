"""Figures of the joint diagnostics (thesis Figs 4.26-4.30): one panel per joint, lengths in µm."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.ticker import MaxNLocator

from robotcal.diagnostics import CircleDiagnostics, HarmonicModel, JointDiagnostics
from robotcal.plots.figures import new_figure, save_figure

__all__ = [
    "plot_backlash_vectors",
    "plot_backlash_xyz",
    "plot_backlash_magnitude",
    "plot_eccentricity",
    "write_joint_figures",
    "FIGURE_NAMES",
]

#: File names written by :func:`write_joint_figures`.
FIGURE_NAMES = (
    "backlash_vectors.png",
    "backlash_xyz.png",
    "backlash_magnitude.png",
    "eccentricity_axial.png",
    "eccentricity_radial.png",
)
UM = 1000.0  # mm -> µm
FORWARD, RETURN = "tab:blue", "tab:orange"


#: Fixed margins of the panel grid [in]: left, right, bottom (room for the figure legend), top, and the
#: gaps between panels.
_MARGINS_IN = {"left": 0.8, "right": 0.2, "bottom": 0.85, "top": 0.6, "wspace": 0.85, "hspace": 0.8}
_PANEL_WIDTH_IN = 4.0
NOISE = "0.25"  # colour of the noise-floor lines


def _panels(n_joints: int, title: str, *, height_per_row: float = 2.6):
    """A grid of up to 3 panels a row with fixed margins."""
    n_cols = min(3, n_joints)
    n_rows = math.ceil(n_joints / n_cols)
    m = _MARGINS_IN
    width = _PANEL_WIDTH_IN * n_cols
    height = height_per_row * n_rows + m["bottom"] + m["top"] - m["hspace"]
    figure, axes = new_figure(n_rows, n_cols, width_in=width, height_in=height, squeeze=False, layout=None)
    figure.subplots_adjust(
        left=m["left"] / width,
        right=1.0 - m["right"] / width,
        bottom=m["bottom"] / height,
        top=1.0 - m["top"] / height,
        wspace=m["wspace"] / (_PANEL_WIDTH_IN - m["wspace"]),
        hspace=m["hspace"] / (height_per_row - m["hspace"]),
    )
    figure.suptitle(title)
    flat = axes.ravel()
    for extra in flat[n_joints:]:
        extra.set_visible(False)
    return figure, flat[:n_joints]




def _legend(figure, axes) -> None:
    """One legend for the figure, below the panels: every panel draws the same kinds of line.

    (Per-panel ``loc="best"`` legends searched each panel's data for a free corner, a tenth of the
    drawing time; entries are collected from all panels, first label wins.)
    """
    entries: dict[str, object] = {}
    for axis in axes:
        for handle, label in zip(*axis.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    if entries:
        figure.legend(
            list(entries.values()), list(entries), loc="lower center", ncols=min(6, len(entries)),
            fontsize="small", frameon=False,
        )  # fmt: skip


def _each_joint(diagnostics: JointDiagnostics, axes):
    """(axis, circle or None) per joint; a joint without a circle gets a note in its panel."""
    present = {c.joint: c for c in diagnostics.circles}
    for joint, axis in enumerate(axes, start=1):
        circle = present.get(joint)
        axis.set_title(f"J{joint}", y=1.0)  # a fixed y: matplotlib then skips its title-overlap search
        axis.xaxis.set_major_locator(MaxNLocator(5))
        axis.yaxis.set_major_locator(MaxNLocator(5))
        if circle is None:
            axis.text(0.5, 0.5, "no circle in the capture", ha="center", va="center", transform=axis.transAxes)
            axis.set_xticks([])
            axis.set_yticks([])
        yield axis, circle


def _no_backlash(axis, circle: CircleDiagnostics) -> bool:
    if circle is not None and circle.n_pairs == 0:
        axis.text(0.5, 0.5, "no forward/return pairs", ha="center", va="center", transform=axis.transAxes)
        return True
    return circle is None


def plot_backlash_vectors(diagnostics: JointDiagnostics, path, *, scale: float = 500.0) -> Path:
    """Backlash vectors along each circle (Fig. 4.26), drawn in the circle's plane.

    Arrows start at the forward point and end at the return point, their length multiplied by
    ``scale`` (the thesis uses 500); the axial component is not drawn. Positions in mm.
    """
    figure, axes = _panels(
        diagnostics.n_joints, f"Backlash vectors in each circle's plane (arrows ×{scale:g})"
    )
    for axis, circle in _each_joint(diagnostics, axes):
        if circle is None:
            continue
        offsets = circle.points - circle.centre
        first = offsets[0] - (offsets[0] @ circle.normal) * circle.normal
        e1 = first / np.linalg.norm(first)  # in-plane axes: e1 towards the first point, e2 = normal x e1
        e2 = np.cross(circle.normal, e1)
        points = np.stack([offsets @ e1, offsets @ e2], axis=-1)
        angle = np.linspace(0.0, 2 * np.pi, 361)
        axis.plot(circle.radius * np.cos(angle), circle.radius * np.sin(angle), color="0.8", lw=0.8, zorder=0)
        forward = circle.direction == 1
        axis.plot(points[forward, 0], points[forward, 1], ".", color=FORWARD, ms=3, label="forward")
        axis.plot(points[~forward, 0], points[~forward, 1], ".", color=RETURN, ms=3, label="return")
        if circle.n_pairs:
            start = points[np.searchsorted(circle.rows, circle.pair_forward)]
            arrows = np.stack([circle.backlash @ e1, circle.backlash @ e2], axis=-1) * scale
            axis.quiver(
                start[:, 0], start[:, 1], arrows[:, 0], arrows[:, 1],
                angles="xy", scale_units="xy", scale=1.0, color="tab:red", width=0.006,
            )  # fmt: skip
        else:
            axis.text(0.5, 0.5, "no forward/return pairs", ha="center", va="center", transform=axis.transAxes)
        axis.set_aspect("equal", adjustable="datalim")
        axis.set_xlabel("in-plane u [mm]")
        axis.set_ylabel("in-plane v [mm]")
    _legend(figure, axes)
    return save_figure(figure, path)


def plot_backlash_xyz(diagnostics: JointDiagnostics, path) -> Path:
    """Signed backlash per coordinate (x, y, z of the tracker frame) against the angle (Fig. 4.27), in µm.

    Dashed: ``+-sqrt(2) sigma``, one standard deviation of a component of the difference of two noisy
    points (:attr:`~robotcal.diagnostics.CircleDiagnostics.noise_sigma`).
    """
    figure, axes = _panels(
        diagnostics.n_joints, "Backlash per coordinate (return − forward) vs joint angle"
    )
    for axis, circle in _each_joint(diagnostics, axes):
        if _no_backlash(axis, circle):
            continue
        angle = np.rad2deg(circle.pair_reading)
        for k, (name, colour) in enumerate(zip("xyz", ("tab:blue", "tab:green", "tab:red"), strict=True)):
            axis.plot(angle, circle.backlash[:, k] * UM, "o-", color=colour, ms=3, lw=1, label=f"Δ{name}")
        axis.axhline(0.0, color="0.6", lw=0.6)
        band = math.sqrt(2.0) * circle.noise_sigma * UM
        if math.isfinite(band):
            for sign in (1.0, -1.0):
                axis.axhline(sign * band, color=NOISE, ls="--", lw=0.8, label="noise ±1 s.d. of a difference")
        axis.set_xlabel("joint reading [deg]")
        axis.set_ylabel("backlash [µm]")
    _legend(figure, axes)
    return save_figure(figure, path)


def plot_backlash_magnitude(diagnostics: JointDiagnostics, path) -> Path:
    """Euclidean length of the backlash vector against the angle (Fig. 4.28), in µm; turnarounds hollow.

    The dashed line is the noise floor, the mean magnitude that instrument noise alone gives
    (:attr:`~robotcal.diagnostics.CircleDiagnostics.backlash_noise_floor`); each panel's title says
    whether the joint's mean lies above it (:attr:`~robotcal.diagnostics.JointSummary.backlash_exceeds_noise`).
    """
    figure, axes = _panels(diagnostics.n_joints, "Backlash magnitude vs joint angle (dashed: noise floor)")
    summary = {row.joint: row for row in diagnostics.summary()}
    for axis, circle in _each_joint(diagnostics, axes):
        if _no_backlash(axis, circle):
            continue
        angle = np.rad2deg(circle.pair_reading)
        magnitude = circle.backlash_magnitude * UM
        keep = ~circle.turnaround
        axis.plot(angle, magnitude, "-", color="0.6", lw=0.8)
        axis.plot(angle[keep], magnitude[keep], "o", color="tab:purple", ms=4, label="pair")
        if np.any(~keep):
            axis.plot(angle[~keep], magnitude[~keep], "o", mfc="none", color="tab:purple", ms=5, label="turnaround")
        if np.any(keep):
            axis.axhline(float(np.mean(magnitude[keep])), color="tab:purple", ls="-.", lw=0.9, label="mean")
        floor = circle.backlash_noise_floor * UM
        if math.isfinite(floor):
            axis.axhline(floor, color=NOISE, ls="--", lw=1.0, label="noise floor (instrument alone)")
            row = summary[circle.joint]
            verdict = "above noise" if row.backlash_exceeds_noise else "within noise"
            axis.set_title(f"J{circle.joint}: {verdict} (floor {floor:.1f} µm)", y=1.0, fontsize="medium")
        axis.set_ylim(bottom=0.0)
        axis.set_xlabel("joint reading [deg]")
        axis.set_ylabel("|backlash| [µm]")
    _legend(figure, axes)
    return save_figure(figure, path)


def plot_eccentricity(
    diagnostics: JointDiagnostics, path, *, kind: str, model: HarmonicModel | None = None
) -> Path:
    """Axial (Fig. 4.29) or radial (Fig. 4.30) eccentricity against the angle, with the harmonic model, in µm.

    Dashed: ``+-2 sigma`` of the instrument noise (:attr:`~robotcal.diagnostics.CircleDiagnostics.noise_sigma`),
    where about 95 % of the points of an error-free joint would lie.
    """
    if kind not in ("axial", "radial"):
        raise ValueError(f"kind must be 'axial' or 'radial'; got {kind!r}")
    what = "distance to the fitted plane" if kind == "axial" else "distance to the fitted circle"
    figure, axes = _panels(
        diagnostics.n_joints, f"{kind.capitalize()} eccentricity ({what}) vs joint angle"
    )
    for axis, circle in _each_joint(diagnostics, axes):
        if circle is None:
            continue
        values = (circle.axial if kind == "axial" else circle.radial) * UM
        angle = np.rad2deg(circle.reading)
        forward = circle.direction == 1
        axis.plot(angle[forward], values[forward], "^", color=FORWARD, ms=4, label="forward")
        axis.plot(angle[~forward], values[~forward], "v", color=RETURN, ms=4, label="return")
        fit = model.fit(circle.joint, kind) if model is not None else None
        if fit is not None:
            grid = np.linspace(circle.reading.min(), circle.reading.max(), 300)
            axis.plot(np.rad2deg(grid), fit.evaluate(grid) * UM, "k-", lw=1, label=f"harmonics K={fit.order}")
        axis.axhline(0.0, color="0.6", lw=0.6)
        band = 2.0 * circle.noise_sigma * UM
        if math.isfinite(band):
            for sign in (1.0, -1.0):
                axis.axhline(sign * band, color=NOISE, ls="--", lw=0.8, label="instrument noise ±2σ")
        axis.set_xlabel("joint reading [deg]")
        axis.set_ylabel(f"{kind} eccentricity [µm]")
    _legend(figure, axes)
    return save_figure(figure, path)


def write_joint_figures(
    diagnostics: JointDiagnostics, folder, *, model: HarmonicModel | None = None, scale: float = 500.0
) -> list[Path]:
    """Write the figures of :data:`FIGURE_NAMES` into ``folder`` (backlash ones only with backlash)."""
    folder = Path(folder)
    written = []
    if diagnostics.backlash:
        written.append(plot_backlash_vectors(diagnostics, folder / FIGURE_NAMES[0], scale=scale))
        written.append(plot_backlash_xyz(diagnostics, folder / FIGURE_NAMES[1]))
        written.append(plot_backlash_magnitude(diagnostics, folder / FIGURE_NAMES[2]))
    for name, kind in ((FIGURE_NAMES[3], "axial"), (FIGURE_NAMES[4], "radial")):
        written.append(plot_eccentricity(diagnostics, folder / name, kind=kind, model=model))
    return written
