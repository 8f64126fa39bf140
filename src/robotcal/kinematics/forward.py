"""Batched forward kinematics of the hybrid DH / Hayati model (eqs 3-72, 3-82, 3-84).

One code path serves one pose and one parameter set, many poses, and a Monte Carlo batch of
parameter sets: ``parameters (..., n_joints, 5)`` and ``q (n_poses, n_joints)`` give
``(..., n_poses, 4, 4)``. Lengths in mm, angles in radians; ``q`` are *model* joint variables
(see :meth:`RobotModel.model_joint_variables` for controller readings).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.geometry.transforms import apply_transform, rot_z
from robotcal.kinematics.reflector import ReflectorMount

__all__ = [
    "link_transforms",
    "joint_frames",
    "forward_kinematics",
    "probe_rotations",
    "target_positions",
    "check_joint_variables",
]


def check_joint_variables(q: ArrayLike, n_joints: int, name: str = "q") -> np.ndarray:
    """Coerce ``q`` to float ``(n_poses, n_joints)`` (a single pose becomes a batch of one)."""
    try:
        q = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"`{name}` must be numeric") from exc
    if q.ndim == 1:
        q = q[None, :]
    if q.ndim != 2 or q.shape[1] != n_joints:
        raise InputError(f"`{name}` must have shape (n_poses, {n_joints}); got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise InputError(f"`{name}` contains NaN or infinite joint values")
    return q


def link_transforms(parameters: ArrayLike, q: ArrayLike) -> np.ndarray:
    """Link transforms ``A_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)``.

    With beta = 0 this is the DH matrix of eq. 3-72; with d = 0 the Hayati matrix of eq. 3-82
    (read as the factor product, docs/conventions.md). The model fixes the unused parameter at 0, so a
    single formula serves both joint types.

    Parameters
    ----------
    parameters : array_like, shape (..., n_joints, 5)
        ``d, theta, a, alpha, beta`` [mm, rad].
    q : array_like, shape (n_poses, n_joints)
        Model joint variables [rad].

    Returns
    -------
    ndarray, shape (..., n_poses, n_joints, 4, 4)
        ``{i-1}_from_{i}`` for every pose and joint.
    """
    parameters = np.asarray(parameters, dtype=float)
    q = np.asarray(q, dtype=float)
    p = parameters[..., None, :, :]
    d, theta, a, alpha, beta = (p[..., k] for k in range(5))
    angle = theta + q
    ct, st = np.cos(angle), np.sin(angle)
    ca, sa = np.cos(alpha), np.sin(alpha)
    cb, sb = np.cos(beta), np.sin(beta)
    # columns of Rz(theta+q) Rx(alpha): x = (ct, st, 0), y = (-st ca, ct ca, sa), z = (st sa, -ct sa, ca)
    out = np.zeros(np.broadcast_shapes(angle.shape, d.shape) + (4, 4))
    x = (ct, st, 0.0)
    z = (st * sa, -ct * sa, ca)
    for row in range(3):
        out[..., row, 0] = cb * x[row] - sb * z[row]
        out[..., row, 2] = sb * x[row] + cb * z[row]
    out[..., 0, 1] = -st * ca
    out[..., 1, 1] = ct * ca
    out[..., 2, 1] = sa
    out[..., 0, 3] = a * ct
    out[..., 1, 3] = a * st
    out[..., 2, 3] = d
    out[..., 3, 3] = 1.0
    return out


def _chain(links: np.ndarray, keep_all: bool) -> np.ndarray:
    current = np.broadcast_to(np.eye(4), links.shape[:-3] + (4, 4)).copy()
    frames = [current]
    for i in range(links.shape[-3]):
        current = current @ links[..., i, :, :]
        if keep_all:
            frames.append(current)
    return np.stack(frames, axis=-3) if keep_all else current


def joint_frames(parameters: ArrayLike, q: ArrayLike, *, joint_errors: ArrayLike | None = None) -> np.ndarray:
    """All DH frames ``base_from_link_i`` for i = 0..n, shape ``(..., n_poses, n_joints + 1, 4, 4)``.

    ``joint_errors`` (optional, ``(n_poses, n_joints, 4, 4)`` or broadcastable) are rigid error
    transforms ``E_i`` applied in frame {i-1} before joint i turns, as the generator's
    ``G_Zi = RT_err`` of eqs 5-3/5-4: the link becomes ``E_i A_i``.
    """
    links = link_transforms(parameters, q)
    if joint_errors is not None:
        links = np.asarray(joint_errors, dtype=float) @ links
    return _chain(links, keep_all=True)


def forward_kinematics(parameters: ArrayLike, q: ArrayLike) -> np.ndarray:
    """Flange pose ``base_from_flange = A_1 ... A_n`` (eq. 3-84), shape ``(..., n_poses, 4, 4)``.

    Parameters
    ----------
    parameters : array_like, shape (..., n_joints, 5)
        One set ``(n_joints, 5)`` or a batch ``(n_sets, n_joints, 5)`` [mm, rad].
    q : array_like, shape (n_poses, n_joints)
        Model joint variables [rad].
    """
    parameters = np.asarray(parameters, dtype=float)
    q = check_joint_variables(q, parameters.shape[-2])
    return _chain(link_transforms(parameters, q), keep_all=False)


def probe_rotations(parameters: ArrayLike, q: ArrayLike, probe_rotation: ArrayLike, tracker: ArrayLike) -> np.ndarray:
    """Orientation of a 6-DoF probe in the tracker frame, ``R_T F_n R_P`` per pose (issue 29), ``(n_poses, 3, 3)``.

    ``F_n`` the flange rotation of :func:`forward_kinematics` at one parameter set ``(n_joints, 5)`` [mm, rad]
    and model joint variables ``q (n_poses, n_joints)`` [rad]; ``R_P`` (``probe_rotation``, 3 x 3) the probe frame's
    rotation in the flange frame {n}; ``R_T`` the rotation block of ``tracker`` (``tracker_from_base``, 3 x 3 or
    4 x 4): one frame for every pose, or ``(n_poses, ...)`` each pose's (its session's).
    """
    flange = forward_kinematics(parameters, q)[..., :3, :3]
    tracker_rotation = np.asarray(tracker, dtype=float)[..., :3, :3]
    return tracker_rotation @ flange @ np.asarray(probe_rotation, dtype=float)


def target_positions(
    parameters: ArrayLike,
    q: ArrayLike,
    turning_joint: ArrayLike,
    reflector: ReflectorMount,
    *,
    joint_errors: ArrayLike | None = None,
) -> np.ndarray:
    """Positions of the measured target in the base frame [mm], one per capture point.

    Parameters
    ----------
    parameters : array_like, shape (..., n_joints, 5)
    q : array_like, shape (n_points, n_joints)
        Model joint variables of every point [rad].
    turning_joint : array_like of int, shape (n_points,)
        0-based index of the joint whose circle the point belongs to.
    reflector : ReflectorMount
        ``"joint"``: ``F_{i-1} E_i Rz(q_i) r_i`` (eq. 5-1); ``"flange"``: ``F_n r``.
    joint_errors : array_like, shape (..., n_points, n_joints, 4, 4), optional
        Error transforms ``E_i`` (see :func:`joint_frames`); leading axes (e.g. Monte Carlo draws)
        broadcast against those of ``parameters``.

    Returns
    -------
    ndarray, shape (..., n_points, 3)
    """
    parameters = np.asarray(parameters, dtype=float)
    n_joints = parameters.shape[-2]
    q = check_joint_variables(q, n_joints)
    turning_joint = np.asarray(turning_joint, dtype=int)
    frames = joint_frames(parameters, q, joint_errors=joint_errors)
    if reflector.frame == "flange":
        return apply_transform(frames[..., -1, :, :], reflector.positions[0])
    if reflector.positions.shape[0] != n_joints:
        raise InputError(f"a per-joint reflector needs {n_joints} positions; got {reflector.positions.shape[0]}")
    points = np.arange(q.shape[0])
    before = frames[..., points, turning_joint, :, :]
    turn = rot_z(q[points, turning_joint])
    if joint_errors is not None:
        turn = np.asarray(joint_errors, dtype=float)[..., points, turning_joint, :, :] @ turn
    return apply_transform(before @ turn, reflector.positions[turning_joint])
