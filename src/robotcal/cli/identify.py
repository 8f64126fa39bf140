"""``robotcal identify CAPTURE.csv --scenario S --out PARAMS.json``: CPA identification."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli import app
from robotcal.cli._common import circle_table, console, handle_errors, parameter_table
from robotcal.io import load_scenario, read_capture, write_parameters
from robotcal.kinematics.model import ParameterSet
from robotcal.workflow import cpa_provenance, identify_scenario


@app.command()
@handle_errors
def identify(
    capture: Annotated[Path, typer.Argument(help="Capture CSV (circle,direction,q1..qN,x,y,z).")],
    scenario: Annotated[
        str, typer.Option("--scenario", "-s", help="Scenario name or TOML: robot, reflector, base frame, options.")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Parameter JSON to write.")],
) -> None:
    """Identify the kinematic parameters by Circle Point Analysis and print nominal / identified / difference."""
    loaded = load_scenario(scenario)
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    result = identify_scenario(measured, loaded)
    write_parameters(out, result.parameters, cpa_provenance(result, measured, loaded))
    console.print(
        parameter_table(ParameterSet.nominal(loaded.robot), result.parameters, f"CPA parameters of {loaded.robot.name}")
    )
    console.print(circle_table(result))
    if result.registration_rms is not None:
        console.print(f"base frame registered: RMS residual {result.registration_rms:.4f} mm", highlight=False)
    console.print(f"wrote {out}", highlight=False)
