"""The Monte Carlo's problem: the noise-free capture simulated once, and what every draw identifies from it.

:func:`prepare_monte_carlo` simulates the noise-free capture of a plan (thesis ch. 5.2.3), prepares CPA's structure
and, for the refined (deployed) model, the refinement every draw repeats (:mod:`robotcal.uncertainty.refined`) with
the Gauss-Newton draws' stopping rule (:mod:`robotcal.uncertainty.gauss_newton`). The draws are made by
:mod:`robotcal.uncertainty.draws`, the statistics by :mod:`robotcal.uncertainty.montecarlo`.

References
----------
JCGM 101:2008 §5.9, §7; thesis ch. 5.2.3.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from robotcal.capture import Capture, join_captures
from robotcal.errors import InputError
from robotcal.geometry.transforms import check_rigid_transform
from robotcal.identification.cpa import CPAOptions, _Structure, identify_cpa_batch, prepare_cpa
from robotcal.identification.health import repeatability_sigma
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.kinematics.model import ParameterSet, RobotModel
from robotcal.simulation.generator import JointErrorModel, simulate_capture, simulate_target_poses
from robotcal.simulation.plan import CapturePlan

if TYPE_CHECKING:  # the refinement (and SciPy's optimizer behind it) is imported only for model="refined"
    from robotcal.kinematics.joint_model import JointModel
    from robotcal.uncertainty.refined_kernel import RefinedModel

__all__ = ["MonteCarloProblem", "prepare_monte_carlo"]

_NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)
#: What a draw computes: capture -> CPA, or capture -> CPA -> refinement.
MODELS = ("cpa", "refined")


@dataclass(frozen=True, slots=True, kw_only=True)
class MonteCarloProblem:
    """What every draw shares: the noise-free capture and how to identify it.

    Attributes
    ----------
    robot : RobotModel
    true_parameters : ParameterSet
        The robot that "produced" the capture (nominal unless a perturbed truth is given).
    capture : Capture
        The noise-free capture (readings of every point; points in the tracker frame [mm]).
    exact_points : ndarray, shape (n_points, 3)
        Noise-free target positions in the tracker frame [mm] (with the deterministic part of the
        joint error model).
    error_bound : ndarray, shape (n_points,)
        Instrument bound ``U(L) = A + B L`` at every point [mm].
    instrument : Instrument
    tracker_from_base : ndarray, shape (4, 4)
    joint_errors : JointErrorModel or None
        Kept only when it has a random part, which is then redrawn in every draw.
    options : CPAOptions
    structure
        The CPA structure shared by all draws (``prepare_cpa``).
    noise_free_values : ndarray, shape (n_joints, 5)
        The model value ``f(x)`` at the input estimates [mm, rad]: CPA of the noise-free capture
        (``model="cpa"``) or its refinement (``model="refined"``); used by the linearised comparison.
    identified : ndarray of bool, shape (n_joints, 5)
        Parameters the model determines from the data (the others keep their nominal value).
    model : {"cpa", "refined"}
        What every draw computes: capture -> CPA, or capture -> CPA -> refinement (the deployed model).
    refined : RefinedModel or None
        The refinement's structure (free set, base handling, scale), ``model="refined"`` only.
    n_circle : int
        The capture's first ``n_circle`` points are the plan's circles, which CPA identifies; the others are
        calibration poses on a flange target (``[calibration_poses]``), which only the refinement uses.
    extra_true : ndarray, shape (m,)
        The joint-model values of the robot the capture was simulated from, on the refined model's joint model
        (0 for a term it does not have; empty for the geometric model).
    repeatability_sd : float
        The robot's pose scatter per coordinate [mm] (the noise budget: the stated ISO 9283 repeatability RP /
        3.616, :func:`robotcal.identification.health.repeatability_sigma`), added to every point of every draw as
        isotropic normal noise after the instrument's; 0 when not stated.
    source_points : ndarray, shape (k, n_points, 3)
        Where the joint errors were measured (:class:`robotcal.uncertainty.joint_errors.MeasuredJointErrors`): the
        noise-free capture again with each source of their uncertainty, one measured input one standard uncertainty
        larger [mm]; solved as draws, they give how the bias moves with each
        (:attr:`robotcal.uncertainty.montecarlo.MonteCarloResult.correction_shifts`). Empty otherwise.
    """

    robot: RobotModel
    true_parameters: ParameterSet
    capture: Capture
    exact_points: np.ndarray
    error_bound: np.ndarray
    instrument: Instrument
    tracker_from_base: np.ndarray
    joint_errors: JointErrorModel | None
    options: CPAOptions
    structure: _Structure  # prepare_cpa's
    noise_free_values: np.ndarray
    identified: np.ndarray
    model: str = "cpa"
    refined: RefinedModel | None = None
    n_circle: int = -1
    extra_true: np.ndarray = field(default_factory=lambda: np.zeros(0))
    repeatability_sd: float = 0.0
    source_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3)))

    def __post_init__(self):
        if self.n_circle < 0:
            object.__setattr__(self, "n_circle", self.exact_points.shape[0])

    @property
    def n_points(self) -> int:
        return self.exact_points.shape[0]

    @property
    def n_extra(self) -> int:
        """Joint-model values every draw estimates besides the parameters (0 for the geometric model)."""
        return 0 if self.refined is None or self.refined.joint_model is None else self.refined.joint_model.size

    @property
    def identified_all(self) -> np.ndarray:
        """The flat mask of a draw's outputs ``(5 n + m,)``: the identified parameters, then the joint-model
        values the refinement estimates."""
        refined = self.refined
        extra = np.zeros(0, dtype=bool) if refined is None or self.n_extra == 0 else np.asarray(refined.extra_free, dtype=bool)
        return np.r_[self.identified.ravel(), extra]


def prepare_monte_carlo(
    robot: RobotModel,
    plan: CapturePlan,
    instrument: Instrument,
    tracker_from_base,
    *,
    options: CPAOptions | None = None,
    true_parameters: ParameterSet | None = None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: str = "warn",
    model: str = "cpa",
    criterion: str = "points",
    poses=None,
    poses_target: Target | None = None,
    joint_model: JointModel | None = None,
    repeatability_mm: float | None = None,
) -> MonteCarloProblem:
    """Simulate the noise-free capture once and check that CPA can identify it.

    Every problem that would make draws fail (a circle of 2 points, a joint that does not turn, a
    reading sign that contradicts the data) raises here, before any draw is made.

    Parameters
    ----------
    robot, plan, instrument, tracker_from_base, true_parameters, joint_errors, joint_limits
        As for :func:`robotcal.simulation.generator.simulate_capture`. Measured ``joint_errors``
        (:class:`robotcal.uncertainty.joint_errors.MeasuredJointErrors`) carry the sources of their uncertainty:
        the noise-free capture is simulated with each too (:attr:`MonteCarloProblem.source_points`).
    options : CPAOptions, optional
        CPA options (circle fit, base frame, theta1 reference).
    model : {"cpa", "refined"}
        ``"refined"``: every draw is refined after CPA (thesis ch. 4.5.7), starting from its own CPA
        estimate; the free set and the base handling are those ``refine_parameters`` chooses on the
        noise-free capture (points criterion: the base frame is held when ``options.base_frame`` is
        ``"given"``, else its 6 corrections are estimated).
    criterion : {"points", "distances"}
        Refinement objective (eq. 4-101 or 4-102), ``model="refined"`` only.
    poses : array_like, shape (n_poses, n_joints), optional
        ``model="refined"``: readings [rad] of calibration poses measured on ``poses_target`` (a flange target of
        known offset) after the circles, refined with them (issue 22); CPA sees only the circles.
    poses_target : Target, optional
    joint_model : JointModel, optional
        ``model="refined"``: the extended model's joint model, fitted from zero in every draw (issue 22).
    repeatability_mm : float, optional
        The robot's ISO 9283 pose repeatability RP [mm]: every draw adds its scatter to every point
        (:attr:`MonteCarloProblem.repeatability_sd`).
    """
    if model not in MODELS:
        raise InputError(f"`model` must be one of {MODELS}; got {model!r}")
    options = CPAOptions() if options is None else options
    tracker_from_base = check_rigid_transform(tracker_from_base, "tracker_from_base")
    repeatability_sd = repeatability_sigma(repeatability_mm)
    true_parameters = ParameterSet.nominal(robot) if true_parameters is None else true_parameters
    noisy_joints = joint_errors is not None and bool(np.any(joint_errors.noise_sd > 0))
    capture, exact = _noise_free_capture(robot, plan, tracker_from_base, true_parameters, joint_errors, joint_limits)
    structure = prepare_cpa(capture, robot, plan.reflector, options)
    reference = identify_cpa_batch(exact, structure, tracker_from_base)
    values, identified, refined = reference.values, reference.identified, None
    n_circle, extra_true = capture.n_points, np.zeros(0)
    if model != "refined" and (poses is not None or joint_model is not None):
        raise InputError("calibration poses and a joint model are the refined model's: give model='refined'")
    if model == "refined":
        capture, exact, refined, extra_true = _refined_structure(
            robot, capture, exact, reference, plan, instrument, tracker_from_base, true_parameters, options,
            criterion=criterion, poses=poses, poses_target=poses_target, joint_model=joint_model,
            repeatability_sd=repeatability_sd, joint_errors=_deterministic(joint_errors),
        )  # fmt: skip
        values, identified = refined.reference_values, reference.identified | refined.free
    problem = MonteCarloProblem(
        robot=robot,
        true_parameters=true_parameters,
        capture=capture,
        exact_points=exact,
        error_bound=instrument.error_bound(exact),
        instrument=instrument,
        tracker_from_base=tracker_from_base,
        joint_errors=joint_errors if noisy_joints else None,
        options=options,
        structure=structure,
        noise_free_values=values,
        identified=identified,
        model=model,
        refined=refined,
        n_circle=n_circle,
        extra_true=extra_true,
        repeatability_sd=repeatability_sd,
    )
    sources = getattr(joint_errors, "sources", ())  # measured joint errors: their uncertainty's sources
    if not sources:
        return problem
    points = [
        np.concatenate([_noise_free_capture(robot, plan, tracker_from_base, true_parameters, errors, joint_limits)[1],
                        _noise_free_poses(robot, poses, poses_target, tracker_from_base, true_parameters, errors)])
        for errors in sources
    ]  # fmt: skip
    return dataclasses.replace(problem, source_points=np.stack(points))


def _deterministic(joint_errors: JointErrorModel | None) -> JointErrorModel | None:
    """The deterministic part of ``joint_errors`` (its noise left to the draws)."""
    if joint_errors is not None and bool(np.any(joint_errors.noise_sd > 0)):
        return dataclasses.replace(joint_errors, noise_sd=np.zeros_like(joint_errors.noise_sd))
    return joint_errors


def _noise_free_poses(robot, poses, poses_target, tracker_from_base, true_parameters, joint_errors) -> np.ndarray:
    """The calibration poses' exact points ``(n_poses, 3)`` with the deterministic joint errors (none without poses)."""
    if poses is None:
        return np.zeros((0, 3))
    return simulate_target_poses(
        robot, poses, (poses_target,), _NOISE_FREE, tracker_from_base, true_parameters=true_parameters,
        joint_errors=_deterministic(joint_errors), rng=0,
    )[1]  # fmt: skip


