"""The front door's calls on a calibrated model and on a real cell's files: commands that compensate taught poses
(:func:`compensate`), compensated robot programs (:func:`filter_program`), forward kinematics of any flange point
(:func:`predict`), the model written for other software (:func:`export_model`), the ISO 9283 test
(:func:`iso9283`) and a capture imported from a tracker export (:func:`import_capture`).

They are part of :mod:`robotcal.api` (which re-exports them; import them from there or from ``robotcal``) and
follow its conventions: a ``robot`` is a RobotModel or a Scenario, ``parameters`` a ParameterSet, a result holding
one or a parameter JSON path, numbers in mm and degrees, value objects in mm and radians.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.io.schema.robots import load_robot
from robotcal.io.schema.scenario import Scenario
from robotcal.kinematics.forward import check_joint_variables
from robotcal.kinematics.model import ParameterSet, RobotModel
from robotcal.resolve import (
    ParameterSource,
    as_capture,
    as_parameters,
    calibrated_parameters,
    compensation_targets,
    needed,
    program_tcp_uncertainty,
    split_robot,
)
from robotcal.uncertainty.tcp import check_readings

if TYPE_CHECKING:
    from robotcal.diagnostics.iso9283 import Iso9283Result
    from robotcal.io.formats.tracker_import import TrackerPoints
    from robotcal.kinematics.compensation import Compensation, CompensationSettings
    from robotcal.programs.base import Program
    from robotcal.programs.filter import FilteredProgram

__all__ = ["compensate", "export_model", "filter_program", "import_capture", "iso9283", "predict"]

PathLike = str | os.PathLike


def compensate(
    parameters: ParameterSource,
    robot: RobotModel | Scenario | None = None,
    *,
    poses_deg: ArrayLike | None = None,
    cartesian: ArrayLike | None = None,
    start_deg: ArrayLike | None = None,
    tool_mm: ArrayLike | None = None,
    settings: CompensationSettings | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Compensation:
    """Joint commands with which the calibrated robot reaches the poses it was taught (issues 22, 28; thesis ch. 6.2).

    The targets are joint poses ``poses_deg`` (n_poses, n_joints) taught on the nominal model [deg] (their branch is
    kept), or Cartesian targets ``cartesian`` (n_poses, 6): ``x, y, z`` [mm], ``A, B, C`` [deg, KUKA ``Rz Ry Rx``] in
    the base frame, whose nominal solution nearest ``start_deg`` [deg] (default mid-limits) is what the command
    replaces; ``tool_mm`` (3,): the tool point in the flange frame [mm]. ``robot`` is needed for a parameter JSON path;
    ``settings``: what an ``ok`` command must meet; ``progress(done, total)`` after every block of 5,000 poses.

    Every row gets a command and a status (:mod:`robotcal.kinematics.compensation`): ``ok``, ``near_singular`` /
    ``large_correction`` (flagged), ``outside_limits`` / ``unreachable`` (NaN). One hard pose never fails the others.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> robot = robotcal.load_robot("kuka-kr5-sixx-r650")
    >>> calibrated = robotcal.perturb(robot, rng=3)
    >>> taught = [[10.0, 40.0, 30.0, 5.0, 45.0, 0.0]]
    >>> result = robotcal.compensate(calibrated, poses_deg=taught)
    >>> result.status.tolist(), bool(np.abs(np.rad2deg(result.readings) - taught).max() > 1e-3)
    (['ok'], True)
    """
    from robotcal.kinematics.compensation import compensate_commands

    parameters = calibrated_parameters(parameters, robot)
    targets, taught, tool = compensation_targets(
        parameters.robot, poses_deg=poses_deg, cartesian=cartesian, start_deg=start_deg, tool_mm=tool_mm
    )
    return compensate_commands(parameters, targets, taught, tool=tool, settings=settings, progress=progress)


def filter_program(
    program: PathLike | Program,
    parameters: ParameterSource,
    robot: RobotModel | Scenario | None = None,
    *,
    controller: RobotModel | str | None = None,
    frames: dict[str, np.ndarray] | None = None,
    language: str | None = None,
    dat: PathLike | None = None,
    config_dat: PathLike | None = None,
    encoding: str = "utf-8",
    start_deg: ArrayLike | None = None,
    settings: CompensationSettings | None = None,
    draws: Any = None,
) -> FilteredProgram:
    """A robot program (KRL ``.src``, RAPID ``.mod``, URScript, or a read Program) with every target compensated by
    the calibrated model, numbers changed only (issue 28).

    ``controller``: the robot file whose readings are the program's axis values (default the model's robot);
    ``frames``: tools and bases [mm] the program does not declare; ``language``, ``dat``, ``config_dat``,
    ``encoding``: how to read it (:func:`robotcal.programs.read_program`); ``start_deg``: readings before the first
    point [deg]; ``draws``: the deployed model's Monte Carlo draws, for every written point's tool position
    uncertainty at its command (``tcp_u_mm``, thesis ch. 5.3). Returns ``texts``, ``points`` and ``counts``.
    """
    from robotcal.programs import read_program
    from robotcal.programs.base import Program
    from robotcal.programs.filter import filter_program as filter_core

    parameters = calibrated_parameters(parameters, robot)
    if isinstance(controller, str | os.PathLike):
        controller = load_robot(controller)
    if not isinstance(program, Program):
        program = read_program(program, language=language, dat=dat, config_dat=config_dat, encoding=encoding)
    result = filter_core(program, parameters, controller=controller, frames=frames, settings=settings, start_deg=start_deg)
    if draws is None:
        return result
    return program_tcp_uncertainty(result, parameters.robot, controller or parameters.robot, draws, frames)


def predict(
    parameters: ParameterSource,
    poses_deg: ArrayLike,
    robot: RobotModel | Scenario | None = None,
    *,
    tool_mm: ArrayLike | None = None,
    world_from_base: np.ndarray | None = None,
) -> np.ndarray:
    """``world_from_tool`` frames (n_poses, 4, 4) [mm] of the calibrated model at controller readings ``poses_deg``
    (n_poses, n_joints) [deg] (``robotcal predict``; docs/export.md).

    The tool is the flange translated to ``tool_mm`` (flange frame [mm]; default the flange); ``world_from_base``
    (4, 4) [mm] defaults to the robot base. Readings outside the joint limits give a JointLimitWarning.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> robot = robotcal.load_robot("kuka-kr5-sixx-r650")
    >>> frames = robotcal.predict(None, [[0, -90, 90, 0, 0, 0]], robot, tool_mm=[0, 0, 100])
    >>> frames.shape
    (1, 4, 4)
    """
    from robotcal.kinematics.forward import forward_kinematics

    parameters = calibrated_parameters(parameters, robot)
    readings = np.deg2rad(check_joint_variables(poses_deg, parameters.robot.n_joints, "poses_deg"))
    readings = check_readings(parameters.robot, readings, name="poses_deg")
    frames = forward_kinematics(parameters.values, parameters.model_joint_variables(readings))
    if tool_mm is not None:
        tool = np.eye(4)
        tool[:3, 3] = np.asarray(tool_mm, dtype=float).reshape(3)
        frames = frames @ tool
    return frames if world_from_base is None else np.asarray(world_from_base, dtype=float) @ frames


def iso9283(
    capture: Capture | PathLike,
    robot: RobotModel | Scenario,
    models: Mapping[str, Any] | None = None,
    *,
    nominal: bool = True,
    tracker_from_base: np.ndarray | None = None,
    point_mm: ArrayLike | None = None,
    targets_mm: Mapping[str, Any] | None = None,
    poses_per_cycle: int = 5,
    distance_poses: tuple[int, int] = (2, 4),
    orientation_axes: Literal["base", "flange"] = "base",
) -> dict[str, Iso9283Result]:
    """ISO 9283 pose accuracy and repeatability (AP, RP; with three or more flange targets per pose APa/b/c and
    RPa/b/c too), distance accuracy and repeatability (AD, RD between the 1-based ``distance_poses``) of every
    model on a capture of repeated test poses (cycles of ``poses_per_cycle`` poses), as ``robotcal iso9283``.

    ``models``: names to parameters or :class:`~robotcal.diagnostics.iso9283.IsoModel` (a model with its own base
    frame and target offsets), after the nominal model (``nominal``); ``tracker_from_base`` [mm] (default the
    scenario's); the measured flange point ``point_mm`` [mm] (default the scenario's flange reflector) or, for a
    capture with a ``target`` column, the flange offsets ``targets_mm`` of its targets [mm] (default the scenario's
    known ones).
    """
    from robotcal.diagnostics.iso9283 import IsoModel, iso_from_capture, scenario_flange_point

    robot, scenario = split_robot(robot)
    capture = as_capture(capture, robot)
    base = needed(tracker_from_base, "tracker_from_base", scenario, lambda s: s.tracker_from_base)
    sets = {"nominal": IsoModel(parameters=ParameterSet.nominal(robot), tracker_from_base=base)} if nominal else {}
    for name, model in (models or {}).items():
        if not isinstance(model, IsoModel):
            model = IsoModel(parameters=as_parameters(model, robot, f"models[{name!r}]"), tracker_from_base=base)
        sets[str(name)] = model
    if not sets:
        raise InputError("nothing to evaluate: give `models` or leave `nominal` on")
    point = None if point_mm is None else np.asarray(point_mm, dtype=float)
    offsets = None
    if capture.target is None:
        point = needed(point, "point_mm", scenario, scenario_flange_point)
    elif targets_mm is None and scenario is not None:
        offsets = {t.name: t.positions for t in scenario.targets if t.frame == "flange" and t.known}
    else:
        offsets = None if targets_mm is None else dict(targets_mm)
    return iso_from_capture(
        capture, sets, point=point, targets=offsets, n_test_poses=poses_per_cycle,
        distance_pair=(int(distance_poses[0]) - 1, int(distance_poses[1]) - 1), orientation_axes=orientation_axes,
    )  # fmt: skip


def import_capture(
    export: PathLike,
    joints: PathLike,
    robot: RobotModel | Scenario | None = None,
    *,
    columns: str | Mapping[str, str] | None = None,
    units: str | None = None,
    delimiter: str | None = None,
    decimal: str | None = None,
    join: Literal["name", "order"] = "name",
    encoding: str = "utf-8",
    target: str | None = None,
) -> tuple[Capture, TrackerPoints]:
    """A capture from a tracker export and a joint-angle log (``robotcal import``; docs/real-robot.md): the export's
    points [its ``units``, default its header's; converted to mm] joined to the log's readings [deg] by point name
    (``join="name"``) or by order; ``robot`` checks the number of joint columns. ``columns``: the column map of a
    generic export; ``delimiter``, ``decimal``, ``encoding``: how to read both files (default detected, utf-8);
    ``target``: the target name of every point, or ``VALUE=NAME,...`` renaming the target column's values.
    Returns the capture (write it with :func:`robotcal.write_capture`) and the export as read (its layout, unit)."""
    from robotcal.io.formats.tracker_import import join_points_to_readings, read_joint_log, read_tracker_export

    n_joints = None if robot is None else split_robot(robot)[0].n_joints
    # names are checked after the join (a target column in either file may tell points apart)
    points = read_tracker_export(
        export, columns=None if columns is None else (columns if isinstance(columns, str) else dict(columns)),
        delimiter=delimiter, decimal=decimal, units=units, check_names=False, encoding=encoding,
    )  # fmt: skip
    log = read_joint_log(joints, n_joints=n_joints, check_names=False, encoding=encoding)
    return join_points_to_readings(points, log, join=join, target=target), points


def export_model(
    parameters: ParameterSource,
    format: Literal["json", "urdf", "ur-yaml", "dh", "mdh"] = "json",
    robot: RobotModel | Scenario | None = None,
    *,
    tool_mm: ArrayLike | None = None,
    joint_variable: Literal["reading", "model"] = "reading",
    markdown: bool = False,
    provenance: Mapping[str, Any] | None = None,
) -> str:
    """The text of the calibrated model in ``format`` (``robotcal export``; docs/export.md): a parameter JSON (with
    ``provenance``), URDF (``tool_mm``: its tool0 frame on the flange [mm]), UR calibration YAML, or a DH / MDH table
    (CSV, or ``markdown``), exact or an InputError; ``joint_variable``: the tables' joint value is the controller
    reading or the model variable q. An extended model's joint model, which none but the JSON holds, is noted.

    Examples
    --------
    >>> import robotcal
    >>> text = robotcal.export_model(robotcal.load_robot("kuka-kr5-sixx-r650"), "dh")
    >>> text.splitlines()[0].split(",")[:3]
    ['joint', 'theta_deg', 'd_mm']
    """
    import json

    from robotcal.io.formats import export as formats
    from robotcal.io.formats.parameters_json import parameters_to_dict

    if isinstance(parameters, RobotModel):
        parameters = ParameterSet.nominal(parameters)
    parameters = calibrated_parameters(parameters, robot)
    if format not in formats.EXPORT_FORMATS:
        raise InputError(f"`format` must be one of {', '.join(formats.EXPORT_FORMATS)}; got {format!r}")
    if tool_mm is not None and format != "urdf":
        raise InputError("a tool (`tool_mm`) is written only by the urdf format")
    if format == "json":
        document = parameters_to_dict(parameters, dict(provenance or {}))
        return json.dumps(document, indent=2, allow_nan=False) + "\n"
    if format == "urdf":
        text = formats.parameters_to_urdf(parameters, tool=tool_mm, joint_variable=joint_variable)
    elif format == "ur-yaml":
        if joint_variable != "reading":
            raise InputError("`joint_variable` 'model' is written only by the urdf, dh and mdh formats")
        text = formats.parameters_to_ur_yaml(parameters)
    else:
        rows = (formats.dh_table if format == "dh" else formats.mdh_table)(parameters, joint_variable=joint_variable)
        title = f"{'DH' if format == 'dh' else 'Modified DH'} table of {parameters.robot.name} [mm, deg]"
        if joint_variable == "model":
            title += "; joint value = model variable q (reading_sign 1, reading_offset_deg 0)"
        text = formats.table_to_markdown(rows, title=title) if markdown else formats.table_to_csv(rows)
    note = formats.joint_model_note(parameters)
    if note is None:
        return text
    return formats.with_note(text, note, "markdown" if markdown and format in ("dh", "mdh") else format)
