"""Geometry: batched fits, Plücker lines, line-pair analysis, rigid transforms, registration, KUKA A, B, C.

Everything in mm and radians; batched over leading axes, last axis the coordinates.

Examples
--------
A circle fitted to points of a known circle gives its centre, radius and axis back:

>>> import numpy as np
>>> from robotcal.geometry import fit_circle_3d
>>> angle = np.linspace(0.0, 1.5, 12)
>>> points = np.stack([10 + 50 * np.cos(angle), -5 + 50 * np.sin(angle), np.full(12, 3.0)], axis=-1)
>>> fit = fit_circle_3d(points)
>>> np.round(fit.centre, 9).tolist(), round(float(fit.radius), 9), np.round(np.abs(fit.normal), 9).tolist()
([10.0, -5.0, 3.0], 50.0, [0.0, 0.0, 1.0])
"""

from robotcal.geometry.euler import (
    GIMBAL_TOLERANCE,
    kuka_abc_from_matrix,
    matrix_from_kuka_abc,
    thesis_order,
    wrap_angle_near,
)
from robotcal.geometry.fits import CircleFit, PlaneFit, check_points, fit_circle_3d, fit_plane
from robotcal.geometry.lines import (
    INTERSECTION_TOLERANCE_MM,
    PARALLEL_TOLERANCE_RAD,
    LinePair,
    PluckerLine,
    analyse_dh_pair,
    analyse_hayati_pair,
    signed_angle_about,
)
from robotcal.geometry.registration import Registration, register_points
from robotcal.geometry.transforms import (
    apply_transform,
    check_rigid_transform,
    invert_transform,
    nearest_rotation,
    rot_x,
    rot_y,
    rot_z,
    rotation_about_line,
    translation,
)

__all__ = [
    "GIMBAL_TOLERANCE",
    "kuka_abc_from_matrix",
    "matrix_from_kuka_abc",
    "thesis_order",
    "wrap_angle_near",
    "PlaneFit",
    "CircleFit",
    "fit_plane",
    "fit_circle_3d",
    "check_points",
    "PluckerLine",
    "LinePair",
    "PARALLEL_TOLERANCE_RAD",
    "INTERSECTION_TOLERANCE_MM",
    "analyse_dh_pair",
    "analyse_hayati_pair",
    "signed_angle_about",
    "Registration",
    "register_points",
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
