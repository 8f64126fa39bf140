"""``robotcal identify CAPTURE.csv --scenario S --out PARAMS.json``: CPA identification."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import FORCE_HELP, circle_table, command_app, console, handle_errors, parameter_table
from robotcal.identification.cpa import point_rows
from robotcal.identification.plausibility import OUTLIER_MAD, OUTLIER_U
from robotcal.identification.plausibility import reject_outliers as drop_outliers
from robotcal.identification.refine import wrap_angles
from robotcal.io import load_scenario, read_capture, write_parameters
from robotcal.io.output import check_output_file, existing_inputs, result_file
from robotcal.kinematics.model import ParameterSet
from robotcal.workflow import cpa_provenance, identify_scenario

app = command_app()


@app.command()
@handle_errors
def identify(
    capture: Annotated[Path, typer.Argument(help="Capture CSV (circle,direction,q1..qN,x,y,z).")],
    scenario: Annotated[
        str, typer.Option("--scenario", "-s", help="Scenario name or TOML: robot, reflector, base frame, options.")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Parameter JSON to write.")],
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
    strict: Annotated[
        bool,
        typer.Option(
            "--strict",
            help="Fail when the fit does not pass the fit-health test (circle residual > 3 x the stated noise, "
            "or a circle whose axis direction the noise leaves uncertain by more than 1 deg).",
        ),
    ] = False,
    reject_outliers: Annotated[
        bool,
        typer.Option(
            "--reject-outliers",
            help="Drop points far off their fitted circle before CPA: residual above 4 U(L) of the instrument "
            "and above median + 5 x 1.4826 MAD of the circle; refit and repeat once; at most 30 % of a circle. "
            "The removed rows are recorded in the parameter JSON's provenance.",
        ),
    ] = False,
) -> None:
    """Identify the kinematic parameters by Circle Point Analysis and print nominal / identified / difference."""
    inputs = existing_inputs(capture, scenario)
    check_output_file(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    removed = None
    if reject_outliers:
        measured, removed = drop_outliers(measured, loaded.instrument, circle_fit=loaded.identification.circle_fit)
    result = identify_scenario(measured, loaded, health="strict" if strict else "warn")
    provenance = cpa_provenance(result, measured, loaded)
    if removed is not None:
        provenance["outliers_rejected"] = {
            "rule": f"residual > {OUTLIER_U:g} U(L) and > median + {OUTLIER_MAD:g} x 1.4826 MAD per circle, twice",
            "points": [int(row) + 1 for row in removed],
            "csv_lines": [int(row) + 2 for row in removed],
        }
    with result_file(out, inputs=inputs, force=force):
        write_parameters(out, result.parameters, provenance)
    if removed is not None:
        summary = point_rows(removed) if removed.size else "none"
        console.print(f"outliers rejected: {removed.size} ({summary})", highlight=False, markup=False)
    console.print(
        parameter_table(  # angles wrapped into (-180, 180] deg, as in the JSON
            ParameterSet.nominal(loaded.robot),
            result.parameters.replace(values=wrap_angles(result.parameters.values, result.parameters.robot.nominal)),
            f"CPA parameters of {loaded.robot.name}",
        )
    )
    console.print(circle_table(result))
    health = provenance["fit_health"]
    ratio = (
        f"not compared ({health['noise_source']})"
        if health["ratio"] is None
        else f"{health['ratio']:.3g} x the stated noise ({health['noise_source']})"
    )
    verdict = "OK" if health["healthy"] else "FAILED (" + "; ".join(health["problems"]) + ")"
    console.print(f"fit health: {verdict}: circle residual {ratio}", highlight=False, markup=False)
    if result.registration_rms is not None:
        console.print(f"base frame registered: RMS residual {result.registration_rms:.4f} mm", highlight=False)
    console.print(f"wrote {out}", highlight=False)
