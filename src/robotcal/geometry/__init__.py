"""Geometry: batched fits, Plücker lines, line-pair analysis, rigid transforms, registration."""

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
    "CircleFit",
    "PlaneFit",
    "check_points",
    "fit_circle_3d",
    "fit_plane",
    "INTERSECTION_TOLERANCE_MM",
    "PARALLEL_TOLERANCE_RAD",
    "LinePair",
    "PluckerLine",
    "analyse_dh_pair",
    "analyse_hayati_pair",
    "signed_angle_about",
    "Registration",
    "register_points",
    "apply_transform",
    "check_rigid_transform",
    "invert_transform",
    "nearest_rotation",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotation_about_line",
    "translation",
]
