"""``robotcal predict PARAMS --poses CSV [--target X,Y,Z | --flange] --out F``: FK of any point (docs/export.md)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from robotcal.cli._common import FORCE_HELP, command_app, console, handle_errors
from robotcal.cli.export import ROBOT_HELP, SCENARIO_HELP, load_parameter_set, parse_vector
from robotcal.errors import InputError
from robotcal.geometry.euler import kuka_abc_from_matrix, matrix_from_kuka_abc
from robotcal.io import atomic_write_text
from robotcal.io.output import check_output_file, existing_inputs, result_file
from robotcal.io.trajectory_csv import read_trajectory
from robotcal.kinematics.forward import forward_kinematics

app = command_app()

PREDICT_COLUMNS = ("pose", "x", "y", "z", "A", "B", "C")


def predict_frames(parameters, readings, *, target=None, world_from_base=None) -> np.ndarray:
    """``world_from_tool`` frames [mm] at controller ``readings (n_poses, n_joints)`` [rad].

    The tool frame is the flange frame translated to ``target`` (flange-frame offset [mm], zero for
    the flange); ``world_from_base`` (4, 4) defaults to the identity (robot base = DH frame {0}).
    """
    q = parameters.robot.model_joint_variables(readings)
    frames = forward_kinematics(parameters.values, q)
    if target is not None:
        tool = np.eye(4)
        tool[:3, 3] = target
        frames = frames @ tool
    if world_from_base is not None:
        frames = world_from_base @ frames
    return frames


def predictions_to_csv(frames) -> str:
    """CSV ``pose,x,y,z,A,B,C`` (mm, KUKA deg ``R = Rz(A) Ry(B) Rx(C)``; 9 decimals)."""
    abc = np.degrees(kuka_abc_from_matrix(frames))
    lines = [",".join(PREDICT_COLUMNS)]
    for i, (frame, angles) in enumerate(zip(frames, abc, strict=True)):
        values = list(frame[:3, 3]) + list(angles)
        lines.append(f"{i + 1}," + ",".join(f"{v:.9f}" for v in values))
    return "\n".join(lines) + "\n"


@app.command()
@handle_errors
def predict(
    params: Annotated[Path, typer.Argument(help="Parameter JSON (nominal, CPA or refined).")],
    poses: Annotated[Path, typer.Option("--poses", help="Pose CSV with q1..qN, controller readings [deg].")],
    out: Annotated[Path, typer.Option("--out", "-o", help="CSV to write: pose,x,y,z [mm],A,B,C [deg].")],
    target: Annotated[
        str | None, typer.Option("--target", help='Point on the flange "x,y,z" [mm] (flange frame).')
    ] = None,
    flange: Annotated[bool, typer.Option("--flange", help="Predict the flange frame (the default).")] = False,
    tracker_from_base: Annotated[
        str | None,
        typer.Option(
            "--tracker-from-base", help='Base frame in the tracker "x,y,z,A,B,C" [mm, deg KUKA]; default identity.'
        ),
    ] = None,
    robot: Annotated[str | None, typer.Option("--robot", "-r", help=ROBOT_HELP)] = None,
    scenario: Annotated[str | None, typer.Option("--scenario", "-s", help=SCENARIO_HELP)] = None,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
) -> None:
    """Forward kinematics of the flange or of any flange point at given poses, with the calibrated model."""
    if target is not None and flange:
        raise InputError("give --target or --flange, not both")
    point = parse_vector(target, "--target")
    pose6 = parse_vector(tracker_from_base, "--tracker-from-base", 6)
    world_from_base = None
    if pose6 is not None:
        world_from_base = np.eye(4)
        world_from_base[:3, :3] = matrix_from_kuka_abc([math.radians(v) for v in pose6[3:]])
        world_from_base[:3, 3] = pose6[:3]
    parameters, inputs = load_parameter_set(params, robot, scenario)
    inputs += existing_inputs(poses)
    check_output_file(out, inputs=inputs, force=force)
    readings = read_trajectory(poses, n_joints=parameters.robot.n_joints)
    frames = predict_frames(parameters, readings, target=point, world_from_base=world_from_base)
    with result_file(out, inputs=inputs, force=force):
        atomic_write_text(out, predictions_to_csv(frames))
    console.print(f"wrote {out} ({frames.shape[0]} poses)", highlight=False)
