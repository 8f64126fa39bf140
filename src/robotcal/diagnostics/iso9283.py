"""ISO 9283 pose accuracy and repeatability: test poses P1..P5, AP, RP, AD, RD (docs/iso9283.md).

Definitions (ISO 9283:1998, clauses 7.2.1, 7.2.2, 7.3.1, 7.3.2), ``n`` cycles visiting the test
poses in order:

* Pose accuracy of pose k: barycentre ``x_bar = (1/n) sum_j x_j`` of the attained positions,
  ``APx = x_bar - x_c`` (likewise y, z) and ``AP = sqrt(APx^2 + APy^2 + APz^2)``, with ``x_c`` the
  commanded position.
* Pose repeatability: ``l_j = |x_j - x_bar|``, ``l_bar = (1/n) sum_j l_j``,
  ``S_l = sqrt(sum_j (l_j - l_bar)^2 / (n - 1))``, ``RP = l_bar + 3 S_l``.
* Distance accuracy between two poses (P2 and P4 by default): attained distances
  ``D_j = |x_{a,j} - x_{b,j}|``, commanded ``D_c = |x_{a,c} - x_{b,c}|``, ``AD = D_bar - D_c``;
  distance repeatability ``RD = 3 sqrt(sum_j (D_j - D_bar)^2 / (n - 1))``.
* Orientation (when the flange orientation is measured, e.g. from three or more flange targets
  registered onto their offsets, :func:`register_flange_poses`): the deviation of cycle j is the
  rotation vector ``(a_j, b_j, c_j)`` of ``R_a,j R_c^T`` (small rotations about the base axes x, y,
  z; ``axes="flange"``: of ``R_c^T R_a,j``, about the commanded flange axes); ``APa = a_bar`` (the
  commanded deviation is 0, so this is ISO's ``a_bar - a_c`` to first order), likewise b, c;
  ``S_a = sqrt(sum_j (a_j - a_bar)^2 / (n - 1))``, ``RPa = +-3 S_a``.

The standard's test poses lie on the diagonal plane ``C1-C2-C7-C8`` of a cube in the workspace
(edges parallel to the base axes): P1 at the cube's centre, P2..P5 on the plane's diagonals at
10 % of the diagonal's length from the corners C1, C2, C7, C8. Lengths in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.diagnostics.orientation import (
    ORIENTATION_AXES,
    orientation_deviations,
    register_flange_poses,
    rotation_vectors,
)
from robotcal.errors import InputError
from robotcal.instruments import Instrument
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.model import ParameterSet, RobotModel
from robotcal.limits import ISO_CYCLES

__all__ = [
    "ISO_CYCLES",
    "ORIENTATION_AXES",
    "Iso9283Result",
    "IsoModel",
    "IsoStudy",
    "default_iso_start",
    "iso_from_capture",
    "orientation_deviations",
    "pose_visits",
    "register_flange_poses",
    "rotation_vectors",
    "scenario_flange_point",
    "simulate_iso_study",
    "iso_cube_corners",
    "iso_cube_plan",
    "iso_test_positions",
    "iso_plan_readings",
    "pose_characteristics",
    "simulate_attained_positions",
]

_FRACTION = 0.1  # P2..P5 at 10 % of the diagonal from the corners


@dataclass(frozen=True, slots=True, kw_only=True)
class Iso9283Result:
    """ISO 9283 position characteristics of one model against measured repeated poses.

    Attributes
    ----------
    barycentre : ndarray, shape (n_test_poses, 3)
        Mean attained position of each pose [mm].
    commanded : ndarray, shape (n_test_poses, 3)
        Commanded position [mm].
    ap_xyz : ndarray, shape (n_test_poses, 3)
        ``APx, APy, APz`` [mm].
    ap : ndarray, shape (n_test_poses,)
        Position accuracy AP [mm].
    rp : ndarray, shape (n_test_poses,)
        Position repeatability ``RP = l_bar + 3 S_l`` [mm].
    l_bar, s_l : ndarray, shape (n_test_poses,)
        Mean and standard deviation of the distances to the barycentre [mm].
    distance_pair : tuple of int
        0-based poses of the distance characteristics.
    ad, rd : float
        Distance accuracy ``D_bar - D_c`` and repeatability ``3 S_D`` [mm].
    n_cycles : int
    orientation_axes : {"base", "flange"} or None
        Axes of the orientation deviations; None when the orientation was not measured (then the
        orientation fields are None).
    ap_abc : ndarray, shape (n_test_poses, 3), or None
        Orientation accuracy ``APa, APb, APc`` [rad].
    s_abc : ndarray, shape (n_test_poses, 3), or None
        Standard deviations ``S_a, S_b, S_c`` of the orientation deviations [rad].
    rp_abc : ndarray, shape (n_test_poses, 3), or None
        Orientation repeatability ``RPa = +-3 S_a`` (likewise b, c; the half-width) [rad].
    registration_rms : ndarray, shape (n_test_poses,), or None
        Largest RMS residual over the cycles of the targets' registration [mm] (None with one target).
    """

    barycentre: np.ndarray
    commanded: np.ndarray
    ap_xyz: np.ndarray
    ap: np.ndarray
    rp: np.ndarray
    l_bar: np.ndarray
    s_l: np.ndarray
    distance_pair: tuple[int, int]
    ad: float
    rd: float
    n_cycles: int
    orientation_axes: str | None = None
    ap_abc: np.ndarray | None = None
    s_abc: np.ndarray | None = None
    rp_abc: np.ndarray | None = None
    registration_rms: np.ndarray | None = None

    def __post_init__(self):
        for name in ("barycentre", "commanded", "ap_xyz", "ap", "rp", "l_bar", "s_l"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        for name in ("ap_abc", "s_abc", "rp_abc", "registration_rms"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _frozen(getattr(self, name)))

    @property
    def has_orientation(self) -> bool:
        """Whether the orientation characteristics were measured."""
        return self.ap_abc is not None


def pose_characteristics(
    attained: ArrayLike,
    commanded: ArrayLike,
    *,
    distance_pair: tuple[int, int] = (1, 3),
    attained_rotations: ArrayLike | None = None,
    commanded_rotations: ArrayLike | None = None,
    orientation_axes: str = "base",
    registration_rms: ArrayLike | None = None,
) -> Iso9283Result:
    """AP, RP, AD and RD of ISO 9283 (clauses 7.2.1, 7.2.2, 7.3.1, 7.3.2) from repeated poses, and
    APa/b/c, RPa/b/c when the orientations are given.

    Parameters
    ----------
    attained : array_like, shape (n_cycles, n_test_poses, 3)
        Attained positions, cycle-major [mm]; n_cycles >= 2.
    commanded : array_like, shape (n_test_poses, 3)
        Commanded positions [mm].
    distance_pair : tuple of int
        0-based test poses of the distance characteristics (default P2, P4).
    attained_rotations : array_like, shape (n_cycles, n_test_poses, 3, 3), optional
        Attained flange orientations (base_from_flange rotations).
    commanded_rotations : array_like, shape (n_test_poses, 3, 3), optional
        Commanded flange orientations; needed with ``attained_rotations``.
    orientation_axes : {"base", "flange"}
        Axes of the deviation angles (:func:`orientation_deviations`).
    registration_rms : array_like, shape (n_cycles, n_test_poses), optional
        RMS residual of each pose's target registration [mm]; the result keeps the largest per pose.

    Returns
    -------
    Iso9283Result
    """
    attained = np.asarray(attained, dtype=float)
    commanded = np.asarray(commanded, dtype=float)
    if attained.ndim != 3 or attained.shape[2] != 3 or attained.shape[0] < 2:
        raise InputError(f"`attained` must have shape (n_cycles >= 2, n_test_poses, 3); got {attained.shape}")
    if commanded.shape != attained.shape[1:]:
        raise InputError(f"`commanded` must have shape {attained.shape[1:]}; got {commanded.shape}")
    if not (np.all(np.isfinite(attained)) and np.all(np.isfinite(commanded))):
        raise InputError("`attained` and `commanded` must be finite")
    a, b = (int(k) for k in distance_pair)
    if not (0 <= a < attained.shape[1] and 0 <= b < attained.shape[1] and a != b):
        raise InputError(
            f"`distance_pair` must name two different poses of 0..{attained.shape[1] - 1}; got {distance_pair}"
        )
    n = attained.shape[0]
    barycentre = attained.mean(axis=0)
    ap_xyz = barycentre - commanded
    ap = np.linalg.norm(ap_xyz, axis=-1)
    spread = np.linalg.norm(attained - barycentre, axis=-1)  # (n_cycles, n_test_poses)
    l_bar = spread.mean(axis=0)
    s_l = np.sqrt(((spread - l_bar) ** 2).sum(axis=0) / (n - 1))
    distances = np.linalg.norm(attained[:, a] - attained[:, b], axis=-1)
    d_c = np.linalg.norm(commanded[a] - commanded[b])
    d_bar = distances.mean()
    rd = 3.0 * np.sqrt(((distances - d_bar) ** 2).sum() / (n - 1))
    orientation = {}
    if (attained_rotations is None) != (commanded_rotations is None):
        raise InputError("give both `attained_rotations` and `commanded_rotations`, or neither")
    if attained_rotations is not None:
        attained_rotations = np.asarray(attained_rotations, dtype=float)
        commanded_rotations = np.asarray(commanded_rotations, dtype=float)
        if attained_rotations.shape != attained.shape[:2] + (3, 3):
            raise InputError(
                f"`attained_rotations` must have shape {attained.shape[:2] + (3, 3)}; got {attained_rotations.shape}"
            )
        if commanded_rotations.shape != attained.shape[1:2] + (3, 3):
            raise InputError(
                f"`commanded_rotations` must have shape {attained.shape[1:2] + (3, 3)}; got {commanded_rotations.shape}"
            )
        deviations = orientation_deviations(attained_rotations, commanded_rotations, axes=orientation_axes)
        mean = deviations.mean(axis=0)
        s_abc = np.sqrt(((deviations - mean) ** 2).sum(axis=0) / (n - 1))
        orientation = {"orientation_axes": orientation_axes, "ap_abc": mean, "s_abc": s_abc, "rp_abc": 3.0 * s_abc}
        if registration_rms is not None:
            rms = np.asarray(registration_rms, dtype=float)
            if rms.shape != attained.shape[:2]:
                raise InputError(f"`registration_rms` must have shape {attained.shape[:2]}; got {rms.shape}")
            orientation["registration_rms"] = rms.max(axis=0)
    return Iso9283Result(
        barycentre=barycentre,
        commanded=commanded,
        ap_xyz=ap_xyz,
        ap=ap,
        rp=l_bar + 3.0 * s_l,
        l_bar=l_bar,
        s_l=s_l,
        distance_pair=(a, b),
        ad=float(d_bar - d_c),
        rd=float(rd),
        n_cycles=n,
        **orientation,
    )


def iso_cube_corners(center: ArrayLike, side: float) -> np.ndarray:
    """Corners ``C1, C2, C7, C8`` of the diagonal plane of the test cube, shape ``(4, 3)`` [mm].

    The cube has edges parallel to the base axes; the plane holds the edge ``y = z = -side/2``
    (C1 at -x, C2 at +x) and the opposite edge ``y = z = +side/2`` (C7 at +x, C8 at -x).
    """
    center = np.asarray(center, dtype=float)
    if center.shape != (3,) or not np.all(np.isfinite(center)):
        raise InputError(f"cube `center` must be three finite numbers [mm]; got shape {center.shape}")
    if not (np.isfinite(side) and side > 0):
        raise InputError(f"cube `side` must be > 0 [mm]; got {side}")
    h = side / 2.0
    return center + np.array([[-h, -h, -h], [h, -h, -h], [h, h, h], [-h, h, h]])


def iso_test_positions(center: ArrayLike, side: float) -> np.ndarray:
    """Test positions P1..P5, shape ``(5, 3)`` [mm]: the cube's centre and 10 % in from C1, C2, C7, C8."""
    corners = iso_cube_corners(center, side)
    center = np.asarray(center, dtype=float)
    # each corner's diagonal runs through the centre to the opposite corner: length 2 |corner - centre|
    inward = (center - corners) * (2.0 * _FRACTION)
    return np.vstack([center, corners + inward])


