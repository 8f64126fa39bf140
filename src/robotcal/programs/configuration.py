"""Configuration data of a Cartesian target: which inverse-kinematics solution the controller is to take (issue 28).

A Cartesian target has up to eight solutions (:data:`robotcal.kinematics.inverse.BRANCH_NAMES`) and, for joints
that turn more than a full turn, several whole-turn variants of each. Controllers name the one they take:

KUKA ``S`` (status) and ``T`` (turn), from the controller axis values ``A1..A6`` (KUKA System Software 8.x,
Operating and Programming Instructions for System Integrators, "S and T"):

- ``S`` bit 0: the wrist root point (where the axes of A4, A5, A6 meet) has a negative x in the A1 coordinate system
  (the robot's base frame turned with A1: "overhead area"); bit 1: A3 at or above the angle ``phi`` at which the arm
  is stretched (the wrist root on the line through the axes of A2 and A3), the usual elbow-up working pose, whose
  programs carry ``S 'B010'`` (2) or ``'B110'`` (6); bit 2: A5 negative (in ``[-180, 0)``).
- ``T`` bit ``i - 1``: axis ``Ai`` negative.

ABB ``confdata [cf1, cf4, cf6, cfx]`` (Technical reference manual - RAPID Instructions, Functions and Data types,
"confdata"): ``cf1``, ``cf4``, ``cf6`` the quadrants of axes 1, 4 and 6 (``floor(angle / 90 deg)``: 0 for
``[0, 90)``, -1 for ``[-90, 0)``...), ``cfx = 4 (wrist centre behind axis 1) + 2 (wrist centre behind the lower arm)
+ (axis 5 negative)``, "in front" being the side the robot has at its calibration position.

The geometry (wrist centre, arm plane) is that of the robot's nominal model at the controller's readings; the
readings are the controller's (a robot file with the controller's reading signs, e.g.
``kuka-kr5-sixx-r650-krc``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.kinematics.forward import joint_frames
from robotcal.kinematics.inverse import wrist_centre_in_flange
from robotcal.kinematics.model import RobotModel

__all__ = ["CONFIG_KEYS", "configuration", "kuka_status_turn", "abb_confdata"]

#: The configuration entries of each language (URScript has none).
CONFIG_KEYS = {"krl": ("S", "T"), "rapid": ("cf1", "cf4", "cf6", "cfx"), "urscript": ()}


def _geometry(controller: RobotModel, readings: np.ndarray):
    """Per pose: the wrist centre's x in the A1 coordinate system, and its side of the lower arm (the cross product
    of axis 2 -> axis 3 and axis 2 -> wrist centre along axis 2's direction) [mm, mm^2]."""
    q = controller.model_joint_variables(readings)
    frames = joint_frames(controller.nominal, q)  # (P, n + 1, 4, 4)
    wrist = (frames[:, -1] @ wrist_centre_in_flange(controller))[:, :3]
    zero_q = controller.model_joint_variables(np.zeros(controller.n_joints))
    turn = q[:, 0] - zero_q[0]  # J1 from its zero reading
    x_axis = np.stack([np.cos(turn), np.sin(turn), np.zeros_like(turn)], axis=-1)  # the A1 system's x
    forward = np.einsum("pi,pi->p", wrist, x_axis)
    axis2, axis3 = frames[:, 1, :3, 3], frames[:, 2, :3, 3]
    side = np.einsum("pi,pi->p", np.cross(axis3 - axis2, wrist - axis2), frames[:, 1, :3, 2])
    return forward, side


def _key(robot: RobotModel) -> tuple:
    return (robot.name, robot.nominal.tobytes(), robot.reading_matrix.tobytes(), robot.reading_offset.tobytes())


_STRETCHED: dict[tuple, float] = {}


