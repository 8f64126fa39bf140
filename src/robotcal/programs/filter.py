"""Filter a robot program with the calibrated model: the same program, with targets at which the real robot reaches
what the program meant (issue 28; thesis ch. 6.2, compensation).

For every point of a :class:`~robotcal.programs.base.Program` (in file order):

1. Its target: a Cartesian point is the tool frame ``P`` in its base / work object ``B`` (both from the program's
   declarations or the user), the tool ``T`` in the controller's flange frame; the tool frame in the robot base is
   ``X = B P`` and the flange ``X T^-1``. A joint point is controller axis values ``a``; its target is the nominal
   tool frame there.
2. The readings the nominal controller runs: for a Cartesian point, the nominal model's inverse-kinematics solution
   (:func:`robotcal.kinematics.inverse.nominal_solutions`) whose configuration data is the point's own (KUKA S and
   T, ABB cf1/cf4/cf6/cfx: :mod:`robotcal.programs.configuration`), else the solution nearest the previous point
   (URScript, or a KRL point without S and T). No solution with the point's configuration: status
   ``config_mismatch``.
3. The compensated command (:func:`robotcal.kinematics.compensation.compensate_commands`): the calibrated model's
   solution on that branch, with a status.
4. Written back in the program's own representation, numbers only: a joint point gets the command's axis values; a
   Cartesian point the target the *nominal* controller must be told so that it runs the command,
   ``P' = B^-1 F_nominal(command) T``, with its configuration data recomputed (equal unless an axis crossed zero).

A point whose status is not ``ok`` keeps the damped command (``near_singular``, ``large_correction``) or its original
numbers (``outside_limits``, ``unreachable``, ``config_mismatch``); :class:`FilteredProgram` lists every point with
its status, and the CLI exits with status 3 when any point is not ok.

Frames: the calibrated model's base frame is the controller's robot base (``$ROBROOT``, ABB's world frame); tools are
given in the controller's flange frame, which the robot file's ``flange_frame`` relates to the model's last DH frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.kinematics.compensation import CompensationSettings, compensate_commands
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.inverse import nominal_solutions, rotation_vector, within_limits
from robotcal.kinematics.model import ParameterSet, RobotModel
from robotcal.programs.base import Program, ProgramPoint, Render, replace_numbers
from robotcal.programs.configuration import configuration

__all__ = ["POINT_STATUSES", "FilteredPoint", "FilteredProgram", "filter_program", "missing_frames", "renderer"]

#: A filtered point's status: the compensation's (:data:`robotcal.kinematics.compensation.STATUSES`), or
#: ``config_mismatch`` when no nominal solution has the point's configuration data.
POINT_STATUSES = ("ok", "near_singular", "large_correction", "outside_limits", "unreachable", "config_mismatch")


@dataclass(frozen=True, slots=True, kw_only=True)
class FilteredPoint:
    """One point of a filtered program.

    Attributes
    ----------
    point : ProgramPoint
        As read.
    status : str
        One of :data:`POINT_STATUSES`.
    taught_deg : ndarray (n,)
        The controller readings the nominal controller runs for the original point [deg] (NaN if none).
    command_deg : ndarray (n,)
        The controller readings the filtered point makes it run [deg] (NaN where the point is left as it was).
    correction_mm, correction_deg : float
        How far the filtered target moves the tool on the nominal model: distance [mm] and rotation [deg].
    largest_change_deg : float
        Largest joint change from ``taught_deg`` [deg].
    position_error_mm, orientation_error_deg : float
        What remains between the calibrated model's tool at the command and the intended target.
    written : bool
        Whether the point's numbers were changed.
    remark : str
        What else a reader of the table should know of this point (a tool declared nowhere), else empty.
    tcp_u_mm : float
        Standard uncertainty of the tool position at the command [mm] (root-sum-square of u(X), u(Y), u(Z)) from the
        deployed model's Monte Carlo draws, when they were given (NaN otherwise).
    """

    point: ProgramPoint
    status: str
    taught_deg: np.ndarray
    command_deg: np.ndarray
    correction_mm: float
    correction_deg: float
    largest_change_deg: float
    position_error_mm: float
    orientation_error_deg: float
    written: bool
    remark: str = ""
    tcp_u_mm: float = float("nan")


@dataclass(frozen=True, slots=True, kw_only=True)
class FilteredProgram:
    """A filtered program: the new file texts and every point's record."""

    program: Program
    texts: dict[str, str]
    points: list[FilteredPoint] = field(default_factory=list)

    @property
    def counts(self) -> dict[str, int]:
        """How many points have each status (statuses with none left out)."""
        found = [p.status for p in self.points]
        return {status: found.count(status) for status in POINT_STATUSES if status in found}

    @property
    def all_ok(self) -> bool:
        return all(p.status == "ok" for p in self.points)


