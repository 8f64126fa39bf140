"""make_run_folder: a run folder (docs/results.md) for the report tests.

capture.csv, validation.csv, cpa/parameters.json, truth.json and refine/points.json come from the
library (simulate_scenario, identify_scenario, write_capture, write_parameters) on the thesis
laser-tracker scenario; the other stages are small synthetic files that follow docs/results.md.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from robotcal.io import load_scenario, write_capture, write_parameters
from robotcal.kinematics.model import ParameterSet
from robotcal.report.figures import new_figure, save_figure
from robotcal.workflow import cpa_provenance, identify_scenario, simulate_scenario

#: Synthetic standard uncertainties written to uncertainty/parameters.csv [mm or deg].
U_LENGTH_MM = 0.012
U_ANGLE_DEG = 0.004
#: Synthetic TCP standard uncertainties per coordinate [mm]: u_pos = sqrt(3) * this at the pose.
U_TCP_MM = 0.010
#: Synthetic workspace: per-pose coordinate uncertainties [mm] of five poses.
WORKSPACE_U_MM = (0.005, 0.010, 0.020, 0.040, 0.080)
#: Synthetic semi-axes of the 95 % TCP position ellipsoid at the pose [mm].
ELLIPSOID_MM = (0.01, 0.03, 0.02)
#: Synthetic standard uncertainties of the refined (deployed) model, uncertainty-refined/parameters.csv.
U_REFINED_LENGTH_MM = 0.0021
U_REFINED_ANGLE_DEG = 0.0007
#: Synthetic validation consistency check (tcp/consistency.json) [mm]: 30 and 16 um give 34 um expected.
CONSISTENCY_MM = {"predicted_rms_mm": 0.030, "instrument_rms_mm": 0.016, "observed_rms_mm": 0.091}


def _write_csv(path: Path, header: list[str], rows: list[list]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        writer.writerows(rows)


def _figure(path: Path, title: str, xlabel: str, ylabel: str) -> None:
    figure, axes = new_figure(width_in=4.0, height_in=2.6)
    x = np.linspace(0.0, 1.0, 20)
    axes.plot(x, x**2)
    axes.set(title=title, xlabel=xlabel, ylabel=ylabel)
    save_figure(figure, path)


def _tcp_rows(pose: str, u_mm: float) -> list[list]:
    rows = []
    for name, unit, value in (("X", "mm", 500.0), ("Y", "mm", 10.0), ("Z", "mm", 700.0)):
        rows.append(
            [
                pose,
                name,
                unit,
                value,
                value,
                u_mm,
                value - 2 * u_mm,
                value + 2 * u_mm,
                value - 4 * u_mm,
                value + 4 * u_mm,
            ]
        )
    for name, value in (("A", 10.0), ("B", 80.0), ("C", -5.0)):
        rows.append([pose, name, "deg", value, value, 1e-3, value - 2e-3, value + 2e-3, value - 4e-3, value + 4e-3])
    return rows


TCP_HEADER = [
    "pose",
    "name",
    "unit",
    "nominal",
    "mean",
    "std_uncertainty",
    "coverage_low",
    "coverage_high",
    "min",
    "max",
]


def make_run_folder(root: Path) -> Path:
    """Write a complete run folder under ``root``; returns it."""
    scenario = load_scenario("thesis-laser-tracker")
    run = simulate_scenario(scenario, seed=3)
    validation = simulate_scenario(scenario, seed=4)
    result = identify_scenario(run.capture, scenario)
    write_capture(root / "capture.csv", run.capture)
    write_capture(root / "validation.csv", validation.capture)
    write_parameters(root / "cpa" / "parameters.json", result.parameters, cpa_provenance(result, run.capture, scenario))
    write_parameters(root / "truth.json", ParameterSet.nominal(scenario.robot), {"source": "nominal robot"})
    write_parameters(
        root / "refine" / "points.json", result.parameters, {"method": "levenberg-marquardt", "iterations": 6}
    )
    (root / "run.json").write_text(
        json.dumps(
            {
                "scenario": {
                    "name": scenario.name,
                    "description": scenario.description,
                    "robot": scenario.robot.name,
                    "instrument": {"name": "thesis-laser-tracker", "a_um": 10.0, "b_um_per_m": 2.5},
                },
                "seed": 3,
                "versions": {"robotcal": "test"},
                "stages": {
                    "simulate": {"status": "done", "seconds": 0.05},
                    "identify": {"status": "done", "seconds": 0.1},
                },
            }
        )
    )
    evaluation = root / "evaluation"
    rows = []
    for capture, scale in (("capture", 0.5), ("validation", 1.0)):
        for view, factor in (("points", 1.0), ("distances", 1.7)):
            for label, mean in (("nominal", 0.9), ("cpa", 0.12), ("points", 0.05)):
                value = mean * scale * factor
                rows.append([label, view, capture, 135, value, 2 * value, 1.1 * value, 100 * (1 - mean / 0.9)])
    _write_csv(
        evaluation / "evaluation.csv",
        [
            "parameter_set",
            "view",
            "capture",
            "n_errors",
            "mean_error_mm",
            "max_error_mm",
            "rms_error_mm",
            "improvement_pct",
        ],
        rows,
    )
    (evaluation / "evaluation.json").write_text(json.dumps({"points": 135, "criterion": "points"}))
    _figure(evaluation / "convergence.png", "Convergence", "iteration", "cost (mm²)")
    joints = root / "joints"
    _write_csv(
        joints / "summary.csv",
        ["joint", "backlash_deg", "axial_eccentricity_mm"],
        [[j, 0.01 * j, 0.002 * j] for j in range(1, 7)],
    )
    (joints / "harmonics.json").write_text(json.dumps({"J1": {"amplitude_mm": 0.003}}))
    _figure(joints / "radial_residuals.png", "Radial residuals", "joint angle (deg)", "residual (mm)")
    uncertainty = root / "uncertainty"
    rows = []
    nominal = ParameterSet.nominal(scenario.robot)
    for name, value, flag in zip(
        scenario.robot.parameter_names,
        nominal.values.reshape(-1),
        result.parameters.identified.reshape(-1),
        strict=True,
    ):
        is_angle = name.split(".")[1] in ("theta", "alpha", "beta")
        shown = float(np.degrees(value)) if is_angle else float(value)
        u = (U_ANGLE_DEG if is_angle else U_LENGTH_MM) if flag else 0.0
        rows.append(
            [
                name,
                "deg" if is_angle else "mm",
                shown,
                shown,
                u,
                shown - 2 * u,
                shown + 2 * u,
                shown - 4 * u,
                shown + 4 * u,
                flag,
            ]
        )
    _write_csv(
        uncertainty / "parameters.csv",
        [
            "name",
            "unit",
            "nominal",
            "mean",
            "std_uncertainty",
            "coverage_low",
            "coverage_high",
            "min",
            "max",
            "identified",
        ],
        rows,
    )
    (uncertainty / "parameters.json").write_text(json.dumps({"seed": 11, "draws": 1000, "coverage": 0.95}))
    header = ["name", "unit", "nominal", "mean", "std_uncertainty", "coverage_low", "coverage_high", "min", "max"]
    refined_rows = []
    for row in rows:
        u = (U_REFINED_ANGLE_DEG if row[1] == "deg" else U_REFINED_LENGTH_MM) if row[-1] else 0.0
        refined_rows.append(
            [*row[:4], u, row[3] - 2 * u, row[3] + 2 * u, row[3] - 4 * u, row[3] + 4 * u, row[-1], "refined"]
        )
    _write_csv(root / "uncertainty-refined" / "parameters.csv", [*header, "identified", "model"], refined_rows)
    (root / "uncertainty-refined" / "parameters.json").write_text(
        json.dumps({"seed": 11, "draws": 500, "coverage": 0.95, "model": "refined", "criterion": "points"})
    )
    expected = float(np.hypot(CONSISTENCY_MM["predicted_rms_mm"], CONSISTENCY_MM["instrument_rms_mm"]))
    (root / "tcp").mkdir(exist_ok=True)
    (root / "tcp" / "consistency.json").write_text(
        json.dumps(
            {**CONSISTENCY_MM, "expected_rms_mm": expected, "poses": 100, "model": "refined (CPA + points refinement)"}
        )
    )
    plan = root / "plan"
    _write_csv(
        plan / "plan_check.csv",
        ["circle", "direction", "joint limit", "range", "acceptance", "line of sight", "ok"],
        [[1, 1, 0, 0, 0, 0, 1], [5, 1, 1, 0, 0, 0, 0]],
    )
    (plan / "plan_check.json").write_text(json.dumps({"feasible": False, "points": 2, "failing": 1}))
    _write_csv(
        plan / "sensitivity" / "sensitivity.csv", ["case", "capture.sweep_deg.4", "name", "cpk"], [[1, 15, "J4.a", 0.1]]
    )
    _figure(uncertainty / "hist_J1.d.png", "J1.d", "J1.d (mm)", "draws")
    _write_csv(root / "tcp" / "pose" / "tcp.csv", TCP_HEADER, _tcp_rows("table-5.8", U_TCP_MM))
    _figure(root / "tcp" / "pose" / "ellipsoid.png", "Ellipsoid", "X (mm)", "Y (mm)")
    (root / "tcp" / "pose" / "tcp.json").write_text(
        json.dumps({"coverage": 0.95, "poses": [{"pose": 1, "ellipsoid": {"semi_axes_mm": list(ELLIPSOID_MM)}}]})
    )
    _write_csv(
        root / "tcp" / "trajectory" / "tcp.csv",
        TCP_HEADER,
        sum((_tcp_rows(str(k), 0.01 + 0.001 * k) for k in range(60)), []),
    )
    _write_csv(
        root / "tcp" / "workspace" / "tcp.csv",
        TCP_HEADER,
        sum((_tcp_rows(str(k), u) for k, u in enumerate(WORKSPACE_U_MM)), []),
    )
    _figure(root / "tcp" / "workspace" / "workspace.png", "Workspace", "X (mm)", "Z (mm)")
    return root
