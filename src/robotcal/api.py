"""The front door for Python users: one call per thing a user does (docs/api.md).

Every function takes the objects a user already has, explicitly, or a :class:`~robotcal.io.schema.scenario.Scenario` in
place of the robot, which supplies the robot and every keyword the call leaves out (its targets, base frame,
instrument, capture plan, joint errors, options and seeds), as ``robotcal run`` uses it. Each call resolves its
defaults once (:mod:`robotcal.resolve`) and calls the core; the command line and the pipeline call these same
functions. This module holds the calibration (simulate, identify, refine, evaluate, Monte Carlo) and re-exports the
studies of :mod:`robotcal.studies` and the calls of :mod:`robotcal.deploy`. They never print and never write files
(:func:`import_capture` and :func:`sensitivity` read the files they are given).

Arguments shared by the functions below, described once:

- ``robot`` : RobotModel or Scenario (:func:`robotcal.load_robot`, :func:`robotcal.load_scenario`);
- ``capture`` : a :class:`Capture` or the path of a capture CSV;
- ``parameters``, ``start``, ``estimate`` : a :class:`ParameterSet`, a result holding one (``.parameters``) or a
  parameter JSON path; None: the nominal parameters;
- ``instrument`` : :class:`~robotcal.instruments.Instrument`; ``tracker_from_base`` : array (4, 4), the robot base
  in the instrument frame [mm];
- ``rng`` : None, an int seed or a ``numpy.random.Generator`` (:func:`seed_from`); the core takes an int seed, so
  that blocks of draws are reproducible for any batch size or worker count, and every result records it.

Units, one rule: a number or array given to a function of this module is in millimetres and degrees, and its name
says so (``poses_deg``, ``tool_mm``, ``acceptance_deg``); a value object (RobotModel, ParameterSet, Capture,
CapturePlan, ReflectorMount, JointModel, CPAOptions, the results) holds the core's units, millimetres and radians,
whichever function takes or returns it. The readings of a Capture and the angles of a CapturePlan are in radians
(build them from files, or convert with ``numpy.deg2rad``); :func:`change_plan` takes degrees.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from robotcal.capture import Capture
from robotcal.deploy import compensate, export_model, filter_program, import_capture, iso9283, predict
from robotcal.errors import InputError
from robotcal.identification.cpa import CPAOptions, CPAResult, identify_cpa
from robotcal.identification.evaluation import EvaluationRow, evaluate_parameters
from robotcal.identification.health import cpa_health, report_health
from robotcal.identification.model_choice import refine_model
from robotcal.identification.plausibility import check_capture
from robotcal.identification.records import RefinementResult
from robotcal.identification.settings import RefinementSettings
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.schema.scenario import Scenario, TruthTable, repeatability_of
from robotcal.kinematics.forward import check_joint_variables
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ParameterSet, ReflectorMount, RobotModel
from robotcal.limits import SEED_BOUND
from robotcal.resolve import (
    DEFAULT_TRAJECTORY,
    KUKA_CONTROLLER_ROBOT,
    TABLE_5_8_READINGS_DEG,
    ParameterSource,
    TCPTargets,
    calibration_capture,
    capture_targets,
    convert_readings,
    cpa_rows,
    free_pose_table,
    link_masses,
    model_choice_settings,
    needed,
    refinement_targets,
    scenario_cpa_target,
    seed_from,
    simulation_inputs,
    target_name,
    tcp_targets,
    true_offsets,
    validation_target,
)
from robotcal.resolve import as_capture as _capture
from robotcal.resolve import as_parameters as _parameters
from robotcal.resolve import scenario_instrument as _instrument
from robotcal.resolve import split_robot as _split
from robotcal.simulation import CapturePlan, JointErrorModel, simulate_capture
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses
from robotcal.simulation.poses import simulate_poses as simulate_poses_core
from robotcal.studies import (
    JointAnalysis,
    backlash_correction,
    change_plan,
    check_plan,
    coverage_study,
    diagnose_joints,
    measured_monte_carlo,
    optimise_plan,
    sensitivity,
    tcp_uncertainty,
    validation_consistency,
    workspace_uncertainty,
)
from robotcal.uncertainty.tcp import check_readings

if TYPE_CHECKING:  # the Monte Carlo, TCP, planning and file modules load when a function needs them
    from robotcal.uncertainty.montecarlo import MonteCarloProblem, MonteCarloResult, MonteCarloSettings

__all__ = [  # the calls of this module, those it re-exports from robotcal.deploy and robotcal.studies, and names kept here
    "DEFAULT_TRAJECTORY", "KUKA_CONTROLLER_ROBOT", "SEED_BOUND", "TABLE_5_8_READINGS_DEG", "JointAnalysis", "TCPTargets",
    "calibration_capture", "capture_targets", "change_plan", "check_plan", "compensate", "convert_readings",
    "coverage_study", "diagnose_joints", "evaluate", "export_model", "filter_program", "identify", "import_capture",
    "iso9283", "link_masses", "measured_monte_carlo", "monte_carlo", "monte_carlo_problem", "optimise_plan", "perturb",
    "plan_tcp_p95", "predict", "refine", "seed_from", "sensitivity", "simulate", "simulate_poses", "tcp_targets",
    "tcp_uncertainty", "validation_consistency", "validation_target", "workspace_uncertainty",
]  # fmt: skip


Criterion = Literal["points", "distances"]
ModelName = Literal["geometric", "compliance", "harmonic", "compliance+harmonic", "auto"]
Health = Literal["warn", "strict", "off"]
PathLike = str | os.PathLike


# ---------------------------------------------------------------------------------------- simulation


def perturb(
    robot: RobotModel | Scenario,
    *,
    length_sd_mm: float | None = None,
    angle_sd_deg: float | None = None,
    include_base: bool | None = None,
    rng: np.random.Generator | int | None = None,
) -> ParameterSet:
    """A perturbed "true" robot for a synthetic study: nominal + N(0, sd) on the identifiable parameters.

    A scenario supplies its ``[truth]`` table's ``length_sd_mm``, ``angle_sd_deg`` [mm, deg], ``include_base``
    (also perturb d1 and theta1), compliance and seed; without one, the table's defaults (0.2 mm, 0.05 deg).
    Returns the true ParameterSet [mm, rad], to give :func:`simulate` as ``true_parameters``.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> robot = robotcal.load_robot("kuka-kr5-sixx-r650")
    >>> truth = robotcal.perturb(robot, length_sd_mm=0.2, angle_sd_deg=0.05, rng=11)
    >>> bool(np.any(truth.values != robot.nominal)), truth.values.shape
    (True, (6, 5))
    """
    robot, scenario = _split(robot)
    table = (scenario.truth if scenario is not None else None) or TruthTable()  # the table's defaults
    truth = perturb_parameters(
        robot,
        length_sd_mm=table.length_sd_mm if length_sd_mm is None else length_sd_mm,
        angle_sd_deg=table.angle_sd_deg if angle_sd_deg is None else angle_sd_deg,
        include_base=table.include_base if include_base is None else include_base,
        rng=np.random.default_rng(seed_from(rng, table.seed)),
    )
    compliance = table.compliance_rad_per_nm
    if compliance is None or not any(compliance):
        return truth
    masses = link_masses(robot, scenario)
    if masses is None:
        raise InputError(
            f"[truth] compliance_rad_per_nm needs the link masses of robot {robot.name!r} (mass_kg, com_mm per joint "
            "in its robot file) to compute the gravity torques"
        )
    joints = [j for j, k in enumerate(compliance) if k > 0]
    structure = JointModel.build(robot, compliance_joints=joints, masses=masses)
    return truth.replace(joint_model=structure.with_values([compliance[j] for j in joints]))


def simulate(
    robot: RobotModel | Scenario,
    plan: CapturePlan | None = None,
    *,
    instrument: Instrument | None = None,
    tracker_from_base: np.ndarray | None = None,
    true_parameters: ParameterSource = None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: str | None = None,
    rng: np.random.Generator | int | None = None,
) -> Capture:
    """Simulate a Circle Point capture of ``plan`` (thesis ch. 5.2.1) on the robot ``true_parameters`` (default
    nominal; e.g. :func:`perturb`'s), measured by ``instrument``.

    Joint errors (eqs 5-2..5-4 and backlash) and instrument noise U(L) = A + B L come from one generator seeded
    from ``rng``; the capture records the seed. ``joint_limits``: what a plan beyond the limits does (default
    "warn"). A scenario supplies the plan, instrument, base frame, joint errors, limits policy and seed. Returns
    readings [rad] and points in the tracker frame [mm] (write them with :func:`robotcal.write_capture`).

    Examples
    --------
    >>> import robotcal
    >>> capture = robotcal.simulate(robotcal.load_scenario("kr5-demo"), rng=7)
    >>> capture.n_points, capture.n_joints, capture.seed
    (270, 6, 7)
    """
    robot, scenario = _split(robot)
    plan = needed(plan, "plan", scenario, lambda s: s.plan)
    instrument = needed(instrument, "instrument", scenario, lambda s: s.instrument)
    if tracker_from_base is None:
        tracker_from_base = np.eye(4) if scenario is None else scenario.tracker_from_base
    if joint_errors is None and scenario is not None:
        joint_errors = scenario.joint_errors
    if joint_limits is None:
        joint_limits = "warn" if scenario is None else scenario.joint_limits
    seed = seed_from(rng, None if scenario is None else scenario.seed)
    capture, _ = simulate_capture(
        robot, plan, instrument, tracker_from_base, true_parameters=_parameters(true_parameters, robot, "true_parameters"),
        joint_errors=joint_errors, joint_limits=joint_limits, rng=np.random.default_rng(seed),
    )  # fmt: skip
    source = "capture simulated" + (f" from {scenario.name}" if scenario is not None else "")
    return dataclasses.replace(capture, source=source, seed=seed)


def simulate_poses(
    robot: RobotModel | Scenario,
    poses_deg: np.typing.ArrayLike | None = None,
    *,
    n_poses: int | None = None,
    targets: ReflectorMount | Sequence[Target] | None = None,
    offsets_mm: Mapping[str, Any] | None = None,
    margin_deg: float | None = None,
    min_height_mm: float | None = None,
    instrument: Instrument | None = None,
    tracker_from_base: np.ndarray | None = None,
    true_parameters: ParameterSource = None,
    joint_errors: JointErrorModel | None = None,
    kind: Literal["validation", "calibration"] = "validation",
    rng: np.random.Generator | int | None = None,
) -> Capture:
    """A capture at free poses (``circle = 0``): readings ``poses_deg`` (n_poses, n_joints) [deg], or ``n_poses``
    random reachable poses ``margin_deg`` inside the joint limits with the target ``min_height_mm`` above the base;
    each measured on one flange target (a ReflectorMount: a validation capture) or on several ``targets`` in turn
    (a ``target`` column; ``offsets_mm``: the true offsets of those declared with a guess). One generator seeded from
    ``rng`` draws the poses, then the noise; readings outside the limits give a JointLimitWarning.

    A scenario supplies its ``[validation]`` table (``kind="calibration"``: ``[calibration_poses]``), the instrument,
    the base frame and the ``joint_errors`` (its ``[[capture.joint_errors]]``; at free poses without lash).

    Examples
    --------
    >>> import robotcal
    >>> validation = robotcal.simulate_poses(robotcal.load_scenario("kr5-demo"), rng=8)
    >>> validation.n_points, int(validation.circle.max())
    (100, 0)
    """
    from robotcal.simulation.generator import simulate_target_poses

    robot, scenario = _split(robot)
    table, targets = free_pose_table(scenario, kind, targets)
    instrument = needed(instrument, "instrument", scenario, lambda s: s.instrument)
    if tracker_from_base is None:
        tracker_from_base = np.eye(4) if scenario is None else scenario.tracker_from_base
    truth = _parameters(true_parameters, robot, "true_parameters")
    joint_errors = scenario.joint_errors if joint_errors is None and scenario is not None else joint_errors
    targets, offsets = true_offsets(targets, offsets_mm)
    seed = seed_from(rng, table.seed)
    generator = np.random.default_rng(seed)
    if poses_deg is None:
        readings = random_poses(
            robot, table.poses if n_poses is None else n_poses,
            margin_deg=table.margin_deg if margin_deg is None else margin_deg,
            min_height_mm=table.min_height_mm if min_height_mm is None else min_height_mm,
            reflector=ReflectorMount(frame="flange", positions=offsets.mean(axis=0)), rng=generator,
        )  # fmt: skip
    else:
        readings = np.deg2rad(check_joint_variables(poses_deg, robot.n_joints, "poses_deg"))
        readings = check_readings(robot, readings, name="poses_deg")  # outside the limits: a JointLimitWarning
    if isinstance(targets, ReflectorMount):
        capture, _ = simulate_poses_core(
            robot, readings, targets, instrument, tracker_from_base, true_parameters=truth, joint_errors=joint_errors,
            rng=generator,
        )
    else:
        capture, _ = simulate_target_poses(
            robot, readings, targets, instrument, tracker_from_base, true_parameters=truth, true_offsets=offsets,
            joint_errors=joint_errors, rng=generator,
        )  # fmt: skip
    what = "validation capture"
    if not isinstance(targets, ReflectorMount):
        what = f"capture of {len(targets)} target(s) at free poses"
    what = "calibration poses" if kind == "calibration" else what
    source = f"{what} simulated" + (f" from {scenario.name}" if scenario is not None else "")
    return dataclasses.replace(capture, source=source, seed=seed)


# ------------------------------------------------------------------------------------ identification


def identify(
    capture: Capture | PathLike,
    robot: RobotModel | Scenario,
    *,
    target: ReflectorMount | Target | str | None = None,
    tracker_from_base: np.ndarray | None = None,
    options: CPAOptions | None = None,
    instrument: Instrument | None = None,
    check: bool = True,
    health: Health = "warn",
) -> CPAResult:
    """Circle Point Analysis of a capture (thesis ch. 4.4-4.5).

    Parameters
    ----------
    capture : Capture or path
        One circle per joint (``circle,direction,q1..qN,x,y,z``: deg, mm in the tracker frame).
    robot : RobotModel or Scenario
        A scenario supplies the target, the base frame, the ``[identification]`` options and the instrument.
    target : ReflectorMount, Target or str
        Where the measured target sat (a known target); with a ``target`` column, the target (or its name)
        whose rows CPA uses (default: the capture's first target).
    tracker_from_base : array_like, shape (4, 4), optional
        The base frame in the tracker frame [mm]; None: registered from the data (Horn), unless
        ``options.base_frame`` says "given".
    options : CPAOptions, optional
        Circle fit, base frame and base axis choices (docs/scenario.md, ``[identification]``).
    instrument : Instrument, optional
        For the plausibility checks and the fit health (the points' U(95) when the capture has them).
    check : bool
        First run the plausibility checks (units, radians for degrees, another robot, outliers):
        :func:`robotcal.identification.plausibility.check_capture` (they need the instrument).
    health : {"warn", "strict", "off"}
        The fit health (:mod:`robotcal.identification.health`): warn when it is not OK, raise
        :class:`~robotcal.errors.FitHealthError` (``"strict"``), or neither; ``result.health`` holds it.

    Returns
    -------
    CPAResult
        ``.parameters`` [mm, rad], the fitted circles, the line-pair cases, the base frame of the identified
        model, ``health``, ``success`` and ``message``.

    Examples
    --------
    Noise-free data give the true parameters back (thesis Table 5.1 scenario):

    >>> import numpy as np, robotcal
    >>> scenario = robotcal.load_scenario("thesis-noise-free")
    >>> truth = robotcal.perturb(scenario, rng=3)
    >>> capture = robotcal.simulate(scenario, rng=1, true_parameters=truth)
    >>> cpa = robotcal.identify(capture, scenario)
    >>> int(cpa.parameters.identified.sum())  # of the 6 x 5 table, those CPA determines
    20
    >>> bool(np.abs(cpa.parameters.difference(truth)).max() < 1e-9)  # mm, rad (angles wrapped)
    True
    """
    robot, scenario = _split(robot)
    capture = _capture(capture, robot)
    if scenario is not None:
        if target is None:
            target = scenario_cpa_target(scenario, capture)
        elif isinstance(target, str):
            target = scenario.target(target)
        if options is None:
            options = scenario.identification
        if tracker_from_base is None and options.base_frame == "given":
            tracker_from_base = scenario.tracker_from_base
    if target is None:
        raise InputError("`target` is needed: where the target sat (a ReflectorMount or a known Target)")
    if options is None:
        options = CPAOptions(base_frame="given" if tracker_from_base is not None else "registered")
    instrument = _instrument(instrument, scenario)
    capture, mount = cpa_rows(capture, target)
    if check and instrument is not None:
        check_capture(capture, robot, mount, instrument, options=options)
    result = identify_cpa(capture, robot, mount, tracker_from_base=tracker_from_base, options=options)
    verdict = cpa_health(result, capture, instrument, repeatability_of(scenario))
    if health != "off":
        report_health(verdict, source=capture.source, strict=health == "strict")
    return dataclasses.replace(result, health=verdict)


def refine(
    capture: Capture | PathLike,
    robot: RobotModel | Scenario,
    start: ParameterSource = None,
    *,
    targets: ReflectorMount | Target | Sequence[Target] | None = None,
    tracker_from_base: np.ndarray | None = None,
    criterion: Criterion = "points",
    instrument: Instrument | None = None,
    health: Health = "warn",
    model: ModelName | None = None,
    folds: int | None = None,
    backlash_deg: np.typing.ArrayLike | JointAnalysis | None = None,
    workers: int = 1,
    progress: Callable[[int, int | None, str], None] | None = None,
    settings: RefinementSettings | None = None,
    **options: Any,
) -> RefinementResult:
    """Least-squares refinement over every measured point (thesis ch. 4.5.7), geometric or extended (issue 22).

    Parameters
    ----------
    capture : Capture or path
        Circles or free poses, one or several targets (``target`` column).
    robot : RobotModel or Scenario
        A scenario supplies the targets, the base frame (held when ``[identification] base_frame = "given"``,
        estimated when "registered"), the instrument, the payload and the ``[joint_model]`` settings.
    start : ParameterSet, CPAResult, RefinementResult, path or None
        Start values (usually :func:`identify`'s result; None: nominal). Its joint model, if any, is the start
        of a model with the same parameters; the others start at zero.
    targets : ReflectorMount, Target or sequence of Target
        Where the points were measured; flange targets may have unknown offsets, which are estimated.
    tracker_from_base : array_like, shape (4, 4), optional
        Points criterion: the base frame, held (pass ``estimate_base=True`` to estimate it from there);
        None: estimated from a Horn registration start.
    criterion : {"points", "distances"}
        Eq. 4-101 (positions in the tracker frame) or eq. 4-102 (all pairwise distances).
    instrument : Instrument, optional
        For the fit health (the points' U(95) when the capture has them).
    health : {"warn", "strict", "off"}
        As for :func:`identify`; ``result.health`` holds the verdict.
    model : {"geometric", "compliance", "harmonic", "compliance+harmonic", "auto"}, optional
        The model fitted (:mod:`robotcal.identification.model_choice`); ``auto`` fits each and keeps the one
        cross-validation chooses. Default: the scenario's ``[joint_model] fit``, else ``geometric``.
    folds : int, optional
        k of the cross-validation by pose every fit reports (``result.cross_validation``); 0: none. Default: the
        scenario's ``[joint_model] folds``, else 5.
    backlash_deg : array_like, shape (n_joints,), or JointAnalysis, optional
        The angular lash of every joint [deg] (or :func:`diagnose_joints`' analysis: the joints whose backlash
        exceeds the noise), a fixed correction of the circle points by their direction, whatever the model.
    workers : int
        Processes running the fits and the cross-validation folds (``auto``: 4 models x (1 + folds) fits); the
        result does not depend on it.
    progress : callable, optional
        ``progress(done, total, what)`` after every fit.
    settings : RefinementSettings, optional
        The refinement's settings whole (then ``criterion`` and ``**options`` are not given).
    **options
        The other fields of :class:`~robotcal.identification.settings.RefinementSettings` (``free``,
        ``estimate_base``, ``method``, ``max_nfev``, ``tolerance``, ``rank_tolerance``, ``weights``,
        ``on_unidentifiable``).

    Returns
    -------
    RefinementResult
        ``.parameters`` [mm, rad] (with its joint model for an extended fit), ``success``, ``fit`` (residual
        statistics [mm], convergence history), ``identifiability``, ``uncertainty`` (linearised covariance,
        ``standard_uncertainty`` [mm, rad], ``joint_model_uncertainty``), ``health``, ``cross_validation`` and,
        for ``auto``, ``model_choice``.

    Examples
    --------
    >>> import robotcal
    >>> scenario = robotcal.load_scenario("kr5-demo")
    >>> truth = robotcal.perturb(scenario, rng=11)
    >>> capture = robotcal.simulate(scenario, rng=1, true_parameters=truth)
    >>> result = robotcal.refine(capture, scenario, robotcal.identify(capture, scenario), criterion="distances")
    >>> bool(result.success), result.criterion
    (True, 'distances')
    >>> bool(result.fit.residual_rms < 0.05)  # mm: laser-tracker noise and the backlash the model does not hold
    True
    """
    robot, scenario = _split(robot)
    capture = _capture(capture, robot)
    choice = model_choice_settings(scenario, model, folds)
    if settings is None:
        settings = RefinementSettings(criterion=criterion, **{"repeatability_mm": repeatability_of(scenario), **options})
    elif options or criterion != "points":
        raise InputError("give `settings` or `criterion` and the options, not both")
    targets, tracker_from_base = refinement_targets(scenario, capture, targets, tracker_from_base)
    lash, lash_source = backlash_correction(backlash_deg, robot)
    result = refine_model(
        capture, _parameters(start, robot, "start"), targets, settings=settings, choice=choice,
        tracker_from_base=tracker_from_base, masses=link_masses(robot, scenario), backlash=lash,
        backlash_source=lash_source, instrument=_instrument(instrument, scenario), workers=workers, progress=progress,
    )  # fmt: skip
    if health != "off" and result.health is not None:  # (never None: every refinement judges its fit)
        report_health(result.health, source=capture.source, strict=health == "strict")
    return result


def evaluate(
    captures: Capture | PathLike | Mapping[str, Capture | PathLike],
    parameter_sets: Mapping[str, ParameterSource],
    robot: RobotModel | Scenario,
    *,
    targets: Any = None,
    views: Sequence[str] = ("points", "distances"),
    bases: Mapping[str, np.ndarray] | None = None,
    set_targets: Mapping[str, Any] | None = None,
) -> tuple[EvaluationRow, ...]:
    """Mean, max and RMS errors of named parameter sets on captures (thesis Tables 4.10/4.11).

    ``captures``: a capture (named ``"capture"``) or a mapping of names to captures; ``parameter_sets``: names to
    parameters, e.g. ``{"nominal": None, "cpa": cpa, "refined": refined}``, the first the reference of
    ``improvement_pct``; ``targets``: where each capture's points were measured (one for all, or per capture name;
    a scenario supplies them: :func:`capture_targets`); ``views``: ``points`` (after a best-fit registration),
    ``distances`` (all pairwise) or ``absolute`` (in the base frames ``bases``: set name -> 4x4 [mm]);
    ``set_targets``: per set, the flange offsets it estimated (name -> xyz [mm]). Rows are ordered by capture, view,
    parameter set.

    Examples
    --------
    >>> import robotcal
    >>> scenario = robotcal.load_scenario("kr5-demo")
    >>> truth = robotcal.perturb(scenario, rng=11)
    >>> capture = robotcal.simulate(scenario, rng=1, true_parameters=truth)
    >>> validation = robotcal.simulate_poses(scenario, rng=2, true_parameters=truth)
    >>> refined = robotcal.refine(capture, scenario, robotcal.identify(capture, scenario))
    >>> rows = robotcal.evaluate({"validation": validation}, {"nominal": None, "refined": refined}, scenario,
    ...                          views=["points"])
    >>> [(row.parameter_set, row.view) for row in rows]
    [('nominal', 'points'), ('refined', 'points')]
    >>> bool(rows[1].mean_error_mm < 0.25 * rows[0].mean_error_mm)  # calibration removes most of the error
    True
    """
    robot, scenario = _split(robot)
    if isinstance(captures, Mapping):
        named = {str(name): _capture(value, robot, f"captures[{name!r}]") for name, value in captures.items()}
    else:
        named = {"capture": _capture(captures, robot, "captures")}
    if not isinstance(parameter_sets, Mapping):
        raise InputError(
            f"`parameter_sets` must be a mapping of names to parameters; got {type(parameter_sets).__name__}"
        )
    sets = {str(name): _parameters(value, robot, f"parameter_sets[{name!r}]") for name, value in parameter_sets.items()}
    if targets is None:
        if scenario is None:
            raise InputError("`targets` is needed: where the points of each capture were measured")
        targets = {name: capture_targets(scenario, capture) for name, capture in named.items()}
    elif not isinstance(targets, Mapping):
        targets = dict.fromkeys(named, targets)
    return evaluate_parameters(named, sets, targets, views=tuple(views), bases=bases, set_targets=set_targets)


# ------------------------------------------------------------------------------------------ uncertainty


def monte_carlo_problem(
    robot: RobotModel | Scenario,
    *,
    plan: CapturePlan | None = None,
    instrument: Instrument | None = None,
    tracker_from_base: np.ndarray | None = None,
    parameters: ParameterSource = None,
    options: CPAOptions | None = None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: str | None = None,
    model: Literal["cpa", "refined"] = "cpa",
    criterion: Criterion = "points",
    poses: Capture | PathLike | None = None,
    joint_model: JointModel | None = None,
) -> MonteCarloProblem:
    """The Monte Carlo problem (:func:`robotcal.uncertainty.montecarlo.prepare_monte_carlo`) of a capture plan:
    every input check happens here, before any draw. Arguments as for :func:`monte_carlo`."""
    from robotcal.uncertainty.montecarlo import prepare_monte_carlo

    robot, scenario = _split(robot)
    truth = _parameters(parameters, robot, "parameters")
    pose_readings = pose_target = None
    if model == "refined":
        if joint_model is None and truth.joint_model is not None:  # the deployed model's own (and its lash)
            joint_model = truth.joint_model
        if poses is None and scenario is not None and scenario.calibration_poses is not None:
            poses = simulate_poses(scenario, kind="calibration", true_parameters=truth)
        if poses is not None:
            poses = _capture(poses, robot, "poses")
            if scenario is None:
                raise InputError("calibration poses need the scenario that names their target")
            pose_readings = poses.readings
            names = set(poses.point_targets or (target_name(scenario, poses),))
            if len(names) != 1:
                raise InputError(
                    f"{poses.source}: calibration poses on one flange target; got {', '.join(sorted(names))}"
                )
            pose_target = scenario.target(names.pop())
    if scenario is not None:
        plan, instrument, tracker_from_base, options, joint_errors, joint_limits = simulation_inputs(
            scenario, plan=plan, instrument=instrument, tracker_from_base=tracker_from_base, options=options,
            joint_errors=joint_errors, joint_limits=joint_limits,
        )  # fmt: skip
    if plan is None or instrument is None:
        raise InputError("`plan` and `instrument` are needed (or give a Scenario in place of the robot)")
    return prepare_monte_carlo(
        robot, plan, instrument, np.eye(4) if tracker_from_base is None else tracker_from_base, options=options,
        true_parameters=truth, joint_errors=joint_errors, joint_limits=joint_limits or "warn", model=model,
        criterion=criterion, poses=pose_readings, poses_target=pose_target,
        joint_model=None if joint_model is None else joint_model.with_values(np.zeros(joint_model.size)),
        repeatability_mm=repeatability_of(scenario),
    )  # fmt: skip


def monte_carlo(
    robot: RobotModel | Scenario,
    *,
    settings: MonteCarloSettings | None = None,
    plan: CapturePlan | None = None,
    instrument: Instrument | None = None,
    tracker_from_base: np.ndarray | None = None,
    parameters: ParameterSource = None,
    options: CPAOptions | None = None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: str | None = None,
    draws: int | None = None,
    model: Literal["cpa", "refined"] = "cpa",
    criterion: Criterion = "points",
    rng: np.random.Generator | int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    coverage: float | None = None,
    interval: Literal["symmetric", "shortest"] | None = None,
    adaptive: bool | None = None,
    keep_draws: bool | None = None,
    linearised: bool | None = None,
    batch_size: int | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    poses: Capture | PathLike | None = None,
    joint_model: JointModel | None = None,
) -> MonteCarloResult:
    """GUM Supplement 1 Monte Carlo of a calibration by Circle Point Analysis (thesis ch. 5.2.3).

    Every draw adds the instrument noise (and the random part of the joint errors) to the capture the plan gives
    on the robot ``parameters`` (the estimate, when stating a calibration's uncertainty; default nominal),
    identifies it by CPA and, with ``model="refined"``, refines it with ``criterion`` (the deployed model: its
    ``joint_model``, default that of ``parameters``, fitted from zero, and the calibration ``poses``, default the
    scenario's ``[calibration_poses]``, refined with the circles); the spread of the draws is the uncertainty.

    Parameters
    ----------
    robot : RobotModel or Scenario
        A scenario supplies the plan, instrument, base frame, CPA options, joint errors, limits policy and its
        ``[montecarlo]`` table (draws, seed, coverage).
    settings : MonteCarloSettings, optional
        How many draws and how they are organised, built once (e.g. by the pipeline) and used unchanged; or give
        its fields as the keywords ``draws`` (M: default the scenario's ``montecarlo.iterations``, else 10^4),
        ``coverage`` (default the scenario's, else 0.95), ``interval``, ``adaptive`` (JCGM 101 §7.9),
        ``workers`` (processes; ``scheduler`` a Dask address instead), ``keep_draws`` (needed by
        :func:`tcp_uncertainty`) and ``batch_size`` (draws per vectorised call). A keyword that disagrees with
        ``settings`` is an InputError.
    rng : None, int or numpy.random.Generator
        The draws are seeded per block from one int seed (default the scenario's), so the result does not
        depend on ``workers``; ``result.seed`` records it.
    linearised : bool, optional
        Also compute the GUM law-of-propagation comparison (JCGM 101 §8); default True for ``model="cpa"``, False
        for ``"refined"`` (where it costs as much as many draws).
    progress : callable, optional
        ``progress(draws_done, draws_total)`` after every block.

    Returns
    -------
    MonteCarloResult
        ``summary`` (mean, ``std_uncertainty``, intervals, min, max per parameter, shape (n_joints, 5) [mm, rad]),
        covariance, ``draws`` (n_draws, n_joints, 5), ``seed``; for an extended model also ``joint_model``,
        ``extra_draws`` and ``extra_summary``.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> result = robotcal.monte_carlo(robotcal.load_scenario("thesis-laser-tracker"), draws=200, rng=1)
    >>> result.n_draws, result.seed, result.model
    (200, 1, 'cpa')
    >>> u = result.summary.std_uncertainty  # (6, 5): d, theta, a, alpha, beta per joint [mm, rad]
    >>> bool(np.all(u[result.identified] > 0)), bool(np.all(u[~result.identified] == 0))
    (True, True)
    """
    from robotcal.resolve import monte_carlo_settings
    from robotcal.uncertainty.montecarlo import run_monte_carlo

    _, scenario = _split(robot)
    settings = monte_carlo_settings(
        settings, scenario, draws=draws, coverage=coverage, interval=interval, adaptive=adaptive, workers=workers,
        scheduler=scheduler, keep_draws=keep_draws, batch_size=batch_size,
    )  # fmt: skip
    problem = monte_carlo_problem(
        robot, plan=plan, instrument=instrument, tracker_from_base=tracker_from_base, parameters=parameters,
        options=options, joint_errors=joint_errors, joint_limits=joint_limits, model=model, criterion=criterion,
        poses=poses, joint_model=joint_model,
    )  # fmt: skip
    seed = seed_from(rng, scenario.montecarlo.seed if scenario is not None and scenario.montecarlo else None)
    linearised = model == "cpa" if linearised is None else linearised
    return run_monte_carlo(problem, settings, seed=seed, linearised=linearised, progress=progress)


# ----------------------------------------------------------------------------------------------- planning


def plan_tcp_p95(
    scenario: Scenario,
    plan: CapturePlan | None = None,
    *,
    draws: int = 10_000,
    rng: np.random.Generator | int | None = None,
    workspace_poses: int = 200,
    workspace_seed: int = 0,
    workers: int | None = None,
    progress: Callable[[int, int | None], None] | None = None,
) -> float:
    """The 95th percentile [mm] of the TCP position uncertainty over ``workspace_poses`` seeded workspace poses,
    from a Monte Carlo of ``draws`` draws of ``plan`` (default the scenario's) without joint errors or limits: how
    ``robotcal plan optimise`` confirms the baseline and the optimised plan (``workers`` default: up to 2)."""
    from robotcal.planning.optimise import workspace_readings
    from robotcal.uncertainty.workspace import workspace_uncertainty as workspace

    variant = dataclasses.replace(
        scenario, plan=scenario.plan if plan is None else plan, joint_errors=None, joint_limits="ignore"
    )
    workers = min(os.cpu_count() or 1, 2) if workers is None else workers
    result = monte_carlo(variant, draws=draws, rng=rng, workers=workers, linearised=False, progress=progress)
    readings = workspace_readings(scenario.robot, workspace_poses, workspace_seed)
    return float(np.percentile(workspace(scenario.robot, result.draws, readings=readings).position_uncertainty, 95.0))
