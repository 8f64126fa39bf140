"""Figures of the joint diagnostics (thesis Figs 4.26-4.30): one panel per joint, lengths in µm."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from robotcal.diagnostics import CircleDiagnostics, HarmonicModel, JointDiagnostics
from robotcal.report.figures import new_figure, save_figure

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


def _panels(n_joints: int, title: str, *, height_per_row: float = 2.6):
    n_cols = min(3, n_joints)
    n_rows = math.ceil(n_joints / n_cols)
    figure, axes = new_figure(
        n_rows, n_cols, width_in=4.0 * n_cols, height_in=height_per_row * n_rows + 0.6, squeeze=False
    )
    figure.suptitle(title)
    flat = axes.ravel()
    for extra in flat[n_joints:]:
        extra.set_visible(False)
    return figure, flat[:n_joints]


def _each_joint(diagnostics: JointDiagnostics, axes):
    """(axis, circle or None) per joint; a joint without a circle gets a note in its panel."""
    present = {c.joint: c for c in diagnostics.circles}
    for joint, axis in enumerate(axes, start=1):
        circle = present.get(joint)
        axis.set_title(f"J{joint}")
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
    ``scale`` (the thesis uses 500); the axial component is not drawn.
    """
    figure, axes = _panels(diagnostics.n_joints, f"Backlash vectors in each circle's plane (arrows ×{scale:g})")
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
    axes[0].legend(loc="best", fontsize="small")
    return save_figure(figure, path)


def plot_backlash_xyz(diagnostics: JointDiagnostics, path) -> Path:
    """Signed backlash per coordinate (x, y, z of the tracker frame) against the angle (Fig. 4.27)."""
    figure, axes = _panels(diagnostics.n_joints, "Backlash per coordinate (return − forward) vs joint angle")
    for axis, circle in _each_joint(diagnostics, axes):
        if _no_backlash(axis, circle):
            continue
        angle = np.rad2deg(circle.pair_reading)
        for k, (name, colour) in enumerate(zip("xyz", ("tab:blue", "tab:green", "tab:red"), strict=True)):
            axis.plot(angle, circle.backlash[:, k] * UM, "o-", color=colour, ms=3, lw=1, label=f"Δ{name}")
        axis.axhline(0.0, color="0.6", lw=0.6)
        axis.set_xlabel("joint reading [deg]")
        axis.set_ylabel("backlash [µm]")
        axis.legend(loc="best", fontsize="x-small", ncols=3)
    return save_figure(figure, path)


def plot_backlash_magnitude(diagnostics: JointDiagnostics, path) -> Path:
    """Euclidean length of the backlash vector against the angle (Fig. 4.28); turnarounds hollow."""
    figure, axes = _panels(diagnostics.n_joints, "Backlash magnitude vs joint angle")
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
            axis.axhline(float(np.mean(magnitude[keep])), color="tab:purple", ls="--", lw=0.8, label="mean")
        axis.set_ylim(bottom=0.0)
        axis.set_xlabel("joint reading [deg]")
        axis.set_ylabel("|backlash| [µm]")
        axis.legend(loc="best", fontsize="x-small")
    return save_figure(figure, path)


def plot_eccentricity(diagnostics: JointDiagnostics, path, *, kind: str, model: HarmonicModel | None = None) -> Path:
    """Axial (Fig. 4.29) or radial (Fig. 4.30) eccentricity against the angle, with the harmonic model."""
    if kind not in ("axial", "radial"):
        raise ValueError(f"kind must be 'axial' or 'radial'; got {kind!r}")
    what = "distance to the fitted plane" if kind == "axial" else "distance to the fitted circle"
    figure, axes = _panels(diagnostics.n_joints, f"{kind.capitalize()} eccentricity ({what}) vs joint angle")
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
        axis.set_xlabel("joint reading [deg]")
        axis.set_ylabel(f"{kind} eccentricity [µm]")
        axis.legend(loc="best", fontsize="x-small")
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
    written.append(plot_eccentricity(diagnostics, folder / FIGURE_NAMES[3], kind="axial", model=model))
    written.append(plot_eccentricity(diagnostics, folder / FIGURE_NAMES[4], kind="radial", model=model))
    return written
