"""``robotcal iso9283``: ISO 9283 AP, RP, AD, RD of several models on measured repeated poses, and
``robotcal iso9283-plan``: the standard's five test poses as a pose CSV (docs/iso9283.md)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table

from robotcal.cli._common import FORCE_HELP, command_app, console, handle_errors
from robotcal.cli.export import parse_vector
from robotcal.diagnostics.iso9283 import ISO_CYCLES, iso_plan_readings, iso_test_positions, pose_characteristics
from robotcal.errors import InputError
from robotcal.geometry.transforms import apply_transform, check_rigid_transform, invert_transform
from robotcal.io import atomic_write_text, load_scenario, read_capture, read_parameters
from robotcal.io._validation import read_json_file
from robotcal.io.output import check_output_file, existing_inputs, result_file
from robotcal.io.trajectory_csv import write_trajectory
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.model import ParameterSet

app = command_app()

ISO_COLUMNS = ("model", "pose", "APx", "APy", "APz", "AP", "l_bar", "S_l", "RP", "AD", "RD")


def _tracker_from_base(path: Path, default: np.ndarray) -> np.ndarray:
    data = read_json_file(path, kind="parameter JSON")
    matrix = (data.get("provenance") or {}).get("tracker_from_base") if isinstance(data, dict) else None
    if matrix is None:
        return default
    try:
        return check_rigid_transform(np.asarray(matrix, dtype=float), f"{path}: provenance.tracker_from_base")
    except (TypeError, ValueError) as exc:
        raise InputError(f"{path}: key `provenance.tracker_from_base` must be a 4x4 rigid transform") from exc


def flange_target(scenario, target: str | None) -> np.ndarray:
    """The measured flange point [mm]: ``--target``, else the scenario's flange reflector or validation target."""
    if target is not None:
        return np.asarray(parse_vector(target, "--target"), dtype=float)
    if scenario.plan.reflector.frame == "flange":
        return scenario.plan.reflector.positions[0]
    if scenario.validation and scenario.validation.get("flange_reflector_mm") is not None:
        return np.asarray(scenario.validation["flange_reflector_mm"], dtype=float)
    raise InputError(
        f"scenario {scenario.name!r} declares no flange target ([validation] flange_reflector_mm); give --target x,y,z"
    )


def iso_results(capture, target, sets: dict, n_test_poses: int, distance_pair: tuple[int, int]) -> dict:
    """ISO 9283 result of every model: measured points mapped to the model's base frame.

    ``sets`` maps a label to ``(ParameterSet, tracker_from_base)``; the commanded position of a
    test pose is the model's FK of the flange ``target`` [mm] at the pose's mean readings.
    """
    free = capture.circle == 0
    if not np.any(free):
        raise InputError("the capture has no free poses (rows with circle = 0)")
    readings, points = capture.readings[free], capture.points[free]
    if readings.shape[0] % n_test_poses or readings.shape[0] < 2 * n_test_poses:
        raise InputError(
            f"the capture's {readings.shape[0]} free poses are not whole cycles of {n_test_poses} test poses "
            "(at least 2 cycles, cycle-major)"
        )
    n_cycles = readings.shape[0] // n_test_poses
    commands = readings.reshape(n_cycles, n_test_poses, -1).mean(axis=0)
    results = {}
    for label, (parameters, tracker_from_base) in sets.items():
        frames = forward_kinematics(parameters.values, parameters.robot.model_joint_variables(commands))
        commanded = apply_transform(frames, target)
        attained = apply_transform(invert_transform(tracker_from_base), points).reshape(n_cycles, n_test_poses, 3)
        results[label] = pose_characteristics(attained, commanded, distance_pair=distance_pair)
    return results


def iso_to_csv(results: dict) -> str:
    lines = [",".join(ISO_COLUMNS)]
    for label, r in results.items():
        for k in range(r.ap.shape[0]):
            values = [*r.ap_xyz[k], r.ap[k], r.l_bar[k], r.s_l[k], r.rp[k]]
            lines.append(f"{label},P{k + 1}," + ",".join(f"{v:.6f}" for v in values) + ",,")
        a, b = r.distance_pair
        lines.append(f"{label},P{a + 1}-P{b + 1}" + "," * 8 + f"{r.ad:.6f},{r.rd:.6f}")
    return "\n".join(lines) + "\n"


