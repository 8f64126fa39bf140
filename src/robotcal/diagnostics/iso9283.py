"""ISO 9283 position accuracy and repeatability: test poses P1..P5, AP, RP, AD, RD (docs/iso9283.md).

Definitions (ISO 9283:1998, clauses 7.2.1, 7.2.2, 7.3.1, 7.3.2), positions only, ``n`` cycles
visiting the test poses in order:

* Pose accuracy of pose k: barycentre ``x_bar = (1/n) sum_j x_j`` of the attained positions,
  ``APx = x_bar - x_c`` (likewise y, z) and ``AP = sqrt(APx^2 + APy^2 + APz^2)``, with ``x_c`` the
  commanded position.
* Pose repeatability: ``l_j = |x_j - x_bar|``, ``l_bar = (1/n) sum_j l_j``,
  ``S_l = sqrt(sum_j (l_j - l_bar)^2 / (n - 1))``, ``RP = l_bar + 3 S_l``.
* Distance accuracy between two poses (P2 and P4 by default): attained distances
  ``D_j = |x_{a,j} - x_{b,j}|``, commanded ``D_c = |x_{a,c} - x_{b,c}|``, ``AD = D_bar - D_c``;
  distance repeatability ``RD = 3 sqrt(sum_j (D_j - D_bar)^2 / (n - 1))``.

The standard's test poses lie on the diagonal plane ``C1-C2-C7-C8`` of a cube in the workspace
(edges parallel to the base axes): P1 at the cube's centre, P2..P5 on the plane's diagonals at
10 % of the diagonal's length from the corners C1, C2, C7, C8. Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.errors import InputError
from robotcal.kinematics.forward import forward_kinematics

__all__ = [
    "ISO_CYCLES",
    "Iso9283Result",
    "iso_cube_corners",
    "iso_test_positions",
    "iso_plan_readings",
    "pose_characteristics",
    "simulate_attained_positions",
]

#: Cycles of the standard's pose test.
ISO_CYCLES = 30
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

    def __post_init__(self):
        for name in ("barycentre", "commanded", "ap_xyz", "ap", "rp", "l_bar", "s_l"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))


def pose_characteristics(attained, commanded, *, distance_pair=(1, 3)) -> Iso9283Result:
    """AP, RP, AD and RD of ISO 9283 (clauses 7.2.1, 7.2.2, 7.3.1, 7.3.2) from repeated poses.

    Parameters
    ----------
    attained : array_like, shape (n_cycles, n_test_poses, 3)
        Attained positions, cycle-major [mm]; n_cycles >= 2.
    commanded : array_like, shape (n_test_poses, 3)
        Commanded positions [mm].
    distance_pair : tuple of int
        0-based test poses of the distance characteristics (default P2, P4).

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
    )


def iso_cube_corners(center, side: float) -> np.ndarray:
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


def iso_test_positions(center, side: float) -> np.ndarray:
    """Test positions P1..P5, shape ``(5, 3)`` [mm]: the cube's centre and 10 % in from C1, C2, C7, C8."""
    corners = iso_cube_corners(center, side)
    center = np.asarray(center, dtype=float)
    # each corner's diagonal runs through the centre to the opposite corner: length 2 |corner - centre|
    inward = (center - corners) * (2.0 * _FRACTION)
    return np.vstack([center, corners + inward])


def iso_plan_readings(
    parameters,
    positions,
    start_readings,
    *,
    target=(0.0, 0.0, 0.0),
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
        frame = forward_kinematics(parameters.values, robot.model_joint_variables(readings))[0]
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


def simulate_attained_positions(parameters, readings, *, target=(0.0, 0.0, 0.0), joint_errors=None, rng=None):
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
    robot = parameters.robot
    q = robot.model_joint_variables(np.asarray(readings, dtype=float))
    errors = None if joint_errors is None else joint_errors.transforms(q, rng=rng)
    mount = ReflectorMount(frame="flange", positions=np.asarray(target, dtype=float))
    return target_positions(parameters.values, q, np.zeros(q.shape[0], dtype=int), mount, joint_errors=errors)
