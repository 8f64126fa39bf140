"""Does the stated uncertainty explain the error observed at the validation points? (docs/uncertainty.md)

The check a metrologist asks for: at every validation pose the Monte Carlo draws of the model give the
covariance ``V_p`` of the predicted target position, so the RMS position uncertainty predicted by the
calibration is ``sqrt(mean_p tr V_p)``; the instrument adds ``3 sigma_p^2`` per point (sigma from its U(L),
uniform: U/sqrt(3), normal: U/k). If the model explains the data, the RMS of the observed errors
``|T p(estimate) - m|`` is close to ``sqrt(mean_p (tr V_p + 3 sigma_p^2))``; a larger observed RMS points to
what the model does not hold (joint errors such as backlash, eccentricity, gravity sag, or a wrong instrument
level). Joint errors the capture measured but the deployed model cannot represent (a joint's eccentricity: the
chain's parameters turn no translation with the joint angle) are no surprise: given them, their move of the target
at every validation pose, ``|d_p|^2``, adds to the expected error and is reported on its own
(``uncompensated_rms_mm``). Front door: :func:`robotcal.api.validation_consistency`.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np

from robotcal.errors import InputError
from robotcal.geometry.registration import register_points
from robotcal.identification.health import repeatability_sigma
from robotcal.kinematics.forward import target_positions
from robotcal.uncertainty.tcp import position_covariance

if TYPE_CHECKING:
    from robotcal.capture import Capture
    from robotcal.instruments import Instrument
    from robotcal.kinematics.joint_model import JointModel
    from robotcal.kinematics.model import ParameterSet, ReflectorMount, RobotModel
    from robotcal.simulation.generator import JointErrorModel

__all__ = ["check_validation_consistency", "observed_errors"]

METHOD = (
    "predicted = sqrt(mean over poses of tr V_p), V_p the covariance of the validation target position "
    "over the Monte Carlo draws (plus the bias correction's uncertainty where the joint errors were measured); "
    "instrument = sqrt(mean of 3 sigma_p^2) from U(L) (with the robot's repeatability sigma_r^2 = (RP / 3.616)^2 "
    "added to sigma_p^2 when stated); uncompensated = RMS over poses of the move d_p of the target by the measured "
    "joint errors the deployed model does not represent (when given); expected = "
    "sqrt(predicted^2 + instrument^2 + uncompensated^2); observed = RMS of |T p(estimate) - measured|"
)


def check_validation_consistency(
    validation: Capture,
    estimate: ParameterSet,
    robot: RobotModel,
    values: np.ndarray,
    target: ReflectorMount,
    instrument: Instrument,
    *,
    tracker_from_base: np.ndarray | None = None,
    joint_model: JointModel | None = None,
    extra_draws: np.ndarray | None = None,
    model: str = "refined",
    repeatability_mm: float | None = None,
    correction_shifts: np.ndarray | None = None,
    joint_errors: JointErrorModel | None = None,
) -> dict[str, Any]:
    """Predicted, instrument, expected and observed RMS errors at the validation points [mm].

    Parameters
    ----------
    validation : Capture
        Free poses (circle = 0) measured with the flange ``target`` [mm].
    estimate : ParameterSet
        The deployed parameters [mm, rad].
    robot : RobotModel
        The robot whose readings the capture holds.
    values : ndarray, shape (n_draws, n_joints, 5)
        Monte Carlo draws of the same model [mm, rad]; ``joint_model`` and ``extra_draws`` for an extended one.
    target : ReflectorMount
    instrument : Instrument
    tracker_from_base : ndarray, shape (4, 4), optional
        The base frame [mm]; None: a Horn registration of the predictions on the measurements (which absorbs part
        of the error).
    model : str
        Name of the model, recorded.
    repeatability_mm : float, optional
        The robot's ISO 9283 pose repeatability RP [mm] (the noise budget): its scatter, ``3 sigma_r^2`` per point
        (:func:`robotcal.identification.health.repeatability_sigma`), adds to the instrument's.
    correction_shifts : ndarray, shape (k, 5 n + m), optional
        The bias correction's uncertainty sources (:attr:`robotcal.uncertainty.montecarlo.MonteCarloResult.
        correction_shifts`): each moves the predicted positions, and the squared moves add to ``tr V_p``.
    joint_errors : JointErrorModel, optional
        Joint errors measured on the robot that ``estimate`` does not represent (the measured eccentricity,
        :func:`robotcal.uncertainty.joint_errors.measured_joint_errors`), at free poses without lash: their move of
        the target adds to the expected error (module notes).

    Returns
    -------
    dict
        JSON-ready figures in mm (``predicted_rms_mm``, ``instrument_rms_mm``, ``expected_rms_mm``,
        ``observed_rms_mm``, ``ratio``), the base-frame mode and the counts.
    """
    measured = np.asarray(validation.points, dtype=float)
    predicted, observed, base = observed_errors(validation, estimate, target, tracker_from_base)
    # the Monte Carlo covariance of the target position at every validation pose (positions only)
    covariance = position_covariance(
        robot, values, validation.readings, tool=target.positions[0], joint_model=joint_model, extra_draws=extra_draws
    )
    traces = np.trace(covariance, axis1=1, axis2=2) + _correction_variance(
        estimate, validation, target, correction_shifts, predicted
    )
    noise = 3.0 * (instrument.standard_uncertainty(measured) ** 2 + repeatability_sigma(repeatability_mm) ** 2)
    uncompensated = _uncompensated(estimate, validation, target, joint_errors, predicted)
    expected = float(np.sqrt(np.mean(traces + noise + uncompensated)))
    observed_rms = float(np.sqrt(np.mean(observed**2)))
    return {
        "model": model,
        "poses": int(validation.n_points),
        "draws": int(values.shape[0]),
        "base_frame": base,
        "predicted_rms_mm": float(np.sqrt(np.mean(traces))),
        "instrument_rms_mm": float(np.sqrt(np.mean(noise))),
        "expected_rms_mm": expected,
        "observed_rms_mm": observed_rms,
        "observed_mean_mm": float(observed.mean()),
        "ratio": observed_rms / expected if expected > 0 else None,
        **({} if joint_errors is None else {"uncompensated_rms_mm": float(np.sqrt(np.mean(uncompensated)))}),
        "method": METHOD,
        **({} if repeatability_mm is None else {"repeatability_mm": float(repeatability_mm)}),
    }


def observed_errors(
    validation: Capture, estimate: ParameterSet, target: ReflectorMount, tracker_from_base: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, str]:
    """The positions ``estimate`` predicts at the validation poses ``(n, 3)`` [mm, base frame], the distance of each
    from its measurement ``(n,)`` [mm] and the base-frame mode: ``"given"`` (``tracker_from_base``) or
    ``"registered"`` (a Horn registration of the predictions on the measurements)."""
    q = estimate.model_joint_variables(validation.readings)
    measured = np.asarray(validation.points, dtype=float)
    predicted = target_positions(estimate.values, q, np.zeros(validation.n_points, dtype=int), target)
    if tracker_from_base is not None:
        tracker, base = np.asarray(tracker_from_base, dtype=float), "given"
    else:
        tracker, base = register_points(predicted, measured).transform, "registered"
    observed = np.linalg.norm(predicted @ tracker[:3, :3].T + tracker[:3, 3] - measured, axis=1)
    return predicted, observed, base


def _uncompensated(estimate, validation, target, joint_errors, predicted: np.ndarray) -> np.ndarray:
    """Per validation pose, ``|d_p|^2`` [mm^2]: how far ``joint_errors`` (at free poses, without lash) move the
    target ``estimate`` predicts; zeros without them."""
    if joint_errors is None:
        return np.zeros(validation.n_points)
    if joint_errors.n_joints != estimate.robot.n_joints:
        raise InputError(
            f"validation consistency: the joint errors are of {joint_errors.n_joints} joints; robot "
            f"{estimate.robot.name!r} has {estimate.robot.n_joints}"
        )
    commanded = estimate.robot.model_joint_variables(validation.readings)
    transforms = joint_errors.at_free_poses().transforms(commanded)
    q = estimate.model_joint_variables(validation.readings)
    moved = target_positions(
        estimate.values, q, np.zeros(validation.n_points, dtype=int), target, joint_errors=transforms
    )
    return np.sum((moved - predicted) ** 2, axis=1)


def _correction_variance(estimate, validation, target, shifts, predicted: np.ndarray) -> np.ndarray:
    """Per validation pose, the variance of the predicted position the bias correction's uncertainty adds: the sum
    over ``shifts`` of the squared move of the position when the parameters (and joint-model values) move by it."""
    if shifts is None or np.size(shifts) == 0:
        return np.zeros(predicted.shape[0])
    n = estimate.robot.n_joints
    turning = np.zeros(validation.n_points, dtype=int)
    total = np.zeros(predicted.shape[0])
    for shift in np.asarray(shifts, dtype=float):
        moved = estimate.values + shift[: 5 * n].reshape(n, 5)
        joint_model = estimate.joint_model
        if joint_model is not None and shift.size > 5 * n:
            joint_model = joint_model.with_values(joint_model.values + shift[5 * n :])
        shifted = dataclasses.replace(estimate, values=moved, joint_model=joint_model)
        q = shifted.model_joint_variables(validation.readings)
        total += np.sum((target_positions(shifted.values, q, turning, target) - predicted) ** 2, axis=1)
    return total
