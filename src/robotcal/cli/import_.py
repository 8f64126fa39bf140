"""``robotcal import EXPORT --joints LOG --out CAPTURE.csv``: a tracker export into a capture CSV (docs/real-robot.md)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal, cast

import typer

from robotcal.cli._common import Force, command_app, console, handle_errors

if TYPE_CHECKING:
    from robotcal.io.schema.scenario import Scenario
    from robotcal.kinematics.model import RobotModel

app = command_app()

COLUMNS_HELP = (
    'Column map of a generic export: x="X [mm]",y=...,z=...[,name=...,u95=...,target=...,circle=...,direction=...] '
    "(header names, or 1-based column numbers in a file without header); a 6-DoF orientation as qw,qx,qy,qz "
    "(quaternion), a,b,c (KUKA ABC, deg), roll,pitch,yaw (deg) or r11..r33, with u95_deg. Default: Leica or plain "
    "name;x;y;z recognised."
)


def _with_session(capture, session: str | None):
    """The capture in session ``session`` (``--session``), unchanged without it."""
    if session is None:
        return capture
    if not session.strip():
        from robotcal.errors import InputError

        raise InputError("--session: the session name must not be empty")
    return capture.with_session(session.strip())


@app.command("import")
@handle_errors
def import_(
    export: Annotated[Path, typer.Argument(help="Tracker export (Leica, plain name;x;y;z, or generic with --columns).")],
    joints: Annotated[
        Path, typer.Option("--joints", "-j", help="Joint-angle log CSV: name (to join by name), q1..qN [deg].")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Capture CSV to write (circle,direction,q1..qN,x,y,z,...).")],
    columns: Annotated[str | None, typer.Option("--columns", help=COLUMNS_HELP)] = None,
    units: Annotated[
        str | None, typer.Option("--units", help="Unit of the export's coordinates: mm | m | in | um (default: its header).")
    ] = None,
    delimiter: Annotated[
        str | None, typer.Option("--delimiter", help="Delimiter of the export: ',' | ';' | tab | space (default: detected).")
    ] = None,
    decimal: Annotated[
        str | None, typer.Option("--decimal", help="Decimal separator of the export: '.' | ',' (default: detected).")
    ] = None,
    join: Annotated[
        str, typer.Option("--join", help="name: point names = pose names of the log | order: point k <-> row k.")
    ] = "name",
    encoding: Annotated[
        str,
        typer.Option(
            "--encoding",
            help="Text encoding of the export and the log (e.g. cp1252, latin-1: Windows exports with '[µm]' or "
            "'[°C]' headers).",
        ),
    ] = "utf-8",
    target: Annotated[
        str | None,
        typer.Option(
            "--target",
            help="Target name for every point (no target column, or one holding a single value such as a "
            "reflector serial, which it renames); or VALUE=NAME,... to rename each value of the target column.",
        ),
    ] = None,
    session: Annotated[
        str | None,
        typer.Option("--session", help="Session of every point (tracker station, day): one base frame per session."),
    ] = None,
    robot: Annotated[
        str | None, typer.Option("--robot", "-r", help="Robot name or TOML: checks the number of joint columns.")
    ] = None,
    scenario: Annotated[
        str | None, typer.Option("--scenario", "-s", help="Scenario whose robot checks the joint columns.")
    ] = None,
    force: Force = False,
) -> None:
    """Convert a tracker export and a joint-angle log into a capture CSV (mm, deg; U(95) kept as u95_mm)."""
    from robotcal import api
    from robotcal.errors import InputError
    from robotcal.io import load_robot, load_scenario
    from robotcal.io.formats.capture_csv import write_capture
    from robotcal.io.results.output import check_output_file, existing_inputs, result_file

    if robot is not None and scenario is not None:
        raise InputError("give --robot or --scenario, not both")
    inputs = existing_inputs(export, joints, robot, scenario)
    model: Scenario | RobotModel | None = None
    if scenario is not None:
        model = load_scenario(scenario)
        inputs += existing_inputs(*model.files)
    elif robot is not None:
        model = load_robot(robot)
    check_output_file(out, inputs=inputs, force=force)
    capture, points = api.import_capture(
        export, joints, model, columns=columns, units=units, delimiter=delimiter, decimal=decimal,
        join=cast(Literal["name", "order"], join),  # any other text: InputError from the join itself
        encoding=encoding, target=target,
    )  # fmt: skip
    capture = _with_session(capture, session)
    with result_file(out, inputs=inputs, force=force):
        write_capture(out, capture)
    poses = len({tuple(row) for row in capture.readings.tolist()})
    targets = f", targets {', '.join(capture.target_names)}" if capture.target is not None else ""
    u95 = (", U(95) per point" if capture.u95 is not None else "") + (f", session {session}" if session else "")
    console.print(
        f"wrote {out}: {capture.n_points} points at {poses} poses ({points.layout} export in {points.unit}{targets}{u95})",
        highlight=False,
    )
