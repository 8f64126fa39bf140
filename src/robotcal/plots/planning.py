"""Figures of the planning commands: cell check, sensitivity (Figs 5.14-5.16), optimisation.

The files they accompany: :mod:`robotcal.planning.files`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robotcal.planning.cell import PlanCheck
from robotcal.plots.figures import new_figure, save_figure

__all__ = ["plot_check", "plot_sensitivity", "plot_optimisation"]


def plot_check(check: PlanCheck, path: Path, *, acceptance_deg: float | None) -> Path:
    """Per circle: line-of-sight clearance and incidence angle against the turning joint's reading."""
    n = check.readings.shape[1]
    width, height = 2.6 * n, 5.0
    # fixed margins [in] instead of constrained layout, which measured all 2 n panels on every draw
    figure, axes = new_figure(2, n, width_in=width, height_in=height, squeeze=False, layout=None)
    panel_width, panel_height = (width - 0.9) / n, (height - 1.15) / 2
    figure.subplots_adjust(
        left=0.75 / width, right=1.0 - 0.15 / width, bottom=0.55 / height, top=1.0 - 0.6 / height,
        wspace=0.45 / (panel_width - 0.45), hspace=0.6 / (panel_height - 0.6),
    )  # fmt: skip
    for c in range(1, n + 1):
        rows = np.flatnonzero((check.circle == c) & (check.direction == 1))
        x = np.rad2deg(check.readings[rows, c - 1])
        ok = check.ok[rows]
        top, bottom = axes[0, c - 1], axes[1, c - 1]
        clearance = np.where(np.isfinite(check.clearance[rows]), check.clearance[rows], np.nan)
        top.plot(x, clearance, color="0.6", lw=1)
        top.scatter(x[ok], clearance[ok], s=12, color="tab:green", label="feasible")
        top.scatter(x[~ok], clearance[~ok], s=12, color="tab:red", label="infeasible")
        top.axhline(0.0, color="k", lw=0.8)
        top.set_title(f"circle {c}", y=1.0)
        bottom.plot(x, np.rad2deg(check.incidence[rows]), color="tab:blue")
        if acceptance_deg is not None:
            bottom.axhline(acceptance_deg, color="tab:red", ls="--", lw=0.8)
        bottom.set_xlabel(f"J{c} reading (deg)")
        if c == 1:
            top.set_ylabel("sight-line clearance (mm)")
            bottom.set_ylabel("incidence (deg)")
            top.legend(fontsize="x-small", loc="lower left")
    figure.suptitle("Cell check: red = infeasible point (joint limit, range, acceptance or line of sight)")
    return save_figure(figure, path)


def plot_sensitivity(rows: list[dict], keys: tuple[str, ...], folder: Path, *, parameters: list[str] | None = None):
    """Per varied key (the others at their first value): Cpk and mean deviation of each parameter
    against the key's value (Figs 5.15/5.16 for sweeps and points; Fig. 5.14 for iterations)."""
    paths = []
    for key in keys:
        others = [k for k in keys if k != key]
        firsts = {k: rows[0][k] for k in others}
        subset = [r for r in rows if all(r[k] == v for k, v in firsts.items())]
        names = sorted({r["name"] for r in subset}) if parameters is None else parameters
        figure, (left, right) = new_figure(1, 2, width_in=11.0, height_in=4.2, layout=None)
        figure.subplots_adjust(left=0.6 / 11.0, right=1.0 - 0.15 / 11.0, bottom=0.55 / 4.2, top=1.0 - 0.45 / 4.2)
        figure.subplots_adjust(wspace=0.75 / ((11.0 - 0.75 - 0.75) / 2))
        for number, name in enumerate(names):
            style = ("-", "--", ":")[number // 10 % 3]  # tab10 repeats after 10 lines
            points = [(r[key], r["cpk"], r["mean"] - r["nominal"], r["unit"]) for r in subset if r["name"] == name]
            if not points:
                continue
            x = [p[0] for p in points]
            left.plot(x, [p[1] for p in points], marker="o", lw=1, ls=style, label=name)
            scale = 1000.0  # mm -> um, deg -> mdeg
            right.plot(x, [p[2] * scale for p in points], marker="o", lw=1, ls=style, label=name)
        left.set_xlabel(key)
        left.set_ylabel("Cpk (eq. 5-5)")
        left.axhline(1.33, color="k", ls=":", lw=0.8)
        right.set_xlabel(key)
        right.set_ylabel("mean - nominal (µm | mdeg)")
        right.legend(fontsize="xx-small", ncol=2)
        figure.suptitle(f"Sensitivity to {key}")
        safe = key.replace(".", "_")
        paths.append(save_figure(figure, folder / f"sensitivity_{safe}.png"))
    return paths


def plot_optimisation(history: np.ndarray, baseline: float, confirmed: dict, path: Path, *, objective: str) -> Path:
    """Best linearised objective per generation, with the baseline and the Monte Carlo confirmations."""
    figure, axis = new_figure(1, 1, width_in=6.4, height_in=4.0)
    axis.semilogy(np.arange(1, history.size + 1), history, marker=".", label="best (linearised)")
    axis.axhline(baseline, color="tab:red", ls="--", label="baseline (linearised)")
    for label, value in confirmed.items():
        axis.axhline(value, ls=":", color="k" if "optimised" in label else "tab:orange", label=f"{label} (Monte Carlo)")
    axis.set_xlabel("generation")
    axis.set_ylabel(objective)
    axis.legend(fontsize="x-small")
    return save_figure(figure, path)
