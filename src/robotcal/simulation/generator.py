"""Synthetic Circle Point capture generator (thesis ch. 5.2.1.1, eqs 5-1..5-4).

A target point of circle i is ``tracker_from_base . F_{i-1} . G_Zi(q_i) . r_i`` (eq. 5-1), where
``F_{i-1}`` chains the links of the earlier joints at their current readings and
``G_Zi = RT_err = T(dx, dy, dz) Rx(ex) Ry(ey) Rz(q_i)`` (eqs 5-3, 5-4) carries the joint error model.
Beyond the thesis, the error model has a direction-dependent backlash term (an angular lash about the
joint axis and a translational lash), so that forward and return sweeps differ (ch. 4.6).
Instrument noise ``U(L) = A + B L`` is added last, from one seeded generator.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from robotcal.capture import Capture
from robotcal.errors import InputError, JointLimitWarning
from robotcal.geometry.transforms import apply_transform, check_rigid_transform, rot_x, rot_y, rot_z, translation
from robotcal.instruments import Instrument
from robotcal.kinematics.forward import target_positions
from robotcal.kinematics.joint_model import motion_direction
from robotcal.kinematics.model import ParameterSet, ReflectorMount, RobotModel
from robotcal.simulation.plan import CapturePlan

__all__ = [
    "JointErrorModel",
    "simulate_capture",
    "simulate_target_poses",
    "free_pose_errors",
    "free_pose_points",
    "motion_direction",
    "ERROR_TERMS",
]

#: Error terms of a joint, in the order of the thesis's Err matrix rows (eq. 5-2).
ERROR_TERMS = ("dx", "dy", "dz", "ex", "ey")


@dataclass(frozen=True, slots=True, kw_only=True)
class JointErrorModel:
    """Per-joint error model of eq. 5-2: ``e = A sin(2 pi / T * q + phi) + N(0, R)`` per term.

    Terms (columns): ``dx, dy, dz`` translations [mm] and ``ex, ey`` rotations [rad] about the x and
    y axes of frame {i-1}; the joint's own rotation about z is the joint variable. ``q`` is the
    model joint variable [rad]. A joint that does not move keeps its error: the random part is drawn
    once each time the joint reaches a new reading (so a joint resting after its circle keeps the
    error of its last point, as the thesis's generator keeps its last ``G_Zi``).

    Backlash (not in the thesis's generator; ch. 4.6 measures it): the joint output lags the
    commanded motion by half the lash. With ``s = +1`` when the joint's last motion was towards
    larger ``q`` and ``s = -1`` towards smaller (see :func:`motion_direction`), the joint turns by
    ``-s * backlash / 2`` about its axis and shifts by ``-s * lash / 2`` in frame {i-1}. A return
    point therefore differs from the forward point at the same reading by a turn of ``+backlash``
    and a shift of ``+lash``; a point reached without motion (the turnaround of a bidirectional
    sweep) keeps the state of the motion before it.

    Attributes
    ----------
    amplitude, period, phase, noise_sd : ndarray, shape (n_joints, 5)
        A [mm | rad], T [rad of joint angle, > 0], phi [rad], R (standard deviation) [mm | rad].
    backlash : ndarray, shape (n_joints,), optional
        Total angular lash of each joint, >= 0 [rad]; zeros by default. A measured model
        (:class:`robotcal.uncertainty.joint_errors.MeasuredJointErrors`) may hold a negative one: a lash that lags the
        other way, which no joint has but the mean of a measurement of a lash of about zero can (its
        :attr:`signed_backlash`).
    lash : ndarray, shape (n_joints, 3), optional
        Total translational lash of each joint in frame {i-1} [mm]; zeros by default.
    """

    amplitude: np.ndarray
    period: np.ndarray
    phase: np.ndarray
    noise_sd: np.ndarray
    backlash: np.ndarray = None  # type: ignore[assignment]  # None: zeros, set in __post_init__
    lash: np.ndarray = None  # type: ignore[assignment]  # None: zeros, set in __post_init__
    #: Whether a negative ``backlash`` is accepted: not in a model stated for a robot, whose lash is a gap.
    signed_backlash: ClassVar[bool] = False

    def __post_init__(self):
        shape = np.shape(self.amplitude)
        for name in ("amplitude", "period", "phase", "noise_sd"):
            value = np.array(getattr(self, name), dtype=float)
            if value.shape != shape or value.ndim != 2 or value.shape[1] != 5:
                raise InputError(f"joint error model: `{name}` must have shape (n_joints, 5); got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise InputError(f"joint error model: `{name}` contains NaN or infinite values")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if np.any(self.period <= 0):
            raise InputError("joint error model: every `period` must be > 0")
        if np.any(self.noise_sd < 0):
            raise InputError("joint error model: `noise_sd` must be >= 0")
        n = shape[0]
        for name, expected in (("backlash", (n,)), ("lash", (n, 3))):
            raw = getattr(self, name)
            value = np.zeros(expected) if raw is None else np.array(raw, dtype=float)
            if value.shape != expected:
                raise InputError(f"joint error model: `{name}` must have shape {expected}; got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise InputError(f"joint error model: `{name}` contains NaN or infinite values")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if not self.signed_backlash and np.any(self.backlash < 0):
            raise InputError("joint error model: every `backlash` angle must be >= 0")

    @classmethod
    def zeros(cls, n_joints: int) -> JointErrorModel:
        zeros = np.zeros((n_joints, 5))
        return cls(amplitude=zeros, period=np.full((n_joints, 5), 2 * np.pi), phase=zeros, noise_sd=zeros)

    @property
    def n_joints(self) -> int:
        return self.amplitude.shape[0]

    def values(self, q, *, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Error terms ``(n_points, n_joints, 5)`` at model joint variables ``q (n_points, n_joints)``."""
        rng = np.random.default_rng(rng)
        q = np.asarray(q, dtype=float)
        values = self.amplitude * np.sin(2 * np.pi / self.period * q[..., None] + self.phase)
        if np.any(self.noise_sd > 0):
            raw = rng.standard_normal(values.shape) * self.noise_sd
            for joint in range(q.shape[1]):
                new_reading = np.r_[True, np.diff(q[:, joint]) != 0.0]
                first = np.flatnonzero(new_reading)[np.cumsum(new_reading) - 1]
                raw[:, joint] = raw[first, joint]
            values = values + raw
        return values

    @property
    def has_lash(self) -> bool:
        """Whether any joint has an angular or translational lash."""
        return bool(np.any(self.backlash != 0.0) or np.any(self.lash != 0.0))

    def at_free_poses(self) -> JointErrorModel:
        """The model a robot shows at free poses: the same terms without lash (a free pose's approach direction,
        which sets each joint's lash state, is not recorded: the refinement does not model it there either)."""
        return replace(self, backlash=np.zeros_like(self.backlash), lash=np.zeros_like(self.lash))

    def transforms(self, q, *, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Error transforms ``E = T(dx, dy, dz) Rx(ex) Ry(ey)``, shape ``(n_points, n_joints, 4, 4)``.

        With lash, ``E = T(d - s lash / 2) Rx(ex) Ry(ey) Rz(-s backlash / 2)`` with ``s`` the
        direction of each joint's last motion along the rows of ``q`` (:func:`motion_direction`);
        ``E Rz(q)`` is then the joint turned to ``q - s backlash / 2``. The sinusoidal terms are
        evaluated at the commanded ``q``.
        """
        values = self.values(q, rng=rng)
        shift = values[..., :3]
        if not self.has_lash:
            return translation(shift) @ rot_x(values[..., 3]) @ rot_y(values[..., 4])
        state = motion_direction(q)
        shift = shift - 0.5 * state[..., None] * self.lash
        turn = rot_z(-0.5 * state * self.backlash)
        return translation(shift) @ rot_x(values[..., 3]) @ rot_y(values[..., 4]) @ turn


def free_pose_points(
    parameters: ParameterSet,
    readings: np.ndarray,
    offsets: np.ndarray,
    instrument: Instrument,
    tracker_from_base: ArrayLike,
    joint_errors: JointErrorModel | None,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Measured and exact tracker-frame points ``(n_poses * n_targets, 3)`` [mm] of flange targets at ``offsets
    (n_targets, 3)`` [mm] at every pose (pose by pose, the targets in order), on the robot ``parameters`` with its
    ``joint_errors`` at free poses (:func:`free_pose_errors`); ``rng`` draws the joint noise, then the instrument's."""
    tracker_from_base = check_rigid_transform(tracker_from_base, "tracker_from_base")
    q = parameters.model_joint_variables(readings)
    errors = free_pose_errors(joint_errors, parameters.robot, readings, rng)
    base_points = np.stack(
        [target_positions(parameters.values, q, np.zeros(q.shape[0], dtype=int), mount, joint_errors=errors)
         for mount in (ReflectorMount(frame="flange", positions=offset) for offset in offsets)],
        axis=1,
    )  # fmt: skip
    exact = apply_transform(tracker_from_base, base_points.reshape(-1, 3))
    noisy = exact + instrument.sample_noise(exact, rng=rng) if not instrument.is_noise_free else exact.copy()
    return noisy, exact


def free_pose_errors(
    joint_errors: JointErrorModel | None, robot: RobotModel, readings: np.ndarray, rng: np.random.Generator
) -> np.ndarray | None:
    """The error transforms ``(n_poses, n_joints, 4, 4)`` of ``joint_errors`` at free poses (no lash:
    :meth:`JointErrorModel.at_free_poses`), evaluated like a capture's at the commanded joint variables; None
    without joint errors (and then no draw from ``rng``)."""
    if joint_errors is None:
        return None
    if joint_errors.n_joints != robot.n_joints:
        raise InputError(f"joint error model has {joint_errors.n_joints} joints; robot has {robot.n_joints}")
    return joint_errors.at_free_poses().transforms(robot.model_joint_variables(readings), rng=rng)


def _check_limits(robot: RobotModel, readings: np.ndarray, circle: np.ndarray, policy: str) -> None:
    if policy == "ignore":
        return
    outside = (readings < robot.limits[:, 0] - 1e-12) | (readings > robot.limits[:, 1] + 1e-12)
    if not np.any(outside):
        return
    messages = []
    for joint in np.flatnonzero(outside.any(axis=0)):
        rows = np.flatnonzero(outside[:, joint])
        worst = readings[rows, joint][np.argmax(np.abs(readings[rows, joint]))]
        lo, hi = np.rad2deg(robot.limits[joint])
        messages.append(
            f"J{joint + 1} reaches {np.rad2deg(worst):.6g} deg (circle {circle[rows[0]]}), outside its limits [{lo:g}, {hi:g}] deg"
        )
    text = "capture plan leaves the joint limits of robot " + repr(robot.name) + ": " + "; ".join(messages)
    if policy == "error":
        raise InputError(text)
    warnings.warn(text, JointLimitWarning, stacklevel=3)


def simulate_capture(
    robot: RobotModel,
    plan: CapturePlan,
    instrument: Instrument,
    tracker_from_base: ArrayLike,
    *,
    true_parameters: ParameterSet | None = None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: str = "warn",
    rng: np.random.Generator | int | None = None,
) -> tuple[Capture, np.ndarray]:
    """Simulate a Circle Point capture (algorithm 5.2.1.1).

    Parameters
    ----------
    robot : RobotModel
        Gives the reading map (controller readings -> model joint variables) and limits.
    plan : CapturePlan
        Readings to visit and where the target sits.
    instrument : Instrument
        Noise model; a noise-free instrument gives exact points.
    tracker_from_base : array_like, shape (4, 4)
        Rigid transform from the robot base frame to the instrument frame [mm].
    true_parameters : ParameterSet, optional
        The "real" robot; nominal parameters by default.
    joint_errors : JointErrorModel, optional
        Joint error model of eq. 5-2 with its backlash term (none by default). The lash state of
        each joint follows the order of ``plan.readings(robot)`` (on a coupled robot the coupled readings follow the turning joint).
    joint_limits : {"warn", "error", "ignore"}
        What to do when the plan leaves the robot's software limits.
    rng : numpy.random.Generator or int or None
        Source of all random draws (joint error noise first, then instrument noise).

    Returns
    -------
    capture : Capture
        Noisy points in the tracker frame; readings as the controller reports them.
    exact_points : ndarray, shape (n_points, 3)
        The same points without instrument noise [mm].
    """
    rng = np.random.default_rng(rng)
    if joint_limits not in ("warn", "error", "ignore"):
        raise InputError(f"`joint_limits` must be 'warn', 'error' or 'ignore'; got {joint_limits!r}")
    if plan.n_joints != robot.n_joints:
        raise InputError(
            f"capture plan has {plan.n_joints} circles but robot {robot.name!r} has {robot.n_joints} joints"
        )
    tracker_from_base = check_rigid_transform(tracker_from_base, "tracker_from_base")
    parameters = ParameterSet.nominal(robot) if true_parameters is None else true_parameters
    if parameters.robot.n_joints != robot.n_joints:
        raise InputError(
            f"true parameters have {parameters.robot.n_joints} joints; robot {robot.name!r} has {robot.n_joints}"
        )
    circle, direction, readings = plan.readings(robot)
    _check_limits(robot, readings, circle, joint_limits)
    q = parameters.model_joint_variables(readings)
    errors = None
    if joint_errors is not None:
        if joint_errors.n_joints != robot.n_joints:
            raise InputError(f"joint error model has {joint_errors.n_joints} joints; robot has {robot.n_joints}")
        # the joint errors (and each joint's lash state) follow the commanded motion, not the gravity sag of an
        # extended truth: a joint that rests keeps its lash while its deflection changes with the others
        errors = joint_errors.transforms(robot.model_joint_variables(readings), rng=rng)
    base_points = target_positions(parameters.values, q, circle - 1, plan.reflector, joint_errors=errors)
    exact = apply_transform(tracker_from_base, base_points)
    noisy = exact + instrument.sample_noise(exact, rng=rng) if not instrument.is_noise_free else exact.copy()
    capture = Capture(circle=circle, direction=direction, readings=readings, points=noisy, source="simulated capture")
    return capture, exact


def simulate_target_poses(
    robot: RobotModel,
    readings: ArrayLike,
    targets,
    instrument: Instrument,
    tracker_from_base: ArrayLike,
    *,
    true_parameters: ParameterSet | None = None,
    true_offsets: ArrayLike | None = None,
    u95_mm: float | None = None,
    joint_errors: JointErrorModel | None = None,
    rng: np.random.Generator | int | None = None,
) -> tuple[Capture, np.ndarray]:
    """A capture of several flange targets at every one of a set of free poses (issue 14).

    Each pose is measured on every target in turn (rows pose by pose, the targets in the given
    order), ``circle = 0``, ``direction = +1``, with a ``target`` column naming them; a flange target
    sits at ``T F_n r_t`` (the true robot, the true offset ``r_t``).

    Parameters
    ----------
    robot : RobotModel
    readings : array_like, shape (n_poses, n_joints)
        Controller readings [rad].
    targets : sequence of robotcal.identification.targets.Target
        Flange targets (``frame="flange"``); their names go to the ``target`` column.
    instrument : Instrument
        Noise model (a noise-free instrument gives exact points).
    tracker_from_base : array_like, shape (4, 4)
    true_parameters : ParameterSet, optional
        The "real" robot (nominal by default).
    true_offsets : array_like, shape (n_targets, 3), optional
        The real offsets [mm] (default: each target's ``positions``, e.g. for a target declared unknown
        with a guess, pass the truth here).
    u95_mm : float, optional
        Written to the ``u95_mm`` column of every point (the instrument's stated U(95)) [mm].
    joint_errors : JointErrorModel, optional
        The robot's joint errors (eq. 5-2) at the poses, without lash (:meth:`JointErrorModel.at_free_poses`).
    rng : numpy.random.Generator or int or None
        Joint error noise (when given and noisy), then instrument noise.

    Returns
    -------
    capture : Capture
    exact_points : ndarray, shape (n_poses * n_targets, 3)
    """
    rng = np.random.default_rng(rng)
    readings = np.atleast_2d(np.asarray(readings, dtype=float))
    if readings.shape[1] != robot.n_joints:
        raise InputError(f"{readings.shape[1]} readings per pose; robot {robot.name!r} has {robot.n_joints} joints")
    targets = tuple(targets)
    if not targets or any(target.frame != "flange" for target in targets):
        raise InputError("simulate_target_poses needs one or more flange targets")
    offsets = (
        np.array([target.positions for target in targets], dtype=float)
        if true_offsets is None
        else np.asarray(true_offsets, dtype=float).reshape(len(targets), 3)
    )
    parameters = ParameterSet.nominal(robot) if true_parameters is None else true_parameters
    noisy, exact = free_pose_points(parameters, readings, offsets, instrument, tracker_from_base, joint_errors, rng)
    n_points = exact.shape[0]
    capture = Capture(
        circle=np.zeros(n_points, dtype=int),
        direction=np.ones(n_points, dtype=int),
        readings=np.repeat(readings, len(targets), axis=0),
        points=noisy,
        source="simulated multi-target capture",
        target=np.tile(np.arange(len(targets)), readings.shape[0]),
        target_names=tuple(target.name for target in targets),
        u95=None if u95_mm is None else np.full(n_points, float(u95_mm)),
    )
    return capture, exact
