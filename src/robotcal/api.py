"""The front door for Python users: one call per calibration step (docs/api.md).

Every function takes the objects a user already has, explicitly: a robot (:class:`RobotModel`, from
:func:`robotcal.load_robot` or built by hand), a capture (:class:`Capture`, from :func:`robotcal.read_capture`
or :func:`simulate`), targets, an instrument, options. A :class:`~robotcal.io.scenario.Scenario` is a
convenience: given in place of the robot, it supplies the robot and every keyword the call leaves out
(its targets, base frame, instrument, capture plan, joint errors, identification options and seeds), as
``robotcal run`` uses it. The command line and the pipeline call these same functions.

Conventions:

- numbers given here are in millimetres and degrees (names carry the unit: ``poses_deg``, ``tool_mm``); the
  result objects returned are the core's, in mm and radians;
- a capture may be given as a :class:`Capture` or a capture CSV path, parameters as a :class:`ParameterSet`,
  a result holding one (``.parameters``) or a parameter JSON path;
- randomness comes from ``rng``: None, an int seed or a ``numpy.random.Generator`` (:func:`seed_from`); the
  core takes an int seed, so that blocks of draws are reproducible for any batch size or worker count, and
  every result records the seed it used.

These functions never print and never write files (use :func:`robotcal.write_capture`,
:func:`robotcal.write_parameters`, or the pipeline of :func:`robotcal.run_calibration`).
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from robotcal.capture import Capture, join_captures
from robotcal.diagnostics import HarmonicModel, JointDiagnostics, analyze_joints, fit_harmonics
from robotcal.errors import InputError, JointLimitWarning
from robotcal.identification.cpa import CPAOptions, CPAResult, identify_cpa
from robotcal.identification.evaluation import EvaluationRow, evaluate_parameters
from robotcal.identification.health import cpa_health, report_health
from robotcal.identification.model_choice import refine_model
from robotcal.identification.plausibility import check_capture
from robotcal.identification.records import RefinementResult
from robotcal.identification.settings import ModelChoiceSettings, RefinementSettings
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.robots import load_robot
from robotcal.io.scenario import JointModelTable, Scenario, TCPTable, TruthTable, ValidationTable
from robotcal.io.trajectory_csv import builtin_trajectories, load_trajectory
from robotcal.kinematics.forward import check_joint_variables
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ParameterSet, ReflectorMount, RobotModel
from robotcal.limits import SEED_BOUND
from robotcal.simulation import CapturePlan, JointErrorModel, simulate_capture
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses
from robotcal.simulation.poses import simulate_poses as simulate_poses_core
from robotcal.uncertainty.tcp import check_readings

if TYPE_CHECKING:  # the Monte Carlo, TCP and planning modules load when a function needs them
    from robotcal.kinematics.compensation import Compensation, CompensationSettings
    from robotcal.planning.cell import CellModel, PlanCheck
    from robotcal.programs.filter import FilteredProgram
    from robotcal.uncertainty.montecarlo import MonteCarloResult
    from robotcal.uncertainty.tcp import TCPUncertainty
    from robotcal.uncertainty.workspace import WorkspaceUncertainty

__all__ = [
    "SEED_BOUND",
    "JointAnalysis",
    "diagnose_joints",
    "calibration_capture",
    "capture_targets",
    "change_plan",
    "compensate",
    "check_plan",
    "evaluate",
    "identify",
    "link_masses",
    "measured_monte_carlo",
    "monte_carlo",
    "monte_carlo_problem",
    "perturb",
    "refine",
    "seed_from",
    "simulate",
    "simulate_poses",
    "tcp_uncertainty",
    "validation_consistency",
    "validation_target",
    "workspace_uncertainty",
    "DEFAULT_TRAJECTORY",
    "KUKA_CONTROLLER_ROBOT",
    "TABLE_5_8_READINGS_DEG",
    "TCPTargets",
    "convert_readings",
    "coverage_study",
    "tcp_targets",
]


Criterion = Literal["points", "distances"]
ModelName = Literal["geometric", "compliance", "harmonic", "compliance+harmonic", "auto"]
Health = Literal["warn", "strict", "off"]


# ------------------------------------------------------------------------------------------ coercion


def seed_from(rng, default: int | None = None) -> int:
    """The int seed a core function takes, from an ``rng`` argument.

    Parameters
    ----------
    rng : None, int or numpy.random.Generator
        None: ``default`` when given (a seed the scenario records), else fresh entropy; an int: that
        seed; a Generator: ``rng.integers(2**63)`` (the Generator advances, so two calls with one
        Generator give two different, reproducible seeds).
    default : int, optional

    Returns
    -------
    int
        A seed in ``[0, 2**63)``, to record with the result.

    Examples
    --------
    >>> import numpy as np
    >>> from robotcal.api import seed_from
    >>> seed_from(7)
    7
    >>> seed_from(None, default=3)
    3
    >>> a = seed_from(np.random.default_rng(1))
    >>> a == seed_from(np.random.default_rng(1))
    True
    """
    if rng is None:
        if default is not None:
            return seed_from(default)
        return int(np.random.SeedSequence().entropy % SEED_BOUND)
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(SEED_BOUND))
    if isinstance(rng, bool) or not isinstance(rng, int | np.integer):
        raise InputError(f"`rng` must be None, an int seed or a numpy.random.Generator; got {type(rng).__name__}")
    if not 0 <= int(rng) < SEED_BOUND:
        raise InputError(f"`rng` seed must be in [0, 2**63); got {rng}")
    return int(rng)


def _split(robot) -> tuple[RobotModel, Scenario | None]:
    """The robot and the scenario (None) of a ``robot`` argument: a RobotModel or a Scenario."""
    if isinstance(robot, Scenario):
        return robot.robot, robot
    if isinstance(robot, RobotModel):
        return robot, None
    raise InputError(
        "`robot` must be a RobotModel (robotcal.load_robot) or a Scenario (robotcal.load_scenario); "
        f"got {type(robot).__name__}"
    )


def _needed(value, name: str, scenario: Scenario | None, what: str):
    """``value``, else the scenario's ``what`` (a callable of the scenario), else an error naming ``name``."""
    if value is not None:
        return value
    if scenario is None:
        raise InputError(f"`{name}` is needed (or give a Scenario in place of the robot)")
    return what(scenario)


def _capture(capture, robot: RobotModel, name: str = "capture") -> Capture:
    """A Capture from a Capture or a capture CSV path (read with the robot's joint count)."""
    if isinstance(capture, Capture):
        return capture
    if isinstance(capture, str | os.PathLike):
        from robotcal.io.capture_csv import read_capture

        return read_capture(capture, n_joints=robot.n_joints)
    raise InputError(f"`{name}` must be a Capture or the path of a capture CSV; got {type(capture).__name__}")


def _parameters(parameters, robot: RobotModel, name: str = "parameters") -> ParameterSet:
    """A ParameterSet from a ParameterSet, a result holding one, a parameter JSON path, or None (nominal)."""
    if parameters is None:
        return ParameterSet.nominal(robot)
    if isinstance(getattr(parameters, "parameters", None), ParameterSet):  # CPAResult, RefinementResult
        parameters = parameters.parameters
    elif isinstance(parameters, str | os.PathLike):
        from robotcal.io.parameters_json import read_parameters

        return read_parameters(parameters, robot)
    if not isinstance(parameters, ParameterSet):
        raise InputError(
            f"`{name}` must be a ParameterSet, a CPA or refinement result, or the path of a parameter JSON; "
            f"got {type(parameters).__name__}"
        )
    if parameters.robot.n_joints != robot.n_joints:
        raise InputError(
            f"`{name}` belong to robot {parameters.robot.name!r} ({parameters.robot.n_joints} joints); "
            f"the robot {robot.name!r} has {robot.n_joints}"
        )
    return parameters


def _instrument(instrument, scenario: Scenario | None) -> Instrument | None:
    if instrument is not None or scenario is None:
        return instrument
    return scenario.instrument if scenario.has_instrument else None


