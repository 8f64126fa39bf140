"""make_run_folder: a run folder (docs/results.md) for the report tests.

capture.csv, validation.csv, cpa/parameters.json, truth.json and refine/points.json come from the
library (simulate, identify, write_capture, write_parameters) on the thesis
laser-tracker scenario; the other stages are small synthetic files that follow docs/results.md.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from robotcal.api import identify, simulate
from robotcal.io import load_scenario, write_capture, write_parameters
from robotcal.io.results.provenance import cpa_provenance
from robotcal.kinematics.model import ParameterSet
from robotcal.plots.figures import new_figure, save_figure

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


#: Header of plan/sensitivity/sensitivity.csv (a sweep of circle 4's sweep_deg, as `robotcal run` writes it).
SENSITIVITY_HEADER = ["case", "capture.sweep_deg.4", "name", "unit", "nominal", "mean", "std_uncertainty", "cpk", "draws"]

#: Synthetic backlash per joint [mm] and the noise floor of each circle [um]: J1, J3 above it, the others not.
BACKLASH_MM = (0.040, 0.012, 0.035, 0.010, 0.011, 0.009)
NOISE_FLOOR_UM = 15.0
#: The refine stage's one-line result in run.json, as the pipeline words it (micrometres written "um").
REFINE_DETAIL = "points RMS 11.5 um, distances RMS 13.9 um, model compliance"
#: Synthetic refinement: RMS per coordinate of the criterion and RMS point distance [mm].
CRITERION_RMS_MM = 0.0108
POINT_RMS_MM = 0.0188


def _tcp_json(u_mm_per_pose, *, ellipsoid=None) -> dict:
    """A tcp.json: per pose the position uncertainty sqrt(3) u [mm] (u per coordinate)."""
    poses = [{"pose": k + 1, "position_uncertainty_mm": float(np.sqrt(3) * u)} for k, u in enumerate(u_mm_per_pose)]
    if ellipsoid is not None:
        poses[0]["ellipsoid"] = {"semi_axes_mm": list(ellipsoid)}
    return {"coverage": 0.95, "poses": poses, "provenance": {"model": "refined (CPA + points refinement), Monte Carlo"}}


def _statistics_json(rows: list[list], *, draws: int, model: str) -> dict:
    """A Monte Carlo parameters.json from the rows of its parameters.csv."""
    keys = ("name", "unit", "nominal", "mean", "std_uncertainty", "coverage_low", "coverage_high", "min", "max")
    return {
        "seed": 11,
        "draws": draws,
        "coverage": 0.95,
        "model": model,
        "parameters": [{**dict(zip(keys, row[:9], strict=True)), "identified": bool(row[9])} for row in rows],
    }


def make_run_folder(root: Path) -> Path:
    """Write a complete run folder under ``root`` (the file names and keys of docs/results.md); returns it."""
    scenario = load_scenario("thesis-laser-tracker")
    capture = simulate(scenario, rng=3)
    validation = simulate(scenario, rng=4)
    result = identify(capture, scenario)
    write_capture(root / "capture.csv", capture)
    write_capture(root / "validation.csv", validation)
    write_parameters(root / "cpa" / "parameters.json", result.parameters, cpa_provenance(result, capture, scenario=scenario))
    write_parameters(root / "truth.json", ParameterSet.nominal(scenario.robot), {"source": "nominal robot"})
    write_parameters(
        root / "refine" / "points.json",
        result.parameters,
        {
            "method": "levenberg-marquardt",
            "criterion": "points",
            "points": capture.n_points,
            "residuals": 3 * capture.n_points,
            "residual_rms_mm": POINT_RMS_MM,
            "convergence": {"criterion": "points", "rms_mm": [0.13, CRITERION_RMS_MM]},
            "standard_uncertainty": {"J1.a": 0.00686, "J1.alpha": 0.0012},
        },
    )
    (root / "run.json").write_text(
        json.dumps(
            {
                "command": "robotcal run thesis-laser-tracker --out run",
                "scenario": {
                    "name": scenario.name,
                    "description": scenario.description,
                    # a long token (a path with no place to break it) must not widen its table
                    "source": "/calibration_runs_of_the_welding_cell_number_two_" + "x" * 60 + "/scenario.toml",
                    "robot": scenario.robot.name,
                    "instrument": {"name": "thesis-laser-tracker", "a_um": 10.0, "b_um_per_m": 2.5},
                },
                "robot": scenario.robot.name,
                "seed": 3,
                "versions": {"robotcal": "test"},
                "stages": {
                    "simulate": {"status": "done", "seconds": 0.05},
                    "identify": {"status": "done", "seconds": 0.1},
                    # one-line results as long as the demo's: they squeeze the stage table's other columns
                    "refine": {"status": "done", "seconds": 4.04, "detail": REFINE_DETAIL},
                    "uncertainty": {
                        "status": "done",
                        "seconds": 9.71,
                        "detail": "CPA 100,000 draws (33,037/s), refined 5,000 draws (823/s)",
                    },
                    "plan": {
                        "status": "done",
                        "seconds": 0.57,
                        "detail": "82 of 270 points fail a cell check; sensitivity to the J4 sweep, 4 cases",
                    },
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
    header = ["parameter_set", "view", "capture", "n_errors", "mean_error_mm", "max_error_mm", "rms_error_mm"]
    _write_csv(evaluation / "evaluation.csv", [*header, "improvement_pct"], rows)
    (evaluation / "evaluation.json").write_text(
        json.dumps(
            {
                "rows": [dict(zip([*header, "improvement_pct"], row, strict=True)) for row in rows],
                "headline": {
                    "capture": "validation",
                    "view": "points",
                    "before_label": "nominal",
                    "after_label": "points",
                    "before_mean_mm": 0.9,
                    "after_mean_mm": 0.05,
                },
            }
        )
    )
    _figure(evaluation / "convergence.png", "Convergence", "iteration", "RMS residual [mm]")
    joints = root / "joints"
    _write_csv(
        joints / "summary.csv",
        ["joint", "points", "pairs", "radius_mm", "plane_rms_mm", "circle_rms_mm", "backlash_mean_mm", "noise_floor_um"],
        [[j, 30, 14, 100.0 + j, 0.006, 0.009, BACKLASH_MM[j - 1], NOISE_FLOOR_UM] for j in range(1, 7)],
    )
    _write_csv(
        joints / "backlash.csv",
        ["circle", "reading_deg", "magnitude_mm"],
        [[j, 10.0 * k, BACKLASH_MM[j - 1]] for j in range(1, 7) for k in range(3)],
    )
    (joints / "harmonics.json").write_text(json.dumps({"order": 2, "units": {"length": "mm", "angle": "deg"}}))
    _figure(joints / "backlash_magnitude.png", "Backlash", "joint reading [deg]", "|backlash| [µm]")
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
                bool(flag),
            ]
        )
    header = ["name", "unit", "nominal", "mean", "std_uncertainty", "coverage_low", "coverage_high", "min", "max"]
    _write_csv(uncertainty / "parameters.csv", [*header, "identified"], rows)
    (uncertainty / "parameters.json").write_text(json.dumps(_statistics_json(rows, draws=1000, model="cpa")))
    refined_rows = []
    for row in rows:
        u = (U_REFINED_ANGLE_DEG if row[1] == "deg" else U_REFINED_LENGTH_MM) if row[-1] else 0.0
        refined_rows.append([*row[:4], u, row[3] - 2 * u, row[3] + 2 * u, row[3] - 4 * u, row[3] + 4 * u, row[-1]])
    _write_csv(root / "uncertainty-refined" / "parameters.csv", [*header, "identified"], refined_rows)
    (root / "uncertainty-refined" / "parameters.json").write_text(
        json.dumps(_statistics_json(refined_rows, draws=500, model="refined"))
    )
    expected = float(np.hypot(CONSISTENCY_MM["predicted_rms_mm"], CONSISTENCY_MM["instrument_rms_mm"]))
    (root / "tcp").mkdir(exist_ok=True)
    (root / "tcp" / "consistency.json").write_text(
        json.dumps(
            {
                **CONSISTENCY_MM,
                "expected_rms_mm": expected,
                "ratio": CONSISTENCY_MM["observed_rms_mm"] / expected,
                "poses": 100,
                "model": "refined (CPA + points refinement)",
                "base_frame": "given",
            }
        )
    )
    plan = root / "plan"
    _write_csv(
        plan / "plan_check.csv",
        ["circle", "direction", "joint limit", "range", "acceptance", "line of sight", "ok"],
        [[1, 1, 0, 0, 0, 0, 1], [5, 1, 1, 0, 0, 0, 0]],
    )
    (plan / "plan_check.json").write_text(json.dumps({"feasible": False, "points": 2, "failing": 1}))
    # the columns of planning.files.write_sensitivity_files: the varied key, then per parameter its unit,
    # statistics in that unit, Cpk (a pure number) and the draws
    _write_csv(
        plan / "sensitivity" / "sensitivity.csv",
        SENSITIVITY_HEADER,
        [
            [case, sweep, name, unit, nominal, nominal + 0.001, u, cpk, 1000]
            for case, sweep in ((1, 15.0), (2, 50.0))
            for name, unit, nominal, u, cpk in (("J4.a", "mm", 0.0, 0.4, 0.1), ("J4.theta", "deg", 0.0, 0.02, 0.3))
        ],
    )
    _write_csv(
        root / "iso9283" / "iso9283.csv",
        ["model", "pose", "APx", "APy", "APz", "AP", "l_bar", "S_l", "RP", "AD", "RD"],
        [["nominal", "P1", 0.3, 0.4, 0.0, 0.5, 0.01, 0.002, 0.016, "", ""], ["nominal", "P2-P4", *[""] * 7, 0.2, 0.03]],
    )
    _figure(uncertainty / "hist_J1.png", "J1", "J1.d [mm]", "density [1/mm]")
    _write_csv(root / "tcp" / "pose" / "tcp.csv", TCP_HEADER, _tcp_rows("1", U_TCP_MM))
    _figure(root / "tcp" / "pose" / "ellipsoid.png", "Ellipsoid", "X (mm)", "Y (mm)")
    (root / "tcp" / "pose" / "tcp.json").write_text(json.dumps(_tcp_json([U_TCP_MM], ellipsoid=ELLIPSOID_MM)))
    trajectory_u = [0.01 + 0.001 * k for k in range(60)]
    _write_csv(
        root / "tcp" / "trajectory" / "tcp.csv",
        TCP_HEADER,
        sum((_tcp_rows(str(k + 1), u) for k, u in enumerate(trajectory_u)), []),
    )
    (root / "tcp" / "trajectory" / "tcp.json").write_text(json.dumps(_tcp_json(trajectory_u)))
    _write_csv(
        root / "tcp" / "workspace" / "tcp.csv",
        TCP_HEADER,
        sum((_tcp_rows(str(k + 1), u) for k, u in enumerate(WORKSPACE_U_MM)), []),
    )
    (root / "tcp" / "workspace" / "tcp.json").write_text(json.dumps(_tcp_json(WORKSPACE_U_MM)))
    _figure(root / "tcp" / "workspace" / "workspace.png", "Workspace", "X (mm)", "Z (mm)")
    return root


def load_run(folder: Path):
    """The RunResult of a run folder: ``robotcal.io.results.run_folder.read_run`` where it exists, else a small
    loader of the tests' own (JSON -> dict, CSV -> Table, other files -> Path), without its checks."""
    try:
        from robotcal.io.results.run_folder import read_run
    except ImportError:
        read_run = None
    if read_run is not None:
        return read_run(folder)
    from robotcal.io.results.run_folder import RunResult, Table

    documents = {}
    for path in sorted(p for p in Path(folder).rglob("*") if p.is_file() and not p.name.startswith(".")):
        name = path.relative_to(folder).as_posix()
        if name == "report.html" or any(part.startswith(".") for part in Path(name).parts):
            continue
        if path.suffix == ".json":
            documents[name] = json.loads(path.read_text(encoding="utf-8"))
        elif path.suffix == ".csv":
            with path.open(newline="", encoding="utf-8") as stream:
                rows = [row for row in csv.reader(stream) if row]
            documents[name] = Table(header=tuple(rows[0]), rows=tuple(tuple(row) for row in rows[1:]))
        else:
            documents[name] = path
    return RunResult(folder=Path(folder), record=documents.get("run.json", {}), documents=documents)
