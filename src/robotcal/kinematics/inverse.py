"""Inverse kinematics: every solution of a tool pose, in closed form on the nominal geometry, then on any calibrated
model by Newton's method from each (issue 28; thesis ch. 6.2, compensation).

Two families of 6R arms have a closed form, and robotcal recognises them from the robot file's nominal geometry
(:func:`arm_family`), whatever their reading signs, offsets and couplings:

``"spherical-wrist"`` (KUKA, ABB, Fanuc and most industrial arms)
    J2 parallel to J3, and the axes of J4, J5, J6 meeting in one point, the wrist centre ``w``. ``w`` is fixed in
    the flange frame, so the target gives it; it is also fixed in link 3, and since J2 and J3 turn about axes
    parallel to ``z1`` its component along ``z1`` is a constant ``h``. With ``A_i = Rz(phi_i) C_i``
    (``phi_i = theta_i + q_i``, ``C_i = Tz(d) Tx(a) Rx(alpha) Ry(beta)``, eq. 3-84):

    1. J1: ``z1(phi_1) . w = h + z1 . o1`` is ``A cos phi_1 + B sin phi_1 = c``: two roots (the *shoulder*).
    2. J2, J3: in frame 1, ``w`` is a planar two-link point, ``w_1 = Rz(phi_2) (t_2 + Rz(phi_3) v)``; the law of
       cosines gives two roots of ``phi_3`` (the *elbow*) and then ``phi_2``.
    3. J4, J5, J6: ``R_36 = R_03^T R_06`` is ``Rz(phi_4) C_4 Rz(phi_5) C_5 Rz(phi_6) C_6``; the axis of J6 in frame
       3 gives ``phi_5`` (two roots: the *wrist*), then ``phi_4`` and ``phi_6``.

``"parallel-wrist"`` (Universal Robots and their clones)
    J2, J3, J4 parallel, ``a4 = a5 = 0``. Frame 5's origin is on J6's axis (fixed in the flange frame) and rigid in
    link 4, so its component along ``z1`` is constant: the same equation gives J1 (*shoulder*). The direction of
    ``z1`` seen from the flange depends on J5 and J6 alone: ``z1 . z5`` gives J5 (*wrist*), ``z1`` in frame 6 gives
    J6. Frame 4's origin is then a planar two-link point in frame 1: J3 (*elbow*), J2, and J4 from ``R_14``.

Each family has 2 x 2 x 2 = 8 *branches*, numbered ``4 shoulder + 2 elbow + wrist`` (:data:`BRANCH_NAMES`). At a
singularity (the wrist centre on J1's axis, J4 and J6 aligned) the free angle is taken from ``reference``. A
branch's readings are the controller readings of its model variables (:meth:`RobotModel.readings_from_model`),
each shifted by whole turns to lie nearest ``reference`` (inside the limits where a turn allows it).

A calibrated :class:`ParameterSet` is solved by Newton's method (:func:`solve_pose`)
from every nominal branch solution of the same pose: the calibrated model differs from the nominal by fractions of
a millimetre, so each nominal branch leads to the calibrated solution of the same branch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.kinematics.forward import forward_kinematics, joint_frames, link_transforms
from robotcal.kinematics.model import ParameterSet, RobotModel

__all__ = [
    "Solved",
    "rotation_vector",
    "solve_pose",
    "tool_frames",
    "as_tool_frame",
    "BRANCH_NAMES",
    "FAMILIES",
    "InverseSolutions",
    "arm_family",
    "branch_of",
    "inverse_kinematics",
    "nominal_solutions",
    "within_limits",
    "wrap_readings",
    "wrist_centre_in_flange",
    "robot_size",
    "check_targets",
]

FAMILIES = ("spherical-wrist", "parallel-wrist")
#: Branch ``k``: bit 2 the shoulder root, bit 1 the elbow root, bit 0 the wrist root of the closed form.
BRANCH_NAMES = tuple(
    f"shoulder {'AB'[k >> 2 & 1]}, elbow {'AB'[k >> 1 & 1]}, wrist {'AB'[k & 1]}" for k in range(8)
)
_STRUCTURE_TOLERANCE = 1e-9  # [mm, rad]: how exactly the nominal geometry must have the family's structure
_ROOT_SLACK = 1e-9  # a cosine this far beyond +-1 is the double root at the boundary, not "no solution"


@dataclass(frozen=True, slots=True)
class _Structure:
    family: str
    constants: np.ndarray  # C_i (n, 4, 4): the link transforms at phi_i = 0
    point_in_flange: np.ndarray  # (4,) the wrist centre (spherical) or frame 5's origin (parallel), flange frame
    point_along_z1: float  # its constant component along z1, in frame 1
    planar_point: np.ndarray  # (3,) the planar two-link point in frame 2 before Rz(phi_3): C_3 w_3 or C_3 t_4


def _constants(values: np.ndarray) -> np.ndarray:
    at_zero = values.copy()
    at_zero[:, 1] = 0.0
    return link_transforms(at_zero, np.zeros((1, values.shape[0])))[0]


def _invert(frame: np.ndarray) -> np.ndarray:
    out = np.zeros_like(frame)
    rotation = np.swapaxes(frame[..., :3, :3], -1, -2)
    out[..., :3, :3] = rotation
    out[..., :3, 3] = -(rotation @ frame[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def _chain_frames(values: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``base_from_link_i`` for i = 0..n, ``(P, n + 1, 4, 4)``."""
    links = link_transforms(values, q)
    frames = [np.broadcast_to(np.eye(4), links.shape[:-3] + (4, 4))]
    for i in range(links.shape[-3]):
        frames.append(frames[-1] @ links[..., i, :, :])
    return np.stack(frames, axis=-3)