def iso_plan_readings(
    parameters: ParameterSet,
    positions: ArrayLike,
    start_readings: ArrayLike,
    *,
    target: ArrayLike = (0.0, 0.0, 0.0),
    n_cycles: int = ISO_CYCLES,
    tolerance_mm: float = 1e-9,
    max_iterations: int = 100,
) -> np.ndarray:
    """Controller readings that bring a flange point to each test position, repeated ``n_cycles`` times.

    The orientation of the flange is held at that of ``start_readings`` (ISO 9283 keeps one
    orientation for the pose test); the readings are found by Gauss-Newton (least-squares steps) on position and
    orientation, starting from ``start_readings`` for every pose.

    Parameters
    ----------
    parameters : ParameterSet
        The model the plan is computed with (the controller's: usually nominal).
    positions : array_like, shape (n_test_poses, 3)
        Test positions in the base frame [mm] (:func:`iso_test_positions`).
    start_readings : array_like, shape (n_joints,)
        Controller readings of the start configuration [rad].
    target : array_like, shape (3,)
        The point in the flange frame [mm].

    Returns
    -------
    ndarray, shape (n_cycles * n_test_poses, n_joints)
        Readings [rad], cycle-major: P1..P5 of cycle 1, then cycle 2, ...
    """
    robot = parameters.robot
    positions = np.asarray(positions, dtype=float)
    start = np.asarray(start_readings, dtype=float)
    target = np.asarray(target, dtype=float)
    if start.shape != (robot.n_joints,):
        raise InputError(f"`start_readings` must have {robot.n_joints} values; got shape {start.shape}")
    if n_cycles < 2:
        raise InputError(f"`n_cycles` must be >= 2; got {n_cycles}")

    def pose(readings):
        frame = forward_kinematics(parameters.values, parameters.model_joint_variables(readings))[0]
        return frame[:3, :3], frame[:3, :3] @ target + frame[:3, 3]

    goal_rotation, _ = pose(start)
    solutions = []
    for k, goal in enumerate(positions):
        r = start.copy()
        for _ in range(max_iterations):
            rotation, point = pose(r)
            skew = rotation @ goal_rotation.T - goal_rotation @ rotation.T
            error = np.r_[goal - point, -0.5 * np.array([skew[2, 1], skew[0, 2], skew[1, 0]]) * 1000.0]
            if np.linalg.norm(error[:3]) < tolerance_mm and np.linalg.norm(error[3:]) < tolerance_mm:
                break
            jac = np.empty((6, robot.n_joints))
            step = 1e-7
            for j in range(robot.n_joints):
                dr = np.zeros(robot.n_joints)
                dr[j] = step
                rot_p, pt_p = pose(r + dr)
                rot_m, pt_m = pose(r - dr)
                drot = (rot_p - rot_m) @ rotation.T / (2 * step)
                jac[:3, j] = (pt_p - pt_m) / (2 * step)
                jac[3:, j] = np.array([drot[2, 1], drot[0, 2], drot[1, 0]]) * 1000.0
            r = r + np.linalg.lstsq(jac, error, rcond=None)[0]
        else:
            raise InputError(
                f"ISO 9283 pose P{k + 1} at {np.round(goal, 3).tolist()} mm is not reachable from the start"
            )
        outside = np.flatnonzero((r < robot.limits[:, 0]) | (r > robot.limits[:, 1]))
        if outside.size:
            j = int(outside[0])
            raise InputError(
                f"ISO 9283 pose P{k + 1}: the readings reaching it put J{j + 1} at {np.rad2deg(r[j]):.3f} deg, outside "
                f"its limits [{np.rad2deg(robot.limits[j, 0]):.3f}, {np.rad2deg(robot.limits[j, 1]):.3f}] deg; "
                "choose another start pose or a smaller cube"
            )
        solutions.append(r)
    return np.tile(np.array(solutions), (n_cycles, 1))


