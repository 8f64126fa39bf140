"""``robotcal filter PROGRAM --params JSON --out DIR [--controller ROBOT] [--frame NAME=x,y,z,A,B,C]...``: a robot
program (KUKA KRL .src/.dat, ABB RAPID .mod, URScript .script) with every target compensated by the calibrated
model, numbers changed and nothing else (issue 28; :mod:`robotcal.programs.filter`, docs/deploy.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import Force, ParamsRobot, ParamsScenario, app_command, command_app, console
from robotcal.cli.compensate import say_not_ok
from robotcal.cli.export import load_parameter_set, parse_vector

app = command_app()

__all__ = ["filter_command"]

def _frames(items: list[str] | None) -> dict:
    """``NAME=x,y,z,A,B,C`` options -> ``{NAME: 4x4}`` [mm, deg KUKA]."""
    import numpy as np

    from robotcal.errors import InputError
    from robotcal.geometry.euler import matrix_from_kuka_abc

    frames = {}
    for item in items or []:
        name, separator, numbers = item.partition("=")
        if not separator or not name.strip():
            raise InputError(f"--frame must be NAME=x,y,z,A,B,C (mm, deg KUKA); got {item!r}")
        values = parse_vector(numbers, f"--frame {name.strip()}", 6)
        frame = np.eye(4)
        frame[:3, :3] = matrix_from_kuka_abc(np.deg2rad(values[3:]))
        frame[:3, 3] = values[:3]
        frames[name.strip()] = frame
    return frames


# The options of `filter`, declared once here (the command reads as a list of its options).
_Out = Annotated[
    Path,
    typer.Option(
        "--out",
        "-o",
        help="Folder to write: the filtered program files under their own names, points.csv (every point's "
        "status and correction) and filter.html.",
    ),
]
_Controller = Annotated[
    str | None,
    typer.Option(
        help="Robot file of the same arm with the controller's reading signs and flange frame (e.g. "
        "kuka-kr5-sixx-r650-krc); default: the parameters' robot."
    ),
]
_Frame = Annotated[
    list[str] | None,
    typer.Option(
        "--frame",
        help="A tool or base the program uses, NAME=x,y,z,A,B,C [mm, deg KUKA] (e.g. TOOL_DATA[1]=..., tool1=..., "
        "wobj1=...); replaces the program's own declaration. Repeat for several.",
    ),
]
_ConfigDat = Annotated[
    Path | None, typer.Option("--config-dat", help="KRL: the cell's $config.dat with TOOL_DATA and BASE_DATA.")
]
_StartDeg = Annotated[
    str | None,
    typer.Option(
        "--start-deg",
        help="Controller readings q1,..,qN [deg] where the robot stands before the program: the first point "
        "without configuration data takes the solution nearest them (default: mid-limits).",
    ),
]
_MaxChangeDeg = Annotated[
    float, typer.Option("--max-change-deg", min=0.001, help="Largest joint change in an ok point [deg].")
]
_Draws = Annotated[
    Path | None,
    typer.Option(
        "--draws",
        help="The deployed model's Monte Carlo draws (a run's uncertainty-refined/draws.npz): each point's tool "
        "position uncertainty at its command, column tcp_u_mm.",
    ),
]


@app_command(app, "filter")
def filter_command(
    program: Annotated[Path, typer.Argument(help="The robot program: KRL .src (its .dat beside it), RAPID .mod, URScript .script.")],
    params: Annotated[Path, typer.Option("--params", "-p", help="Parameter JSON of the calibrated model.")],
    out: _Out,
    controller: _Controller = None,
    frame: _Frame = None,
    language: Annotated[str | None, typer.Option(help="krl | rapid | urscript (default: from the suffix).")] = None,
    dat: Annotated[Path | None, typer.Option("--dat", help="KRL: the .dat (default: beside the .src).")] = None,
    config_dat: _ConfigDat = None,
    start_deg: _StartDeg = None,
    max_change_deg: _MaxChangeDeg = 2.0,
    draws: _Draws = None,
    encoding: Annotated[str, typer.Option(help="Text encoding of the program files (e.g. cp1252).")] = "utf-8",
    robot: ParamsRobot = None,
    scenario: ParamsScenario = None,
    force: Force = False,
) -> None:
    """Filter a robot program with the calibrated model: every target solved on the nominal controller's branch
    (its S/T or cf configuration data, or nearest the previous point), compensated on the calibrated model, and
    written back in the program's own representation; everything else byte-identical. Exit status 3 when some
    point is not ok."""
    from robotcal import api
    from robotcal.io import load_robot
    from robotcal.io.results.output import check_output_folder, existing_inputs, result_folder
    from robotcal.kinematics.compensation import CompensationSettings
    from robotcal.programs import read_program
    from robotcal.programs.report import STATUS_NOTES, write_report

    parameters, inputs = load_parameter_set(params, robot, scenario)
    target = None if controller is None else load_robot(controller)
    inputs += existing_inputs(program, dat, config_dat, controller, draws)
    check_output_folder(out, inputs=inputs, force=force)
    loaded = read_program(program, language=language, dat=dat, config_dat=config_dat, encoding=encoding)
    inputs += existing_inputs(*(program.with_name(name) for name in loaded.texts))
    start = None if start_deg is None else parse_vector(start_deg, "--start-deg", parameters.robot.n_joints)
    result = api.filter_program(
        loaded, parameters, controller=target, frames=_frames(frame), start_deg=start,
        settings=CompensationSettings(max_change_deg=max_change_deg), draws=draws,
    )  # fmt: skip
    with result_folder(out, inputs=inputs, force=force, command="filter") as folder:
        write_report(result, folder, params=params, program=program, encoding=encoding)
    counts = result.counts
    console.print(
        f"wrote {out}: {', '.join(loaded.texts)} filtered ({len(result.points)} point"
        f"{'s' if len(result.points) != 1 else ''}: {', '.join(f'{n} {s}' for s, n in counts.items()) or 'none'}"
        f"{f'; {len(loaded.skipped)} target(s) not filtered, listed in points.csv' if loaded.skipped else ''})",
        highlight=False, soft_wrap=True, markup=False,
    )  # fmt: skip
    say_not_ok(
        {s: [f"{p.point.label} (line {p.point.line})" for p in result.points if p.status == s] for s in STATUS_NOTES if s != "ok"},
        STATUS_NOTES, "point", "read points.csv before running the program",
    )  # fmt: skip