@app.command()
@handle_errors
def iso9283(
    capture: Annotated[Path, typer.Argument(help="Capture CSV of the repeated test poses (circle = 0, cycle-major).")],
    scenario: Annotated[str, typer.Option("--scenario", "-s", help="Scenario: robot, flange target, base frame.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="CSV to write (model, pose, AP..., RP, AD, RD) [mm].")],
    params: Annotated[
        list[Path] | None, typer.Option("--params", "-p", help="Parameter JSON (repeatable): CPA, refined, ...")
    ] = None,
    nominal: Annotated[bool, typer.Option("--nominal/--no-nominal", help="Include the nominal model first.")] = True,
    poses_per_cycle: Annotated[int, typer.Option("--poses-per-cycle", min=2, help="Test poses per cycle.")] = 5,
    distance_poses: Annotated[str, typer.Option("--distance-poses", help='Poses of AD/RD, "2,4" = P2, P4.')] = "2,4",
    target: Annotated[str | None, typer.Option("--target", help='Measured flange point "x,y,z" [mm].')] = None,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
) -> None:
    """ISO 9283 position accuracy (AP) and repeatability (RP), distance accuracy (AD) and repeatability (RD)."""
    pair = parse_vector(distance_poses, "--distance-poses", 2)
    if any(v != int(v) or not 1 <= v <= poses_per_cycle for v in pair):
        raise InputError(f"--distance-poses must be two pose numbers 1..{poses_per_cycle}; got {distance_poses!r}")
    params = list(params or [])
    inputs = existing_inputs(capture, scenario, *params)
    loaded = load_scenario(scenario)
    check_output_file(out, inputs=inputs, force=force)
    sets = {}
    if nominal:
        sets["nominal"] = (ParameterSet.nominal(loaded.robot), loaded.tracker_from_base)
    for path in params:
        label = path.stem if path.stem not in sets else str(path)
        sets[label] = (read_parameters(path, loaded.robot), _tracker_from_base(path, loaded.tracker_from_base))
    if not sets:
        raise InputError("nothing to evaluate: give --params or leave --nominal on")
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    results = iso_results(
        measured, flange_target(loaded, target), sets, poses_per_cycle, (int(pair[0]) - 1, int(pair[1]) - 1)
    )
    with result_file(out, inputs=inputs, force=force):
        atomic_write_text(out, iso_to_csv(results))
    table = Table(title=f"ISO 9283 ({next(iter(results.values())).n_cycles} cycles) [mm]")
    for column in ("model", "max AP", "max RP", "AD", "RD"):
        table.add_column(column)
    for label, r in results.items():
        table.add_row(label, f"{r.ap.max():.4f}", f"{r.rp.max():.4f}", f"{r.ad:.4f}", f"{r.rd:.4f}")
    console.print(table)
    console.print(f"wrote {out}", highlight=False)


@app.command("iso9283-plan")
@handle_errors
def iso9283_plan(
    scenario: Annotated[str, typer.Option("--scenario", "-s", help="Scenario: robot and flange target.")],
    center: Annotated[str, typer.Option("--center", help='Cube centre "x,y,z" in the base frame [mm].')],
    side: Annotated[float, typer.Option("--side", help="Cube side [mm].")],
    start: Annotated[str, typer.Option("--start", help='Start readings "q1,...,qN" [deg]; sets the orientation.')],
    out: Annotated[Path, typer.Option("--out", "-o", help="Pose CSV to write (q1..qN in deg).")],
    cycles: Annotated[int, typer.Option("--cycles", min=2, help="Cycles through P1..P5.")] = ISO_CYCLES,
    target: Annotated[str | None, typer.Option("--target", help='Flange point placed on P1..P5 "x,y,z" [mm].')] = None,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
) -> None:
    """The ISO 9283 test poses P1..P5 (cube's diagonal plane) as controller readings, repeated per cycle."""
    loaded = load_scenario(scenario)
    robot = loaded.robot
    centre = parse_vector(center, "--center")
    start_deg = parse_vector(start, "--start", robot.n_joints)
    inputs = existing_inputs(scenario)
    check_output_file(out, inputs=inputs, force=force)
    point = flange_target(loaded, target)
    positions = iso_test_positions(centre, side)
    readings = iso_plan_readings(
        ParameterSet.nominal(robot), positions, [math.radians(v) for v in start_deg], target=point, n_cycles=cycles
    )
    with result_file(out, inputs=inputs, force=force):
        write_trajectory(out, readings, comment=f"ISO 9283 test poses P1..P5, {cycles} cycles, cube side {side:g} mm")
    console.print(f"wrote {out} ({readings.shape[0]} poses)", highlight=False)
