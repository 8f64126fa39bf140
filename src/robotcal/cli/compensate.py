"""``robotcal compensate PARAMS --poses CSV --out CSV [--tool x,y,z] [--start-deg q1,..,qN] [--max-change-deg D]``:
the joint commands with which the calibrated robot reaches what was taught (issues 22, 28; :func:`robotcal.compensate`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import Force, ParamsRobot, ParamsScenario, app_command, command_app, console, progress_bar
from robotcal.cli.export import load_parameter_set, parse_vector
from robotcal.io.results.output import SIGNATURE, check_output_file, existing_inputs, result_file

#: Exit status of a command that wrote its output but some of its rows or points are not ok (their status says why).
PARTIAL_EXIT = 3
#: What each status other than ok means, for the console.
STATUS_MEANING = {
    "near_singular": "at a singularity: a damped command that leaves the error in the file",
    "large_correction": "a correction larger than the calibration explains: a damped command, check it",
    "outside_limits": "reachable only beyond a joint limit: no command",
    "unreachable": "out of the calibrated robot's reach on the taught branch: no command",
}

app = command_app()


def _targets(cartesian, readings, start) -> tuple[dict, str]:
    """:func:`robotcal.api.compensate`'s targets from a pose CSV read by ``read_pose_targets`` (joint poses, or
    Cartesian targets and their seeds, else ``--start-deg``) [deg, mm], and what they are, in words."""
    import numpy as np

    if cartesian is None:
        return {"poses_deg": np.rad2deg(readings)}, "joint targets taught on the nominal model"
    seeds = np.rad2deg(readings) if readings is not None else start
    targets = {"cartesian": np.c_[cartesian[:, :3], np.rad2deg(cartesian[:, 3:])], "start_deg": seeds}
    return targets, "Cartesian targets in the robot base frame"


def _write_commands(
    out: Path, result, labels, params: str, poses: str, kind: str, max_change_deg: float, extended: bool, inputs, force: bool
) -> str:
    """Write the commands, every row under its own name with its status and errors; returns the status counts
    as words ("3 ok, 1 unreachable")."""
    import numpy as np

    from robotcal.io.formats.trajectory_csv import write_trajectory
    from robotcal.kinematics.compensation import STATUSES

    counts = {status: int(np.sum(result.status == status)) for status in STATUSES if np.any(result.status == status)}
    rows = ", ".join(f"{count} {status}" for status, count in counts.items())
    comment = (
        f"{SIGNATURE} compensate: commands with which the calibrated model {params} reaches the {kind} of "
        f"{poses}\nrows: {rows}; only 'ok' rows are exact (<= 1e-6 mm, 1e-6 deg, same branch, no joint moved "
        f"more than {max_change_deg:g} deg); rows without a command have empty q cells"
        + ("" if not extended else "\nthe joint model (gravity compliance, harmonic errors) is applied")
    )
    columns = {
        "status": result.status,
        "position_error_mm": result.position_error_mm,
        "orientation_error_deg": result.orientation_error_deg,
        "largest_change_deg": result.largest_change_deg,
    }
    with result_file(out, inputs=inputs, force=force):
        write_trajectory(out, result.readings, comment=comment, labels=labels, columns=columns)
    return rows


# The options of `compensate` that take several lines, declared once here (the command reads as a list of its options).
_Poses = Annotated[
    Path,
    typer.Option(
        "--poses",
        help="Targets: a pose CSV pose,q1..qN [deg] taught on the nominal model, or Cartesian targets "
        "pose,x,y,z,A,B,C [mm, deg KUKA] in the robot base frame (predict's format), optionally with q1..qN seeds.",
    ),
]
_Out = Annotated[
    Path,
    typer.Option(
        "--out",
        "-o",
        help="Pose CSV to write: pose,q1..qN [deg],status,position_error_mm,orientation_error_deg,"
        "largest_change_deg; every input row under its own name.",
    ),
]
_Tool = Annotated[
    str | None, typer.Option("--tool", help='Tool point "x,y,z" in the flange frame [mm] (default: the flange).')
]
_StartDeg = Annotated[
    str | None,
    typer.Option(
        "--start-deg",
        help="Cartesian targets without seeds: readings q1,..,qN [deg] near the wanted solution (default: the "
        "middle of the joint limits).",
    ),
]
_MaxChangeDeg = Annotated[
    float,
    typer.Option(
        "--max-change-deg",
        min=0.001,
        help="Largest joint change from the taught reading in an ok row [deg]; more means a singularity or "
        "another branch.",
    ),
]


@app_command(app)
def compensate(
    params: Annotated[Path, typer.Argument(help="Parameter JSON of the calibrated model (refined, extended or not).")],
    poses: _Poses,
    out: _Out,
    tool: _Tool = None,
    start_deg: _StartDeg = None,
    max_change_deg: _MaxChangeDeg = 2.0,
    robot: ParamsRobot = None,
    scenario: ParamsScenario = None,
    force: Force = False,
) -> None:
    """Joint commands with which the calibrated robot reaches the poses taught on the nominal model (or Cartesian
    targets): on the taught branch, near the taught joints, its joint model (gravity sag, harmonic errors) included.
    Every row is written under its own name with a status (ok, near_singular, large_correction, outside_limits,
    unreachable); rows without a command have empty q cells. Exit status 3 when some row is not ok."""
    import numpy as np

    from robotcal import api
    from robotcal.io.formats.trajectory_csv import pose_labels, read_pose_targets
    from robotcal.kinematics.compensation import BLOCK_ROWS, STATUSES, CompensationSettings

    parameters, inputs = load_parameter_set(params, robot, scenario)
    n = parameters.robot.n_joints
    inputs += existing_inputs(poses)
    check_output_file(out, inputs=inputs, force=force)
    cartesian, readings = read_pose_targets(poses, n_joints=n)
    labels = pose_labels(poses)
    tool_mm = None if tool is None else parse_vector(tool, "--tool")
    start = None if start_deg is None else parse_vector(start_deg, "--start-deg", n)
    settings = CompensationSettings(max_change_deg=max_change_deg)
    targets, kind = _targets(cartesian, readings, start)
    if len(labels) > BLOCK_ROWS:  # more than one block: show the blocks go by
        with progress_bar("compensate", "poses") as display:
            task = display.add_task("compensate", total=len(labels))
            result = api.compensate(
                parameters, **targets, tool_mm=tool_mm, settings=settings,
                progress=lambda done, total: display.update(task, completed=done),
            )  # fmt: skip
    else:
        result = api.compensate(parameters, **targets, tool_mm=tool_mm, settings=settings)
    extended = parameters.joint_model is not None
    rows = _write_commands(out, result, labels, params.name, poses.name, kind, max_change_deg, extended, inputs, force)
    ok = result.status == "ok"
    worst = (
        f"; ok rows: largest remaining error {np.max(result.position_error_mm[ok]):.2g} mm, "
        f"{np.max(result.orientation_error_deg[ok]):.2g} deg, largest joint change {np.max(result.largest_change_deg[ok]):.4f} deg"
        if ok.any()
        else ""
    )
    plural = "s" if len(labels) != 1 else ""
    console.print(f"wrote {out} ({len(labels)} pose{plural}, {kind}: {rows}{worst})", highlight=False, soft_wrap=True, markup=False)
    say_not_ok(
        {status: [labels[k] for k in np.flatnonzero(result.status == status)] for status in STATUSES[1:]},
        STATUS_MEANING, "row", "check the status column before running the file",
    )  # fmt: skip


def say_not_ok(names_by_status: dict[str, list[str]], meaning: dict[str, str], what: str, advice: str) -> None:
    """Name, on the console, the rows (points) of every status but ok, then exit with :data:`PARTIAL_EXIT` if any."""
    count = 0
    for status, names in names_by_status.items():
        if names:
            count += len(names)
            shown = ", ".join(names[:10]) + (f" and {len(names) - 10} more" if len(names) > 10 else "")
            console.print(f"  {status}: {shown} ({meaning[status]})", highlight=False, soft_wrap=True, markup=False)
    if count:
        console.print(
            f"{count} {what}{'s are' if count != 1 else ' is'} not ok: {advice} (exit status {PARTIAL_EXIT})",
            highlight=False, soft_wrap=True, markup=False,
        )  # fmt: skip
        raise typer.Exit(code=PARTIAL_EXIT)
