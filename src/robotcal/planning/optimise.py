"""Capture-plan optimisation (thesis 6.2, future work): wider sweeps and longer lever arms within the cell.

Search space, per joint i: the start reading and the signed sweep (within the joint limits), the
number of points (the total is the budget, at least 3 per circle), and the reflector position on
link i's capsule surface (a point of the segment ``F_{i-1} -> F_i`` at fraction ``t``, offset by the
capsule radius plus a mount standoff at azimuth ``phi``, in the mounting frame of eq. 5-1).

Objective of a candidate, from the **linearised** covariance of the CPA parameters
(``U_y = J U_x J^T``, :func:`robotcal.uncertainty.montecarlo.linearised_uncertainty`):

- ``p95-tcp``: 95th percentile over a seeded workspace sample of the TCP position uncertainty
  ``sqrt(trace(J_tcp U_y J_tcp^T))`` [mm] (default);
- ``max-u``: largest standard uncertainty of an identified parameter, angles as mm at 1 m [mm];
- ``d-opt``: ``log det`` of the identified parameters' covariance (angles scaled by 1000 mm/rad);
- ``e-opt``: its largest eigenvalue.

Search: a seeded (1 + lambda) evolution. Each generation mutates the best plan (the start/sweep
or reflector of 1, 2, 3 or all joints, or moves points between circles); a mutant that fails the
cell check is repaired by clipping its sweeps into the joint limits and trimming each failing circle to its
longest feasible run; feasible mutants are
scored, in parallel through :mod:`robotcal.execution` when workers or a scheduler are given.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from robotcal.errors import InputError, RobotcalError
from robotcal.identification.cpa import CPAOptions
from robotcal.instruments import Instrument
from robotcal.kinematics.model import ReflectorMount, RobotModel
from robotcal.planning.cell import CellModel, check_plan
from robotcal.simulation.plan import CapturePlan

__all__ = ["OBJECTIVES", "PlanProblem", "OptimisationResult", "evaluate_plan", "optimise_plan", "workspace_readings"]

OBJECTIVES = ("p95-tcp", "max-u", "d-opt", "e-opt")
#: Distance from the capsule surface to the reflector centre (an SMR nest) [mm].
MOUNT_STANDOFF_MM = 20.0
_MIN_SWEEP = np.deg2rad(10.0)


@dataclass(frozen=True, slots=True, kw_only=True)
class PlanProblem:
    """What every candidate shares: robot, instrument, tracker, CPA options, cell, workspace sample."""

    robot: RobotModel
    instrument: Instrument
    tracker_from_base: np.ndarray
    options: CPAOptions
    cell: CellModel
    workspace_q: np.ndarray  # model joint variables (n_poses, n_joints) [rad]
    objective: str = "p95-tcp"

    @classmethod
    def from_scenario(cls, scenario, cell: CellModel, *, workspace_poses: int, seed: int, objective: str = "p95-tcp"):
        """The problem of a scenario's robot, instrument, tracker and CPA options in ``cell``, scored over
        ``workspace_poses`` seeded workspace poses; returns ``(problem, workspace readings [rad])``."""
        readings = workspace_readings(scenario.robot, workspace_poses, seed)
        problem = cls(
            robot=scenario.robot,
            instrument=scenario.instrument,
            tracker_from_base=scenario.tracker_from_base,
            options=scenario.identification,
            cell=cell,
            workspace_q=scenario.robot.model_joint_variables(readings),
            objective=objective,
        )
        return problem, readings


def workspace_readings(robot: RobotModel, n_poses: int, seed: int) -> np.ndarray:
    """Seeded workspace sample (readings uniform within the limits) [rad]."""
    from robotcal.uncertainty.workspace import sample_workspace

    return sample_workspace(robot, n_poses, rng=seed)


def _scaled_identified_covariance(covariance: np.ndarray, identified: np.ndarray) -> np.ndarray:
    scale = np.tile([1.0, 1000.0, 1.0, 1000.0, 1000.0], identified.shape[0])
    mask = identified.reshape(-1)
    sub = covariance[np.ix_(mask, mask)]
    return sub * np.outer(scale[mask], scale[mask])


def evaluate_plan(plan: CapturePlan, problem: PlanProblem) -> dict:
    """Linearised figures of ``plan`` (no cell check): every objective, and the parameter covariance.

    Returns ``{"p95-tcp", "max-u", "d-opt", "e-opt"}`` (inf when CPA cannot identify the capture) and
    ``"covariance"`` (n_params, n_params) [mm, rad].
    """
    from robotcal.uncertainty.montecarlo import linearised_uncertainty, prepare_monte_carlo
    from robotcal.uncertainty.tcp import tcp_jacobian

    bad = dict.fromkeys(OBJECTIVES, np.inf) | {"covariance": None}
    try:
        mc = prepare_monte_carlo(
            problem.robot, plan, problem.instrument, problem.tracker_from_base,
            options=problem.options, joint_limits="ignore",
        )  # fmt: skip
        covariance = linearised_uncertainty(mc).covariance
    except RobotcalError:
        return bad
    if not np.all(np.isfinite(covariance)):
        return bad
    jac = tcp_jacobian(problem.robot.nominal, problem.workspace_q)[:, :3, :]
    position = np.sqrt(np.clip(np.einsum("pik,kl,pil->p", jac, covariance, jac), 0.0, None))
    scaled = _scaled_identified_covariance(covariance, mc.identified)
    eigen = np.linalg.eigvalsh(scaled)
    return {
        "p95-tcp": float(np.percentile(position, 95.0)),
        "max-u": float(np.sqrt(np.max(np.diag(scaled)))),
        "d-opt": float(np.sum(np.log(np.clip(eigen, 1e-300, None)))),
        "e-opt": float(eigen[-1]),
        "covariance": covariance,
    }


def _score(task) -> dict:
    plan, problem = task
    result = evaluate_plan(plan, problem)
    result.pop("covariance")
    return result


@dataclass(frozen=True, slots=True, kw_only=True)
class OptimisationResult:
    """The best plan found, its figures, the baseline's, and the search record."""

    plan: CapturePlan
    baseline: CapturePlan
    objective: str
    best: dict
    baseline_figures: dict
    baseline_feasible: bool
    evaluations: int
    feasible_evaluations: int
    history: np.ndarray  # best objective after each generation
    seed: int
    executor: str


