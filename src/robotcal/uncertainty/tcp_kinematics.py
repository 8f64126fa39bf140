"""TCP kinematics of many parameter draws at once: the six TCP coordinates and their Jacobian (thesis ch. 5.3).

The chain is carried as ``(3 P, 4)`` blocks ``[R | t]`` per draw (the speed notes of
:mod:`robotcal.uncertainty.tcp`); each angle of the KUKA orientation ``A, B, C`` (``R = Rz(A) Ry(B) Rx(C)``) is
the nominal's plus the angle of its vector turned by the nominal (:func:`_angle_from`). Lengths in mm, angles in
radians.

References
----------
Thesis ch. 5.3 (Table 5.8); JCGM 102:2011 §6.2 (the sensitivity matrix of a multivariate model).
"""

from __future__ import annotations

import numpy as np

from robotcal.errors import InputError
from robotcal.geometry.euler import GIMBAL_TOLERANCE, kuka_abc_from_matrix, wrap_angle_near
from robotcal.kinematics.forward import link_transforms
from robotcal.kinematics.model import ANGLE_COLUMNS, check_parameter_array

__all__ = ["check_tool", "tcp_coordinates", "tcp_jacobian"]

_ANGLES = slice(3, 6)
_ANGLE_KINDS = list(ANGLE_COLUMNS)
#: Central-difference steps of :func:`tcp_jacobian`: lengths [mm], angles [rad].
JACOBIAN_STEP_MM = 1e-4
JACOBIAN_STEP_RAD = 1e-6


