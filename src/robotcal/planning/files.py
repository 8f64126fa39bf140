"""The files of the planning commands and of a run's ``plan/`` folder: the cell check and the sensitivity study
(mm, deg). Their figures: :mod:`robotcal.plots.planning`."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from robotcal.io.atomic import atomic_write_text
from robotcal.planning.cell import REASONS, CellModel, PlanCheck

__all__ = ["check_document", "write_check_files", "write_sensitivity_files"]


def check_document(check: PlanCheck, *, scenario: str, cell: CellModel, notes: list[str]) -> dict:
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


def write_sensitivity_files(folder: Path, rows: list[dict], document: dict) -> None:
    """``sensitivity.csv`` (one row per case and parameter) and ``sensitivity.json``."""
    buffer = io.StringIO()
    if rows:
        writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    atomic_write_text(folder / "sensitivity.csv", buffer.getvalue())
    atomic_write_text(folder / "sensitivity.json", json.dumps(document | {"rows": rows}, indent=2) + "\n")
