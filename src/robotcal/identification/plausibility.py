"""Plausibility checks of a capture against the robot, the reflector and the instrument (issue 12).

CPA accepts any points that lie on circles, so a capture in the wrong units, readings in radians, a
file appended to itself or a circle with gross outliers can give a plausible-looking and wrong
calibration. These checks run before CPA (:func:`robotcal.identify`) and compare the
capture with what the nominal model and the instrument predict. Where the answer would certainly
be wrong they raise :class:`InputError`; where it may be wrong they warn with
:class:`PlausibilityWarning`. Every message names the capture, the circle and rows, and the likely
cause.

Checks and thresholds (all relative to the nominal model or to the instrument's ``U(L) = A + B L``):

- **Scale** (units): RMS spread of the measured cloud about its centroid over that of the nominal
  model's predicted targets. Both are invariant to the unknown instrument pose. Outside
  [1/2, 2]: error, naming metres (ratio ~1e-3), centimetres (~0.1) or inches (~1/25.4) when the
  ratio is within 15 % of those; outside [0.8, 1.25]: warning (another robot or reflector set-up).
  A real robot differs from nominal by millimetres over a cloud of hundreds of mm (ratio 1 +- 1 %).
- **Readings scale**: per circle, the least-squares slope of the target's angle about the fitted axis
  against the turning joint's model variable (thesis eq. 5-1: the target turns by the joint angle).
  Slope 57.3 +- 15 %: the readings are in radians (error). Otherwise a slope outside [2/3, 3/2]:
  warning (a gear ratio or a wrong joint). The thesis iGPS scenario (+-200 um on a 20 mm, 50 deg
  circle) gives 0.87..1.10 over 200 seeds.
- **Radius**: per circle, fitted radius against the radius of the nominal predicted targets (the
  reflector arm the scenario declares): a nominal radius below 1 um is an error (the target sits on
  the axis, CPA cannot see the joint); a difference above max(10 mm, 20 %) warns (the iGPS
  scenario's short arcs give up to 3.3 mm over 200 seeds).
- **Duplicated rows**: rows identical in every reading and coordinate never occur in a measurement.
  Half or more of the rows duplicated is an error (a file appended to itself); fewer warn.
- **Outliers**: per point, the distance to the fitted circle ``r = hypot(plane, radial residual)``.
  A point is an outlier when ``r > OUTLIER_U * U(L)`` (with a floor of :data:`RESIDUAL_FLOOR_MM`)
  **and** ``r > median(r) + OUTLIER_MAD * 1.4826 * MAD(r)`` (robust z-score; 1.4826 MAD estimates
  sigma for normal residuals). A circle whose RMS residual exceeds ``OUTLIER_U * U`` warns even when
  no single point stands out. :func:`reject_outliers` removes outliers, refits and removes once more.

References: thesis ch. 4.4 (circle fits), 5.2.1 (instrument model ``U = A + B L``, eq. 5-1).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import DegenerateGeometryError, InputError, RobotcalWarning
from robotcal.geometry.fits import CircleFit, fit_circle_3d
from robotcal.identification.cpa import CPAOptions, point_rows, prepare_cpa
from robotcal.instruments import Instrument
from robotcal.kinematics.model import ReflectorMount, RobotModel

__all__ = [
    "PlausibilityWarning",
    "PlausibilityReport",
    "check_capture",
    "reject_outliers",
    "OUTLIER_U",
    "OUTLIER_MAD",
    "RESIDUAL_FLOOR_MM",
]


class PlausibilityWarning(RobotcalWarning):
    """A capture that may not match the robot, the reflector or the instrument (see the message)."""


#: Residual threshold in units of the instrument's U(L): uniform errors of +-U per coordinate give
#: 3-D residuals below sqrt(3) U, normal errors with U = 2 sigma exceed 4 U with probability ~1e-6.
OUTLIER_U = 4.0
#: Robust z-score threshold (median / 1.4826 MAD) of an outlier.
OUTLIER_MAD = 5.0
#: Residual floor [mm]: joint eccentricity and backlash of a real robot reach tens of micrometres, and
#: a noise-free instrument has U = 0.
RESIDUAL_FLOOR_MM = 0.1
#: Largest share of a circle's points that :func:`reject_outliers` removes.
MAX_REJECTED_SHARE = 0.3

_UNITS = {"metres": 1e-3, "centimetres": 0.1, "inches": 1 / 25.4}


@dataclass(frozen=True, slots=True, kw_only=True)
class PlausibilityReport:
    """What :func:`check_capture` measured.

    Attributes
    ----------
    scale_ratio : float
        RMS spread of the measured cloud over that of the nominal prediction (1 expected).
    turn_ratio : ndarray, shape (n_circles,)
        Target angle turned per unit of model joint variable, per circle (1 expected).
    radius_mm, nominal_radius_mm : ndarray, shape (n_circles,)
        Fitted and nominally predicted circle radii [mm].
    circle_rms_mm, bound_mm : ndarray, shape (n_circles,)
        RMS fit residual and median instrument U(L) per circle [mm].
    outliers : tuple of ndarray
        Per circle, 0-based capture rows flagged as outliers.
    duplicates : ndarray
        0-based rows that repeat an earlier row exactly.
    findings : tuple of str
        The warnings issued (empty when all is plausible).
    """

    scale_ratio: float
    turn_ratio: np.ndarray
    radius_mm: np.ndarray
    nominal_radius_mm: np.ndarray
    circle_rms_mm: np.ndarray
    bound_mm: np.ndarray
    outliers: tuple[np.ndarray, ...]
    duplicates: np.ndarray
    findings: tuple[str, ...]


def _residuals(fit: CircleFit) -> np.ndarray:
    assert fit.plane_residuals is not None and fit.radial_residuals is not None  # fitted with residuals
    return np.hypot(fit.plane_residuals, fit.radial_residuals)


def _outlier_mask(residual: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """Rows of one circle that are outliers by both the instrument rule and the robust z-score."""
    median = np.median(residual)
    mad = 1.4826 * np.median(np.abs(residual - median))
    return (residual > np.maximum(OUTLIER_U * bound, RESIDUAL_FLOOR_MM)) & (residual > median + OUTLIER_MAD * mad)


def _turn_ratio(fit: CircleFit, points: np.ndarray, q: np.ndarray) -> float:
    """Least-squares slope of the target's angle about the fitted normal against the joint variable ``q``."""
    normal = fit.normal
    radial = points - fit.centre
    e1 = radial[0] - np.dot(radial[0], normal) * normal
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    angle = np.unwrap(np.arctan2(radial @ e2, radial @ e1))
    dq = q - q.mean()
    slope = float(np.dot(dq, angle - angle.mean()) / np.dot(dq, dq))
    return abs(slope)


