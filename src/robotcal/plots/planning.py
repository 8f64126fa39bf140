"""Figures and files of the planning commands: cell check, sensitivity (Figs 5.14-5.16), optimisation.

The file writers (:func:`check_document`, :func:`write_check_files`, :func:`write_sensitivity_files`) run in
the pipeline's own process; matplotlib is imported by the ``plot_*`` functions only, which run in the figure
process (importing it here cost the run's main process about 0.8 s of CPU for nothing).
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from robotcal.io.atomic import atomic_write_text
from robotcal.planning.cell import REASONS, PlanCheck

__all__ = [
    "check_document",
    "write_check_files",
    "plot_check",
    "write_sensitivity_files",
    "plot_sensitivity",
    "plot_optimisation",
]


def check_document(check: PlanCheck, *, scenario: str, cell, notes: list[str]) -> dict:
    """The JSON document of a cell check (mm, deg)."""
    return {
        "scenario": scenario,
        "feasible": check.feasible,
        "cell": {
            "tracker_position_mm": cell.tracker_position.tolist(),
            "capsule_radius_mm": cell.capsule_radius.tolist(),
            "min_distance_mm": cell.min_distance,
            "max_distance_mm": None if not np.isfinite(cell.max_distance) else cell.max_distance,
            "acceptance_deg": None if cell.acceptance is None else float(np.rad2deg(cell.acceptance)),
            "aim": cell.aim,
        },
        "notes": notes,
        "circles": [
            {
                "circle": c.circle,
                "points": c.points,
                "feasible_points": c.feasible_points,
                "start_deg": c.start_deg,
                "end_deg": c.end_deg,
                "usable_deg": None if c.usable_deg is None else list(c.usable_deg),
                "first_failure": c.first_failure,
                "first_reasons": list(c.first_reasons),
            }
            for c in check.circles
        ],
        "failures": {reason: int(check.failures[:, k].sum()) for k, reason in enumerate(REASONS)},
    }


def write_check_files(folder: Path, check: PlanCheck, document: dict) -> None:
    """``plan_check.json`` and ``plan_check.csv`` (one row per point) in ``folder``."""
    atomic_write_text(folder / "plan_check.json", json.dumps(document, indent=2) + "\n")
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    n = check.readings.shape[1]
    writer.writerow(
        ["circle", "direction", *[f"q{j + 1}_deg" for j in range(n)], "distance_mm", "incidence_deg", "clearance_mm"]
        + [reason.replace(" ", "_") for reason in REASONS]
        + ["ok"]
    )
    for i in range(check.readings.shape[0]):
        writer.writerow(
            [int(check.circle[i]), int(check.direction[i])]
            + [f"{v:.6f}" for v in np.rad2deg(check.readings[i])]
            + [f"{check.distance[i]:.3f}", f"{np.rad2deg(check.incidence[i]):.3f}", f"{check.clearance[i]:.3f}"]
            + [int(v) for v in check.failures[i]]
            + [int(check.ok[i])]
        )
    atomic_write_text(folder / "plan_check.csv", buffer.getvalue())


def plot_check(check: PlanCheck, path: Path, *, acceptance_deg: float | None) -> Path:
    """Per circle: line-of-sight clearance and incidence angle against the turning joint's reading."""
    from robotcal.plots.figures import new_figure, save_figure

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


def write_sensitivity_files(folder: Path, rows: list[dict], document: dict) -> None:
    """``sensitivity.csv`` (one row per case and parameter) and ``sensitivity.json``."""
    buffer = io.StringIO()
    if rows:
        writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    atomic_write_text(folder / "sensitivity.csv", buffer.getvalue())
    atomic_write_text(folder / "sensitivity.json", json.dumps(document | {"rows": rows}, indent=2) + "\n")


def plot_sensitivity(rows: list[dict], keys: tuple[str, ...], folder: Path, *, parameters: list[str] | None = None):
    """Per varied key (the others at their first value): Cpk and mean deviation of each parameter
    against the key's value (Figs 5.15/5.16 for sweeps and points; Fig. 5.14 for iterations)."""
    from robotcal.plots.figures import new_figure, save_figure

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
    from robotcal.plots.figures import new_figure, save_figure

    figure, axis = new_figure(1, 1, width_in=6.4, height_in=4.0)
    axis.semilogy(np.arange(1, history.size + 1), history, marker=".", label="best (linearised)")
    axis.axhline(baseline, color="tab:red", ls="--", label="baseline (linearised)")
    for label, value in confirmed.items():
        axis.axhline(value, ls=":", color="k" if "optimised" in label else "tab:orange", label=f"{label} (Monte Carlo)")
    axis.set_xlabel("generation")
    axis.set_ylabel(objective)
    axis.legend(fontsize="x-small")
    return save_figure(figure, path)
