"""Rigid registration of corresponding point sets by Horn's unit-quaternion method.

Used to estimate ``tracker_from_base`` from measured target positions (tracker frame) and the same
targets predicted by the nominal model (base frame), thesis ch. 4.5 and 4.5.4 ("orientaciones
absolutas ... con el uso de cuaterniones").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import DegenerateGeometryError, InputError
from robotcal.geometry.fits import check_points
from robotcal.geometry.transforms import apply_transform

__all__ = ["Registration", "register_points"]


@dataclass(frozen=True, slots=True, kw_only=True)
class Registration:
    """Least-squares rigid transform ``target_from_source`` and its residuals.

    Attributes
    ----------
    transform : ndarray, shape (..., 4, 4)
        Minimises ``sum_k |R p_k + t - q_k|^2`` over rotations R and translations t.
    residuals : ndarray, shape (..., n_points)
        Distance ``|T p_k - q_k|`` per point [mm].
    rms : ndarray, shape (...)
        RMS of ``residuals`` [mm].
    """

    transform: np.ndarray
    residuals: np.ndarray
    rms: np.ndarray


def register_points(source_points: ArrayLike, target_points: ArrayLike) -> Registration:
    """Rigid transform taking ``source_points`` onto ``target_points`` (Horn 1987, closed form).

    The rotation is the unit quaternion that is the eigenvector of Horn's symmetric 4x4 matrix ``N``
    (built from the cross-covariance of the centred sets) with the largest eigenvalue; the
    translation maps the source centroid onto the target centroid. Batched: leading axes of either
    set broadcast (a Monte Carlo batch of measured sets against one predicted set).

    Parameters
    ----------
    source_points, target_points : array_like, shape (..., n_points, 3)
        Corresponding points [mm], ``n_points >= 3`` and not collinear.

    Returns
    -------
    Registration
        ``transform (..., 4, 4)``, ``residuals (..., n_points)``, ``rms (...)``.

    References
    ----------
    B. K. P. Horn, "Closed-form solution of absolute orientation using unit quaternions",
    J. Opt. Soc. Am. A 4 (1987) 629-642; thesis ref. [25].
    """
    source = check_points(source_points, "source_points")
    target = check_points(target_points, "target_points")
    if source.shape[-2] != target.shape[-2]:
        raise InputError(
            f"`source_points` and `target_points` must hold the same number of points; "
            f"got {source.shape} and {target.shape}"
        )
    source_centroid, target_centroid = source.mean(axis=-2), target.mean(axis=-2)
    p = source - source_centroid[..., None, :]
    q = target - target_centroid[..., None, :]
    singular = np.linalg.svd(p, compute_uv=False)
    if np.any(singular[..., 1] <= 1e-9 * np.maximum(singular[..., 0], 1e-300)):
        raise DegenerateGeometryError("registration needs at least 3 non-collinear points")
    m = np.einsum("...ki,...kj->...ij", p, q)
    sxx, sxy, sxz = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    syx, syy, syz = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    szx, szy, szz = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    n = np.stack(
        [
            np.stack([sxx + syy + szz, syz - szy, szx - sxz, sxy - syx], axis=-1),
            np.stack([syz - szy, sxx - syy - szz, sxy + syx, szx + sxz], axis=-1),
            np.stack([szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy], axis=-1),
            np.stack([sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz], axis=-1),
        ],
        axis=-2,
    )
    _, vectors = np.linalg.eigh(n)
    w, x, y, z = (vectors[..., k, -1] for k in range(4))
    rotation = np.stack(
        [
            np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
            np.stack([2 * (y * x + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], axis=-1),
            np.stack([2 * (z * x - w * y), 2 * (z * y + w * x), w * w - x * x - y * y + z * z], axis=-1),
        ],
        axis=-2,
    )
    transform = np.zeros(rotation.shape[:-2] + (4, 4))
    transform[..., :3, :3] = rotation
    transform[..., :3, 3] = target_centroid - np.einsum("...ij,...j->...i", rotation, source_centroid)
    transform[..., 3, 3] = 1.0
    residuals = np.linalg.norm(apply_transform(transform[..., None, :, :], source) - target, axis=-1)
    return Registration(transform=transform, residuals=residuals, rms=np.sqrt(np.mean(residuals**2, axis=-1)))