def _noise_free_capture(robot, plan, tracker_from_base, true_parameters, joint_errors, joint_limits):
    """The plan's capture without instrument noise, with the deterministic part of the joint errors."""
    deterministic_errors = _deterministic(joint_errors)
    capture, exact = simulate_capture(
        robot,
        plan,
        _NOISE_FREE,
        tracker_from_base,
        true_parameters=true_parameters,
        joint_errors=deterministic_errors,
        joint_limits=joint_limits,
        rng=0,
    )
    capture = Capture(
        circle=capture.circle,
        direction=capture.direction,
        readings=capture.readings,
        points=capture.points,
        source="noise-free capture of the Monte Carlo scenario",
    )
    return capture, exact


def _refined_structure(
    robot, capture, exact, reference, plan, instrument, tracker_from_base, true_parameters, options, *, criterion, poses,
    poses_target, joint_model, repeatability_sd=0.0, joint_errors=None,
):  # fmt: skip
    """The refined model's capture (the circles, then the calibration poses), exact points, refinement structure
    (with the Gauss-Newton draws' stopping rule) and the true joint-model values."""
    from robotcal.uncertainty.gauss_newton import shared_step, step_tolerance
    from robotcal.uncertainty.refined import prepare_refined_model

    targets = plan.reflector
    if poses is not None:  # the circles, then the calibration poses on their flange target
        if poses_target is None or poses_target.frame != "flange" or not poses_target.known:
            raise InputError("calibration poses need their flange target, of known offset (`poses_target`)")
        pose_capture, pose_exact = simulate_target_poses(
            robot, poses, (poses_target,), _NOISE_FREE, tracker_from_base, true_parameters=true_parameters,
            joint_errors=joint_errors, rng=0,
        )  # fmt: skip
        circles = Target.from_mount(plan.reflector, "capture" if poses_target.name != "capture" else "circles")
        capture = join_captures([(capture, circles.name), (pose_capture, None)], source=capture.source)
        exact = np.concatenate([exact, pose_exact])
        targets = (circles, poses_target)
    start = ParameterSet(robot=robot, values=reference.values, identified=reference.identified)
    refined = prepare_refined_model(
        capture,
        start,
        targets,
        criterion=criterion,
        tracker_from_base=reference.tracker_from_base,
        estimate_base=options.base_frame != "given",
        joint_model=joint_model,
    )
    variance = coordinate_variance(instrument, instrument.error_bound(exact)) + repeatability_sd**2
    tolerance = step_tolerance(refined, exact, variance)
    refined = dataclasses.replace(refined, step_tolerance=tolerance)
    refined = dataclasses.replace(refined, shared_step=shared_step(refined))
    extra_true = np.zeros(0)
    if refined.joint_model is not None:
        truth = true_parameters.joint_model
        known = {} if truth is None else dict(zip(truth.names, truth.values, strict=True))
        extra_true = np.array([known.get(name, 0.0) for name in refined.joint_model.names])
    return capture, exact, refined, extra_true


def coordinate_variance(instrument: Instrument, error_bound: np.ndarray) -> np.ndarray:
    """``(n_points, 3)`` [mm^2] from the bound ``U(L)`` of every point: U^2/3 (uniform) or (U/k)^2."""
    bound = np.repeat(np.asarray(error_bound)[:, None], 3, axis=1)
    if instrument.noise == "uniform":
        return bound**2 / 3.0
    return (bound / instrument.coverage_factor) ** 2
