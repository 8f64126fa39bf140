"""Fit health: does a fit explain the data, and if not, is it the model or the fit that failed?

After every fit (CPA and refinement) robotcal gives one verdict on one scale, the same word in the
console, the parameter JSON and the report:

========== ===========================================================================================
OK          the residual is what the stated noise explains (ratio <= :data:`RESIDUAL_RATIO_LIMIT`)
MODEL ERROR the fit is sound (converged, well conditioned, residual physically plausible) but the
            residual is well above the noise: the kinematic model does not hold this robot. The
            unexplained part is stated in mm, with what would hold it (gravity compliance of J2/J3,
            joint-angle errors, backlash) or a stated noise that is too optimistic.
FAILED      the fit cannot be trusted: not converged, ill conditioned (:data:`CONDITION_LIMIT`), or a
            residual beyond anything physical for a calibrated industrial robot
            (:data:`PHYSICAL_RESIDUAL_MM` per coordinate: a wrong unit, robot file or target, points of
            another pose, a jumped reflector).
NOT CHECKED no stated noise to compare with (no instrument and no U(95)); the other tests still ran.
========== ===========================================================================================

The figures:

* **residual ratio** ``rho = s / u``: ``s`` the residual standard deviation per coordinate the fit leaves
  (refinement: its ``sigma``, the square root of the residual sum of squares over the degrees of freedom,
  weighted by ``1/u_k^2`` when the points carry U(95); CPA: the RMS distance of the points to their fitted
  circles over ``sqrt(2)``, since a point's offset from a fitted circle has two noise components, across
  the plane and along the radius, the third being along the circle) and ``u`` the stated standard
  uncertainty per coordinate, from the points' U(95) (``u_k = U_k / 2``, k = 2, normal) or else the
  instrument (``U(L) / sqrt(3)`` uniform, ``U(L) / k`` normal), RMS over the points. An honest fit has
  ``rho ~ 1`` with a relative spread of ``1/sqrt(2 dof)``, a few per cent with 100 or more residuals, so a
  ratio above 3 is beyond chance. The thesis's own joint errors (eccentricities and backlash of a few um
  to 0.01 deg) stay below it; real robots do not (a small industrial arm measured by a laser tracker: 14.5
  after a good geometric fit, its residual being gravity sag).
* **unexplained** part of the residual, ``sqrt(3 (s^2 - u^2))`` [mm RMS per point]: what the model leaves
  once the noise is taken out.
* **conditioning** of the column-scaled Jacobian (1 mm for lengths, ``1/L`` rad for angles: a unit step
  moves the points by about 1 mm), above :data:`CONDITION_LIMIT` = 1e8: a direction of the parameters is
  then determined to no better than ``1e8`` times the noise's effect, i.e. not at all (a broken real fit
  stopped at 8.5e8, the thesis captures are at 1e2-1e4).

**Small circles (CPA)** are judged by their effect in millimetres. The direction of a circle's axis comes from
the plane fit; its standard uncertainty is ``u_axis = u / sqrt(lambda_2)`` [rad], ``u`` the stated noise per
coordinate or the circle's own out-of-plane RMS if larger, ``lambda_2`` the smaller in-plane eigenvalue of the
points' scatter matrix ``sum (p - mean)(p - mean)^T`` (a full circle of N points of radius r: ``lambda_2 = N r^2
/ 2``). The axis is pinned at the circle's centre, so the tilt moves the feet of the common normals with the
neighbouring axes (where the parameters of the two joint pairs are taken: :func:`common_normal_feet`; the robot
origin for axis 1, the flange for the last) by ``u_axis`` times their distance from the centre, the lever: the
parameters of those pairs, and the arm they carry, are off by that many millimetres. Above
:data:`CPA_EFFECT_LIMIT_MM` = 2 mm the verdict is FAILED and the parameters are named under ``poorly_determined``
with the effect and the radius that would bring it under the limit (``u_axis`` falls as ``1/r``). The same tilt
judged against a fixed angle missed real 1.6 mm wrist circles: 0.3 deg over a 1,280 mm lever left J3.a 7 mm off.
The effect matches the thesis's Monte Carlo: on the iGPS capture circle 4 (2.6 deg over 291 mm) gives 13 mm,
Table 5.7 u(J4.a) = 12.6 mm; circle 1 3.9 mm, u(J1.a) = 3.7 mm. The built-in laser-tracker captures stay below
1.1 mm (circle 4, 5 mm radius).

A **registered base frame** (CPA with ``base_frame = "registered"``) is judged against the noise too: the
identified model's points registered on the measured ones leave an RMS residual per point that the noise alone
would make ``sqrt(3) u``. Above :data:`RESIDUAL_RATIO_LIMIT` times that it is said in ``notes`` with both figures,
the verdict unchanged: CPA's own parameter uncertainty already leaves 4-5 times the noise on the noise-only
kr5-demo capture (0.07 mm), and the last joint's parameters and the target offsets that CPA cannot see add to
it (real cells: 0.8-0.9 mm); the refinement, which sees every point, is what places the points absolutely.

Poorly determined refined quantities are named the same way, by their effect in mm: ``u_k e_k``, with ``e_k`` the
RMS displacement of the points per unit of quantity k (the norm of its Jacobian column over the points,
``RefinementResult.identifiability.effect``), is what one standard uncertainty of that quantity alone does to
the points [mm]. ``u_k`` is taken at the stated noise (the fit's u times ``u / sigma``): what the capture fails to
determine, not what a model error inflates (a geometric fit of a sagging robot at 21 times the noise listed 7
parameters that its 30 poses determine well). Above :data:`U_EFFECT_LIMIT_MM` = 0.1 mm (several times a laser
tracker's noise, the size of the errors a calibration is there to remove) the quantity is named with its u, that
effect and what would determine it better, worded for its kind: a joint's geometry "a wider arc" only when the
joint swept less than :data:`NARROW_SWEEP_DEG`, else the quantity it is confounded with; a harmonic term its
joint's range, never the load; a compliance poses of different gravity torque. The demo's refined parameters stay
below 0.01 mm.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import FitHealthError, FitHealthWarning
from robotcal.kinematics.forward import joint_frames
from robotcal.kinematics.model import LENGTH_KINDS

__all__ = [
    "CONDITION_LIMIT",
    "CPA_EFFECT_LIMIT_MM",
    "PHYSICAL_RESIDUAL_MM",
    "RESIDUAL_RATIO_LIMIT",
    "VERDICTS",
    "FitHealth",
    "FitHealthError",
    "FitHealthWarning",
    "Verdict",
    "assess_fit",
    "model_advice",
    "circle_axis_uncertainty",
    "cpa_health",
    "refine_health",
    "report_health",
    "stated_noise",
]

#: Largest residual standard deviation, in units of the stated noise, of a fit that explains the data.
RESIDUAL_RATIO_LIMIT = 3.0
#: Largest condition number of the column-scaled Jacobian of a fit whose parameters are all determined.
CONDITION_LIMIT = 1e8
#: Largest residual standard deviation per coordinate [mm] a sound fit of a real robot can leave: a calibrated
#: industrial arm's model errors (gravity sag, joint errors) are tenths of a millimetre.
PHYSICAL_RESIDUAL_MM = 1.0
#: Largest effect [mm] of one standard uncertainty of a CPA circle's axis direction on the parameters of its pairs
#: (module notes): an uncalibrated industrial arm's own geometric errors are tenths of a millimetre to 1-2 mm, so
#: parameters uncertain by more are no better than the nominal ones.
CPA_EFFECT_LIMIT_MM = 2.0
#: Largest effect on the points [mm] of one standard uncertainty of a refined quantity (module notes).
U_EFFECT_LIMIT_MM = 0.1
#: A joint that swept less than this in a capture [deg] determines its own parameters poorly from its range alone.
NARROW_SWEEP_DEG = 45.0

Verdict = Literal["OK", "MODEL ERROR", "FAILED", "NOT CHECKED"]
#: The verdicts, best first.
VERDICTS: tuple[Verdict, ...] = ("OK", "NOT CHECKED", "MODEL ERROR", "FAILED")


@dataclass(frozen=True, slots=True, kw_only=True)
class FitHealth:
    """The verdict of :func:`assess_fit` with its figures (JSON-ready through :meth:`as_dict`).

    Attributes
    ----------
    what : str
        The fit, e.g. ``"refinement (points criterion)"``.
    verdict : {"OK", "MODEL ERROR", "FAILED", "NOT CHECKED"}
    residual_sd_mm : float
        Residual standard deviation per coordinate the fit leaves [mm].
    noise_sd_mm : float or None
        Stated standard uncertainty per coordinate [mm] (None: no instrument and no U(95)).
    noise_source : str
    ratio : float or None
        ``residual_sd_mm / noise_sd_mm``.
    unexplained_mm : float or None
        ``sqrt(3 (s^2 - u^2))``, the RMS per point the model leaves beyond the noise [mm] (0 when the
        residual is at or below the noise; None without a stated noise).
    condition_number : float or None
    converged : bool
    problems : tuple of str
        Why the verdict is not OK: one sentence per failed test, with the figures.
    advice : tuple of str
        What to do about it.
    poorly_determined : tuple of str
        Parameters or circles the data leave poorly determined, whatever the verdict (named with what to
        measure instead).
    notes : tuple of str
        Figures judged against the noise that do not change the verdict (a CPA base registration's residual).
    """

    what: str
    verdict: Verdict
    residual_sd_mm: float
    noise_sd_mm: float | None
    noise_source: str
    ratio: float | None
    unexplained_mm: float | None
    condition_number: float | None
    converged: bool = True
    problems: tuple[str, ...] = ()
    advice: tuple[str, ...] = ()
    poorly_determined: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def healthy(self) -> bool:
        """OK or NOT CHECKED: nothing found wrong."""
        return self.verdict in ("OK", "NOT CHECKED")

    @property
    def failed(self) -> bool:
        return self.verdict == "FAILED"

    def line(self) -> str:
        """The verdict with its key figure, one line for a console: ``"MODEL ERROR: residual 14.5 x ..."``."""
        if self.ratio is None:
            figure = f"residual {self.residual_sd_mm:.4g} mm per coordinate, not compared ({self.noise_source})"
        else:
            figure = f"residual {self.ratio:.3g} x the stated noise ({self.noise_source})"
            if self.unexplained_mm:
                figure += f", {self.unexplained_mm:.3g} mm RMS per point unexplained"
        if self.condition_number is not None:
            figure += f", condition number {self.condition_number:.3g}"
        return f"{self.verdict}: {figure}"

    def as_dict(self) -> dict:
        def finite(value):
            return None if value is None or not np.isfinite(value) else float(value)

        return {
            "fit": self.what,
            "verdict": self.verdict,
            "healthy": self.healthy,
            "residual_sd_mm": finite(self.residual_sd_mm),
            "noise_sd_mm": finite(self.noise_sd_mm),
            "noise_source": self.noise_source,
            "ratio": finite(self.ratio),
            "ratio_limit": RESIDUAL_RATIO_LIMIT,
            "unexplained_mm": finite(self.unexplained_mm),
            "physical_residual_limit_mm": PHYSICAL_RESIDUAL_MM,
            "condition_number": finite(self.condition_number),
            "condition_limit": CONDITION_LIMIT,
            "converged": bool(self.converged),
            "problems": list(self.problems),
            "advice": list(self.advice),
            "poorly_determined": list(self.poorly_determined),
            "notes": list(self.notes),
        }


#: The models ``robotcal refine --model`` fits (identification.model_choice), each with the joint-model groups it holds.
_MODEL_GROUPS = {
    "geometric": (),
    "compliance": ("compliance",),
    "harmonic": ("harmonic",),
    "compliance+harmonic": ("compliance", "harmonic"),
}
_GROUP_ADVICE = {
    "compliance": "`--model compliance` for gravity sag of J2/J3",
    "harmonic": "`--model harmonic` for joint-angle errors",
}


def model_advice(fitted_model: str | None = None) -> str:
    """What to do when the residual of a fit of ``fitted_model`` exceeds the stated noise (MODEL ERROR): the
    models it does not hold yet (never the one just fitted), then what no model of robotcal's holds."""
    held = _MODEL_GROUPS.get(fitted_model or "geometric", ())
    missing = [advice for group, advice in _GROUP_ADVICE.items() if group not in held]
    name = f"the {fitted_model or 'geometric'} model"
    rest = (
        "see the joint errors that no joint model holds (axis eccentricity, backlash: `robotcal joints` on a "
        "bidirectional capture), or check that the stated noise is not too optimistic (the instrument's alone leaves "
        "out the robot's repeatability)"
    )
    if not missing:
        return f"{name} (every joint model robotcal fits) does not hold what remains: {rest}"
    both = "" if held else ", `--model compliance+harmonic` for both"
    return (
        f"{name} does not hold this robot: refine with a model that holds what remains ({', '.join(missing)}{both}, "
        f"`--model auto` to let cross-validation choose), {rest}"
    )


def assess_fit(
    what: str,
    residual_sd_mm: float,
    noise_sd_mm: float | None,
    *,
    noise_source: str = "",
    condition_number: float | None = None,
    converged: bool = True,
    poorly_determined=(),
    fitted_model: str | None = None,
    undetermined: Sequence[str] = (),
) -> FitHealth:
    """The verdict of a fit (module docstring): FAILED, MODEL ERROR, OK or NOT CHECKED.

    Parameters
    ----------
    what : str
        Name of the fit for the messages.
    residual_sd_mm : float
        Residual standard deviation per coordinate [mm] (module notes).
    noise_sd_mm : float or None
        Stated standard uncertainty per coordinate [mm]; None: the residual is not compared (NOT CHECKED,
        unless another test fails).
    condition_number : float, optional
        Of the column-scaled Jacobian; None skips the test.
    converged : bool
        Whether the solver met its tolerance.
    poorly_determined : sequence of str
        Findings that name poorly determined parameters or circles (reported, verdict unchanged).
    fitted_model : str, optional
        The model fitted (``geometric``, ``compliance``, ...): a MODEL ERROR's advice names the models it lacks
        (:func:`model_advice`), never itself.
    undetermined : sequence of str
        Findings that make the fit FAILED: parameters the data leave off by more than a calibration removes
        (a CPA circle too small for its lever, module notes); the details are in ``poorly_determined``.
    """
    residual = float(residual_sd_mm)
    noise = None if noise_sd_mm is None or not noise_sd_mm > 0 else float(noise_sd_mm)
    ratio = unexplained = None
    if noise is not None and math.isfinite(residual):
        ratio = residual / noise
        unexplained = math.sqrt(3.0 * max(residual**2 - noise**2, 0.0))
    failed, model = [], []
    if not converged:
        failed.append("the solver did not converge")
    if condition_number is not None and (not math.isfinite(condition_number) or condition_number > CONDITION_LIMIT):
        failed.append(
            f"the scaled Jacobian's condition number {condition_number:.3g} exceeds {CONDITION_LIMIT:.0e}: some "
            "combination of the parameters is not determined by the data (likely: too few or too similar poses, "
            "a target offset confounded with the last joint's parameters, or joints that hardly move)"
        )
    failed.extend(undetermined)
    if not math.isfinite(residual) or residual > PHYSICAL_RESIDUAL_MM:
        failed.append(
            f"the residual ({residual:.4g} mm per coordinate) is beyond what a calibrated robot's model errors "
            f"can leave ({PHYSICAL_RESIDUAL_MM:g} mm): likely a wrong unit, robot file, target or target offset, "
            "wrong reading signs or offsets, points of another pose or target mixed in, outliers, or a local "
            "minimum from a poor start"
        )
    elif ratio is not None and ratio > RESIDUAL_RATIO_LIMIT:
        model.append(
            f"the residual ({residual:.4g} mm per coordinate) is {ratio:.3g} times the stated noise "
            f"({noise:.4g} mm, {noise_source}), above {RESIDUAL_RATIO_LIMIT:g}: {unexplained:.3g} mm RMS per point "
            "is not explained by the model"
        )
    advice: tuple[str, ...]
    if failed:
        verdict: Verdict = "FAILED"
        if len(failed) == len(undetermined):  # nothing wrong but what the capture leaves undetermined
            advice = ("do not use the parameters named poorly determined; measure again as said there",)
        else:
            advice = ("do not use these parameters; correct the input or the start and fit again",)
        problems = failed + model
    elif model:
        verdict, problems, advice = "MODEL ERROR", model, (model_advice(fitted_model),)
    elif ratio is None:
        verdict, problems, advice = "NOT CHECKED", [], ("give the instrument (scenario [instrument]) or U(95) per point",)
    else:
        verdict, problems, advice = "OK", [], ()
    return FitHealth(
        what=what,
        verdict=verdict,
        residual_sd_mm=residual,
        noise_sd_mm=noise,
        noise_source=noise_source,
        ratio=ratio,
        unexplained_mm=unexplained,
        condition_number=None if condition_number is None else float(condition_number),
        converged=bool(converged),
        problems=tuple(problems),
        advice=tuple(advice),
        poorly_determined=tuple(poorly_determined),
    )


def report_health(health: FitHealth, *, source: str = "", strict: bool = False) -> FitHealth:
    """Warn (:class:`FitHealthWarning`) when the verdict is MODEL ERROR or FAILED or something is poorly
    determined; with ``strict`` raise :class:`FitHealthError` instead unless the verdict is OK or NOT CHECKED.
    Returns ``health``."""
    prefix = f"{source}: " if source else ""
    if not health.healthy:
        text = f"{prefix}{health.what}: fit health {health.verdict}: " + "; ".join(health.problems + health.advice)
        if strict:
            raise FitHealthError(text)
        warnings.warn(text, FitHealthWarning, stacklevel=3)  # the caller of robotcal.identify or refine
    if health.poorly_determined:
        warnings.warn(
            f"{prefix}{health.what}: poorly determined: " + "; ".join(health.poorly_determined),
            FitHealthWarning,
            stacklevel=3,
        )
    return health


#: ISO 9283 pose repeatability RP = mean(l) + 3 s_l in units of the standard deviation per coordinate of an
#: isotropic normal scatter: the distance l to the barycentre is then sigma times a chi variable of 3 degrees of
#: freedom (Maxwell), of mean 2 sqrt(2 / pi) sigma and standard deviation sqrt(3 - 8 / pi) sigma, so
#: RP = (2 sqrt(2 / pi) + 3 sqrt(3 - 8 / pi)) sigma = 3.616 sigma (the barycentre of many cycles taken as exact).
RP_PER_SIGMA = 2.0 * math.sqrt(2.0 / math.pi) + 3.0 * math.sqrt(3.0 - 8.0 / math.pi)


def repeatability_sigma(repeatability_mm: float | None) -> float:
    """Standard deviation per coordinate [mm] of a robot's pose scatter from its ISO 9283 RP [mm]
    (:data:`RP_PER_SIGMA`, isotropic normal scatter); 0 when not stated."""
    return 0.0 if repeatability_mm is None else float(repeatability_mm) / RP_PER_SIGMA


def stated_noise(capture: Capture, instrument=None, repeatability_mm: float | None = None) -> tuple[float | None, str]:
    """RMS stated standard uncertainty per coordinate of the capture's points [mm], and its source: the
    points' U(95) / 2 (k = 2, normal) when given, else ``instrument``'s U(L); None without both.

    The noise budget: with the robot's ISO 9283 pose repeatability RP ``repeatability_mm`` stated, every point
    also scatters by ``sigma_r = RP / 3.616`` per coordinate (:func:`repeatability_sigma`), and the expected
    noise is ``sqrt(u_instrument^2 + sigma_r^2)`` (alone when the capture has neither instrument nor U(95)).
    """
    sigma_r = repeatability_sigma(repeatability_mm)
    robot = f" + repeatability RP {repeatability_mm:g} mm (sigma {sigma_r * 1e3:.3g} um)" if sigma_r > 0 else ""
    if capture.u95 is not None:
        u2 = float(np.mean((np.asarray(capture.u95) / 2.0) ** 2))
        return math.sqrt(u2 + sigma_r**2), "U(95) / 2 of the points (k = 2)" + robot
    if instrument is not None:
        sd = instrument.standard_uncertainty(capture.points)
        return math.sqrt(float(np.mean(np.asarray(sd) ** 2)) + sigma_r**2), f"instrument {instrument.name}" + robot
    if sigma_r > 0:
        return sigma_r, robot.removeprefix(" + ")
    return None, "no instrument and no U(95)"


def circle_axis_uncertainty(points, noise_sd_mm: float) -> tuple[float, float]:
    """Standard uncertainty of a circle's axis direction [rad] and the circle's RMS radius [mm].

    ``points (n, 3)`` [mm] of one circle; ``u_axis = u / sqrt(lambda_2)`` with ``lambda_2`` the smaller
    in-plane eigenvalue of the scatter matrix (module notes).
    """
    points = np.asarray(points, dtype=float)
    centred = points - points.mean(axis=0)
    eigenvalues = np.linalg.eigvalsh(centred.T @ centred)  # ascending: normal, then the two in-plane ones
    in_plane = max(float(eigenvalues[1]), 1e-300)
    radius = float(np.sqrt((eigenvalues[1] + eigenvalues[2]) / max(points.shape[0], 1)))
    return float(noise_sd_mm) / np.sqrt(in_plane), radius


def common_normal_feet(result) -> list[np.ndarray]:
    """Per joint axis of a CPA result, the points ``(k, 3)`` [mm, tracker frame] on it where the parameters of its
    pairs are taken: the feet of the common normals with the previous axis (the robot origin for axis 1) and with
    the next one (the flange origin for the last axis), at the reference configuration of the identified model."""
    robot = result.parameters.robot
    values = np.asarray(result.parameters.values, dtype=float)
    q = robot.model_joint_variables(np.asarray(result.reference_readings, dtype=float)[None, :])
    frames = np.asarray(result.tracker_from_base, dtype=float) @ joint_frames(values, q)[0]
    origin, x_axis = frames[:, :3, 3], frames[:, :3, 0]
    return [np.stack([origin[j], origin[j + 1] - values[j, 2] * x_axis[j + 1]]) for j in range(robot.n_joints)]


def _small_circles(result, capture: Capture, noise: float | None) -> list[str]:
    """The circles whose axis direction uncertainty moves the parameters of their pairs by more than
    :data:`CPA_EFFECT_LIMIT_MM` (module notes), each named with that effect and the parameters it moves."""
    names = result.parameters.robot.parameter_names
    identified = np.asarray(result.parameters.identified, dtype=bool)
    found = []
    for joint, (fit, feet) in enumerate(zip(result.circle_fits, common_normal_feet(result), strict=True)):
        rows = np.flatnonzero(capture.circle == joint + 1)
        scatter = max(noise or 0.0, float(fit.plane_rms))  # the stated noise, or the circle's own if larger
        if rows.size < 3 or not scatter > 0.0:
            continue
        u_axis, _ = circle_axis_uncertainty(capture.points[rows], scatter)
        lever = float(np.max(np.linalg.norm(feet - np.asarray(fit.centre, dtype=float), axis=1)))
        effect = u_axis * lever
        if not effect > CPA_EFFECT_LIMIT_MM:
            continue
        first = max(joint - 1, 0)  # the rows of the pairs (joint - 1, joint) and (joint, joint + 1)
        moved = [names[first * 5 + k] for k in np.flatnonzero(identified[first : joint + 1].ravel())]
        radius = float(fit.radius)
        found.append(
            f"{', '.join(moved)} (about {effect:.3g} mm): circle {joint + 1} (radius {radius:.3g} mm, {rows.size} "
            f"points) leaves the J{joint + 1} axis direction uncertain by {math.degrees(u_axis):.3g} deg, which moves "
            f"the common normals {lever:.0f} mm along the axis by {effect:.3g} mm (> {CPA_EFFECT_LIMIT_MM:g} mm): "
            f"put the target farther from axis {joint + 1} (a radius of {radius * effect / CPA_EFFECT_LIMIT_MM:.3g} "
            "mm or more), sweep a wider arc or measure more points"
        )
    return found


def cpa_health(result, capture: Capture, instrument=None, repeatability_mm: float | None = None) -> FitHealth:
    """Fit health of a CPA identification: the RMS distance of the points to their fitted circles against
    the stated noise (:func:`stated_noise`), the circle fits' convergence, the circles whose axis direction
    uncertainty moves the parameters of their pairs by more than :data:`CPA_EFFECT_LIMIT_MM` (FAILED, named with
    that effect), and a registered base frame whose residual is far above the noise (MODEL ERROR)."""
    noise, noise_source = stated_noise(capture, instrument, repeatability_mm)
    squares, count = 0.0, 0
    for joint, fit in enumerate(result.circle_fits):
        rows = np.flatnonzero(capture.circle == joint + 1)
        squares += rows.size * (float(fit.plane_rms) ** 2 + float(fit.circle_rms) ** 2)
        count += rows.size
    residual = float(np.sqrt(squares / max(count, 1) / 2.0))  # two noise components per circle point
    converged = all(bool(np.all(fit.converged)) for fit in result.circle_fits)
    small = _small_circles(result, capture, noise)
    undetermined: tuple[str, ...] = ()
    if small:
        undetermined = (
            f"{len(small)} circle{'s' if len(small) > 1 else ''} too small for {'their' if len(small) > 1 else 'its'} "
            f"lever: parameters off by more than {CPA_EFFECT_LIMIT_MM:g} mm (named under poorly determined)",
        )
    health = assess_fit(
        "CPA (circle fits)",
        residual,
        noise,
        noise_source=noise_source,
        converged=converged,
        poorly_determined=small,
        undetermined=undetermined,
    )
    return dataclasses.replace(health, notes=_registration_note(result.registration_rms, noise, noise_source))


def _registration_note(rms: float | None, noise: float | None, noise_source: str) -> tuple[str, ...]:
    """A registered base frame whose RMS residual per point [mm] is more than :data:`RESIDUAL_RATIO_LIMIT` times
    the stated noise per point (``sqrt(3) u``), said with both figures (module notes); nothing otherwise."""
    if rms is None or noise is None or not np.isfinite(rms) or rms <= RESIDUAL_RATIO_LIMIT * math.sqrt(3.0) * noise:
        return ()
    expected = math.sqrt(3.0) * noise
    return (
        f"the base frame registered with the identified model leaves {rms:.3g} mm RMS per point, {rms / expected:.3g} "
        f"times the stated noise ({expected:.3g} mm per point, {noise_source}): the CPA model places the points "
        "absolutely only to that (its own uncertainty, the last joint's parameters and target offsets it cannot "
        "see, gravity sag); refine over every point (`robotcal refine`) before using it absolutely",
    )


def refine_health(
    fit, identifiability, uncertainty, *, criterion: str, converged: bool, model: str | None, capture: Capture,
    instrument=None, repeatability_mm: float | None = None,
) -> FitHealth:  # fmt: skip
    """Fit health of a refinement: its residual standard deviation per coordinate (``uncertainty.sigma``, weighted
    by the points' U(95) when given; the RMS residual ``fit.residual_rms_coordinate`` when no degree of freedom is
    left) against the stated noise, its convergence, the condition number of its scaled Jacobian, and the
    quantities the capture leaves poorly determined at the stated noise (module notes).

    ``fit``, ``identifiability``, ``uncertainty``: the sub-records of the refinement
    (:class:`robotcal.identification.records.RefinementResult`), from which the result is then made.
    """
    noise, noise_source = stated_noise(capture, instrument, repeatability_mm)
    sigma = uncertainty.sigma
    residual = float(sigma) if np.isfinite(sigma) else float(fit.residual_rms_coordinate)
    if criterion == "distances" and not np.isfinite(sigma):
        residual /= np.sqrt(2.0)  # a distance's error has the noise of two points
    health = assess_fit(
        f"refinement ({criterion} criterion)",
        residual,
        noise,
        noise_source=noise_source,
        condition_number=identifiability.condition_number,
        converged=bool(converged),
        fitted_model=model,
    )
    if health.verdict == "FAILED":  # the u of a failed fit say nothing about the capture
        return health
    found = _poorly_refined(identifiability, uncertainty, capture, noise)
    return dataclasses.replace(health, poorly_determined=tuple(found))


def _poorly_refined(identifiability, uncertainty, capture: Capture, noise: float | None) -> list[str]:
    """The refined quantities that the capture leaves poorly determined (module notes): whose standard uncertainty
    at the stated noise moves the points by more than :data:`U_EFFECT_LIMIT_MM`, worst first, each with its u,
    that effect and what would determine it better."""
    covariance = uncertainty.covariance
    if covariance is None or identifiability.effect is None:
        return []
    sigma = float(uncertainty.sigma)
    # the capture's own u: the fit's u with the residual at the stated noise (a model error inflates them all)
    scale = noise / sigma if noise is not None and math.isfinite(sigma) and sigma > 0.0 else 1.0
    u_all = np.sqrt(np.clip(np.diag(covariance), 0.0, None)) * scale
    effect = u_all * np.asarray(identifiability.effect, dtype=float)
    sweep = np.rad2deg(np.ptp(np.asarray(capture.readings, dtype=float), axis=0))
    found = []
    for k in np.argsort(-effect):
        if not effect[k] > U_EFFECT_LIMIT_MM:
            break
        name, u = identifiability.free_names[k], float(u_all[k])
        unit = "mm" if _is_length(name) else "rad/(N m)" if name.endswith(".k") else "deg"
        shown = f"{u:.3g} {unit}" if unit != "deg" else f"{math.degrees(u):.3g} deg"
        partner = _partner(uncertainty.correlation, identifiability.free_names, k)
        found.append(f"{name} (u = {shown}, {effect[k]:.3g} mm on the points): {_remedy(name, sweep, partner)}")
    return found


def _is_length(name: str) -> bool:
    return name.startswith(("target.", "base.t")) or name.split(".")[-1] in LENGTH_KINDS


def _is_harmonic(kind: str) -> bool:
    """``a1``, ``b2``... (a joint model's harmonic amplitudes), not ``alpha`` or ``beta``."""
    return kind[:1] in ("a", "b") and kind[1:].isdigit()


def _partner(correlation, names, k: int) -> tuple[str, float] | None:
    """The free quantity most correlated with quantity ``k``, and the correlation, if above 0.9 in magnitude."""
    if correlation is None or len(names) < 2:
        return None
    row = np.nan_to_num(np.abs(np.asarray(correlation, dtype=float)[k]))
    row[k] = 0.0
    other = int(np.argmax(row))
    value = float(np.asarray(correlation)[k, other])
    return (names[other], value) if abs(value) > 0.9 else None


def _remedy(name: str, sweep_deg: np.ndarray, partner: tuple[str, float] | None) -> str:
    """What capture would determine quantity ``name`` better, worded for its kind: a target offset, the base frame,
    a joint's geometry or harmonic terms (its sweep ``sweep_deg`` of every joint, or the quantity it is confounded
    with), a compliance (poses of different gravity torque)."""
    if name.startswith("target."):
        return "measure the target at more poses, turning the flange"
    if name.startswith("base."):
        return "spread the poses over more of the workspace"
    joint_name, kind = name.split(".")
    joint = int(joint_name[1:]) - 1
    if kind == "k" or (kind[:1] == "g" and kind[1:].isdigit()):  # a compliance: its sweep says nothing, the torque does
        return (
            f"measure poses with different gravity torque on {joint_name} (the arm stretched out and folded back, "
            "at several heights), or give the link masses"
        )
    if sweep_deg[joint] < NARROW_SWEEP_DEG:
        arc = f"turn {joint_name} through a wider arc (it swept {sweep_deg[joint]:.3g} deg"
        return arc + (", a harmonic term needs most of a turn)" if _is_harmonic(kind) else ")")
    if partner is not None:
        other, value = partner
        return (
            f"{joint_name} swept {sweep_deg[joint]:.3g} deg, but {name} is confounded with {other} (correlation "
            f"{value:+.3f}) in this capture: add poses that move them differently"
        )
    return "measure more poses, spread over the workspace"
