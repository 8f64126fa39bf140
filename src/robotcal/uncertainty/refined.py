"""Batched least-squares refinement of many captures at once: the refined (deployed) model's Monte Carlo.

A user deploys CPA followed by refinement (thesis ch. 4.5.7, eqs 4-101/4-102). The Monte Carlo of
that model repeats capture -> CPA -> refinement for every draw. Rather than one
``scipy.optimize.least_squares`` call per draw, all draws of a batch are refined together by one vectorised
Levenberg-Marquardt iteration over the batch:

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
* the link chain is composed on arrays with the draws and groups in the last axes (element-wise
  products, not ``B U`` stacked 4x4 products), and the points criterion's only per-point work, the
  errors ``e_k = R_u s_k + o_u - m_k``, their squares and the moments ``sum_k [s_k; 1] e_k^T`` that
  give ``J^T r``, is two matrix products per class of equally sized groups over the whole batch
  (the measurements are taken to the base frame once per batch when the base frame is held);
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
fixed chunks of pairs so that memory stays bounded by ``batch x chunk`` (the pairs outnumber the coordinates
by about n_points / 6: 36,180 against 810 for the 270-point demo capture, so this criterion costs far more).

Every per-draw quantity is computed by element-wise operations, stacked matrix products and stacked
LAPACK solves, whose per-item results do not depend on the size of the stack: a draw's result is the
same whatever batch it is refined in (a batch of one is padded to two, see
:func:`robotcal.uncertainty.montecarlo.draw_block`). The per-group point products run over blocks of
draws small enough for OpenBLAS to keep them on one thread (``_PRODUCT_SIZE``), where a row of the
result does not depend on its position in the matrix.

The grouped form converges to the same Gauss-Newton fixed points as a per-point Jacobian (a draw's result moves
by at most the stopping rule's own tolerance: tests/unit/uncertainty/test_refined_solver.py); its cost is
recorded by benchmarks/bench_refined_montecarlo.py. An extended model (gravity compliance, harmonic joint errors)
deflects every point's joints by its own amount, so no two points share a carrier frame: its draws go through
the per-point :class:`_PointBatch`, each equal to scipy's refinement of the same capture
(benchmarks/bench_extended.py).

References
----------
Thesis ch. 4.5.7 (eqs 4-101, 4-102); JCGM 101:2008 §5.9, §7; Marquardt (1963).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityWarning, InputError
from robotcal.geometry.transforms import rot_z
from robotcal.identification.refine import (
    CRITERIA,
    RefinementSettings,
    capture_target_index,
    capture_turning_joints,
    measurement_pairs,
    refine_parameters,
)
from robotcal.identification.targets import Target, resolve_targets
from robotcal.kinematics.joint_model import JointModel, lash_turns
from robotcal.kinematics.model import ParameterSet, ReflectorMount
from robotcal.uncertainty.refined_kernel import (
    RefinedBatch,
    RefinedModel,
    _Batch,
    _PointBatch,
    reference_jacobian,
)

__all__ = ["RefinedModel", "RefinedBatch", "prepare_refined_model", "refine_batch", "refined_covariance"]


def prepare_refined_model(
    capture: Capture,
    start: ParameterSet,
    reflector: ReflectorMount | Target | Sequence[Target],
    *,
    criterion: str = "points",
    tracker_from_base=None,
    estimate_base: bool = True,
    joint_model: JointModel | None = None,
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
    reflector : ReflectorMount, Target or sequence of Target
        Where the points were measured (targets of known offsets: a draw estimates no offset).
    criterion : {"points", "distances"}
    tracker_from_base : array_like, shape (4, 4), optional
        Points criterion: the given base frame (held unless ``estimate_base``).
    estimate_base : bool
        Points criterion: estimate the 6 base-frame corrections.
    joint_model : JointModel, optional
        The extended model's joint model, fitted from zero in every draw (as from a CPA start); None: geometric.
    max_iterations : int
        Jacobian evaluations per draw before a draw is declared not converged.
    xtol : float
        Convergence test on the scaled step ``|dz| <= xtol (1 + |z|)``.
    """
    if criterion not in CRITERIA:
        raise InputError(f"`criterion` must be one of {CRITERIA}; got {criterion!r}")
    if capture.session is not None or capture.orientation is not None:
        # the draws' kernel composes one base frame and positions only: it would be silently wrong here
        raise InputError(
            f"{capture.source}: the refined Monte Carlo of a simulated capture plan models one tracker station and "
            "positions only; a capture with sessions or probe orientations is taken by the measured Monte Carlo "
            "(robotcal uncertainty --capture, robotcal.measured_monte_carlo)"
        )
    robot = start.robot
    carrier, vectors, pair_key = _carriers(capture, reflector, robot.n_joints)
    with warnings.catch_warnings():
        # the parameters the data cannot determine are recorded in `held` and stay at the CPA value
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine_parameters(
            capture,
            start.geometric(),
            reflector,
            settings=RefinementSettings(criterion=criterion, estimate_base=estimate_base),
            tracker_from_base=tracker_from_base if criterion == "points" else None,
            joint_model=None if joint_model is None else joint_model.with_values(np.zeros(joint_model.size)),
        )
    commanded = start.robot.model_joint_variables(capture.readings)
    fitted = result.parameters.joint_model
    q = commanded
    if fitted is not None and fitted.has_backlash:  # the circles' lash, corrected in every draw as in the fit
        q = commanded + lash_turns(fitted.backlash, commanded, capture.circle)
    if fitted is not None and fitted.is_empty:
        fitted = None
    groups = _group_points(q, carrier, vectors, robot.n_joints)
    for value in groups.values():
        value.setflags(write=False)
    pair_i = pair_j = sorted_i = sorted_j = None
    if criterion == "distances":
        pair_i, pair_j, _ = measurement_pairs(capture.readings, pair_key)
        position = np.empty_like(groups["order"])
        position[groups["order"]] = np.arange(position.size)
        sorted_i, sorted_j = position[pair_i], position[pair_j]
        # pairs ordered by the groups of their two points: each block shares the two groups' twists
        block = groups["group"][sorted_i] * groups["count"].size + groups["group"][sorted_j]
        pair_order = np.argsort(block, kind="stable")
        pair_i, pair_j = pair_i[pair_order], pair_j[pair_order]
        sorted_i, sorted_j = _frozen(sorted_i[pair_order], int), _frozen(sorted_j[pair_order], int)
    extra_free = np.zeros(0, dtype=bool) if fitted is None else np.array(fitted.identified, dtype=bool)
    return RefinedModel(
        criterion=criterion,
        free=_frozen(result.identifiability.free, bool),
        base_free=_frozen(result.identifiability.base_free, bool),
        x_scale=_frozen(result.identifiability.x_scale),
        q=_frozen(q),
        carrier=_frozen(carrier, int),
        vectors=_frozen(vectors),
        pair_i=None if pair_i is None else _frozen(pair_i, int),
        pair_j=None if pair_j is None else _frozen(pair_j, int),
        reference_values=_frozen(result.parameters.values),
        reference_tracker=None if result.tracker_from_base is None else _frozen(result.tracker_from_base),
        held=tuple(result.identifiability.held),
        free_names=tuple(result.identifiability.free_names),
        groups=groups,
        sorted_i=sorted_i,
        sorted_j=sorted_j,
        max_iterations=int(max_iterations),
        xtol=float(xtol),
        joint_model=fitted,
        joint_columns=None if fitted is None else _frozen(fitted.columns(commanded)),
        extra_free=_frozen(extra_free, bool),
    )


