"""Batched rigid transforms: elementary rotations and translations, rotation about a line, checks.

Every function broadcasts over leading axes; the last axes are coordinates (``(..., 3)`` vectors,
``(..., 4, 4)`` homogeneous matrices). Lengths in mm, angles in radians.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError

__all__ = [
    "rot_x",
    "rot_y",
    "rot_z",
    "translation",
    "rotation_about_line",
    "invert_transform",
    "apply_transform",
    "nearest_rotation",
    "check_rigid_transform",
]


def _elementary(angle, axis: int) -> np.ndarray:
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(angle.shape + (4, 4))
    out[..., 3, 3] = 1.0
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def rot_x(angle: ArrayLike) -> np.ndarray:
    """Homogeneous rotation about x by ``angle`` [rad], shape ``angle.shape + (4, 4)``."""
    return _elementary(angle, 0)


def rot_y(angle: ArrayLike) -> np.ndarray:
    """Homogeneous rotation about y by ``angle`` [rad], shape ``angle.shape + (4, 4)``."""
    return _elementary(angle, 1)


def rot_z(angle: ArrayLike) -> np.ndarray:
    """Homogeneous rotation about z by ``angle`` [rad], shape ``angle.shape + (4, 4)``."""
    return _elementary(angle, 2)


def translation(vector: ArrayLike) -> np.ndarray:
    """Homogeneous translation by ``vector`` [mm], shape ``(..., 3) -> (..., 4, 4)``."""
    vector = np.asarray(vector, dtype=float)
    out = np.zeros(vector.shape[:-1] + (4, 4))
    out[..., [0, 1, 2, 3], [0, 1, 2, 3]] = 1.0
    out[..., :3, 3] = vector
    return out


def rotation_about_line(direction: ArrayLike, point: ArrayLike, angle: ArrayLike) -> np.ndarray:
    """Rigid transform that turns space by ``angle`` about the line through ``point`` along ``direction``.

    Right-handed about ``direction`` (Rodrigues' formula): ``T = Trans(p) Rot(S, angle) Trans(-p)``.

    Parameters
    ----------
    direction : array_like, shape (..., 3)
        Unit direction S of the line.
    point : array_like, shape (..., 3)
        Any point of the line [mm].
    angle : array_like, shape (...)
        Rotation angle [rad].

    Returns
    -------
    ndarray, shape (..., 4, 4)
    """
    s = np.asarray(direction, dtype=float)
    p = np.asarray(point, dtype=float)
    angle = np.asarray(angle, dtype=float)
    shape = np.broadcast_shapes(s.shape[:-1], p.shape[:-1], angle.shape)
    s = np.broadcast_to(s, shape + (3,))
    p = np.broadcast_to(p, shape + (3,))
    c, sn = np.cos(angle)[..., None, None], np.sin(angle)[..., None, None]
    skew = np.zeros(shape + (3, 3))
    skew[..., 0, 1], skew[..., 0, 2] = -s[..., 2], s[..., 1]
    skew[..., 1, 0], skew[..., 1, 2] = s[..., 2], -s[..., 0]
    skew[..., 2, 0], skew[..., 2, 1] = -s[..., 1], s[..., 0]
    rotation = c * np.eye(3) + sn * skew + (1.0 - c) * (s[..., :, None] * s[..., None, :])
    out = np.zeros(shape + (4, 4))
    out[..., :3, :3] = rotation
    out[..., :3, 3] = p - np.einsum("...ij,...j->...i", rotation, p)
    out[..., 3, 3] = 1.0
    return out


def invert_transform(transform: ArrayLike) -> np.ndarray:
    """Inverse of rigid transforms ``(..., 4, 4)`` using ``R^T`` (no general matrix inverse)."""
    transform = np.asarray(transform, dtype=float)
    rotation_t = np.swapaxes(transform[..., :3, :3], -1, -2)
    out = np.zeros_like(transform)
    out[..., :3, :3] = rotation_t
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rotation_t, transform[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def apply_transform(transform: ArrayLike, points: ArrayLike) -> np.ndarray:
    """Apply ``(..., 4, 4)`` transforms to ``(..., 3)`` points [mm] (broadcasting leading axes)."""
    transform = np.asarray(transform, dtype=float)
    points = np.asarray(points, dtype=float)
    return np.einsum("...ij,...j->...i", transform[..., :3, :3], points) + transform[..., :3, 3]


def nearest_rotation(matrix: ArrayLike) -> np.ndarray:
    """Nearest proper rotation (Frobenius norm) to ``(..., 3, 3)`` matrices, by SVD (polar factor)."""
    u, _, vt = np.linalg.svd(np.asarray(matrix, dtype=float))
    d = np.sign(np.linalg.det(u @ vt))
    u = u.copy()
    u[..., :, -1] *= d[..., None]
    return u @ vt


def check_rigid_transform(matrix: ArrayLike, name: str = "transform", *, tolerance: float = 1e-6) -> np.ndarray:
    """Return ``matrix`` as a float (4, 4) rigid transform, or raise :class:`InputError`.

    A rigid transform has a proper orthonormal rotation block (``|R^T R - I| <= tolerance``,
    ``det R > 0``), finite entries and last row ``[0, 0, 0, 1]``.
    """
    try:
        matrix = np.asarray(matrix, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"`{name}` must be a 4x4 numeric matrix; got {matrix!r}") from exc
    if matrix.shape != (4, 4):
        raise InputError(f"`{name}` must have shape (4, 4); got {matrix.shape}")
    if not np.all(np.isfinite(matrix)):
        raise InputError(f"`{name}` contains NaN or infinite values")
    if not np.allclose(matrix[3], [0.0, 0.0, 0.0, 1.0], atol=tolerance, rtol=0.0):
        raise InputError(f"`{name}` last row must be [0, 0, 0, 1]; got {matrix[3].tolist()}")
    rotation = matrix[:3, :3]
    deviation = float(np.max(np.abs(rotation.T @ rotation - np.eye(3))))
    if deviation > tolerance or np.linalg.det(rotation) <= 0.0:
        raise InputError(
            f"`{name}` is not a rigid transform: its rotation block deviates from orthonormal by "
            f"{deviation:.3g} (tolerance {tolerance:g}) or has det <= 0"
        )
    return matrix
