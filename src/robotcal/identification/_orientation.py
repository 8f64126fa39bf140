"""Rotation helpers of the orientation residual of a 6-DoF probe (issue 29): the residual of a point is the rotation
vector ``e = log(R_measured^T R_model)`` [rad], and a body-frame turn ``delta`` of the model changes it by
``J_r^-1(e) delta`` (``J_r`` the right Jacobian of SO(3)), exactly at ``e = 0``."""

from __future__ import annotations

import numpy as np

__all__ = ["rotation_log", "rotation_exp", "inverse_right_jacobian", "vee"]


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


def rotation_log(rotations: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(..., 3)`` [rad] of rotations ``(..., 3, 3)`` (angles below pi)."""
    from scipy.spatial.transform import Rotation

    shape = rotations.shape[:-2]
    return Rotation.from_matrix(rotations.reshape(-1, 3, 3)).as_rotvec().reshape(shape + (3,))


def rotation_exp(vectors: np.ndarray) -> np.ndarray:
    """Rotations ``(..., 3, 3)`` of rotation vectors ``(..., 3)`` [rad]."""
    from scipy.spatial.transform import Rotation

    shape = vectors.shape[:-1]
    return Rotation.from_rotvec(vectors.reshape(-1, 3)).as_matrix().reshape(shape + (3, 3))


def inverse_right_jacobian(vectors: np.ndarray) -> np.ndarray:
    """``J_r^-1(e) = I + [e]x / 2 + (1/t^2 - (1 + cos t) / (2 t sin t)) [e]x^2``, ``t = |e|`` (``1/12`` at 0)."""
    angle = np.linalg.norm(vectors, axis=-1)
    small = angle < 1e-6
    safe = np.where(small, 1.0, angle)
    factor = np.where(small, 1.0 / 12.0, 1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe)))
    skew = _skew(vectors)
    return np.eye(3) + 0.5 * skew + factor[..., None, None] * (skew @ skew)