# --------------------------------------------------------------------------- targets of a scenario's captures


def validation_target(scenario: Scenario) -> ReflectorMount:
    """The flange target of a scenario's captures at free poses: ``[validation].flange_reflector_mm``, else the
    plan's (or ``[capture]``'s) reflector when it is a flange one, else the only known flange target of
    ``[[targets]]``."""
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


def capture_targets(scenario: Scenario, capture: Capture) -> ReflectorMount | Target | tuple[Target, ...]:
    """The target(s) the points of ``capture`` were measured on, as the scenario declares them.

    * a ``target`` column: the scenario's declared targets (each point names one);
    * free poses (circle = 0): the validation flange target (:func:`validation_target`), or the
      only ``[[targets]]`` entry (whose offset may be unknown);
    * circles: the plan's reflector, else ``[capture]``'s, else the only ``[[targets]]`` entry.
    """
    if capture.target is not None:
        return scenario.targets
    declared = [t for t in scenario.targets if t.name not in ("capture", "validation")]
    if np.any(capture.circle == 0):
        if len(declared) == 1 and scenario.validation is None and scenario.reflector is None:
            return declared[0]
        return validation_target(scenario)
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


def calibration_capture(scenario: Scenario, capture, poses=None) -> Capture:
    """The capture a refinement fits: the circles (or any capture) and, when given, the free calibration poses
    (:func:`simulate_poses` with ``kind="calibration"``, or measured), one after the other with a ``target``
    column. A part without its own column takes the name of the scenario target it was measured on."""
    parts = [capture] if poses is None else [capture, poses]
    named = []
    for part in parts:
        part = _capture(part, scenario.robot)
        named.append((part, None if part.target is not None else _target_name(scenario, part)))
    if len(named) == 1 and named[0][1] is None:
        return named[0][0]
    return join_captures(named, source=" + ".join(part.source for part, _ in named))


def _target_name(scenario: Scenario, capture: Capture) -> str:
    """The name, among the scenario's targets, of the one target of a capture without a ``target`` column."""
    target = capture_targets(scenario, capture)
    if isinstance(target, Target):
        return target.name
    for declared in scenario.targets:
        if declared.frame == target.frame and np.array_equal(
            np.reshape(declared.positions, (-1, 3)), np.reshape(target.positions, (-1, 3))
        ):
            return declared.name
    raise InputError(f"{capture.source}: its target is none of the scenario's named targets; give it a target column")


def _cpa_rows(capture: Capture, target) -> tuple[Capture, ReflectorMount]:
    """The rows CPA uses and their (known) target: all rows, or with a ``target`` column those of ``target``
    (a Target or a name; None: the capture's first target)."""
    if isinstance(target, ReflectorMount):
        if capture.target is not None:
            raise InputError(
                f"{capture.source}: the capture has a `target` column; give CPA's target as a Target (or its name)"
            )
        return capture, target
    if capture.target is not None:
        names = capture.target_names
        name = names[int(capture.target[0])] if target is None else getattr(target, "name", target)
        if name not in names:
            raise InputError(f"{capture.source}: no point of target {name!r} (targets: {', '.join(names)})")
        capture = capture.select(capture.target == names.index(name))
    if not isinstance(target, Target):
        raise InputError(f"`target` must be a ReflectorMount or a Target; got {type(target).__name__}")
    if not target.known:
        raise InputError(
            f"CPA needs a target of known position; the offset of target {target.name!r} is unknown (refine from "
            "the nominal parameters instead, which estimates it)"
        )
    return capture, target.mount


def _scenario_cpa_target(scenario: Scenario, capture: Capture):
    if capture.target is not None:
        return scenario.target(capture.target_names[int(capture.target[0])])
    target = capture_targets(scenario, capture)
    return target if isinstance(target, ReflectorMount | Target) else target[0]


# ---------------------------------------------------------------------------------------- simulation