def renderer(language: str) -> Render:
    """The ``render`` function of a language's module."""
    if language == "krl":
        from robotcal.programs.krl import render
    elif language == "rapid":
        from robotcal.programs.rapid import render
    elif language == "urscript":
        from robotcal.programs.urscript import render
    else:
        raise InputError(f"unknown program language {language!r}; choose krl, rapid or urscript")
    return render


def _invert(frame: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = frame[:3, :3].T
    out[:3, 3] = -frame[:3, :3].T @ frame[:3, 3]
    return out


def _frames_of(point: ProgramPoint, frames: dict, flange: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """``(B, T, remark)``: the point's base in the robot base frame, its tool in the model's flange frame, and a
    remark when a joint point's tool is declared nowhere (it is then compensated at the flange: its joints are
    what the program moves, the tool only says which point of the arm is to be exact)."""
    if point.kind == "joint" and point.tool is not None and point.tool not in frames:
        return np.eye(4), flange, f"tool {point.tool} declared nowhere: compensated at the flange"
    missing = [name for name in (point.tool, point.base) if name is not None and name not in frames]
    if missing:
        raise InputError(f"{point.file}: line {point.line}: frame {missing[0]} is not declared in the files read")
    base = np.eye(4) if point.base is None else frames[point.base]
    tool = flange @ (np.eye(4) if point.tool is None else frames[point.tool])
    return base, tool, ""


def missing_frames(program: Program, frames: dict) -> list[str]:
    """Names of the tools and bases the program's points use but neither it nor ``frames`` declares, in order."""
    known = {**program.frames, **frames}
    names: list[str] = []
    for point in program.points:
        if point.kind != "cartesian":
            continue  # a joint target needs no frame: the joints are what is moved
        for name in (point.tool, point.base):
            if name is not None and name not in known and name not in names:
                names.append(name)
    return names


def _candidates(robot: RobotModel, readings: np.ndarray) -> np.ndarray:
    """Every whole-turn variant ``(C, n)`` of ``readings`` ``(B, n)`` inside the limits."""
    variants = [readings]
    for joint in range(robot.n_joints):
        span = robot.limits[joint, 1] - robot.limits[joint, 0]
        if span <= 2 * np.pi:
            continue
        shifted = []
        for turns in (-2, -1, 1, 2):
            moved = np.concatenate(variants, axis=0).copy()
            moved[:, joint] += 2 * np.pi * turns
            shifted.append(moved)
        variants += shifted
    every = np.concatenate(variants, axis=0)
    inside = np.all((every >= robot.limits[:, 0] - 1e-9) & (every <= robot.limits[:, 1] + 1e-9), axis=1)
    return every[inside]


def _taught(
    program: Program, point: ProgramPoint, robot: RobotModel, controller: RobotModel, flange_target, previous
) -> tuple[np.ndarray | None, str]:
    """The robot readings [rad] the nominal controller runs for a Cartesian point, or None and why: ``unreachable``
    (the nominal model reaches the original target on no branch) or ``config_mismatch`` (no solution has the point's
    configuration data). Without configuration data, the solution nearest ``previous`` (whole turns included),
    inside the limits where one is."""
    solutions, exists = nominal_solutions(robot, flange_target[None], reference=previous)
    existing = solutions[0][exists[0]]
    if existing.size == 0:
        return None, "unreachable"
    wanted = dict(point.config)
    if wanted and program.language != "urscript":
        candidates = _candidates(robot, existing)  # every whole-turn variant: the turn data pick among them
        found = configuration(program.language, controller, _to_controller(robot, controller, candidates))
        match = np.array([all(entry.get(key) == value for key, value in wanted.items()) for entry in found], dtype=bool)
        candidates = candidates[match] if candidates.size else candidates
        if candidates.size == 0:
            return None, "config_mismatch"
    else:  # nominal_solutions already took the turns nearest previous, inside the limits where they allow
        inside = within_limits(robot, existing)
        candidates = existing[inside] if inside.any() else existing
    distance = np.abs(candidates - previous).max(axis=1)
    return candidates[int(np.argmin(distance))], ""


def _to_controller(robot: RobotModel, controller: RobotModel, readings) -> np.ndarray:
    return controller.readings_from_model(robot.model_joint_variables(readings))


def _to_robot(robot: RobotModel, controller: RobotModel, readings) -> np.ndarray:
    return robot.readings_from_model(controller.model_joint_variables(readings))


def filter_program(
    program: Program,
    parameters: ParameterSet,
    *,
    controller: RobotModel | None = None,
    frames: dict | None = None,
    settings: CompensationSettings | None = None,
    start_deg: ArrayLike | None = None,
) -> FilteredProgram:
    """The program with every point solved on the calibrated model and written back (module notes).

    Parameters
    ----------
    program : Program
        As read by :mod:`robotcal.programs.krl`, :mod:`~robotcal.programs.rapid` or :mod:`~robotcal.programs.urscript`.
    parameters : ParameterSet
        The calibrated model (with its joint model, if any).
    controller : RobotModel, optional
        The robot file whose readings are the program's axis values and whose ``flange_frame`` is the controller's
        flange (default: the calibrated model's robot).
    frames : dict of str to ndarray (4, 4), optional
        Tools and bases the program uses but does not declare (or that replace its declarations) [mm].
    settings : CompensationSettings, optional
    start_deg : array_like (n,), optional
        Controller readings the robot stands at before the first point [deg] (default: mid-limits): the first
        point without configuration data takes the solution nearest it.

    Returns
    -------
    FilteredProgram
    """
    robot = parameters.robot
    controller = controller or robot
    if controller.n_joints != robot.n_joints or not np.allclose(controller.nominal, robot.nominal):
        raise InputError(
            f"controller robot {controller.name!r} has another nominal geometry than the calibrated model's robot "
            f"{robot.name!r}: give the robot file of the same arm with the controller's reading signs"
        )
    known = {**program.frames, **(frames or {})}
    missing = missing_frames(program, frames or {})
    if missing:
        raise InputError(
            f"the program uses {', '.join(missing)} but no file read declares {'it' if len(missing) == 1 else 'them'}: "
            "give each with --frame NAME=x,y,z,A,B,C (mm, deg KUKA), or the file that declares it"
        )
    flange = np.eye(4) if controller.flange_frame is None else np.asarray(controller.flange_frame)
    nominal = ParameterSet.nominal(robot)
    if start_deg is None:
        previous = np.where(np.isfinite(robot.limits), robot.limits, 0.0).mean(axis=1)
    else:
        previous = _to_robot(robot, controller, np.deg2rad(np.asarray(start_deg, dtype=float)))
    targets: list[np.ndarray] = []
    taught: list[np.ndarray] = []
    tools: list[np.ndarray] = []
    records: list[dict] = []
    for point in program.points:
        base, tool, remark = _frames_of(point, known, flange)
        readings: np.ndarray | None
        if point.kind == "joint":
            readings = _to_robot(robot, controller, np.deg2rad(np.asarray(point.joints_deg, dtype=float)))
            target = forward_kinematics(robot.nominal, robot.model_joint_variables(readings[None]))[0] @ tool
        else:
            target = base @ point.frame_mm
            readings, why = _taught(program, point, robot, controller, target @ _invert(tool), previous)
        if readings is None:
            if why == "unreachable":
                remark = "; ".join(filter(None, (remark, "the nominal model reaches it on no branch either")))
            records.append({"point": point, "status": why, "base": base, "tool": tool, "remark": remark})
            continue
        previous = readings
        records.append({"point": point, "status": None, "base": base, "tool": tool, "row": len(targets), "remark": remark})
        targets.append(target)
        taught.append(readings)
        tools.append(tool)
    result = _compensate(parameters, targets, taught, tools, settings)
    replacements = {}
    filtered = []
    n = robot.n_joints
    for record in records:
        point, base, tool = record["point"], record["base"], record["tool"]
        if record["status"] is not None:  # no nominal solution to start from: left as written
            nan = np.full(n, np.nan)
            filtered.append(_record(point, record["status"], nan, nan, None, None, False, record["remark"]))
            continue
        row = record["row"]
        status = str(result.status[row])
        taught_row = taught[row]
        command = result.readings[row]
        written = bool(np.all(np.isfinite(command)))
        if written:
            replacements.update(_new_numbers(program.language, point, command, robot, controller, base, tool))
        moved = _nominal_move(nominal, taught_row, command, tool) if written else (np.nan, np.nan)
        filtered.append(
            _record(
                point, status, np.degrees(_to_controller(robot, controller, taught_row)),
                np.degrees(_to_controller(robot, controller, command)) if written else np.full(n, np.nan),
                moved, (result, row), written, record["remark"],
            )
        )  # fmt: skip
    return FilteredProgram(program=program, texts=replace_numbers(program.texts, replacements), points=filtered)


def _new_numbers(language: str, point: ProgramPoint, command, robot, controller, base, tool) -> dict:
    """The replacement text of ``point``'s numbers for the robot ``command`` [rad]: a joint point's controller axis
    values; a Cartesian point's target for the nominal controller, ``B^-1 F_nominal(command) T``, with its
    configuration data recomputed."""
    render = renderer(language)
    controller_command = _to_controller(robot, controller, command)
    if point.kind == "joint":
        return render(point, joints_deg=np.degrees(controller_command))
    frame = forward_kinematics(robot.nominal, robot.model_joint_variables(command[None]))[0] @ tool
    new_config = configuration(language, controller, controller_command[None])[0]
    config = {key: new_config[key] for key in point.config} if point.config else None
    return render(point, frame_mm=_invert(base) @ frame, config=config)


def _compensate(parameters, targets, taught, tools, settings):
    """Compensate every point at once, grouped by tool (the solver takes one tool per call)."""
    from robotcal.kinematics.compensation import Compensation

    count = len(targets)
    n = parameters.robot.n_joints
    readings = np.full((count, n), np.nan)
    taught_all = np.stack(taught) if count else np.zeros((0, n))
    status = np.full(count, "unreachable", dtype=object)
    position, angle, change = (np.full(count, np.nan) for _ in range(3))
    groups: dict[bytes, list[int]] = {}
    for index, tool in enumerate(tools):
        groups.setdefault(np.round(tool, 12).tobytes(), []).append(index)
    for members in groups.values():
        rows = np.array(members)
        part = compensate_commands(
            parameters, np.stack([targets[k] for k in rows]), np.stack([taught[k] for k in rows]),
            tool=tools[rows[0]], settings=settings,
        )  # fmt: skip
        readings[rows] = part.readings
        status[rows] = part.status
        position[rows], angle[rows], change[rows] = (
            part.position_error_mm, part.orientation_error_deg, part.largest_change_deg
        )
    return Compensation(
        readings=readings, position_error_mm=position, orientation_error_deg=angle, iterations=0,
        reached=status == "ok", status=status.astype(str), largest_change_deg=change, taught=taught_all,
    )  # fmt: skip


def _nominal_move(nominal: ParameterSet, taught, command, tool) -> tuple[float, float]:
    """Distance [mm] and rotation [deg] between the nominal tool at ``taught`` and at ``command``."""
    robot = nominal.robot
    frames = forward_kinematics(nominal.values, robot.model_joint_variables(np.stack([taught, command]))) @ tool
    distance = float(np.linalg.norm(frames[1, :3, 3] - frames[0, :3, 3]))
    turn = float(np.degrees(np.linalg.norm(rotation_vector(frames[1, :3, :3] @ frames[0, :3, :3].T))))
    return distance, turn


def _record(point, status, taught_deg, command_deg, moved, solved, written, remark) -> FilteredPoint:
    if solved is None:
        errors = (np.nan, np.nan, np.nan)
    else:
        result, row = solved
        errors = (result.largest_change_deg[row], result.position_error_mm[row], result.orientation_error_deg[row])
    correction = (np.nan, np.nan) if moved is None else moved
    return FilteredPoint(
        point=point, status=status, taught_deg=taught_deg, command_deg=command_deg,
        correction_mm=float(correction[0]), correction_deg=float(correction[1]), largest_change_deg=float(errors[0]),
        position_error_mm=float(errors[1]), orientation_error_deg=float(errors[2]), written=written, remark=remark,
    )  # fmt: skip

