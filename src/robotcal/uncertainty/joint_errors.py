"""The joint errors a calibration's Monte Carlo simulates: those the capture's own joints stage measured.

A Monte Carlo that states the uncertainty of a calibration simulates the capture at the estimate; the joint
errors of that simulation can only come from what the capture itself shows (on a real cell nobody knows a
"true" joint error model). The joints stage (:func:`robotcal.diagnostics.joints.analyze_joints`, thesis ch. 4.6,
with its harmonic model :mod:`robotcal.diagnostics.harmonics`) measures per joint

* the angular backlash: the mean signed angle from a forward to a return point at the same reading; and
* the axial and radial eccentricity of every circle point against its fitted plane and circle, of which the
  harmonic model keeps the smooth part.

:func:`measured_joint_errors` converts them into the simulation's :class:`~robotcal.simulation.generator.
JointErrorModel` (eq. 5-2): the backlash as its ``backlash`` angle (a negative mean, which no lash gives, as 0),
and the eccentricity as one sinusoid per translation term, ``dx, dy = A sin(q + phi)`` (an axis that runs out
once per turn: radial eccentricity of order 0 and 2 in the joint angle) and ``dz = A sin(2 q + phi)``
(axial eccentricity of order 2), whose amplitudes and phases are the least-squares fit of the eccentricity
those terms leave after the circle fits (computed on the noise-free circles of the plan at the estimate,
where the fits absorb orders 0 and 1 exactly as on the capture) to the eccentricity the harmonic model
predicts at the same readings. The translational lash and the tilt terms ``ex, ey`` are not converted.
"""

from __future__ import annotations

import numpy as np

from robotcal.diagnostics.harmonics import HarmonicModel
from robotcal.diagnostics.joints import JointDiagnostics, analyze_joints
from robotcal.instruments import Instrument
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.generator import JointErrorModel, simulate_capture
from robotcal.simulation.plan import CapturePlan

__all__ = ["measured_joint_errors"]

#: The eccentricity shapes fitted, two per group (sine and cosine of the same harmonic): per shape the
#: (amplitude, phase [rad], harmonic order) of the terms dx, dy, dz. A once-per-turn run-out of the axis,
#: ``dx = A sin(q + phi)``, ``dy = A cos(q + phi)``, gives radial eccentricity of order 2 (the run-out that turns with
#: the joint, of order 0, is the axis position itself); ``dz = A sin(2 q + phi)``, axial eccentricity of order 2.
_SHAPES = (
    ((1.0, 0.0, 1), (1.0, 0.5 * np.pi, 1), (0.0, 0.0, 2)),
    ((1.0, 0.5 * np.pi, 1), (1.0, np.pi, 1), (0.0, 0.0, 2)),
    ((0.0, 0.0, 1), (0.0, 0.0, 1), (1.0, 0.0, 2)),
    ((0.0, 0.0, 1), (0.0, 0.0, 1), (1.0, 0.5 * np.pi, 2)),
)
#: A combination of the shapes is fitted only where the circles show at least this fraction of it (RMS of the
#: eccentricity it leaves after the circle fits, per unit amplitude): a short arc leaves an order-2 shape mostly to
#: the circle fit, and what the capture cannot show is not amplified out of its noise (it stays 0).
_SHOWN = 0.15
#: Amplitude of the unit responses [mm]: small enough that the circle fits respond linearly.
_PROBE_MM = 1e-3
_NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)


def measured_joint_errors(
    diagnostics: JointDiagnostics,
    harmonics: HarmonicModel,
    estimate: ParameterSet,
    plan: CapturePlan,
    tracker_from_base,
    *,
    circle_fit: str = "geometric",
) -> JointErrorModel:
    """The joint error model of a capture's joints stage, in the simulation's form (module notes).

    Parameters
    ----------
    diagnostics, harmonics
        The joints stage's analysis of the capture (:class:`robotcal.studies.JointAnalysis`).
    estimate : ParameterSet
        The robot the Monte Carlo simulates (the calibration's estimate) [mm, rad].
    plan : CapturePlan
        The capture's plan (the readings its circles visit).
    tracker_from_base : array_like, shape (4, 4)
    circle_fit : {"geometric", "algebraic"}
        The joints stage's in-plane circle fit.

    Returns
    -------
    JointErrorModel
        Deterministic (``noise_sd`` 0): amplitudes [mm], periods and phases [rad], backlash [rad].
    """
    robot = estimate.robot
    n = robot.n_joints
    backlash = np.zeros(n)
    for row in diagnostics.summary():
        if np.isfinite(row.backlash_angle_mean):
            backlash[row.joint - 1] = max(row.backlash_angle_mean, 0.0)
    responses = [
        _eccentricity(_shape_model(n, shape), estimate, plan, tracker_from_base, circle_fit) for shape in _SHAPES
    ]
    amplitude, phase = np.zeros((n, 5)), np.zeros((n, 5))
    period = np.tile(2.0 * np.pi / np.array([1.0, 1.0, 2.0, 1.0, 1.0]), (n, 1))
    for joint, reading in responses[0]["readings"].items():
        measured = np.concatenate([harmonics.predict(joint, q, reading) for q in ("radial", "axial")])
        design = np.stack([response[joint] for response in responses], axis=1)
        c = _shown_fit(design, measured) * _PROBE_MM
        run_out, run_phase = np.hypot(c[0], c[1]), np.arctan2(c[1], c[0])
        amplitude[joint - 1, :3] = run_out, run_out, np.hypot(c[2], c[3])
        phase[joint - 1, :3] = run_phase, run_phase + 0.5 * np.pi, np.arctan2(c[3], c[2])
    return JointErrorModel(amplitude=amplitude, period=period, phase=phase, noise_sd=np.zeros((n, 5)), backlash=backlash)


def _shape_model(n_joints: int, shape) -> JointErrorModel:
    """One of :data:`_SHAPES`, of amplitude :data:`_PROBE_MM`, on every joint."""
    amplitude, phase, period = (np.zeros((n_joints, 5)) for _ in range(3))
    period[:] = 2.0 * np.pi
    for term, (scale, angle, order) in enumerate(shape):
        amplitude[:, term], phase[:, term], period[:, term] = scale * _PROBE_MM, angle, 2.0 * np.pi / order
    return JointErrorModel(amplitude=amplitude, period=period, phase=phase, noise_sd=np.zeros((n_joints, 5)))


def _eccentricity(errors: JointErrorModel, estimate, plan, tracker_from_base, circle_fit) -> dict:
    """Per joint (1-based): the radial then axial eccentricity the noise-free circles show with ``errors``, and
    under the key ``"readings"`` the turning joint's readings of every circle [rad]."""
    capture, _ = simulate_capture(
        estimate.robot, plan, _NOISE_FREE, tracker_from_base, true_parameters=estimate, joint_errors=errors,
        joint_limits="ignore", rng=0,
    )  # fmt: skip
    analysis = analyze_joints(capture, backlash=False, method=circle_fit)  # type: ignore[arg-type]
    out: dict = {circle.joint: np.concatenate([circle.radial, circle.axial]) for circle in analysis.circles}
    out["readings"] = {circle.joint: circle.reading for circle in analysis.circles}
    return out


def _shown_fit(design: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """Least squares ``design c = measured`` over the singular directions the circles show (:data:`_SHOWN`)."""
    left, singular, right = np.linalg.svd(design, full_matrices=False)
    shown = singular / np.sqrt(design.shape[0]) >= _SHOWN * _PROBE_MM
    return right[shown].T @ ((left[:, shown].T @ measured) / singular[shown])