def _meeting_point(frames: np.ndarray) -> np.ndarray | None:
    """The point where the z axes of frames 3, 4, 5 (the axes of J4, J5, J6) meet, per probe pose, or None."""
    points = []
    for pose in frames:
        lines = [(pose[k, :3, 3], pose[k, :3, 2]) for k in (3, 4, 5)]
        projectors = [np.eye(3) - np.outer(direction, direction) for _, direction in lines]
        normal = sum(projectors)
        if np.linalg.cond(normal) > 1e8:
            return None
        point = np.linalg.solve(normal, sum(p @ origin for p, (origin, _) in zip(projectors, lines, strict=True)))
        if max(np.linalg.norm(p @ (point - origin)) for p, (origin, _) in zip(projectors, lines, strict=True)) > 1e-6:
            return None
        points.append(point)
    return np.array(points)


_STRUCTURES: dict[tuple, _Structure] = {}


def _structure(robot: RobotModel) -> _Structure:
    """The closed form's constants of ``robot``'s nominal geometry (computed once per geometry)."""
    key = (robot.name, robot.nominal.tobytes())
    if key not in _STRUCTURES:
        _STRUCTURES[key] = _find_structure(robot)
    return _STRUCTURES[key]


def _find_structure(robot: RobotModel) -> _Structure:
    """The closed form's constants of ``robot``'s nominal geometry, or InputError naming what is missing."""
    if robot.n_joints != 6:
        raise InputError(
            f"robot {robot.name!r}: robotcal's closed-form inverse kinematics needs 6 joints; it has {robot.n_joints}"
        )
    values = np.asarray(robot.nominal, dtype=float)
    constants = _constants(values)
    z = np.array([0.0, 0.0, 1.0])
    parallel = [bool(np.linalg.norm(constants[i, :3, :3] @ z - z) < _STRUCTURE_TOLERANCE) for i in range(6)]
    if not parallel[1]:
        raise InputError(
            f"robot {robot.name!r}: J2's axis is not parallel to J3's in the nominal geometry; robotcal's closed-form "
            "inverse kinematics covers arms with J2 parallel to J3 and a spherical wrist, or J2, J3, J4 parallel (UR type)"
        )
    probe = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(4, 6))
    frames = _chain_frames(values, probe)
    to_frame1 = _invert(frames[:, 1])
    meeting = _meeting_point(frames)
    if meeting is not None:
        homogeneous = np.c_[meeting, np.ones(len(meeting))][..., None]
        in_flange = (_invert(frames[:, 6]) @ homogeneous)[..., 0]
        in_link3 = (_invert(frames[:, 3]) @ homogeneous)[..., 0]
        if max(np.ptp(in_flange, axis=0).max(), np.ptp(in_link3, axis=0).max()) < 1e-6:
            along = float((to_frame1[0] @ homogeneous[0])[2, 0])
            return _Structure("spherical-wrist", constants, in_flange[0], along, (constants[2] @ in_link3[0])[:3])
    if parallel[2] and np.linalg.norm(constants[3, :2, 3]) < _STRUCTURE_TOLERANCE and (
        np.linalg.norm(constants[4, :2, 3]) < _STRUCTURE_TOLERANCE
    ):
        in_flange = _invert(constants[5]) @ np.r_[0.0, 0.0, 0.0, 1.0]
        along = float((to_frame1[0] @ frames[0, 5][:, 3])[2])
        return _Structure("parallel-wrist", constants, in_flange, along, (constants[2] @ constants[3][:, 3])[:3])
    raise InputError(
        f"robot {robot.name!r}: neither a spherical wrist (J4, J5, J6 meeting in a point) nor a UR-type arm (J2, J3, J4 "
        "parallel, a4 = a5 = 0) in the nominal geometry; robotcal has no closed-form inverse kinematics for it"
    )


def wrist_centre_in_flange(robot: RobotModel) -> np.ndarray:
    """The wrist centre (where the axes of J4, J5, J6 meet) in the flange frame, homogeneous ``(4,)`` [mm], of a
    spherical-wrist arm's nominal geometry (InputError for any other arm)."""
    structure = _structure(robot)
    if structure.family != "spherical-wrist":
        raise InputError(f"robot {robot.name!r} has no spherical wrist (its axes J4, J5, J6 do not meet)")
    return structure.point_in_flange


