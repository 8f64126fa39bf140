"""Is a capture plan feasible in the cell? Joint limits, measuring range, target acceptance, line of sight.

The thesis plans its captures with a parametric CAD model of the robot, tracker and target (ch. 4.5.2,
Fig. 4.16): the widest angular range per axis that keeps the software limits (Fig. 4.17) and the line
of sight between tracker and reflector. This module is that check in numbers, point by point:

- **joint limits**: every reading within the robot file's ``limits_deg`` (in that file's reading
  convention, which is the controller's for a ``reading_sign`` file);
- **measuring range**: tracker-to-target distance within ``[min_distance, max_distance]``;
- **acceptance**: the angle between the target's normal and the direction to the tracker within the
  acceptance half-angle. The normal is fixed on the body carrying the target and is *aimed* at the
  tracker at one point of each circle (``aim="middle"``: the middle point of the circle, the way an
  operator sets an SMR to cover a sweep; ``aim="start"``: its first point). A flange target is
  re-aimed for every circle. With no acceptance angle the check is skipped (an active target);
- **line of sight**: the segment from the tracker to the target must not cross the robot's links,
  modelled as capsules (segments with a radius) between consecutive DH frame origins
  ``F_{i-1} -> F_i`` (link i). The link carrying the target and any capsule that contains the target
  itself are not obstacles (the target sits on that body's surface; its own body is the acceptance
  cone's business).

Geometry in the robot base frame, millimetres and radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.kinematics.forward import joint_frames
from robotcal.kinematics.model import ParameterSet, RobotModel
from robotcal.simulation.plan import CapturePlan

__all__ = ["CellModel", "PlanCheck", "CircleCheck", "segment_distance", "check_plan", "REASONS"]

#: Failure reasons, in the order they are reported.
REASONS = ("joint limit", "range", "acceptance", "line of sight")
_EPS = 1e-12


def segment_distance(p0: ArrayLike, p1: ArrayLike, q0: ArrayLike, q1: ArrayLike) -> np.ndarray:
    """Shortest distance between segments ``p0-p1`` and ``q0-q1`` (batched, broadcasting).

    Closest points ``p0 + s (p1 - p0)`` and ``q0 + t (q1 - q0)`` with ``s, t`` in [0, 1] minimise
    ``|w + s u - t v|^2`` (``w = p0 - q0``): the unconstrained minimiser's ``s`` clamped to [0, 1],
    ``t`` from ``s``, and where ``t`` leaves [0, 1], ``t`` clamped and ``s`` recomputed from it
    (exact for this convex quadratic; C. Ericson, *Real-Time Collision Detection*, 2005, 5.1.9).
    Zero-length segments are points.

    Parameters
    ----------
    p0, p1, q0, q1 : array_like, shape (..., 3)
        Segment ends [mm].

    Returns
    -------
    ndarray, shape (...)
        Distance [mm].
    """
    p0, p1, q0, q1 = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (p0, p1, q0, q1)))
    u = p1 - p0
    v = q1 - q0
    w = p0 - q0
    a = np.sum(u * u, axis=-1)
    b = np.sum(u * v, axis=-1)
    c = np.sum(v * v, axis=-1)
    d = np.sum(u * w, axis=-1)
    e = np.sum(v * w, axis=-1)
    point_p, point_q = a <= _EPS, c <= _EPS
    safe_a, safe_c = np.where(point_p, 1.0, a), np.where(point_q, 1.0, c)
    denominator = a * c - b * b
    parallel = denominator <= 1e-12 * np.maximum(a * c, _EPS)
    s = np.where(parallel, 0.0, (b * e - c * d) / np.where(parallel, 1.0, denominator))
    s = np.where(point_p, 0.0, np.clip(s, 0.0, 1.0))
    s = np.where(point_q & ~point_p, np.clip(-d / safe_a, 0.0, 1.0), s)
    t = np.where(point_q, 0.0, (b * s + e) / safe_c)
    low, high = t < 0.0, t > 1.0
    t = np.clip(t, 0.0, 1.0)
    s = np.where(low & ~point_p, np.clip(-d / safe_a, 0.0, 1.0), s)
    s = np.where(high & ~point_p, np.clip((b - d) / safe_a, 0.0, 1.0), s)
    gap = (p0 + s[..., None] * u) - (q0 + t[..., None] * v)
    return np.linalg.norm(gap, axis=-1)


@dataclass(frozen=True, slots=True, kw_only=True)
class CellModel:
    """The cell around the robot: where the tracker is, what it can measure, how thick the links are.

    Attributes
    ----------
    tracker_from_base : ndarray, shape (4, 4)
        Instrument pose (``tracker_from_base`` of the scenario) [mm].
    capsule_radius : ndarray, shape (n_joints,)
        Radius of link i's capsule ``F_{i-1} -> F_i`` [mm] (0: the link is no obstacle).
    min_distance, max_distance : float
        Usable measuring range [mm] (0 and inf: unchecked).
    acceptance : float or None
        Acceptance half-angle of the target [rad]; None: unchecked (active target).
    aim : {"middle", "start"}
        Where on each circle the target's normal points at the tracker.
    """

    tracker_from_base: np.ndarray
    capsule_radius: np.ndarray
    min_distance: float = 0.0
    max_distance: float = np.inf
    acceptance: float | None = None
    aim: str = "middle"

    def __post_init__(self):
        transform = np.asarray(self.tracker_from_base, dtype=float)
        if transform.shape != (4, 4):
            raise InputError(f"`tracker_from_base` must be 4x4; got {transform.shape}")
        radius = np.asarray(self.capsule_radius, dtype=float)
        if radius.ndim != 1 or np.any(radius < 0) or not np.all(np.isfinite(radius)):
            raise InputError(f"`capsule_radius` must be finite, non-negative, one per link; got {radius.tolist()}")
        if not 0.0 <= self.min_distance < self.max_distance:
            raise InputError(
                f"measuring range must satisfy 0 <= min < max; got [{self.min_distance}, {self.max_distance}] mm"
            )
        if self.acceptance is not None and not 0.0 < self.acceptance <= np.pi:
            raise InputError(f"acceptance half-angle must be in (0, 180] deg; got {np.rad2deg(self.acceptance)} deg")
        if self.aim not in ("middle", "start"):
            raise InputError(f"`aim` must be 'middle' or 'start'; got {self.aim!r}")
        for name, value in (("tracker_from_base", transform), ("capsule_radius", radius)):
            value = value.copy()
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def tracker_position(self) -> np.ndarray:
        """Tracker origin in the base frame ``(3,)`` [mm] (``base_from_tracker`` translation)."""
        rotation = self.tracker_from_base[:3, :3]
        return -rotation.T @ self.tracker_from_base[:3, 3]


@dataclass(frozen=True, slots=True, kw_only=True)
class CircleCheck:
    """One circle's verdict (forward sweep).

    ``usable_deg``: the longest run of consecutive feasible points as (first, last) reading of the
    turning joint [deg], or None. ``first_failure``: 1-based point index of the first infeasible
    point (None when all pass) and ``first_reasons`` its reasons.
    """

    circle: int
    points: int
    feasible_points: int
    start_deg: float
    end_deg: float
    usable_deg: tuple[float, float] | None
    first_failure: int | None
    first_reasons: tuple[str, ...]


@dataclass(frozen=True, slots=True, kw_only=True)
class PlanCheck:
    """Point-by-point verdict of a plan in the cell.

    Attributes
    ----------
    circle, direction : ndarray of int, shape (n_points,)
    readings : ndarray, shape (n_points, n_joints)
        Controller readings [rad].
    limit_joint : ndarray of int, shape (n_points,)
        0-based first joint outside its limits, -1 when none.
    distance : ndarray, shape (n_points,)
        Tracker-to-target distance [mm].
    incidence : ndarray, shape (n_points,)
        Angle between the target normal and the direction to the tracker [rad].
    clearance : ndarray, shape (n_points,)
        Smallest (sight-line distance - radius) over the obstacle capsules [mm]; negative = blocked.
    blocking_link : ndarray of int, shape (n_points,)
        1-based link whose capsule blocks the sight line (the deepest), 0 when clear.
    failures : ndarray of bool, shape (n_points, 4)
        Per point and reason (``REASONS`` order).
    circles : tuple of CircleCheck
    """

    circle: np.ndarray
    direction: np.ndarray
    readings: np.ndarray
    limit_joint: np.ndarray
    distance: np.ndarray
    incidence: np.ndarray
    clearance: np.ndarray
    blocking_link: np.ndarray
    failures: np.ndarray
    circles: tuple[CircleCheck, ...]

    @property
    def ok(self) -> np.ndarray:
        """``(n_points,)`` bool: the point passes every check."""
        return ~np.any(self.failures, axis=1)

    @property
    def feasible(self) -> bool:
        return bool(np.all(self.ok))

    def reasons(self, index: int) -> tuple[str, ...]:
        """Human-readable reasons why point ``index`` (0-based) fails."""
        out = []
        for k in range(len(REASONS)):
            if not self.failures[index, k]:
                continue
            if k == 0:
                out.append(f"joint limit J{self.limit_joint[index] + 1}")
            elif k == 1:
                out.append(f"range ({self.distance[index] / 1000:.2f} m)")
            elif k == 2:
                out.append(f"acceptance ({np.rad2deg(self.incidence[index]):.0f} deg)")
            else:
                out.append(f"line of sight (link {self.blocking_link[index]})")
        return tuple(out)


def _rz(angle: np.ndarray) -> np.ndarray:
    out = np.zeros(angle.shape + (4, 4))
    c, s = np.cos(angle), np.sin(angle)
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    out[..., 2, 2] = out[..., 3, 3] = 1.0
    return out


def _target_frames(frames: np.ndarray, q: np.ndarray, circle: np.ndarray, plan: CapturePlan) -> np.ndarray:
    """``base_from_mount`` per point: ``F_{i-1} Rz(q_i)`` (joint mount, eq. 5-1) or ``F_n`` (flange)."""
    index = np.arange(q.shape[0])
    if plan.reflector.frame == "flange":
        return frames[index, -1]
    joint = circle - 1
    return frames[index, joint] @ _rz(q[index, joint])


def check_plan(
    robot: RobotModel, plan: CapturePlan, cell: CellModel, *, parameters: ParameterSet | None = None
) -> PlanCheck:
    """Check every point of ``plan`` in ``cell`` (module docstring for the rules).

    Parameters
    ----------
    robot : RobotModel
    plan : CapturePlan
    cell : CellModel
        ``capsule_radius`` must have one radius per joint.
    parameters : ParameterSet, optional
        Kinematic parameters of the check (nominal by default).

    Returns
    -------
    PlanCheck
    """
    n = robot.n_joints
    if cell.capsule_radius.shape != (n,):
        raise InputError(f"cell: {cell.capsule_radius.shape[0]} capsule radii for robot {robot.name!r} with {n} joints")
    values = (ParameterSet.nominal(robot) if parameters is None else parameters).values
    circle, direction, readings = plan.readings(robot)
    q = robot.model_joint_variables(readings)
    frames = joint_frames(values, q)  # (n_points, n + 1, 4, 4)
    mount = _target_frames(frames, q, circle, plan)
    local = plan.reflector.positions[circle - 1] if plan.reflector.frame == "joint" else plan.reflector.positions[0]
    local = np.broadcast_to(local, (q.shape[0], 3))
    target = np.einsum("pij,pj->pi", mount[:, :3, :3], local) + mount[:, :3, 3]
    tracker = cell.tracker_position

    # joint limits (reading convention of the robot file)
    lower, upper = robot.limits[:, 0], robot.limits[:, 1]
    tolerance = 1e-9
    outside = (readings < lower - tolerance) | (readings > upper + tolerance)
    limit_joint = np.where(outside.any(axis=1), np.argmax(outside, axis=1), -1)

    # range
    sight = tracker - target
    distance = np.linalg.norm(sight, axis=1)
    out_of_range = (distance < cell.min_distance) | (distance > cell.max_distance)

    # acceptance: normal fixed in the mount frame, aimed at the tracker at one point of each circle
    direction_to_tracker = sight / np.maximum(distance, _EPS)[:, None]
    incidence = np.zeros(q.shape[0])
    for c in np.unique(circle):
        forward = np.flatnonzero((circle == c) & (direction == 1))
        aim = forward[(forward.size - 1) // 2] if cell.aim == "middle" else forward[0]
        normal_mount = mount[aim, :3, :3].T @ direction_to_tracker[aim]
        rows = np.flatnonzero(circle == c)
        normal = np.einsum("pij,j->pi", mount[rows, :3, :3], normal_mount)
        cosine = np.clip(np.sum(normal * direction_to_tracker[rows], axis=1), -1.0, 1.0)
        incidence[rows] = np.arccos(cosine)
    bad_angle = incidence > cell.acceptance + 1e-12 if cell.acceptance is not None else np.zeros(q.shape[0], bool)

    # line of sight against the link capsules
    origins = frames[:, :, :3, 3]  # (n_points, n + 1, 3)
    starts, ends = origins[:, :-1], origins[:, 1:]
    gap = segment_distance(np.broadcast_to(tracker, starts.shape), target[:, None, :], starts, ends)
    radius = cell.capsule_radius[None, :]
    contains_target = segment_distance(target[:, None, :], target[:, None, :], starts, ends) < radius
    carrier = np.zeros_like(contains_target)
    carrier_link = circle - 1 if plan.reflector.frame == "joint" else np.full(q.shape[0], n - 1)
    carrier[np.arange(q.shape[0]), carrier_link] = True
    obstacle = (radius > 0) & ~contains_target & ~carrier
    margin = np.where(obstacle, gap - radius, np.inf)
    clearance = margin.min(axis=1)
    blocked = clearance < 0
    blocking_link = np.where(blocked, np.argmin(margin, axis=1) + 1, 0)

    failures = np.stack([limit_joint >= 0, out_of_range, bad_angle, blocked], axis=1)
    check = PlanCheck(
        circle=circle,
        direction=direction,
        readings=readings,
        limit_joint=limit_joint,
        distance=distance,
        incidence=incidence,
        clearance=clearance,
        blocking_link=blocking_link,
        failures=failures,
        circles=(),
    )
    object.__setattr__(check, "circles", tuple(_circle_summary(check, c) for c in range(1, n + 1)))
    return check


def _circle_summary(check: PlanCheck, c: int) -> CircleCheck:
    rows = np.flatnonzero((check.circle == c) & (check.direction == 1))
    ok = check.ok[rows]
    angles = np.rad2deg(check.readings[rows, c - 1])
    best, best_range, run_start = 0, None, None
    for k, good in enumerate(np.append(ok, False)):
        if good and run_start is None:
            run_start = k
        elif not good and run_start is not None:
            if k - run_start > best:
                best, best_range = k - run_start, (float(angles[run_start]), float(angles[k - 1]))
            run_start = None
    failing = np.flatnonzero(~ok)
    first = int(failing[0]) if failing.size else None
    return CircleCheck(
        circle=c,
        points=int(rows.size),
        feasible_points=int(ok.sum()),
        start_deg=float(angles[0]),
        end_deg=float(angles[-1]),
        usable_deg=best_range,
        first_failure=None if first is None else first + 1,
        first_reasons=() if first is None else check.reasons(int(rows[first])),
    )
