"""``robotcal iso9283``: ISO 9283 AP, RP, AD, RD (and APa/b/c, RPa/b/c with three or more flange
targets per pose) of several models on measured repeated poses, and ``robotcal iso9283-plan``: the
standard's five test poses as a pose CSV and, with ``--program``, a robot program (docs/iso9283.md)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal, cast

import typer

from robotcal.cli._common import Force, ProgramController, ProgramSpeed, app_command, command_app, console
from robotcal.cli._tables import Column, FittedTable
from robotcal.cli.export import parse_vector
from robotcal.errors import InputError
from robotcal.io.results.output import check_output_file, existing_inputs, result_file
from robotcal.limits import ISO_CYCLES

if TYPE_CHECKING:  # numpy and the diagnostics load in the commands: a fast --help
    import numpy as np

app = command_app()

PROGRAM_SUFFIX = {"krl": ".src", "rapid": ".mod", "urscript": ".script"}


def _tracker_from_base(path: Path, default: np.ndarray) -> np.ndarray:
    from robotcal.io.formats.parameters_json import read_tracker_from_base

    matrix = read_tracker_from_base(path)
    return default if matrix is None else matrix


def flange_target(scenario, target: str | None) -> np.ndarray:
    """The measured flange point [mm]: ``--target``, else :func:`scenario_flange_point`."""
    import numpy as np

    from robotcal.diagnostics.iso9283 import scenario_flange_point

    if target is not None:
        return np.asarray(parse_vector(target, "--target"), dtype=float)
    return scenario_flange_point(scenario)


def parse_targets_mm(text: str) -> dict:
    """``"name=x,y,z;name=x,y,z"`` -> ``{name: (3,) offset [mm]}`` (``--targets-mm``)."""
    import numpy as np

    out = {}
    for item in (part.strip() for part in text.split(";")):
        if not item:
            continue
        name, sep, vector = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise InputError(f"--targets-mm: expected name=x,y,z entries separated by ';'; got {item!r}")
        if name in out:
            raise InputError(f"--targets-mm: target {name!r} given twice")
        out[name] = np.asarray(parse_vector(vector, f"--targets-mm {name}", 3), dtype=float)
    if not out:
        raise InputError("--targets-mm: no target given (name=x,y,z;...)")
    return out


def scenario_offsets(scenario) -> dict:
    """Flange offsets [mm] of the scenario's known flange targets, by name."""
    return {t.name: t.positions for t in scenario.targets if t.frame == "flange" and t.known}


def _model_offsets(path: Path) -> dict | None:
    """The flange target offsets a parameter JSON carries (a refinement's ``targets``: estimates of unknown ones)."""
    import numpy as np

    from robotcal.io.formats.parameters_json import read_targets

    return {name: np.asarray(v, dtype=float) for name, v in read_targets(path).items()} or None


