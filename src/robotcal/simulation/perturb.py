"""A plausible "true" robot: the nominal model with random deviations of its identifiable parameters."""

from __future__ import annotations

import numpy as np

from robotcal.errors import InputError
from robotcal.kinematics.model import LENGTH_KINDS, PARAMETER_KINDS, ParameterSet, RobotModel

__all__ = ["perturb_parameters", "perturbable_mask"]


def perturbable_mask(robot: RobotModel, *, include_base: bool = False) -> np.ndarray:
    """``(n_joints, 5)`` bool: parameters both CPA and the refinement can identify.

    Every parameter the model does not fix, of joints 1..n-1 (joint n's d, theta, a, alpha are
    invisible to CPA, docs/conventions.md), except d of a DH joint whose next axis is nominally parallel
    (alpha = 0 or 180 deg; CPA holds it) and, unless ``include_base``, d1 and theta1. Those two are a
    rigid motion of the base only for a flange target with an estimated base frame; with per-joint
    reflectors or a given base the data determine them (see :mod:`robotcal.identification.refine`),
    and a truth that moves them (``include_base=True``) is the stricter test.
    """
    mask = ~robot.structurally_fixed.copy()
    mask[-1] = False
    alpha = robot.nominal[:, 3]
    parallel = np.isclose(np.sin(alpha), 0.0, atol=1e-9) & ~robot.hayati
    mask[parallel, 0] = False
    if not include_base:
        mask[0, :2] = False
    return mask


def perturb_parameters(
    robot: RobotModel,
    *,
    length_sd_mm: float,
    angle_sd_deg: float,
    rng: np.random.Generator | int | None = None,
    include_base: bool = False,
) -> ParameterSet:
    """The nominal parameters plus normal deviations on :func:`perturbable_mask`.

    Parameters
    ----------
    robot : RobotModel
    length_sd_mm : float
        Standard deviation of d and a deviations [mm], >= 0.
    angle_sd_deg : float
        Standard deviation of theta, alpha and beta deviations [deg], >= 0.
    rng : numpy.random.Generator or int or None
    include_base : bool
        Also perturb d1 and theta1.

    Returns
    -------
    ParameterSet
        ``identified`` all False (a truth, not an estimate).
    """
    rng = np.random.default_rng(rng)
    for name, value in (("length_sd_mm", length_sd_mm), ("angle_sd_deg", angle_sd_deg)):
        if not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
            raise InputError(f"`{name}` must be a finite number >= 0; got {value!r}")
    sd = np.array([length_sd_mm if kind in LENGTH_KINDS else np.deg2rad(angle_sd_deg) for kind in PARAMETER_KINDS])
    deviation = rng.standard_normal((robot.n_joints, 5)) * sd
    mask = perturbable_mask(robot, include_base=include_base)
    return ParameterSet(robot=robot, values=robot.nominal + np.where(mask, deviation, 0.0))
