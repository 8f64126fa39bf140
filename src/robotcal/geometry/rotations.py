"""Rotations as rotation vectors and back, and the small-rotation algebra of SO(3), batched.

A rotation vector ``v`` (axis times angle, ``|v| <= pi``) [rad] and its matrix ``R = exp([v]x)``: the orientation
residual of a 6-DoF probe is ``e = log(R_measured^T R_model)`` (issue 29), and a body-frame turn ``delta`` of the
model changes it by ``J_r^-1(e) delta`` (``J_r`` the right Jacobian of SO(3)), exactly at ``e = 0``. The log and
exp are those of :class:`scipy.spatial.transform.Rotation` (imported on first use).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError

__all__ = ["rotation_vectors", "rotation_matrices", "vee", "inverse_right_jacobian"]


def rotation_vectors(rotations: ArrayLike) -> np.ndarray:
    """Rotation vectors (axis times angle, ``|v| <= pi``) ``(..., 3)`` of rotation matrices ``(..., 3, 3)`` [rad]
    (the log of SO(3))."""
    from scipy.spatial.transform import Rotation

    rotations = np.asarray(rotations, dtype=float)
    if rotations.shape[-2:] != (3, 3):
        raise InputError(f"rotations must have shape (..., 3, 3); got {rotations.shape}")
    flat = rotations.reshape(-1, 3, 3)
    return Rotation.from_matrix(flat).as_rotvec().reshape(rotations.shape[:-2] + (3,))


def rotation_matrices(vectors: ArrayLike) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of rotation vectors ``(..., 3)`` [rad] (the exp of SO(3))."""
    from scipy.spatial.transform import Rotation

    vectors = np.asarray(vectors, dtype=float)
    if vectors.shape[-1:] != (3,):
        raise InputError(f"rotation vectors must have shape (..., 3); got {vectors.shape}")
    return Rotation.from_rotvec(vectors.reshape(-1, 3)).as_matrix().reshape(vectors.shape[:-1] + (3, 3))


def vee(matrices: np.ndarray) -> np.ndarray:
    """The vector ``w`` of the skew part of ``(..., 3, 3)`` matrices, ``[w]x = (M - M^T) / 2``."""
    return 0.5 * np.stack(
        [
            matrices[..., 2, 1] - matrices[..., 1, 2],
            matrices[..., 0, 2] - matrices[..., 2, 0],
            matrices[..., 1, 0] - matrices[..., 0, 1],
        ],
        axis=-1,
    )


def _skew(vectors: np.ndarray) -> np.ndarray:
    out = np.zeros(vectors.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -vectors[..., 2], vectors[..., 1], -vectors[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = vectors[..., 2], -vectors[..., 1], vectors[..., 0]
    return out


def inverse_right_jacobian(vectors: np.ndarray) -> np.ndarray:
    """``J_r^-1(e) = I + [e]x / 2 + (1/t^2 - (1 + cos t) / (2 t sin t)) [e]x^2``, ``t = |e|`` (``1/12`` at 0)."""
    angle = np.linalg.norm(vectors, axis=-1)
    small = angle < 1e-6
    safe = np.where(small, 1.0, angle)
    factor = np.where(small, 1.0 / 12.0, 1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe)))
    skew = _skew(vectors)
    return np.eye(3) + 0.5 * skew + factor[..., None, None] * (skew @ skew)
