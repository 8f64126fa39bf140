"""Pose sets: random reachable poses for validation captures, and the thesis's real test-2 plan.

A validation capture measures a flange-mounted target at poses other than the calibration circles
(thesis ch. 4.5.7 evaluates the parameters on the measured points). Its points belong to no
circle: in a :class:`~robotcal.capture.Capture` they carry ``circle = 0`` and ``direction = +1``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.instruments import Instrument
from robotcal.kinematics.forward import target_positions
from robotcal.kinematics.model import ParameterSet, ReflectorMount, RobotModel
from robotcal.simulation.generator import JointErrorModel, free_pose_points
from robotcal.simulation.plan import CapturePlan

__all__ = [
    "random_poses",
    "simulate_poses",
    "thesis_test2_plan",
    "TABLE_4_1_RANGE_DEG",
    "TABLE_4_2_START_DEG",
    "TABLE_4_4_POINTS",
]

#: Thesis Table 4.1: initial and final controller angle of each joint's circle [deg] (KUKA signs).
TABLE_4_1_RANGE_DEG = np.array(
    [[167.0, -167.0], [-5.0, -162.0], [145.0, -114.0], [177.0, -177.0], [90.0, -90.0], [178.0, -178.0]]
)
#: Thesis Table 4.2: row i is the configuration from which circle i starts [deg]; the turning
#: joint itself starts at Table 4.1's initial angle.
TABLE_4_2_START_DEG = np.array(
    [
        [0.0, -90.0, 90.0, 0.0, -90.0, 0.0],
        [0.0, -90.0, 45.0, -90.0, -90.0, 0.0],
        [0.0, -90.0, 90.0, -90.0, -90.0, 0.0],
        [0.0, -90.0, 90.0, 0.0, -90.0, 0.0],
        [0.0, -90.0, 90.0, 0.0, 0.0, 0.0],
        [0.0, -90.0, 90.0, 0.0, 0.0, 0.0],
    ]
)
#: Thesis Table 4.4 (test 2): points per joint and direction; both directions give 580 points.
TABLE_4_4_POINTS = np.array([60, 30, 50, 60, 30, 60])


def thesis_test2_plan(flange_reflector_mm: ArrayLike = (60.0, 40.0, 30.0)) -> CapturePlan:
    """The capture plan of the thesis's real test 2 (Tables 4.1, 4.2, 4.4): 580 points.

    Controller readings of the KUKA KR 5 sixx R650 (robot ``kuka-kr5-sixx-r650-krc``); circle i
    starts from row i of Table 4.2 with joint i at Table 4.1's initial angle and turns to the final
    angle in 60/30/50/60/30/60 points, forward and back. The active target sits on the flange
    (Fig. 4.19); its position is not published, so ``flange_reflector_mm`` (frame {6}) [mm] must be
    off axis 6 (the default is a plausible mount, not a thesis value).
    """
    start = TABLE_4_2_START_DEG.copy()
    start[np.arange(6), np.arange(6)] = TABLE_4_1_RANGE_DEG[:, 0]
    sweep = TABLE_4_1_RANGE_DEG[:, 1] - TABLE_4_1_RANGE_DEG[:, 0]
    return CapturePlan(
        start=np.deg2rad(start),
        sweep=np.deg2rad(sweep),
        points=TABLE_4_4_POINTS,
        reflector=ReflectorMount(frame="flange", positions=np.asarray(flange_reflector_mm, dtype=float)),
        bidirectional=True,
    )


def random_poses(
    robot: RobotModel,
    n_poses: int,
    *,
    margin_deg: float = 5.0,
    min_height_mm: float | None = None,
    reflector: ReflectorMount | None = None,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Seeded random controller readings, uniform within the robot's limits less a margin.

    Parameters
    ----------
    robot : RobotModel
        Its ``limits`` (controller readings) must be finite.
    n_poses : int
        Number of poses, >= 1.
    margin_deg : float
        Distance kept from each software limit [deg], >= 0.
    min_height_mm : float, optional
        Reject (and redraw) poses whose flange target (``reflector``, nominal model) lies below this
        height above the base's xy plane [mm]: a crude floor so that "reachable" excludes poses
        through the mounting surface.
    reflector : ReflectorMount, optional
        Flange target for ``min_height_mm`` (the flange origin when omitted).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    ndarray, shape (n_poses, n_joints)
        Readings [rad].
    """
    rng = np.random.default_rng(rng)
    if isinstance(n_poses, (bool, np.bool_)) or not isinstance(n_poses, (int, np.integer)) or n_poses < 1:
        raise InputError(f"`n_poses` must be a whole number >= 1; got {n_poses!r}")
    if not np.isfinite(margin_deg) or margin_deg < 0:
        raise InputError(f"`margin_deg` must be a finite number >= 0; got {margin_deg!r}")
    limits = robot.limits
    if not np.all(np.isfinite(limits)):
        raise InputError(f"robot {robot.name!r} has unbounded joint limits; random poses need finite `limits_deg`")
    low = limits[:, 0] + np.deg2rad(margin_deg)
    high = limits[:, 1] - np.deg2rad(margin_deg)
    if np.any(low >= high):
        joint = int(np.flatnonzero(low >= high)[0])
        raise InputError(f"`margin_deg` = {margin_deg:g} leaves no range for J{joint + 1}")
    if reflector is not None and reflector.frame != "flange":
        raise InputError("random poses need a flange reflector (frame='flange')")
    target = reflector if reflector is not None else ReflectorMount(frame="flange", positions=np.zeros(3))
    accepted = np.empty((0, robot.n_joints))
    for _ in range(100):
        batch = rng.uniform(low, high, size=(max(2 * (n_poses - accepted.shape[0]), 16), robot.n_joints))
        if min_height_mm is not None:
            q = robot.model_joint_variables(batch)
            height = target_positions(robot.nominal, q, np.zeros(q.shape[0], dtype=int), target)[:, 2]
            batch = batch[height >= min_height_mm]
        accepted = np.concatenate([accepted, batch])[:n_poses]
        if accepted.shape[0] == n_poses:
            return accepted
    raise InputError(f"could not find {n_poses} poses with the target above {min_height_mm} mm")


