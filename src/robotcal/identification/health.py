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

Small circles (CPA) do not change the verdict but are named (:class:`FitHealthWarning` and the
``poorly_determined`` list): the direction of a circle's axis comes from the plane fit; its standard
uncertainty is ``u_axis = u / sqrt(lambda_2)`` [rad], ``lambda_2`` the smaller in-plane eigenvalue of the
points' scatter matrix ``sum (p - mean)(p - mean)^T`` (a full circle of N points of radius r: ``lambda_2 =
N r^2 / 2``). Above :data:`AXIS_LIMIT_DEG` = 1 deg the tilt alone moves the axis by ~5 mm at 300 mm along
it (a wrist's d), where the common normals to the next axes are taken: the parameters of that joint pair
are then off by millimetres (real 1.6 mm circles gave J3.a 7 mm off). The built-in laser-tracker scenarios
stay below 0.25 deg; the thesis iGPS capture reaches 2.6 deg on circle 4, rightly named: the thesis's
own Monte Carlo (Table 5.7) gives u(J4.a) = 12.6 mm for it.

Poorly determined refined quantities are named the same way: ``u_k e_k``, with ``e_k`` the RMS displacement of
the points per unit of quantity k (the norm of its Jacobian column over the points, ``RefinementResult.identifiability.effect``),
is what one standard uncertainty of that quantity alone does to the points [mm]. Above
:data:`U_EFFECT_LIMIT_MM` = 0.1 mm (several times a laser tracker's noise, the size of the errors a calibration
is there to remove) the quantity is named with its u and what would determine it better. The demo's refined
parameters stay below 0.01 mm.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import FitHealthError, FitHealthWarning
from robotcal.kinematics.model import ANGLE_KINDS, LENGTH_KINDS

__all__ = [
    "AXIS_LIMIT_DEG",
    "CONDITION_LIMIT",
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
#: Largest standard uncertainty of a CPA circle's axis direction [deg].
AXIS_LIMIT_DEG = 1.0
#: Largest effect on the points [mm] of one standard uncertainty of a refined quantity (module notes).
U_EFFECT_LIMIT_MM = 0.1

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
    if failed:
        verdict: Verdict = "FAILED"
        problems, advice = failed + model, ("do not use these parameters; correct the input or the start and fit again",)
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


def cpa_health(result, capture: Capture, instrument=None, repeatability_mm: float | None = None) -> FitHealth:
    """Fit health of a CPA identification: the RMS distance of the points to their fitted circles against
    the stated noise (:func:`stated_noise`), the circle fits' convergence, and the circles whose axis
    direction the noise leaves uncertain by more than :data:`AXIS_LIMIT_DEG` (named, with the joints whose
    parameters they determine)."""
    noise, noise_source = stated_noise(capture, instrument, repeatability_mm)
    squares, count, small = 0.0, 0, []
    for joint, fit in enumerate(result.circle_fits):
        rows = np.flatnonzero(capture.circle == joint + 1)
        squares += rows.size * (float(fit.plane_rms) ** 2 + float(fit.circle_rms) ** 2)
        count += rows.size
        if noise is not None and rows.size >= 3:
            u_axis, _ = circle_axis_uncertainty(capture.points[rows], noise)
            if np.rad2deg(u_axis) > AXIS_LIMIT_DEG:
                pair = f"J{joint}-J{joint + 1}" if joint > 0 else "the base"
                small.append(
                    f"circle {joint + 1} (radius {float(fit.radius):.4g} mm, {rows.size} points, radius / u = "
                    f"{float(fit.radius) / noise:.3g}) leaves the J{joint + 1} axis direction uncertain by "
                    f"{np.rad2deg(u_axis):.3g} deg (> {AXIS_LIMIT_DEG:g} deg), so the parameters of {pair} and "
                    f"J{joint + 1}-J{joint + 2} are poorly determined: put the target farther from axis {joint + 1}, "
                    "sweep a wider arc or measure more points"
                )
    residual = float(np.sqrt(squares / max(count, 1) / 2.0))  # two noise components per circle point
    converged = all(bool(np.all(fit.converged)) for fit in result.circle_fits)
    return assess_fit(
        "CPA (circle fits)",
        residual,
        noise,
        noise_source=noise_source,
        converged=converged,
        poorly_determined=small,
    )


def refine_health(
    fit, identifiability, uncertainty, *, criterion: str, converged: bool, model: str | None, capture: Capture,
    instrument=None, repeatability_mm: float | None = None,
) -> FitHealth:  # fmt: skip
    """Fit health of a refinement: its residual standard deviation per coordinate (``uncertainty.sigma``, weighted
    by the points' U(95) when given; the RMS residual ``fit.residual_rms_coordinate`` when no degree of freedom is
    left) against the stated noise, its convergence, and the condition number of its scaled Jacobian.

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
    return dataclasses.replace(health, poorly_determined=tuple(_poorly_refined(identifiability, uncertainty)))


def _poorly_refined(identifiability, uncertainty) -> list[str]:
    """The refined quantities whose standard uncertainty moves the points by more than :data:`U_EFFECT_LIMIT_MM`
    (module notes), worst first, each with its u and what would determine it better."""
    covariance = uncertainty.covariance
    if covariance is None or identifiability.effect is None:
        return []
    effect = np.sqrt(np.clip(np.diag(covariance), 0.0, None)) * np.asarray(identifiability.effect, dtype=float)
    found = []
    for k in np.argsort(-effect):
        if effect[k] <= U_EFFECT_LIMIT_MM:
            break
        name = identifiability.free_names[k]
        u = math.sqrt(max(float(covariance[k, k]), 0.0))
        if name.startswith("target."):
            shown, where = f"{u:.3g} mm", "measure the target at more poses, turning the flange"
        elif name.startswith("base."):
            shown = f"{u:.3g} mm" if name[-2] == "t" else f"{math.degrees(u):.3g} deg"
            where = "spread the poses over more of the workspace"
        elif name.split(".")[1] in LENGTH_KINDS:
            shown, where = f"{u:.3g} mm", f"turn {name.split('.')[0]} through a wider arc or measure more poses"
        elif name.split(".")[1] in ANGLE_KINDS:
            shown, where = f"{math.degrees(u):.3g} deg", f"turn {name.split('.')[0]} through a wider arc or measure more poses"
        else:  # a joint-model value
            shown = f"{u:.3g} rad/(N m)" if name.endswith(".k") else f"{math.degrees(u):.3g} deg"
            where = "measure poses that load the joint in more ways (free poses over the workspace)"
        found.append(f"{name} (u = {shown}, {effect[k]:.3g} mm on the points): {where}")
    return found
