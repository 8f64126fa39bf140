"""Figures of the TCP uncertainty (thesis Figs 5.17-5.20) and of the workspace map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import Normalize
from matplotlib.ticker import MaxNLocator

from robotcal.errors import InputError
from robotcal.plots.figures import new_figure, save_figure, set_margins, y_label_room
from robotcal.uncertainty.tcp import TCP_COORDINATES, TCP_UNITS, TCPUncertainty
from robotcal.uncertainty.workspace import WorkspaceUncertainty

__all__ = ["plot_tcp_scatter", "plot_tcp_histograms", "plot_trajectory", "plot_workspace", "write_tcp_figures"]

_DEG = np.array([1.0, 1.0, 1.0, *([180.0 / np.pi] * 3)])


def _need_draws(result: TCPUncertainty, pose: int) -> np.ndarray:
    if result.draws is None:
        raise InputError("this figure needs the draws: call propagate_to_tcp(..., keep_draws=True)")
    return result.draws[:, pose] * _DEG


def _ellipsoid_mesh(semi_axes: np.ndarray, directions: np.ndarray, n: int = 24):
    u = np.linspace(0.0, 2.0 * np.pi, n)
    v = np.linspace(0.0, np.pi, n // 2)
    sphere = np.stack(
        [np.outer(np.cos(u), np.sin(v)), np.outer(np.sin(u), np.sin(v)), np.outer(np.ones_like(u), np.cos(v))]
    )
    points = np.einsum("ij,j,jkl->ikl", directions, semi_axes, sphere)
    return points[0], points[1], points[2]


def plot_tcp_scatter(result: TCPUncertainty, path, *, pose: int = 0, max_points: int = 4000, rng=0) -> Path:
    """3-D scatter of the TCP positions of the draws around their mean, with the coverage ellipsoid (Fig. 5.19).

    Positions are drawn relative to the mean (a calibrated robot's mean can sit millimetres from the
    nominal, which would squash the cloud to a dot); the title gives the mean minus the nominal.
    """
    rng = np.random.default_rng(rng)
    mean = result.summary.mean[pose, :3]
    draws = _need_draws(result, pose)[:, :3] - mean
    if draws.shape[0] > max_points:
        draws = draws[rng.choice(draws.shape[0], max_points, replace=False)]
    figure, _ = new_figure(0, width_in=6.4, height_in=5.6, layout=None)
    axes = figure.add_axes((0.0, 0.04, 0.94, 0.82), projection="3d")
    axes.scatter(draws[:, 0], draws[:, 1], draws[:, 2], s=2, alpha=0.25, color="tab:blue", label="draws")
    x, y, z = _ellipsoid_mesh(result.ellipsoid.semi_axes[pose], result.ellipsoid.directions[pose])
    axes.plot_wireframe(x, y, z, color="tab:red", linewidth=0.5, alpha=0.6, label=f"{result.coverage:.0%} ellipsoid")
    axes.set_xlabel("X - mean [mm]", labelpad=10)
    axes.set_ylabel("Y - mean [mm]", labelpad=10)
    axes.set_zlabel("Z - mean [mm]", labelpad=10)
    for axis in (axes.xaxis, axes.yaxis, axes.zaxis):
        axis.set_major_locator(MaxNLocator(5, symmetric=True))  # fewer tick labels, no overlaps
    semi = ", ".join(f"{a:.3g}" for a in result.ellipsoid.semi_axes[pose])
    offset = ", ".join(f"{v:+.3g}" for v in mean - result.nominal[pose, :3])
    figure.suptitle(  # above the 3-D box, clear of the legend
        f"TCP positions of {result.n_draws} draws, pose {pose + 1}; mean - nominal = ({offset}) mm\n"
        f"{result.coverage:.0%} ellipsoid semi-axes {semi} mm",
        fontsize=9,
        y=0.985,
    )
    figure.legend(*axes.get_legend_handles_labels(), loc="upper left", bbox_to_anchor=(0.02, 0.9), fontsize=8)
    return save_figure(figure, path)


def plot_tcp_histograms(result: TCPUncertainty, path, *, pose: int = 0, bins: int = 60) -> Path:
    """Histograms of X, Y, Z [mm] and A, B, C [deg] over the draws at one pose (Figs 5.17/5.18).

    Each panel shows the draws about their mean (its title gives the mean): a calibrated robot's mean can
    sit far from the nominal (0.85 mm against a spread of a few µm), and an axis that spans both squashes
    the histogram to a line. The nominal is drawn where it lies within the draws' range; elsewhere the
    title gives it as ``nominal = mean + d``.
    """
    draws = _need_draws(result, pose)
    figure, axes = new_figure(2, 3, width_in=10.0, height_in=5.6, layout=None)
    low, high = result.summary.interval("symmetric")
    for k, ax in enumerate(axes.ravel()):
        f = _DEG[k]
        mean = result.summary.mean[pose, k] * f
        values = draws[:, k] - mean
        counts, edges = np.histogram(values, bins=bins)  # one step artist, not a patch per bin
        ax.stairs(counts, edges, fill=True, color="tab:blue", alpha=0.75, linewidth=0)
        ax.axvline(0.0, color="tab:red", linewidth=1.2, label="mean")
        for bound in (low[pose, k], high[pose, k]):
            ax.axvline(bound * f - mean, color="tab:red", linestyle="--", linewidth=1.0)
        nominal = result.nominal[pose, k] * f - mean
        unit = TCP_UNITS[k]
        where = ""
        if edges[0] <= nominal <= edges[-1]:
            ax.axvline(nominal, color="black", linestyle=":", linewidth=1.5, label="nominal")
        else:
            where = f"\nnominal = mean {nominal:+.3g} {unit} (off the axis)"
        angle = " (KUKA, about " + "ZYX"[k - 3] + ")" if k >= 3 else ""
        ax.set_xlabel(f"{TCP_COORDINATES[k]}{angle} - mean [{unit}]")
        ax.set_ylabel("draws")
        u = result.summary.std_uncertainty[pose, k] * f
        ax.set_title(f"mean {mean:.6g} {unit}, u = {u:.4g} {unit}{where}", fontsize=8, y=1.0)
        ax.ticklabel_format(axis="x", useOffset=False)  # an offset label ("-1.65e2") would sit on the x label
        ax.xaxis.set_major_locator(MaxNLocator(4, symmetric=True))
        ax.yaxis.set_major_locator(MaxNLocator(5))
    handles: dict[str, object] = {}
    for ax in axes.ravel():  # mean and interval always; the nominal where some panel draws it
        handles.update(zip(*reversed(ax.get_legend_handles_labels()), strict=True))
    axes[0, 0].legend(list(handles.values()), list(handles), fontsize=7, loc="upper left")
    # fixed margins [in], wide enough for the count labels drawn (thousands with many draws)
    room = max(y_label_room(ax) for ax in axes.ravel())
    left, gap = max(0.65, room + 0.08), max(0.75, room + 0.25)
    cell = ((10.0 - left - 0.15 + gap) / 3, 2.23)
    set_margins(figure, left=left, right=0.15, bottom=0.6, top=0.7, wspace=gap, hspace=1.0, cell=cell)
    figure.suptitle(
        f"TCP at pose {pose + 1}: {result.n_draws} draws about their mean, {result.coverage:.0%} interval dashed",
        fontsize=10,
    )
    return save_figure(figure, path)


def plot_trajectory(result: TCPUncertainty, path) -> Path:
    """The trajectory coloured by its uncertainty (Fig. 5.20) with per-pose u and ranges."""
    figure, _ = new_figure(0, width_in=11.0, height_in=8.0, layout=None)
    # fixed positions [figure fraction]; the 3-D panel and its colour bar keep clear of each other's labels
    grid = figure.add_gridspec(2, 2, left=0.085, right=0.985, bottom=0.065, top=0.93, wspace=0.25, hspace=0.3)
    axes3d = figure.add_subplot(grid[0, 0], projection="3d")
    position = result.nominal[:, :3]
    value_range = result.value_range * _DEG
    colour = value_range[:, :3].max(axis=1)
    axes3d.plot(position[:, 0], position[:, 1], position[:, 2], color="0.7", linewidth=0.8)
    points = axes3d.scatter(position[:, 0], position[:, 1], position[:, 2], c=colour, cmap="viridis", s=18)
    colour_axes = figure.add_axes((0.075, 0.6, 0.012, 0.28))  # left of the 3-D box, in its empty margin
    colour_bar = figure.colorbar(points, cax=colour_axes, label="largest range of X, Y, Z [mm]")
    colour_bar.ax.yaxis.set_ticks_position("left")
    colour_bar.ax.yaxis.set_label_position("left")
    axes3d.set_xlabel("X [mm]", labelpad=8)
    axes3d.set_ylabel("Y [mm]", labelpad=8)
    axes3d.set_zlabel("Z [mm]", labelpad=8)
    for axis in (axes3d.xaxis, axes3d.yaxis, axes3d.zaxis):
        axis.set_major_locator(MaxNLocator(4))
    axes3d.set_title("nominal TCP path, coloured by max - min", fontsize=9, y=1.0)
    pose = np.arange(1, result.n_poses + 1)
    std = result.std_uncertainty * _DEG
    position_labels = TCP_COORDINATES[:3]
    angle_labels = [f"{TCP_COORDINATES[k]} (about {'ZYX'[k - 3]})" for k in range(3, 6)]
    for cell, values, labels, y_label, title in (
        (grid[0, 1], value_range[:, :3], position_labels, "max - min over the draws [mm]", "range per coordinate (thesis Fig. 5.20)"),
        (grid[1, 0], std[:, :3], position_labels, "standard uncertainty [mm]", "position"),
        (grid[1, 1], std[:, 3:], angle_labels, "standard uncertainty [deg]", "orientation (KUKA A, B, C)"),
    ):
        ax = figure.add_subplot(cell)
        for k, label in enumerate(labels):
            ax.plot(pose, values[:, k], marker=".", label=label)
        ax.set_xlabel("pose")
        ax.set_ylabel(y_label)
        ax.set_title(title, fontsize=9, y=1.0)
        ax.legend(fontsize=8, loc="upper right")
    figure.suptitle(f"TCP uncertainty along {result.n_poses} poses, {result.n_draws} draws", fontsize=10)
    return save_figure(figure, path)


def plot_workspace(workspace: WorkspaceUncertainty, path) -> Path:
    """Sampled TCP positions coloured by ``sqrt(u_X^2 + u_Y^2 + u_Z^2)``: top view, side view, histogram."""
    result = workspace.tcp
    position = result.nominal[:, :3]
    value = workspace.position_uncertainty
    figure, axes = new_figure(1, 3, width_in=13.0, height_in=4.4, layout=None)
    set_margins(figure, left=0.75, right=0.2, bottom=0.6, top=0.4, wspace=0.9, cell=(3.77, 3.4))
    norm = Normalize(vmin=float(value.min()), vmax=float(value.max()))
    order = np.argsort(value)  # most uncertain drawn last, on top
    axes[0].scatter(position[order, 0], position[order, 1], c=value[order], cmap="viridis", norm=norm, s=10)
    axes[0].set_xlabel("X [mm]")
    axes[0].set_ylabel("Y [mm]")
    axes[0].set_title("top view", fontsize=9, y=1.0)
    axes[0].set_aspect("equal", adjustable="datalim")
    radial = np.hypot(position[:, 0], position[:, 1])
    points = axes[1].scatter(radial[order], position[order, 2], c=value[order], cmap="viridis", norm=norm, s=10)
    axes[1].set_xlabel("distance from the base axis sqrt(X^2 + Y^2) [mm]")
    axes[1].set_ylabel("Z [mm]")
    axes[1].set_title("side view", fontsize=9, y=1.0)
    axes[1].set_aspect("equal", adjustable="datalim")
    figure.colorbar(points, ax=axes[:2], label="position standard uncertainty sqrt(trace V) [mm]", pad=0.02)
    counts, edges = np.histogram(value, bins=40)  # one step artist, not a patch per bin
    axes[2].stairs(counts, edges, fill=True, color="tab:blue", alpha=0.8, linewidth=0)
    for level, mark in zip(workspace.percentiles, workspace.position_uncertainty_percentiles, strict=True):
        if level in (5.0, 50.0, 95.0):
            axes[2].axvline(mark, color="tab:red", linestyle="--", linewidth=1.0)
            axes[2].text(mark, axes[2].get_ylim()[1] * 0.95, f"P{level:g}", fontsize=7, rotation=90, va="top")
    axes[2].set_xlabel("position standard uncertainty [mm]")
    axes[2].set_ylabel("poses")
    axes[2].set_title(f"{result.n_poses} random poses, {result.n_draws} draws", fontsize=9, y=1.0)
    return save_figure(figure, path)


def write_tcp_figures(result: TCPUncertainty, folder, mode: str, *, workspace: WorkspaceUncertainty | None = None) -> list[Path]:
    """The figures of a TCP folder: pose -> ``scatter.png``, ``histograms.png``; trajectory -> ``trajectory.png``;
    workspace -> ``workspace.png`` (from ``workspace``). Returns the paths written."""
    folder = Path(folder)
    if mode == "pose":
        return [plot_tcp_scatter(result, folder / "scatter.png"), plot_tcp_histograms(result, folder / "histograms.png")]
    if mode == "trajectory":
        return [plot_trajectory(result, folder / "trajectory.png")]
    if workspace is None:
        raise InputError("the workspace figure needs `workspace` (a WorkspaceUncertainty)")
    return [plot_workspace(workspace, folder / "workspace.png")]