def _carriers(capture: Capture, reflector, n_joints: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Per point: the frame that carries its target (``t`` for a per-joint target of circle t + 1, ``n`` for a
    flange target), its target vector in that frame [mm], and the key of :func:`measurement_pairs`."""
    if isinstance(reflector, ReflectorMount):
        turning = capture_turning_joints(capture, reflector)
        if reflector.frame == "joint":
            return turning, reflector.positions[turning], capture_target_index(capture, reflector)
        return np.full(capture.n_points, n_joints), np.repeat(reflector.positions, capture.n_points, axis=0), None
    given = (reflector,) if isinstance(reflector, Target) else tuple(reflector)
    targets, index = resolve_targets(capture, given)
    unknown = [target.name for target in targets if not target.known]
    if unknown:
        raise InputError(
            f"the refined Monte Carlo needs targets of known offset; {', '.join(unknown)} is estimated: declare its "
            "offset as measured (or from the refinement's estimate)"
        )
    turning = np.maximum(capture.circle - 1, 0)
    carrier = np.empty(capture.n_points, dtype=int)
    vectors = np.empty((capture.n_points, 3))
    for t, target in enumerate(targets):
        rows = np.flatnonzero(index == t)
        if target.frame == "joint":
            carrier[rows], vectors[rows] = turning[rows], target.positions[turning[rows]]
        else:
            carrier[rows], vectors[rows] = n_joints, target.positions
    is_joint = np.array([target.frame == "joint" for target in targets])
    return carrier, vectors, index * (n_joints + 1) + np.where(is_joint[index], turning + 1, 0)


# ------------------------------------------------------------------------------ model and Jacobian


def _group_points(q: np.ndarray, carrier: np.ndarray, vectors: np.ndarray, n_joints: int) -> dict:
    """Group the points by the configuration of the frame that carries their target.

    A per-joint target of circle t sits at ``F_t Rz(q_t) r_t``: ``F_t`` depends only on joints
    ``0..t-1``, which rest while joint t turns, so every point of a circle shares one frame and
    only the local vector ``s_k = Rz(q_t) r_t`` changes (a flange target: ``F_n r``, one group per
    distinct pose). The chain of link transforms is then evaluated per group, not per point.
    """
    on_joint = np.flatnonzero(carrier < n_joints)
    local = np.array(vectors, dtype=float)
    local[on_joint] = (rot_z(q[on_joint, carrier[on_joint]])[:, :3, :3] @ local[on_joint][..., None])[..., 0]
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


# ------------------------------------------------------------------------------------------- solver


def check_draws(
    model: RefinedModel, measured, start_values, base_start
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The draws of :func:`refine_batch` as float arrays of checked shapes (``base_start`` one frame per draw)."""
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
    return measured, start, base_start


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
    measured, start, base_start = check_draws(model, measured, start_values, base_start)
    n_draws = measured.shape[0]
    problem = (_Batch if model.joint_model is None else _PointBatch)(model, measured, start, base_start)
    scale = model.x_scale
    # every draw starts from its own CPA estimate, the joint model from zero, as a user's refinement does
    x = np.concatenate(
        [start[:, model.free], np.zeros((n_draws, model.n_extra)), np.zeros((n_draws, int(model.base_free.sum())))],
        axis=1,
    )
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
    return batch_outcome(problem, x, converged & ~failed, iterations, cost)


def batch_outcome(problem, x: np.ndarray, ok: np.ndarray, iterations: np.ndarray, cost: np.ndarray) -> RefinedBatch:
    """The :class:`RefinedBatch` of the unknowns ``x`` ``(n_draws, p)``; rows not ``ok`` are NaN."""
    model = problem.model
    everyone = np.arange(x.shape[0])
    values, free_extras, x_base = problem.unpack(x, everyone)
    tracker = problem.tracker(x_base, everyone) if model.criterion == "points" else None
    values[~ok] = np.nan
    extras = np.zeros((x.shape[0], model.extra_free.size))  # the joint-model values the data cannot determine stay 0
    extras[:, model.extra_free] = free_extras
    extras[~ok] = np.nan
    if tracker is not None:
        tracker[~ok] = np.nan
    return RefinedBatch(
        values=values, tracker_from_base=tracker, converged=ok, iterations=iterations, cost=cost, extras=extras
    )


def _pad_one(active: np.ndarray, compute):
    """``compute(work)`` on the draws ``active``; a stack of one is computed as two copies of itself,
    because numpy reduces a stack of one with other loops than a larger one (last-bit differences)."""
    if active.size != 1:
        return compute(active)
    result = compute(np.r_[active, active])
    return tuple(item[:1] for item in result) if isinstance(result, tuple) else result[:1]


def _lm_step(normal: np.ndarray, gradient: np.ndarray, damping: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """``(A + lambda diag(A)) dz = -g`` for a stack of draws ``(B, p)``."""
    if damping.any():
        diagonal = np.einsum("bii->bi", normal)
        system = normal + damping[:, None, None] * (diagonal[:, :, None] * eye)
    else:  # Gauss-Newton for the whole stack (the usual case near the optimum): A itself
        system = normal
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
    points, full, order, pairs = reference_jacobian(model)
    variance = np.asarray(variance, dtype=float)[order]
    n_points = points.shape[0]
    if model.criterion == "points":
        # the tracker-frame Jacobian is R_tot J; with V = diag(var) isotropic per point the rotation
        # cancels in J^T V J only when the three variances of a point are equal (they are: U(L) per point)
        full = full.reshape(-1, model.n_free)
        middle = full.T @ (full * variance.reshape(-1)[:, None])
        normal = full.T @ full
    else:
        assert pairs is not None  # the distances criterion has its pairs
        i, j = pairs
        diff = points[i] - points[j]
        unit = diff / np.linalg.norm(diff, axis=1, keepdims=True)
        rows = np.einsum("pc,pck->pk", unit, full[i] - full[j])  # (n_pairs, p)
        normal = rows.T @ rows
        # J^T G: (p, 3N); column block of point i collects + rows (x) unit, of point j - rows (x) unit
        jtg = np.zeros((n_points, 3, rows.shape[1]))
        np.add.at(jtg, i, unit[:, :, None] * rows[:, None, :])
        np.add.at(jtg, j, -unit[:, :, None] * rows[:, None, :])
        jtg = jtg.reshape(-1, rows.shape[1])
        middle = jtg.T @ (jtg * variance.reshape(-1)[:, None])
    inverse = np.linalg.pinv(normal)
    return inverse @ middle @ inverse