def simulate_poses(
    robot: RobotModel,
    readings: ArrayLike,
    reflector: ReflectorMount,
    instrument: Instrument,
    tracker_from_base: ArrayLike,
    *,
    true_parameters: ParameterSet | None = None,
    joint_errors: JointErrorModel | None = None,
    rng: np.random.Generator | int | None = None,
) -> tuple[Capture, np.ndarray]:
    """A capture of a flange target at free poses (``circle = 0``, ``direction = +1``).

    Parameters
    ----------
    robot : RobotModel
    readings : array_like, shape (n_points, n_joints)
        Controller readings [rad].
    reflector : ReflectorMount
        Flange target (``frame="flange"``).
    instrument : Instrument
    tracker_from_base : array_like, shape (4, 4)
    true_parameters : ParameterSet, optional
        The "real" robot (nominal by default).
    joint_errors : JointErrorModel, optional
        The robot's joint errors (eq. 5-2) at the poses, without lash
        (:func:`robotcal.simulation.generator.free_pose_errors`).
    rng : numpy.random.Generator or int or None
        Joint error noise (when given and noisy), then instrument noise.

    Returns
    -------
    capture : Capture
    exact_points : ndarray, shape (n_points, 3)
        Noise-free points in the tracker frame [mm].
    """
    rng = np.random.default_rng(rng)
    if reflector.frame != "flange":
        raise InputError("a capture at free poses needs a flange reflector (frame='flange')")
    readings = np.asarray(readings, dtype=float)
    if readings.ndim != 2 or readings.shape[1] != robot.n_joints or readings.shape[0] < 1:
        raise InputError(f"`readings` must have shape (n_points, {robot.n_joints}); got {readings.shape}")
    parameters = ParameterSet.nominal(robot) if true_parameters is None else true_parameters
    offset = np.reshape(reflector.positions, (1, 3))
    noisy, exact = free_pose_points(parameters, readings, offset, instrument, tracker_from_base, joint_errors, rng)
    n = readings.shape[0]
    capture = Capture(
        circle=np.zeros(n, dtype=int),
        direction=np.ones(n, dtype=int),
        readings=readings,
        points=noisy,
        source="simulated validation capture",
    )
    return capture, exact
