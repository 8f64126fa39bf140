"""``robotcal joints CAPTURE.csv --scenario S --out DIR``: backlash and eccentricity per joint (ch. 4.6)."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table

from robotcal.capture import Capture
from robotcal.cli import app
from robotcal.cli._common import FORCE_HELP, console, error_console, handle_errors
from robotcal.diagnostics import HarmonicModel, JointDiagnostics, analyze_joints, fit_harmonics
from robotcal.io import load_scenario, read_capture
from robotcal.io.atomic import atomic_write_text
from robotcal.io.output import check_output_folder, existing_inputs, result_folder
from robotcal.workflow import versions

SUMMARY_COLUMNS = (
    "joint", "points", "pairs", "radius_mm", "plane_rms_mm", "circle_rms_mm", "axial_min_mm", "axial_max_mm",
    "radial_min_mm", "radial_max_mm", "backlash_max_mm", "backlash_min_mm", "backlash_mean_mm", "backlash_std_mm",
    "backlash_angle_mean_deg",
)  # fmt: skip


def _number(value: float, digits: int = 9) -> str:
    return "" if not math.isfinite(value) else f"{value:.{digits}f}"


def _csv(header, rows) -> str:
    stream = io.StringIO()
    writer = csv.writer(stream, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return stream.getvalue()


def summary_csv(diagnostics: JointDiagnostics) -> str:
    """``summary.csv``: one row per joint (Tables 4.12-4.17 plus eccentricity and fit RMS), mm/deg."""
    rows = []
    for s in diagnostics.summary():
        rows.append(
            [s.joint, s.points, s.pairs]
            + [
                _number(v)
                for v in (
                    s.radius,
                    s.plane_rms,
                    s.circle_rms,
                    s.axial_min,
                    s.axial_max,
                    s.radial_min,
                    s.radial_max,
                    s.backlash_max,
                    s.backlash_min,
                    s.backlash_mean,
                    s.backlash_std,
                )
            ]  # fmt: skip
            + [_number(float(np.rad2deg(s.backlash_angle_mean)))]
        )
    return _csv(SUMMARY_COLUMNS, rows)


def points_csv(diagnostics: JointDiagnostics) -> str:
    """``points.csv``: per point its circle, sweep, lash state, reading and signed eccentricities."""
    rows = []
    for c in diagnostics.circles:
        for k in range(c.n_points):
            rows.append(
                [int(c.rows[k]) + 1, c.joint, int(c.direction[k]), int(c.state[k])]
                + [_number(float(np.rad2deg(c.reading[k]))), _number(float(c.axial[k])), _number(float(c.radial[k]))]
            )
    return _csv(("point", "circle", "direction", "state", "reading_deg", "axial_mm", "radial_mm"), rows)


def backlash_csv(diagnostics: JointDiagnostics) -> str:
    """``backlash.csv``: per circle and matched reading, the vector return - forward and its parts."""
    rows = []
    for c in diagnostics.circles:
        magnitude = c.backlash_magnitude
        for k in range(c.n_pairs):
            rows.append(
                [c.joint, _number(float(np.rad2deg(c.pair_reading[k]))), int(c.pair_forward[k]) + 1]
                + [int(c.pair_return[k]) + 1, int(bool(c.turnaround[k]))]
                + [_number(float(v)) for v in (*c.backlash[k], magnitude[k], *c.backlash_local[k])]
                + [_number(float(np.rad2deg(c.backlash_angle[k])))]
            )
    header = (
        "circle", "reading_deg", "forward_point", "return_point", "turnaround", "dx_mm", "dy_mm", "dz_mm",
        "magnitude_mm", "axial_mm", "radial_mm", "tangential_mm", "angle_deg",
    )  # fmt: skip
    return _csv(header, rows)


def harmonics_document(model: HarmonicModel, diagnostics: JointDiagnostics, *, capture: Path, scenario) -> dict:
    """``harmonics.json``: the model (:meth:`HarmonicModel.to_dict`) plus provenance."""
    document = model.to_dict()
    document["provenance"] = {
        "capture": str(capture),
        "scenario": {"name": scenario.name, "source": scenario.source},
        "backlash": diagnostics.backlash,
        "match_tolerance_deg": float(np.rad2deg(diagnostics.match_tolerance)),
        "ignored_points": diagnostics.ignored_points,
        "notes": list(diagnostics.messages),
        "versions": versions(),
    }
    return document


def _table(diagnostics: JointDiagnostics) -> Table:
    table = Table(
        title="Joint diagnostics (µm; backlash over matched pairs, turnarounds excluded)", title_justify="left"
    )
    columns = ("joint", "points", "pairs", "axial RMS", "radial RMS", "backlash max", "min", "mean", "angle (deg)")
    for column in columns:
        table.add_column(column, justify="right")

    def um(value):
        return "-" if not math.isfinite(value) else f"{value * 1000:.2f}"

    for s in diagnostics.summary():
        angle = "-" if not math.isfinite(s.backlash_angle_mean) else f"{np.rad2deg(s.backlash_angle_mean):+.5f}"
        table.add_row(
            f"J{s.joint}", str(s.points), str(s.pairs), um(s.plane_rms), um(s.circle_rms),
            um(s.backlash_max), um(s.backlash_min), um(s.backlash_mean), angle,
        )  # fmt: skip
    return table


def compute_joints(
    capture: Capture, scenario, *, order: int = 2, backlash: bool = True, match_tolerance_deg: float = 1e-3
) -> tuple[JointDiagnostics, HarmonicModel]:
    """Diagnostics (:func:`analyze_joints` with the scenario's circle fit) and their harmonic model."""
    diagnostics = analyze_joints(
        capture,
        backlash=backlash,
        match_tolerance=float(np.deg2rad(match_tolerance_deg)),
        method=scenario.identification.circle_fit,
    )
    return diagnostics, fit_harmonics(diagnostics, order=order)


def write_joints_folder(
    folder: Path, diagnostics: JointDiagnostics, model: HarmonicModel, *, capture, scenario, scale: float = 500.0
) -> list[str]:
    """Write the CSV files, ``harmonics.json`` and the figures into ``folder`` (an existing, normally
    temporary, folder); ``capture`` names the capture in the provenance. Returns the file names."""
    from robotcal.report.joints import write_joint_figures  # matplotlib only when writing figures

    atomic_write_text(folder / "summary.csv", summary_csv(diagnostics))
    atomic_write_text(folder / "points.csv", points_csv(diagnostics))
    if diagnostics.backlash:
        atomic_write_text(folder / "backlash.csv", backlash_csv(diagnostics))
    document = harmonics_document(model, diagnostics, capture=capture, scenario=scenario)
    atomic_write_text(folder / "harmonics.json", json.dumps(document, indent=2, allow_nan=False) + "\n")
    figures = write_joint_figures(diagnostics, folder, model=model, scale=scale)
    files = ["summary.csv", "points.csv"] + (["backlash.csv"] if diagnostics.backlash else [])
    return files + ["harmonics.json"] + [path.name for path in figures]


@app.command()
@handle_errors
def joints(
    capture: Annotated[
        Path, typer.Argument(help="Capture CSV (circle,direction,q1..qN,x,y,z), ideally bidirectional.")
    ],
    scenario: Annotated[
        str, typer.Option("--scenario", "-s", help="Scenario name or TOML: robot (joint count) and circle fit.")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Result folder to write.")],
    order: Annotated[int, typer.Option(min=1, help="Highest harmonic K of the harmonic model.")] = 2,
    backlash: Annotated[
        bool, typer.Option("--backlash/--no-backlash", help="Analyse backlash (needs both sweep directions).")
    ] = True,
    scale: Annotated[float, typer.Option(min=0.0, help="Arrow scale of backlash_vectors.png (thesis: 500).")] = 500.0,
    match_tolerance_deg: Annotated[
        float, typer.Option(min=0.0, help="Largest reading difference of a forward/return pair [deg].")
    ] = 1e-3,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
) -> None:
    """Backlash and axial/radial eccentricity per joint (thesis ch. 4.6), with a harmonic model."""
    inputs = existing_inputs(capture, scenario)
    check_output_folder(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    diagnostics, model = compute_joints(
        measured, loaded, order=order, backlash=backlash, match_tolerance_deg=match_tolerance_deg
    )
    with result_folder(out, inputs=inputs, force=force, command="robotcal joints") as folder:
        files = write_joints_folder(folder, diagnostics, model, capture=capture, scenario=loaded, scale=scale)
    console.print(_table(diagnostics))
    for note in (*diagnostics.messages, *model.messages):
        error_console.print(f"note: {note}", highlight=False)
    console.print(f"wrote {out}: {', '.join(files)}", highlight=False)
