"""The joint errors a calibration's Monte Carlo simulates: those the capture's own joints stage measured.

A Monte Carlo that states the uncertainty of a calibration simulates the capture at the estimate; the joint
errors of that simulation can only come from what the capture itself shows (on a real cell nobody knows a
"true" joint error model). The joints stage (:func:`robotcal.diagnostics.joints.analyze_joints`, thesis ch. 4.6)
measures per joint

* the angular backlash: the signed angle from a forward to a return point at the same reading, pair by pair; and
* the axial and radial eccentricity of every circle point against its fitted plane and circle.

:func:`measured_joint_errors` converts them into the simulation's :class:`~robotcal.simulation.generator.
JointErrorModel` (eq. 5-2), a :class:`MeasuredJointErrors` that carries its uncertainty: the backlash as the mean
angle of the pairs, signed (standard uncertainty: their standard deviation over the root of their number), and the
eccentricity as one sinusoid per translation term, ``dx = A sin(q + phi)``,
``dy = A cos(q + phi)`` (an axis that runs out once per turn: radial eccentricity of order 2 in the joint angle)
and ``dz = A sin(2 q + phi)`` (axial eccentricity of order 2), fitted by least squares to the circle's residuals
through the eccentricity those shapes leave after the circle fits (computed on the noise-free circles of the plan
at the estimate, where the fits absorb orders 0 and 1 exactly as on the capture). Only the directions the circle
shows (at least :data:`_SHOWN` of a shape) are fitted, and the fit is kept only where it stands out of the
circle's noise; each direction of a kept fit has its standard uncertainty (the circle's noise over its singular
value). The translational lash and the tilt terms ``ex, ey`` are not converted.

What a short arc does not show (J1 turned 45 deg shows 0.7 % of a run-out, J2 turned 80 deg 4 %), the circle fit
absorbs into the axis: the run-out moves the estimated axis, and the refinement's estimate with it. The calibration
poses, which turn every joint through its range, show it: given the deployed refinement (:class:`CalibrationFit`),
the directions no circle shows are fitted jointly with the refinement, by least squares of its residuals on their
*unabsorbed* responses (each response is added to the measured points and refitted; the change of the residuals
is what the refinement cannot take up). What the circles' eccentricity leaves is taken off the residuals first, and
every joint's lash is a nuisance of the fit (its unabsorbed response projected out): the lash the refinement does
not correct marks the poses too, and would otherwise be taken for eccentricity. The directions are kept under the
same two rules (shown by the poses, out of the noise) and, kept, carry their standard uncertainties as sources too.

The poses show one more kind of eccentricity, which no circle of a short arc does: a radial term of order 3 along
fixed directions, ``dx = A sin(3 q + phi)``, ``dy = B sin(3 q + psi)`` (:data:`_LOBES`; the demo's J3 has one, and
its 100 deg circle shows 4 % of it). Four more directions per joint, for every joint, would leave the 30 poses to
fit some 50 directions from their noise; instead a joint's group of four joins the fit only where it stands out
(:func:`_kept_lobes`: forward selection, chi-squared at 99 % with a Bonferroni correction over the joints). A
measured model carries them as :attr:`MeasuredJointErrors.lobes`, added to the terms (eq. 5-2 has one sinusoid per
term, and the same joint may carry a run-out).

Two choices keep the correction's uncertainty what it states (docs/validation.md, the coverage of issue 29):

* **The backlash is simulated signed.** A negative mean, which no lash gives, is what the noise makes of a lash of
  about zero. Clipped to 0, the estimate scatters less than its standard uncertainty says (0.55 of it on a joint
  without lash), and the parameters a lash moves (J4.theta, about 3 u per u of J4's lash on the demo) covered more
  than stated.
* **A fit that does not stand out of the noise carries no uncertainty source.** It is 0 in every capture of a joint
  without eccentricity, so steps stated for it are uncertainty the correction does not have: with them, J4.alpha
  and J5.a covered 0.990 and 1.000 over 200 captures. Leaving out what the test rejects is the model selection any
  fit makes, as it leaves out an order-3 term.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from robotcal.capture import Capture
from robotcal.diagnostics.joints import JointDiagnostics, analyze_joints
from robotcal.identification.evaluation import fit_frames, tracker_points
from robotcal.identification.records import RefinementResult
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.kinematics.joint_model import lash_turns
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.generator import JointErrorModel, simulate_capture
from robotcal.simulation.plan import CapturePlan

__all__ = ["CalibrationFit", "MeasuredJointErrors", "measured_joint_errors"]

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
#: The radial eccentricity of order 3 in the joint angle, along fixed directions of frame {i-1} (a three-lobed
#: bearing, or one whose rollers wobble): ``dx = A sin(3 q + phi)``, ``dy = B sin(3 q + psi)``, as (term, phase [rad])
#: of its four unit directions. No circle of a short arc shows it; the calibration poses can, and a joint's group of
#: four is fitted there only where it stands out of the noise (:func:`_kept_lobes`).
_LOBES = ((0, 0.0), (0, 0.5 * np.pi), (1, 0.0), (1, 0.5 * np.pi))
#: Coefficients per joint: the shapes', then the lobes'.
_COEFFICIENTS = len(_SHAPES) + len(_LOBES)
#: A combination of the shapes is fitted only where the circles show at least this fraction of it (RMS of the
#: eccentricity it leaves after the circle fits, per unit amplitude): a short arc leaves an order-2 shape mostly to
#: the circle fit, and what the capture cannot show is not amplified out of its noise (it stays 0).
_SHOWN = 0.3
#: The eccentricity is kept only when it stands out of the circle's noise at this level (:func:`_shown_fit`).
_SIGNIFICANCE = 0.99
#: Amplitude of the unit responses [mm]: small enough that the circle fits respond linearly.
_PROBE_MM = 1e-3
#: Amplitude of the responses refitted for the calibration poses' fit [mm]: within the refinement's linear range,
#: and far above its convergence tolerance.
_REFIT_MM = 1e-2
#: The lash whose response is refitted for the nuisance of the calibration poses' fit [rad] (0.006 deg).
_LASH_RAD = 1e-4
_NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)


@dataclass(frozen=True, slots=True, kw_only=True)
class CalibrationFit:
    """The deployed refinement, whose residuals at the calibration poses show what the circles cannot.

    Attributes
    ----------
    capture : Capture
        The points it fitted: the circles, then the calibration poses (``circle = 0``).
    targets : tuple of Target
        Where they were measured.
    result : RefinementResult
        The refinement of ``capture``.
    refit : callable
        ``refit(capture) -> RefinementResult``: the same refinement (criterion, model, base, lash) of another
        capture of the same readings.
    """

    capture: Capture
    targets: tuple[Target, ...]
    result: RefinementResult
    refit: Callable[[Capture], RefinementResult]


@dataclass(frozen=True, slots=True, kw_only=True)
class MeasuredJointErrors(JointErrorModel):
    """A joint error model measured by a joints analysis (deterministic: ``noise_sd`` 0), with its uncertainty.

    Attributes
    ----------
    sources : tuple of JointErrorModel
        One per independent measured input of non-zero standard uncertainty (a joint's backlash, a direction of a
        joint's eccentricity the circle shows): this model with that input moved by one standard uncertainty. A
        Monte Carlo simulating this model propagates them to its bias correction
        (:attr:`robotcal.uncertainty.montecarlo.MonteCarloResult.correction_u`).

    lobes : JointErrorModel, optional
        Sinusoids added to this model's (:meth:`values`): the order-3 eccentricity the calibration poses measured
        (:data:`_LOBES`), on the terms that already carry a joint's run-out.

    Its ``backlash`` is the signed mean the pairs measured (module notes): negative where noise outweighs a lash of
    about zero.
    """

    sources: tuple[JointErrorModel, ...] = ()
    lobes: JointErrorModel | None = None
    signed_backlash: ClassVar[bool] = True

    def values(self, q, *, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Error terms ``(n_points, n_joints, 5)`` (:meth:`JointErrorModel.values`), the :attr:`lobes` added."""
        values = JointErrorModel.values(self, q, rng=rng)
        return values if self.lobes is None else values + self.lobes.values(q)


def measured_joint_errors(
    diagnostics: JointDiagnostics,
    estimate: ParameterSet,
    plan: CapturePlan,
    tracker_from_base,
    *,
    circle_fit: str = "geometric",
    calibration: CalibrationFit | None = None,
) -> MeasuredJointErrors:
    """The joint errors the joints stage measured, in the simulation's form, with their uncertainty (module notes).

    Parameters
    ----------
    diagnostics : JointDiagnostics
        The joints stage's analysis of the capture (:class:`robotcal.studies.JointAnalysis` ``.diagnostics``).
    estimate : ParameterSet
        The robot the Monte Carlo simulates (the calibration's estimate) [mm, rad].
    plan : CapturePlan
        The capture's plan (the readings its circles visit).
    tracker_from_base : array_like, shape (4, 4)
    circle_fit : {"geometric", "algebraic"}
        The joints stage's in-plane circle fit.
    calibration : CalibrationFit, optional
        The deployed refinement of the circles and calibration poses: the directions no circle shows are fitted
        to its residuals (module notes). None, or a capture without free poses: they stay 0.
    """
    n = estimate.robot.n_joints
    backlash, backlash_u = np.zeros(n), np.zeros(n)
    for circle in diagnostics.circles:
        angles = circle.backlash_angle[~circle.turnaround]
        if angles.size:
            backlash[circle.joint - 1] = float(angles.mean())
        if angles.size >= 2:
            backlash_u[circle.joint - 1] = float(np.std(angles, ddof=1)) / np.sqrt(angles.size)
    responses = [
        _eccentricity(_shape_model(n, shape), estimate, plan, tracker_from_base, circle_fit) for shape in _SHAPES
    ]
    coefficients = np.zeros((n, _COEFFICIENTS))
    steps: list[np.ndarray] = []  # one standard uncertainty along a fitted direction, (n, _COEFFICIENTS) [mm]
    hidden = {joint: np.eye(len(_SHAPES)) for joint in range(n)}  # per joint: the directions no circle shows
    for circle in diagnostics.circles:
        if circle.joint not in responses[0] or not np.isfinite(circle.noise_sigma):
            continue
        design = np.stack([_at(response[circle.joint], circle.reading) for response in responses], axis=1)
        value, directions, unshown = _shown_fit(design, np.r_[circle.radial, circle.axial], circle.noise_sigma)
        coefficients[circle.joint - 1, : len(_SHAPES)] = value * _PROBE_MM
        steps.extend(_on_joint(n, circle.joint - 1, step * _PROBE_MM) for step in directions)
        hidden[circle.joint - 1] = unshown
    if calibration is not None and np.any(calibration.capture.circle == 0):
        value, directions = _calibration_fit(calibration, hidden, _model(coefficients, np.zeros(n)))
        coefficients += value
        steps.extend(directions)
    sources = []
    for lashed in np.flatnonzero(backlash_u > 0):
        moved = backlash.copy()
        moved[lashed] += backlash_u[lashed]
        sources.append(_model(coefficients, moved))
    sources.extend(_model(coefficients + step, backlash) for step in steps)
    return replace(_model(coefficients, backlash), sources=tuple(sources))


def _model(coefficients: np.ndarray, backlash: np.ndarray) -> MeasuredJointErrors:
    """The joint error model of the ``coefficients (n, _COEFFICIENTS)`` [mm] (:data:`_SHAPES`, then :data:`_LOBES`)
    and signed ``backlash`` [rad], without sources."""
    n = coefficients.shape[0]
    lobes = None
    if np.any(coefficients[:, len(_SHAPES) :]):
        order3 = coefficients[:, len(_SHAPES) :].reshape(n, 2, 2)  # per term dx, dy: the sin 3q and cos 3q parts
        amplitude3, phase3 = np.zeros((n, 5)), np.zeros((n, 5))
        amplitude3[:, :2], phase3[:, :2] = np.hypot(order3[..., 0], order3[..., 1]), np.arctan2(order3[..., 1], order3[..., 0])
        period3 = np.full((n, 5), 2.0 * np.pi / 3.0)
        lobes = JointErrorModel(amplitude=amplitude3, period=period3, phase=phase3, noise_sd=np.zeros((n, 5)))
    amplitude, phase = np.zeros((n, 5)), np.zeros((n, 5))
    period = np.tile(2.0 * np.pi / np.array([1.0, 1.0, 2.0, 1.0, 1.0]), (n, 1))
    run_out = np.hypot(coefficients[:, 0], coefficients[:, 1])
    run_phase = np.arctan2(coefficients[:, 1], coefficients[:, 0])
    axial, axial_phase = np.hypot(coefficients[:, 2], coefficients[:, 3]), np.arctan2(coefficients[:, 3], coefficients[:, 2])
    amplitude[:, :3] = np.stack([run_out, run_out, axial], axis=1)
    phase[:, :3] = np.stack([run_phase, run_phase + 0.5 * np.pi, axial_phase], axis=1)
    return MeasuredJointErrors(
        amplitude=amplitude, period=period, phase=phase, noise_sd=np.zeros((n, 5)), backlash=backlash, lobes=lobes
    )


def _shape_model(n_joints: int, shape) -> JointErrorModel:
    """One of :data:`_SHAPES`, of amplitude :data:`_PROBE_MM`, on every joint."""
    amplitude, phase, period = (np.zeros((n_joints, 5)) for _ in range(3))
    period[:] = 2.0 * np.pi
    for term, (scale, angle, order) in enumerate(shape):
        amplitude[:, term], phase[:, term], period[:, term] = scale * _PROBE_MM, angle, 2.0 * np.pi / order
    return JointErrorModel(amplitude=amplitude, period=period, phase=phase, noise_sd=np.zeros((n_joints, 5)))


def _eccentricity(errors: JointErrorModel, estimate, plan, tracker_from_base, circle_fit) -> dict:
    """Per joint (1-based): the turning joint's readings [rad] and the radial and axial eccentricity [mm] the
    noise-free circles of the plan show with ``errors``."""
    capture, _ = simulate_capture(
        estimate.robot, plan, _NOISE_FREE, tracker_from_base, true_parameters=estimate, joint_errors=errors,
        joint_limits="ignore", rng=0,
    )  # fmt: skip
    analysis = analyze_joints(capture, backlash=False, method=circle_fit)
    return {circle.joint: (circle.reading, circle.radial, circle.axial) for circle in analysis.circles}


def _at(response: tuple, readings: np.ndarray) -> np.ndarray:
    """A shape's radial then axial eccentricity at ``readings`` (interpolated in the reading; the forward and
    return points of one reading, which a shape moves alike, averaged)."""
    simulated, radial, axial = response
    grid, index = np.unique(simulated, return_inverse=True)
    count = np.bincount(index, minlength=grid.size)
    mean = [np.bincount(index, weights=values, minlength=grid.size) / count for values in (radial, axial)]
    return np.concatenate([np.interp(readings, grid, values) for values in mean])


def _on_joint(n_joints: int, joint: int, step: np.ndarray) -> np.ndarray:
    """``step`` of one joint's shape coefficients (4, :data:`_SHAPES`) or of all its coefficients
    (:data:`_COEFFICIENTS`) as the ``(n_joints, _COEFFICIENTS)`` coefficients of every joint."""
    out = np.zeros((n_joints, _COEFFICIENTS))
    out[joint, : len(step)] = step
    return out


def _calibration_fit(
    calibration: CalibrationFit, hidden: dict[int, np.ndarray], known: JointErrorModel
) -> tuple[np.ndarray, list[np.ndarray]]:
    """The directions ``hidden`` (per joint, rows: unit shape combinations no circle shows) fitted to the deployed
    refinement's residuals (module notes), less the part the ``known`` eccentricity (the circles') explains and
    with every joint's lash a nuisance of the fit, with the order-3 eccentricity of the joints where it stands out
    (:func:`_kept_lobes`): their coefficients ``(n, _COEFFICIENTS)`` [mm] and one standard-uncertainty step of that
    shape along each direction the poses show."""
    n = len(hidden)
    capture, result, targets = calibration.capture, calibration.result, calibration.targets
    measured = _residuals(capture, result, targets)

    def unabsorbed(errors: JointErrorModel) -> np.ndarray:
        """What the refinement leaves of ``errors``' move of the points: the change of its residuals."""
        moved = replace(capture, points=capture.points + _response(capture, result, targets, errors))
        return (_residuals(moved, calibration.refit(moved), targets) - measured).ravel()

    def responses(directions: list) -> np.ndarray:
        """The unabsorbed responses ``(rows, k)`` of ``(joint, unit coefficients)`` per :data:`_PROBE_MM`."""
        columns = [unabsorbed(_model(_on_joint(n, joint, unit * _REFIT_MM), np.zeros(n))) for joint, unit in directions]
        return np.stack(columns, axis=1) * (_PROBE_MM / _REFIT_MM) if columns else np.zeros((measured.size, 0))

    base = measured.ravel() - (unabsorbed(known) if np.any(known.amplitude) else 0.0)
    columns = [(joint, direction) for joint, rows in hidden.items() for direction in rows]
    design = responses(columns)
    lobe_units = np.eye(_COEFFICIENTS)[len(_SHAPES) :]
    lobes = {joint: responses([(joint, unit) for unit in lobe_units]) for joint in range(n)}
    # a lash the refinement does not correct (or corrects by a noisy mean) leaves its own pattern: a nuisance
    turning = sorted({int(turned) - 1 for turned in capture.circle[capture.circle > 0]})
    if turning:
        no_shape = np.zeros((n, _COEFFICIENTS))
        lash = np.stack([unabsorbed(_model(no_shape, _LASH_RAD * np.eye(n)[joint])) for joint in turning], axis=1)
        basis = np.linalg.qr(lash)[0]
        off = lambda x: x - basis @ (basis.T @ x)  # noqa: E731
        design, base, lobes = off(design), off(base), {joint: off(group) for joint, group in lobes.items()}
    rows = 3 * int(np.sum(capture.circle == 0))
    free = int(result.identifiability.free.sum()) + len(turning)
    for joint in _kept_lobes(design, base, lobes, free + len(columns), rows):
        columns.extend((joint, unit) for unit in lobe_units)
        design = np.hstack([design, lobes[joint]])
    if not columns:
        return np.zeros((n, _COEFFICIENTS)), []
    noise_sigma = _residual_sigma(design, base, free + len(columns))
    value, directions, _ = _shown_fit(design, base, noise_sigma, rows=rows)
    coefficients = np.stack([_on_joint(n, joint, direction) for joint, direction in columns])  # (k, n, _COEFFICIENTS)
    to_joints = lambda combination: np.tensordot(combination, coefficients, axes=1) * _PROBE_MM  # noqa: E731
    return to_joints(value), [to_joints(step) for step in directions]


def _residual_sigma(design: np.ndarray, measured: np.ndarray, free: int) -> float:
    """The noise per row that the least squares of ``measured`` on ``design`` leaves, ``free`` unknowns in all."""
    fitted = design @ np.linalg.lstsq(design, measured, rcond=None)[0] if design.size else 0.0
    return float(np.sqrt(np.sum((measured - fitted) ** 2) / max(measured.size - free, 1)))


def _kept_lobes(design: np.ndarray, measured: np.ndarray, lobes: dict[int, np.ndarray], free: int, rows: int) -> list[int]:
    """The joints whose order-3 group (the columns of ``lobes[joint]``, :data:`_LOBES`) stands out of the noise beside
    ``design`` (``free`` unknowns with it), chosen forward: the group of the smallest p-value joins while it passes,
    and the others are tested again beside it (a strong group leaks into the groups it resembles). A group's
    statistic is the part of ``measured`` along its shown directions (:data:`_SHOWN`, once the span of the design so
    far is taken off) over the noise the design leaves, chi-squared at :data:`_SIGNIFICANCE` over all the joints
    tested together (Bonferroni: instrument noise adds a group to 1 % of the captures, not to 1 % per joint)."""
    from scipy.stats import chi2  # scipy.stats is slow to import: only when a joints analysis is converted

    alpha = (1.0 - _SIGNIFICANCE) / max(len(lobes), 1)
    kept: list[int] = []
    while len(kept) < len(lobes):
        noise_sigma = _residual_sigma(design, measured, free)
        left, singular, _ = np.linalg.svd(design, full_matrices=False)
        basis = left[:, singular > singular.max() * 1e-9] if singular.size else left
        p_values = {}
        for joint, group in lobes.items():
            if joint in kept:
                continue
            beside, group_singular, _ = np.linalg.svd(group - basis @ (basis.T @ group), full_matrices=False)
            shown = group_singular / np.sqrt(rows) >= _SHOWN * _PROBE_MM
            projection = beside[:, shown].T @ measured
            if shown.any() and noise_sigma > 0:
                p_values[joint] = float(chi2.sf(float(projection @ projection) / noise_sigma**2, int(shown.sum())))
        if not p_values or min(p_values.values()) >= alpha:
            break
        best = min(p_values, key=p_values.__getitem__)
        kept.append(best)
        design, free = np.hstack([design, lobes[best]]), free + lobes[best].shape[1]
    return kept


def _residuals(capture: Capture, result: RefinementResult, targets) -> np.ndarray:
    """Measured minus predicted points ``(n_points, 3)`` [mm] of a refinement, its circle points turned by the
    lash correction the refinement applied (:func:`robotcal.kinematics.joint_model.lash_turns`)."""
    parameters = result.parameters
    robot, joint_model = parameters.robot, parameters.joint_model
    commanded = robot.model_joint_variables(capture.readings)
    lash = np.zeros_like(commanded)
    if joint_model is not None and joint_model.has_backlash:
        lash = lash_turns(joint_model.backlash, commanded, capture.circle)
    turned = replace(capture, readings=robot.readings_from_model(commanded + lash))
    return capture.points - tracker_points(turned, parameters, targets, fit_frames(result))


def _response(capture: Capture, result: RefinementResult, targets, errors: JointErrorModel) -> np.ndarray:
    """How ``errors`` move the refinement's predicted points ``(n_points, 3)`` in the tracker frame [mm]: on the
    circles with each joint's lash state along them in capture order (as the simulator), at free poses without
    lash (:meth:`JointErrorModel.at_free_poses`)."""
    parameters = result.parameters
    commanded = parameters.robot.model_joint_variables(capture.readings)
    transforms = errors.at_free_poses().transforms(commanded)
    circles = capture.circle > 0
    if errors.has_lash and circles.any():
        transforms[circles] = errors.transforms(commanded[circles])
    frames = fit_frames(result)
    moved = tracker_points(capture, parameters, targets, frames, joint_errors=transforms)
    return moved - tracker_points(capture, parameters, targets, frames)


def _shown_fit(
    design: np.ndarray, measured: np.ndarray, noise_sigma: float, rows: int | None = None
) -> tuple[np.ndarray, list, np.ndarray]:
    """Least squares ``design c = measured`` over the singular directions the circles show (:data:`_SHOWN`), and
    one standard uncertainty step along each of them (``noise_sigma`` per point: ``noise_sigma / s_i`` along the
    right singular vector ``v_i``). The fit is kept only where the fitted eccentricity stands out of the noise (a
    chi-squared test at :data:`_SIGNIFICANCE` of its squared norm over ``noise_sigma^2``, as many degrees of
    freedom as directions shown); otherwise value and steps are none (module notes): a noise-only capture gives
    neither. ``rows``: the number of rows that can show a direction (the RMS per unit amplitude is taken over them;
    default all). Third: the right singular vectors not shown (rows), the directions left to another fit."""
    from scipy.stats import chi2  # scipy.stats is slow to import: only when a joints analysis is converted

    left, singular, right = np.linalg.svd(design, full_matrices=False)
    shown = singular / np.sqrt(design.shape[0] if rows is None else rows) >= _SHOWN * _PROBE_MM
    unshown = right[~shown]
    projection = left[:, shown].T @ measured
    if not shown.any() or (
        noise_sigma > 0 and float(projection @ projection) <= noise_sigma**2 * chi2.ppf(_SIGNIFICANCE, int(shown.sum()))
    ):
        return np.zeros(design.shape[1]), [], unshown
    steps = [noise_sigma / s * v for s, v in zip(singular[shown], right[shown], strict=True)] if noise_sigma > 0 else []
    return right[shown].T @ (projection / singular[shown]), steps, unshown