def _stretched_a3(controller: RobotModel) -> float:
    """The A3 reading [rad] at which the wrist centre lies on the line through the axes of A2 and A3, beyond A3
    (computed once per robot geometry and reading map)."""
    key = _key(controller)
    if key not in _STRETCHED:
        _STRETCHED[key] = _search_stretched_a3(controller)
    return _STRETCHED[key]


def _search_stretched_a3(controller: RobotModel) -> float:
    readings = np.zeros((721, controller.n_joints))
    readings[:, 2] = np.linspace(-np.pi, np.pi, 721)
    q = controller.model_joint_variables(readings)
    frames = joint_frames(controller.nominal, q)
    wrist = (frames[:, -1] @ wrist_centre_in_flange(controller))[:, :3]
    axis2, axis3 = frames[:, 1, :3, 3], frames[:, 2, :3, 3]
    along = np.einsum("pi,pi->p", axis3 - axis2, wrist - axis2)
    reach = np.linalg.norm(wrist - axis2, axis=1)
    best = int(np.argmax(np.where(along > 0, reach, -np.inf)))
    # refine the maximum of the reach by a parabola through the neighbours
    lo, hi = max(best - 1, 0), min(best + 1, 720)
    x, y = readings[[lo, best, hi], 2], reach[[lo, best, hi]]
    denominator = y[0] - 2 * y[1] + y[2]
    step = x[1] - x[0]
    return float(x[1] + (0.5 * step * (y[0] - y[2]) / denominator if denominator != 0 else 0.0))


def kuka_status_turn(controller: RobotModel, readings: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """KUKA ``S`` and ``T`` (module notes) of controller readings ``(P, 6)`` [rad]."""
    readings = np.atleast_2d(np.asarray(readings, dtype=float))
    forward, _ = _geometry(controller, readings)
    phi = _stretched_a3(controller)
    a3_above = np.angle(np.exp(1j * (readings[:, 2] - phi))) >= 0
    a5 = np.angle(np.exp(1j * readings[:, 4]))
    status = (forward < 0).astype(int) + 2 * a3_above.astype(int) + 4 * (a5 < 0).astype(int)
    turn = ((readings < 0).astype(int) * (2 ** np.arange(readings.shape[1]))).sum(axis=1)
    return status, turn


def abb_confdata(controller: RobotModel, readings: ArrayLike) -> np.ndarray:
    """ABB ``[cf1, cf4, cf6, cfx]`` (module notes) of controller readings ``(P, 6)`` [rad], shape (P, 4)."""
    readings = np.atleast_2d(np.asarray(readings, dtype=float))
    forward, side = _geometry(controller, readings)
    _, side_at_zero = _geometry(controller, np.zeros((1, controller.n_joints)))
    behind_arm = np.sign(side) != np.sign(side_at_zero[0])
    quadrant = np.floor(np.degrees(readings[:, [0, 3, 5]]) / 90.0 + 1e-9).astype(int)
    a5 = np.angle(np.exp(1j * readings[:, 4]))
    cfx = 4 * (forward < 0).astype(int) + 2 * behind_arm.astype(int) + (a5 < 0).astype(int)
    return np.column_stack([quadrant, cfx])


def configuration(language: str, controller: RobotModel, readings: ArrayLike) -> list[dict[str, int]]:
    """The configuration entries of ``language`` (:data:`CONFIG_KEYS`) for each pose of controller ``readings``."""
    if language not in CONFIG_KEYS:
        raise InputError(f"unknown program language {language!r}; choose one of {', '.join(CONFIG_KEYS)}")
    readings = np.atleast_2d(np.asarray(readings, dtype=float))
    if language == "krl":
        status, turn = kuka_status_turn(controller, readings)
        return [{"S": int(s), "T": int(t)} for s, t in zip(status, turn, strict=True)]
    if language == "rapid":
        values = abb_confdata(controller, readings)
        return [dict(zip(CONFIG_KEYS["rapid"], (int(v) for v in row), strict=True)) for row in values]
    return [{} for _ in readings]