@app_command(app)
def iso9283(
    capture: Annotated[Path, typer.Argument(help="Capture CSV of the repeated test poses (circle = 0, cycle-major).")],
    scenario: Annotated[str, typer.Option("--scenario", "-s", help="Scenario: robot, flange target(s), base frame.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="CSV to write (model, pose, AP..., RP, AD, RD, APa..RPc).")],
    params: Annotated[
        list[Path] | None, typer.Option("--params", "-p", help="Parameter JSON (repeatable): CPA, refined, ...")
    ] = None,
    nominal: Annotated[bool, typer.Option("--nominal/--no-nominal", help="Include the nominal model first.")] = True,
    poses_per_cycle: Annotated[int, typer.Option("--poses-per-cycle", min=2, help="Test poses per cycle.")] = 5,
    distance_poses: Annotated[str, typer.Option("--distance-poses", help='Poses of AD/RD, "2,4" = P2, P4.')] = "2,4",
    target: Annotated[
        str | None,
        typer.Option("--target", help='Flange point whose position is evaluated "x,y,z" [mm] (several targets: '
                     "default their centroid)."),
    ] = None,
    targets_mm: Annotated[
        str | None,
        typer.Option("--targets-mm", help='Flange offsets of the capture\'s targets "name=x,y,z;..." [mm] '
                     "(default: the parameter JSON's, else the scenario's [[targets]])."),
    ] = None,
    orientation_axes: Annotated[
        str, typer.Option("--orientation-axes", help="Axes of APa/b/c, RPa/b/c: base (ISO) or flange (commanded).")
    ] = "base",
    force: Force = False,
) -> None:
    """ISO 9283 pose accuracy (AP, APa/b/c) and repeatability (RP, RPa/b/c), distance accuracy (AD) and
    repeatability (RD). With three or more flange targets per pose (a `target` column) the flange
    orientation is measured too."""
    import numpy as np

    from robotcal import api
    from robotcal.diagnostics.iso9283 import ORIENTATION_AXES, IsoModel
    from robotcal.io.atomic import atomic_write_text
    from robotcal.io.formats.capture_csv import read_capture
    from robotcal.io.formats.parameters_json import read_parameters
    from robotcal.io.results.iso9283_files import iso_to_csv
    from robotcal.io.schema.scenario import load_scenario

    if orientation_axes not in ORIENTATION_AXES:
        raise InputError(f"--orientation-axes must be one of {', '.join(ORIENTATION_AXES)}; got {orientation_axes!r}")
    pair = parse_vector(distance_poses, "--distance-poses", 2)
    if any(v != int(v) or not 1 <= v <= poses_per_cycle for v in pair):
        raise InputError(f"--distance-poses must be two pose numbers 1..{poses_per_cycle}; got {distance_poses!r}")
    params = list(params or [])
    given_offsets = None if targets_mm is None else parse_targets_mm(targets_mm)
    inputs = existing_inputs(capture, scenario, *params)
    loaded = load_scenario(scenario)
    check_output_file(out, inputs=inputs, force=force)
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    models = {}
    for path in params:
        models[path.stem if path.stem not in models and (path.stem != "nominal" or not nominal) else str(path)] = IsoModel(
            parameters=read_parameters(path, loaded.robot),
            tracker_from_base=_tracker_from_base(path, loaded.tracker_from_base),
            target_offsets=None if given_offsets is not None else _model_offsets(path),
        )
    if not models and not nominal:
        raise InputError("nothing to evaluate: give --params or leave --nominal on")
    results = api.iso9283(
        measured, loaded, models, nominal=nominal, point_mm=None if target is None else parse_vector(target, "--target"),
        targets_mm=given_offsets, poses_per_cycle=poses_per_cycle, distance_poses=(int(pair[0]), int(pair[1])),
        orientation_axes=cast(Literal["base", "flange"], orientation_axes),  # one of ORIENTATION_AXES, checked above
    )  # fmt: skip
    with result_file(out, inputs=inputs, force=force):
        atomic_write_text(out, iso_to_csv(results))
    first = next(iter(results.values()))
    columns = [Column("model", "name"), *(Column(header) for header in ("max AP", "max RP", "AD", "RD"))]
    if first.has_orientation:
        columns += [Column("max |APa,b,c|"), Column("max RPa,b,c"), Column("max fit RMS", narrow=1)]
    table = FittedTable(f"ISO 9283 ({first.n_cycles} cycles) [mm, deg]", columns, elsewhere=str(out))
    for label, r in results.items():
        row = [label, f"{r.ap.max():.4f}", f"{r.rp.max():.4f}", f"{r.ad:.4f}", f"{r.rd:.4f}"]
        if r.has_orientation:
            assert r.ap_abc is not None and r.rp_abc is not None and r.registration_rms is not None
            row += [
                f"{np.rad2deg(np.abs(r.ap_abc).max()):.5f}",
                f"{np.rad2deg(r.rp_abc.max()):.5f}",
                f"{r.registration_rms.max():.4f}",
            ]
        table.add_row(*row)
    console.print(table)
    console.print(f"wrote {out}", highlight=False)


# The options of `iso9283_plan` that take several lines, declared once here (the command reads as a list of its options).
_PlanCenter = Annotated[
    str | None,
    typer.Option("--center", help='Cube centre "x,y,z" in the base frame [mm] (default: the point at --start).'),
]
_PlanSide = Annotated[
    float | None, typer.Option("--side", help="Cube side [mm] (default: 20 % of the reach, halved to fit).")
]
_PlanStart = Annotated[
    str | None,
    typer.Option("--start", help='Start readings "q1,...,qN" [deg]; sets the orientation (default: the best '
                 "conditioned of a grid in the limits)."),
]
_PlanProgram = Annotated[
    str | None, typer.Option("--program", help="Also write a robot program: krl | rapid | urscript.")
]
_PlanProgramOut = Annotated[
    Path | None, typer.Option("--program-out", help="Program file (default: --out with .src, .mod or .script).")
]
_PlanName = Annotated[
    str | None,
    typer.Option("--name", help="Program name: KRL takes the program file's name (DEF name = file name, <= 24 "
                 "characters; a --name must equal it); RAPID module / URScript function (default robotcal_iso9283)."),
]


@app_command(app, "iso9283-plan")
def iso9283_plan(
    scenario: Annotated[str, typer.Option("--scenario", "-s", help="Scenario: robot and flange target.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Pose CSV to write (q1..qN in deg).")],
    center: _PlanCenter = None,
    side: _PlanSide = None,
    start: _PlanStart = None,
    cycles: Annotated[int, typer.Option("--cycles", min=2, help="Cycles through P1..P5.")] = ISO_CYCLES,
    target: Annotated[str | None, typer.Option("--target", help='Flange point placed on P1..P5 "x,y,z" [mm].')] = None,
    program: _PlanProgram = None,
    program_out: _PlanProgramOut = None,
    dwell: Annotated[float, typer.Option("--dwell", help="Dwell at every test pose in the program [s].")] = 2.0,
    controller: ProgramController = None,
    speed: ProgramSpeed = 10.0,
    name: _PlanName = None,
    force: Force = False,
) -> None:
    """The ISO 9283 test poses P1..P5 (cube's diagonal plane) as controller readings, repeated per cycle;
    with --program also as a robot program (a joint move and a dwell per pose)."""
    import numpy as np

    from robotcal.diagnostics.iso9283 import iso_cube_plan
    from robotcal.io.atomic import atomic_write_text
    from robotcal.io.formats.trajectory_csv import write_trajectory
    from robotcal.io.schema.scenario import load_scenario
    from robotcal.kinematics.model import ParameterSet
    from robotcal.planning.program import LANGUAGES, program_name

    loaded = load_scenario(scenario)
    robot = loaded.robot
    centre = None if center is None else parse_vector(center, "--center")
    start_deg = None if start is None else parse_vector(start, "--start", robot.n_joints)
    if side is not None and not (math.isfinite(side) and side > 0):
        raise InputError(f"--side must be > 0 mm; got {side:g}")
    if program is not None and program not in LANGUAGES:
        raise InputError(f"--program must be one of {', '.join(LANGUAGES)}; got {program!r}")
    if program is None and program_out is not None:
        raise InputError("--program-out needs --program krl|rapid|urscript")
    inputs = existing_inputs(scenario)
    check_output_file(out, inputs=inputs, force=force)
    if program is not None:
        program_out = program_out if program_out is not None else out.with_suffix(PROGRAM_SUFFIX[program])
        if program_out.resolve() == out.resolve():
            raise InputError(f"--program-out {program_out} is the pose CSV --out; give another file")
        name = program_name(program, program_out, "robotcal_iso9283" if name is None and program != "krl" else name)
        check_output_file(program_out, inputs=inputs, force=force)
    point = flange_target(loaded, target)
    start_readings, centre, side, readings = iso_cube_plan(
        ParameterSet.nominal(robot), point, start_readings=None if start_deg is None else np.radians(start_deg),
        center_mm=centre, side_mm=side, n_cycles=cycles,
    )  # fmt: skip
    text = None
    if program is not None:
        text = iso_program(
            loaded, readings, language=program, dwell_s=dwell, controller=controller, speed_percent=speed, name=name,
            description=f"cube centre {', '.join(f'{v:.3f}' for v in centre)} mm, side {side:g} mm, flange point "
            f"{', '.join(f'{v:g}' for v in point)} mm",
        )  # fmt: skip
    with result_file(out, inputs=inputs, force=force):
        write_trajectory(
            out, readings, comment=f"ISO 9283 test poses P1..P5, {cycles} cycles, cube centre "
            f"{', '.join(f'{v:.3f}' for v in centre)} mm, side {side:g} mm, start "
            f"{', '.join(f'{v:.3f}' for v in np.degrees(start_readings))} deg",
        )  # fmt: skip
    console.print(
        f"wrote {out} ({readings.shape[0]} poses; cube centre {', '.join(f'{v:.3f}' for v in centre)} mm, "
        f"side {side:g} mm)", highlight=False,
    )  # fmt: skip
    if text is not None:
        with result_file(program_out, inputs=inputs, force=force) as path:
            atomic_write_text(path, text)
        moves = f"{readings.shape[0]} {program} joint moves, dwell {dwell:g} s"
        console.print(f"wrote {program_out}: {moves}", highlight=False)


def iso_program(
    scenario, readings, *, language: str, dwell_s: float, controller=None, speed_percent=10.0, name="robotcal_iso9283",
    description: str = "",
) -> str:
    """The ISO 9283 plan (readings of the scenario's robot, cycle-major P1..P5) as a robot program:
    one joint move per test pose, a dwell for the measurement and a comment "cycle c Pk"."""
    from robotcal.io.schema.robots import load_robot
    from robotcal.planning.program import controller_readings, write_program

    target = None if controller is None else load_robot(controller)
    angles = controller_readings(readings, scenario.robot, target)
    n_poses = 5
    labels = [f"ISO 9283 cycle {k // n_poses + 1} P{k % n_poses + 1}" for k in range(angles.shape[0])]
    header = (
        f"robotcal ISO 9283 pose test: scenario {scenario.name} ({scenario.source})\n"
        + (f"{description}\n" if description else "")
        + f"controller readings of robot {(target or scenario.robot).name}; {angles.shape[0] // n_poses} cycles of "
        f"P1..P5, dwell {dwell_s:g} s"
    )
    return write_program(None, None, angles, language=language, dwell_s=dwell_s, name=name,
                         speed_percent=speed_percent, header=header, labels=labels)  # fmt: skip