def _mount_segment(robot: RobotModel, joint: int) -> np.ndarray:
    """Link ``joint``'s origin in its mounting frame (eq. 5-1: frame {i-1} turned by q_i) [mm]."""
    d, theta, a = robot.nominal[joint, :3]
    return np.array([a * np.cos(theta), a * np.sin(theta), d])


def reflector_on_link(robot: RobotModel, radius: np.ndarray, joint: int, t: float, phi: float) -> np.ndarray:
    """Reflector position on link ``joint``'s capsule surface (module docstring) [mm]."""
    end = _mount_segment(robot, joint)
    length = np.linalg.norm(end)
    axis = end / length if length > 1e-9 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    offset = (radius[joint] + MOUNT_STANDOFF_MM) * (np.cos(phi) * e1 + np.sin(phi) * e2)
    return t * end + offset


def _allocate(weights: np.ndarray, budget: int) -> np.ndarray:
    n = weights.size
    extra = budget - 3 * n
    share = weights / weights.sum() * extra
    points = 3 + np.floor(share).astype(int)
    remainder = budget - points.sum()
    order = np.argsort(-(share - np.floor(share)))
    points[order[:remainder]] += 1
    return points


def _repair(plan: CapturePlan, robot: RobotModel, cell: CellModel):
    """Clip sweeps into the joint limits, then trim failing circles to their longest feasible run
    (twice at most); returns (plan, check)."""
    lower, upper = robot.limits[:, 0], robot.limits[:, 1]
    first = np.clip(plan.start, lower, upper)
    last = np.clip(plan.start + plan.sweep, lower, upper)
    if np.all(np.abs(last - first) >= _MIN_SWEEP):
        plan = dataclasses.replace(plan, start=first, sweep=last - first)
    check = check_plan(robot, plan, cell)
    for _ in range(2):
        if check.feasible:
            break
        start, sweep = plan.start.copy(), plan.sweep.copy()
        for summary in check.circles:
            j = summary.circle - 1
            if summary.feasible_points == summary.points:
                continue
            if summary.usable_deg is None:
                return plan, check
            first, last = np.deg2rad(summary.usable_deg)
            if abs(last - first) < _MIN_SWEEP:
                return plan, check
            start[j], sweep[j] = first, last - first
        plan = dataclasses.replace(plan, start=start, sweep=sweep)
        check = check_plan(robot, plan, cell)
    return plan, check


