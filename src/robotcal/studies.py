"""The front door's studies around a calibration: the joints (:func:`diagnose_joints`), its capture plan (:func:`check_plan`, :func:`change_plan`,
:func:`optimise_plan`, :func:`sensitivity`) and the uncertainty it states (at the TCP: :func:`tcp_uncertainty`, over
the workspace: :func:`workspace_uncertainty`, at the validation points: :func:`validation_consistency`, of a
measured capture: :func:`measured_monte_carlo`, and the coverage of its intervals: :func:`coverage_study`).

They are part of :mod:`robotcal.api` (which re-exports them; import them from there or from ``robotcal``) and
follow its conventions: a ``robot`` is a RobotModel or a Scenario, numbers in mm and degrees, value objects and
results in mm and radians.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from robotcal.capture import Capture
from robotcal.diagnostics import HarmonicModel, JointDiagnostics, analyze_joints, fit_harmonics
from robotcal.errors import InputError
from robotcal.identification.cpa import CPAOptions
from robotcal.identification.refine import RefinementResult
from robotcal.instruments import Instrument
from robotcal.io.schema.scenario import Scenario
from robotcal.kinematics.model import ReflectorMount, RobotModel
from robotcal.resolve import (
    ParameterSource,
    as_capture,
    as_parameters,
    needed,
    parameter_draws,
    refinement_targets,
    scenario_instrument,
    seed_from,
    simulation_inputs,
    split_robot,
    tcp_targets,
    validation_target,
)
from robotcal.simulation import CapturePlan, JointErrorModel

if TYPE_CHECKING:
    from robotcal.planning.cell import CellModel, PlanCheck
    from robotcal.planning.optimise import OptimisationResult
    from robotcal.planning.sensitivity import SensitivityStudy
    from robotcal.uncertainty.coverage import CoverageStudy
    from robotcal.uncertainty.measured import MeasuredMonteCarloResult
    from robotcal.uncertainty.tcp import TCPUncertainty
    from robotcal.uncertainty.workspace import WorkspaceUncertainty

__all__ = [
    "JointAnalysis",
    "change_plan",
    "check_plan",
    "coverage_study",
    "diagnose_joints",
    "measured_monte_carlo",
    "optimise_plan",
    "sensitivity",
    "tcp_uncertainty",
    "validation_consistency",
    "workspace_uncertainty",
]

Criterion = Literal["points", "distances"]
PathLike = str | os.PathLike


@dataclass(frozen=True, slots=True, kw_only=True)
class JointAnalysis:
    """Joint diagnostics of a capture (thesis ch. 4.6) and the harmonic model fitted to them."""

    diagnostics: JointDiagnostics
    harmonics: HarmonicModel

    def __repr__(self) -> str:
        return f"JointAnalysis({len(self.diagnostics.circles)} circles, backlash={self.diagnostics.backlash})"


def backlash_correction(backlash: ArrayLike | JointAnalysis | None, robot: RobotModel) -> tuple[np.ndarray | None, str]:
    """The lash correction [rad] and its source from ``backlash_deg`` (array [deg] or a JointAnalysis)."""
    if backlash is None:
        return None, ""
    if isinstance(backlash, JointAnalysis):
        return (
            backlash.diagnostics.lash_correction(),
            "the joints stage (angular backlash of the joints whose backlash exceeds the noise)",
        )
    values = np.asarray(backlash, dtype=float)
    if values.shape != (robot.n_joints,) or not np.all(np.isfinite(values)):
        raise InputError(f"`backlash_deg` must be {robot.n_joints} finite angles [deg]; got shape {values.shape}")
    return np.deg2rad(values), "given"


def diagnose_joints(
    capture: Capture | PathLike,
    robot: RobotModel | Scenario | None = None,
    *,
    backlash: bool = True,
    circle_fit: Literal["geometric", "algebraic"] | None = None,
    order: int = 2,
    match_tolerance_deg: float = 1e-3,
) -> JointAnalysis:
    """Backlash and axial/radial eccentricity per joint from a (bidirectional) Circle Point capture (thesis
    ch. 4.6), and their harmonic model of ``order``.

    ``robot`` is needed for a capture path; a scenario supplies the circle fit (``[identification] circle_fit``).
    ``backlash``: match forward and return points, readings closer than ``match_tolerance_deg`` [deg] being the same.
    """
    scenario = None
    if robot is not None:
        robot, scenario = split_robot(robot)
        capture = as_capture(capture, robot)
    elif not isinstance(capture, Capture):
        raise InputError("`capture` must be a Capture (or give `robot` to read a capture CSV)")
    if circle_fit is None:
        circle_fit = "geometric" if scenario is None else scenario.identification.circle_fit
    diagnostics = analyze_joints(
        capture, backlash=backlash, match_tolerance=float(np.deg2rad(match_tolerance_deg)), method=circle_fit
    )
    return JointAnalysis(diagnostics=diagnostics, harmonics=fit_harmonics(diagnostics, order=order))


def check_plan(
    robot: RobotModel | Scenario,
    plan: CapturePlan | None = None,
    *,
    cell: CellModel | None = None,
    acceptance_deg: float | None = None,
    aim: str = "middle",
) -> PlanCheck:
    """Check every point of a capture plan in its cell (thesis ch. 4.5.2), as ``robotcal plan check`` does: joint
    limits, the instrument's measuring range, the reflector's acceptance angle (``acceptance_deg``, default the
    instrument preset's) and the line of sight past the robot's links. A scenario supplies the plan and builds the
    ``cell`` (:func:`robotcal.planning.scenario.cell_from_scenario`, with ``aim``); without one, give both.

    Examples
    --------
    The demo's plan (Table 5.1 with J5 swept -115..115 deg) in the cell of Table 5.4: no reading leaves a joint
    limit, but the circles of J5 and J6 lose points to the acceptance angle and to the line of sight:

    >>> import robotcal
    >>> check = robotcal.check_plan(robotcal.load_scenario("kr5-demo"))
    >>> check.feasible, int(check.failures[:, 0].sum())  # joint limit
    (False, 0)
    >>> [(c.circle, c.feasible_points, c.points) for c in check.circles if c.feasible_points < c.points]
    [(5, 9, 25), (6, 5, 30)]
    >>> check.circles[4].first_reasons
    ('acceptance (66 deg)',)
    """
    from robotcal.planning.cell import check_plan as check_points
    from robotcal.planning.scenario import cell_from_scenario

    robot, scenario = split_robot(robot)
    if scenario is not None:
        plan = scenario.plan if plan is None else plan
        if cell is None:
            cell, _ = cell_from_scenario(scenario, acceptance_deg=acceptance_deg, aim=aim)
    if plan is None or cell is None:
        raise InputError("`plan` and `cell` are needed (or give a Scenario in place of the robot)")
    return check_points(robot, plan, cell)


def change_plan(
    scenario: Scenario,
    *,
    start_deg: ArrayLike | None = None,
    sweep_deg: ArrayLike | None = None,
    points: Any = None,
    reflector_mm: ArrayLike | None = None,
    bidirectional: bool | None = None,
) -> Scenario:
    """The scenario with another capture plan: the keys given replace those of ``[capture]`` (``start_deg``: one
    start for all circles or one per circle [deg]; ``sweep_deg``: the signed angle of each circle [deg];
    ``points`` per circle and direction; ``reflector_mm``: the targets in the frames of the scenario's reflector
    mount [mm]). Returns a new scenario, its plan checked as a scenario file's would be.

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
    changes: dict[str, Any] = {}
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


def optimise_plan(
    scenario: Scenario,
    cell: CellModel | None = None,
    *,
    objective: str = "p95-tcp",
    budget: int | None = None,
    generations: int = 60,
    population: int = 8,
    seed: int = 0,
    workspace_poses: int = 200,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> OptimisationResult:
    """A capture plan of ``budget`` points per direction (default the scenario's) with a lower ``objective``
    (``p95-tcp``, ``max-u``, ``d-opt``, ``e-opt``, linearised over ``workspace_poses`` seeded poses) that passes the
    ``cell`` check (default the scenario's cell), as ``robotcal plan optimise`` searches it (docs/planning.md): a
    seeded search of ``generations`` x ``population`` candidates, ``progress(done, generations)`` after each
    generation. Confirm the result by Monte Carlo with :func:`plan_tcp_p95`."""
    from robotcal.planning.optimise import PlanProblem
    from robotcal.planning.optimise import optimise_plan as search_plan
    from robotcal.planning.scenario import cell_from_scenario

    cell = cell_from_scenario(scenario)[0] if cell is None else cell
    problem, _ = PlanProblem.from_scenario(
        scenario, cell, workspace_poses=workspace_poses, seed=seed, objective=objective
    )
    return search_plan(
        scenario.plan, problem, budget=budget, generations=generations, population=population, seed=seed,
        workers=workers, scheduler=scheduler, progress=progress,
    )  # fmt: skip


def sensitivity(
    scenario: PathLike,
    vary: Sequence[str] | Mapping[str, Sequence[Any]],
    *,
    seed: int = 1,
    iterations: int | None = None,
    length_limit_mm: float = 0.1,
    angle_limit_deg: float = 0.01,
    workers: int = 1,
    scheduler: str | None = None,
) -> SensitivityStudy:
    """Mean, u and Cpk (eq. 5-5) of every parameter against varied capture conditions (thesis ch. 5.2.4, Figs
    5.14-5.16): one Monte Carlo of ``iterations`` draws (default the scenario's) per combination of ``vary``
    (``"KEY=V1,V2,..."`` strings as ``robotcal sensitivity --vary`` takes them, or a mapping of keys to values),
    every case with the same ``seed``; Cpk against +-``length_limit_mm`` [mm] and +-``angle_limit_deg`` [deg].
    ``scenario``: a built-in name or a scenario TOML path (each case edits its document)."""
    from robotcal.planning.scenario import scenario_document
    from robotcal.planning.sensitivity import parse_vary, run_sensitivity

    document, base_dir, name, source = scenario_document(scenario)
    cases = [(str(k), list(v)) for k, v in vary.items()] if isinstance(vary, Mapping) else parse_vary(list(vary))
    return run_sensitivity(
        document, base_dir, name, source, cases, seed=seed, iterations=iterations, length_limit_mm=length_limit_mm,
        angle_limit_deg=angle_limit_deg, workers=workers, scheduler=scheduler,
    )  # fmt: skip


def tcp_uncertainty(
    robot: RobotModel | Scenario,
    draws: Any,
    poses_deg: ArrayLike,
    *,
    tool_mm: ArrayLike | None = None,
    coverage: float = 0.95,
    keep_draws: bool = False,
) -> TCPUncertainty:
    """TCP position and orientation uncertainty at controller readings ``poses_deg`` (n_poses, n_joints) [deg] from
    Monte Carlo parameter draws (thesis ch. 5.3).

    ``draws``: :func:`monte_carlo`'s result (``keep_draws=True``), a ``draws.npz`` of ``robotcal uncertainty
    --save-draws``, or an array (n_draws, n_joints, 5) [mm, rad]; ``tool_mm``: the TCP in the flange frame [mm];
    ``keep_draws``: keep every draw's TCP. Per pose X, Y, Z [mm] and KUKA A, B, C [rad]: ``std_uncertainty``
    (n_poses, 6), ``position_uncertainty`` [mm], covariance, ``coverage`` ellipsoid and the linearised result.

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

    robot, _ = split_robot(robot)
    values, joint_model, extras = parameter_draws(draws, robot)
    poses = np.deg2rad(np.asarray(poses_deg, dtype=float))
    tool = None if tool_mm is None else np.asarray(tool_mm, dtype=float)
    return propagate_to_tcp(
        robot, values, poses, tool=tool, coverage=coverage, keep_draws=keep_draws, joint_model=joint_model,
        extra_draws=extras,
    )  # fmt: skip


def workspace_uncertainty(
    robot: RobotModel | Scenario,
    draws: Any,
    n_poses: int = 1000,
    *,
    tool_mm: ArrayLike | None = None,
    coverage: float = 0.95,
    rng: np.random.Generator | int | None = 0,
    draws_used: int | None = None,
) -> WorkspaceUncertainty:
    """TCP position uncertainty over ``n_poses`` random poses within the joint limits (thesis ch. 5.3, Fig. 5.21):
    the map of where the calibration can be trusted. Arguments as for :func:`tcp_uncertainty`; ``draws_used``: the
    first draws only (the map's cost is draws x poses)."""
    from robotcal.uncertainty.workspace import workspace_uncertainty as workspace

    robot, _ = split_robot(robot)
    tool = None if tool_mm is None else np.asarray(tool_mm, dtype=float)
    values, joint_model, extras = parameter_draws(draws, robot, draws_used)
    return workspace(
        robot, values, n_poses, rng=rng, tool=tool, coverage=coverage, joint_model=joint_model, extra_draws=extras
    )


def validation_consistency(
    validation: Capture,
    estimate: ParameterSource,
    draws: Any,
    robot: RobotModel | Scenario,
    *,
    target: ReflectorMount | None = None,
    instrument: Instrument | None = None,
    tracker_from_base: np.ndarray | None = None,
    model: str = "refined",
    joint_errors: JointErrorModel | None = None,
) -> dict[str, Any]:
    """Does the stated uncertainty explain the error observed at the validation points?
    (:func:`robotcal.uncertainty.consistency.check_validation_consistency`: predicted, instrument, expected and
    observed RMS errors [mm] and their ratio.)

    ``validation``: free poses measured on the flange ``target``; ``estimate``: the deployed parameters; ``draws``:
    Monte Carlo draws of the same model (as for :func:`tcp_uncertainty`); ``tracker_from_base``: the base frame
    (None: a Horn registration, which absorbs part of the error); ``model``: its name, recorded; ``joint_errors``:
    joint errors measured on the robot that ``estimate`` does not represent (their move of the target is expected).
    A scenario supplies the target, the instrument and the base frame when ``[identification] base_frame =
    "given"``.
    """
    from robotcal.uncertainty.consistency import check_validation_consistency

    robot, scenario = split_robot(robot)
    target = needed(target, "target", scenario, validation_target)
    instrument = needed(instrument, "instrument", scenario, lambda s: s.instrument)
    if tracker_from_base is None and scenario is not None and scenario.identification.base_frame == "given":
        tracker_from_base = scenario.tracker_from_base
    values, joint_model, extras = parameter_draws(draws, robot)
    return check_validation_consistency(
        validation, as_parameters(estimate, robot, "estimate"), robot, values, target, instrument,
        tracker_from_base=tracker_from_base, joint_model=joint_model, extra_draws=extras, model=model,
        repeatability_mm=None if scenario is None else scenario.repeatability_mm,
        correction_shifts=getattr(draws, "correction_shifts", None), joint_errors=joint_errors,
    )  # fmt: skip


def measured_monte_carlo(
    capture: Capture | PathLike,
    robot: RobotModel | Scenario,
    estimate: ParameterSource,
    *,
    targets: Any = None,
    instrument: Instrument | None = None,
    tracker_from_base: np.ndarray | None = None,
    draws: int = 300,
    criterion: Criterion | None = None,
    offsets: Mapping[str, Any] | None = None,
    estimate_base: bool = False,
    weights: Literal["auto", "none"] = "auto",
    rng: np.random.Generator | int | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    coverage: float = 0.95,
    interval: Literal["symmetric", "shortest"] = "symmetric",
    progress: Callable[[int, int | None], None] | None = None,
) -> MeasuredMonteCarloResult:
    """Monte Carlo (JCGM 101) of the refinement of a measured capture: each of ``draws`` (a few hundred: each is
    one refinement) adds each point's noise (its U(95), else the instrument's U(L)) to the points the ``estimate``
    (a RefinementResult also gives its criterion and estimated offsets) predicts and refines them again
    (:mod:`robotcal.uncertainty.measured`: ``criterion``, ``offsets``, ``estimate_base``, ``weights``).

    A scenario supplies the targets, the instrument and the held base frame (``base_frame = "given"``); ``targets``,
    ``instrument``, ``tracker_from_base`` as for :func:`refine`; the others as for :func:`monte_carlo`.
    """
    from robotcal.uncertainty.measured import measured_monte_carlo as run_measured
    from robotcal.uncertainty.montecarlo import MonteCarloSettings

    robot, scenario = split_robot(robot)
    capture = as_capture(capture, robot)
    targets, tracker_from_base = refinement_targets(scenario, capture, targets, tracker_from_base)
    if not isinstance(estimate, RefinementResult):
        estimate = as_parameters(estimate, robot, "estimate")
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
        capture, estimate, targets, settings, seed=seed_from(rng), instrument=scenario_instrument(instrument, scenario),
        tracker_from_base=tracker_from_base, criterion=criterion, offsets=offsets, estimate_base=estimate_base,
        weights=weights, progress=progress,
    )  # fmt: skip


def coverage_study(
    robot: RobotModel | Scenario,
    truth: ParameterSource,
    *,
    captures: int,
    draws: int,
    plan: CapturePlan | None = None,
    instrument: Instrument | None = None,
    tracker_from_base: np.ndarray | None = None,
    options: CPAOptions | None = None,
    joint_errors: JointErrorModel | None = None,
    tcp_readings_deg: ArrayLike | None = None,
    **study: Any,
) -> CoverageStudy:
    """Empirical coverage of the Monte Carlo and linearised intervals over ``captures`` simulated captures of one
    ``truth`` robot [mm, rad], ``draws`` draws per capture and model (:func:`robotcal.uncertainty.coverage.
    coverage_study`; ``**study``: its ``methods``, ``criterion``, ``coverage``, ``rng``, ``progress``): does a stated
    95 % interval contain the truth 95 % of the time? The TCP ellipsoid is checked at ``tcp_readings_deg``
    (n_joints,) [deg]; a scenario supplies the plan, instrument, base frame, options, joint errors and that pose
    (:func:`tcp_targets`)."""
    from robotcal.uncertainty.coverage import coverage_study as study_coverage

    robot, scenario = split_robot(robot)
    readings = None if tcp_readings_deg is None else np.deg2rad(np.asarray(tcp_readings_deg, dtype=float))
    if scenario is not None:
        plan, instrument, tracker_from_base, options, joint_errors = simulation_inputs(
            scenario, plan=plan, instrument=instrument, tracker_from_base=tracker_from_base, options=options,
            joint_errors=joint_errors,
        )  # fmt: skip
        readings = tcp_targets(scenario).pose if readings is None else readings
    if plan is None or instrument is None:
        raise InputError("`plan` and `instrument` are needed (or give a Scenario in place of the robot)")
    return study_coverage(
        robot, plan, instrument, as_parameters(truth, robot, "truth"), captures=captures, draws=draws,
        tracker_from_base=tracker_from_base, options=options, joint_errors=joint_errors,
        joint_limits="ignore" if scenario is None else scenario.joint_limits,
        tcp_readings=None if readings is None else np.atleast_2d(readings)[0], **study,
    )  # fmt: skip
