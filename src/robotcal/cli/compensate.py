"""``robotcal compensate PARAMS --poses CSV --out CSV [--tool x,y,z] [--start-deg q1,..,qN]``: the joint commands
with which the calibrated robot reaches what was taught (issue 22; :func:`robotcal.compensate`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from robotcal.cli._common import FORCE_HELP, command_app, console, handle_errors
from robotcal.cli.export import ROBOT_HELP, SCENARIO_HELP, load_parameter_set, parse_vector
from robotcal.io.output import SIGNATURE, check_output_file, existing_inputs, result_file
from robotcal.io.trajectory_csv import read_pose_targets, write_trajectory

app = command_app()


@app.command()
@handle_errors
def compensate(
    params: Annotated[Path, typer.Argument(help="Parameter JSON of the calibrated model (refined, extended or not).")],
    poses: Annotated[
        Path,
        typer.Option(
            "--poses",
            help="Targets: a pose CSV pose,q1..qN [deg] taught on the nominal model, or Cartesian targets "
            "pose,x,y,z,A,B,C [mm, deg KUKA] in the robot base frame (predict's format), optionally with q1..qN seeds.",
        ),
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Pose CSV to write: pose,q1..qN, the commands [deg].")],
    tool: Annotated[
        str | None, typer.Option("--tool", help='Tool point "x,y,z" in the flange frame [mm] (default: the flange).')
    ] = None,
    start_deg: Annotated[
        str | None,
        typer.Option(
            "--start-deg",
            help="Cartesian targets without seeds: readings q1,..,qN [deg] near the wanted solution (default: the "
            "middle of the joint limits).",
        ),
    ] = None,
    robot: Annotated[str | None, typer.Option("--robot", "-r", help=ROBOT_HELP)] = None,
    scenario: Annotated[str | None, typer.Option("--scenario", "-s", help=SCENARIO_HELP)] = None,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
) -> None:
    """Joint commands with which the calibrated robot reaches the poses taught on the nominal model (or Cartesian
    targets): Newton/LM on the calibrated model, its joint model (gravity sag, harmonic errors) included."""
    from robotcal import api

    parameters, inputs = load_parameter_set(params, robot, scenario)
    n = parameters.robot.n_joints
    inputs += existing_inputs(poses)
    check_output_file(out, inputs=inputs, force=force)
    cartesian, readings = read_pose_targets(poses, n_joints=n)
    tool_mm = None if tool is None else parse_vector(tool, "--tool")
    start = None if start_deg is None else parse_vector(start_deg, "--start-deg", n)
    if cartesian is None:
        result = api.compensate(parameters, poses_deg=np.rad2deg(readings), tool_mm=tool_mm)
        kind = "joint targets taught on the nominal model"
    else:
        seeds = np.rad2deg(readings) if readings is not None else start
        result = api.compensate(
            parameters, cartesian=np.c_[cartesian[:, :3], np.rad2deg(cartesian[:, 3:])], start_deg=seeds, tool_mm=tool_mm
        )
        kind = "Cartesian targets in the robot base frame"
    geometric_only = parameters.joint_model is None
    comment = (
        f"{SIGNATURE} compensate: commands with which the calibrated model {params.name} reaches the {kind} of "
        f"{poses.name}\n"
        f"largest remaining error {result.position_error_mm.max():.2g} mm, {result.orientation_error_deg.max():.2g} deg"
        + ("" if geometric_only else "; the joint model (gravity compliance, harmonic errors) is applied")
    )
    with result_file(out, inputs=inputs, force=force):
        write_trajectory(out, result.readings, comment=comment)
    change = np.abs(np.rad2deg(result.readings) - (np.rad2deg(readings) if cartesian is None else 0.0))
    moved = f"; largest change from the taught commands {change.max():.4f} deg" if cartesian is None else ""
    console.print(
        f"wrote {out} ({result.readings.shape[0]} poses, {kind}; Newton/LM in {result.iterations} steps, largest "
        f"remaining error {result.position_error_mm.max():.2g} mm{moved})",
        highlight=False,
        soft_wrap=True,
    )