def _unit_hint(ratio: float) -> str | None:
    for name, factor in _UNITS.items():
        if abs(ratio / factor - 1.0) < 0.15:
            return name
    return None


def _repeated_rows(capture: Capture, findings: list[str]) -> np.ndarray:
    """Rows whose readings and point repeat an earlier row exactly (0-based); a finding, or an error when they are
    half the file or more."""
    src = capture.source
    table = np.concatenate([capture.readings, capture.points], axis=1)
    _, first, inverse = np.unique(table, axis=0, return_index=True, return_inverse=True)
    inverse = np.ravel(inverse)
    duplicates = np.flatnonzero(first[inverse] != np.arange(capture.n_points))
    if duplicates.size * 2 >= capture.n_points:
        pair = duplicates[0]
        raise InputError(
            f"{src}: {duplicates.size} of {capture.n_points} rows repeat an earlier row exactly (e.g. point "
            f"{pair + 1} = point {first[inverse[pair]] + 1}): the file holds the same measurements twice "
            "(a file appended to itself?); remove the copies"
        )
    if duplicates.size:
        findings.append(
            f"{src}: {point_rows(duplicates)} repeat earlier rows exactly; a real measurement never repeats "
            "to the last digit (copied rows?)"
        )
    return duplicates


def _scale_ratio(measured: np.ndarray, predicted: np.ndarray, robot: RobotModel, src: str, findings: list[str]) -> float:
    """RMS spread of the measured points about their centroid over the nominal prediction's (invariant to the
    tracker pose); a finding outside 0.8..1.25, an error outside 0.5..2."""
    spread = np.sqrt(np.mean(np.sum((measured - measured.mean(axis=0)) ** 2, axis=-1)))
    nominal_spread = np.sqrt(np.mean(np.sum((predicted - predicted.mean(axis=0)) ** 2, axis=-1)))
    ratio = float(spread / nominal_spread) if nominal_spread > 0 else 1.0
    if not 0.5 <= ratio <= 2.0:
        hint = _unit_hint(ratio)
        cause = (
            f"the coordinates look like {hint}; robotcal reads millimetres"
            if hint
            else f"a capture of another robot, or of robot {robot.name!r} in other units?"
        )
        raise InputError(
            f"{src}: the measured points spread {spread:.4g} mm about their centroid, {ratio:.3g} times the "
            f"{nominal_spread:.4g} mm that nominal robot {robot.name!r} predicts: {cause}"
        )
    if not 0.8 <= ratio <= 1.25:
        findings.append(
            f"{src}: the measured points spread {ratio:.3g} times what nominal robot {robot.name!r} predicts "
            f"({spread:.4g} mm vs {nominal_spread:.4g} mm RMS about the centroid): a capture of another robot "
            "or another reflector set-up?"
        )
    return ratio