def simulate_attained_positions(
    parameters: ParameterSet, readings: ArrayLike, *, target: ArrayLike = (0.0, 0.0, 0.0), joint_errors=None,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Attained positions of a flange point at controller ``readings`` with the joint error model [mm].

    Parameters
    ----------
    parameters : ParameterSet
        The "real" robot.
    readings : array_like, shape (n_points, n_joints)
        Controller readings [rad], in the order the robot visits them (the error model's random
        part is redrawn at each new reading, eq. 5-2).
    target : array_like, shape (3,)
        Point in the flange frame [mm].
    joint_errors : JointErrorModel, optional
    rng : numpy.random.Generator or int or None

    Returns
    -------
    ndarray, shape (n_points, 3)
        Positions in the base frame [mm].
    """
    from robotcal.kinematics.forward import target_positions
    from robotcal.kinematics.model import ReflectorMount

    rng = np.random.default_rng(rng)
    q = parameters.model_joint_variables(np.asarray(readings, dtype=float))
    errors = None if joint_errors is None else joint_errors.transforms(q, rng=rng)
    mount = ReflectorMount(frame="flange", positions=np.asarray(target, dtype=float))
    return target_positions(parameters.values, q, np.zeros(q.shape[0], dtype=int), mount, joint_errors=errors)


# --- from a capture ---------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, kw_only=True)
class IsoModel:
    """A model evaluated by the ISO 9283 test.

    Attributes
    ----------
    parameters : ParameterSet
        Gives the commanded poses (forward kinematics at the pose's readings).
    tracker_from_base : ndarray, shape (4, 4)
        Maps the measured points into this model's base frame.
    target_offsets : dict of str to array_like, optional
        Flange offsets [mm] of named targets for this model (e.g. a refinement's estimates); they take
        precedence over the offsets given to :func:`iso_from_capture`.
    """

    parameters: object
    tracker_from_base: np.ndarray
    target_offsets: dict | None = None


def pose_visits(capture: Capture, *, same_pose_rad: float = np.deg2rad(1e-3)) -> np.ndarray:
    """Visit index of every row of a multi-target capture (rows of the same pose form one visit).

    A new visit starts at a row whose target was already measured in the current visit, or whose
    readings differ from the visit's first row by more than ``same_pose_rad`` (any joint).
    """
    visits = np.empty(capture.n_points, dtype=int)
    current, first = -1, None
    seen: set[int] = set()
    for row in range(capture.n_points):
        target = int(capture.target[row]) if capture.target is not None else 0
        readings = capture.readings[row]
        if first is None or target in seen or np.max(np.abs(readings - first)) > same_pose_rad:
            current, seen, first = current + 1, set(), readings
        seen.add(target)
        visits[row] = current
    return visits


#: Largest difference of a joint reading [rad] between visits of one test pose (0.05 deg): repeated
#: visits of a commanded pose log readings within the servo error (~1e-3 deg); ISO 9283's test poses
#: lie degrees apart.
SAME_POSE_RAD = np.deg2rad(0.05)


def _check_iso_cycles(readings, n_test_poses: int, *, rows, source: str, same_pose_rad: float = SAME_POSE_RAD) -> int:
    """The number of cycles of visits that are ISO 9283 cycles, else an :class:`InputError` saying what was found.

    ISO 9283 (clause 7.2.1): ``n`` cycles, each visiting the test poses P1..Pm in the same order. The
    visits are grouped into distinct poses (readings within ``same_pose_rad`` on every joint are one
    pose); P_k is the pose most cycles visit k-th. Refused: a number of distinct poses other than m
    (e.g. unrepeated poses), pose-major order (each pose repeated before the next) and a cycle that
    visits the poses in another order (e.g. P1 and P2 swapped), naming the cycle and the data row.

    Parameters
    ----------
    readings : ndarray, shape (n_visits, n_joints)
        Readings of each visit, in the order measured [rad].
    n_test_poses : int
    rows : ndarray of int, shape (n_visits,)
        1-based data row of the capture where each visit starts (for the messages).
    source : str
    same_pose_rad : float
    """
    n_visits = readings.shape[0]
    n_cycles = n_visits // n_test_poses
    tolerance = f"readings within {np.rad2deg(same_pose_rad):g} deg on every joint count as one pose"
    representatives: list[np.ndarray] = []
    labels = np.empty(n_visits, dtype=int)
    for k, q in enumerate(readings):
        for label, first in enumerate(representatives):
            if np.max(np.abs(q - first)) <= same_pose_rad:
                labels[k] = label
                break
        else:
            labels[k] = len(representatives)
            representatives.append(q)
    found = len(representatives)
    if found > n_test_poses:
        repeated = n_visits - found
        raise InputError(
            f"{source}: not ISO 9283 cycles: {n_visits} pose visits hold {found} distinct poses ({repeated} repeated); "
            f"expected {n_cycles} cycles of the same {n_test_poses} test poses P1..P{n_test_poses} ({tolerance})"
        )
    steps = np.diff(labels)
    if n_test_poses > 1 and np.all(steps >= 0):  # P1 P1 ... P2 P2 ...: every pose repeated before the next
        k = int(np.flatnonzero(steps == 0)[0])
        raise InputError(
            f"{source}: not ISO 9283 cycles: the poses are in pose-major order (data rows {rows[k]} and {rows[k + 1]} "
            f"visit the same pose); ISO 9283 cycles visit P1..P{n_test_poses} in turn, cycle after cycle: reorder the "
            "rows cycle-major"
        )
    if found < n_test_poses:
        raise InputError(
            f"{source}: not ISO 9283 cycles: {n_visits} pose visits hold only {found} distinct poses; expected "
            f"{n_test_poses} test poses P1..P{n_test_poses} in each of {n_cycles} cycles ({tolerance})"
        )
    by_cycle = labels.reshape(n_cycles, n_test_poses)
    expected = np.array([np.bincount(column, minlength=found).argmax() for column in by_cycle.T])
    if np.unique(expected).size != n_test_poses:  # no order that most cycles follow
        first_cycle = " ".join(f"P{np.flatnonzero(expected == v)[0] + 1}" for v in by_cycle[0])
        raise InputError(
            f"{source}: not ISO 9283 cycles: the cycles visit the {n_test_poses} poses in no common order "
            f"(cycle 1: {first_cycle}); each cycle must visit P1..P{n_test_poses} in the same order"
        )
    name = {int(v): k + 1 for k, v in enumerate(expected)}
    for cycle, visited in enumerate(by_cycle):
        wrong = np.flatnonzero(visited != expected)
        if wrong.size:
            k = int(wrong[0])
            order = ", ".join(f"P{name[int(v)]}" for v in visited)
            raise InputError(
                f"{source}: not ISO 9283 cycles: cycle {cycle + 1} (data row {rows[cycle * n_test_poses + k]}) visits "
                f"P{name[int(visited[k])]} where P{k + 1} belongs (its order: {order}); every cycle must visit "
                f"P1..P{n_test_poses} in the order of the other cycles"
            )
    return n_cycles


def _visits_of_targets(capture, free: np.ndarray, names: tuple) -> tuple[np.ndarray, np.ndarray]:
    """The rows of every pose visit of a capture with several targets per pose, ``(n_visits, n_targets)`` with the
    targets in name-index order, and each visit's first data row (1-based, for messages)."""
    visits = pose_visits(capture)
    n_visits = int(visits[-1]) + 1
    order = np.lexsort((capture.target, visits))  # rows grouped by visit, targets in name-index order
    counts = np.bincount(visits, minlength=n_visits)
    if np.any(counts != len(names)):
        bad = int(np.flatnonzero(counts != len(names))[0])
        row = int(np.flatnonzero(visits == bad)[0]) + 1
        raise InputError(
            f"{capture.source}: pose visit {bad + 1} (free row {row}) measured {counts[bad]} of the {len(names)} "
            f"targets {', '.join(names)}; every visit must measure every target (three or more for the orientation)"
        )
    if len(names) < 3:
        raise InputError(
            f"{capture.source}: {len(names)} targets per pose ({', '.join(names)}): the orientation needs three or "
            "more; keep the rows of one target for positions only"
        )
    visit_rows = free[np.array([np.flatnonzero(visits == v)[0] for v in range(n_visits)])] + 1
    return order.reshape(n_visits, len(names)), visit_rows


def _target_offsets(model: IsoModel, label: str, target_names, targets: dict | None, source: str) -> np.ndarray:
    """The flange offsets ``(n_targets, 3)`` [mm] of ``target_names``: the model's own, else those given."""
    own = model.target_offsets or {}
    rows = []
    for name in target_names:
        offsets = own if name in own else (targets or {})
        if name not in offsets:
            raise InputError(
                f"{source}: model {label!r} has no flange offset for target {name!r} (its parameter "
                "set did not estimate it and the scenario does not give it): declare it in the scenario's "
                "[[targets]] (known), give --targets-mm, or leave the nominal model out with --no-nominal"
            )
        rows.append(np.asarray(offsets[name], dtype=float).reshape(3))
    return np.array(rows)


def iso_from_capture(
    capture: Capture,
    models: dict,
    *,
    point: ArrayLike | None = None,
    targets: dict | None = None,
    n_test_poses: int = 5,
    distance_pair: tuple[int, int] = (1, 3),
    orientation_axes: str = "base",
) -> dict:
    """ISO 9283 characteristics of every model on a capture of repeated test poses (``circle = 0`` rows).

    The visits must be ISO 9283 cycles: ``n`` cycles visiting the same test poses P1..Pm in the same
    order (:func:`_check_iso_cycles`; pose-major order, unrepeated poses or a cycle in another order
    are an :class:`InputError` naming the cycle and data row).

    Without a ``target`` column (or with one target name) each row is one visit of a test pose,
    cycle-major, and the measured point is the flange ``point`` (the named target's offset with one
    target name). With three or more targets per pose, consecutive rows of one pose
    (:func:`pose_visits`) are registered onto the targets' offsets (:func:`register_flange_poses`):
    the attained flange pose gives the attained orientation and the attained position of ``point``
    (default: the centroid of the targets' offsets).

    Parameters
    ----------
    capture : Capture
    models : dict of str to IsoModel
    point : array_like, shape (3,), optional
        Flange point whose position is evaluated [mm]; required with a single unnamed target.
    targets : dict of str to array_like, optional
        Flange offsets [mm] of the capture's target names (a model's ``target_offsets`` take precedence).
    n_test_poses : int
    distance_pair : tuple of int
    orientation_axes : {"base", "flange"}

    Returns
    -------
    dict of str to Iso9283Result
    """
    from robotcal.geometry.transforms import apply_transform, invert_transform

    free = np.flatnonzero(capture.circle == 0)
    if not free.size:
        raise InputError(f"{capture.source}: the capture has no free poses (rows with circle = 0)")
    capture = capture.select(free)
    names = () if capture.target is None else tuple(capture.target_names[k] for k in np.unique(capture.target))
    multi = len(names) > 1
    if multi:
        row_of_visit, visit_rows = _visits_of_targets(capture, free, names)
        n_visits = row_of_visit.shape[0]
        visit_readings = capture.readings[row_of_visit[:, 0]]
    else:
        n_visits = capture.n_points
        visit_readings = capture.readings
        visit_rows = free + 1
    if n_visits % n_test_poses or n_visits < 2 * n_test_poses:
        raise InputError(
            f"{capture.source}: the capture's {n_visits} free poses are not whole cycles of {n_test_poses} test poses "
            "(at least 2 cycles, cycle-major)"
        )
    n_cycles = _check_iso_cycles(visit_readings, n_test_poses, rows=visit_rows, source=capture.source)
    commands = visit_readings.reshape(n_cycles, n_test_poses, -1).mean(axis=0)
    target_names = list(names)  # the capture's target names in name-index order

    def offsets_of(model: IsoModel, label: str) -> np.ndarray:
        return _target_offsets(model, label, target_names, targets, capture.source)

    results = {}
    for label, model in models.items():
        parameters = model.parameters
        base_from_tracker = invert_transform(np.asarray(model.tracker_from_base, dtype=float))
        frames = forward_kinematics(parameters.values, parameters.model_joint_variables(commands))
        if multi:
            offsets = offsets_of(model, label)
            flange_point = offsets.mean(axis=0) if point is None else np.asarray(point, dtype=float)
            measured = apply_transform(base_from_tracker, capture.points[row_of_visit])
            attained_frames, rms = register_flange_poses(offsets, measured)
            attained = apply_transform(attained_frames, flange_point)
            results[label] = pose_characteristics(
                attained.reshape(n_cycles, n_test_poses, 3),
                apply_transform(frames, flange_point),
                distance_pair=distance_pair,
                attained_rotations=attained_frames[:, :3, :3].reshape(n_cycles, n_test_poses, 3, 3),
                commanded_rotations=frames[:, :3, :3],
                orientation_axes=orientation_axes,
                registration_rms=rms.reshape(n_cycles, n_test_poses),
            )
            continue
        if names:
            flange_point = offsets_of(model, label)[0]
        elif point is None:
            raise InputError(f"{capture.source}: which flange point was measured? give its offset")
        else:
            flange_point = np.asarray(point, dtype=float)
        attained = apply_transform(base_from_tracker, capture.points).reshape(n_cycles, n_test_poses, 3)
        commanded = apply_transform(frames, flange_point)
        results[label] = pose_characteristics(attained, commanded, distance_pair=distance_pair)
    return results


# --- simulated study --------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, kw_only=True)
class IsoStudy:
    """A simulated ISO 9283 pose test (:func:`simulate_iso_study`).

    Attributes
    ----------
    results : dict of str to Iso9283Result
        Per model, in the order given.
    center_mm : ndarray, shape (3,)
        Cube centre in the base frame [mm].
    side_mm : float
        Cube side [mm].
    start_readings : ndarray, shape (n_joints,)
        Start readings [rad] (they set the flange orientation of the test).
    readings : ndarray, shape (n_test_poses, n_joints)
        Commanded readings of P1..P5 [rad] (nominal model).
    point_mm : ndarray, shape (3,)
        Flange point whose position is evaluated [mm].
    targets_mm : dict of str to ndarray
        The measured flange targets [mm].
    capture : Capture
        The simulated measurement (tracker frame).
    """

    results: dict
    center_mm: np.ndarray
    side_mm: float
    start_readings: np.ndarray
    readings: np.ndarray
    point_mm: np.ndarray
    targets_mm: dict
    capture: object


def _reach_mm(robot, point) -> float:
    """Length of the chain from joint 2 to the flange point: sum of ``sqrt(a^2 + d^2)`` of links 2..n plus |point|."""
    nominal = robot.nominal
    links = np.hypot(nominal[1:, 0], nominal[1:, 2]).sum()
    return float(links + np.linalg.norm(point))


def default_iso_start(parameters: ParameterSet, point: ArrayLike) -> np.ndarray:
    """Start readings of the default cube [rad]: of the readings ``lower + f (upper - lower)``, f in
    {0.25, 0.5, 0.75} for every joint, the one with the largest ``|det J|`` (J: the 6 x n Jacobian of
    the flange point's position [mm] and the flange orientation [rad x reach]), i.e. the best
    conditioned configuration of that grid; ties go to the first (joint 1 slowest)."""
    import itertools

    robot = parameters.robot
    point = np.asarray(point, dtype=float)
    lower, upper = robot.limits[:, 0], robot.limits[:, 1]
    fractions = np.array(list(itertools.product((0.25, 0.5, 0.75), repeat=robot.n_joints)))
    candidates = lower + fractions * (upper - lower)
    reach = _reach_mm(robot, point)
    step = 1e-6

    def pose(readings):
        frames = forward_kinematics(parameters.values, parameters.model_joint_variables(readings))
        return frames[:, :3, :3], frames[:, :3, :3] @ point + frames[:, :3, 3]

    rotation, _ = pose(candidates)
    jacobian = np.empty((candidates.shape[0], 6, robot.n_joints))
    for j in range(robot.n_joints):
        delta = np.zeros(robot.n_joints)
        delta[j] = step
        rot_p, pt_p = pose(candidates + delta)
        rot_m, pt_m = pose(candidates - delta)
        drot = (rot_p - rot_m) @ np.swapaxes(rotation, -1, -2) / (2 * step)
        jacobian[:, :3, j] = (pt_p - pt_m) / (2 * step)
        jacobian[:, 3:, j] = np.stack([drot[:, 2, 1], drot[:, 0, 2], drot[:, 1, 0]], axis=-1) * reach
    measure = np.sqrt(np.abs(np.linalg.det(jacobian @ np.swapaxes(jacobian, -1, -2))))
    return candidates[int(np.argmax(measure))]


def scenario_flange_point(scenario) -> np.ndarray:
    """The scenario's measured flange point [mm]: its ``[capture]`` flange reflector, else its
    ``[validation]`` flange target, else its only known ``[[targets]]`` flange target."""
    if scenario.reflector is not None and scenario.reflector.frame == "flange":
        return np.asarray(scenario.reflector.positions[0], dtype=float)
    known = [t for t in scenario.targets if t.frame == "flange" and t.known]
    for target in known:
        if target.name == "validation":
            return np.asarray(target.positions, dtype=float)
    if len(known) == 1:
        return np.asarray(known[0].positions, dtype=float)
    raise InputError(
        f"scenario {scenario.name!r} declares no flange target ([validation] flange_reflector_mm); give --target x,y,z"
    )


def iso_cube_plan(
    parameters: ParameterSet, point: ArrayLike, *, start_readings: ArrayLike | None = None,
    center_mm: ArrayLike | None = None, side_mm: float | None = None, n_cycles: int = ISO_CYCLES,
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """The test cube and its plan, with the default rule for what is not given (docs/iso9283.md).

    Start readings: :func:`default_iso_start`; centre: the flange ``point`` at the start readings;
    side: 20 % of the reach (links 2..n, ``sqrt(a^2 + d^2)`` each, plus ``|point|``), rounded down to
    1 mm and halved (up to four times) until P1..P5 are reachable within the joint limits. A given
    side is not shrunk.

    Parameters
    ----------
    parameters : ParameterSet
        The controller's model (nominal).
    point : array_like, shape (3,)
        Flange point placed on P1..P5 [mm].
    start_readings : array_like, shape (n_joints,), optional
        [rad]
    center_mm : array_like, shape (3,), optional
    side_mm : float, optional
    n_cycles : int

    Returns
    -------
    start_readings : ndarray, shape (n_joints,) [rad]
    center_mm : ndarray, shape (3,)
    side_mm : float
    readings : ndarray, shape (n_cycles * 5, n_joints)
        :func:`iso_plan_readings` [rad].
    """
    robot = parameters.robot
    point = np.asarray(point, dtype=float)
    start = default_iso_start(parameters, point) if start_readings is None else np.asarray(start_readings, float)
    if center_mm is None:
        frame = forward_kinematics(parameters.values, parameters.model_joint_variables(start))[0]
        center = frame[:3, :3] @ point + frame[:3, 3]
    else:
        center = np.asarray(center_mm, dtype=float)
    if side_mm is not None:
        sides = [float(side_mm)]
    else:
        sides = [math.floor(0.2 * _reach_mm(robot, point)) / 2**k for k in range(5)]
    for k, side in enumerate(sides):
        try:
            positions = iso_test_positions(center, side)
            readings = iso_plan_readings(parameters, positions, start, target=point, n_cycles=n_cycles)
            return start, center, side, readings
        except InputError:
            if k == len(sides) - 1:
                raise
    raise AssertionError("unreachable")  # pragma: no cover


def simulate_iso_study(
    robot: RobotModel,
    parameter_sets: dict,
    *,
    targets_mm: dict,
    true_parameters: ParameterSet | None = None,
    tracker_from_base: ArrayLike | None = None,
    joint_errors=None,
    instrument: Instrument | None = None,
    cycles: int = ISO_CYCLES,
    seed: int | None = None,
    center_mm: ArrayLike | None = None,
    side_mm: float | None = None,
    start_deg: ArrayLike | None = None,
    orientation_axes: str = "base",
) -> IsoStudy:
    """A simulated ISO 9283 pose test of a true robot, evaluated with several models.

    The plan (:func:`iso_plan_readings`, nominal model: the controller's) visits P1..P5 of the cube
    ``cycles`` times; the true robot (``true_parameters``, else nominal) with the joint error model (eq. 5-2
    and backlash, redrawn at each visit) attains the flange poses (after one unmeasured warm-up cycle, so that
    the backlash state of every measured visit is that of the cycle); the instrument measures every flange
    target in the tracker frame with its noise; :func:`iso_from_capture` evaluates every model.

    Default cube: :func:`iso_cube_plan` (``start_deg``, ``center_mm``, ``side_mm`` override it).

    Parameters
    ----------
    robot : RobotModel
    parameter_sets : dict of str to ParameterSet or IsoModel
        Models to evaluate (e.g. ``{"nominal": ..., "cpa": ..., "refined": ...}``); a ParameterSet is
        evaluated in the base frame ``tracker_from_base``.
    targets_mm : dict of str to array_like
        Flange targets measured at each pose [mm] (three or more: the orientation is measured too).
    true_parameters : ParameterSet, optional
    tracker_from_base : array_like, shape (4, 4), optional
        Default identity.
    joint_errors : JointErrorModel, optional
        None: no joint errors.
    instrument : Instrument, optional
        None: exact measurement.
    cycles : int
    seed : int, optional
        Seeds the joint errors' random part and the instrument noise (one generator).
    center_mm, side_mm, start_deg : optional
        Cube centre [mm], side [mm] and start readings [deg].
    orientation_axes : {"base", "flange"}

    Returns
    -------
    IsoStudy
    """
    from robotcal.capture import Capture
    from robotcal.geometry.transforms import apply_transform
    from robotcal.kinematics.forward import joint_frames
    from robotcal.kinematics.model import ParameterSet

    nominal = ParameterSet.nominal(robot)
    if true_parameters is None:
        true_parameters = nominal
    tracker_from_base = np.eye(4) if tracker_from_base is None else np.asarray(tracker_from_base, dtype=float)
    targets_mm = {str(name): np.asarray(value, dtype=float).reshape(3) for name, value in targets_mm.items()}
    offsets = np.array(list(targets_mm.values()))
    point = offsets.mean(axis=0)
    start = None if start_deg is None else np.deg2rad(np.asarray(start_deg, dtype=float))
    start, center, side, readings = iso_cube_plan(
        nominal, point, start_readings=start, center_mm=center_mm, side_mm=side_mm, n_cycles=cycles
    )
    rng = np.random.default_rng(seed)
    # one unmeasured cycle first, so that every measured visit has the same motion history (backlash)
    visits = np.vstack([readings[:5], readings])
    q = true_parameters.model_joint_variables(visits)
    # the joint errors and lash states follow the commanded motion (see simulate_capture)
    errors = None if joint_errors is None else joint_errors.transforms(robot.model_joint_variables(visits), rng=rng)[5:]
    flange = joint_frames(true_parameters.values, q[5:], joint_errors=errors)[:, -1]
    base_points = np.einsum("vij,tj->vti", flange[:, :3, :3], offsets) + flange[:, None, :3, 3]
    tracker_points = apply_transform(tracker_from_base, base_points.reshape(-1, 3))
    if instrument is not None and not instrument.is_noise_free:
        tracker_points = tracker_points + instrument.sample_noise(tracker_points, rng=rng)
    n_targets, n_rows = offsets.shape[0], tracker_points.shape[0]
    capture = Capture(
        circle=np.zeros(n_rows, dtype=int),
        direction=np.ones(n_rows, dtype=int),
        readings=np.repeat(readings, n_targets, axis=0),
        points=tracker_points,
        source="ISO 9283 study (simulated)",
        seed=seed,
        target=np.tile(np.arange(n_targets), readings.shape[0]),
        target_names=tuple(targets_mm),
    )
    models = {
        label: value
        if isinstance(value, IsoModel)
        else IsoModel(parameters=value, tracker_from_base=tracker_from_base)
        for label, value in parameter_sets.items()
    }
    results = iso_from_capture(
        capture, models, point=point, targets=targets_mm, n_test_poses=5, orientation_axes=orientation_axes
    )
    return IsoStudy(
        results=results,
        center_mm=_frozen(center),
        side_mm=float(side),
        start_readings=_frozen(start),
        readings=_frozen(readings[:5]),
        point_mm=_frozen(point),
        targets_mm=targets_mm,
        capture=capture,
    )
