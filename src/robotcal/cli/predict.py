"""``robotcal predict PARAMS --poses CSV [--target X,Y,Z|NAME | --flange] [--tracker-from-base
x,y,z,A,B,C|params|scenario] --out F``: FK of any point (docs/export.md).

Readings beyond :data:`robotcal.io.formats.trajectory_csv.MAX_READING_DEG` or not finite are refused by the
pose CSV reader; readings outside the robot's joint limits are a
:class:`~robotcal.errors.JointLimitWarning` naming the pose and joint, as everywhere in robotcal
(:func:`robotcal.uncertainty.tcp.check_readings`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from robotcal.cli._common import Force, ParamsRobot, ParamsScenario, app_command, command_app, console
from robotcal.cli.export import load_parameter_set, parse_vector
from robotcal.errors import InputError
from robotcal.io.results.output import check_output_file, existing_inputs, result_file

if TYPE_CHECKING:  # numpy and the kinematics load in the command: a fast --help
    import numpy as np

app = command_app()

PREDICT_COLUMNS = ("pose", "x", "y", "z", "A", "B", "C")


def flange_target_mm(text: str, *, params: Path, scenario=None) -> tuple[np.ndarray, str]:
    """``--target``: ``"x,y,z"`` [mm], or the name of a flange target of the parameter JSON's ``targets``
    (a refinement's estimates and known offsets) or, failing that, a known flange target of the scenario.

    Returns the offset [mm] and a few words on where it came from.
    """
    import numpy as np

    from robotcal.io.formats.parameters_json import read_targets

    parts = text.split(",")
    if len(parts) > 1:
        return np.asarray(parse_vector(text, "--target"), dtype=float), "given"
    name = text.strip()
    from_params = read_targets(params)
    if name in from_params:
        return np.asarray(from_params[name], dtype=float), f"target {name!r} of {params}"
    declared = {t.name: t for t in scenario.targets} if scenario is not None else {}
    if name in declared:
        target = declared[name]
        if target.frame != "flange":
            raise InputError(
                f"--target {name}: scenario target {name!r} is a per-joint reflector, not a flange point; give x,y,z"
            )
        if not target.known:
            raise InputError(
                f"--target {name}: the scenario declares target {name!r} with an unknown offset (estimated by "
                f"refinement) and {params} does not give it; use the parameter JSON of the refinement that estimated "
                "it, or give x,y,z"
            )
        return np.asarray(target.positions, dtype=float), f"target {name!r} of scenario {scenario.name}"
    known = sorted(from_params) + sorted(n for n, t in declared.items() if t.frame == "flange" and t.known)
    where = f"{params}" + (f" nor scenario {scenario.name}" if scenario is not None else " (give --scenario for its targets)")
    raise InputError(
        f"--target {name!r}: no flange target of that name in {where}; known: {', '.join(known) or 'none'} "
        "(or give x,y,z [mm])"
    )


def world_from_base_of(text: str, *, params: Path, scenario=None) -> tuple[np.ndarray, str]:
    """``--tracker-from-base``: ``"x,y,z,A,B,C"`` [mm, deg KUKA], ``params`` (the JSON's
    ``provenance.tracker_from_base``) or ``scenario`` (its ``tracker_from_base``, which it must declare)."""
    import numpy as np

    from robotcal.geometry.euler import matrix_from_kuka_abc
    from robotcal.io.formats.parameters_json import read_tracker_from_base
    from robotcal.io.schema.builtins import read_toml

    word = text.strip().lower()
    if word == "params":
        matrix = read_tracker_from_base(params)
        if matrix is None:
            raise InputError(
                f"--tracker-from-base params: {params} records no base frame (provenance.tracker_from_base); "
                "give --tracker-from-base scenario with --scenario, or x,y,z,A,B,C"
            )
        return matrix, f"the base frame recorded in {params}"
    if word == "scenario":
        if scenario is None:
            raise InputError("--tracker-from-base scenario needs --scenario")
        if "tracker_from_base" not in read_toml(scenario.source):
            raise InputError(
                f"--tracker-from-base scenario: scenario {scenario.name} ({scenario.source}) declares no "
                "tracker_from_base; give --tracker-from-base params or x,y,z,A,B,C"
            )
        return np.asarray(scenario.tracker_from_base, dtype=float), f"tracker_from_base of scenario {scenario.name}"
    if "," not in word:
        raise InputError(f"--tracker-from-base must be x,y,z,A,B,C [mm, deg], params or scenario; got {text!r}")
    pose6 = parse_vector(text, "--tracker-from-base", 6)
    world_from_base = np.eye(4)
    world_from_base[:3, :3] = matrix_from_kuka_abc([math.radians(v) for v in pose6[3:]])
    world_from_base[:3, 3] = pose6[:3]
    return world_from_base, "given"


def predictions_to_csv(frames) -> str:
    """CSV ``pose,x,y,z,A,B,C`` (mm, KUKA deg ``R = Rz(A) Ry(B) Rx(C)``; 9 decimals)."""
    import numpy as np

    from robotcal.geometry.euler import kuka_abc_from_matrix

    abc = np.degrees(kuka_abc_from_matrix(frames))
    lines = [",".join(PREDICT_COLUMNS)]
    for i, (frame, angles) in enumerate(zip(frames, abc, strict=True)):
        values = list(frame[:3, 3]) + list(angles)
        lines.append(f"{i + 1}," + ",".join(f"{v:.9f}" for v in values))
    return "\n".join(lines) + "\n"


@app_command(app)
def predict(
    params: Annotated[Path, typer.Argument(help="Parameter JSON (nominal, CPA or refined).")],
    poses: Annotated[Path, typer.Option("--poses", help="Pose CSV with q1..qN, controller readings [deg].")],
    out: Annotated[Path, typer.Option("--out", "-o", help="CSV to write: pose,x,y,z [mm],A,B,C [deg].")],
    target: Annotated[
        str | None,
        typer.Option(
            "--target",
            help='Point on the flange: "x,y,z" [mm] (flange frame), or the NAME of a flange target of the parameter '
            "JSON's targets or of --scenario's [[targets]].",
        ),
    ] = None,
    flange: Annotated[bool, typer.Option("--flange", help="Predict the flange frame (the default).")] = False,
    tracker_from_base: Annotated[
        str | None,
        typer.Option(
            "--tracker-from-base",
            help='Base frame in the tracker: "x,y,z,A,B,C" [mm, deg KUKA], params (the JSON\'s '
            "provenance.tracker_from_base) or scenario (--scenario's tracker_from_base); default: none, the robot base.",
        ),
    ] = None,
    robot: ParamsRobot = None,
    scenario: ParamsScenario = None,
    force: Force = False,
) -> None:
    """Forward kinematics of the flange or of any flange point at given poses, with the calibrated model."""
    import warnings

    import numpy as np

    from robotcal import api
    from robotcal.errors import JointLimitWarning
    from robotcal.io.atomic import atomic_write_text
    from robotcal.io.formats.trajectory_csv import read_trajectory
    from robotcal.io.schema.scenario import load_scenario
    from robotcal.uncertainty.tcp import check_readings

    if target is not None and flange:
        raise InputError("give --target or --flange, not both")
    parameters, inputs = load_parameter_set(params, robot, scenario)
    loaded = None if scenario is None else load_scenario(scenario)
    point, point_from = (None, "flange") if target is None else flange_target_mm(target, params=params, scenario=loaded)
    world_from_base, frame_from = (None, "") if tracker_from_base is None else world_from_base_of(
        tracker_from_base, params=params, scenario=loaded
    )
    inputs += existing_inputs(poses)
    check_output_file(out, inputs=inputs, force=force)
    readings = read_trajectory(poses, n_joints=parameters.robot.n_joints)
    readings = check_readings(parameters.robot, readings, name="--poses", source=str(poses))  # limits: warning
    with warnings.catch_warnings():  # the readings were checked above, naming --poses and its file
        warnings.simplefilter("ignore", JointLimitWarning)
        frames = api.predict(parameters, np.rad2deg(readings), tool_mm=point, world_from_base=world_from_base)
    with result_file(out, inputs=inputs, force=force):
        atomic_write_text(out, predictions_to_csv(frames))
    console.print(f"wrote {out}: {prediction_summary(frames.shape[0], point, point_from, frame_from)}", highlight=False)


def prediction_summary(n_poses: int, point, point_from: str, frame_from: str) -> str:
    """What ``predict`` wrote, as a sentence: ``"3 poses of the flange point (60, 40, 30) mm given by --target,
    in the tracker frame, from the base frame recorded in refined.json"``.

    ``point``: the flange point [mm] (None: the flange frame); ``point_from``, ``frame_from``: where the point and
    the base frame come from, as :func:`flange_target_mm` and :func:`world_from_base_of` say ("given": the option's
    numbers; ``frame_from`` empty: no base frame, the robot base).
    """
    poses = f"{n_poses} pose{'s' if n_poses != 1 else ''}"
    if point is None:
        what = "the flange frame"
    else:
        where = "given by --target" if point_from == "given" else f"of {point_from}"
        what = f"the flange point ({', '.join(f'{v:g}' for v in point)}) mm {where}"
    if not frame_from:
        frame = "in the robot base frame"
    else:
        frame = "in the tracker frame, " + ("given by --tracker-from-base" if frame_from == "given" else f"from {frame_from}")
    return f"{poses} of {what}, {frame}"