def check_tool(tool) -> np.ndarray:
    """Tool offset on the flange ``(3,)`` [mm] in flange coordinates; ``None`` = the flange origin."""
    if tool is None:
        return np.zeros(3)
    try:
        tool = np.asarray(tool, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError("`tool` must be three numbers x, y, z [mm]") from exc
    if tool.shape != (3,) or not np.all(np.isfinite(tool)):
        raise InputError(f"`tool` must be three finite numbers x, y, z [mm]; got {tool.tolist()}")
    return tool


def _flange_blocks(links: np.ndarray, cos_q: np.ndarray, sin_q: np.ndarray, tool: np.ndarray):
    """TCP rotation ``(m, P, 3, 3)`` and position ``(m, P, 3)`` for ``m`` parameter sets and ``P`` poses.

    ``links (m, n, 4, 4)`` are the pose-independent factors ``B_i = Rz(theta_i) Tz(d_i) Tx(a_i)
    Rx(alpha_i) Ry(beta_i)``, so that ``A_i(q) = Rz(q_i) B_i`` and the flange is
    ``Rz(q_1) B_1 ... Rz(q_n) B_n`` (eq. 3-84). The chain is carried as 3x4 blocks ``[R | t]``:
    right-multiplying by ``Rz(q)`` mixes the first two columns elementwise, and by ``B_i`` is one
    stacked matrix product over all poses of a parameter set.
    """
    m, n = links.shape[0], links.shape[1]
    n_poses = cos_q.shape[0]
    block = np.zeros((1, n_poses, 3, 4))
    block[0, :, 0, 0] = block[0, :, 1, 1] = 1.0
    block[0, :, 2, 2] = 1.0
    block = np.broadcast_to(block, (m, n_poses, 3, 4))
    for joint in range(n):
        c = cos_q[None, :, joint, None]
        s = sin_q[None, :, joint, None]
        first, second = block[..., 0], block[..., 1]
        turned = np.empty((m, n_poses, 3, 4))
        turned[..., 0] = first * c + second * s
        turned[..., 1] = second * c - first * s
        turned[..., 2:] = block[..., 2:]
        block = np.matmul(turned.reshape(m, n_poses * 3, 4), links[:, joint]).reshape(m, n_poses, 3, 4)
    rotation = block[..., :3]
    position = block[..., 3] + rotation @ tool
    return rotation, position


def _pose_independent_links(parameters: np.ndarray) -> np.ndarray:
    """``B_i`` of every parameter set: link transforms at q = 0, ``(m, n_joints, 4, 4)``."""
    n = parameters.shape[-2]
    return link_transforms(parameters, np.zeros((1, n)))[:, 0]


def _coordinates(parameters: np.ndarray, q_model: np.ndarray, tool: np.ndarray) -> np.ndarray:
    """``(m, P, 6)`` X, Y, Z [mm], A, B, C [rad] for parameter sets ``(m, n, 5)``."""
    links = _pose_independent_links(parameters)
    rotation, position = _flange_blocks(links, np.cos(q_model), np.sin(q_model), tool)
    out = np.empty(position.shape[:-1] + (6,))
    out[..., :3] = position
    out[..., 3:] = kuka_abc_from_matrix(rotation)
    return out


def _chain_columns(links: np.ndarray, cos_q: np.ndarray, sin_q: np.ndarray) -> np.ndarray:
    """``B_1 A_2(q_2) ... A_n(q_n)`` of ``m`` parameter sets at ``P`` poses as ``(m, 3, P, 4)`` blocks.

    The flange frame is ``Rz(q_1)`` times this (eq. 3-84 with ``A_i(q) = Rz(q_i) B_i``); the caller
    applies ``Rz(q_1)`` analytically (it turns X, Y about the base Z axis and adds ``q_1`` to A).
    Entry ``[s, r, p, k]`` is row ``r``, column ``k`` of the 3x4 block ``[R | t]`` of set ``s`` at pose
    ``p``. Right-multiplying by ``Rz(q)`` turns the first two columns: with the columns adjacent in
    memory, ``column_0 + i column_1`` is a complex number that is multiplied by ``exp(-i q)`` in place
    (one pass, the other columns untouched); right-multiplying by ``B_i`` is one ``(3 P, 4) @ (4, 4)``
    product per set. ``links (m, n, 4, 4)`` holds ``B_i`` of every set; ``cos_q``, ``sin_q`` are ``(P, n)``, or
    ``(m, P, n)`` when every set turns its joints by its own angles (an extended model's deflection).
    """
    m, n = links.shape[0], links.shape[1]
    n_poses = cos_q.shape[-2]
    block = np.empty((m, 3 * n_poses, 4))
    other = np.empty_like(block)
    for joint in range(1, n):
        phase = cos_q[..., joint] - 1j * sin_q[..., joint]  # exp(-i q): (c0 + i c1) exp(-i q) = c0' + i c1'
        if phase.ndim == 2:  # per set and pose (an extended model's deflected joints): (m, 1, P)
            phase = phase[:, None, :]
        pairs = block.view(complex).reshape(m, 3, n_poses, 2)  # [..., 0]: c0 + i c1, [..., 1]: c2 + i c3
        if joint == 1:  # B_1 Rz(q_2) written at once: the turned first two columns and B_1's last two
            first = np.ascontiguousarray(links[:, 0, :3]).view(complex)  # (m, 3, 2)
            np.multiply(first[:, :, 0, None], phase, out=pairs[..., 0])
            pairs[..., 1] = first[:, :, 1, None]
        else:
            np.multiply(pairs[..., 0], phase, out=pairs[..., 0])
        np.matmul(block, links[:, joint], out=other)
        block, other = other, block
    if n == 1:
        block.reshape(m, 3, n_poses, 4)[...] = links[:, 0, :3, None, :]
    return block.reshape(m, 3, n_poses, 4)


def _chain_points(links: np.ndarray, cos_q: np.ndarray, sin_q: np.ndarray, point: np.ndarray) -> np.ndarray:
    """``B_1 A_2(q_2) ... A_n(q_n) [point; 1]`` of ``m`` parameter sets at ``P`` poses, ``(m, 3, P)`` [mm].

    The position-only chain of :func:`_chain_columns` (the caller applies ``Rz(q_1)``), evaluated from the
    tool end: ``B_n [point; 1]`` is the same at every pose, then each joint turns the point about its z axis
    (``Rz(q_i)``) and moves it by ``B_{i-1}`` (``R_{i-1} v + t_{i-1}``, one ``(3, 3) @ (3, P)`` product per
    set). One point instead of a 3x4 block: about a third of the work of :func:`_chain_columns`.
    ``links (m, n, 4, 4)`` holds ``B_i`` of every set; ``cos_q``, ``sin_q`` ``(P, n)`` or ``(m, P, n)``.
    """
    m, n = links.shape[0], links.shape[1]
    n_poses = cos_q.shape[-2]
    end = links[:, n - 1, :3, :3] @ point + links[:, n - 1, :3, 3]  # (m, 3), pose-independent
    x, y, z = end[:, 0, None], end[:, 1, None], end[:, 2, None]
    turned = np.empty((m, 3, n_poses))
    for joint in range(n - 1, 0, -1):
        c, s = cos_q[..., joint], sin_q[..., joint]
        np.multiply(x, c, out=turned[:, 0])
        turned[:, 0] -= y * s
        np.multiply(x, s, out=turned[:, 1])
        turned[:, 1] += y * c
        turned[:, 2] = z
        moved = np.matmul(links[:, joint - 1, :3, :3], turned)
        moved += links[:, joint - 1, :3, 3, None]
        x, y, z = moved[:, 0], moved[:, 1], moved[:, 2]
    return moved if n > 1 else np.broadcast_to(end[:, :, None], (m, 3, n_poses)).copy()


def _angle_from(x: np.ndarray, y: np.ndarray, cos_ref: np.ndarray, sin_ref: np.ndarray, out: np.ndarray) -> None:
    """``atan2(y, x) - reference`` into ``(-pi, pi]``, written to ``out``, given ``cos``/``sin`` of the reference.

    The vector ``(x, y)`` turned by ``-reference`` is ``(x', y') = (x c + y s, y c - x s)`` and its angle is the
    difference itself, ``atan2(y', x')``: no quadrant fix and no wrap.
    """
    along = x * cos_ref
    along += y * sin_ref
    np.multiply(y, cos_ref, out=out)
    out -= x * sin_ref
    np.arctan2(out, along, out=out)


def _abc_near(block: np.ndarray, first_joint: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """KUKA ``A, B, C`` ``(3, m, P)`` [rad] of ``Rz(q_1)`` times ``(m, 4, 3, P)`` blocks, within pi of ``reference (P, 3)``.

    ``Rz(q_1) Rz(A') Ry(B) Rx(C) = Rz(A' + q_1) Ry(B) Rx(C)``: the first joint ``first_joint (P,)``, or ``(m, P)``
    per set, [rad] only adds to A.

    The formulas of :func:`~robotcal.geometry.euler.kuka_abc_from_matrix`, ``A' = atan2(r10, r00)``,
    ``B = atan2(-r20, cos B)`` with ``cos B = sqrt(r00^2 + r10^2)``, ``C = atan2(r21, r22)``, each taken as
    the reference plus the angle of its vector turned by the reference (:func:`_angle_from`): the
    result lies within pi of the reference (A and C wrapped as before; B and its reference both lie in
    [-pi/2, pi/2], so it is B itself). Blocks at the gimbal lock go through :func:`kuka_abc_from_matrix`.
    """
    r00, r10, r20 = block[:, 0, 0], block[:, 0, 1], block[:, 0, 2]
    r21, r22 = block[:, 1, 2], block[:, 2, 2]
    out = np.empty((3,) + r00.shape)
    local = np.array(reference.T, dtype=float)  # (3, P): A's reference before Rz(q_1)
    if np.ndim(first_joint) == 2:  # per set: (3, m, P)
        local = np.repeat(local[:, None, :], r00.shape[0], axis=1)
    local[0] -= first_joint
    cos_ref, sin_ref = np.cos(local), np.sin(local)
    cos_b = np.sqrt(r00 * r00 + r10 * r10)
    _angle_from(r00, r10, cos_ref[0], sin_ref[0], out[0])
    _angle_from(cos_b, -r20, cos_ref[1], sin_ref[1], out[1])
    _angle_from(r22, r21, cos_ref[2], sin_ref[2], out[2])
    out += reference.T[:, None, :]
    locked = cos_b < GIMBAL_TOLERANCE
    if np.any(locked):
        rotation = np.moveaxis(block[:, :3], (1, 2), (-1, -2))  # (m, P, 3, 3) with [.., r, c]
        exact = np.moveaxis(kuka_abc_from_matrix(rotation), -1, 0)
        exact[0] += first_joint
        exact[::2] = wrap_angle_near(exact[::2], reference.T[::2, None, :])
        out[:, locked] = exact[:, locked]
    return out


def tcp_coordinates(parameters, q, *, tool=None) -> np.ndarray:
    """TCP position and KUKA orientation for parameter sets and poses.

    Parameters
    ----------
    parameters : array_like, shape (..., n_joints, 5)
        ``d, theta, a, alpha, beta`` [mm, rad]; one set or a batch.
    q : array_like, shape (n_poses, n_joints)
        *Model* joint variables [rad] (``RobotModel.model_joint_variables`` of the readings).
    tool : array_like, shape (3,), optional
        TCP in flange coordinates [mm]; default the flange origin (Table 5.8).

    Returns
    -------
    ndarray, shape (..., n_poses, 6)
        ``X, Y, Z`` [mm] in the base frame and ``A, B, C`` [rad], angles in their principal ranges.
    """
    parameters = np.asarray(parameters, dtype=float)
    n = parameters.shape[-2]
    parameters = check_parameter_array(parameters, n)
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        q = q[None, :]
    if q.ndim != 2 or q.shape[1] != n or not np.all(np.isfinite(q)):
        raise InputError(f"`q` must be finite with shape (n_poses, {n}); got {q.shape}")
    lead = parameters.shape[:-2]
    flat = parameters.reshape((-1, n, 5))
    return _coordinates(flat, q, check_tool(tool)).reshape(lead + (q.shape[0], 6))


def _free_steps(values: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    index = np.flatnonzero(free.reshape(-1))
    kinds = index % 5
    steps = np.where(np.isin(kinds, _ANGLE_KINDS), JACOBIAN_STEP_RAD, JACOBIAN_STEP_MM)
    return index, steps


def tcp_jacobian(parameters, q, *, tool=None, free=None) -> np.ndarray:
    """Jacobian of the six TCP coordinates with respect to the kinematic parameters.

    Central differences with steps ``JACOBIAN_STEP_MM`` (1e-4 mm) and ``JACOBIAN_STEP_RAD``
    (1e-6 rad): the truncation error ``h^2 f'''/6`` and the rounding error ``eps |f| / h`` are both
    below 1e-9 relative for a robot of metre size. All ``2 k`` perturbed parameter sets go through
    one batched kinematics call. Angle differences are wrapped, so A or C near +-180 deg is fine;
    at the gimbal lock (B = +-90 deg) the A and C rows are undefined.

    Parameters
    ----------
    parameters : array_like, shape (n_joints, 5)
        Where to linearise [mm, rad].
    q : array_like, shape (n_poses, n_joints)
        Model joint variables [rad].
    tool : array_like, shape (3,), optional
        TCP in flange coordinates [mm].
    free : array_like of bool, shape (n_joints, 5), optional
        Parameters to differentiate for (default all ``n_joints * 5``, joint-major like
        ``RobotModel.parameter_names``).

    Returns
    -------
    ndarray, shape (n_poses, 6, k)
        ``d(X, Y, Z, A, B, C) / d(parameter)`` [mm/mm, mm/rad, rad/mm, rad/rad], k free parameters.
    """
    values = np.asarray(parameters, dtype=float)
    if values.ndim != 2 or values.shape[1] != 5:
        raise InputError(f"`parameters` must be one set (n_joints, 5); got {values.shape}")
    n = values.shape[0]
    values = check_parameter_array(values, n)
    free = np.ones(values.shape, dtype=bool) if free is None else np.asarray(free, dtype=bool)
    if free.shape != values.shape:
        raise InputError(f"`free` must have shape {values.shape}; got {free.shape}")
    index, steps = _free_steps(values, free)
    k = index.size
    centre = tcp_coordinates(values, q, tool=tool)
    perturbed = np.repeat(values.reshape(1, -1), 2 * k, axis=0)
    perturbed[np.arange(k), index] += steps
    perturbed[k + np.arange(k), index] -= steps
    coords = tcp_coordinates(perturbed.reshape(2 * k, n, 5), q, tool=tool)
    coords[..., _ANGLES] = wrap_angle_near(coords[..., _ANGLES], centre[..., _ANGLES])
    derivative = (coords[:k] - coords[k:]) / (2.0 * steps[:, None, None])
    return np.moveaxis(derivative, 0, -1)
