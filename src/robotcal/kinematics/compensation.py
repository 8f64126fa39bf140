"""Compensation: the joint commands with which the calibrated robot reaches the poses it was taught (issues 22, 28).

A program taught on the nominal model (or written as Cartesian targets) sends joint commands that put the real
robot somewhere else: its geometry differs from the nominal one and its joints sag under gravity and carry
periodic angle errors (:mod:`robotcal.kinematics.joint_model`). Knowing the calibrated model, the controller can be
sent other commands instead, those at which the *calibrated* model's tool frame is the intended one (thesis
ch. 6.2, the compensation of joint errors left as future work).

A command must be one a controller can run safely (issue 28): on the taught command's inverse-kinematics branch,
near it, and exact. :func:`compensate_commands` gives every row a status (:data:`STATUSES`):

``ok``
    The calibrated model at the command is the target to 1e-6 mm and 1e-6 deg, every reading inside the limits,
    the same branch (:func:`robotcal.kinematics.inverse.branch_of`) as the taught readings, no joint moved more than
    ``max_change_deg`` (2 deg), and the nominal tool moved by no more than about the calibrated model's difference
    from the nominal one there (``explained_ratio``).
``near_singular``
    The exact command would swing a joint more than ``max_change_deg`` or cross a branch boundary: the pose is at a
    singularity (J4 and J6 aligned, the wrist centre on J1's axis, the stretched elbow). The command written is the
    damped least-squares one (Levenberg-Marquardt towards the taught readings: the J4/J6 split stays where the taught
    command had it), with the error it leaves.
``large_correction``
    The same away from any singularity: the exact command moves the robot further than the calibration explains
    (a model far from nominal, or a pose the taught branch reaches only by a large move). The damped command is
    written, flagged.
``outside_limits``
    The calibrated model reaches the target only with a reading outside the limits: no command (NaN).
``unreachable``
    No branch reaches the target: no command (NaN).

The solve: Newton's method from the taught readings (:func:`robotcal.kinematics.inverse.solve_pose`: its steps are
the smallest joint change that removes the error, so it stays on the taught branch); the rows it does not bring to
``ok`` are solved on every branch (:func:`robotcal.kinematics.inverse.inverse_kinematics`, closed form on the nominal
geometry then Newton on the calibrated model), and the taught branch's solution, or a neighbouring branch's within
``max_change_deg``, is taken.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError, check_count
from robotcal.kinematics.inverse import (
    as_tool_frame,
    branch_of,
    check_targets,
    inverse_kinematics,
    nominal_solutions,
    robot_size,
    rotation_vector,
    solve_pose,
    tool_frames,
    within_limits,
    wrap_readings,
)
from robotcal.kinematics.model import ParameterSet

__all__ = [
    "STATUSES",
    "Compensation",
    "CompensationSettings",
    "compensate_commands",
]

#: Rows solved at a time by :func:`compensate_commands` (its working arrays stay a few MB).
BLOCK_ROWS = 5000
#: The status of a compensated row (:func:`compensate_commands`), from best to worst.
STATUSES = ("ok", "near_singular", "large_correction", "outside_limits", "unreachable")


@dataclass(frozen=True, slots=True, kw_only=True)
class Compensation:
    """Compensated commands and how close they bring the calibrated model to every target.

    Attributes
    ----------
    readings : ndarray, shape (n_poses, n_joints)
        Controller readings to command [rad]; NaN in the rows whose status is ``outside_limits`` or
        ``unreachable`` (no command is given for them).
    position_error_mm, orientation_error_deg : ndarray, shape (n_poses,)
        Remaining distance and rotation between the calibrated tool frame at ``readings`` and the target (NaN where
        no command is given).
    iterations : int
        Newton steps taken from the taught readings (the slowest pose's).
    reached : ndarray of bool, shape (n_poses,)
        Within the tolerances of :class:`CompensationSettings` (an ``ok`` row always is).
    status : ndarray of str, shape (n_poses,)
        One of :data:`STATUSES` per row.
    largest_change_deg : ndarray, shape (n_poses,)
        The largest joint change from the taught readings [deg] (NaN where no command is given).
    taught : ndarray, shape (n_poses, n_joints)
        The readings the commands replace [rad].
    """

    readings: np.ndarray
    position_error_mm: np.ndarray
    orientation_error_deg: np.ndarray
    iterations: int
    reached: np.ndarray
    status: np.ndarray
    largest_change_deg: np.ndarray
    taught: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        """Rows whose command can be run as it is (status ``ok``)."""
        return self.status == "ok"

    def __repr__(self) -> str:
        """One line: how many poses, how many ok (or reached), the worst remaining error."""
        n_poses = len(self.reached)
        done = self.ok
        given = np.isfinite(self.position_error_mm)
        worst = (
            f", worst {np.max(self.position_error_mm[given]) * 1e3:.2g} um / "
            f"{np.max(self.orientation_error_deg[given]):.2g} deg"
            if given.any()
            else ""
        )
        steps = f"{self.iterations} Newton step{'s' if self.iterations != 1 else ''}"
        return f"Compensation({n_poses} pose{'s' if n_poses != 1 else ''}, {int(done.sum())} ok{worst}, {steps})"


@dataclass(frozen=True, slots=True, kw_only=True)
class CompensationSettings:
    """What :func:`compensate_commands` accepts as a command a controller can run.

    Attributes
    ----------
    max_change_deg : float
        Largest change of any joint from the taught reading [deg] in an ``ok`` row; a calibration moves joints by
        hundredths of a degree, so more means a singularity or another branch.
    position_tolerance_mm, orientation_tolerance_deg : float
        Largest remaining error of an ``ok`` row (the calibrated model at the command against the target).
    explained_ratio : float
        An ``ok`` row's correction moves the nominal tool by about the calibrated model's difference from the
        nominal one at the pose; more than this times that difference (plus 1 um) is ``large_correction``.
    max_iterations : int
        Newton steps per solve.
    """

    max_change_deg: float = 2.0
    position_tolerance_mm: float = 1e-6
    orientation_tolerance_deg: float = 1e-6
    explained_ratio: float = 2.0
    max_iterations: int = 200

    def __post_init__(self):
        for name in ("max_change_deg", "position_tolerance_mm", "orientation_tolerance_deg", "explained_ratio"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value) or value <= 0:
                raise InputError(f"compensation setting `{name}` must be a finite number > 0; got {value!r}")
        check_count(self.max_iterations, "max_iterations")


def _damped(parameters: ParameterSet, targets, taught, tool, max_change: float, iterations: int):
    """Damped least-squares commands near ``taught``: minimise ``|e(r)|^2 + mu^2 |r - taught|^2`` by Gauss-Newton, for
    the smallest ``mu`` of 1e-3, 1e-2, ... times the robot's size [mm/rad] that keeps every joint within
    ``max_change`` [rad] of ``taught``. ``e`` is the position error [mm] and the orientation error [rad] times 1 % of
    the robot's size: at a singularity the position is met and the orientation gives way."""
    robot = parameters.robot
    size = 0.01 * robot_size(robot)
    weight = np.r_[np.ones(3), np.full(3, size)][:, None]
    best = taught.copy()
    left = np.arange(len(taught))
    for factor in (1e-3, 1e-2, 1e-1, 1.0, 10.0):
        mu = factor * size
        readings, wanted, start = taught[left].copy(), targets[left], taught[left]
        for _ in range(min(iterations, 30)):
            frames, jacobian = tool_frames(parameters, readings, tool)
            error = np.concatenate(
                [
                    wanted[:, :3, 3] - frames[:, :3, 3],
                    size * rotation_vector(wanted[:, :3, :3] @ np.swapaxes(frames[:, :3, :3], 1, 2)),
                ],
                axis=1,
            )
            scaled = jacobian * weight
            normal = np.swapaxes(scaled, 1, 2) @ scaled + mu**2 * np.eye(robot.n_joints)
            gradient = (np.swapaxes(scaled, 1, 2) @ error[..., None])[..., 0] - mu**2 * (readings - start)
            step = np.linalg.solve(normal, gradient[..., None])[..., 0]
            readings = readings + step
            if np.abs(step).max() < 1e-13:
                break
        fits = np.abs(readings - start).max(axis=1) <= max_change
        best[left[fits]] = readings[fits]
        left = left[~fits]
        if left.size == 0:
            break
    return best


def _errors(parameters: ParameterSet, targets, readings, tool):
    frames = tool_frames(parameters, readings, tool)[0]
    position = np.linalg.norm(targets[:, :3, 3] - frames[:, :3, 3], axis=1)
    turn = rotation_vector(targets[:, :3, :3] @ np.swapaxes(frames[:, :3, :3], 1, 2))
    return position, np.degrees(np.linalg.norm(turn, axis=1))


def compensate_commands(
    parameters: ParameterSet,
    targets: ArrayLike,
    taught: ArrayLike,
    *,
    tool: ArrayLike | None = None,
    settings: CompensationSettings | None = None,
    progress: Callable[[int, int], object] | None = None,
) -> Compensation:
    """The command of every row, on the taught command's branch and near it, with its status (module notes).

    Parameters
    ----------
    parameters, targets
        The calibrated model and the target tool frames, as in :func:`robotcal.kinematics.inverse.solve_pose`.
    taught : array_like, shape (n_poses, n_joints)
        The readings the commands replace [rad]: the taught joint targets, or the nominal controller's solution of
        Cartesian targets. They choose the branch.
    tool : array_like, shape (3,) or (4, 4), optional
        The tool point or frame in the flange frame [mm] (default: the flange).
    settings : CompensationSettings, optional
    progress : callable, optional
        ``progress(done, total)`` after each block of :data:`BLOCK_ROWS` rows (the rows are solved a block at a
        time, so that memory stays bounded).

    Returns
    -------
    Compensation
        With ``status``, ``largest_change_deg`` and ``taught``; NaN readings where no command is given.
    """
    settings = settings or CompensationSettings()
    targets, taught = np.asarray(targets, dtype=float), np.asarray(taught, dtype=float)
    if len(targets) > BLOCK_ROWS or progress is not None:
        parts = []
        for start in range(0, len(targets), BLOCK_ROWS):
            rows = slice(start, start + BLOCK_ROWS)
            parts.append(compensate_commands(parameters, targets[rows], taught[rows], tool=tool, settings=settings))
            if progress is not None:
                progress(min(start + BLOCK_ROWS, len(targets)), len(targets))
        return _concatenate(parts)
    robot = parameters.robot
    targets, taught = check_targets(targets, taught, robot.n_joints, "taught")
    tool_frame = as_tool_frame(tool)
    tolerance = (settings.position_tolerance_mm, settings.orientation_tolerance_deg)
    max_change = np.radians(settings.max_change_deg)
    taught_branch = branch_of(robot, taught)

    # Newton from the taught readings: 97 % of random poses converge within 5 steps; what has not by 20 is solved
    # branch by branch below
    first_pass = min(settings.max_iterations, 20)
    solved = solve_pose(parameters, targets, taught, tool=tool_frame, max_iterations=first_pass)
    readings = wrap_readings(solved.readings, robot, taught)
    change = np.abs(readings - taught).max(axis=1)
    good = (
        solved.reached(*tolerance)
        & within_limits(robot, readings)
        & (change <= max_change)
        & (branch_of(robot, readings) == taught_branch)
    )
    status = np.where(good, "ok", "unreachable").astype(object)
    rest = np.flatnonzero(~good)
    if rest.size:
        readings[rest], status[rest] = _branch_by_branch(
            parameters, targets[rest], taught[rest], taught_branch[rest], tool_frame, settings
        )
    # an ok correction moves the nominal tool by about the calibrated model's difference from the nominal there
    ok = np.flatnonzero(status == "ok")
    if ok.size:
        status[ok[~_explained(parameters, taught[ok], readings[ok], tool_frame, settings)]] = "large_correction"
    given = np.all(np.isfinite(readings), axis=1)
    position = np.full(len(readings), np.nan)
    angle = np.full(len(readings), np.nan)
    if given.any():
        position[given], angle[given] = _errors(parameters, targets[given], readings[given], tool_frame)
    exact = given & (position <= tolerance[0]) & (angle <= tolerance[1])
    status[(status == "ok") & ~exact] = "near_singular"
    return Compensation(
        readings=readings,
        position_error_mm=position,
        orientation_error_deg=angle,
        iterations=solved.iterations,
        reached=exact,
        status=status.astype(str),
        largest_change_deg=np.degrees(np.where(given, np.abs(readings - taught).max(axis=1), np.nan)),
        taught=taught,
    )


def _explained(parameters: ParameterSet, taught, commands, tool, settings: CompensationSettings) -> np.ndarray:
    """Whether the commands move the nominal tool by no more than ``explained_ratio`` times the calibrated model's
    difference from the nominal one at ``taught`` (plus 1 um)."""
    return _moved(parameters, taught, commands, tool) <= (
        settings.explained_ratio * _moved(parameters, taught, None, tool) + 1e-3
    )


def _branch_by_branch(parameters: ParameterSet, targets, taught, taught_branch, tool, settings: CompensationSettings):
    """Readings ``(R, n)`` and statuses ``(R,)`` of the rows Newton's method from the taught readings did not bring
    to ``ok``: the calibrated solution of the taught branch, or of a neighbouring branch within ``max_change``
    (a boundary crossed: ``near_singular``); else the damped command or none (module notes)."""
    robot = parameters.robot
    count = len(targets)
    max_change = np.radians(settings.max_change_deg)
    # the taught branch, and the branches whose nominal solution lies within max_change (+ 5 deg for the
    # calibration) of the taught readings: the others cannot be picked
    nominal, _ = nominal_solutions(robot, targets @ np.linalg.inv(tool), reference=taught)
    near = np.abs(nominal - taught[:, None, :]).max(axis=-1) <= max_change + np.radians(5.0)
    near[np.arange(count), taught_branch] = True
    every = inverse_kinematics(
        parameters, targets, tool=tool, reference=taught, branches=near,
        position_tolerance_mm=settings.position_tolerance_mm,
        orientation_tolerance_deg=settings.orientation_tolerance_deg, max_iterations=settings.max_iterations,
    )  # fmt: skip
    nearest = wrap_readings(every.readings, robot, taught[:, None, :], prefer_limits=False)
    inside = within_limits(robot, nearest)
    branch_change = np.abs(nearest - taught[:, None, :]).max(axis=-1)  # (R, 8)
    on_branch = np.arange(8)[None, :] == taught_branch[:, None]
    close = every.reached & (branch_change <= max_change)
    # the taught branch's solution first, then a neighbouring branch's within max_change
    cost = np.where(close & inside, branch_change + np.where(on_branch, 0.0, 10.0), np.inf)
    pick = np.argmin(cost, axis=1)
    found = np.isfinite(cost[np.arange(count), pick])
    readings = np.full((count, robot.n_joints), np.nan)
    status = np.full(count, "unreachable", dtype=object)
    readings[found] = nearest[found, pick[found]]
    status[found] = np.where(on_branch[found, pick[found]], "ok", "near_singular")
    own = every.reached & on_branch  # the taught branch's exact solution, nearest turn
    outside = ~found & np.any(close | (own & ~inside), axis=1)  # near, or on the branch, only beyond a limit
    far = ~found & ~outside & np.any(own, axis=1)  # on the branch within the limits, but only by a large move
    status[outside] = "outside_limits"
    if np.any(far):
        exact = nearest[far][np.arange(int(far.sum())), taught_branch[far]]
        # a singularity turns a small move of the tool into a large joint move: the exact solution moves the
        # nominal tool by no more than the calibration explains; anything else is a correction too large
        status[far] = np.where(
            _explained(parameters, taught[far], exact, tool, settings), "near_singular", "large_correction"
        )
        readings[far] = _damped(parameters, targets[far], taught[far], tool, max_change, settings.max_iterations)
    return readings, status


def _concatenate(parts: list[Compensation]) -> Compensation:
    if not parts:
        raise InputError("no poses to compensate")
    return Compensation(
        readings=np.concatenate([p.readings for p in parts]),
        position_error_mm=np.concatenate([p.position_error_mm for p in parts]),
        orientation_error_deg=np.concatenate([p.orientation_error_deg for p in parts]),
        iterations=max(p.iterations for p in parts),
        reached=np.concatenate([p.reached for p in parts]),
        status=np.concatenate([p.status for p in parts]),
        largest_change_deg=np.concatenate([p.largest_change_deg for p in parts]),
        taught=np.concatenate([p.taught for p in parts]),
    )


def _moved(parameters: ParameterSet, taught, commands, tool) -> np.ndarray:
    """Per pose, how far the nominal tool moves from ``taught`` to ``commands`` (None: the calibrated model's
    difference from the nominal one at ``taught``): the larger of the distance [mm] and the rotation [rad] times the
    robot's size."""
    robot = parameters.robot
    nominal = ParameterSet.nominal(robot)
    reference = tool_frames(nominal, taught, tool)[0]
    moved = tool_frames(parameters, taught, tool)[0] if commands is None else tool_frames(nominal, commands, tool)[0]
    size = robot_size(robot)
    position = np.linalg.norm(moved[:, :3, 3] - reference[:, :3, 3], axis=1)
    turn = np.linalg.norm(rotation_vector(moved[:, :3, :3] @ np.swapaxes(reference[:, :3, :3], 1, 2)), axis=1)
    return np.maximum(position, size * turn)