def _residual_finding(
    label: str, rows: np.ndarray, residual: np.ndarray, flagged: np.ndarray, bound: float, findings: list[str]
) -> None:
    """A finding when a circle has outliers (``flagged`` rows) or its RMS distance to the fitted circle is over
    ``OUTLIER_U`` times the instrument's median ``U`` [mm] of its points (``bound``), at least ``RESIDUAL_FLOOR_MM``."""
    total_rms = float(np.sqrt(np.mean(residual**2)))
    limit = max(OUTLIER_U * bound, RESIDUAL_FLOOR_MM)
    if flagged.size or total_rms > limit:
        worst = rows[np.argsort(residual)[::-1][: max(flagged.size, 3)]]
        named = flagged if flagged.size else worst
        residual_of = dict(zip(rows.tolist(), residual.tolist(), strict=True))
        findings.append(
            f"{label}: RMS distance to the fitted circle {total_rms:.3g} mm against the instrument's "
            f"U = {bound:.3g} mm; "
            + (f"outliers at {point_rows(flagged)}" if flagged.size else f"largest at {point_rows(named)}")
            + f" (residuals {', '.join(f'{residual_of[r]:.3g}' for r in named[:6])} mm): a mis-measurement, "
            "a moved target or a loose reflector? `robotcal identify --reject-outliers` drops outliers"
        )