def perturb(
    robot,
    *,
    length_sd_mm: float | None = None,
    angle_sd_deg: float | None = None,
    include_base: bool | None = None,
    rng=None,
) -> ParameterSet:
    """A perturbed "true" robot for a synthetic study: nominal + N(0, sd) on the identifiable parameters.

    Parameters
    ----------
    robot : RobotModel or Scenario
        A scenario supplies its ``[truth]`` table's ``length_sd_mm``, ``angle_sd_deg``, ``include_base`` and
        seed; without a scenario or table, the table's defaults (0.2 mm, 0.05 deg).
    length_sd_mm, angle_sd_deg : float, optional
        Standard deviations [mm, deg].
    include_base : bool, optional
        Also perturb d1 and theta1.
    rng : None, int or numpy.random.Generator

    Returns
    -------
    ParameterSet
        [mm, rad]; give it to :func:`simulate` as ``true_parameters``.

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


def link_masses(robot, scenario=None):
    """The link masses of the extended model: the robot file's, with the scenario's ``[payload]`` on the flange
    (None when the robot file gives no masses: the compliance is then the lumped form)."""
    robot, scenario = _split(robot) if scenario is None else (robot, scenario)
    masses = robot.masses
    payload = None if scenario is None else scenario.payload
    if masses is None or payload is None:
        return masses
    return masses.with_payload(payload.mass_kg, payload.com_mm)


def _backlash(backlash, robot: RobotModel) -> tuple[np.ndarray | None, str]:
    """The lash correction [rad] and its source from ``backlash_deg`` (array [deg] or a JointAnalysis)."""
    if backlash is None:
        return None, ""
    if isinstance(backlash, JointAnalysis):
        lash = np.zeros(robot.n_joints)
        for joint in backlash.diagnostics.summary():
            if joint.backlash_exceeds_noise:
                lash[joint.joint - 1] = joint.backlash_angle_mean
        return lash, "the joints stage (angular backlash of the joints whose backlash exceeds the noise)"
    values = np.asarray(backlash, dtype=float)
    if values.shape != (robot.n_joints,) or not np.all(np.isfinite(values)):
        raise InputError(f"`backlash_deg` must be {robot.n_joints} finite angles [deg]; got shape {values.shape}")
    return np.deg2rad(values), "given"


def simulate(
    robot,
    plan: CapturePlan | None = None,
    *,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    true_parameters=None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: Literal["warn", "error", "ignore"] | None = None,
    rng=None,
) -> Capture:
    """Simulate a Circle Point capture (thesis ch. 5.2.1).

    Joint errors (eqs 5-2..5-4 and backlash) and instrument noise U(L) = A + B L come from one generator
    seeded from ``rng``; the capture records the seed (``capture.seed``).

    Parameters
    ----------
    robot : RobotModel or Scenario
        A scenario supplies the plan, instrument, base frame, joint errors, limits policy and seed.
    plan : CapturePlan
        The circles: start, sweep and points per joint, and the reflector.
    instrument : Instrument
    tracker_from_base : array_like, shape (4, 4), optional
        The robot base in the instrument frame [mm] (default identity).
    true_parameters : ParameterSet, CPAResult, RefinementResult or path, optional
        The robot that is measured [mm, rad] (e.g. from :func:`perturb`); default nominal.
    joint_errors : JointErrorModel, optional
    joint_limits : {"warn", "error", "ignore"}, optional
        What a plan reaching beyond the joint limits does (default "warn").
    rng : None, int or numpy.random.Generator

    Returns
    -------
    Capture
        Joint readings [rad] and target positions in the tracker frame [mm]; write it as a capture
        CSV (deg, mm) with :func:`robotcal.write_capture`.

    Examples
    --------
    >>> import robotcal
    >>> capture = robotcal.simulate(robotcal.load_scenario("kr5-demo"), rng=7)
    >>> capture.n_points, capture.n_joints, capture.seed
    (270, 6, 7)
    """
    robot, scenario = _split(robot)
    plan = _needed(plan, "plan", scenario, lambda s: s.plan)
    instrument = _needed(instrument, "instrument", scenario, lambda s: s.instrument)
    if tracker_from_base is None:
        tracker_from_base = np.eye(4) if scenario is None else scenario.tracker_from_base
    if joint_errors is None and scenario is not None:
        joint_errors = scenario.joint_errors
    if joint_limits is None:
        joint_limits = "warn" if scenario is None else scenario.joint_limits
    seed = seed_from(rng, None if scenario is None else scenario.seed)
    capture, _ = simulate_capture(
        robot,
        plan,
        instrument,
        tracker_from_base,
        true_parameters=_parameters(true_parameters, robot, "true_parameters"),
        joint_errors=joint_errors,
        joint_limits=joint_limits,
        rng=np.random.default_rng(seed),
    )
    source = "capture simulated" + (f" from {scenario.name}" if scenario is not None else "")
    return dataclasses.replace(capture, source=source, seed=seed)


def simulate_poses(
    robot,
    poses_deg=None,
    *,
    n_poses: int | None = None,
    targets: ReflectorMount | Sequence[Target] | None = None,
    offsets_mm: Mapping | None = None,
    margin_deg: float | None = None,
    min_height_mm: float | None = None,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    true_parameters=None,
    kind: Literal["validation", "calibration"] = "validation",
    rng=None,
) -> Capture:
    """A capture at free poses (``circle = 0``): given readings, or random reachable poses within the joint
    limits, each measured on one flange target (a validation capture) or on several (a ``target`` column).
    One generator seeded from ``rng`` draws the poses, then the noise.

    Parameters
    ----------
    robot : RobotModel or Scenario
        A scenario supplies its ``[validation]`` table (poses, margin, minimum height, seed, flange target), the
        instrument and the base frame: ``simulate_poses(scenario)`` is the scenario's validation capture;
        ``kind="calibration"``: its ``[calibration_poses]`` table and target (``flange``, in a ``target`` column),
        the free poses measured for the refinement.
    poses_deg : array_like, shape (n_poses, n_joints), optional
        Joint readings [deg]; default: ``n_poses`` random poses. Readings outside the joint limits are simulated
        with a :class:`~robotcal.errors.JointLimitWarning` naming the pose and joint.
    n_poses : int, optional
        Number of random poses (default the ``[validation]`` table's, 100).
    targets : ReflectorMount or sequence of Target, optional
        One flange target (a ReflectorMount, ``frame="flange"``: no ``target`` column), or flange Targets
        measured in turn at every pose. Default: the scenario's validation target.
    offsets_mm : mapping of str to (x, y, z), optional
        The true offsets [mm] of Targets whose declared position is only a guess (``known=False``).
    margin_deg, min_height_mm : float, optional
        Random poses: distance kept from the joint limits [deg] (default 5); lowest height of the target above
        the base [mm].
    instrument, tracker_from_base, true_parameters, rng
        As for :func:`simulate`.

    Examples
    --------
    >>> import robotcal
    >>> validation = robotcal.simulate_poses(robotcal.load_scenario("kr5-demo"), rng=8)
    >>> validation.n_points, int(validation.circle.max())
    (100, 0)
    """
    from robotcal.simulation.generator import simulate_target_poses

    robot, scenario = _split(robot)
    if kind == "calibration":
        if scenario is None or scenario.calibration_poses is None:
            raise InputError("calibration poses are a scenario's [calibration_poses] table: give a scenario with one")
        table = scenario.calibration_poses
        targets = (scenario.target(scenario.poses_target),) if targets is None else targets
    elif kind == "validation":
        table = ValidationTable() if scenario is None or scenario.validation is None else scenario.validation
    else:
        raise InputError(f"`kind` must be 'validation' or 'calibration'; got {kind!r}")
    targets = _needed(targets, "targets", scenario, validation_target)
    instrument = _needed(instrument, "instrument", scenario, lambda s: s.instrument)
    if tracker_from_base is None:
        tracker_from_base = np.eye(4) if scenario is None else scenario.tracker_from_base
    truth = _parameters(true_parameters, robot, "true_parameters")
    single = isinstance(targets, ReflectorMount)
    if single:
        offsets = targets.positions
    else:
        targets = tuple(targets)
        offsets = np.array([(offsets_mm or {}).get(t.name, t.positions) for t in targets], dtype=float)
        guessed = [t.name for t in targets if not t.known and t.name not in (offsets_mm or {})]
        if guessed:
            raise InputError(
                f"target(s) {', '.join(guessed)}: declared with an unknown offset, whose guess is no truth; give "
                "their true offsets (`offsets_mm`)"
            )
    seed = seed_from(rng, table.seed)
    generator = np.random.default_rng(seed)
    if poses_deg is None:
        readings = random_poses(
            robot,
            table.poses if n_poses is None else n_poses,
            margin_deg=table.margin_deg if margin_deg is None else margin_deg,
            min_height_mm=table.min_height_mm if min_height_mm is None else min_height_mm,
            reflector=ReflectorMount(frame="flange", positions=offsets.mean(axis=0)),
            rng=generator,
        )
    else:
        readings = np.deg2rad(check_joint_variables(poses_deg, robot.n_joints, "poses_deg"))
        readings = check_readings(robot, readings, name="poses_deg")  # outside the limits: a JointLimitWarning
    if single:
        capture, _ = simulate_poses_core(
            robot, readings, targets, instrument, tracker_from_base, true_parameters=truth, rng=generator
        )
    else:
        capture, _ = simulate_target_poses(
            robot, readings, targets, instrument, tracker_from_base, true_parameters=truth, true_offsets=offsets,
            rng=generator,
        )  # fmt: skip
    what = "validation capture" if single else f"capture of {len(targets)} target(s) at free poses"
    if kind == "calibration":
        what = "calibration poses"
    source = f"{what} simulated" + (f" from {scenario.name}" if scenario is not None else "")
    return dataclasses.replace(capture, source=source, seed=seed)


# ------------------------------------------------------------------------------------ identification


def identify(
    capture,
    robot,
    *,
    target: ReflectorMount | Target | str | None = None,
    tracker_from_base=None,
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
            target = _scenario_cpa_target(scenario, capture)
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
    capture, mount = _cpa_rows(capture, target)
    if check and instrument is not None:
        check_capture(capture, robot, mount, instrument, options=options)
    result = identify_cpa(capture, robot, mount, tracker_from_base=tracker_from_base, options=options)
    verdict = cpa_health(result, capture, instrument)
    if health != "off":
        report_health(verdict, source=capture.source, strict=health == "strict")
    return dataclasses.replace(result, health=verdict)


def refine(
    capture,
    robot,
    start=None,
    *,
    targets: ReflectorMount | Target | Sequence[Target] | None = None,
    tracker_from_base=None,
    criterion: Criterion = "points",
    instrument: Instrument | None = None,
    health: Health = "warn",
    model: ModelName | None = None,
    folds: int | None = None,
    backlash_deg=None,
    workers: int = 1,
    progress: Callable[[int, int | None, str], None] | None = None,
    settings: RefinementSettings | None = None,
    **options,
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
    choice = _model_choice(scenario, model, folds)
    if settings is None:
        settings = RefinementSettings(criterion=criterion, **options)
    elif options or criterion != "points":
        raise InputError("give `settings` or `criterion` and the options, not both")
    if scenario is not None:
        targets = capture_targets(scenario, capture) if targets is None else targets
        if tracker_from_base is None and scenario.identification.base_frame == "given":
            tracker_from_base = scenario.tracker_from_base
    if targets is None:
        raise InputError("`targets` is needed: where the points were measured (a ReflectorMount or Targets)")
    lash, lash_source = _backlash(backlash_deg, robot)
    result = refine_model(
        capture, _parameters(start, robot, "start"), targets, settings=settings, choice=choice,
        tracker_from_base=tracker_from_base, masses=link_masses(robot, scenario), backlash=lash,
        backlash_source=lash_source, instrument=_instrument(instrument, scenario), workers=workers, progress=progress,
    )  # fmt: skip
    if health != "off":
        report_health(result.health, source=capture.source, strict=health == "strict")
    return result


def _model_choice(scenario: Scenario | None, model: str | None, folds: int | None) -> ModelChoiceSettings:
    """The model-choice settings: the arguments, else the scenario's ``[joint_model]`` (joints made 0-based)."""
    table = scenario.joint_model if scenario is not None else JointModelTable()

    def joints(values):
        return None if values is None else tuple(j - 1 for j in values)

    return ModelChoiceSettings(
        model=table.fit if model is None else model, folds=table.folds if folds is None else folds, seed=table.seed,
        compliance_joints=joints(table.compliance_joints), harmonic_joints=joints(table.harmonic_joints),
        harmonic_order=table.harmonic_order,
    )  # fmt: skip


def _calibrated(parameters, robot) -> ParameterSet:
    """The calibrated model of ``compensate`` and ``filter_program``: a ParameterSet, a result holding one, or a
    parameter JSON path read for ``robot`` (a RobotModel or a Scenario)."""
    if robot is None:
        held = getattr(parameters, "parameters", parameters)
        if not isinstance(held, ParameterSet):
            raise InputError("`parameters` must be a ParameterSet or a result holding one (a JSON path needs `robot`)")
        robot = held.robot
    else:
        robot, _ = _split(robot)
    return _parameters(parameters, robot, "parameters")


def compensate(
    parameters,
    robot=None,
    *,
    poses_deg=None,
    cartesian=None,
    start_deg=None,
    tool_mm=None,
    settings: CompensationSettings | None = None,
    progress=None,
) -> Compensation:
    """Joint commands with which the calibrated robot reaches the poses it was taught (issues 22, 28; thesis ch. 6.2).

    Every row gets a command and a status (:mod:`robotcal.kinematics.compensation`): ``ok`` (exact to 1e-6 mm and
    1e-6 deg, on the taught branch, no joint moved more than 2 deg), ``near_singular`` / ``large_correction`` (a
    damped command, flagged), ``outside_limits`` / ``unreachable`` (no command: NaN). One hard pose never fails the
    others.

    Parameters
    ----------
    parameters : ParameterSet, a result holding one, or a parameter JSON path
        The calibrated model (an extended one applies its joint model too); a path needs ``robot``.
    robot : RobotModel or Scenario, optional
        For a parameter JSON path.
    poses_deg : array_like, shape (n_poses, n_joints), optional
        Joint targets taught on the nominal model [deg]: the target is the nominal model's tool frame there, and
        their branch is kept.
    cartesian : array_like, shape (n_poses, 6), optional
        Or Cartesian targets ``x, y, z`` [mm], ``A, B, C`` [deg, KUKA ``Rz(A) Ry(B) Rx(C)``] in the robot base
        frame; the nominal controller's solution nearest ``start_deg`` (its branch) is what the command replaces.
    start_deg : array_like, shape (n_joints,) or (n_poses, n_joints), optional
        Cartesian targets: readings near the wanted solution branch [deg] (default: the middle of the joint limits).
    tool_mm : array_like, shape (3,), optional
        The tool point in the flange frame [mm] (default: the flange).
    settings : CompensationSettings, optional
        What an ``ok`` command must meet (default: 2 deg, 1e-6 mm, 1e-6 deg).
    progress : callable, optional
        ``progress(done, total)`` after every block of 5,000 poses.

    Returns
    -------
    Compensation
        ``readings`` [rad] to command, ``status`` and the remaining error of every pose.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> robot = robotcal.load_robot("kuka-kr5-sixx-r650")
    >>> calibrated = robotcal.perturb(robot, rng=3)
    >>> taught = [[10.0, 40.0, 30.0, 5.0, 45.0, 0.0]]
    >>> result = robotcal.compensate(calibrated, poses_deg=taught)
    >>> result.status.tolist(), bool(np.abs(np.rad2deg(result.readings) - taught).max() > 1e-3)
    (['ok'], True)
    """
    from robotcal.geometry.euler import matrix_from_kuka_abc
    from robotcal.kinematics.compensation import compensate_commands
    from robotcal.kinematics.forward import forward_kinematics
    from robotcal.kinematics.inverse import nominal_solutions

    parameters = _calibrated(parameters, robot)
    robot = parameters.robot
    if (poses_deg is None) == (cartesian is None):
        raise InputError("give the targets as joint poses (`poses_deg`) or as Cartesian targets (`cartesian`), one of them")
    tool = np.eye(4)
    if tool_mm is not None:
        tool[:3, 3] = np.asarray(tool_mm, dtype=float).reshape(3)
    if poses_deg is not None:
        taught = check_joint_variables(np.deg2rad(np.asarray(poses_deg, dtype=float)), robot.n_joints, "poses_deg")
        targets = forward_kinematics(robot.nominal, robot.model_joint_variables(taught)) @ tool
    else:
        values = np.atleast_2d(np.asarray(cartesian, dtype=float))
        if values.ndim != 2 or values.shape[1] != 6 or not np.all(np.isfinite(values)):
            raise InputError(f"`cartesian` must be finite rows of x, y, z, A, B, C; got shape {values.shape}")
        targets = np.broadcast_to(np.eye(4), (values.shape[0], 4, 4)).copy()
        targets[:, :3, :3] = matrix_from_kuka_abc(np.deg2rad(values[:, 3:]))
        targets[:, :3, 3] = values[:, :3]
        middle = np.where(np.isfinite(robot.limits), robot.limits, 0.0).mean(axis=1)
        seed = middle if start_deg is None else np.deg2rad(np.asarray(start_deg, dtype=float))
        seed = np.broadcast_to(seed, (values.shape[0], robot.n_joints))
        solutions, exists = nominal_solutions(robot, targets @ np.linalg.inv(tool), reference=seed)
        # the nominal controller's solution nearest the seed: an exact one inside the limits before any other
        inside = np.all((solutions >= robot.limits[:, 0]) & (solutions <= robot.limits[:, 1]), axis=-1)
        distance = np.abs(solutions - seed[:, None, :]).max(axis=-1) + np.where(exists, 0.0, 1e6) + np.where(inside, 0.0, 1e3)
        taught = solutions[np.arange(len(seed)), np.argmin(distance, axis=1)]
    return compensate_commands(parameters, targets, taught, tool=tool, settings=settings, progress=progress)


def filter_program(
    program,
    parameters,
    robot=None,
    *,
    controller=None,
    frames=None,
    language: str | None = None,
    dat=None,
    config_dat=None,
    encoding: str = "utf-8",
    start_deg=None,
    settings: CompensationSettings | None = None,
    draws=None,
) -> FilteredProgram:
    """A robot program with every target compensated by the calibrated model, numbers changed only (issue 28).

    Parameters
    ----------
    program : path or Program
        A KUKA KRL ``.src`` (its ``.dat`` beside it), ABB RAPID ``.mod`` or URScript ``.script``, or a program read by
        :func:`robotcal.programs.read_program`.
    parameters : ParameterSet, a result holding one, or a parameter JSON path
        The calibrated model; a path needs ``robot``.
    robot : RobotModel or Scenario, optional
        For a parameter JSON path.
    controller : RobotModel or robot name, optional
        The robot file whose readings are the program's axis values and whose ``flange_frame`` is the controller's
        flange (e.g. ``"kuka-kr5-sixx-r650-krc"``; default: the calibrated model's robot).
    frames : dict of str to (4, 4) [mm], optional
        Tools and bases the program uses but does not declare, or that replace its declarations.
    language, dat, config_dat, encoding
        How to read a program path (:func:`robotcal.programs.read_program`).
    start_deg : array_like (n_joints,), optional
        Controller readings before the first point [deg] (default: mid-limits).
    settings : CompensationSettings, optional
    draws : MonteCarloResult, draws.npz path or array, optional
        The deployed model's Monte Carlo draws (``uncertainty-refined/draws.npz`` of a run): each written point's
        tool position uncertainty at its command (``tcp_u_mm``, thesis ch. 5.3).

    Returns
    -------
    FilteredProgram
        ``texts`` (the new files), ``points`` (every point's status, correction, remaining error and, with
        ``draws``, its tool position uncertainty) and ``counts``.
    """
    from robotcal.programs import read_program
    from robotcal.programs.base import Program
    from robotcal.programs.filter import filter_program as filter_core

    parameters = _calibrated(parameters, robot)
    if isinstance(controller, str | os.PathLike):
        controller = load_robot(controller)
    if not isinstance(program, Program):
        program = read_program(program, language=language, dat=dat, config_dat=config_dat, encoding=encoding)
    result = filter_core(program, parameters, controller=controller, frames=frames, settings=settings, start_deg=start_deg)
    if draws is None:
        return result
    return _with_tcp_uncertainty(result, parameters.robot, controller or parameters.robot, draws, frames)


def _with_tcp_uncertainty(result: FilteredProgram, robot: RobotModel, controller: RobotModel, draws, frames):
    """``result`` with every written point's tool position uncertainty at its command, from ``draws``; points are
    grouped by their tool point in the model's flange frame (the propagation takes one tool point per call)."""
    from robotcal.uncertainty.tcp import propagate_to_tcp

    values, joint_model, extras = _parameter_draws(draws, robot)
    flange = np.eye(4) if controller.flange_frame is None else controller.flange_frame
    known = {**result.program.frames, **(frames or {})}
    groups: dict[tuple, list[int]] = {}
    for index, record in enumerate(result.points):
        if record.written:
            tool = flange @ (np.eye(4) if record.point.tool not in known else known[record.point.tool])
            groups.setdefault(tuple(np.round(tool[:3, 3], 9)), []).append(index)
    points = list(result.points)
    for tool_mm, members in groups.items():
        commands = np.deg2rad([points[k].command_deg for k in members])
        readings = robot.readings_from_model(controller.model_joint_variables(commands))
        tcp = propagate_to_tcp(
            robot, values, readings, tool=np.array(tool_mm), joint_model=joint_model, extra_draws=extras
        )
        for k, u in zip(members, tcp.position_uncertainty, strict=True):
            points[k] = dataclasses.replace(points[k], tcp_u_mm=float(u))
    return dataclasses.replace(result, points=points)


def evaluate(
    captures,
    parameter_sets: Mapping,
    robot,
    *,
    targets=None,
    views: Sequence[str] = ("points", "distances"),
    bases: Mapping | None = None,
    set_targets: Mapping | None = None,
) -> tuple[EvaluationRow, ...]:
    """Mean, max and RMS errors of named parameter sets on captures (thesis Tables 4.10/4.11).

    Parameters
    ----------
    captures : Capture, path, or mapping of str to Capture or path
        E.g. ``{"validation": ...}``; a single capture is named ``"capture"``.
    parameter_sets : mapping of str to ParameterSet, CPAResult, RefinementResult, path or None
        E.g. ``{"nominal": None, "cpa": cpa, "refined": refined}`` (None: nominal); the first is the
        reference of ``improvement_pct``.
    robot : RobotModel or Scenario
        A scenario supplies each capture's target(s) (:func:`capture_targets`).
    targets : ReflectorMount, Target, sequence of Target, or mapping of capture name to those
        Where each capture's points were measured.
    views : sequence of {"points", "distances", "absolute"}
        Points after a best-fit registration of the prediction on the measurement, all pairwise distances,
        or points in a given base frame (``bases``: set name -> 4x4).
    set_targets : mapping, optional
        Per set, the flange offsets it estimated (name -> xyz [mm]).

    Returns
    -------
    tuple of EvaluationRow
        ``parameter_set, view, capture, n_errors, mean_error_mm, max_error_mm, rms_error_mm,
        improvement_pct``, ordered by capture, view, parameter set.

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


@dataclass(frozen=True, slots=True, kw_only=True)
class JointAnalysis:
    """Joint diagnostics of a capture (thesis ch. 4.6) and the harmonic model fitted to them."""

    diagnostics: JointDiagnostics
    harmonics: HarmonicModel

    def __repr__(self) -> str:
        return f"JointAnalysis({len(self.diagnostics.circles)} circles, backlash={self.diagnostics.backlash})"


def diagnose_joints(
    capture,
    robot=None,
    *,
    backlash: bool = True,
    circle_fit: Literal["geometric", "algebraic"] | None = None,
    order: int = 2,
    match_tolerance_deg: float = 1e-3,
) -> JointAnalysis:
    """Backlash and axial/radial eccentricity per joint from a (bidirectional) Circle Point capture (thesis
    ch. 4.6), and their harmonic model.

    Parameters
    ----------
    capture : Capture or path
        A path needs ``robot`` (its joint count).
    robot : RobotModel or Scenario, optional
        A scenario supplies the circle fit (``[identification] circle_fit``).
    backlash : bool
        Match forward and return points (a bidirectional capture).
    circle_fit : {"geometric", "algebraic"}, optional
    order : int
        Order of the harmonic series.
    match_tolerance_deg : float
        Readings closer than this are the same reading [deg].
    """
    scenario = None
    if robot is not None:
        robot, scenario = _split(robot)
        capture = _capture(capture, robot)
    elif not isinstance(capture, Capture):
        raise InputError("`capture` must be a Capture (or give `robot` to read a capture CSV)")
    if circle_fit is None:
        circle_fit = "geometric" if scenario is None else scenario.identification.circle_fit
    diagnostics = analyze_joints(
        capture, backlash=backlash, match_tolerance=float(np.deg2rad(match_tolerance_deg)), method=circle_fit
    )
    return JointAnalysis(diagnostics=diagnostics, harmonics=fit_harmonics(diagnostics, order=order))


# ------------------------------------------------------------------------------------------ uncertainty


def monte_carlo_problem(
    robot,
    *,
    plan: CapturePlan | None = None,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    parameters=None,
    options: CPAOptions | None = None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: str | None = None,
    model: Literal["cpa", "refined"] = "cpa",
    criterion: Criterion = "points",
    poses=None,
    joint_model: JointModel | None = None,
):
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
            names = set(poses.point_targets or (_target_name(scenario, poses),))
            if len(names) != 1:
                raise InputError(f"{poses.source}: calibration poses on one flange target; got {', '.join(sorted(names))}")
            pose_target = scenario.target(names.pop())
    if scenario is not None:
        plan = scenario.plan if plan is None else plan
        instrument = scenario.instrument if instrument is None else instrument
        tracker_from_base = scenario.tracker_from_base if tracker_from_base is None else tracker_from_base
        options = scenario.identification if options is None else options
        joint_errors = scenario.joint_errors if joint_errors is None else joint_errors
        joint_limits = scenario.joint_limits if joint_limits is None else joint_limits
    if plan is None or instrument is None:
        raise InputError("`plan` and `instrument` are needed (or give a Scenario in place of the robot)")
    return prepare_monte_carlo(
        robot,
        plan,
        instrument,
        np.eye(4) if tracker_from_base is None else tracker_from_base,
        options=options,
        true_parameters=truth,
        joint_errors=joint_errors,
        joint_limits=joint_limits or "warn",
        model=model,
        criterion=criterion,
        poses=pose_readings,
        poses_target=pose_target,
        joint_model=None if joint_model is None else joint_model.with_values(np.zeros(joint_model.size)),
    )


def monte_carlo(
    robot,
    *,
    plan: CapturePlan | None = None,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    parameters=None,
    options: CPAOptions | None = None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: str | None = None,
    draws: int | None = None,
    model: Literal["cpa", "refined"] = "cpa",
    criterion: Criterion = "points",
    rng=None,
    workers: int = 1,
    scheduler: str | None = None,
    coverage: float | None = None,
    interval: Literal["symmetric", "shortest"] = "symmetric",
    adaptive: bool = False,
    keep_draws: bool = True,
    linearised: bool | None = None,
    batch_size: int | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    poses=None,
    joint_model: JointModel | None = None,
) -> MonteCarloResult:
    """GUM Supplement 1 Monte Carlo of a calibration by Circle Point Analysis (thesis ch. 5.2.3).

    Every draw adds the instrument noise (and the random part of the joint errors) to the capture the plan
    gives on the robot ``parameters``, identifies it by CPA and, with ``model="refined"``, refines it (the
    deployed model); the spread of the draws is the uncertainty of the parameters.

    Parameters
    ----------
    robot : RobotModel or Scenario
        A scenario supplies the plan, instrument, base frame, CPA options, joint errors, limits policy and its
        ``[montecarlo]`` table (draws, seed, coverage).
    plan, instrument, tracker_from_base, options, joint_errors, joint_limits
        As for :func:`simulate` and :func:`identify`.
    parameters : ParameterSet, CPAResult, RefinementResult, path or None
        The robot the capture is simulated from: the estimate, when stating the uncertainty of a
        calibration; default nominal.
    draws : int, optional
        Number of draws M (default the scenario's ``montecarlo.iterations``, else 10^4; JCGM 101
        recommends 10^4 or more).
    model : {"cpa", "refined"}
        The parameters of CPA, or of CPA followed by the refinement with ``criterion``.
    rng : None, int or numpy.random.Generator
        The draws are seeded per block from one int seed, so the result does not depend on ``workers``;
        ``result.seed`` records it.
    workers : int
        Processes computing blocks of draws in parallel; ``scheduler`` a Dask scheduler address instead.
    coverage : float, optional
        Coverage probability of the intervals (default the scenario's, else 0.95).
    interval : {"symmetric", "shortest"}
    adaptive : bool
        JCGM 101 §7.9 adaptive procedure instead of a fixed ``draws``.
    keep_draws : bool
        Keep every draw (``result.draws``, needed by :func:`tcp_uncertainty`).
    linearised : bool, optional
        Also compute the GUM law-of-propagation comparison (JCGM 101 §8); default True for
        ``model="cpa"``, False for ``"refined"`` (where it costs as much as many draws).
    batch_size : int, optional
        Draws per vectorised call (bounds memory).
    progress : callable, optional
        ``progress(draws_done, draws_total)`` after every block.
    poses : Capture or path, optional
        ``model="refined"``: the calibration poses refined with the circles (their readings and target; the
        points are simulated); default the scenario's ``[calibration_poses]`` (the poses of its seed), if any.
    joint_model : JointModel, optional
        ``model="refined"``: the extended model every draw fits (from zero); default the joint model of
        ``parameters`` when it has one (the deployed extended model), else the geometric model.

    Returns
    -------
    MonteCarloResult
        ``summary`` (mean, ``std_uncertainty``, intervals, min, max per parameter, shape
        (n_joints, 5) [mm, rad]), covariance, ``draws`` (n_draws, n_joints, 5), ``seed``; for an extended model
        also ``joint_model``, ``extra_draws`` and ``extra_summary``.

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
    from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo

    _, scenario = _split(robot)
    table = None if scenario is None else scenario.montecarlo
    settings = MonteCarloSettings(
        iterations=int(draws if draws is not None else (table.iterations if table else 10_000)),
        coverage=float(coverage if coverage is not None else (table.coverage if table else 0.95)),
        interval=interval,
        adaptive=adaptive,
        workers=workers,
        scheduler=scheduler,
        keep_draws=keep_draws,
        **({} if batch_size is None else {"batch_size": batch_size}),
    )
    problem = monte_carlo_problem(
        robot,
        plan=plan,
        instrument=instrument,
        tracker_from_base=tracker_from_base,
        parameters=parameters,
        options=options,
        joint_errors=joint_errors,
        joint_limits=joint_limits,
        model=model,
        criterion=criterion,
        poses=poses,
        joint_model=joint_model,
    )
    seed = seed_from(rng, table.seed if table else None)
    if linearised is None:
        linearised = model == "cpa"
    return run_monte_carlo(problem, settings, seed=seed, linearised=linearised, progress=progress)


def measured_monte_carlo(
    capture,
    robot,
    estimate,
    *,
    targets=None,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    draws: int = 300,
    criterion: Criterion | None = None,
    offsets: Mapping | None = None,
    estimate_base: bool = False,
    weights: Literal["auto", "none"] = "auto",
    rng=None,
    workers: int = 1,
    scheduler: str | None = None,
    coverage: float = 0.95,
    interval: Literal["symmetric", "shortest"] = "symmetric",
    progress: Callable[[int, int | None], None] | None = None,
):
    """Monte Carlo (JCGM 101) of the refinement of a measured capture: each draw adds each point's noise (its
    U(95), else the instrument's U(L)) to the points the estimate predicts and refines them again
    (:mod:`robotcal.uncertainty.measured`).

    Parameters
    ----------
    capture : Capture or path
    robot : RobotModel or Scenario
        A scenario supplies the targets, the instrument and the held base frame (``base_frame = "given"``).
    estimate : RefinementResult, ParameterSet or path
        The refined parameters (a RefinementResult also gives its criterion and estimated target offsets).
    targets, instrument, tracker_from_base
        As for :func:`refine`.
    draws : int
        A few hundred: each draw is one refinement.
    criterion, offsets, estimate_base, weights
        See :func:`robotcal.uncertainty.measured.prepare_measured`.
    rng, workers, scheduler, coverage, interval, progress
        As for :func:`monte_carlo`.

    Returns
    -------
    MeasuredMonteCarloResult
    """
    from robotcal.uncertainty.measured import measured_monte_carlo as run_measured
    from robotcal.uncertainty.montecarlo import MonteCarloSettings

    robot, scenario = _split(robot)
    capture = _capture(capture, robot)
    if scenario is not None:
        targets = capture_targets(scenario, capture) if targets is None else targets
        if tracker_from_base is None and scenario.identification.base_frame == "given":
            tracker_from_base = scenario.tracker_from_base
    if targets is None:
        raise InputError("`targets` is needed: where the points were measured (a ReflectorMount or Targets)")
    if not isinstance(estimate, RefinementResult):
        estimate = _parameters(estimate, robot, "estimate")
    given = estimate.parameters.robot if isinstance(estimate, RefinementResult) else estimate.robot
    if given.name != robot.name:
        raise InputError(
            f"the estimate is for robot {given.name!r}; the capture is of robot {robot.name!r} (give the parameter "
            "JSON that `robotcal refine` wrote for this capture)"
        )
    settings = MonteCarloSettings(
        iterations=int(draws), coverage=coverage, interval=interval, workers=workers, scheduler=scheduler
    )
    return run_measured(
        capture,
        estimate,
        targets,
        settings,
        seed=seed_from(rng),
        instrument=_instrument(instrument, scenario),
        tracker_from_base=tracker_from_base,
        criterion=criterion,
        offsets=offsets,
        estimate_base=estimate_base,
        weights=weights,
        progress=progress,
    )


def _parameter_draws(draws, robot: RobotModel, limit: int | None = None):
    """Parameter draws (n_draws, n_joints, 5) [mm, rad] from a result, a draws file or an array, with an extended
    model's joint model and its values in every draw ``(n_draws, m)`` (None, None for the geometric model);
    ``limit``: the first draws only.

    Draws that name their robot (a Monte Carlo result, a draws file) must be of ``robot``'s model (same
    joint types and nominal parameters; its reading map may differ, e.g. controller readings).
    """
    source = getattr(draws, "robot", None)
    joint_model = extras = None
    if isinstance(draws, str | os.PathLike):
        from robotcal.io.draws_npz import read_draws

        read = read_draws(draws)
        values, source, joint_model, extras = read.values, read.robot, read.joint_model, read.extras
    elif hasattr(draws, "draws") and hasattr(draws, "summary"):  # a MonteCarloResult
        if draws.draws is None:
            raise InputError("`draws`: this Monte Carlo result kept no draws; run monte_carlo(..., keep_draws=True)")
        values = draws.draws
        if draws.is_extended:
            joint_model, extras = draws.joint_model, draws.extra_draws
    else:
        values = getattr(draws, "values", draws)  # a ParameterDraws, or an array
    values = np.asarray(values, dtype=float)
    if values.ndim != 3 or values.shape[1:] != (robot.n_joints, 5):
        raise InputError(
            f"`draws` must be a MonteCarloResult, a draws.npz path or an array of shape (n_draws, "
            f"{robot.n_joints}, 5) [mm, rad]; got shape {values.shape}"
        )
    if isinstance(source, RobotModel) and not (
        np.array_equal(source.hayati, robot.hayati) and np.allclose(source.nominal, robot.nominal, rtol=0, atol=1e-9)
    ):
        raise InputError(
            f"`draws` are parameters of robot {source.name!r}, whose model differs from robot {robot.name!r}'s"
        )
    if extras is not None and extras.shape[0] != values.shape[0]:
        raise InputError(f"`draws`: {extras.shape[0]} joint-model draws for {values.shape[0]} parameter draws")
    if limit is not None:
        values = values[:limit]
        extras = None if extras is None else extras[:limit]
    return values, joint_model, extras


def tcp_uncertainty(
    robot, draws, poses_deg, *, tool_mm=None, coverage: float = 0.95, keep_draws: bool = False
) -> TCPUncertainty:
    """TCP position and orientation uncertainty at poses from Monte Carlo parameter draws (thesis ch. 5.3).

    Parameters
    ----------
    robot : RobotModel or Scenario
        The robot whose readings ``poses_deg`` are.
    draws : MonteCarloResult, path, or array_like of shape (n_draws, n_joints, 5)
        :func:`monte_carlo`'s result (run with ``keep_draws=True``), a ``draws.npz`` written by
        ``robotcal uncertainty --save-draws``, or draws in core units [mm, rad].
    poses_deg : array_like, shape (n_poses, n_joints) or (n_joints,)
        Controller joint readings [deg] (e.g. a trajectory).
    tool_mm : array_like, shape (3,), optional
        TCP in flange coordinates [mm]; default the flange origin.
    coverage : float
        Coverage probability of the intervals and of the ellipsoid.
    keep_draws : bool
        Keep the TCP coordinates of every draw (``result.draws``; for scatter plots of a few poses).

    Returns
    -------
    TCPUncertainty
        Per pose X, Y, Z [mm] and KUKA A, B, C [rad]: ``std_uncertainty`` (n_poses, 6),
        ``position_uncertainty`` (n_poses,) [mm], covariance, coverage ellipsoid, and the linearised
        (LPU) result beside.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> scenario = robotcal.load_scenario("thesis-laser-tracker")
    >>> result = robotcal.monte_carlo(scenario, draws=200, rng=1)
    >>> poses_deg = [[0, 10, 90, 0, 30, 0], [20, 30, 60, 10, 40, 0]]  # readings J1..J6 [deg]
    >>> tcp = robotcal.tcp_uncertainty(scenario, result, poses_deg, tool_mm=[0, 0, 100])
    >>> tcp.n_poses, tcp.std_uncertainty.shape
    (2, (2, 6))
    >>> # the Monte Carlo and the linearised propagation of the same draws agree to a few percent
    >>> bool(np.allclose(tcp.std_uncertainty[:, :3], tcp.lpu_std_uncertainty[:, :3], rtol=0.1))
    True
    """
    from robotcal.uncertainty.tcp import propagate_to_tcp

    robot, _ = _split(robot)
    values, joint_model, extras = _parameter_draws(draws, robot)
    poses = np.deg2rad(np.asarray(poses_deg, dtype=float))
    tool = None if tool_mm is None else np.asarray(tool_mm, dtype=float)
    return propagate_to_tcp(
        robot, values, poses, tool=tool, coverage=coverage, keep_draws=keep_draws, joint_model=joint_model,
        extra_draws=extras,
    )  # fmt: skip


def workspace_uncertainty(
    robot, draws, n_poses: int = 1000, *, tool_mm=None, coverage: float = 0.95, rng=0, draws_used: int | None = None
) -> WorkspaceUncertainty:
    """TCP position uncertainty over ``n_poses`` random poses within the joint limits (thesis ch. 5.3, Fig. 5.21):
    the map of where the calibration can be trusted. Arguments as for :func:`tcp_uncertainty`; ``draws_used``: the
    first draws only (the map's cost is draws x poses)."""
    from robotcal.uncertainty.workspace import workspace_uncertainty as workspace

    robot, _ = _split(robot)
    tool = None if tool_mm is None else np.asarray(tool_mm, dtype=float)
    values, joint_model, extras = _parameter_draws(draws, robot, draws_used)
    return workspace(
        robot, values, n_poses, rng=rng, tool=tool, coverage=coverage, joint_model=joint_model, extra_draws=extras
    )


def validation_consistency(
    validation,
    estimate,
    draws,
    robot,
    *,
    target: ReflectorMount | None = None,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    model: str = "refined",
) -> dict:
    """Does the stated uncertainty explain the error observed at the validation points?

    The check a metrologist asks for: at every validation pose the Monte Carlo draws of the model give the
    covariance of the predicted target position, so the RMS position uncertainty predicted by the
    calibration is ``sqrt(mean_p tr V_p)``; the instrument adds ``3 sigma_p^2`` per point (sigma from its
    U(L), uniform: U/sqrt(3), normal: U/k). If the model explains the data, the RMS of the observed errors
    ``|T p(estimate) - m|`` is close to ``sqrt(mean_p (tr V_p + 3 sigma_p^2))``; a larger observed RMS points
    to what the model does not hold (joint errors such as backlash, eccentricity, gravity sag, or a wrong
    instrument level).

    Parameters
    ----------
    validation : Capture
        Free poses (circle = 0) measured with the flange ``target`` [mm].
    estimate : ParameterSet or result
        The deployed parameters [mm, rad].
    draws : MonteCarloResult, path or array, shape (n_draws, n_joints, 5)
        Monte Carlo draws of the same model [mm, rad].
    robot : RobotModel or Scenario
        A scenario supplies the target, the instrument and the base frame (given, or registered).
    target : ReflectorMount
    instrument : Instrument
    tracker_from_base : array_like, shape (4, 4), optional
        The base frame; None: a Horn registration of the predictions on the measurements (which absorbs part
        of the error).
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

    robot, scenario = _split(robot)
    target = _needed(target, "target", scenario, validation_target)
    instrument = _needed(instrument, "instrument", scenario, lambda s: s.instrument)
    if tracker_from_base is None and scenario is not None and scenario.identification.base_frame == "given":
        tracker_from_base = scenario.tracker_from_base
    values, joint_model, extras = _parameter_draws(draws, robot)
    estimate = _parameters(estimate, robot, "estimate")
    q = estimate.model_joint_variables(validation.readings)
    measured = np.asarray(validation.points, dtype=float)
    predicted = target_positions(estimate.values, q, np.zeros(validation.n_points, dtype=int), target)
    if tracker_from_base is not None:
        tracker, base = np.asarray(tracker_from_base, dtype=float), "given"
    else:
        tracker, base = register_points(predicted, measured).transform, "registered"
    observed = np.linalg.norm(predicted @ tracker[:3, :3].T + tracker[:3, 3] - measured, axis=1)
    # the Monte Carlo covariance of the target position at every validation pose (positions only)
    traces = np.trace(
        position_covariance(
            robot, values, validation.readings, tool=target.positions[0], joint_model=joint_model, extra_draws=extras
        ),
        axis1=1,
        axis2=2,
    )
    noise = 3.0 * instrument.standard_uncertainty(measured) ** 2
    expected = float(np.sqrt(np.mean(traces + noise)))
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
        "method": (
            "predicted = sqrt(mean over poses of tr V_p), V_p the covariance of the validation target position "
            "over the Monte Carlo draws; instrument = sqrt(mean of 3 sigma_p^2) from U(L); expected = "
            "sqrt(predicted^2 + instrument^2); observed = RMS of |T p(estimate) - measured|"
        ),
    }


# ----------------------------------------------------------------------------------------------- planning


def change_plan(
    scenario: Scenario,
    *,
    start_deg=None,
    sweep_deg=None,
    points=None,
    reflector_mm=None,
    bidirectional: bool | None = None,
) -> Scenario:
    """The scenario with another capture plan: the keys given replace those of ``[capture]``.

    Parameters
    ----------
    scenario : Scenario
    start_deg : array_like, shape (n_joints,) or (n_joints, n_joints), optional
        Readings where the circles start [deg] (one start for all, or one full start per circle).
    sweep_deg : array_like, shape (n_joints,), optional
        Signed angle each joint turns in its circle [deg].
    points : array_like of int, shape (n_joints,), optional
        Points per circle and direction.
    reflector_mm : array_like, shape (n_joints, 3) or (3,), optional
        Target positions [mm] in the frames of the scenario's reflector mount (per joint, or flange).
    bidirectional : bool, optional

    Returns
    -------
    Scenario
        A new scenario (the one given is unchanged); the plan is checked as a scenario file's would be.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> scenario = robotcal.load_scenario("thesis-laser-tracker")
    >>> longer = robotcal.change_plan(scenario, reflector_mm=[[100, 0, 0], [200, 0, 0], [0, 50, 0],
    ...                                                       [120, 0, 0], [0, 80, 0], [0, 60, 0]])
    >>> float(longer.plan.reflector.positions[3, 0]), float(scenario.plan.reflector.positions[3, 0])
    (120.0, 20.0)
    """
    if not isinstance(scenario, Scenario):
        raise InputError(f"`scenario` must be a Scenario (robotcal.load_scenario); got {type(scenario).__name__}")
    plan = scenario.plan  # a scenario without a capture plan raises its InputError (naming the key) on first use
    if plan.n_joints != scenario.robot.n_joints:
        raise InputError(
            f"{scenario.source}: the plan has {plan.n_joints} circles for {scenario.robot.n_joints} joints"
        )
    changes = {}
    if start_deg is not None:
        changes["start"] = np.deg2rad(np.asarray(start_deg, dtype=float))
    if sweep_deg is not None:
        changes["sweep"] = np.deg2rad(np.asarray(sweep_deg, dtype=float))
    if points is not None:
        changes["points"] = np.asarray(points)
    if bidirectional is not None:
        changes["bidirectional"] = bool(bidirectional)
    if reflector_mm is not None:
        changes["reflector"] = dataclasses.replace(plan.reflector, positions=np.asarray(reflector_mm, dtype=float))
    try:
        new_plan = dataclasses.replace(plan, **changes)
    except InputError as exc:
        raise InputError(f"{scenario.source}: changed plan: {exc}") from None
    return dataclasses.replace(scenario, plan=new_plan)


def check_plan(
    robot,
    plan: CapturePlan | None = None,
    *,
    cell: CellModel | None = None,
    acceptance_deg: float | None = None,
    aim: str = "middle",
) -> PlanCheck:
    """Check every point of a capture plan in its cell (thesis ch. 4.5.2).

    Joint limits, the instrument's measuring range, the reflector's acceptance angle and the line of
    sight past the robot's links (capsules), as ``robotcal plan check`` does.

    Parameters
    ----------
    robot : RobotModel or Scenario
        A scenario supplies the plan and builds the cell: tracker pose, link capsules, instrument preset
        (range, acceptance).
    plan : CapturePlan, optional
    cell : CellModel, optional
        :class:`robotcal.planning.cell.CellModel`; needed without a scenario.
    acceptance_deg : float, optional
        Reflector acceptance half-angle [deg] (a scenario's cell: default the instrument preset's).
    aim : str
        How the reflector is aimed (:class:`robotcal.planning.cell.CellModel`).

    Returns
    -------
    PlanCheck
        ``feasible``, per point ``ok`` and ``reasons(i)``, per circle ``circles`` (usable range [deg]).

    Examples
    --------
    The demo's plan (Table 5.1 with J5 swept -115..115 deg, within its limits) in the cell of Table 5.4:
    no reading leaves a joint limit, but the circles of J5 and J6 lose points to the reflector's acceptance
    angle and to the line of sight past the links:

    >>> import robotcal
    >>> check = robotcal.check_plan(robotcal.load_scenario("kr5-demo"))
    >>> check.feasible
    False
    >>> int(check.failures[:, 0].sum())  # joint limit
    0
    >>> [(c.circle, c.feasible_points, c.points) for c in check.circles if c.feasible_points < c.points]
    [(5, 9, 25), (6, 5, 30)]
    >>> check.circles[4].first_reasons
    ('acceptance (66 deg)',)
    """
    from robotcal.planning.cell import check_plan as check_points
    from robotcal.planning.scenario import cell_from_scenario

    robot, scenario = _split(robot)
    if scenario is not None:
        plan = scenario.plan if plan is None else plan
        if cell is None:
            cell, _ = cell_from_scenario(scenario, acceptance_deg=acceptance_deg, aim=aim)
    if plan is None or cell is None:
        raise InputError("`plan` and `cell` are needed (or give a Scenario in place of the robot)")
    return check_points(robot, plan, cell)


def coverage_study(
    robot,
    truth,
    *,
    captures: int,
    draws: int,
    plan: CapturePlan | None = None,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    options: CPAOptions | None = None,
    joint_errors: JointErrorModel | None = None,
    tcp_readings_deg=None,
    **study,
):
    """Empirical coverage of the Monte Carlo and linearised intervals over repeated simulated captures of one
    true robot (:func:`robotcal.uncertainty.coverage.coverage_study`): does a stated 95 % interval contain
    the truth 95 % of the time?

    Parameters
    ----------
    robot : RobotModel or Scenario
        A scenario supplies the plan, instrument, base frame, CPA options, joint errors and the TCP pose
        (:func:`tcp_targets`).
    truth : ParameterSet
        The fixed true robot [mm, rad].
    captures, draws : int
        K captures, Monte Carlo draws per capture and model.
    tcp_readings_deg : array_like, shape (n_joints,), optional
        Readings [deg] of the pose where the TCP ellipsoid is checked.
    **study
        ``methods``, ``criterion``, ``coverage``, ``rng``, ``progress`` of the core study.
    """
    from robotcal.uncertainty.coverage import coverage_study as study_coverage

    robot, scenario = _split(robot)
    if scenario is not None:
        plan = scenario.plan if plan is None else plan
        instrument = scenario.instrument if instrument is None else instrument
        tracker_from_base = scenario.tracker_from_base if tracker_from_base is None else tracker_from_base
        options = scenario.identification if options is None else options
        joint_errors = scenario.joint_errors if joint_errors is None else joint_errors
        pose = tcp_targets(scenario).pose if tcp_readings_deg is None else None
    else:
        pose = None
    readings = np.deg2rad(np.asarray(tcp_readings_deg, dtype=float)) if tcp_readings_deg is not None else pose
    if plan is None or instrument is None:
        raise InputError("`plan` and `instrument` are needed (or give a Scenario in place of the robot)")
    return study_coverage(
        robot,
        plan,
        instrument,
        _parameters(truth, robot, "truth"),
        captures=captures,
        draws=draws,
        tracker_from_base=tracker_from_base,
        options=options,
        joint_errors=joint_errors,
        joint_limits="ignore" if scenario is None else scenario.joint_limits,
        tcp_readings=None if readings is None else np.atleast_2d(readings)[0],
        **study,
    )


# --------------------------------------------------------------------------------------- a scenario's TCP

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