def arm_family(robot: RobotModel) -> str:
    """``"spherical-wrist"`` or ``"parallel-wrist"``: which closed form solves ``robot`` (InputError if neither)."""
    return _structure(robot).family


def _cos_sin_roots(a, b, c):
    """The two roots of ``a cos phi + b sin phi = c`` (``delta + acos``, ``delta - acos``), ``(..., 2)``; a mask of
    where they exist, and one where ``hypot(a, b)`` vanishes (any phi, or none: the angle is free)."""
    radius = np.hypot(a, b)
    free = radius < 1e-9
    ratio = np.where(free, 0.0, c / np.where(free, 1.0, radius))
    exists = np.where(free, np.abs(c) < 1e-6, np.abs(ratio) <= 1.0 + _ROOT_SLACK)
    half = np.arccos(np.clip(ratio, -1.0, 1.0))
    delta = np.arctan2(b, a)
    return np.stack([delta + half, delta - half], axis=-1), exists, free


def _rz(angle) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(np.shape(angle) + (4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    out[..., 2, 2] = out[..., 3, 3] = 1.0
    return out


def _rotate_z(angle, vector) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * vector[..., 0] - s * vector[..., 1], s * vector[..., 0] + c * vector[..., 1], vector[..., 2]], -1)


def _first_joint(structure: _Structure, point: np.ndarray, reference: np.ndarray):
    """Roots of phi_1 ``(P, 2)`` at which ``point`` ``(P, 3)`` (base frame) has its constant component along z1."""
    c1 = structure.constants[0]
    u = c1[:3, :3] @ np.array([0.0, 0.0, 1.0])  # z1 at phi_1 = 0
    a = point[:, 0] * u[0] + point[:, 1] * u[1]
    b = point[:, 1] * u[0] - point[:, 0] * u[1]
    c = structure.point_along_z1 + float(u @ c1[:3, 3]) - point[:, 2] * u[2]
    roots, exists, free = _cos_sin_roots(a, b, c)
    # on J1's axis (and at the height the arm can put it there): phi_1 is free, taken from the reference
    return np.where(free[:, None], reference[:, None], roots), exists


def _planar(structure: _Structure, local: np.ndarray):
    """Roots ``(P, 2)`` of phi_2 and phi_3 that put the planar point at ``local`` ``(P, 3)`` (frame 1):
    ``local = Rz(phi_2) (t_2 + R_2 Rz(phi_3) v)``, ``R_2 = Rz(gamma_2)`` the rotation of C_2."""
    c2, v = structure.constants[1], structure.planar_point
    gamma2 = np.arctan2(c2[1, 0], c2[0, 0])
    t2 = c2[:2, 3]
    length2, length3 = np.linalg.norm(t2), np.hypot(v[0], v[1])
    cosine = (local[:, 0] ** 2 + local[:, 1] ** 2 - length2**2 - length3**2) / (2.0 * length2 * length3)
    exists = np.abs(cosine) <= 1.0 + _ROOT_SLACK
    psi = np.arccos(np.clip(cosine, -1.0, 1.0))
    direction = np.stack([psi, -psi], axis=-1) + np.arctan2(t2[1], t2[0])  # of R_2 Rz(phi_3) v
    phi3 = direction - gamma2 - np.arctan2(v[1], v[0])
    k = t2 + length3 * np.stack([np.cos(direction), np.sin(direction)], axis=-1)
    phi2 = np.arctan2(local[:, 1], local[:, 0])[:, None] - np.arctan2(k[..., 1], k[..., 0])
    return phi2, phi3, exists


#: The z axis, about which every joint of the chain turns in its own frame.
_E_Z = np.array([0.0, 0.0, 1.0])


def _to_frame(frame: np.ndarray, points: np.ndarray) -> np.ndarray:
    return (_invert(frame) @ np.c_[points, np.ones(len(points))][..., None])[:, :3, 0]


def _wrist_start(structure: _Structure, flange: np.ndarray, reference: np.ndarray):
    """What both closed forms start from: the wrist point (J5's origin) in the base frame, J1's two solutions and
    whether they exist, J4's turning axis ``g`` (z1 in frame 4), J6's axis ``v5`` in frame 4 at phi_5 = 0, and the
    empty tables of the eight branches' angles ``(n, 8, 6)`` and validity ``(n, 8)``."""
    constants, count = structure.constants, flange.shape[0]
    wrist = (flange @ structure.point_in_flange)[:, :3]
    phi1, ok1 = _first_joint(structure, wrist, reference[:, 0])
    g = constants[3, :3, :3].T @ _E_Z
    v5 = constants[4, :3, :3] @ _E_Z
    return wrist, phi1, ok1, g, v5, np.zeros((count, 8, 6)), np.zeros((count, 8), dtype=bool)


