"""Scenario-level operations shared by the CLI and by scripts: simulate, identify, provenance.

Each function is one library call over core objects; nothing here prints or exits.
"""

from __future__ import annotations

import platform
from dataclasses import dataclass

import numpy as np

import robotcal
from robotcal.capture import Capture
from robotcal.identification.cpa import CPAResult, identify_cpa
from robotcal.identification.plausibility import check_capture
from robotcal.io.scenario import Scenario, TCPTable, TruthTable, ValidationTable
from robotcal.kinematics.model import ANGLE_KINDS, ParameterSet, ReflectorMount
from robotcal.simulation.generator import simulate_capture

__all__ = [
    "SimulationRun",
    "resolve_seed",
    "simulate_scenario",
    "identify_scenario",
    "versions",
    "scenario_truth",
    "simulate_validation",
    "refine_scenario",
    "refine_provenance",
    "refined_targets",
    "capture_reflector",
    "cpa_target",
    "cpa_health",
    "refine_health",
    "stated_noise",
    "evaluate_scenario",
    "absolute_bases",
    "validation_consistency",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class SimulationRun:
    """A simulated capture with what produced it."""

    capture: Capture
    exact_points: np.ndarray
    seed: int
    true_parameters: ParameterSet


def resolve_seed(*candidates: int | None) -> int:
    """The first seed given, else fresh entropy (returned so that it can be recorded)."""
    for seed in candidates:
        if seed is not None:
            return int(seed)
    return int(np.random.SeedSequence().entropy % (2**63))


def simulate_scenario(
    scenario: Scenario, *, seed: int | None = None, true_parameters: ParameterSet | None = None
) -> SimulationRun:
    """Simulate the scenario's capture (noise and joint errors from one generator seeded by ``seed``,
    else the scenario's ``capture.seed``, else fresh entropy)."""
    seed = resolve_seed(seed, scenario.seed)
    true_parameters = ParameterSet.nominal(scenario.robot) if true_parameters is None else true_parameters
    capture, exact = simulate_capture(
        scenario.robot,
        scenario.plan,
        scenario.instrument,
        scenario.tracker_from_base,
        true_parameters=true_parameters,
        joint_errors=scenario.joint_errors,
        joint_limits=scenario.joint_limits,
        rng=np.random.default_rng(seed),
    )
    capture = Capture(
        circle=capture.circle,
        direction=capture.direction,
        readings=capture.readings,
        points=capture.points,
        source=f"capture simulated from {scenario.name}",
        seed=seed,
    )
    return SimulationRun(capture=capture, exact_points=exact, seed=seed, true_parameters=true_parameters)


def scenario_monte_carlo(
    scenario: Scenario,
    *,
    true_parameters: ParameterSet | None = None,
    instrument=None,
    model: str = "cpa",
    criterion: str = "points",
):
    """The Monte Carlo problem of a scenario: its robot, plan, instrument (or ``instrument``), base frame,
    joint errors, limits policy and CPA options (``prepare_monte_carlo``; every input check happens here).
    ``model="refined"`` refines every draw after CPA with ``criterion`` (the deployed model)."""
    from robotcal.uncertainty.montecarlo import prepare_monte_carlo

    return prepare_monte_carlo(
        scenario.robot,
        scenario.plan,
        scenario.instrument if instrument is None else instrument,
        scenario.tracker_from_base,
        options=scenario.identification,
        true_parameters=true_parameters,
        joint_errors=scenario.joint_errors,
        joint_limits=scenario.joint_limits,
        model=model,
        criterion=criterion,
    )


def cpa_target(scenario: Scenario, capture: Capture) -> tuple[Capture, ReflectorMount]:
    """The capture rows CPA uses and their (known) target.

    Without a ``target`` column: every row, on :func:`capture_reflector`'s target. With one: the rows of
    the capture's first target (file order), which must be declared with a known position (CPA fits one
    circle per joint of one target; :func:`refine_scenario` uses every target).
    """
    from robotcal.errors import InputError
    from robotcal.identification.targets import Target

    if capture.target is None:
        target = capture_reflector(scenario, capture)
        if isinstance(target, ReflectorMount):
            return capture, target
        target = target if isinstance(target, Target) else target[0]
    else:
        name = capture.target_names[int(capture.target[0])]
        target = scenario.target(name)
        capture = capture.select(capture.target == capture.target[0])
    if not target.known:
        raise InputError(
            f"{scenario.source}: CPA needs a target of known position; the offset of target {target.name!r} is "
            "unknown (refine from the nominal parameters instead, which estimates it)"
        )
    return capture, target.mount


def identify_scenario(
    capture: Capture, scenario: Scenario, *, check: bool = True, health: str = "warn"
) -> CPAResult:
    """CPA of ``capture`` with the scenario's robot, reflector, base frame and options.

    With ``check`` (default) the capture first passes the plausibility checks of
    :func:`robotcal.identification.plausibility.check_capture` (units, readings in radians, radii,
    duplicated rows, outliers against the instrument's U): an :class:`InputError` where the result
    would certainly be wrong, a ``PlausibilityWarning`` where it may be. They need the scenario's
    ``[instrument]`` and are skipped without it. Then the fit-health test
    (:func:`cpa_health`): ``health`` = ``"warn"`` (default), ``"strict"`` (raise) or ``"off"``.
    """
    capture, reflector = cpa_target(scenario, capture)
    if check and scenario.has_instrument:
        check_capture(capture, scenario.robot, reflector, scenario.instrument, options=scenario.identification)
    result = identify_cpa(
        capture,
        scenario.robot,
        reflector,
        tracker_from_base=scenario.tracker_from_base,
        options=scenario.identification,
    )
    if health != "off":
        cpa_health(result, capture, scenario, strict=health == "strict")
    return result


def stated_noise(scenario: Scenario, capture: Capture) -> tuple[float | None, str]:
    """RMS stated standard uncertainty per coordinate of the capture's points [mm], and its source:
    the points' U(95) / 2 (k = 2, normal) when given, else the scenario's instrument; None without both."""
    if capture.u95 is not None:
        return float(np.sqrt(np.mean((np.asarray(capture.u95) / 2.0) ** 2))), "U(95) / 2 of the points (k = 2)"
    if scenario.has_instrument:
        sd = scenario.instrument.standard_uncertainty(capture.points)
        return float(np.sqrt(np.mean(np.asarray(sd) ** 2))), f"instrument {scenario.instrument.name}"
    return None, "no instrument and no U(95)"


def cpa_health(result: CPAResult, capture: Capture, scenario: Scenario, *, strict: bool = False, warn: bool = True):
    """Fit health of a CPA identification (:mod:`robotcal.identification.health`): the RMS distance of the
    points to their fitted circles against the stated noise, and circles whose axis direction the noise
    leaves uncertain by more than :data:`~robotcal.identification.health.AXIS_LIMIT_DEG`."""
    from robotcal.identification.health import AXIS_LIMIT_DEG, circle_axis_uncertainty, fit_health

    noise, noise_source = stated_noise(scenario, capture)
    squares, count, small = 0.0, 0, []
    for joint, fit in enumerate(result.circle_fits):
        rows = np.flatnonzero(capture.circle == joint + 1)
        n_rows = rows.size
        squares += n_rows * (float(fit.plane_rms) ** 2 + float(fit.circle_rms) ** 2)
        count += n_rows
        if noise is not None and n_rows >= 3:
            u_axis, _ = circle_axis_uncertainty(capture.points[rows], noise)
            if np.rad2deg(u_axis) > AXIS_LIMIT_DEG:
                small.append(
                    f"circle {joint + 1} (radius {float(fit.radius):.4g} mm, radius / u = {float(fit.radius) / noise:.3g}, "
                    f"{n_rows} points) leaves its axis direction uncertain by {np.rad2deg(u_axis):.3g} deg "
                    f"(> {AXIS_LIMIT_DEG:g} deg): measure it farther from the axis, over a wider arc or with more points"
                )
    residual = float(np.sqrt(squares / max(count, 1) / 2.0))  # two noise components per circle point
    return fit_health(
        "CPA (circle fits)",
        residual,
        noise,
        noise_source=noise_source,
        extra_problems=small,
        source=capture.source,
        strict=strict,
        warn=warn,
    )


def refine_health(result, capture: Capture, scenario: Scenario, *, strict: bool = False, warn: bool = True):
    """Fit health of a refinement: its residual standard deviation per coordinate (``sigma``, weighted by the
    points' U(95) when given; the RMS residual when no degree of freedom is left) against the stated noise,
    and the condition number of its scaled Jacobian (:mod:`robotcal.identification.health`)."""
    from robotcal.identification.health import fit_health

    noise, noise_source = stated_noise(scenario, capture)
    residual = float(result.sigma) if np.isfinite(result.sigma) else float(result.residual_rms_coordinate)
    if result.criterion == "distances" and not np.isfinite(result.sigma):
        residual /= np.sqrt(2.0)  # a distance's error has the noise of two points
    return fit_health(
        f"refinement ({result.criterion} criterion)",
        residual,
        noise,
        noise_source=noise_source,
        condition_number=result.condition_number,
        source=capture.source,
        strict=strict,
        warn=warn,
    )


def versions() -> dict[str, str]:
    """Versions of robotcal and of the numeric stack, for provenance records."""
    import scipy

    return {
        "robotcal": robotcal.__version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "python": platform.python_version(),
    }


def cpa_provenance(result: CPAResult, capture: Capture, scenario: Scenario) -> dict:
    """What a parameter JSON records about a CPA identification (mm, deg)."""
    return {
        "method": "circle point analysis (thesis ch. 4.4-4.5)",
        "capture": capture.source,
        "capture_seed": capture.seed,
        "points": int(capture.n_points),
        "scenario": {"name": scenario.name, "source": scenario.source},
        "options": {
            "circle_fit": result.options.circle_fit,
            "base_frame": result.options.base_frame,
            "base_axis": result.options.base_axis,
            "near_parallel_deg": result.options.near_parallel_deg,
            "still_tolerance_deg": result.options.still_tolerance_deg,
        },
        "fit_health": cpa_health(result, cpa_target(scenario, capture)[0], scenario, warn=False).as_dict(),
        "reference_readings_deg": np.rad2deg(result.reference_readings).tolist(),
        "circles": [
            {
                "circle": joint + 1,
                "points": int(fit.plane_residuals.shape[-1]),
                "radius_mm": float(fit.radius),
                "plane_rms_mm": float(fit.plane_rms),
                "circle_rms_mm": float(fit.circle_rms),
            }
            for joint, fit in enumerate(result.circle_fits)
        ],
        "line_pairs": [f"J{j + 1}-J{j + 2}: {case}" for j, case in enumerate(result.pair_cases)],
        "tracker_from_base": result.tracker_from_base.tolist(),
        "registration_rms_mm": result.registration_rms,
        "success": result.success,
        "message": result.message,
        "versions": versions(),
    }


# --- refinement and evaluation (thesis ch. 4.5.7) -------------------------------------------------


def scenario_truth(scenario: Scenario, *, seed: int | None = None) -> tuple[ParameterSet, int]:
    """A perturbed "true" robot from the scenario's ``[truth]`` table (defaults when absent).

    Returns the parameters and the seed used (``seed``, else ``truth.seed``, else fresh entropy).
    """
    from robotcal.simulation.perturb import perturb_parameters

    table = scenario.truth or TruthTable()
    seed = resolve_seed(seed, table.seed)
    truth = perturb_parameters(
        scenario.robot,
        length_sd_mm=table.length_sd_mm,
        angle_sd_deg=table.angle_sd_deg,
        include_base=table.include_base,
        rng=np.random.default_rng(seed),
    )
    return truth, seed


def validation_reflector(scenario: Scenario):
    """The flange target of validation captures: ``[validation].flange_reflector_mm``, else the
    plan's (or ``[capture]``'s) reflector when it is a flange one, else the only known flange target
    of ``[[targets]]``."""
    from robotcal.errors import InputError

    if scenario.validation is not None:
        return ReflectorMount(frame="flange", positions=scenario.validation.flange_reflector_mm)
    reflector = scenario.plan.reflector if scenario.has_plan else scenario.reflector
    if reflector is not None and reflector.frame == "flange":
        return reflector
    flange = [t for t in scenario.targets if t.frame == "flange" and t.known]
    if reflector is None and len(flange) == 1:
        return flange[0].mount
    raise InputError(
        f"{scenario.source}: a capture at free poses (circle = 0) needs a flange target: add a [validation] table "
        "with `flange_reflector_mm`, use a scenario with `capture.flange_reflector_mm`, or give the capture a "
        "`target` column naming [[targets]] entries"
    )


def capture_reflector(scenario: Scenario, capture: Capture):
    """The target(s) of ``capture`` for refinement and evaluation.

    * a ``target`` column: the scenario's declared targets (:attr:`Scenario.targets`; each point names one);
    * free poses (circle = 0): the validation flange target (:func:`validation_reflector`), or the
      only ``[[targets]]`` entry (whose offset may be unknown);
    * circles: the plan's reflector, else ``[capture]``'s, else the only ``[[targets]]`` entry.

    Returns a :class:`ReflectorMount` (the historical single target), or :class:`Target` objects.
    """
    from robotcal.errors import InputError

    if capture.target is not None:
        return scenario.targets
    declared = [t for t in scenario.targets if t.name not in ("capture", "validation")]
    if np.any(capture.circle == 0):
        if len(declared) == 1 and scenario.validation is None and scenario.reflector is None:
            return declared[0]
        return validation_reflector(scenario)
    if scenario.has_plan:
        return scenario.plan.reflector
    if scenario.reflector is not None:
        return scenario.reflector
    if len(declared) == 1:
        return declared[0]
    raise InputError(
        f"{scenario.source}: which target was measured? declare one (`capture.flange_reflector_mm`, "
        "`capture.reflector_mm` or one [[targets]] entry) or give the capture a `target` column"
    )


def simulate_validation(
    scenario: Scenario, *, seed: int | None = None, true_parameters: ParameterSet | None = None
) -> SimulationRun:
    """A validation capture at seeded random reachable poses (``[validation]`` table, defaults when
    absent); one generator seeded by ``seed`` (else ``validation.seed``) draws the poses, then the noise."""
    from robotcal.simulation.poses import random_poses, simulate_poses

    table = scenario.validation or ValidationTable()
    seed = resolve_seed(seed, table.seed)
    rng = np.random.default_rng(seed)
    reflector = validation_reflector(scenario)
    readings = random_poses(
        scenario.robot,
        table.poses,
        margin_deg=table.margin_deg,
        min_height_mm=table.min_height_mm,
        reflector=reflector,
        rng=rng,
    )
    true_parameters = ParameterSet.nominal(scenario.robot) if true_parameters is None else true_parameters
    capture, exact = simulate_poses(
        scenario.robot,
        readings,
        reflector,
        scenario.instrument,
        scenario.tracker_from_base,
        true_parameters=true_parameters,
        rng=rng,
    )
    capture = Capture(
        circle=capture.circle,
        direction=capture.direction,
        readings=capture.readings,
        points=capture.points,
        source=f"validation capture simulated from {scenario.name}",
        seed=seed,
    )
    return SimulationRun(capture=capture, exact_points=exact, seed=seed, true_parameters=true_parameters)


def refine_scenario(capture: Capture, scenario: Scenario, start: ParameterSet, *, criterion: str = "points", **options):
    """Refine ``start`` on ``capture`` with the scenario's robot and target (thesis ch. 4.5.7).

    Points criterion: with ``[identification].base_frame = "given"`` the scenario's
    ``tracker_from_base`` is **held** (as CPA holds it), unless ``estimate_base=True`` is passed
    (then it is the start of the estimate); with ``"registered"`` the base frame is estimated from a
    Horn registration start. ``health`` (an option: ``"warn"`` default, ``"strict"``, ``"off"``) runs
    :func:`refine_health` on the result; the other ``options`` go to
    :func:`robotcal.identification.refine.refine_parameters`.
    """
    from robotcal.identification.refine import refine_parameters

    health = options.pop("health", "warn")
    base = scenario.tracker_from_base if scenario.identification.base_frame == "given" else None
    result = refine_parameters(
        capture,
        start,
        capture_reflector(scenario, capture),
        criterion=criterion,
        tracker_from_base=base,
        **options,
    )
    if health != "off":
        refine_health(result, capture, scenario, strict=health == "strict")
    return result


def _finite_or_none(value):
    """JSON has no NaN/inf: an undefined figure (e.g. sigma with no degrees of freedom) is null."""
    value = float(value)
    return value if np.isfinite(value) else None


def refine_provenance(result, capture: Capture, scenario: Scenario, start_source: str) -> dict:
    """What a parameter JSON records about a refinement (mm, deg), convergence history included."""
    names = scenario.robot.parameter_names
    sd = {}
    for name, value in zip(names, result.standard_uncertainty.ravel(), strict=True):
        if np.isfinite(value):
            sd[name] = float(np.rad2deg(value)) if name.split(".")[1] in ANGLE_KINDS else float(value)
    return {
        "method": f"least-squares refinement, {result.criterion} criterion (thesis ch. 4.5.7, "
        + ("eq. 4-101)" if result.criterion == "points" else "eq. 4-102)"),
        "criterion": result.criterion,
        "solver": f"scipy.optimize.least_squares method={result.method!r}",
        "start": start_source,
        "capture": capture.source,
        "capture_seed": capture.seed,
        "points": int(capture.n_points),
        "residuals": result.n_residuals,
        "scenario": {"name": scenario.name, "source": scenario.source},
        "free": list(result.free_names),
        "base_frame": None
        if result.tracker_from_base is None
        else ("estimated" if bool(np.any(result.base_free)) else "held"),
        "gauge": list(result.gauge),
        "held": list(result.held),
        "confounded": list(result.confounded),
        "still_joints": list(result.still_joints),
        "success": result.success,
        "message": result.message,
        "nfev": result.nfev,
        "njev": result.njev,
        "wall_time_s": result.wall_time_s,
        "convergence": {
            "criterion": result.criterion,
            "cost_mm2": result.cost_history.tolist(),
            "rms_mm": result.rms_history.tolist(),
        },
        "residual_rms_mm": result.residual_rms,
        "residual_mean_mm": result.residual_mean,
        "residual_max_mm": result.residual_max,
        "sigma_mm": _finite_or_none(result.sigma),
        "condition_number": _finite_or_none(result.condition_number),
        "singular_values": [_finite_or_none(v) for v in result.singular_values],
        "standard_uncertainty": sd,
        "correlation": None
        if result.correlation is None
        else {
            "names": list(result.free_names),
            "matrix": [[round(float(v), 12) for v in row] for row in result.correlation],
        },
        "tracker_from_base": None if result.tracker_from_base is None else result.tracker_from_base.tolist(),
        "base_frame_note": None
        if result.tracker_from_base is not None
        else "the distances criterion has no base frame (pairwise distances do not depend on it)",
        "weights": "1/u^2 per point, u = U(95) / 2 (k = 2, normal)" if result.weighted else "equal",
        "targets": {
            target.name: {
                "frame": target.frame,
                "known": bool(target.known),
                "points": int(np.sum(np.asarray(capture.point_targets or ()) == target.name))
                if capture.target is not None
                else int(capture.n_points),
            }
            for target in result.targets
        },
        "fit_health": refine_health(result, capture, scenario, warn=False).as_dict(),
        "versions": versions(),
    }


def refined_targets(result) -> dict | None:
    """The parameter JSON's ``targets`` key of a refinement (estimated offsets with their standard
    uncertainty), None when it used the historical single mount."""
    from robotcal.io.parameters_json import targets_to_dict

    if not result.targets:
        return None
    return targets_to_dict(result.targets, result.target_uncertainty)


def evaluate_scenario(
    scenario: Scenario,
    captures: dict,
    parameter_sets: dict,
    *,
    views=None,
    bases: dict | None = None,
    set_targets: dict | None = None,
):
    """Evaluation rows (thesis Tables 4.10/4.11) of named parameter sets on named captures.

    Each capture is evaluated on its own target(s) (:func:`capture_reflector`: a ``target`` column names
    them per point). ``views`` default to points and distances; ``"absolute"`` needs ``bases`` (a base
    frame per set, see :func:`absolute_bases`); ``set_targets`` gives per set the offsets it estimated.
    """
    from robotcal.identification.evaluation import VIEWS, evaluate_parameters

    reflectors = {name: capture_reflector(scenario, capture) for name, capture in captures.items()}
    return evaluate_parameters(
        captures,
        parameter_sets,
        reflectors,
        views=VIEWS if views is None else views,
        bases=bases,
        set_targets=set_targets,
    )


def absolute_bases(scenario: Scenario, provenances: dict) -> tuple[dict, dict]:
    """Base frame of each parameter set for the absolute view, and a note per set saying where it comes from.

    ``provenances``: set name -> the parameter JSON's ``provenance`` (empty for the nominal set). The
    base frame a fit recorded (``provenance.tracker_from_base``: a refinement's estimated or held one,
    CPA's given or registered one) is used as it is; a set without one, such as a distances-criterion
    refinement (it has no base frame), is evaluated with the scenario's ``tracker_from_base``.
    """
    bases, notes = {}, {}
    for name, provenance in provenances.items():
        recorded = (provenance or {}).get("tracker_from_base")
        if recorded is not None:
            bases[name] = np.asarray(recorded, dtype=float)
            notes[name] = "the base frame recorded in its parameter JSON (provenance.tracker_from_base)"
        else:
            bases[name] = np.asarray(scenario.tracker_from_base, dtype=float)
            why = (
                "the distances criterion has no base frame"
                if (provenance or {}).get("criterion") == "distances"
                else "no base frame recorded"
            )
            notes[name] = f"{why}: the scenario's tracker_from_base is used"
    return bases, notes


def validation_consistency(
    scenario: Scenario, validation: Capture, estimate: ParameterSet, draws: np.ndarray, *, model: str
) -> dict:
    """Does the stated uncertainty explain the error observed at the validation points?

    The check a metrologist asks for: at every validation pose the Monte Carlo draws of ``model``
    give the covariance of the predicted target position, so the RMS position uncertainty predicted
    by the calibration is ``sqrt(mean_p tr V_p)``; the instrument adds ``3 sigma_p^2`` per point
    (sigma from its U(L), uniform: U/sqrt(3), normal: U/k). If the model explains the data, the RMS of
    the observed errors ``|T p(estimate) - m|`` is close to ``sqrt(mean_p (tr V_p + 3 sigma_p^2))``;
    a larger observed RMS points to what the model does not hold (joint errors such as backlash,
    eccentricity, or a wrong instrument level).

    The base frame is the scenario's ``tracker_from_base`` when ``[identification] base_frame = "given"``,
    else a Horn registration of the predictions on the measurements (which absorbs part of the error).

    Parameters
    ----------
    validation : Capture
        Free poses (circle = 0) measured with the validation flange target [mm].
    estimate : ParameterSet
        The deployed parameters [mm, rad].
    draws : ndarray, shape (n_draws, n_joints, 5)
        Monte Carlo draws of the same model [mm, rad].
    model : str
        Name of the model, recorded.

    Returns
    -------
    dict
        JSON-ready figures in mm (``predicted_rms_mm``, ``instrument_rms_mm``, ``expected_rms_mm``,
        ``observed_rms_mm``, ``ratio``), the base-frame mode and the counts.
    """
    from robotcal.geometry.registration import register_points
    from robotcal.kinematics.forward import target_positions
    from robotcal.uncertainty.tcp import position_covariance

    robot = scenario.robot
    reflector = validation_reflector(scenario)
    q = robot.model_joint_variables(validation.readings)
    measured = np.asarray(validation.points, dtype=float)
    turning = np.zeros(validation.n_points, dtype=int)
    predicted = target_positions(estimate.values, q, turning, reflector)
    if scenario.identification.base_frame == "given":
        tracker_from_base, base = np.asarray(scenario.tracker_from_base), "given"
    else:
        tracker_from_base, base = register_points(predicted, measured).transform, "registered"
    in_tracker = predicted @ tracker_from_base[:3, :3].T + tracker_from_base[:3, 3]
    observed = np.linalg.norm(in_tracker - measured, axis=1)
    # the Monte Carlo covariance of the target position at every validation pose (the forward kinematics
    # of the TCP stage, with the validation target as the tool; positions only)
    spread = position_covariance(robot, draws, validation.readings, tool=reflector.positions[0])
    traces = np.trace(spread, axis1=1, axis2=2)
    n = draws.shape[0]
    instrument = 3.0 * scenario.instrument.standard_uncertainty(measured) ** 2
    predicted_rms = float(np.sqrt(np.mean(traces)))
    instrument_rms = float(np.sqrt(np.mean(instrument)))
    expected_rms = float(np.sqrt(np.mean(traces + instrument)))
    observed_rms = float(np.sqrt(np.mean(observed**2)))
    return {
        "model": model,
        "poses": int(validation.n_points),
        "draws": int(n),
        "base_frame": base,
        "predicted_rms_mm": predicted_rms,
        "instrument_rms_mm": instrument_rms,
        "expected_rms_mm": expected_rms,
        "observed_rms_mm": observed_rms,
        "observed_mean_mm": float(observed.mean()),
        "ratio": observed_rms / expected_rms if expected_rms > 0 else None,
        "method": (
            "predicted = sqrt(mean over poses of tr V_p), V_p the covariance of the validation target position "
            "over the Monte Carlo draws; instrument = sqrt(mean of 3 sigma_p^2) from U(L); expected = "
            "sqrt(predicted^2 + instrument^2); observed = RMS of |T p(estimate) - measured|"
        ),
    }


# --- TCP targets of `robotcal run` (thesis ch. 5.3) ------------------------------------------------

#: Robot whose readings are KUKA controller angles; the thesis's Table 5.8 pose and the built-in
#: trajectories are given in its readings.
KUKA_CONTROLLER_ROBOT = "kuka-kr5-sixx-r650-krc"
#: Thesis Table 5.8 pose, KUKA controller readings A1..A6 [deg] (the text's "68" is a misprint: docs/conventions.md).
TABLE_5_8_READINGS_DEG = (60.0, 80.0, -45.0, 200.0, 125.0, 280.0)
#: Built-in 75-pose trajectory of the TCP stage (docs/tcp.md), KUKA controller readings.
DEFAULT_TRAJECTORY = "kr5-sweep-75"


@dataclass(frozen=True, slots=True, kw_only=True)
class TCPTargets:
    """Where ``robotcal run`` states the TCP uncertainty: readings of the scenario's robot [rad].

    ``pose`` (1, n) and ``trajectory`` (m, n) are ``None`` when the stage part is skipped (the reason
    is in ``notes``); ``*_source`` say where the readings come from.
    """

    pose: np.ndarray | None
    pose_source: str
    trajectory: np.ndarray | None
    trajectory_source: str
    workspace_poses: int
    workspace_draws: int | None
    workspace_seed: int
    tool_mm: np.ndarray | None
    notes: tuple[str, ...] = ()


def _same_geometry(a, b) -> bool:
    return (
        a.n_joints == b.n_joints
        and bool(np.all(a.hayati == b.hayati))
        and np.allclose(a.nominal, b.nominal, rtol=0.0, atol=1e-9)
    )


def convert_readings(readings, from_robot, to_robot) -> np.ndarray:
    """Readings of ``from_robot`` [rad] as readings of ``to_robot`` [rad], through the model joint
    variables (``q = sign * reading + offset`` of each robot file); both must share the same model."""
    from robotcal.errors import InputError

    if not _same_geometry(from_robot, to_robot):
        raise InputError(
            f"readings of robot {from_robot.name!r} cannot be used on robot {to_robot.name!r}: "
            "their joint count, joint types or nominal parameters differ"
        )
    return to_robot.readings_from_model(from_robot.model_joint_variables(readings))


def tcp_targets(scenario: Scenario) -> TCPTargets:
    """Resolve and check the ``[tcp]`` table (defaults when absent) before any computation.

    Defaults: the Table 5.8 pose and the trajectory ``kr5-sweep-75``, both KUKA controller readings
    (robot ``kuka-kr5-sixx-r650-krc``), converted to the scenario robot's readings when it has the
    same model (e.g. ``kuka-kr5-sixx-r650``, model q = (-60, -80, 45, -200, 125, -280) deg); for
    another robot without ``pose_deg``/``trajectory`` that part is skipped, with a note. Readings
    outside the limits are noted (the thesis's pose is outside them), not refused.
    """
    import warnings

    from robotcal.errors import InputError, JointLimitWarning
    from robotcal.io.robots import load_robot
    from robotcal.io.trajectory_csv import builtin_trajectories, load_trajectory
    from robotcal.uncertainty.tcp import check_readings

    table: TCPTable = scenario.tcp
    robot = scenario.robot
    where = f"{scenario.source}: key `tcp"
    notes: list[str] = []
    kuka = load_robot(KUKA_CONTROLLER_ROBOT)
    kuka_compatible = _same_geometry(kuka, robot)
    readings_robot = robot
    if table.readings_robot:
        try:
            readings_robot = load_robot(table.readings_robot)
        except InputError as exc:
            raise InputError(f"{where}.readings_robot`: {exc}") from None
        if not _same_geometry(readings_robot, robot):
            raise InputError(
                f"{where}.readings_robot`: robot {readings_robot.name!r} does not share the model of {robot.name!r}"
            )

    def checked(values, key, source_robot):
        values = np.asarray(values, dtype=float)
        if values.ndim != 2 or values.shape[1] != robot.n_joints:
            raise InputError(
                f"{where}.{key}`: {values.shape[-1]} joint readings; robot {robot.name!r} has {robot.n_joints}"
            )
        values = convert_readings(values, source_robot, robot)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", JointLimitWarning)
            try:
                values = check_readings(robot, values, name=f"tcp.{key}")
            except InputError as exc:
                raise InputError(f"{scenario.source}: key {exc}") from None
        notes.extend(str(w.message) for w in caught if issubclass(w.category, JointLimitWarning))
        return values

    pose = trajectory = None
    pose_source = trajectory_source = "skipped"
    if table.pose_deg is not None:
        pose = checked(np.deg2rad([table.pose_deg]), "pose_deg", readings_robot)
        pose_source = f"tcp.pose_deg = {list(table.pose_deg)} (readings of {readings_robot.name})"
    elif kuka_compatible:
        pose = checked(np.deg2rad([TABLE_5_8_READINGS_DEG]), "pose_deg", kuka)
        shown = ", ".join(f"{v:g}" for v in np.rad2deg(pose[0]))
        pose_source = (
            f"thesis Table 5.8 pose, KUKA readings {', '.join(f'{v:g}' for v in TABLE_5_8_READINGS_DEG)} deg "
            f"({KUKA_CONTROLLER_ROBOT}) = readings {shown} deg of {robot.name}"
        )
    else:
        notes.append("no TCP pose: give `tcp.pose_deg` (the Table 5.8 default is for the KR 5 sixx R650)")
    name = table.trajectory
    builtin = name is None or name in builtin_trajectories()
    if name is None and not kuka_compatible:
        notes.append(
            f"no trajectory: give `tcp.trajectory` (the {DEFAULT_TRAJECTORY} default is for the KR 5 sixx R650)"
        )
    else:
        try:
            values, path = load_trajectory(DEFAULT_TRAJECTORY if name is None else name, n_joints=robot.n_joints)
        except InputError as exc:
            raise InputError(f"{where}.trajectory`: {exc}") from None
        trajectory = checked(values, "trajectory", kuka if builtin else readings_robot)
        trajectory_source = (
            f"built-in {DEFAULT_TRAJECTORY if name is None else name} ({path}), KUKA readings converted to {robot.name}"
            if builtin
            else path
        )
    return TCPTargets(
        pose=pose,
        pose_source=pose_source,
        trajectory=trajectory,
        trajectory_source=trajectory_source,
        workspace_poses=table.workspace_poses,
        workspace_draws=table.workspace_draws,
        workspace_seed=table.workspace_seed,
        tool_mm=None if table.tool_mm is None else np.asarray(table.tool_mm, dtype=float),
        notes=tuple(notes),
    )
