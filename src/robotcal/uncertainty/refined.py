"""Batched least-squares refinement of many captures at once: the refined (deployed) model's Monte Carlo.

A user deploys CPA followed by refinement (thesis ch. 4.5.7, eqs 4-101/4-102). The Monte Carlo of
that model repeats capture -> CPA -> refinement for every draw. Refining draw after draw with
``scipy.optimize.least_squares`` costs ~0.1 s per draw; here all draws of a batch are refined
together by one vectorised Levenberg-Marquardt iteration over the batch:

* the free set (kinematic parameters and base-frame corrections) and the column scale ``x_scale``
  are those :func:`robotcal.identification.refine.refine_parameters` chooses on the noise-free
  capture (its rank test on the data), shared by every draw: the structure of the problem does not
  change with the noise, only the values do;
* each draw starts from its own CPA estimate (and, for the points criterion, its own CPA base
  frame), as a user would; parameters outside the free set keep the draw's CPA value;
* the analytic Jacobian is that of :func:`robotcal.kinematics.jacobian.target_jacobian` written in
  screw form: the column of every parameter is ``v + omega x p`` with a twist ``(omega, v)`` shared
  by all points whose target is carried by the same frame (a circle's points, per-joint targets),
  so the link chain is evaluated per group of points, not per point, and the points criterion's
  ``J^T J`` follows from per-group moments of the target vectors (no per-point Jacobian at all);
* per-draw normal equations ``(J_s^T J_s + lambda diag(J_s^T J_s)) dz = -J_s^T r`` in the scaled
  variables ``z = x / x_scale`` are solved for the whole batch by one stacked LAPACK call;
* every draw has its own damping ``lambda`` (0 while steps reduce the cost: Gauss-Newton near the
  optimum), its own acceptance test and its own convergence test (scaled step
  ``|dz| <= xtol (1 + |z|)``); draws that do not converge within ``max_iterations`` or become
  non-finite are reported as failed, never kept silently.

Points criterion (eq. 4-101): residuals ``T(x_b) p_k(x) - m_k`` with ``T = T_0 [Rz Ry Rx | t]`` as in
``refine_parameters``; the base corrections are free only when the scenario estimates the base
frame (``base_frame = "registered"``), else ``T_0`` is the given ``tracker_from_base`` and is held.
Distances criterion (eq. 4-102): residuals ``|p_i - p_j| - |m_i - m_j|`` over every pair of distinct
measurements; a pair's row is ``w_i^T Xi_a - w_j^T Xi_b`` with ``w = (p x u, u)``, accumulated in
fixed chunks of pairs so that memory stays bounded by ``batch x chunk`` (about 250x slower than the
points criterion for the 270-point demo capture: 36,180 pairs against 810 coordinates).

Every per-draw quantity is computed by element-wise operations, stacked matrix products and stacked
LAPACK solves, whose per-item results do not depend on the size of the stack: a draw's result is the
same whatever batch it is refined in (a batch of one is padded to two, see
:func:`robotcal.uncertainty.montecarlo.draw_block`).

References
----------
Thesis ch. 4.5.7 (eqs 4-101, 4-102); JCGM 101:2008 §5.9, §7; Marquardt (1963).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityWarning, InputError
from robotcal.geometry._vectors import cross as _cross
from robotcal.geometry.transforms import rot_z
from robotcal.identification.refine import (
    CRITERIA,
    base_correction,
    capture_target_index,
    capture_turning_joints,
    measurement_pairs,
    refine_parameters,
)
from robotcal.kinematics.forward import joint_frames
from robotcal.kinematics.model import ParameterSet, ReflectorMount

__all__ = ["RefinedModel", "RefinedBatch", "prepare_refined_model", "refine_batch", "refined_covariance"]

#: Pairs handled at once by the distances criterion (fixed, so that sums do not depend on the batch size;
#: with ``REFINE_BATCH`` = 500 draws one chunk's arrays take ~12 MB each).
_PAIR_CHUNK = 512


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
    turning : ndarray of int, shape (n_points,)
    reflector : ReflectorMount
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
    """

    criterion: str
    free: np.ndarray
    base_free: np.ndarray
    x_scale: np.ndarray
    q: np.ndarray
    turning: np.ndarray
    reflector: ReflectorMount
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

    @property
    def n_free(self) -> int:
        return int(self.x_scale.size)

    @property
    def n_kinematic(self) -> int:
        return int(self.free.sum())


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
    """

    values: np.ndarray
    tracker_from_base: np.ndarray | None
    converged: np.ndarray
    iterations: np.ndarray
    cost: np.ndarray


def prepare_refined_model(
    capture: Capture,
    start: ParameterSet,
    reflector: ReflectorMount,
    *,
    criterion: str = "points",
    tracker_from_base=None,
    estimate_base: bool = True,
    max_iterations: int = 50,
    xtol: float = 1e-10,
) -> RefinedModel:
    """Refine the noise-free ``capture`` once with :func:`refine_parameters` and keep its structure.

    Parameters
    ----------
    capture : Capture
        The noise-free capture [mm].
    start : ParameterSet
        Start values (the noise-free CPA result) [mm, rad].
    reflector : ReflectorMount
    criterion : {"points", "distances"}
    tracker_from_base : array_like, shape (4, 4), optional
        Points criterion: the given base frame (held unless ``estimate_base``).
    estimate_base : bool
        Points criterion: estimate the 6 base-frame corrections.
    max_iterations : int
        Jacobian evaluations per draw before a draw is declared not converged.
    xtol : float
        Convergence test on the scaled step ``|dz| <= xtol (1 + |z|)``.
    """
    if criterion not in CRITERIA:
        raise InputError(f"`criterion` must be one of {CRITERIA}; got {criterion!r}")
    with warnings.catch_warnings():
        # the parameters the data cannot determine are recorded in `held` and stay at the CPA value
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine_parameters(
            capture,
            start,
            reflector,
            criterion=criterion,
            tracker_from_base=tracker_from_base if criterion == "points" else None,
            estimate_base=estimate_base,
        )
    turning = capture_turning_joints(capture, reflector)
    q = start.robot.model_joint_variables(capture.readings)
    groups = _group_points(q, turning, reflector, start.robot.n_joints)
    for value in groups.values():
        value.setflags(write=False)
    pair_i = pair_j = sorted_i = sorted_j = None
    if criterion == "distances":
        pair_i, pair_j, _ = measurement_pairs(capture.readings, capture_target_index(capture, reflector))
        position = np.empty_like(groups["order"])
        position[groups["order"]] = np.arange(position.size)
        sorted_i, sorted_j = position[pair_i], position[pair_j]
        # pairs ordered by the groups of their two points: each block shares the two groups' twists
        block = groups["group"][sorted_i] * groups["count"].size + groups["group"][sorted_j]
        pair_order = np.argsort(block, kind="stable")
        pair_i, pair_j = pair_i[pair_order], pair_j[pair_order]
        sorted_i, sorted_j = _frozen(sorted_i[pair_order], int), _frozen(sorted_j[pair_order], int)
    return RefinedModel(
        criterion=criterion,
        free=_frozen(result.free, bool),
        base_free=_frozen(result.base_free, bool),
        x_scale=_frozen(result.x_scale),
        q=_frozen(q),
        turning=_frozen(turning, int),
        reflector=reflector,
        pair_i=None if pair_i is None else _frozen(pair_i, int),
        pair_j=None if pair_j is None else _frozen(pair_j, int),
        reference_values=_frozen(result.parameters.values),
        reference_tracker=None if result.tracker_from_base is None else _frozen(result.tracker_from_base),
        held=tuple(result.held),
        free_names=tuple(result.free_names),
        groups=groups,
        sorted_i=sorted_i,
        sorted_j=sorted_j,
        max_iterations=int(max_iterations),
        xtol=float(xtol),
    )


# ------------------------------------------------------------------------------ model and Jacobian


def _group_points(q: np.ndarray, turning: np.ndarray, reflector: ReflectorMount, n_joints: int) -> dict:
    """Group the points by the configuration of the frame that carries their target.

    A per-joint target of circle t sits at ``F_t Rz(q_t) r_t``: ``F_t`` depends only on joints
    ``0..t-1``, which rest while joint t turns, so every point of a circle shares one frame and
    only the local vector ``s_k = Rz(q_t) r_t`` changes (a flange target: ``F_n r``, one group per
    distinct pose). The chain of link transforms is then evaluated per group, not per point.
    """
    n_points = q.shape[0]
    if reflector.frame == "flange":
        carrier = np.full(n_points, n_joints)
        local = np.broadcast_to(reflector.positions[0], (n_points, 3)).copy()
    else:
        carrier = turning.copy()
        local = (rot_z(q[np.arange(n_points), turning])[:, :3, :3] @ reflector.positions[turning][..., None])[..., 0]
    key = np.where(np.arange(n_joints)[None, :] < carrier[:, None], q, 0.0)
    key = np.concatenate([carrier[:, None].astype(float), key], axis=1)
    unique, group = np.unique(key, axis=0, return_inverse=True)
    group = group.ravel()
    order = np.argsort(group, kind="stable")
    counts = np.bincount(group, minlength=unique.shape[0])
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    s = local[order]
    sorted_group = group[order]
    s1 = np.zeros((unique.shape[0], 3))
    s2 = np.zeros((unique.shape[0], 3, 3))
    np.add.at(s1, sorted_group, s)
    np.add.at(s2, sorted_group, s[:, :, None] * s[:, None, :])
    return {
        "config_q": unique[:, 1:],
        "carrier": unique[:, 0].astype(int),
        "order": order,
        "group": sorted_group,
        "starts": starts,
        "local": s,
        "count": counts.astype(float),
        "s1": s1,
        "s2": s2,
    }


def _skew(w: np.ndarray) -> np.ndarray:
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def _kinematics(model: RefinedModel, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Carrier frames and the twists of the free kinematic parameters, per group of points.

    Returns ``rotation (B, U, 3, 3)``, ``origin (B, U, 3)`` of each group's carrier frame and
    ``twists (B, U, 6, n_kin)``: column ``(omega, v)`` such that ``dp/dx = v + omega x p`` for every
    point p of the group (base frame). These are the screw axes of
    :func:`robotcal.kinematics.jacobian.target_jacobian`: d ``(0, z_B)``; theta ``(z_B, o_B x z_B)``;
    a ``(0, x')``; alpha ``(x', o_F x x')``; beta ``(y_F, o_F x y_F)``; zero for joints at or after
    the one that turns the target.
    """
    config_q, carrier = model.groups["config_q"], model.groups["carrier"]
    frames = joint_frames(values, config_q)  # (B, U, n + 1, 4, 4)
    units = np.arange(config_q.shape[0])
    carried = frames[:, units, carrier]
    twists = np.zeros(frames.shape[:2] + (6, model.n_kinematic))
    for column, (joint, kind) in enumerate(zip(*np.nonzero(model.free), strict=True)):
        before = frames[:, :, joint, :3, :]
        if kind == 0:
            omega, v = None, before[..., 2]
        elif kind == 1:
            omega = before[..., 2]
            v = _cross(before[..., 3], omega)  # np.cross's formula, without its moveaxis copies
        else:
            angle = (values[:, joint, 1][:, None] + config_q[None, :, joint])[..., None]
            x_common = np.cos(angle) * before[..., 0] + np.sin(angle) * before[..., 1]
            o_after = frames[:, :, joint + 1, :3, 3]
            if kind == 2:
                omega, v = None, x_common
            else:
                omega = x_common if kind == 3 else frames[:, :, joint + 1, :3, 1]
                v = _cross(o_after, omega)
        active = (joint < carrier)[None, :, None]
        if omega is not None:
            twists[:, :, :3, column] = np.where(active, omega, 0.0)
        twists[:, :, 3:, column] = np.where(active, v, 0.0)
    return carried[..., :3, :3], carried[..., :3, 3], twists


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