def _spherical(structure: _Structure, flange: np.ndarray, reference: np.ndarray):
    constants, count = structure.constants, flange.shape[0]
    wrist, phi1, ok1, g, v5, phi, valid = _wrist_start(structure, flange, reference)
    for s in range(2):
        frame1 = _rz(phi1[:, s]) @ constants[0]
        phi2, phi3, ok23 = _planar(structure, _to_frame(frame1, wrist))
        for e in range(2):
            frame3 = frame1 @ _rz(phi2[:, e]) @ constants[1] @ _rz(phi3[:, e]) @ constants[2]
            r36 = np.swapaxes(frame3[:, :3, :3], 1, 2) @ flange[:, :3, :3]
            axis6 = r36 @ constants[5, :3, :3].T @ _E_Z  # J6's axis in frame 3
            roots5, ok5, _ = _cos_sin_roots(
                g[0] * v5[0] + g[1] * v5[1], g[1] * v5[0] - g[0] * v5[1], axis6[:, 2] - g[2] * v5[2]
            )
            for w in range(2):
                phi5 = roots5[:, w]
                b = (constants[3, :3, :3] @ _rotate_z(phi5, np.broadcast_to(v5, (count, 3)))[..., None])[..., 0]
                aligned = np.hypot(b[:, 0], b[:, 1]) < 1e-9  # J4 and J6 aligned: phi_4 from the reference
                phi4 = np.where(
                    aligned, reference[:, 3], np.arctan2(axis6[:, 1], axis6[:, 0]) - np.arctan2(b[:, 1], b[:, 0])
                )
                rest = (
                    np.swapaxes((_rz(phi4) @ constants[3] @ _rz(phi5) @ constants[4])[:, :3, :3], 1, 2)
                    @ r36
                    @ constants[5, :3, :3].T
                )
                phi6 = np.arctan2(rest[:, 1, 0], rest[:, 0, 0])
                k = 4 * s + 2 * e + w
                phi[:, k] = np.stack([phi1[:, s], phi2[:, e], phi3[:, e], phi4, phi5, phi6], axis=-1)
                valid[:, k] = ok1 & ok23 & ok5
    return phi, valid


def _parallel(structure: _Structure, flange: np.ndarray, reference: np.ndarray):
    constants, count = structure.constants, flange.shape[0]
    _, phi1, ok1, g, v5, phi, valid = _wrist_start(structure, flange, reference)  # g: J2, J3, J4 turn about it
    for s in range(2):
        frame1 = _rz(phi1[:, s]) @ constants[0]
        z1 = frame1[:, :3, 2]
        axis6 = flange[:, :3, :3] @ constants[5, :3, :3].T @ _E_Z  # J6's axis in the base frame
        roots5, ok5, _ = _cos_sin_roots(
            g[0] * v5[0] + g[1] * v5[1], g[1] * v5[0] - g[0] * v5[1], np.einsum("pi,pi->p", z1, axis6) - g[2] * v5[2]
        )
        # z1 seen from frame 6, turned back through C_6: Rz(-phi_6) m = n
        n = (constants[5, :3, :3] @ np.swapaxes(flange[:, :3, :3], 1, 2) @ z1[..., None])[..., 0]
        for w in range(2):
            phi5 = roots5[:, w]
            m = (constants[4, :3, :3].T @ _rotate_z(-phi5, np.broadcast_to(g, (count, 3)))[..., None])[..., 0]
            aligned = np.hypot(m[:, 0], m[:, 1]) < 1e-9  # J6 parallel to J2..J4: phi_6 from the reference
            phi6 = np.where(aligned, reference[:, 5], np.arctan2(m[:, 1], m[:, 0]) - np.arctan2(n[:, 1], n[:, 0]))
            frame4 = flange @ _invert(_rz(phi5) @ constants[4] @ _rz(phi6) @ constants[5])
            phi2, phi3, ok23 = _planar(structure, _to_frame(frame1, frame4[:, :3, 3]))
            r14 = np.swapaxes(frame1[:, :3, :3], 1, 2) @ frame4[:, :3, :3] @ constants[3, :3, :3].T
            total = np.arctan2(r14[:, 1, 0], r14[:, 0, 0])  # phi_2 + gamma_2 + phi_3 + gamma_3 + phi_4
            gammas = sum(np.arctan2(constants[i, 1, 0], constants[i, 0, 0]) for i in (1, 2))
            for e in range(2):
                phi4 = total - phi2[:, e] - phi3[:, e] - gammas
                k = 4 * s + 2 * e + w
                phi[:, k] = np.stack([phi1[:, s], phi2[:, e], phi3[:, e], phi4, phi5, phi6], axis=-1)
                valid[:, k] = ok1 & ok23 & ok5
    return phi, valid