def _mutate(plan: CapturePlan, robot: RobotModel, radius: np.ndarray, budget: int, rng) -> CapturePlan:
    n = robot.n_joints
    start, sweep = plan.start.copy(), plan.sweep.copy()
    positions = plan.reflector.positions.copy()
    points = plan.points.copy()
    lower, upper = robot.limits[:, 0], robot.limits[:, 1]
    move = rng.integers(4)
    joints = rng.choice(n, size=int(rng.choice([1, 2, 3, n], p=[0.4, 0.3, 0.2, 0.1])), replace=False)
    for j in joints:
        if move in (0, 1):  # new start/sweep
            a, b = np.sort(rng.uniform(lower[j], upper[j], size=2))
            if b - a < _MIN_SWEEP:
                continue
            if rng.random() < 0.5:  # favour wide sweeps
                a, b = (
                    lower[j] + rng.uniform(0, 0.2) * (upper[j] - lower[j]),
                    upper[j] - rng.uniform(0, 0.2) * (upper[j] - lower[j]),
                )
            if rng.random() < 0.5:
                start[j], sweep[j] = a, b - a
            else:
                start[j], sweep[j] = b, a - b
        elif move == 2:  # reflector on the link surface
            positions[j] = reflector_on_link(robot, radius, j, rng.uniform(0.0, 1.0), rng.uniform(-np.pi, np.pi))
        else:  # move points between circles
            weights = points.astype(float) - 2.5
            weights[j] *= rng.uniform(0.5, 2.0)
            points = _allocate(weights, budget)
    return dataclasses.replace(
        plan, start=start, sweep=sweep, points=points, reflector=ReflectorMount(frame="joint", positions=positions)
    )


def optimise_plan(
    baseline: CapturePlan,
    problem: PlanProblem,
    *,
    budget: int | None = None,
    generations: int = 30,
    population: int = 8,
    seed: int = 0,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> OptimisationResult:
    """Search for a feasible plan of ``budget`` points (per direction) minimising ``problem.objective``.

    The baseline (the scenario's plan, its points re-allocated to the budget) seeds the search; a
    baseline that fails the cell check is repaired first. Deterministic for a given ``seed`` and any
    backend. ``progress(generations_done, generations)``, if given, is called after every generation.
    """
    from robotcal.execution import open_executor

    if problem.objective not in OBJECTIVES:
        raise InputError(f"unknown objective {problem.objective!r}; choose one of {', '.join(OBJECTIVES)}")
    if baseline.reflector.frame != "joint" or baseline.start.ndim != 1:
        raise InputError(
            "plan optimise needs a per-joint reflector plan (`capture.reflector_mm`) with one start per joint"
        )
    robot = problem.robot
    n = robot.n_joints
    budget = int(baseline.points.sum()) if budget is None else int(budget)
    if budget < 3 * n:
        raise InputError(f"--budget {budget} is too small: at least 3 points for each of {n} circles ({3 * n})")
    rng = np.random.default_rng(seed)
    baseline_check = check_plan(robot, baseline, problem.cell)
    baseline_figures = _score((baseline, problem))
    start_plan = dataclasses.replace(baseline, points=_allocate(baseline.points.astype(float) - 2.5, budget))
    current, check = _repair(start_plan, robot, problem.cell)
    evaluations, feasible_count = 1, 0
    best_figures = _score((current, problem)) if check.feasible else dict.fromkeys(OBJECTIVES, np.inf)
    best_value = best_figures[problem.objective] if check.feasible else np.inf
    history = []
    with open_executor(workers=workers, scheduler=scheduler) as executor:
        kind = executor.kind
        for generation in range(generations):
            candidates = []
            for _ in range(population):
                mutant = _mutate(current, robot, problem.cell.capsule_radius, budget, rng)
                mutant, mutant_check = _repair(mutant, robot, problem.cell)
                if mutant_check.feasible:
                    candidates.append(mutant)
            scores = list(executor.map(_score, [(c, problem) for c in candidates]))
            evaluations += population
            feasible_count += len(candidates)
            for candidate, figures in zip(candidates, scores, strict=True):
                if figures[problem.objective] < best_value:
                    current, best_value, best_figures = candidate, figures[problem.objective], figures
            history.append(best_value)
            if progress is not None:
                progress(generation + 1, generations)
    if not np.isfinite(best_value):
        raise RobotcalError("plan optimise found no feasible plan: relax the cell (acceptance, radii) or the budget")
    return OptimisationResult(
        plan=current,
        baseline=baseline,
        objective=problem.objective,
        best=best_figures,
        baseline_figures=baseline_figures,
        baseline_feasible=baseline_check.feasible,
        evaluations=evaluations,
        feasible_evaluations=feasible_count,
        history=np.array(history),
        seed=seed,
        executor=kind,
    )