def _group_normal(model: RefinedModel, rotation: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """``sum_k W_k^T W_k`` per group ``(B, U, 6, 6)``, ``W_k = [-[p_k]x, I]``, from moments of ``s_k``."""
    g = model.groups
    count = g["count"][None, :, None]
    first = np.einsum("buij,uj->bui", rotation, g["s1"])  # R S1
    p1 = first + count * origin
    p2 = rotation @ g["s2"][None] @ np.swapaxes(rotation, -1, -2)
    p2 = p2 + first[..., :, None] * origin[..., None, :] + origin[..., :, None] * first[..., None, :]
    p2 = p2 + count[..., None] * origin[..., :, None] * origin[..., None, :]
    out = np.zeros(rotation.shape[:2] + (6, 6))
    trace = np.einsum("buii->bu", p2)
    out[..., :3, :3] = trace[..., None, None] * np.eye(3) - p2
    out[..., :3, 3:] = _skew(p1)
    out[..., 3:, :3] = -_skew(p1)
    out[..., 3:, 3:] = count[..., None] * np.eye(3)
    return out


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
        self.measured = measured[:, model.groups["order"]]
        if model.criterion == "distances":
            diff = measured[:, model.pair_i] - measured[:, model.pair_j]
            self.distances = np.sqrt(np.einsum("bpc,bpc->bp", diff, diff))

    def unpack(self, x: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values = self.start[index].copy()
        values[:, self.model.free] = x[:, : self.model.n_kinematic]
        x_base = np.zeros((x.shape[0], 6))
        x_base[:, self.model.base_free] = x[:, self.model.n_kinematic :]
        return values, x_base

    def tracker(self, x_base: np.ndarray, index: np.ndarray) -> np.ndarray:
        rotation, _, _ = base_correction(x_base)
        delta = np.broadcast_to(np.eye(4), (x_base.shape[0], 4, 4)).copy()
        delta[:, :3, :3] = rotation
        delta[:, :3, 3] = x_base[:, :3]
        return self.base_start[index] @ delta

    def normal_equations(self, x: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cost ``(B,)``, ``J_s^T J_s`` ``(B, p, p)`` and ``J_s^T r`` ``(B, p)`` (scaled columns).

        Points criterion: with ``r_k = R_tot e_k`` (``R_tot`` orthonormal) and ``J_k = R_tot W_k Xi``,
        ``J^T J = sum_groups Xi^T (sum_k W_k^T W_k) Xi`` (moments of the local vectors, no per-point
        work) and ``J^T r = sum_groups Xi^T sum_k (p_k x e_k, e_k)``.
        """
        model = self.model
        values, x_base = self.unpack(x, index)
        rotation, origin, twists = _kinematics(model, values)
        points = _points(model, rotation, origin)
        if model.criterion == "distances":
            return self._distance_equations(points, twists * model.x_scale, index)
        base_rotation, _, _ = base_correction(x_base)
        r0 = self.base_start[index, :3, :3]
        total = r0 @ base_rotation
        shift = np.einsum("bij,bj->bi", r0, x_base[:, :3]) + self.base_start[index, :3, 3]
        in_base = (self.measured[index] - shift[:, None, :]) @ total  # R_tot^T (m - t), row-wise
        error = points - in_base
        cost = 0.5 * np.einsum("bnc,bnc->b", error, error)
        moments = np.concatenate([_cross(points, error), error], axis=-1)
        sums = np.add.reduceat(moments, model.groups["starts"], axis=1)  # (B, U, 6)
        base = _base_twists(model, x_base)
        xi = np.concatenate([twists, np.broadcast_to(base[:, None], twists.shape[:3] + base.shape[-1:])], axis=-1)
        xi = xi * model.x_scale
        gradient = np.einsum("busk,bus->bk", xi, sums)
        # sum_u Xi_u^T (G_u Xi_u) as one product over the stacked groups: (B, p, 6U) @ (B, 6U, p); the
        # per-group products Xi_u^T G_u Xi_u made a (B, U, p, p) array to sum and 2 B U small matmuls
        weighted = _group_normal(model, rotation, origin) @ xi  # (B, U, 6, p)
        batch, units, _, width = xi.shape
        stacked = (batch, units * 6, width)
        normal = np.swapaxes(xi.reshape(stacked), -1, -2) @ weighted.reshape(stacked)
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


# ------------------------------------------------------------------------------------------- solver


def refine_batch(model: RefinedModel, measured, start_values, base_start=None) -> RefinedBatch:
    """Refine ``n_draws`` captures of the model's structure, each from its own start.

    Parameters
    ----------
    model : RefinedModel
    measured : array_like, shape (n_draws, n_points, 3)
        Measured points of every draw, tracker frame [mm].
    start_values : array_like, shape (n_draws, n_joints, 5)
        Start of every draw (its CPA estimate) [mm, rad]; parameters outside ``model.free`` keep it.
    base_start : array_like, shape (n_draws, 4, 4) or (4, 4), optional
        Points criterion: start (or held) ``tracker_from_base`` of every draw.

    Returns
    -------
    RefinedBatch

    Notes
    -----
    Levenberg-Marquardt with Marquardt's diagonal scaling in the variables ``z = x / x_scale``:
    ``(A + lambda diag(A)) dz = -g``, ``A = J_s^T J_s``, ``g = J_s^T r``; lambda starts at 0
    (Gauss-Newton), is set to 1e-3 then multiplied by 10 after a step that raises the cost, and
    divided by 10 (0 below 1e-9) after an accepted step. A draw has converged when its next step
    satisfies ``|dz| <= xtol (1 + |z|)`` (that step is taken); it fails after ``max_iterations``
    evaluations, a non-finite value or an unbounded damping.
    """
    measured = np.asarray(measured, dtype=float)
    start = np.asarray(start_values, dtype=float)
    n_draws = measured.shape[0]
    if measured.ndim != 3 or measured.shape[1:] != (model.q.shape[0], 3):
        raise InputError(f"`measured` must have shape (n_draws, {model.q.shape[0]}, 3); got {measured.shape}")
    if start.shape != (n_draws,) + model.free.shape:
        raise InputError(f"`start_values` must have shape ({n_draws}, {model.free.shape[0]}, 5); got {start.shape}")
    if model.criterion == "points":
        if base_start is None:
            raise InputError("the points criterion needs `base_start` (the given or CPA tracker_from_base)")
        base_start = np.broadcast_to(np.asarray(base_start, dtype=float), (n_draws, 4, 4))
    problem = _Batch(model, measured, start, base_start)
    scale = model.x_scale
    x = np.concatenate([start[:, model.free], np.zeros((n_draws, int(model.base_free.sum())))], axis=1)
    everyone = np.arange(n_draws)
    if n_draws == 1:
        cost, normal, gradient = (item[:1] for item in problem.normal_equations(np.r_[x, x], np.r_[0, 0]))
    else:
        cost, normal, gradient = problem.normal_equations(x, everyone)
    damping = np.zeros(n_draws)
    converged = np.zeros(n_draws, dtype=bool)
    failed = ~np.isfinite(cost)
    iterations = np.zeros(n_draws, dtype=int)
    eye = np.eye(model.n_free)
    for _ in range(model.max_iterations):
        active = np.flatnonzero(~converged & ~failed)
        if active.size == 0:
            break
        step = _pad_one(active, lambda work: _lm_step(normal[work], gradient[work], damping[work], eye))
        # a negligible step is taken without another evaluation: the draw has converged
        small = np.linalg.norm(step, axis=1) <= model.xtol * (1.0 + np.linalg.norm(x[active] / scale, axis=1))
        done = active[small]
        x[done] += step[small] * scale
        converged[done] = True
        active, step = active[~small], step[~small]
        if active.size == 0:
            break
        trial = x[active] + step * scale
        if active.size == 1:  # padded like _pad_one
            new_cost, new_normal, new_gradient = (
                item[:1] for item in problem.normal_equations(np.r_[trial, trial], np.r_[active, active])
            )
        else:
            new_cost, new_normal, new_gradient = problem.normal_equations(trial, active)
        iterations[active] += 1
        better = np.isfinite(new_cost) & (new_cost <= cost[active])
        accepted = active[better]
        x[accepted] = trial[better]
        cost[accepted] = new_cost[better]
        normal[accepted] = new_normal[better]
        gradient[accepted] = new_gradient[better]
        damping[accepted] = np.where(damping[accepted] > 1e-9, damping[accepted] / 10.0, 0.0)
        rejected = active[~better]
        damping[rejected] = np.where(damping[rejected] > 0.0, damping[rejected] * 10.0, 1e-3)
        failed[active] |= ~np.isfinite(x[active]).all(axis=1) | (damping[active] > 1e16)
    values, x_base = problem.unpack(x, everyone)
    tracker = problem.tracker(x_base, everyone) if model.criterion == "points" else None
    ok = converged & ~failed
    values[~ok] = np.nan
    if tracker is not None:
        tracker[~ok] = np.nan
    return RefinedBatch(values=values, tracker_from_base=tracker, converged=ok, iterations=iterations, cost=cost)


def _pad_one(active: np.ndarray, compute):
    """``compute(work)`` on the draws ``active``; a stack of one is computed as two copies of itself,
    because numpy reduces a stack of one with other loops than a larger one (last-bit differences)."""
    if active.size != 1:
        return compute(active)
    result = compute(np.r_[active, active])
    return tuple(item[:1] for item in result) if isinstance(result, tuple) else result[:1]


def _lm_step(normal: np.ndarray, gradient: np.ndarray, damping: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """``(A + lambda diag(A)) dz = -g`` for a stack of draws ``(B, p)``."""
    diagonal = np.einsum("bii->bi", normal)
    system = normal + damping[:, None, None] * (diagonal[:, :, None] * eye)
    try:
        return -np.linalg.solve(system, gradient[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.stack([_safe_solve(m, -g) for m, g in zip(system, gradient, strict=True)])


def _safe_solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Least-squares solution where the stacked solve met a singular system (a degenerate draw)."""
    return np.linalg.lstsq(matrix, rhs, rcond=None)[0]


# --------------------------------------------------------------------------------------- linearised


def refined_covariance(model: RefinedModel, measured, variance) -> np.ndarray:
    """Linearised covariance of the refined free unknowns at the noise-free solution [mm, rad].

    The refinement is the least-squares estimator ``x(m)``; to first order in the measurement
    errors, ``dx = -(J^T J)^-1 J^T G dm`` with ``G = d r / d m`` (identity for points, the pair
    unit vectors for distances), hence ``C_x = (J^T J)^-1 J^T G V G^T J (J^T J)^-1`` with ``V`` the
    diagonal of the coordinate variances (GUM law of propagation, JCGM 100 eq. 13). Unlike
    ``refine_parameters``' covariance, the noise level comes from the instrument model, not from the
    residuals (zero on a noise-free capture), and unequal variances are honoured.

    Parameters
    ----------
    model : RefinedModel
    measured : array_like, shape (n_points, 3)
        Noise-free measured points [mm].
    variance : array_like, shape (n_points, 3)
        Variance of every measured coordinate [mm^2].

    Returns
    -------
    ndarray, shape (n_free, n_free)
        In the order of ``model.free_names`` [mm^2, mm rad, rad^2].
    """
    measured = np.asarray(measured, dtype=float)[None]
    variance = np.asarray(variance, dtype=float)[model.groups["order"]]
    start = model.reference_values[None]
    base = None if model.reference_tracker is None else model.reference_tracker[None]
    problem = _Batch(model, measured, start, base)
    x = np.concatenate([start[:, model.free], np.zeros((1, int(model.base_free.sum())))], axis=1)
    values, x_base = problem.unpack(x, np.arange(1))
    rotation, origin, twists = _kinematics(model, values)
    points = _points(model, rotation, origin)
    jac = _point_jacobian(model, points, twists)[0]  # (N, 3, n_kin), base frame, grouped order
    n_points = points.shape[1]
    if model.criterion == "points":
        base = _base_twists(model, x_base)[0]  # (6, n_base)
        base_columns = base[3:][None] + np.cross(base[:3].T[None], points[0][:, None, :]).transpose(0, 2, 1)
        full = np.concatenate([jac, base_columns], axis=-1)
        # the tracker-frame Jacobian is R_tot J; with V = diag(var) isotropic per point the rotation
        # cancels in J^T V J only when the three variances of a point are equal (they are: U(L) per point)
        full = full.reshape(-1, model.n_free)
        middle = full.T @ (full * variance.reshape(-1)[:, None])
        normal = full.T @ full
    else:
        i, j = model.sorted_i, model.sorted_j
        diff = points[0, i] - points[0, j]
        unit = diff / np.linalg.norm(diff, axis=1, keepdims=True)
        rows = np.einsum("pc,pck->pk", unit, jac[i] - jac[j])  # (n_pairs, p)
        normal = rows.T @ rows
        # J^T G: (p, 3N); column block of point i collects + rows (x) unit, of point j - rows (x) unit
        jtg = np.zeros((n_points, 3, rows.shape[1]))
        np.add.at(jtg, i, unit[:, :, None] * rows[:, None, :])
        np.add.at(jtg, j, -unit[:, :, None] * rows[:, None, :])
        jtg = jtg.reshape(-1, rows.shape[1])
        middle = jtg.T @ (jtg * variance.reshape(-1)[:, None])
    inverse = np.linalg.pinv(normal)
    return inverse @ middle @ inverse
