"""Flange orientations for ISO 9283's orientation characteristics: rotation vectors, deviations of attained from
commanded orientations, and attained flange poses registered from three or more measured flange targets
(:func:`rotation_vectors` is :func:`robotcal.geometry.rotations.rotation_vectors`, kept here by its name).

:mod:`robotcal.diagnostics.iso9283` uses these and re-exports them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.geometry.rotations import rotation_vectors

__all__ = ["ORIENTATION_AXES", "orientation_deviations", "register_flange_poses", "rotation_vectors"]


#: Axes the orientation deviations are expressed about (see :func:`orientation_deviations`).
ORIENTATION_AXES = ("base", "flange")


def orientation_deviations(
    attained_rotations: ArrayLike, commanded_rotations: ArrayLike, *, axes: str = "base",
) -> np.ndarray:
    """Orientation deviations ``(a, b, c)`` of attained from commanded flange orientations [rad].

    ``axes="base"`` (ISO 9283's angles about the base axes): the rotation vector of
    ``R_a R_c^T``, the small rotation that, applied in the base frame, turns the commanded flange
    onto the attained one; its components are the rotations about base x, y, z. ``axes="flange"``:
    the rotation vector of ``R_c^T R_a`` (commanded^-1 attained), the same rotation expressed about
    the commanded flange's axes. The two differ only by the commanded rotation: ``v_base = R_c v_flange``.

    Parameters
    ----------
    attained_rotations : array_like, shape (..., 3, 3)
    commanded_rotations : array_like, shape (..., 3, 3)
        Broadcast against ``attained_rotations``.
    axes : {"base", "flange"}

    Returns
    -------
    ndarray, shape (..., 3)
    """
    if axes not in ORIENTATION_AXES:
        raise InputError(f"orientation axes must be one of {', '.join(ORIENTATION_AXES)}; got {axes!r}")
    attained = np.asarray(attained_rotations, dtype=float)
    commanded = np.asarray(commanded_rotations, dtype=float)
    commanded_t = np.swapaxes(commanded, -1, -2)
    deviation = attained @ commanded_t if axes == "base" else commanded_t @ attained
    return rotation_vectors(deviation)


def register_flange_poses(offsets: ArrayLike, points: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Attained flange poses from targets measured at each pose: the rigid transform taking the
    targets' flange offsets onto their measured positions (Horn's closed form, least squares).

    Parameters
    ----------
    offsets : array_like, shape (n_targets, 3)
        Targets in the flange frame [mm], n_targets >= 3, not collinear.
    points : array_like, shape (..., n_targets, 3)
        The same targets measured, in the base frame [mm].

    Returns
    -------
    transforms : ndarray, shape (..., 4, 4)
        ``base_from_flange`` of every pose.
    rms : ndarray, shape (...)
        RMS residual of each registration [mm] (offsets that do not match the targets show here).
    """
    from robotcal.errors import DegenerateGeometryError
    from robotcal.geometry.registration import register_points

    offsets = np.asarray(offsets, dtype=float)
    points = np.asarray(points, dtype=float)
    if offsets.ndim != 2 or offsets.shape[1] != 3 or offsets.shape[0] < 3:
        raise InputError(f"the flange orientation needs >= 3 target offsets (n, 3) [mm]; got shape {offsets.shape}")
    if points.shape[-2:] != offsets.shape:
        raise InputError(f"`points` must have shape (..., {offsets.shape[0]}, 3); got {points.shape}")
    try:
        registration = register_points(np.broadcast_to(offsets, points.shape), points)
    except DegenerateGeometryError as exc:
        raise InputError(f"the flange targets' offsets are collinear: no orientation can be measured ({exc})") from exc
    return registration.transform, registration.rms