def check_capture(
    capture: Capture,
    robot: RobotModel,
    reflector: ReflectorMount,
    instrument: Instrument,
    *,
    options: CPAOptions | None = None,
) -> PlausibilityReport:
    """Check a CPA capture against the nominal robot, the declared reflector and the instrument.

    Parameters
    ----------
    capture : Capture
        Points [mm] in the tracker frame and readings [rad].
    robot : RobotModel
    reflector : ReflectorMount
        The reflector the scenario declares.
    instrument : Instrument
        Gives ``U(L)`` [mm] for the residual checks.
    options : CPAOptions, optional
        Circle-fit method and the structural tolerances of :func:`prepare_cpa`.

    Returns
    -------
    PlausibilityReport

    Raises
    ------
    InputError
        Wrong units, readings in radians, a reflector on its axis, a file appended to itself.

    Warns
    -----
    PlausibilityWarning
        Scale or radius off, readings scaled, duplicated rows, outliers or a circle RMS far above U.
    """
    options = CPAOptions() if options is None else options
    src = capture.source
    structure = prepare_cpa(capture, robot, reflector, options)  # structure and coordinate checks first
    findings: list[str] = []

    duplicates = _repeated_rows(capture, findings)
    measured = capture.points
    predicted = structure.nominal_points
    ratio = _scale_ratio(measured, predicted, robot, src, findings)

    n = len(structure.circle_indices)
    turn = np.zeros(n)
    radius = np.zeros(n)
    nominal_radius = np.zeros(n)
    rms = np.zeros(n)
    bound = np.zeros(n)
    outliers = []
    for joint, rows in enumerate(structure.circle_indices):
        label = f"{src}: circle {joint + 1} (J{joint + 1})"
        try:
            nominal_fit = fit_circle_3d(predicted[rows], method="algebraic")
            nominal_radius[joint] = float(nominal_fit.radius)
        except DegenerateGeometryError:
            nominal_radius[joint] = 0.0
        if nominal_radius[joint] < 1e-3:
            raise InputError(
                f"{label}: the scenario's reflector for this circle lies on axis {joint + 1} (nominal radius "
                f"{nominal_radius[joint]:.2g} mm), so the target cannot trace a circle; check `reflector_mm`"
            )
        try:
            fit = fit_circle_3d(measured[rows], method=options.circle_fit)
        except DegenerateGeometryError as exc:
            raise DegenerateGeometryError(f"{label}, {point_rows(rows)}: {exc}") from None
        radius[joint] = float(fit.radius)
        turn[joint] = _turn_ratio(fit, measured[rows], structure.model_q[rows, joint])
        if abs(turn[joint] / np.rad2deg(1.0) - 1.0) < 0.15:
            raise InputError(
                f"{label}: the target turned {turn[joint]:.3g} times the change of the J{joint + 1} readings: "
                "the readings look like radians; the capture CSV holds degrees"
            )
        if not 2 / 3 <= turn[joint] <= 1.5:
            findings.append(
                f"{label}: the target turned {turn[joint]:.3g} times the change of the J{joint + 1} readings "
                "(1 expected): readings of another joint, or scaled readings?"
            )
        difference = radius[joint] - nominal_radius[joint]
        if abs(difference) > max(10.0, 0.2 * nominal_radius[joint]):
            findings.append(
                f"{label}: fitted radius {radius[joint]:.4g} mm, but the scenario's reflector gives "
                f"{nominal_radius[joint]:.4g} mm: another reflector position, or a capture of another robot?"
            )
        residual = _residuals(fit)
        point_bound = instrument.error_bound(measured[rows])
        bound[joint] = float(np.median(point_bound))
        rms[joint] = float(fit.circle_rms)  # type: ignore[arg-type]  # fitted with residuals
        flagged = rows[_outlier_mask(residual, point_bound)]
        outliers.append(flagged)
        _residual_finding(label, rows, residual, flagged, bound[joint], findings)
    for message in findings:
        warnings.warn(message, PlausibilityWarning, stacklevel=2)
    return PlausibilityReport(
        scale_ratio=ratio,
        turn_ratio=turn,
        radius_mm=radius,
        nominal_radius_mm=nominal_radius,
        circle_rms_mm=rms,
        bound_mm=bound,
        outliers=tuple(outliers),
        duplicates=duplicates,
        findings=tuple(findings),
    )


def reject_outliers(
    capture: Capture, instrument: Instrument, *, circle_fit: Literal["geometric", "algebraic"] = "geometric"
) -> tuple[Capture, np.ndarray]:
    """Remove per-circle outliers (rule in the module docstring), refit, and remove once more.

    At most :data:`MAX_REJECTED_SHARE` of a circle's points (the largest residuals first) and never
    below 3 points per circle are removed. Free poses (circle 0) are kept.

    Returns
    -------
    capture : Capture
        The capture without the rejected rows (same source and seed).
    removed : ndarray of int
        0-based rows of the input capture that were removed, sorted.
    """
    keep = np.ones(capture.n_points, dtype=bool)
    for _ in range(2):
        for circle in np.unique(capture.circle[capture.circle > 0]):
            all_rows = np.flatnonzero(capture.circle == circle)
            rows = all_rows[keep[all_rows]]
            if rows.size < 4:
                continue
            try:
                fit = fit_circle_3d(capture.points[rows], method=circle_fit)
            except DegenerateGeometryError:
                continue
            residual = _residuals(fit)
            flagged = np.flatnonzero(_outlier_mask(residual, instrument.error_bound(capture.points[rows])))
            budget = min(int(MAX_REJECTED_SHARE * all_rows.size) - int(np.sum(~keep[all_rows])), rows.size - 3)
            if flagged.size and budget > 0:
                worst = flagged[np.argsort(residual[flagged])[::-1][:budget]]
                keep[rows[worst]] = False
    removed = np.flatnonzero(~keep)
    return capture.select(keep), removed  # every column kept (targets, U(95), sessions, orientations)