@dataclass(frozen=True, slots=True, kw_only=True)
class Solved:
    """Readings [rad] ``(n_poses, n_joints)`` found by :func:`solve_pose`, the remaining position [mm] and orientation
    [deg] error of every pose ``(n_poses,)``, and the Newton steps the slowest pose took."""

    readings: np.ndarray
    position_error_mm: np.ndarray
    orientation_error_deg: np.ndarray
    iterations: int

    def reached(self, position_mm: float = 1e-6, orientation_deg: float = 1e-6) -> np.ndarray:
        """Poses within ``position_mm`` and ``orientation_deg`` of their target."""
        return (self.position_error_mm <= position_mm) & (self.orientation_error_deg <= orientation_deg)


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """The rotation vector (axis times angle, [rad]) of rotation matrices ``(..., 3, 3)``, angles in [0, pi]."""
    rotation = np.asarray(rotation, dtype=float)
    axial = 0.5 * np.stack(
        [
            rotation[..., 2, 1] - rotation[..., 1, 2],
            rotation[..., 0, 2] - rotation[..., 2, 0],
            rotation[..., 1, 0] - rotation[..., 0, 1],
        ],
        axis=-1,
    )  # sin(angle) axis
    sine = np.linalg.norm(axial, axis=-1)
    cosine = np.clip(0.5 * (np.trace(rotation, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    angle = np.arctan2(sine, cosine)
    small = sine < 1e-12
    factor = np.where(small, 1.0, angle / np.where(small, 1.0, sine))
    out = axial * factor[..., None]
    near_pi = small & (cosine < 0.0)  # 180 deg: the axis from the symmetric part
    if np.any(near_pi):
        symmetric = 0.5 * (rotation[near_pi] + np.eye(3))
        axis = np.sqrt(np.clip(np.diagonal(symmetric, axis1=-2, axis2=-1), 0.0, None))
        column = np.argmax(axis, axis=-1)
        picked = symmetric[np.arange(column.size), :, column]
        axis = picked / np.linalg.norm(picked, axis=-1, keepdims=True)
        out[near_pi] = axis * np.pi
    return out


def tool_frames(parameters: ParameterSet, readings: np.ndarray, tool: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tool frames ``(P, 4, 4)`` of the calibrated model (its joint model included) at ``readings`` ``(P, n)``
    [rad], and their Jacobian ``(P, 6, n)`` in the readings: rows translation [mm/rad] then rotation [rad/rad]. The
    Jacobian is the chain's at the deflected joints; the deflection's own derivative (the gravity torque's change
    with q times a compliance, ~1e-4 of a joint's turn) is left out, which slows Newton's convergence by nothing
    measurable."""
    robot = parameters.robot
    q = parameters.model_joint_variables(readings)
    frames = joint_frames(parameters.values, q)  # (P, n + 1, 4, 4)
    tool_frame = frames[:, -1] @ tool
    point = tool_frame[:, :3, 3]
    axes, origins = frames[:, :-1, :3, 2], frames[:, :-1, :3, 3]  # z_{i-1}, o_{i-1}
    jacobian = np.concatenate([np.cross(axes, point[:, None] - origins), axes], axis=-1)  # (P, n, 6)
    # d q / d reading: the reading map (q = M^-1 reading + offset)
    to_model = robot.model_joint_variables(np.eye(robot.n_joints)) - robot.model_joint_variables(
        np.zeros((1, robot.n_joints))
    )  # row k: dq / d reading_k
    return tool_frame, np.swapaxes(to_model @ jacobian, 1, 2)


def solve_pose(
    parameters: ParameterSet,
    targets: ArrayLike,
    start_readings: ArrayLike,
    *,
    tool: ArrayLike | None = None,
    max_iterations: int = 200,
) -> Solved:
    """Controller readings at which the model's tool frame is each target frame, by Newton's method from
    ``start_readings``.

    For every target frame ``T*`` the commands ``r`` (controller readings) solve ``F(q(r) + delta(q(r))) X = T*``,
    ``F`` the calibrated chain, ``delta`` its joint model, ``X`` the tool. Newton's method, all poses at once: the
    error is ``e = (p* - p, L rotvec(R* R^T))`` (position [mm]; orientation as a rotation vector [rad] times the
    robot's size L, so that both parts are in mm) and the step solves ``J dr = e`` in the least-squares sense (per
    pose, by pseudo-inverse: a square J is solved exactly, a redundant robot takes the smallest step), ``J`` the geometric
    Jacobian of the tool frame in the joint variables (columns ``(z_i x (p - o_i), z_i)``) through the reading map.
    The joint model's own dependence on q (``d delta / d q``, about ``k dtau/dq ~ 1e-3`` or a harmonic amplitude) is
    left out of J: the iteration contracts by that factor per step instead of quadratically, reaching 1e-12 mm in a
    handful of steps. Near a singularity a Newton step can raise the error: each pose then damps its own step
    (Levenberg-Marquardt, ``(J^T J + lambda diag(J^T J)) dr = J^T e``, lambda from 1e-3 up by 10 until the error
    falls, back down by 10 after each accepted step). A pose stops at 2e-13 of the robot's size (2e-10 mm on a 1 m
    arm), when an accepted step moves no joint by 1e-13 rad (a local minimum: an unreachable target), or when no
    damping up to 1e12 lowers its error.

    Parameters
    ----------
    parameters : ParameterSet
        The calibrated model (geometric, or extended with its joint model).
    targets : array_like, shape (n_poses, 4, 4)
        Target tool frames in the robot base frame [mm].
    start_readings : array_like, shape (n_poses, n_joints)
        Where each pose's iteration starts [rad] (the taught commands, or a seed near the wanted branch).
    tool : array_like, shape (3,) or (4, 4), optional
        The tool point [mm] or frame in the flange frame (default: the flange).
    max_iterations : int

    Returns
    -------
    Solved
    """
    robot = parameters.robot
    targets, readings = check_targets(targets, start_readings, robot.n_joints, "start_readings")
    readings = readings.copy()
    tool_frame = as_tool_frame(tool)
    size = robot_size(robot)  # orientation errors [rad] times the robot's size: in mm

    def error(frames, rows):
        position = targets[rows, :3, 3] - frames[:, :3, 3]
        turn = rotation_vector(targets[rows, :3, :3] @ np.swapaxes(frames[:, :3, :3], 1, 2))
        return np.concatenate([position, size * turn], axis=1)

    every = np.arange(targets.shape[0])
    weight = np.r_[np.ones(3), np.full(3, size)][:, None]
    frames, jacobian = tool_frames(parameters, readings, tool_frame)
    residual = error(frames, every)
    cost = np.einsum("pk,pk->p", residual, residual)
    damping = np.zeros(targets.shape[0])
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        active = np.flatnonzero((cost > (2e-13 * size) ** 2) & (damping < 1e12))  # converged, or no step helps
        if active.size == 0:
            iterations -= 1
            break
        scaled = jacobian[active] * weight  # (A, 6, n)
        normal = np.swapaxes(scaled, 1, 2) @ scaled
        gradient = (np.swapaxes(scaled, 1, 2) @ residual[active][..., None])[..., 0]
        diagonal = np.einsum("pii->pi", normal)
        system = normal + damping[active, None, None] * (diagonal[:, :, None] * np.eye(normal.shape[-1]))
        step = (np.linalg.pinv(system) @ gradient[..., None])[..., 0]
        trial = readings[active] + step
        trial_frames, trial_jacobian = tool_frames(parameters, trial, tool_frame)
        trial_residual = error(trial_frames, active)
        trial_cost = np.einsum("pk,pk->p", trial_residual, trial_residual)
        better = trial_cost < cost[active]
        kept = active[better]
        readings[kept], jacobian[kept], residual[kept], cost[kept] = (
            trial[better], trial_jacobian[better], trial_residual[better], trial_cost[better]
        )
        damping[kept] = np.where(damping[kept] > 1e-9, damping[kept] / 10.0, 0.0)
        # a pose whose accepted step moved no joint by 1e-13 rad is at its (local) minimum: done
        damping[kept[np.abs(step[better]).max(axis=1, initial=0.0) < 1e-13]] = np.inf
        worse = active[~better]
        damping[worse] = np.where(damping[worse] > 0.0, damping[worse] * 10.0, 1e-3)
    frames = tool_frames(parameters, readings, tool_frame)[0]
    position = np.linalg.norm(targets[:, :3, 3] - frames[:, :3, 3], axis=1)
    angle = np.degrees(np.linalg.norm(rotation_vector(targets[:, :3, :3] @ np.swapaxes(frames[:, :3, :3], 1, 2)), axis=1))
    return Solved(readings=readings, position_error_mm=position, orientation_error_deg=angle, iterations=iterations)


def robot_size(robot: RobotModel) -> float:
    """The robot's size [mm]: the sum of its link lengths |d| + |a| (at least 1 mm), the lever that turns an
    orientation error [rad] into millimetres where the solvers weigh both."""
    return max(float(np.abs(robot.nominal[:, [0, 2]]).sum()), 1.0)


def check_targets(targets: ArrayLike, readings: ArrayLike, n_joints: int, name: str) -> tuple[np.ndarray, np.ndarray]:
    """``targets`` as finite frames ``(P, 4, 4)`` and ``readings`` as finite ``(P, n_joints)``, or InputError."""
    targets = np.asarray(targets, dtype=float)
    readings = np.asarray(readings, dtype=float)
    if targets.ndim != 3 or targets.shape[1:] != (4, 4) or not np.all(np.isfinite(targets)):
        raise InputError(f"`targets` must be finite frames of shape (n_poses, 4, 4); got {targets.shape}")
    if readings.shape != (targets.shape[0], n_joints) or not np.all(np.isfinite(readings)):
        raise InputError(f"`{name}` must be finite readings of shape ({targets.shape[0]}, {n_joints})")
    return targets, readings


def _wrapped(angle):
    return np.angle(np.exp(1j * np.asarray(angle, dtype=float)))


def wrap_readings(
    readings: ArrayLike, robot: RobotModel, reference: ArrayLike, *, prefer_limits: bool = True
) -> np.ndarray:
    """``readings`` ``(..., n)`` [rad] each shifted by whole turns to lie nearest ``reference`` (broadcastable),
    preferring a shift that puts it inside the robot's limits (unless ``prefer_limits`` is False)."""
    readings = np.asarray(readings, dtype=float)
    reference = np.broadcast_to(np.asarray(reference, dtype=float), readings.shape)
    base = reference + _wrapped(readings - reference)  # nearest the reference
    candidates = base[..., None] + 2.0 * np.pi * np.arange(-2, 3)  # (..., n, 5)
    lower, upper = robot.limits[:, 0][:, None], robot.limits[:, 1][:, None]
    inside = (candidates >= lower - 1e-12) & (candidates <= upper + 1e-12)
    cost = np.abs(candidates - reference[..., None]) + np.where(inside | (not prefer_limits), 0.0, 1e3)
    return np.take_along_axis(candidates, np.argmin(cost, axis=-1)[..., None], axis=-1)[..., 0]


def _reference(robot: RobotModel, reference, count: int) -> np.ndarray:
    if reference is None:
        middle = np.where(np.isfinite(robot.limits), robot.limits, 0.0).mean(axis=1)
        return np.broadcast_to(middle, (count, robot.n_joints)).copy()
    reference = np.asarray(reference, dtype=float)
    if reference.shape not in ((robot.n_joints,), (count, robot.n_joints)) or not np.all(np.isfinite(reference)):
        raise InputError(f"`reference` must be finite readings of shape ({robot.n_joints},) or ({count}, {robot.n_joints})")
    return np.broadcast_to(reference, (count, robot.n_joints)).copy()


def _check_frames(frames, name: str) -> np.ndarray:
    frames = np.asarray(frames, dtype=float)
    if frames.ndim == 2:
        frames = frames[None]
    if frames.ndim != 3 or frames.shape[1:] != (4, 4) or not np.all(np.isfinite(frames)):
        raise InputError(f"`{name}` must be finite frames of shape (n_poses, 4, 4); got {frames.shape}")
    return frames


def nominal_solutions(
    robot: RobotModel, flange_frames: ArrayLike, *, reference: ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Every closed-form solution of flange poses on the robot's nominal geometry (module notes).

    Parameters
    ----------
    robot : RobotModel
    flange_frames : array_like, shape (n_poses, 4, 4)
        ``base_from_flange`` [mm].
    reference : array_like, shape (n_joints,) or (n_poses, n_joints), optional
        Readings [rad] that choose whole turns and the free angle at a singularity (default: mid-limits).

    Returns
    -------
    readings : ndarray, shape (n_poses, 8, n_joints)
        Controller readings [rad] of every branch (:data:`BRANCH_NAMES`); a branch without a solution holds the
        best approximation (e.g. the stretched arm towards an unreachable point).
    exists : ndarray of bool, shape (n_poses, 8)
        Where the branch has an exact solution.
    """
    structure = _structure(robot)
    flange = _check_frames(flange_frames, "flange_frames")
    reference = _reference(robot, reference, flange.shape[0])
    phi_reference = robot.model_joint_variables(reference) + robot.nominal[:, 1]
    solve = _spherical if structure.family == "spherical-wrist" else _parallel
    phi, exists = solve(structure, flange, phi_reference)
    readings = robot.readings_from_model(phi - robot.nominal[:, 1])
    return wrap_readings(readings, robot, reference[:, None, :]), exists


@dataclass(frozen=True, slots=True, kw_only=True)
class InverseSolutions:
    """Every branch's solution of tool poses on a (calibrated) model.

    Attributes
    ----------
    readings : ndarray, shape (n_poses, 8, n_joints)
        Controller readings [rad] per branch (:data:`BRANCH_NAMES`), whole turns nearest the reference.
    reached : ndarray of bool, shape (n_poses, 8)
        The model's tool frame at ``readings`` is the target within the tolerances (default 1e-6 mm, 1e-6 deg).
    within_limits : ndarray of bool, shape (n_poses, 8)
        Every reading inside the robot's limits.
    position_error_mm, orientation_error_deg : ndarray, shape (n_poses, 8)
        What remains between the tool frame at ``readings`` and the target (NaN for a branch not solved).
    """

    readings: np.ndarray
    reached: np.ndarray
    within_limits: np.ndarray
    position_error_mm: np.ndarray
    orientation_error_deg: np.ndarray

    @property
    def usable(self) -> np.ndarray:
        """``reached & within_limits``, shape (n_poses, 8)."""
        return self.reached & self.within_limits

    def __repr__(self) -> str:
        return (
            f"InverseSolutions({self.readings.shape[0]} poses, {int(self.usable.sum())} of "
            f"{self.usable.size} branch solutions reached within the limits)"
        )


def within_limits(robot: RobotModel, readings: ArrayLike) -> np.ndarray:
    """Whether every reading of ``(..., n)`` lies inside the robot's limits (1e-9 rad of slack)."""
    readings = np.asarray(readings, dtype=float)
    return np.all((readings >= robot.limits[:, 0] - 1e-9) & (readings <= robot.limits[:, 1] + 1e-9), axis=-1)


def as_tool_frame(tool: ArrayLike | None) -> np.ndarray:
    """A tool point ``(3,)`` or frame ``(4, 4)`` in the flange frame [mm] as a frame; None: the flange."""
    frame = np.eye(4)
    if tool is None:
        return frame
    tool = np.asarray(tool, dtype=float)
    if tool.shape == (3,):
        frame[:3, 3] = tool
        return frame
    if tool.shape != (4, 4) or not np.all(np.isfinite(tool)):
        raise InputError(f"`tool` must be a point (3,) or a frame (4, 4) [mm]; got shape {tool.shape}")
    return tool


def inverse_kinematics(
    parameters: ParameterSet,
    targets: ArrayLike,
    *,
    tool: ArrayLike | None = None,
    reference: ArrayLike | None = None,
    position_tolerance_mm: float = 1e-6,
    orientation_tolerance_deg: float = 1e-6,
    branches: ArrayLike | None = None,
    max_iterations: int = 200,
) -> InverseSolutions:
    """Every branch's readings at which ``parameters``' tool frame is each target (module notes).

    Parameters
    ----------
    parameters : ParameterSet
        The model to solve: the nominal set, or a calibrated one (with its joint model, if any).
    targets : array_like, shape (n_poses, 4, 4)
        Tool frames in the robot base frame [mm].
    tool : array_like, shape (3,) or (4, 4), optional
        The tool point or frame in the flange frame [mm] (default: the flange).
    reference : array_like, shape (n_joints,) or (n_poses, n_joints), optional
        Readings [rad] that choose whole turns and the free angle at a singularity (default: mid-limits).
    position_tolerance_mm, orientation_tolerance_deg : float
        What ``reached`` means.
    branches : array_like of bool, shape (n_poses, 8), optional
        Solve only these branches on the calibrated model (the others hold their nominal solution, not reached).
    max_iterations : int
        Newton steps per branch solution.

    Returns
    -------
    InverseSolutions

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> from robotcal.kinematics.forward import forward_kinematics
    >>> robot = robotcal.load_robot("kuka-kr5-sixx-r650")
    >>> taught = np.deg2rad([[10.0, 60.0, -30.0, 20.0, 45.0, 5.0]])
    >>> frame = forward_kinematics(robot.nominal, robot.model_joint_variables(taught))
    >>> solutions = inverse_kinematics(ParameterSet.nominal(robot), frame, reference=taught)
    >>> int(solutions.usable.sum()) >= 2, bool(np.any(np.abs(solutions.readings[0] - taught).max(axis=1) < 1e-9))
    (True, True)
    """
    robot = parameters.robot
    tool_frame = as_tool_frame(tool)
    targets = _check_frames(targets, "targets")
    count = targets.shape[0]
    reference = _reference(robot, reference, count)
    start, _ = nominal_solutions(robot, targets @ _invert(tool_frame), reference=reference)
    chosen = np.ones((count, 8), dtype=bool) if branches is None else np.asarray(branches, dtype=bool)
    if chosen.shape != (count, 8):
        raise InputError(f"`branches` must be a mask of shape ({count}, 8); got {chosen.shape}")
    pose, branch = np.nonzero(chosen)
    result = solve_pose(parameters, targets[pose], start[pose, branch], tool=tool_frame, max_iterations=max_iterations)
    readings = start.copy()
    readings[pose, branch] = result.readings
    readings = wrap_readings(readings, robot, reference[:, None, :])
    reached = np.zeros((count, 8), dtype=bool)
    reached[pose, branch] = result.reached(position_tolerance_mm, orientation_tolerance_deg)
    position, angle = np.full((count, 8), np.nan), np.full((count, 8), np.nan)
    position[pose, branch], angle[pose, branch] = result.position_error_mm, result.orientation_error_deg
    return InverseSolutions(
        readings=readings,
        reached=reached,
        within_limits=within_limits(robot, readings),
        position_error_mm=position,
        orientation_error_deg=angle,
    )


def branch_of(robot: RobotModel, readings: ArrayLike) -> np.ndarray:
    """The branch (:data:`BRANCH_NAMES` index) of ``readings`` ``(n_poses, n_joints)`` [rad] on the nominal geometry:
    the closed-form branch whose solution of the pose they reach is nearest them (turns ignored)."""
    readings = np.atleast_2d(np.asarray(readings, dtype=float))
    flange = forward_kinematics(robot.nominal, robot.model_joint_variables(readings))
    solutions, _ = nominal_solutions(robot, flange, reference=readings)
    distance = np.abs(_wrapped(solutions - readings[:, None, :])).max(axis=-1)
    return np.argmin(distance, axis=1)
