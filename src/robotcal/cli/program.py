"""``robotcal program SCENARIO --language krl|rapid|urscript --dwell S --out F``: the capture as a robot program."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import ProgramController, ProgramSpeed, ScenarioArgument, app_command, command_app, console

app = command_app()

__all__ = ["program"]


@app_command(app)
def program(
    scenario: ScenarioArgument,
    out: Annotated[Path, typer.Option("--out", "-o", help="Program file to write.")],
    language: Annotated[str, typer.Option(help="krl (KUKA) | rapid (ABB) | urscript (Universal Robots).")] = "krl",
    dwell: Annotated[float, typer.Option(help="Dwell at every measuring point [s].")] = 2.0,
    controller: ProgramController = None,
    bidirectional: Annotated[
        bool | None,
        typer.Option(
            "--bidirectional/--one-way", help="Return sweeps (default: the scenario's capture.bidirectional)."
        ),
    ] = None,
    speed: ProgramSpeed = 10.0,
    name: Annotated[
        str | None,
        typer.Option(
            help="Program name: KRL takes the --out file's name (DEF name = file name, <= 24 characters; a --name "
            "must equal it); RAPID module / URScript function (default robotcal_capture)."
        ),
    ] = None,
    compensate: Annotated[
        Path | None,
        typer.Option(
            "--compensate",
            help="Parameter JSON of the calibrated model: command the joints with which it reaches the poses the plan "
            "gives on the nominal model (robotcal compensate), its joint model included.",
        ),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace a file not written by robotcal.")] = False,
) -> None:
    """Write the capture plan as joint moves with a dwell and a comment per point (thesis 4.5.2), as taught on the
    nominal model or compensated with a calibrated one."""
    import dataclasses

    from robotcal.io import load_robot, load_scenario
    from robotcal.io.atomic import atomic_write_text
    from robotcal.io.results.output import existing_inputs, result_file
    from robotcal.planning.program import controller_readings, program_name, write_program

    name = program_name(language, out, name)
    loaded = load_scenario(scenario)
    plan = loaded.plan if bidirectional is None else dataclasses.replace(loaded.plan, bidirectional=bidirectional)
    target = None if controller is None else load_robot(controller)
    circle, direction, readings = plan.readings(loaded.robot)
    inputs = existing_inputs(*loaded.files)
    compensated = ""
    if compensate is not None:
        inputs += existing_inputs(compensate)
        readings, compensated = _compensated(compensate, loaded.robot, readings)
    angles = controller_readings(readings, loaded.robot, target)
    header = (
        f"robotcal capture program: scenario {loaded.name} ({loaded.source})\n"
        f"controller readings of robot {(target or loaded.robot).name}; {circle.size} points, dwell {dwell:g} s"
        + compensated
    )
    text = write_program(circle, direction, angles, language=language, dwell_s=dwell, name=name,
                         speed_percent=speed, header=header)  # fmt: skip
    with result_file(out, inputs=inputs, force=force) as path:
        atomic_write_text(path, text)
    what = ", compensated" if compensate is not None else ""
    console.print(f"wrote {out}: {circle.size} {language} joint moves{what}, dwell {dwell:g} s", highlight=False)


def _compensated(params: Path, robot, readings):
    """The plan's readings compensated with the calibrated model of ``params``, and the program header's line;
    a point it cannot reach inside the limits is an error naming it, a damped one (at a singularity) a note."""
    import numpy as np

    from robotcal.api import compensate as compensate_poses
    from robotcal.errors import InputError
    from robotcal.io.formats.parameters_json import read_parameters

    result = compensate_poses(read_parameters(params, robot), poses_deg=np.rad2deg(readings))
    lost = np.flatnonzero(np.isin(result.status, ["outside_limits", "unreachable"]))
    if lost.size:
        raise InputError(
            f"--compensate {params}: the calibrated model cannot reach {lost.size} point(s) of the plan inside the "
            f"joint limits on their branch (point(s) {', '.join(str(k + 1) for k in lost[:10])}"
            f"{'...' if lost.size > 10 else ''}: {', '.join(sorted(set(result.status[lost])))}); no program written"
        )
    header = f"\ncompensated with the calibrated model {params} (robotcal compensate)"
    damped = np.flatnonzero(result.status != "ok")
    if damped.size:
        note = (
            f"{damped.size} point(s) near a singularity ({', '.join(str(k + 1) for k in damped[:10])}"
            f"{'...' if damped.size > 10 else ''}): damped commands, up to "
            f"{np.nanmax(result.position_error_mm[damped]):.3g} mm from the target"
        )
        header += f"; {note}"
        console.print(f"note: {note}", highlight=False, soft_wrap=True, markup=False)
    return result.readings, header
