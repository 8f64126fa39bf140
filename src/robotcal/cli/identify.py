"""``robotcal identify CAPTURE.csv --scenario S --out PARAMS.json``: CPA identification."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import (
    FORCE_HELP,
    app_command,
    circle_table,
    command_app,
    console,
    parameter_table,
    print_health,
    read_scenario_capture,
)
from robotcal.io.results.output import result_file

app = command_app()


@app_command(app)
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
            help="Fail (exit 1, no file written) unless the fit health is OK or NOT CHECKED: a MODEL ERROR "
            "(circle residual > 3 x the stated noise) fails too, not only a FAILED fit.",
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
    from robotcal import api
    from robotcal.identification.cpa import point_rows
    from robotcal.identification.plausibility import OUTLIER_MAD, OUTLIER_U
    from robotcal.identification.plausibility import reject_outliers as drop_outliers
    from robotcal.identification.refine import wrap_angles
    from robotcal.io.formats.parameters_json import write_parameters
    from robotcal.io.results.provenance import cpa_provenance
    from robotcal.kinematics.model import ParameterSet

    loaded, measured, inputs = read_scenario_capture(capture, scenario, out, force=force)
    removed = None
    if reject_outliers:
        measured, removed = drop_outliers(measured, loaded.instrument, circle_fit=loaded.identification.circle_fit)
    result = api.identify(measured, loaded, health="strict" if strict else "warn")
    provenance = cpa_provenance(result, measured, scenario=loaded)
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
    if result.registration_rms is not None:
        console.print(
            f"base frame registered with the identified model: RMS residual {result.registration_rms:.4f} mm",
            highlight=False,
        )
    assert result.health is not None  # robotcal.identify always judges the fit
    for note in result.health.notes:
        console.print(f"note: {note}", highlight=False, markup=False, soft_wrap=True)
    console.print(f"wrote {out}" + (" (marked FAILED)" if result.health.failed else ""), highlight=False)
    print_health(result.health)
