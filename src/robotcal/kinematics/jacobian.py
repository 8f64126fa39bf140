"""Analytic Jacobian of measured target positions with respect to the kinematic parameters.

Every elementary factor of a link ``A_j = Rz(theta_j + q_j) Tz(d_j) Tx(a_j) Rx(alpha_j) Ry(beta_j)``
(eqs 3-72, 3-82) is a screw motion about a line fixed in the base frame at the current
configuration, so the derivative of a point ``p`` carried by the later links is (base frame, 0-based
joint j, ``B = base_from_{j}`` the frame before the joint, ``F = base_from_{j+1}`` after it):

==========  =======================================================================
parameter   ``dp / dparameter``
==========  =======================================================================
``d``       ``z_B``                          (translation along the joint axis)
``theta``   ``z_B x (p - o_B)``              (rotation about the joint axis)
``a``       ``x'``, ``x' = cos(theta+q) x_B + sin(theta+q) y_B`` (common normal)
``alpha``   ``x' x (p - o_F)``               (rotation about the common normal)
``beta``    ``y_F x (p - o_F)``              (Hayati rotation about y of frame j+1)
==========  =======================================================================

A target of circle i with a per-joint reflector (``F_{i-1} Rz(q_i) r_i``, eq. 5-1) depends only on
the joints before i; its derivatives with respect to joint i and later are exactly zero. A flange
target depends on every joint. The result is exact (no finite differences); the tests check it
against central differences.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.geometry.transforms import apply_transform, rot_z
from robotcal.kinematics.forward import check_joint_variables, joint_frames
from robotcal.kinematics.model import ReflectorMount, check_parameter_array

__all__ = ["target_jacobian"]


def target_jacobian(
    parameters: ArrayLike,
    q: ArrayLike,
    turning_joint: ArrayLike,
    reflector: ReflectorMount,
    *,
    joint_variables: bool = False,
) -> tuple[np.ndarray, ...]:
    """Target positions and their derivatives with respect to every ``d, theta, a, alpha, beta``.

    Parameters
    ----------
    parameters : array_like, shape (..., n_joints, 5)
        One parameter set ``d, theta, a, alpha, beta`` [mm, rad], or a stack of them (Monte Carlo draws).
    q : array_like, shape (..., n_points, n_joints)
        Model joint variables of every point [rad]; leading axes broadcast against those of ``parameters``.
    turning_joint : array_like of int, shape (n_points,)
        0-based joint whose circle the point belongs to (used only by a per-joint reflector).
    reflector : ReflectorMount
        ``"joint"`` (one target per circle) or ``"flange"``.
    joint_variables : bool
        Also return ``d point / d q``.

    Returns
    -------
    points : ndarray, shape (..., n_points, 3)
        Target positions in the base frame [mm] (the same as :func:`target_positions`).
    jacobian : ndarray, shape (..., n_points, 3, n_joints, 5)
        ``d point / d parameter``: [mm/mm] for d and a, [mm/rad] for the angles.
    joint_jacobian : ndarray, shape (..., n_points, 3, n_joints)
        With ``joint_variables``: ``d point / d q_j`` [mm/rad], the theta column of every joint that moves the
        point (``theta_j + q_j`` is one angle), and for a per-joint target also of the joint that turns it.
    """
    parameters = np.asarray(parameters, dtype=float)
    if parameters.ndim < 2:
        raise InputError(
            f"`parameters` must be a set of shape (n_joints, 5) or a stack of them; got {parameters.shape}"
        )
    n = parameters.shape[-2]
    if parameters.ndim == 2:
        parameters = check_parameter_array(parameters, n)
        q = check_joint_variables(q, n)
    else:
        q = np.asarray(q, dtype=float)
        if q.shape[-1] != n or not np.all(np.isfinite(q)):
            raise InputError(f"`q` must be finite joint variables of shape (..., n_points, {n}); got {q.shape}")
    frames = joint_frames(parameters, q)  # (..., n_points, n + 1, 4, 4)
    n_points = frames.shape[-4]
    rows = np.arange(n_points)
    if reflector.frame == "flange":
        points = apply_transform(frames[..., -1, :, :], reflector.positions[0])
        active = np.ones((n_points, n), dtype=bool)
        moving = active
    else:
        if reflector.positions.shape[0] != n:
            raise InputError(f"a per-joint reflector needs {n} positions; got {reflector.positions.shape[0]}")
        turning_joint = np.asarray(turning_joint, dtype=int)
        if turning_joint.shape != (n_points,) or np.any((turning_joint < 0) | (turning_joint >= n)):
            raise InputError(
                f"`turning_joint` must hold {n_points} joint indices in 0..{n - 1} for a per-joint reflector"
            )
        turn = rot_z(np.broadcast_to(q, frames.shape[:-3] + (n,))[..., rows, turning_joint])
        carrier = frames[..., rows, turning_joint, :, :] @ turn
        points = apply_transform(carrier, reflector.positions[turning_joint])
        active = np.arange(n)[None, :] < turning_joint[:, None]
        moving = np.arange(n)[None, :] <= turning_joint[:, None]
    before = frames[..., :-1, :, :]  # (..., n_points, n, 4, 4): base_from_{j}
    after = frames[..., 1:, :, :]  # base_from_{j+1}
    x_b, y_b, z_b, o_b = (before[..., :3, k] for k in range(4))
    y_f, o_f = after[..., :3, 1], after[..., :3, 3]
    angle = parameters[..., None, :, 1] + q  # (..., n_points, n)
    x_common = np.cos(angle)[..., None] * x_b + np.sin(angle)[..., None] * y_b
    p = points[..., None, :]
    turning = np.cross(z_b, p - o_b)
    jacobian = np.stack(
        [z_b, turning, x_common, np.cross(x_common, p - o_f), np.cross(y_f, p - o_f)],
        axis=-1,
    )  # (..., n_points, n, 3, 5)
    jacobian = np.where(active[:, :, None, None], jacobian, 0.0)
    jacobian = np.ascontiguousarray(np.moveaxis(jacobian, -2, -3))
    if not joint_variables:
        return points, jacobian
    joint_jacobian = np.where(moving[:, :, None], turning, 0.0)
    return points, jacobian, np.ascontiguousarray(np.swapaxes(joint_jacobian, -1, -2))
