"""Compensation: the joint commands with which the calibrated robot reaches the poses it was taught (issue 22).

A program taught on the nominal model (or written as Cartesian targets) sends joint commands that put the real
robot somewhere else: its geometry differs from the nominal one and its joints sag under gravity and carry
periodic angle errors (:mod:`robotcal.kinematics.joint_model`). Knowing the calibrated model, the controller can be
sent other commands instead, those at which the *calibrated* model's tool frame is the intended one (thesis
ch. 6.2, the compensation of joint errors left as future work).

For every target frame ``T*`` the commands ``r`` (controller readings) solve ``F(q(r) + delta(q(r))) X = T*``,
``F`` the calibrated chain, ``delta`` its joint model, ``X`` the tool. Newton's method, all poses at once: the
error is ``e = (p* - p, L rotvec(R* R^T))`` (position [mm]; orientation as a rotation vector [rad] times the
robot's size L, so that both parts are in mm) and the step solves ``J dr = e`` in the least-squares sense (per
pose, by pseudo-inverse: a square J is solved exactly, a redundant robot takes the smallest step), ``J`` the geometric
Jacobian of the tool frame in the joint variables (columns ``(z_i x (p - o_i), z_i)``) through the reading map.
The joint model's own dependence on q (``d delta / d q``, about ``k dtau/dq ~ 1e-3`` or a harmonic amplitude) is
left out of J: the iteration contracts by that factor per step instead of quadratically, reaching 1e-12 mm in a
handful of steps. Near a singularity a Newton step can raise the error: each pose then damps its own step
(Levenberg-Marquardt, ``(J^T J + lambda diag(J^T J)) dr = J^T e``, lambda from 1e-3 up by 10 until the error
falls, back down by 10 after each accepted step).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotcal.errors import InputError
from robotcal.kinematics.forward import joint_frames
from robotcal.kinematics.model import ParameterSet

__all__ = ["Compensation", "rotation_vector", "solve_commands", "tool_frames"]

#: What a compensated pose must meet: the issue's 1 um and 1e-4 deg.
POSITION_TOLERANCE_MM = 1e-3
ORIENTATION_TOLERANCE_DEG = 1e-4


@dataclass(frozen=True, slots=True, kw_only=True)
class Compensation:
    """Compensated commands and how close they bring the calibrated model to every target.

    Attributes
    ----------
    readings : ndarray, shape (n_poses, n_joints)
        Controller readings to command [rad].
    position_error_mm, orientation_error_deg : ndarray, shape (n_poses,)
        Remaining distance and rotation between the calibrated tool frame at ``readings`` and the target.
    iterations : int
        Newton steps taken (the slowest pose's).
    reached : ndarray of bool, shape (n_poses,)
        Within :data:`POSITION_TOLERANCE_MM` and :data:`ORIENTATION_TOLERANCE_DEG`.
    """

    readings: np.ndarray
    position_error_mm: np.ndarray
    orientation_error_deg: np.ndarray
    iterations: int
    reached: np.ndarray

    def __repr__(self) -> str:
        """One line: how many poses, how many reached, the worst remaining error."""
        n_poses = len(self.reached)
        worst = (
            f", worst {self.position_error_mm.max() * 1e3:.2g} um / {self.orientation_error_deg.max():.2g} deg" if n_poses else ""
        )
        return f"Compensation({n_poses} poses, {int(self.reached.sum())} reached{worst}, {self.iterations} Newton steps)"


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """The rotation vector (axis times angle, [rad]) of rotation matrices ``(..., 3, 3)``, angles in [0, pi]."""
    rotation = np.asarray(rotation, dtype=float)
    axial = 0.5 * np.stack(
        [
            rotation[..., 2, 1] - rotation[..., 1, 2],
            rotation[..., 0, 2] - rotation[..., 2, 0],
            rotation[..., 1, 0] - rotation[..., 0, 1],
        ],
        axis=-1,
    )  # sin(angle) axis
    sine = np.linalg.norm(axial, axis=-1)
    cosine = np.clip(0.5 * (np.trace(rotation, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    angle = np.arctan2(sine, cosine)
    small = sine < 1e-12
    factor = np.where(small, 1.0, angle / np.where(small, 1.0, sine))
    out = axial * factor[..., None]
    near_pi = small & (cosine < 0.0)  # 180 deg: the axis from the symmetric part
    if np.any(near_pi):
        symmetric = 0.5 * (rotation[near_pi] + np.eye(3))
        axis = np.sqrt(np.clip(np.diagonal(symmetric, axis1=-2, axis2=-1), 0.0, None))
        column = np.argmax(axis, axis=-1)
        picked = symmetric[np.arange(column.size), :, column]
        axis = picked / np.linalg.norm(picked, axis=-1, keepdims=True)
        out[near_pi] = axis * np.pi
    return out


def tool_frames(parameters: ParameterSet, readings: np.ndarray, tool: np.ndarray):
    """Tool frames ``(P, 4, 4)`` of the calibrated model (its joint model included) at ``readings`` ``(P, n)``
    [rad], and their Jacobian ``(P, 6, n)`` in the readings: rows translation [mm/rad] then rotation [rad/rad]. The
    Jacobian is the chain's at the deflected joints; the deflection's own derivative (the gravity torque's change
    with q times a compliance, ~1e-4 of a joint's turn) is left out, which slows Newton's convergence by nothing
    measurable."""
    robot = parameters.robot
    q = parameters.model_joint_variables(readings)
    frames = joint_frames(parameters.values, q)  # (P, n + 1, 4, 4)
    tool_frame = frames[:, -1] @ tool
    point = tool_frame[:, :3, 3]
    axes, origins = frames[:, :-1, :3, 2], frames[:, :-1, :3, 3]  # z_{i-1}, o_{i-1}
    jacobian = np.concatenate([np.cross(axes, point[:, None] - origins), axes], axis=-1)  # (P, n, 6)
    # d q / d reading: the reading map (q = M^-1 reading + offset)
    to_model = robot.model_joint_variables(np.eye(robot.n_joints)) - robot.model_joint_variables(
        np.zeros((1, robot.n_joints))
    )  # row k: dq / d reading_k
    return tool_frame, np.swapaxes(to_model @ jacobian, 1, 2)


def solve_commands(
    parameters: ParameterSet,
    targets,
    start_readings,
    *,
    tool=None,
    max_iterations: int = 50,
) -> Compensation:
    """Controller readings at which the calibrated model's tool frame is each target frame (module notes).

    Parameters
    ----------
    parameters : ParameterSet
        The calibrated model (geometric, or extended with its joint model).
    targets : array_like, shape (n_poses, 4, 4)
        Target tool frames in the robot base frame [mm].
    start_readings : array_like, shape (n_poses, n_joints)
        Where each pose's iteration starts [rad] (the taught commands, or a seed near the wanted branch).
    tool : array_like, shape (3,) or (4, 4), optional
        The tool point [mm] or frame in the flange frame (default: the flange).
    max_iterations : int

    Returns
    -------
    Compensation
    """
    robot = parameters.robot
    targets = np.asarray(targets, dtype=float)
    readings = np.array(start_readings, dtype=float)
    if targets.ndim != 3 or targets.shape[1:] != (4, 4) or not np.all(np.isfinite(targets)):
        raise InputError(f"`targets` must be finite frames of shape (n_poses, 4, 4); got {targets.shape}")
    if readings.shape != (targets.shape[0], robot.n_joints) or not np.all(np.isfinite(readings)):
        raise InputError(f"`start_readings` must be finite, shape ({targets.shape[0]}, {robot.n_joints})")
    tool_frame = np.eye(4)
    if tool is not None:
        tool = np.asarray(tool, dtype=float)
        if tool.shape == (3,):
            tool_frame[:3, 3] = tool
        elif tool.shape == (4, 4):
            tool_frame = tool
        else:
            raise InputError(f"`tool` must be a point (3,) or a frame (4, 4) [mm]; got shape {tool.shape}")
    size = max(float(np.abs(robot.nominal[:, [0, 2]]).sum()), 1.0)  # the robot's size [mm]: orientation in mm

    def error(frames, rows):
        position = targets[rows, :3, 3] - frames[:, :3, 3]
        turn = rotation_vector(targets[rows, :3, :3] @ np.swapaxes(frames[:, :3, :3], 1, 2))
        return np.concatenate([position, size * turn], axis=1)

    every = np.arange(targets.shape[0])
    weight = np.r_[np.ones(3), np.full(3, size)][:, None]
    frames, jacobian = tool_frames(parameters, readings, tool_frame)
    residual = error(frames, every)
    cost = np.einsum("pk,pk->p", residual, residual)
    damping = np.zeros(targets.shape[0])
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        active = np.flatnonzero((cost > (1e-11 * size) ** 2) & (damping < 1e12))  # converged, or no step helps
        if active.size == 0:
            iterations -= 1
            break
        scaled = jacobian[active] * weight  # (A, 6, n)
        normal = np.swapaxes(scaled, 1, 2) @ scaled
        gradient = (np.swapaxes(scaled, 1, 2) @ residual[active][..., None])[..., 0]
        diagonal = np.einsum("pii->pi", normal)
        system = normal + damping[active, None, None] * (diagonal[:, :, None] * np.eye(normal.shape[-1]))
        step = (np.linalg.pinv(system) @ gradient[..., None])[..., 0]
        trial = readings[active] + step
        trial_frames, trial_jacobian = tool_frames(parameters, trial, tool_frame)
        trial_residual = error(trial_frames, active)
        trial_cost = np.einsum("pk,pk->p", trial_residual, trial_residual)
        better = trial_cost < cost[active]
        kept = active[better]
        readings[kept], jacobian[kept], residual[kept], cost[kept] = (
            trial[better], trial_jacobian[better], trial_residual[better], trial_cost[better]
        )
        damping[kept] = np.where(damping[kept] > 1e-9, damping[kept] / 10.0, 0.0)
        worse = active[~better]
        damping[worse] = np.where(damping[worse] > 0.0, damping[worse] * 10.0, 1e-3)
    frames = tool_frames(parameters, readings, tool_frame)[0]
    position = np.linalg.norm(targets[:, :3, 3] - frames[:, :3, 3], axis=1)
    angle = np.degrees(np.linalg.norm(rotation_vector(targets[:, :3, :3] @ np.swapaxes(frames[:, :3, :3], 1, 2)), axis=1))
    return Compensation(
        readings=readings,
        position_error_mm=position,
        orientation_error_deg=angle,
        iterations=iterations,
        reached=(position <= POSITION_TOLERANCE_MM) & (angle <= ORIENTATION_TOLERANCE_DEG),
    )
