"""Orientations as tracker exports give them (issue 29, 6-DoF probes), to and from rotation matrices.

A 6-DoF probe (T-Mac, T-Frame, STS) reports, with its position, the orientation of its own frame in the tracker
frame. Exports write it in one of several forms; each becomes the rotation matrix ``R`` with
``v_tracker = R v_probe``:

``quaternion``
    ``qw, qx, qy, qz``, scalar first (normalised on reading; a norm off 1 by more than 1e-3 is refused). The
    capture CSV's canonical form (docs/scenario.md): unambiguous (no axis order, no angle unit), free of the
    gimbal lock of Euler angles, and written to 12 decimals it reproduces the rotation to about 1e-12 rad.
``abc``
    KUKA ``A, B, C`` [deg]: ``R = Rz(A) Ry(B) Rx(C)`` (:func:`robotcal.geometry.euler.matrix_from_kuka_abc`).
``rpy``
    roll, pitch, yaw [deg]: ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (the same rotation as ``A = yaw, B = pitch,
    C = roll``).
``matrix``
    the nine elements ``r11 .. r33`` row by row (orthonormalised to the nearest rotation within 1e-6).

The quaternion conversions are those of :class:`scipy.spatial.transform.Rotation` (imported on first use).
"""

from __future__ import annotations

import numpy as np

from robotcal.errors import InputError
from robotcal.geometry.euler import matrix_from_kuka_abc
from robotcal.geometry.transforms import nearest_rotation

__all__ = [
    "ORIENTATION_FORMS",
    "QUATERNION_COLUMNS",
    "rotations_from_quaternions",
    "quaternions_from_rotations",
    "rotations_from_euler",
    "rotations_from_matrices",
    "ORIENTATION_KEYS",
    "orientation_columns",
]

#: The forms an export's orientation may take.
ORIENTATION_FORMS = ("quaternion", "abc", "rpy", "matrix")
#: The capture CSV's orientation columns: a unit quaternion, scalar first.
QUATERNION_COLUMNS = ("qw", "qx", "qy", "qz")
_NORM_TOLERANCE = 1e-3
_FORM_KEYS = {
    "quaternion": QUATERNION_COLUMNS,
    "abc": ("a", "b", "c"),
    "rpy": ("roll", "pitch", "yaw"),
    "matrix": tuple(f"r{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)),
}
#: Keys of an export's column map (``robotcal import --columns``) that give an orientation, and its U(95) [deg].
ORIENTATION_KEYS = tuple(key for keys in _FORM_KEYS.values() for key in keys) + ("u95_deg",)


def _rotation():
    from scipy.spatial.transform import Rotation

    return Rotation


def rotations_from_quaternions(quaternions, *, source: str = "orientation") -> np.ndarray:
    """``(n, 4)`` quaternions ``qw, qx, qy, qz`` (scalar first) -> ``(n, 3, 3)`` rotation matrices."""
    quaternions = np.atleast_2d(np.asarray(quaternions, dtype=float))
    if quaternions.shape[1:] != (4,) or not np.all(np.isfinite(quaternions)):
        raise InputError(f"{source}: a quaternion is four finite numbers qw, qx, qy, qz")
    norm = np.linalg.norm(quaternions, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > _NORM_TOLERANCE)
    if bad.size:
        raise InputError(f"{source}: point {bad[0] + 1}: the quaternion's norm is {norm[bad[0]]:.6g}, not 1")
    return _rotation().from_quat(quaternions[:, [1, 2, 3, 0]] / norm[:, None]).as_matrix()


def quaternions_from_rotations(rotations) -> np.ndarray:
    """``(n, 3, 3)`` rotations -> ``(n, 4)`` unit quaternions ``qw, qx, qy, qz`` with ``qw >= 0``."""
    xyzw = _rotation().from_matrix(np.asarray(rotations, dtype=float)).as_quat()
    quaternions = xyzw[:, [3, 0, 1, 2]]
    return np.where(quaternions[:, :1] < 0.0, -quaternions, quaternions)


def rotations_from_euler(angles_deg, form: str) -> np.ndarray:
    """``(n, 3)`` angles [deg] -> ``(n, 3, 3)``: ``form="abc"`` (A, B, C) or ``"rpy"`` (roll, pitch, yaw)."""
    angles = np.atleast_2d(np.asarray(angles_deg, dtype=float))
    if form == "rpy":
        angles = angles[:, ::-1]  # yaw, pitch, roll: the order of A, B, C
    elif form != "abc":
        raise InputError(f"Euler angles are 'abc' or 'rpy'; got {form!r}")
    return matrix_from_kuka_abc(np.deg2rad(angles))


def rotations_from_matrices(elements, *, source: str = "orientation") -> np.ndarray:
    """``(n, 9)`` elements ``r11 .. r33`` row by row -> ``(n, 3, 3)`` rotations (nearest rotation, within 1e-6)."""
    matrices = np.asarray(elements, dtype=float).reshape(-1, 3, 3)
    nearest = nearest_rotation(matrices)  # a reflection's nearest rotation is far from it: refused below
    bad = np.flatnonzero(np.abs(nearest - matrices).max(axis=(1, 2)) > 1e-6)
    if bad.size:
        raise InputError(f"{source}: point {bad[0] + 1}: the matrix is not a rotation (within 1e-6)")
    return nearest


def orientation_columns(values: dict, *, source: str) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The rotations ``(n, 3, 3)`` and their U(95) ``(n,)`` [rad] from an export's columns ``values`` (key ->
    the column's numbers, the keys of :data:`ORIENTATION_KEYS` in one form); ``(None, None)`` without any."""
    forms = [form for form, keys in _FORM_KEYS.items() if any(key in values for key in keys)]
    if not forms:
        if "u95_deg" in values:
            raise InputError(f"{source}: an orientation U(95) (u95_deg) without an orientation")
        return None, None
    if len(forms) > 1:
        raise InputError(f"{source}: the orientation is given in several forms ({', '.join(forms)}); map one")
    form, keys = forms[0], _FORM_KEYS[forms[0]]
    missing = [key for key in keys if key not in values]
    if missing:
        raise InputError(f"{source}: the {form} orientation needs the columns {', '.join(keys)}; missing {missing}")
    numbers = np.column_stack([np.asarray(values[key], dtype=float) for key in keys])
    if form == "quaternion":
        rotations = rotations_from_quaternions(numbers, source=source)
    elif form == "matrix":
        rotations = rotations_from_matrices(numbers, source=source)
    else:
        rotations = rotations_from_euler(numbers, form)
    u95 = None
    if "u95_deg" in values:
        u95 = np.deg2rad(np.asarray(values["u95_deg"], dtype=float))
        bad = np.flatnonzero(~(u95 > 0))
        if bad.size:
            raise InputError(f"{source}: point {bad[0] + 1}: the orientation U(95) must be > 0 deg")
    return rotations, u95
