"""``robotcal export PARAMS --format json|urdf|ur-yaml|dh|mdh --out F``: the calibrated model out, and
``robotcal export --nominal ROBOT ...``: a robot's nominal model in the same formats (docs/export.md)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal, cast

import typer

from robotcal.cli._common import Force, ParamsRobot, ParamsScenario, app_command, command_app, console
from robotcal.errors import InputError
from robotcal.io.results.output import check_output_file, existing_inputs, result_file

if TYPE_CHECKING:  # numpy and the model load in the commands: a fast --help (predict, compensate, filter too)
    from robotcal.kinematics.model import ParameterSet

app = command_app()



def parse_vector(text: str | None, option: str, count: int = 3):
    """``"x,y,z"`` -> list of floats, or :class:`InputError` naming the option."""
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise InputError(f"{option} must be {count} comma-separated numbers; got {text!r}") from None
    if len(values) != count or not all(v == v and abs(v) != float("inf") for v in values):
        raise InputError(f"{option} must be {count} finite comma-separated numbers; got {text!r}")
    return values


def load_parameter_set(params: Path, robot: str | None, scenario: str | None) -> tuple[ParameterSet, list[Path]]:
    """Read a parameter JSON for the robot of ``--robot``, ``--scenario`` or the JSON's own robot name."""
    from robotcal.io.formats.parameters_json import read_parameters
    from robotcal.io.schema._validation import read_json_file
    from robotcal.io.schema.builtins import builtin_names
    from robotcal.io.schema.robots import load_robot
    from robotcal.io.schema.scenario import load_scenario

    if robot is not None and scenario is not None:
        raise InputError("give --robot or --scenario, not both")
    inputs = existing_inputs(params, robot, scenario)
    if scenario is not None:
        loaded = load_scenario(scenario)
        model = loaded.robot
        inputs += existing_inputs(*loaded.files)
    elif robot is not None:
        model = load_robot(robot)
    else:
        data = read_json_file(Path(params), kind="parameter JSON")
        name = data.get("robot") if isinstance(data, dict) else None
        if not isinstance(name, str) or name not in builtin_names("robots"):
            raise InputError(
                f"{params}: robot {name!r} is not a built-in robot; name its robot file with --robot or --scenario"
            )
        model = load_robot(name)
    return read_parameters(params, model), inputs


@app_command(app)
def export(
    params: Annotated[
        Path | None, typer.Argument(help="Parameter JSON (of identify / refine); omit it with --nominal.")
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="File to write (.md for a Markdown dh/mdh table).")
    ] = None,
    nominal: Annotated[
        str | None,
        typer.Option(
            "--nominal",
            help="Robot name or TOML: write its nominal parameters instead of a PARAMS file (--format json: a "
            "parameter JSON that identify, refine, predict and export read).",
        ),
    ] = None,
    format: Annotated[str, typer.Option("--format", "-f", help="json | urdf | ur-yaml | dh | mdh.")] = "json",
    robot: ParamsRobot = None,
    scenario: ParamsScenario = None,
    tool: Annotated[str | None, typer.Option("--tool", help='URDF tool0 frame on the flange "x,y,z" [mm].')] = None,
    joint_variable: Annotated[
        str,
        typer.Option(
            "--joint-variable",
            help="URDF / dh / mdh joint value: reading (controller reading; sign/offset folded in) | model (model "
            "variable q: the tables then have reading_sign 1, reading_offset_deg 0; the only export of a coupled "
            "robot).",
        ),
    ] = "reading",
    force: Force = False,
) -> None:
    """Write the calibrated model (or, with --nominal, a robot's nominal model) as JSON, URDF, UR calibration
    YAML or a DH / MDH table (exact, else an error)."""
    from robotcal import api
    from robotcal.io.atomic import atomic_write_text
    from robotcal.io.formats.export import EXPORT_FORMATS, joint_model_note
    from robotcal.io.schema.robots import load_robot
    from robotcal.kinematics.model import ParameterSet

    if out is None:
        raise InputError("--out is required: the file to write")
    if format not in EXPORT_FORMATS:
        raise InputError(f"--format must be one of {', '.join(EXPORT_FORMATS)}; got {format!r}")
    tool_mm = parse_vector(tool, "--tool")
    if tool_mm is not None and format != "urdf":
        raise InputError("--tool is written only by --format urdf")
    if nominal is not None:
        if params is not None or robot is not None or scenario is not None:
            raise InputError("--nominal ROBOT names the robot; give no PARAMS file, --robot or --scenario with it")
        model = load_robot(nominal)
        parameters, inputs = ParameterSet.nominal(model), existing_inputs(nominal)
        provenance = {"method": "nominal parameters of the robot file", "robot_file": str(nominal)}
    elif params is None:
        raise InputError("give a parameter JSON (PARAMS) or --nominal ROBOT")
    else:
        parameters, inputs = load_parameter_set(params, robot, scenario)
        provenance = None
    check_output_file(out, inputs=inputs, force=force)
    if format == "json" and provenance is None:
        assert params is not None  # provenance is None only for a PARAMS file
        provenance = json.loads(Path(params).read_text(encoding="utf-8")).get("provenance", {})
    markdown = Path(out).suffix.lower() in (".md", ".markdown")
    if format == "ur-yaml" and joint_variable != "reading":
        raise InputError("--joint-variable model is written only by --format urdf, dh and mdh")
    text = api.export_model(
        parameters, cast(Literal["json", "urdf", "ur-yaml", "dh", "mdh"], format),  # checked against EXPORT_FORMATS
        tool_mm=tool_mm, markdown=markdown,
        joint_variable=cast(Literal["reading", "model"], joint_variable),  # another value: InputError from the export
        provenance=provenance if isinstance(provenance, dict) else {},
    )  # fmt: skip
    with result_file(out, inputs=inputs, force=force):
        atomic_write_text(out, text)
    note = None if format == "json" else joint_model_note(parameters)
    what = f", nominal model of {parameters.robot.name}" if nominal is not None else ""
    console.print(f"wrote {out} ({format}{what})", highlight=False)
    if note is not None:
        console.print(f"note: {note}", highlight=False, soft_wrap=True)
