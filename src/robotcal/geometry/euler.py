"""KUKA A, B, C orientation angles from rotation matrices and back, batched.

KUKA controllers give a tool orientation as three angles A, B, C with

``R = Rz(A) Ry(B) Rx(C)``

i.e. A about Z, then B about the new Y, then C about the newest X (intrinsic Z-Y'-X''; the same
matrix as the extrinsic rotations C about the fixed X, B about the fixed Y, A about the fixed Z).
In ``scipy.spatial.transform.Rotation`` terms this is ``as_euler("ZYX")`` giving ``(A, B, C)``.

The thesis's Table 5.8 lists the angles in X, Y, Z order (its "A, B, C" columns are the rotations
about X, Y, Z, i.e. KUKA C, B, A; docs/conventions.md "TCP"). :func:`thesis_order` reorders.

Angles in radians; ranges A, C in (-pi, pi], B in [-pi/2, pi/2]. At the gimbal lock
(B = +-90 deg) only A -+ C is determined; robotcal then sets C = 0.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError

__all__ = ["GIMBAL_TOLERANCE", "kuka_abc_from_matrix", "matrix_from_kuka_abc", "thesis_order", "wrap_angle_near"]

#: ``cos(B)`` below which the rotation is treated as gimbal-locked (|B| within ~1e-9 rad of 90 deg).
GIMBAL_TOLERANCE = 1e-9


def _check_rotations(rotation) -> np.ndarray:
    try:
        rotation = np.asarray(rotation, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError("`rotation` must be numeric") from exc
    if rotation.ndim < 2 or rotation.shape[-2:] not in ((3, 3), (4, 4)):
        raise InputError(f"`rotation` must have shape (..., 3, 3) or (..., 4, 4); got {rotation.shape}")
    return rotation[..., :3, :3]


def kuka_abc_from_matrix(rotation: ArrayLike) -> np.ndarray:
    """KUKA ``A, B, C`` [rad] of rotation matrices, ``R = Rz(A) Ry(B) Rx(C)``.

    Parameters
    ----------
    rotation : array_like, shape (..., 3, 3) or (..., 4, 4)
        Rotation matrices (the upper-left 3x3 block of a homogeneous transform is used).

    Returns
    -------
    ndarray, shape (..., 3)
        ``A`` (about Z) in (-pi, pi], ``B`` (about Y) in [-pi/2, pi/2], ``C`` (about X) in (-pi, pi].

    Notes
    -----
    With ``r_ij`` the entries of ``R``: ``A = atan2(r10, r00)``, ``B = atan2(-r20, hypot(r00, r10))``,
    ``C = atan2(r21, r22)``. Where ``hypot(r00, r10) < GIMBAL_TOLERANCE`` (B = +-90 deg), C = 0 and
    ``A = atan2(-r01, r11)``.
    """
    r = _check_rotations(rotation)
    cos_b = np.hypot(r[..., 0, 0], r[..., 1, 0])
    b = np.arctan2(-r[..., 2, 0], cos_b)
    a = np.arctan2(r[..., 1, 0], r[..., 0, 0])
    c = np.arctan2(r[..., 2, 1], r[..., 2, 2])
    locked = cos_b < GIMBAL_TOLERANCE
    if np.any(locked):
        a = np.where(locked, np.arctan2(-r[..., 0, 1], r[..., 1, 1]), a)
        c = np.where(locked, 0.0, c)
    return np.stack([a, b, c], axis=-1)


def matrix_from_kuka_abc(abc: ArrayLike) -> np.ndarray:
    """Rotation matrices ``Rz(A) Ry(B) Rx(C)`` from KUKA angles ``abc (..., 3)`` [rad] -> ``(..., 3, 3)``."""
    abc = np.asarray(abc, dtype=float)
    if abc.ndim < 1 or abc.shape[-1] != 3:
        raise InputError(f"`abc` must have shape (..., 3) (A, B, C); got {abc.shape}")
    ca, sa = np.cos(abc[..., 0]), np.sin(abc[..., 0])
    cb, sb = np.cos(abc[..., 1]), np.sin(abc[..., 1])
    cc, sc = np.cos(abc[..., 2]), np.sin(abc[..., 2])
    out = np.empty(abc.shape[:-1] + (3, 3))
    out[..., 0, 0] = ca * cb
    out[..., 0, 1] = ca * sb * sc - sa * cc
    out[..., 0, 2] = ca * sb * cc + sa * sc
    out[..., 1, 0] = sa * cb
    out[..., 1, 1] = sa * sb * sc + ca * cc
    out[..., 1, 2] = sa * sb * cc - ca * sc
    out[..., 2, 0] = -sb
    out[..., 2, 1] = cb * sc
    out[..., 2, 2] = cb * cc
    return out


def thesis_order(abc: ArrayLike) -> np.ndarray:
    """KUKA ``(A, B, C)`` -> the thesis's X, Y, Z order ``(C, B, A)`` (Table 5.8), ``(..., 3)``."""
    abc = np.asarray(abc, dtype=float)
    return abc[..., ::-1]


def wrap_angle_near(angle: ArrayLike, reference: ArrayLike) -> np.ndarray:
    """``angle`` shifted by a multiple of 2 pi to lie within (-pi, pi] of ``reference`` [rad].

    Used before averaging angles of Monte Carlo draws: draws of C = 179.9 deg and -179.9 deg are
    0.2 deg apart, not 359.8 deg.
    """
    angle = np.asarray(angle, dtype=float)
    reference = np.asarray(reference, dtype=float)
    return reference - np.remainder(reference - angle + np.pi, 2.0 * np.pi) + np.pi
