"""The refined Monte Carlo's kernel: the structure every draw repeats and its batched normal equations.

:class:`RefinedModel` holds the refinement's fixed structure (free set, scale, point groups), :class:`RefinedBatch`
a batch's outcome; :class:`_Batch` (geometric model, per group of points) and :class:`_PointBatch` (extended model,
point by point) evaluate the cost, ``J_s^T J_s`` and ``J_s^T r`` of a stack of draws in screw form. The solvers
that use them are :func:`robotcal.uncertainty.refined.refine_batch` (Levenberg-Marquardt per draw) and
:func:`robotcal.uncertainty.gauss_newton.refine_draws_gauss_newton` (batched Gauss-Newton around the noise-free
solution); the design is described in :mod:`robotcal.uncertainty.refined`.

References
----------
Thesis ch. 4.5.7 (eqs 4-101, 4-102); JCGM 101:2008 §5.9, §7.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robotcal.geometry._vectors import cross as _cross
from robotcal.identification.refine import base_correction
from robotcal.kinematics.joint_model import JointModel

__all__ = ["RefinedModel", "RefinedBatch"]

#: Pairs handled at once by the distances criterion (fixed, so that sums do not depend on the batch size;
#: with ``REFINE_BATCH`` = 500 draws one chunk's arrays take ~12 MB each).
_PAIR_CHUNK = 512


@dataclass(frozen=True, slots=True, kw_only=True)
class SharedStep:
    """The first Gauss-Newton step every draw shares: the model at the noise-free solution ``x0``.

    Attributes
    ----------
    value : ndarray, shape (N, 3) or (n_pairs,)
        Points criterion: the base-frame points ``p(x0)`` in the order ``order`` [mm]; distances: ``|p_i - p_j|``
        over the pairs [mm].
    order : ndarray of int, shape (N,)
        The capture row of every point of ``value``.
    projector : ndarray, shape (p, K)
        ``J0_s^+``, the pseudo-inverse of the scaled Jacobian at ``x0`` (K = 3 N or n_pairs).
    inverse_normal : ndarray, shape (p, p)
        ``(J0_s^T J0_s)^-1 = J0_s^+ (J0_s^+)^T``: the matrix of the corrective steps when ``contraction`` allows.
    contraction : float
        A bound on how much a corrective step with ``inverse_normal`` leaves of a draw's distance to its solution, in
        units of u (:func:`robotcal.uncertainty.gauss_newton._contraction`); inf where not measured (geometric model,
        no stopping rule in u).
    """

    value: np.ndarray
    order: np.ndarray
    projector: np.ndarray
    inverse_normal: np.ndarray
    contraction: float


@dataclass(frozen=True, slots=True, kw_only=True)
class RefinedModel:
    """The refinement every Monte Carlo draw repeats (fixed structure; values vary per draw).

    Attributes
    ----------
    criterion : {"points", "distances"}
    free : ndarray of bool, shape (n_joints, 5)
        Kinematic parameters estimated (from ``refine_parameters`` on the noise-free capture).
    base_free : ndarray of bool, shape (6,)
        ``tracker_from_base`` corrections estimated (points criterion with an estimated base).
    x_scale : ndarray, shape (n_free,)
        Scale of each unknown [mm | rad], kinematic first, then base corrections.
    q : ndarray, shape (n_points, n_joints)
        Model joint variables of the capture [rad].
    carrier : ndarray of int, shape (n_points,)
        The frame that carries each point's target: ``t`` for a per-joint target of circle t + 1 (``F_t Rz(q_t)
        r``, eq. 5-1), ``n`` for a flange target (``F_n r``).
    vectors : ndarray, shape (n_points, 3)
        Each point's target vector ``r`` in its carrier frame [mm].
    pair_i, pair_j : ndarray of int, shape (n_pairs,) or None
        Distances criterion: the pairs of distinct measurements.
    groups : dict
        Points grouped by the configuration of the frame that carries their target (see
        ``_group_points``): the link chain is evaluated once per group.
    sorted_i, sorted_j : ndarray of int or None
        ``pair_i``, ``pair_j`` in the grouped point order.
    reference_values : ndarray, shape (n_joints, 5)
        Refinement of the noise-free capture [mm, rad] (the model value ``f(x)``).
    reference_tracker : ndarray, shape (4, 4) or None
        Its base frame (points criterion).
    held : tuple of str
        Parameters the noise-free refinement could not determine (they keep the CPA value).
    free_names : tuple of str
    max_iterations : int
    xtol : float
    joint_model : JointModel or None
        The extended model's joint model (its values: the noise-free refinement's); None: geometric.
    joint_columns : ndarray, shape (n_points, n_joints, m), or None
        ``C(q)`` of the joint model at the capture (:meth:`JointModel.columns`).
    extra_free : ndarray of bool, shape (m,)
        Joint-model values estimated.
    step_tolerance : ndarray, shape (n_free,), or None
        The Gauss-Newton draws' stopping rule in the scaled unknowns: a draw has converged when every component of
        its step is below this (:data:`robotcal.uncertainty.gauss_newton.STEP_TOLERANCE` times the linearised
        standard uncertainty, set by :func:`robotcal.uncertainty.montecarlo.prepare_monte_carlo`); None: the
        ``xtol`` rule of the per-draw solve.
    shared_step : SharedStep or None
        The Gauss-Newton draws' shared first step at the noise-free solution
        (:class:`SharedStep`, set with ``step_tolerance``); None: computed per call.
    """

    criterion: str
    free: np.ndarray
    base_free: np.ndarray
    x_scale: np.ndarray
    q: np.ndarray
    carrier: np.ndarray
    vectors: np.ndarray
    pair_i: np.ndarray | None
    pair_j: np.ndarray | None
    reference_values: np.ndarray
    reference_tracker: np.ndarray | None
    held: tuple[str, ...]
    free_names: tuple[str, ...]
    groups: dict
    sorted_i: np.ndarray | None
    sorted_j: np.ndarray | None
    max_iterations: int = 50
    xtol: float = 1e-10
    joint_model: JointModel | None = None
    joint_columns: np.ndarray | None = None
    extra_free: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    step_tolerance: np.ndarray | None = None
    shared_step: SharedStep | None = None

    @property
    def n_free(self) -> int:
        return int(self.x_scale.size)

    @property
    def n_kinematic(self) -> int:
        return int(self.free.sum())

    @property
    def n_extra(self) -> int:
        return int(self.extra_free.sum())

    @property
    def reference_extras(self) -> np.ndarray:
        """The joint-model values of the noise-free refinement (empty for the geometric model)."""
        return np.zeros(0) if self.joint_model is None else self.joint_model.values


@dataclass(frozen=True, slots=True, kw_only=True)
class RefinedBatch:
    """Outcome of :func:`refine_batch` for ``n_draws`` captures.

    Attributes
    ----------
    values : ndarray, shape (n_draws, n_joints, 5)
        Refined parameters [mm, rad] (NaN rows where the draw failed).
    tracker_from_base : ndarray, shape (n_draws, 4, 4) or None
    converged : ndarray of bool, shape (n_draws,)
    iterations : ndarray of int, shape (n_draws,)
        Evaluations of residuals and Jacobian after the start's.
    cost : ndarray, shape (n_draws,)
        ``0.5 sum r^2`` [mm^2] at the last evaluated iterate (the final, negligible step below the
        convergence threshold is taken without another evaluation).
    extras : ndarray, shape (n_draws, m)
        Joint-model values of every draw (NaN rows where it failed; ``m = 0`` for the geometric model).
    fallback : ndarray of bool, shape (n_draws,)
        Draws the batched Gauss-Newton did not converge and the per-draw Levenberg-Marquardt solved
        (:func:`robotcal.uncertainty.gauss_newton.refine_draws_gauss_newton`; all False for :func:`refine_batch`).
    """

    values: np.ndarray
    tracker_from_base: np.ndarray | None
    converged: np.ndarray
    iterations: np.ndarray
    cost: np.ndarray
    extras: np.ndarray
    fallback: np.ndarray | None = None

    def __post_init__(self):
        if self.fallback is None:
            object.__setattr__(self, "fallback", np.zeros(self.converged.shape, dtype=bool))


def _kinematics(
    config_q: np.ndarray,
    carrier: np.ndarray,
    free: np.ndarray,
    values: np.ndarray,
    scale: np.ndarray | None = None,
    *,
    joint_twists: bool = False,
    component_major: bool = False,
    record: list | None = None,
):
    """Carrier frames and the twists of the free kinematic parameters, per group of points.

    ``config_q`` ``(U, n)``: the joint variables of every group, shared by the draws, or ``(B, U, n)``: per draw
    (an extended model's deflected joints); ``carrier (U,)``: the frame that carries each group's target.
    Returns ``rotation (B, U, 3, 3)``, ``origin (B, U, 3)`` of each group's carrier frame and
    ``twists (B, U, 6, n_kin)``: column ``(omega, v)`` such that ``dp/dx = v + omega x p`` for every
    point p of the group (base frame), times ``scale`` (one factor per column) when given. These are the
    screw axes of :func:`robotcal.kinematics.jacobian.target_jacobian`: d ``(0, z_B)``; theta
    ``(z_B, o_B x z_B)``; a ``(0, x')``; alpha ``(x', o_F x x')``; beta ``(y_F, o_F x y_F)``; zero for
    joints at or after the one that turns the target. With ``joint_twists`` also ``(B, U, 6, n)``: the twist of
    every joint variable, ``d p / d q_j`` (theta's axis), for every joint that moves the target (for a
    per-joint target the one that turns it too). ``component_major``: the arrays as composed, components first:
    ``frame (4, 3, B, U)`` (columns x, y, z and the origin), ``twists (6, n_kin, B, U)``, ``turns (6, n, B, U)``.
    ``record``: a list to which every joint's ``(z_B, o_B, x', y_F, o_F)`` ``(3, B, U')`` each are appended (the axes
    and anchors of its twists; :meth:`_PointBatch.gradient`). Without twists, on groups in falling order of
    ``carrier``, the chain drops the groups whose frame it has reached: ``U'`` counts the groups whose carrier is at
    or after the joint (``z_B``, ``o_B``) or after it (the others), the leading ones.

    The chain ``F_{j+1} = F_j Rz(theta_j + q_j) Tz(d_j) Tx(a_j) Rx(alpha_j) Ry(beta_j)`` (the link of
    :func:`robotcal.kinematics.forward.link_transforms`) is composed column by column on ``(3, B, U)``
    arrays, draws and groups in the last axes: a few dozen element-wise operations per joint instead of
    ``B U`` stacked 4x4 products, the same products and sums up to rounding.
    """
    batch, n_joints = values.shape[0], values.shape[1]
    units = config_q.shape[-2]
    # per-joint link terms, joint-major: (n, B, U) for the turning angle, (n, 1, B, 1) for the others
    angle = np.moveaxis(values[:, None, :, 1] + (config_q[None] if config_q.ndim == 2 else config_q), -1, 0)
    link = values.T[:, :, None, :, None]  # (5, n, 1, B, 1)
    d, a = link[0], link[2]
    cos_a, sin_a, cos_b, sin_b = np.cos(link[3]), np.sin(link[3]), np.cos(link[4]), np.sin(link[4])
    # F_0 = identity: columns x, y, z and origin, (3, B, U) each
    x_axis, y_axis, z_axis, origin = (np.zeros((3, batch, units)) for _ in range(4))
    x_axis[0], y_axis[1], z_axis[2] = 1.0, 1.0, 1.0
    carried = np.empty((4, 3, batch, units))  # the frame F_carrier of each group
    twists = np.empty((6, int(free.sum()), batch, units))
    turns = np.zeros((6, n_joints, batch, units)) if joint_twists else None
    free_joint, free_kind = np.nonzero(free)
    factor = np.ones(free_joint.size) if scale is None else np.asarray(scale, dtype=float)[: free_joint.size]
    # without twists, groups in falling order of their carrier leave the chain once their frame is reached
    shrink = free_joint.size == 0 and turns is None and bool(np.all(np.diff(carrier) <= 0))
    for joint in range(n_joints + 1):
        here = carrier == joint
        if here.any():
            for slot, vector in enumerate((x_axis, y_axis, z_axis, origin)):
                carried[slot][..., here] = vector[..., here[: vector.shape[-1]]]
        if joint == n_joints:
            break
        if turns is not None:  # d p / d q_j: a turn about z_B through o_B, for the targets joint j moves
            moved = (joint < carrier) | ((joint == carrier) & (carrier < n_joints))
            turns[:3, joint] = np.where(moved, z_axis, 0.0)
            turns[3:, joint] = np.where(moved, _cross3(origin, z_axis), 0.0)
        z_base, o_base = z_axis, origin  # every group that reaches joint j (its turn moves per-joint targets)
        width = int(np.count_nonzero(carrier > joint)) if shrink else units  # the groups carried further
        x_axis, y_axis, z_axis, origin = (v[..., :width] for v in (x_axis, y_axis, z_axis, origin))
        cos_t, sin_t = np.cos(angle[joint][..., :width]), np.sin(angle[joint][..., :width])
        x_c = cos_t * x_axis + sin_t * y_axis  # x axis of F_j Rz(theta_j + q_j): the common normal
        y_c = cos_t * y_axis - sin_t * x_axis
        o_after = origin + d[joint] * z_axis + a[joint] * x_c
        y_after = cos_a[joint] * y_c + sin_a[joint] * z_axis
        if record is not None:
            record.append((z_base, o_base, x_c, y_after, o_after))
        z_alpha = cos_a[joint] * z_axis - sin_a[joint] * y_c
        for column in np.flatnonzero(free_joint == joint):
            kind = free_kind[column]
            if kind == 0:
                omega, v = None, z_axis
            elif kind == 1:
                omega, v = z_axis, _cross3(origin, z_axis)
            elif kind == 2:
                omega, v = None, x_c
            else:
                omega = x_c if kind == 3 else y_after
                v = _cross3(o_after, omega)
            # zero for the groups whose target this joint does not move
            weight = np.where(joint < carrier, factor[column], 0.0)
            if omega is None:
                twists[:3, column] = 0.0
            else:
                np.multiply(omega, weight, out=twists[:3, column])
            np.multiply(v, weight, out=twists[3:, column])
        x_axis = cos_b[joint] * x_c - sin_b[joint] * z_alpha
        z_axis = sin_b[joint] * x_c + cos_b[joint] * z_alpha
        y_axis, origin = y_after, o_after
    if component_major:
        return carried, twists, turns
    rotation = np.ascontiguousarray(carried[:3].transpose(2, 3, 1, 0))  # (B, U, 3 rows, 3 columns)
    origin = np.ascontiguousarray(carried[3].transpose(1, 2, 0))
    twists = np.ascontiguousarray(twists.transpose(2, 3, 0, 1))
    if turns is None:
        return rotation, origin, twists
    return rotation, origin, twists, np.ascontiguousarray(turns.transpose(2, 3, 0, 1))


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of vectors stored component-first, ``(3, ...)``."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products of vectors stored component-first, ``(3, ...)``: element-wise, the same in any batch."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _points(model: RefinedModel, rotation: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Base-frame target positions ``(B, N, 3)`` in the grouped (sorted) point order."""
    g = model.groups
    out = np.empty((rotation.shape[0], g["local"].shape[0], 3))
    stops = np.r_[g["starts"][1:], g["local"].shape[0]]
    for unit, (begin, end) in enumerate(zip(g["starts"], stops, strict=True)):
        out[:, begin:end] = g["local"][begin:end] @ np.swapaxes(rotation[:, unit], -1, -2) + origin[:, unit, None, :]
    return out


def _point_jacobian(model: RefinedModel, points: np.ndarray, twists: np.ndarray) -> np.ndarray:
    """``d p / d x_kin`` ``(B, N, 3, n_kin)`` from the group twists (distances criterion)."""
    group = model.groups["group"]
    omega, v = twists[:, group, :3], twists[:, group, 3:]
    return v + np.cross(omega, points[..., None], axisa=2, axisb=2, axisc=2)


#: Largest ``m n k`` of one matrix product in :meth:`_Batch.normal_equations`: OpenBLAS runs a product this
#: small on the calling thread (``GEMM_MULTITHREAD_THRESHOLD`` 4 x 65536), where each row of the result comes
#: out the same wherever it sits in the matrix; larger products may be split over threads, which changed the
#: last bits of a draw with the batch size (and oversubscribes the Monte Carlo's worker processes).
_PRODUCT_SIZE = 4 * 65536


def _unit_classes(groups: dict) -> list[dict]:
    """The groups, by their number of points: for each class of ``n`` points, ``units (U_c,)``, ``points
    (U_c, n)`` (their positions in the grouped order) and ``local (U_c, 4, n)``, the rows ``s_x, s_y, s_z, 1``
    of their points, so that ``[R_u | o_u] @ local[u]`` gives the points ``R_u s_k + o_u`` of group u."""
    classes = []
    counts = groups["count"].astype(int)
    for size in np.unique(counts):
        units = np.flatnonzero(counts == size)
        points = groups["starts"][units][:, None] + np.arange(size)
        local = np.ones((units.size, 4, size))
        local[:, :3] = np.swapaxes(groups["local"][points], 1, 2)
        classes.append(
            {"units": units, "points": points, "local": local, "draws": max(1, _PRODUCT_SIZE // (12 * size))}
        )
    return classes


def _centred_moments(groups: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per group: the mean local vector ``(U, 3)``, a root ``L (U, 3, 3)`` of ``K = tr(C) I - C`` (``L L^T = K``,
    C the centred second moment of the local vectors, K positive semi-definite) and ``sqrt(n) (U, 1, 1)``."""
    count = groups["count"]
    mean = groups["s1"] / count[:, None]
    centred = groups["s2"] - count[:, None, None] * mean[:, :, None] * mean[:, None, :]
    inertia = np.trace(centred, axis1=1, axis2=2)[:, None, None] * np.eye(3) - centred
    eigenvalues, vectors = np.linalg.eigh(inertia)
    root = vectors * np.sqrt(np.clip(eigenvalues, 0.0, None))[:, None, :]
    return mean, root, np.sqrt(count)[:, None, None]


def _base_twists(model: RefinedModel, x_base: np.ndarray) -> np.ndarray:
    """Twists ``(B, 6, n_base)`` of the free base corrections, in the base frame.

    ``T(x) p = T_0 (R p + t)``: d/dt_a is ``R_0 e_a`` in the tracker frame, ``R^T e_a`` in the base
    frame; d/dr_k is ``R_0 dR_k p``, i.e. ``omega x p`` with ``[omega]x = R^T dR_k``.
    """
    rotation, _, derivatives = base_correction(x_base)
    columns = [np.concatenate([np.zeros_like(rotation[:, 0]), rotation[:, axis]], axis=-1) for axis in range(3)]
    for derivative in derivatives:
        skew = np.swapaxes(rotation, -1, -2) @ derivative
        omega = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=-1)
        columns.append(np.concatenate([omega, np.zeros_like(omega)], axis=-1))
    chosen = [columns[k] for k in np.flatnonzero(model.base_free)]
    return np.stack(chosen, axis=-1) if chosen else np.zeros((x_base.shape[0], 6, 0))


class _Batch:
    """Residuals and normal equations of a stack of draws (pure functions of the unknowns)."""

    def __init__(self, model: RefinedModel, measured: np.ndarray, start: np.ndarray, base_start: np.ndarray | None):
        self.model, self.start, self.base_start = model, start, base_start
        order = model.groups["order"]
        if model.criterion == "distances":
            self.measured = measured[:, order]
            diff = measured[:, model.pair_i] - measured[:, model.pair_j]
            self.distances = np.sqrt(np.einsum("bpc,bpc->bp", diff, diff))
            return
        self.classes = _unit_classes(model.groups)
        self.mean_local, self.moment_root, self.root_count = _centred_moments(model.groups)
        # measured points coordinate-major (B, 3, N) in the grouped order: one gather of the flat rows
        n_draws, n_points = measured.shape[:2]
        columns = (3 * order[None, :] + np.arange(3)[:, None]).ravel()
        self.measured_columns = measured.reshape(n_draws, -1)[:, columns].reshape(n_draws, 3, n_points)
        # the measurements in the robot base frame, R_0^T (m - t_0), once here when the base frame is held
        self.target = None
        if not model.base_free.any():
            self.target = self._by_class(self._in_base(np.arange(n_draws), np.zeros((n_draws, 6))))

    def _by_class(self, columns: np.ndarray) -> list[np.ndarray]:
        """``(B, 3, N)`` in the grouped order -> per class of groups ``(U_c, B, 3, n)`` (groups first)."""
        return [np.ascontiguousarray(np.moveaxis(columns[:, :, c["points"]], 2, 0)) for c in self.classes]

    def _in_base(self, index: np.ndarray, x_base: np.ndarray) -> np.ndarray:
        """``R_tot^T (m - t_tot)`` ``(B, 3, N)`` for ``T_tot = T_0 T(x_b)``: the measurements in the corrected base frame."""
        assert self.base_start is not None  # the points criterion (the only caller) has a base frame
        r0 = self.base_start[index, :3, :3]
        total = r0
        if self.model.base_free.any():
            base_rotation, _, _ = base_correction(x_base)
            total = r0 @ base_rotation
        shift = (r0 @ x_base[:, :3, None])[..., 0] + self.base_start[index, :3, 3]
        return np.swapaxes(total, 1, 2) @ (_rows(self.measured_columns, index) - shift[:, :, None])

    def unpack(self, x: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        values = self.start[index].copy()
        values[:, self.model.free] = x[:, : self.model.n_kinematic]
        x_base = np.zeros((x.shape[0], 6))
        x_base[:, self.model.base_free] = x[:, self.model.n_kinematic :]
        return values, np.zeros((x.shape[0], 0)), x_base

    def tracker(self, x_base: np.ndarray, index: np.ndarray) -> np.ndarray:
        return _tracker(self.base_start, x_base, index)

    def normal_equations(self, x: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cost ``(B,)``, ``J_s^T J_s`` ``(B, p, p)`` and ``J_s^T r`` ``(B, p)`` (scaled columns).

        Points criterion: with ``r_k = R_tot e_k`` (``R_tot`` orthonormal) and ``J_k = R_tot W_k Xi``,
        ``J^T J = sum_groups Xi^T (sum_k W_k^T W_k) Xi`` (moments of the local vectors, no per-point
        work) and ``J^T r = sum_groups Xi^T sum_k (p_k x e_k, e_k)``.
        """
        model = self.model
        values, _, x_base = self.unpack(x, index)
        groups = model.groups
        rotation, origin, twists = _kinematics(groups["config_q"], groups["carrier"], model.free, values, model.x_scale)
        if model.criterion == "distances":
            return self._distance_equations(_points(model, rotation, origin), twists, index)
        batch, units = rotation.shape[:2]
        if self.target is None:
            targets = self._by_class(self._in_base(index, x_base))
        else:
            targets = [_rows(target, index, axis=1) for target in self.target]
        frames = np.concatenate([rotation, origin[..., None]], axis=-1)  # (B, U, 3, 4): [R_u | o_u]
        squares = np.empty((units, batch))
        moments = np.empty((batch, units, 4, 3))
        for group, target in zip(self.classes, targets, strict=True):
            chosen, local = group["units"], group["local"]
            count, size = chosen.size, local.shape[-1]
            stacked = np.ascontiguousarray(np.swapaxes(frames[:, chosen], 0, 1)).reshape(count, batch * 3, 4)
            # the errors e_k = R_u s_k + o_u - m_k of the group's points, (U_c, 3B, n): one product per group
            # and per block of draws (rows of 3 coordinates), then F = sum_k [s_k; 1] e_k^T in one product
            error = np.empty((count, batch * 3, size))
            inner = np.empty((count, 4, batch * 3))
            for begin in range(0, batch, group["draws"]):
                rows = slice(3 * begin, 3 * min(batch, begin + group["draws"]))
                np.matmul(stacked[:, rows], local, out=error[:, rows])
                error[:, rows] -= target.reshape(count, batch * 3, size)[:, rows]
                np.matmul(local, np.swapaxes(error[:, rows], 1, 2), out=inner[:, :, rows])
            flat = error.reshape(count, batch, 3 * size)
            squares[chosen] = np.einsum("ubk,ubk->ub", flat, flat)
            moments[:, chosen] = np.moveaxis(inner.reshape(count, 4, batch, 3), 2, 0)
        cost = 0.5 * squares.sum(axis=0)
        # per group F = sum_k s_k e_k^T and sum_k e_k (moments), then
        # sum_k p_k x e_k = R_u sum_k s_k x R_u^T e_k + o_u x sum_k e_k = R_u axial(F R_u) + o_u x sum_k e_k
        error_sum = moments[:, :, 3]
        product = moments[:, :, :3] @ rotation
        axial = np.stack(
            [
                product[..., 1, 2] - product[..., 2, 1],
                product[..., 2, 0] - product[..., 0, 2],
                product[..., 0, 1] - product[..., 1, 0],
            ],
            axis=-1,
        )
        torque = (rotation @ axial[..., None])[..., 0] + _cross(origin, error_sum)
        sums = np.concatenate([torque, error_sum], axis=-1)  # (B, U, 6): sum_k (p_k x e_k, e_k)
        if model.base_free.any():
            base = _base_twists(model, x_base) * model.x_scale[model.n_kinematic :]
            xi = np.concatenate([twists, np.broadcast_to(base[:, None], twists.shape[:3] + base.shape[-1:])], axis=-1)
        else:
            xi = twists
        gradient = np.einsum("busk,bus->bk", xi, sums)
        # J^T J = sum_u Xi_u^T G_u Xi_u = Z^T Z with Z_u = [L_u^T R_u^T omega; sqrt(n_u) (v + omega x c_u)]:
        # about the centroid c_u of the group's points, sum_k |v + omega x p_k|^2 splits into n_u |v + omega x c_u|^2
        # and omega^T R_u K_u R_u^T omega, K_u = tr(C) I - C with C the centred moment of the local vectors
        # (constant, K_u = L_u L_u^T); one stacked product (B, p, 6U) @ (B, 6U, p) then sums the groups
        omega, v = xi[:, :, :3], xi[:, :, 3:]
        centroid = (rotation @ self.mean_local[..., None])[..., 0] + origin
        c0, c1, c2 = (centroid[:, :, axis, None] for axis in range(3))
        factor = np.empty(xi.shape)
        np.matmul(np.swapaxes(rotation @ self.moment_root, -1, -2), omega, out=factor[:, :, :3])
        factor[:, :, 3] = v[:, :, 0] + omega[:, :, 1] * c2 - omega[:, :, 2] * c1
        factor[:, :, 4] = v[:, :, 1] + omega[:, :, 2] * c0 - omega[:, :, 0] * c2
        factor[:, :, 5] = v[:, :, 2] + omega[:, :, 0] * c1 - omega[:, :, 1] * c0
        factor[:, :, 3:] *= self.root_count
        batch, units, _, width = xi.shape
        stacked = factor.reshape(batch, units * 6, width)
        normal = np.swapaxes(stacked, -1, -2) @ stacked
        return cost, normal, gradient

    def _distance_equations(self, points, twists, index):
        """Distances criterion in twist form: the row of pair (i, j) is ``w_i^T Xi_a - w_j^T Xi_b`` with
        ``w = (p x u, u)``, ``u`` the unit vector from j to i and a, b the groups of i and j, so the normal
        equations are ``Xi^T G Xi`` with G ``(6U, 6U)`` accumulated from 6-vectors (no per-point Jacobian)."""
        model = self.model
        batch, units = points.shape[0], twists.shape[1]
        group = model.groups["group"]
        big = np.zeros((batch, units, 6, units, 6))
        vector = np.zeros((batch, units, 6))
        cost = np.zeros(batch)
        for begin in range(0, model.pair_i.size, _PAIR_CHUNK):
            i = model.sorted_i[begin : begin + _PAIR_CHUNK]
            j = model.sorted_j[begin : begin + _PAIR_CHUNK]
            diff = points[:, i] - points[:, j]
            distance = np.sqrt(np.einsum("bpc,bpc->bp", diff, diff))
            residuals = distance - self.distances[index, begin : begin + _PAIR_CHUNK]
            unit = diff / distance[..., None]
            w_i = np.concatenate([np.cross(points[:, i], unit), unit], axis=-1)
            w_j = np.concatenate([np.cross(points[:, j], unit), unit], axis=-1)
            cost += 0.5 * np.einsum("bp,bp->b", residuals, residuals)
            # split the chunk where the (group i, group j) block changes
            g_i, g_j = group[i], group[j]
            cuts = np.flatnonzero((np.diff(g_i) != 0) | (np.diff(g_j) != 0)) + 1
            for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, i.size], strict=True):
                a, b = g_i[lo], g_j[lo]
                wi, wj, r = w_i[:, lo:hi], w_j[:, lo:hi], residuals[:, None, lo:hi]
                ti, tj = np.swapaxes(wi, 1, 2), np.swapaxes(wj, 1, 2)
                big[:, a, :, a] += ti @ wi
                big[:, b, :, b] += tj @ wj
                cross_term = ti @ wj
                big[:, a, :, b] -= cross_term
                big[:, b, :, a] -= np.swapaxes(cross_term, 1, 2)
                vector[:, a] += (r @ wi)[:, 0]
                vector[:, b] -= (r @ wj)[:, 0]
        xi = twists.reshape(batch, units * 6, -1)
        normal = np.swapaxes(xi, 1, 2) @ big.reshape(batch, units * 6, units * 6) @ xi
        gradient = (vector.reshape(batch, 1, units * 6) @ xi)[:, 0]
        return cost, normal, gradient


class _PointBatch:
    """Residuals and normal equations of a stack of draws of an extended model, point by point.

    The joint model turns every joint by ``C(q) e`` (:mod:`robotcal.kinematics.joint_model`), different in every
    draw and at every point, so no two points share a carrier frame: the chain is composed per point (the groups
    of :class:`_Batch` become single points, with configurations per draw), a per-joint target turned by its own
    deflected joint. The Jacobian of the joint-model values is ``sum_j (d p / d q_j) C_j``, the twists of the
    joint variables weighted by the columns of C. The per-point Jacobian ``(B, N, 3, p)`` is formed explicitly
    (points criterion: ``J^T J`` one stacked product; distances: the pair rows in chunks of pairs).
    """

    def __init__(self, model: RefinedModel, measured: np.ndarray, start: np.ndarray, base_start: np.ndarray | None):
        self.model, self.start, self.base_start = model, start, base_start
        self.measured = measured
        assert model.joint_columns is not None  # this batch serves the models with a joint model
        self.columns = model.joint_columns[:, :, model.extra_free]  # (N, n, m_free)
        # the points in falling order of their carrier: the gradient's chain drops each once its frame is reached
        self.by_carrier = np.argsort(-model.carrier, kind="stable")
        if model.criterion == "distances":
            diff = measured[:, model.pair_i] - measured[:, model.pair_j]
            self.distances = np.sqrt(np.einsum("bpc,bpc->bp", diff, diff))
        elif not model.base_free.any():  # the measurements in the robot base frame, once
            self.in_base = self._in_base(np.arange(measured.shape[0]), np.zeros((measured.shape[0], 6)))

    def _in_base(self, index: np.ndarray, x_base: np.ndarray) -> np.ndarray:
        """``R_tot^T (m - t_tot)`` ``(B, N, 3)`` for ``T_tot = T_0 T(x_b)``."""
        assert self.base_start is not None  # the points criterion (the only caller) has a base frame
        r0 = self.base_start[index, :3, :3]
        total = r0 @ base_correction(x_base)[0] if self.model.base_free.any() else r0
        shift = (r0 @ x_base[:, :3, None])[..., 0] + self.base_start[index, :3, 3]
        return (self.measured[index] - shift[:, None, :]) @ total

    def unpack(self, x: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        model = self.model
        values = self.start[index].copy()
        values[:, model.free] = x[:, : model.n_kinematic]
        extras = x[:, model.n_kinematic : model.n_kinematic + model.n_extra]
        x_base = np.zeros((x.shape[0], 6))
        x_base[:, model.base_free] = x[:, model.n_kinematic + model.n_extra :]
        return values, extras, x_base

    def tracker(self, x_base: np.ndarray, index: np.ndarray) -> np.ndarray:
        return _tracker(self.base_start, x_base, index)

    def point_jacobian(self, x: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Base-frame points ``(3, B, N)`` and ``d p / d z`` ``(3, p, B, N)`` in the scaled unknowns, components
        first (the layout :func:`_kinematics` composes in: element-wise operations on contiguous planes)."""
        model = self.model
        values, extras, x_base = self.unpack(x, index)
        q = model.q + np.einsum("pjm,bm->bpj", self.columns, extras)  # (B, N, n): the deflected joints
        carrier = model.carrier
        frame, twists, turns = _kinematics(
            q, carrier, model.free, values, model.x_scale, joint_twists=True, component_major=True
        )  # fmt: skip
        points = self._carried_points(frame, q, np.arange(q.shape[1]))
        beside = points[:, None]
        parts = [twists[3:] + _cross3(twists[:3], beside)]
        if model.n_extra:  # d p / d e = sum_j (d p / d q_j) C_j
            moved = turns[3:] + _cross3(turns[:3], beside)  # (3, n, B, N)
            scale = model.x_scale[model.n_kinematic : model.n_kinematic + model.n_extra]
            parts.append(np.einsum("cjbp,pjm->cmbp", moved, self.columns * scale))
        if model.base_free.any():
            base = _base_twists(model, x_base) * model.x_scale[model.n_kinematic + model.n_extra :]  # (B, 6, nb)
            base = np.moveaxis(base, 0, -1)[..., None]  # (6, nb, B, 1)
            parts.append(base[3:] + _cross3(base[:3], beside))
        return points, np.concatenate(parts, axis=1)

    def _carried_points(self, frame: np.ndarray, q: np.ndarray, order: np.ndarray) -> np.ndarray:
        """Base-frame points ``(3, B, N)`` from the carrier frames ``(4, 3, B, N)`` and the deflected joints ``q`` of
        the points ``order`` of the capture."""
        model, carrier = self.model, self.model.carrier[order]
        local = np.broadcast_to(model.vectors[order].T[:, None, :], (3,) + q.shape[:2]).copy()  # (3, B, N)
        on_joint = np.flatnonzero(carrier < model.free.shape[0])
        if on_joint.size:  # a per-joint target turned by its own (deflected) joint, eq. 5-1
            angle = q[:, on_joint, carrier[on_joint]]
            cos, sin = np.cos(angle), np.sin(angle)
            x_part, y_part = local[0][:, on_joint], local[1][:, on_joint]
            local[0][:, on_joint], local[1][:, on_joint] = cos * x_part - sin * y_part, sin * x_part + cos * y_part
        return frame[0] * local[0] + frame[1] * local[1] + frame[2] * local[2] + frame[3]

    def gradient(self, x: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cost ``(B,)`` and ``J_s^T r`` ``(B, p)`` without forming the Jacobian (points criterion; distances: the
        gradient of :meth:`normal_equations`).

        Column ``c`` of the Jacobian at point k is the twist ``(omega, o x omega)`` of its screw axis (or ``(0, v)``)
        applied to ``p_k`` (:func:`_kinematics`), so its product with the error ``e_k`` is
        ``omega . (p_k x e_k - o x e_k)`` (``v . e_k``): per joint two arms ``p x e - o x e`` (anchors ``o_B``,
        ``o_F``), per column one dot product summed over the points. The joint model's column m is
        ``sum_j C_jm dp/dq_j``, and ``dp/dq_j . e`` is theta_j's dot product.
        """
        model = self.model
        if model.criterion != "points":
            cost, _, gradient = self.normal_equations(x, index)
            return cost, gradient
        values, extras, x_base = self.unpack(x, index)
        order, n_kin, n_extra = self.by_carrier, model.n_kinematic, model.n_extra
        columns = self.columns[order]
        deflection = np.zeros((x.shape[0],) + model.q.shape)  # C(q) e, (B, N, n): a few products, not an einsum
        for value, column in zip(extras.T, np.moveaxis(columns, -1, 0), strict=True):
            deflection += column * value[:, None, None]
        q = model.q[order] + deflection  # the deflected joints
        carrier = model.carrier[order]
        record: list = []
        frame, _, _ = _kinematics(q, carrier, np.zeros_like(model.free), values, component_major=True, record=record)
        points = self._carried_points(frame, q, order)
        target = self._in_base(index, x_base) if model.base_free.any() else _rows(self.in_base, index)
        error = points - np.moveaxis(target[:, order], -1, 0)  # (3, B, N)
        moment = _cross3(points, error)
        gradient = np.empty((x.shape[0], model.n_free))
        free_joint, free_kind = np.nonzero(model.free)
        weighted = np.zeros((n_extra,) + q.shape[:2]) if n_extra else None  # (m, B, N)
        weights = np.moveaxis(columns * model.x_scale[n_kin : n_kin + n_extra], 0, -1)  # (n, m, N)
        for joint, (z_axis, origin, x_c, y_after, o_after) in enumerate(record):
            # the points joint j carries further (the first ``moved``), then those it turns (per-joint targets)
            reached, moved = z_axis.shape[-1], x_c.shape[-1]
            about_origin = moment[..., :reached] - _cross3(origin, error[..., :reached])
            about_after = moment[..., :moved] - _cross3(o_after, error[..., :moved])
            arms = {0: (z_axis, error), 1: (z_axis, about_origin), 2: (x_c, error), 3: (x_c, about_after)}
            arms[4] = (y_after, about_after)
            for column in np.flatnonzero(free_joint == joint):
                axis, arm = arms[free_kind[column]]
                gradient[:, column] = _dot3(axis[..., :moved], arm[..., :moved]).sum(axis=-1) * model.x_scale[column]
            if weighted is not None:  # d cost / d q_j at every point it moves
                weighted[..., :reached] += _dot3(z_axis, about_origin) * weights[joint][:, None, :reached]
        if weighted is not None:
            gradient[:, n_kin : n_kin + n_extra] = weighted.sum(axis=-1).T
        if model.base_free.any():
            base = _base_twists(model, x_base) * model.x_scale[n_kin + n_extra :]  # (B, 6, nb)
            total_moment, total_error = moment.sum(axis=-1), error.sum(axis=-1)  # (3, B)
            omega, v = np.moveaxis(base[:, :3], 1, 0), np.moveaxis(base[:, 3:], 1, 0)  # (3, B, nb)
            gradient[:, n_kin + n_extra :] = _dot3(omega, total_moment[..., None]) + _dot3(v, total_error[..., None])
        return 0.5 * _dot3(error, error).sum(axis=-1), gradient

    def normal_equations(self, x: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cost ``(B,)``, ``J_s^T J_s`` ``(B, p, p)`` and ``J_s^T r`` ``(B, p)`` (scaled columns)."""
        model = self.model
        points, jacobian = self.point_jacobian(x, index)
        width, batch = jacobian.shape[1], jacobian.shape[2]
        if model.criterion == "points":
            if model.base_free.any():
                target = self._in_base(index, self.unpack(x, index)[2])
            else:
                target = _rows(self.in_base, index)
            error = np.ascontiguousarray((points - np.moveaxis(target, -1, 0)).transpose(1, 0, 2)).reshape(batch, -1)
            flat = np.ascontiguousarray(jacobian.transpose(2, 1, 0, 3)).reshape(batch, width, -1)  # (B, p, 3N)
            gradient = (flat @ error[..., None])[..., 0]
            return 0.5 * np.einsum("bk,bk->b", error, error), flat @ np.swapaxes(flat, 1, 2), gradient
        points = np.moveaxis(points, 0, -1)  # (B, N, 3)
        jacobian = jacobian.transpose(2, 3, 0, 1)  # (B, N, 3, p)
        cost, normal, gradient = np.zeros(batch), np.zeros((batch, width, width)), np.zeros((batch, width))
        assert model.pair_i is not None and model.pair_j is not None  # the distances criterion has its pairs
        for begin in range(0, model.pair_i.size, _PAIR_CHUNK):
            i = model.pair_i[begin : begin + _PAIR_CHUNK]
            j = model.pair_j[begin : begin + _PAIR_CHUNK]
            diff = points[:, i] - points[:, j]
            distance = np.sqrt(np.einsum("bpc,bpc->bp", diff, diff))
            residuals = distance - _rows(self.distances, index)[:, begin : begin + _PAIR_CHUNK]
            rows = np.einsum("bpc,bpck->bpk", diff / distance[..., None], jacobian[:, i] - jacobian[:, j])
            cost += 0.5 * np.einsum("bp,bp->b", residuals, residuals)
            normal += np.swapaxes(rows, 1, 2) @ rows
            gradient += (residuals[:, None] @ rows)[:, 0]
        return cost, normal, gradient


def _tracker(base_start: np.ndarray | None, x_base: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``T_0 T(x_b)`` per draw ``(B, 4, 4)``."""
    assert base_start is not None  # asked only of the points criterion, which has a base frame
    rotation, _, _ = base_correction(x_base)
    delta = np.broadcast_to(np.eye(4), (x_base.shape[0], 4, 4)).copy()
    delta[:, :3, :3] = rotation
    delta[:, :3, 3] = x_base[:, :3]
    return base_start[index] @ delta


def _rows(array: np.ndarray, index: np.ndarray, axis: int = 0) -> np.ndarray:
    """``array`` at ``index`` along ``axis``, without a copy when ``index`` is every row in order (the first
    evaluation of a batch)."""
    if index.size == array.shape[axis] and np.array_equal(index, np.arange(index.size)):
        return array
    return np.take(array, index, axis=axis)


def reference_unknowns(model: RefinedModel) -> np.ndarray:
    """The free unknowns ``(p,)`` of the noise-free solution [mm, rad]: kinematic, joint-model, base corrections
    (0: the base frame's corrections are taken from :attr:`RefinedModel.reference_tracker`)."""
    return np.concatenate(
        [
            model.reference_values[model.free],
            model.reference_extras[model.extra_free],
            np.zeros(int(model.base_free.sum())),
        ]
    )


def reference_jacobian(
    model: RefinedModel,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    """The model at the noise-free solution: its base-frame points and their Jacobian in the unknowns.

    Returns
    -------
    points : ndarray, shape (N, 3)
        Base-frame target positions [mm], in the order ``order`` of the capture's points.
    jacobian : ndarray, shape (N, 3, p)
        ``d p / d x`` in the unscaled unknowns of :func:`reference_unknowns` (base corrections at 0).
    order : ndarray of int, shape (N,)
        The capture row of every point (the grouped order of :class:`_Batch`; the capture's own order for an
        extended model).
    pairs : tuple of two int arrays or None
        Distances criterion: the pairs' rows in ``points``, in the order of ``model.pair_i, model.pair_j``.
    """
    start = model.reference_values[None]
    base = None if model.reference_tracker is None else model.reference_tracker[None]
    x = reference_unknowns(model)[None]
    measured = np.zeros((1, model.q.shape[0], 3))  # the Jacobian does not depend on the measurements
    if model.joint_model is not None:  # point by point, in the capture's order
        problem = _PointBatch(model, measured, start, base)
        points, full = problem.point_jacobian(x, np.arange(1))
        points, full = points[:, 0].T, full[:, :, 0].transpose(2, 0, 1) / model.x_scale  # (N, 3), unscaled columns
        order = np.arange(model.q.shape[0])
        pairs = None if model.pair_i is None or model.pair_j is None else (model.pair_i, model.pair_j)
        return points, full, order, pairs
    batch = _Batch(model, measured, start, base)
    values, _, x_base = batch.unpack(x, np.arange(1))
    rotation, origin, twists = _kinematics(model.groups["config_q"], model.groups["carrier"], model.free, values)
    points = _points(model, rotation, origin)[0]
    full = _point_jacobian(model, points[None], twists)[0]  # (N, 3, n_kin), base frame, grouped order
    if model.criterion == "points":
        base = _base_twists(model, x_base)[0]  # (6, n_base)
        base_columns = base[3:][None] + np.cross(base[:3].T[None], points[:, None, :]).transpose(0, 2, 1)
        full = np.concatenate([full, base_columns], axis=-1)
    pairs = None if model.sorted_i is None or model.sorted_j is None else (model.sorted_i, model.sorted_j)
    return points, full, model.groups["order"], pairs
