"""Batched Gauss-Newton draws around the noise-free solution: the deployed model's Monte Carlo at full size.

Every draw of the refined Monte Carlo (thesis ch. 5.2.3, the deployed model of ch. 4.5.7) refines a capture that
differs from the noise-free capture by the instrument noise (and the joint errors' random part): a small
perturbation. Its least-squares solution is therefore close to the noise-free solution ``x0``, the refinement of the
noise-free capture (:attr:`RefinedModel.reference_values`, computed once by the full solver: the truth when the
model holds; with joint errors the model lacks, the model's best fit to the truth's points, not the truth).
Rather than a Levenberg-Marquardt from each draw's own CPA estimate (:func:`robotcal.uncertainty.refined.refine_batch`),
the draws are solved by Gauss-Newton from ``x0``:

1. one step with the Jacobian ``J0`` at ``x0``, the same for every draw: ``dz_b = -J0_s^+ r_b(x0)`` with ``J0_s^+``
   the pseudo-inverse of the scaled Jacobian, one matrix product for all draws (the first-order estimator that the
   law of propagation of JCGM 101 §5.9 linearises; thesis eq. 5-3);
2. corrective iterations with every draw's own gradient ``g(x) = J_s(x)^T r(x)`` until every component of the step
   is below :data:`STEP_TOLERANCE` (1e-3) of that unknown's linearised standard uncertainty
   (:attr:`RefinedModel.step_tolerance`; without it the rule of ``refine_batch``, ``|dz| <= xtol (1 + |z|)``); the
   step is taken. The geometric model takes Gauss-Newton steps ``dz = -(J_s^T J_s)^-1 g`` with every draw's own
   normal equations (:mod:`robotcal.uncertainty.refined_kernel`, where they cost little more than the gradient);
   the extended model, whose per-draw Jacobian is formed point by point, keeps the shared matrix:
   ``dz = -(J0_s^T J0_s)^-1 g(x)``, with ``g`` evaluated in reverse form without the Jacobian
   (:meth:`~robotcal.uncertainty.refined_kernel._PointBatch.gradient`), when :func:`_contraction` allows (below);
3. a draw whose step does not shrink (``|dz_k| > |dz_{k-1}| / 2``), whose cost rises, that is not converged after
   ``max_corrections`` corrective evaluations, or that turns non-finite is solved again by ``refine_batch`` from its
   own CPA estimate (the fallback): the shortcut never decides a draw's value on its own.

The extended model's corrective step is the chord (simplified Newton) method (Dennis & Schnabel 1996;
Bjorck 1996, §9.2) applied to the normal equations ``g(x) = 0`` with the fixed matrix ``A0 = J0_s^T J0_s`` in
place of the Gauss-Newton matrix. Its fixed point is where the draw's own gradient vanishes, the least-squares
solution itself; the iteration only converges more slowly: to first order the distance left after a step is
``M(x) e`` with ``M(x) = I - A0^-1 J_s(x)^T J_s(x)`` (besides the residuals' second-order term, which plain
Gauss-Newton has as well). ``M`` grows linearly with the draw's distance from ``x0``, and where the problem is
nearly degenerate (the thesis capture with a registered base frame) it is far from normal: one step may leave
0.4 of the distance although its eigenvalues are ten times smaller. It is therefore bounded per problem, once, in
the u-weighted maximum-row-sum norm over probes along every direction (:func:`_contraction`), and the shared
matrix used only where the bound eta is at most :data:`MAX_CONTRACTION`: a draw whose last step (below the stopping
rule t) is taken then lies within ``eta / (1 - eta) * t`` of its solution, the sum of the geometric series of the
steps left, at most ``0.05 / 0.95 * 1e-3`` u (5.3e-5 u; the demo's deployed model: a bound of 0.014). Iterating
on the residuals alone with the shared Jacobian, ``dz = -J0_s^+ r(x)``, would need no gradient, but its fixed point
``J0^T r = 0`` differs from ``J(x)^T r = 0`` by ``(J0_s^T J0_s)^-1 (J(x) - J0)^T r``, second order in the noise
like the first step's own error: measured 4e-4 u (demo's deployed model) and 2e-3 u (thesis capture), no closer
than the first step.

Parameters the noise-free refinement holds keep every draw's CPA value, as in ``refine_batch``. The one-product
first step needs the residuals of every draw at ``x0`` to differ only by the measurements: the held parameters equal
to the reference's in every draw and one base frame (an estimated base frame with its 6 corrections starts every draw
from the reference frame, which reaches the same minimum as the draw's CPA frame); otherwise the corrective
iterations start at ``x0`` itself. Every per-draw operation is element-wise, a stacked solve, a sum in numpy's own
loops (the first step) or the kernel's products, so a draw's value does not depend on the batch it is solved in.

References
----------
JCGM 101:2008 §5.9, §7 (the Monte Carlo method); thesis ch. 4.5.7 (eqs 4-101, 4-102) and ch. 5.2.3; Bjorck,
Numerical Methods for Least Squares Problems (1996), §9.2 (Gauss-Newton and its variants); Dennis & Schnabel,
Numerical Methods for Unconstrained Optimization and Nonlinear Equations (1996) (the chord method).
"""

from __future__ import annotations

import numpy as np

from robotcal.uncertainty.refined import (
    _lm_step,
    _pad_one,
    batch_outcome,
    check_draws,
    refine_batch,
    refined_covariance,
)
from robotcal.uncertainty.refined_kernel import (
    RefinedBatch,
    RefinedModel,
    SharedStep,
    _Batch,
    _PointBatch,
    reference_jacobian,
    reference_unknowns,
)

__all__ = ["refine_draws_gauss_newton"]

#: The stopping rule of the Gauss-Newton draws, in units of every unknown's linearised standard uncertainty: a
#: draw whose corrective step is below it takes the step and stops. Gauss-Newton converges linearly at a rate of
#: 1e-4 to 3e-3 per step on these problems (the next step measured against the last: kr5-demo's deployed model,
#: thesis capture, points and distances), so a draw then lies within ~1e-5 u of its least-squares solution: far below
#: the 0.01 u to which the Monte Carlo's u and interval ends are compared, and below JCGM 101 §7.9's numerical
#: tolerance of two significant digits.
STEP_TOLERANCE = 1e-3
#: The largest :func:`_contraction` for which the corrective steps use the shared matrix: a draw then lies within
#: ``MAX_CONTRACTION / (1 - MAX_CONTRACTION) * STEP_TOLERANCE`` u (5.3e-5 u) of its least-squares solution after its
#: last step (the geometric series of the steps it did not take).
MAX_CONTRACTION = 0.05
#: The probes of :func:`_contraction`, in standard deviations of the draws along every direction.
_PROBE_SIGMA = 3.0
#: The draws' reach along every direction at once in the bound of :func:`_contraction`, in standard deviations.
_DRAW_SIGMA = 4.0
#: A corrective step longer than this fraction of the previous step is not converging: the draw falls back.
_SHRINK = 0.5
#: A cost above the previous one by more than this relative amount (rounding at the optimum) is rising.
_COST_SLACK = 1e-9


def refine_draws_gauss_newton(
    model: RefinedModel, measured, start_values, base_start=None, *, max_corrections: int = 3
) -> RefinedBatch:
    """Refine ``n_draws`` captures by batched Gauss-Newton around the noise-free solution (see the module notes).

    Parameters
    ----------
    model, measured, start_values, base_start
        As for :func:`robotcal.uncertainty.refined.refine_batch`: every draw's measured points [mm], its CPA
        estimate [mm, rad] (the values of the held parameters, and the fallback's start) and, points criterion,
        its CPA (or given) ``tracker_from_base``.
    max_corrections : int
        Evaluations of the per-draw normal equations after the first step; a draw whose step is then still above
        the stopping rule is solved by the fallback.

    Returns
    -------
    RefinedBatch
        ``iterations``: evaluations of the per-draw normal equations (the fallback's added); ``fallback``: the draws
        solved by :func:`robotcal.uncertainty.refined.refine_batch`.
    """
    measured, start, base_start = check_draws(model, measured, start_values, base_start)
    n_draws = measured.shape[0]
    common_base = _common_base(model, base_start)
    problem = (_Batch if model.joint_model is None else _PointBatch)(model, measured, start, common_base)
    x = np.tile(reference_unknowns(model), (n_draws, 1))
    previous = np.full(n_draws, np.inf)
    if _shares_reference(model, start, common_base):
        step = _first_step(model, problem, measured)
        x += step * model.x_scale
        previous = np.linalg.norm(step, axis=1)
    shared = _shared(model)
    inverse_normal = shared.inverse_normal if shared.contraction <= MAX_CONTRACTION else None
    ok, iterations, cost = _correct(problem, x, previous, max_corrections, inverse_normal)
    result = batch_outcome(problem, x, ok, iterations, cost)
    fallback = ~ok
    if not fallback.any():
        return result
    rows = np.flatnonzero(fallback)
    solved = refine_batch(model, measured[rows], start[rows], None if base_start is None else base_start[rows])
    parts = {name: getattr(result, name).copy() for name in ("values", "converged", "iterations", "cost", "extras")}
    for name, array in parts.items():
        array[rows] = getattr(solved, name) + (iterations[rows] if name == "iterations" else 0)
    tracker = result.tracker_from_base
    if tracker is not None:
        tracker = tracker.copy()
        tracker[rows] = solved.tracker_from_base
    return RefinedBatch(tracker_from_base=tracker, fallback=fallback, **parts)


def step_tolerance(model: RefinedModel, measured, variance) -> np.ndarray:
    """:data:`STEP_TOLERANCE` times the linearised standard uncertainty of every free unknown, in the scaled
    unknowns ``(n_free,)`` (:func:`robotcal.uncertainty.refined.refined_covariance` at the noise-free capture
    ``measured`` with the coordinate ``variance`` [mm^2]): the value of :attr:`RefinedModel.step_tolerance`."""
    covariance = refined_covariance(model, measured, variance)
    return STEP_TOLERANCE * np.sqrt(np.clip(np.diag(covariance), 0.0, None)) / model.x_scale


def _common_base(model: RefinedModel, base_start: np.ndarray | None) -> np.ndarray | None:
    """The base frames the Gauss-Newton draws start from: the reference frame for every draw when all 6 base
    corrections are estimated (the minimum does not depend on where the corrections are counted from), else the
    draws' own (a held base frame is the given one)."""
    if base_start is None or not model.base_free.all():
        return base_start
    assert model.reference_tracker is not None  # a base frame to correct: the points criterion, which has one
    return np.broadcast_to(model.reference_tracker, base_start.shape)


def _shares_reference(model: RefinedModel, start: np.ndarray, base: np.ndarray | None) -> bool:
    """Whether every draw's residuals at ``x0`` differ only by its measurements (one Jacobian, one model value)."""
    held = ~model.free
    if not np.array_equal(start[:, held], np.broadcast_to(model.reference_values[held], start[:, held].shape)):
        return False
    if model.criterion != "points":
        return True
    return model.reference_tracker is not None and bool(np.all(base == model.reference_tracker))


def shared_step(model: RefinedModel) -> SharedStep:
    """The :class:`SharedStep` of ``model`` (the value of :attr:`RefinedModel.shared_step`)."""
    points, jacobian, order, pairs = reference_jacobian(model)
    if model.criterion == "points":
        value, rows = points, jacobian.reshape(-1, model.n_free)
    else:
        assert pairs is not None  # the distances criterion has its pairs
        i, j = pairs
        diff = points[i] - points[j]
        value = np.linalg.norm(diff, axis=1)
        rows = np.einsum("pc,pck->pk", diff / value[:, None], jacobian[i] - jacobian[j])
    projector = np.linalg.pinv(rows * model.x_scale)
    inverse_normal = projector @ projector.T
    contraction = _contraction(model, inverse_normal)
    return SharedStep(
        value=value, order=order, projector=projector, inverse_normal=inverse_normal, contraction=contraction
    )


def _contraction(model: RefinedModel, inverse_normal: np.ndarray) -> float:
    """The bound ``eta`` on ``|e_{k+1}| <= eta |e_k|`` (largest component, in units of u) of a corrective step with
    the shared matrix, over the draws' spread (the module notes); inf for the geometric model or without
    :attr:`RefinedModel.step_tolerance`.

    The linearised iteration matrix at the draw's unknowns ``x`` is ``M(x) = I - (J0_s^T J0_s)^-1 J_s(x)^T J_s(x)``
    (the residuals' second-order term left aside: plain Gauss-Newton has it too). It vanishes at ``x0`` and grows
    linearly with ``x - x0``; it is evaluated at ``x0 +- PROBE_SIGMA s_i`` along every eigenvector of
    ``J0_s^T J0_s`` (``s_i`` the draws' standard deviation along it), each taken per standard deviation in the
    u-weighted maximum-row-sum norm, and summed with a weight of ``DRAW_SIGMA`` standard deviations each (the
    triangle inequality: a draw that far out along every direction at once).
    """
    if model.joint_model is None or model.step_tolerance is None:
        return float("inf")
    n_free = model.n_free
    u = model.step_tolerance / STEP_TOLERANCE  # the linearised standard uncertainties, scaled unknowns
    variance = float(np.median(u**2 / np.diag(inverse_normal)))  # the covariance is ~ variance (J0_s^T J0_s)^-1
    eigenvalues, vectors = np.linalg.eigh(np.linalg.pinv(inverse_normal))
    spread = np.sqrt(variance / np.clip(eigenvalues, np.finfo(float).tiny, None)) * vectors  # columns: s_i
    probes = reference_unknowns(model) + np.concatenate([spread.T, -spread.T]) * (_PROBE_SIGMA * model.x_scale)
    count = probes.shape[0]
    base = None if model.reference_tracker is None else np.broadcast_to(model.reference_tracker, (count, 4, 4))
    values = np.broadcast_to(model.reference_values, (count,) + model.reference_values.shape)
    problem = _PointBatch(model, np.zeros((count, model.q.shape[0], 3)), values, base)
    _, normal, _ = problem.normal_equations(probes, np.arange(count))
    iteration = np.eye(n_free) - inverse_normal @ normal  # (2 p, p, p)
    norms = np.abs(iteration * (u[None, :] / u[:, None])).sum(axis=2).max(axis=1) / _PROBE_SIGMA
    return float(_DRAW_SIGMA * norms.reshape(2, n_free).max(axis=0).sum())


def _shared(model: RefinedModel) -> SharedStep:
    return model.shared_step if model.shared_step is not None else shared_step(model)


def _first_step(model: RefinedModel, problem, measured: np.ndarray) -> np.ndarray:
    """``dz_b = -J0_s^+ r_b(x0)`` ``(n_draws, p)`` in the scaled unknowns, for every draw at once.

    Points criterion: ``r_b = p(x0) - R0^T (m_b - t0)`` in the base frame of the reference ``[R0 | t0]`` (the
    tracker-frame residuals turned by the orthonormal ``R0``: the same least-squares problem). Distances:
    ``r_b = |p_i - p_j| (x0) - |m_i - m_j|`` over the pairs (the draws' measured distances of ``problem``).
    """
    shared = _shared(model)
    if model.criterion == "points":
        assert model.reference_tracker is not None  # the points criterion's refinement has its base frame
        rotation, shift = model.reference_tracker[:3, :3], model.reference_tracker[:3, 3]
        in_base = np.einsum("bnc,cd->bnd", measured[:, shared.order] - shift, rotation)
        residuals = (shared.value - in_base).reshape(measured.shape[0], -1)
    else:
        residuals = shared.value - problem.distances
    # einsum's own loops, not BLAS: every draw's sums in the same order whatever the batch (bit-reproducible)
    return -np.einsum("bk,pk->bp", residuals, shared.projector)


def _correct(problem, x: np.ndarray, previous: np.ndarray, max_corrections: int, inverse_normal: np.ndarray | None):
    """Corrective iterations in place on ``x``: every draw's own gradient ``J_s(x)^T r(x)`` and its own normal
    matrix, or the shared ``(J0_s^T J0_s)^-1`` (``inverse_normal``), the step taken while it shrinks and the cost
    does not rise. Returns ``converged (B,)``, ``iterations (B,)`` and ``cost (B,)``."""
    model = problem.model
    scale, eye = model.x_scale, np.eye(model.n_free)
    n_draws = x.shape[0]
    cost, normal, gradient = _evaluate(problem, x, np.arange(n_draws), inverse_normal is None)
    iterations = np.ones(n_draws, dtype=int)
    converged = np.zeros(n_draws, dtype=bool)
    failed = ~np.isfinite(cost)
    for correction in range(1, max_corrections + 1):
        active = np.flatnonzero(~converged & ~failed)
        if active.size == 0:
            break
        if inverse_normal is None:
            step = _pad_one(active, lambda work: _lm_step(normal[work], gradient[work], np.zeros(work.size), eye))
        else:  # einsum's own loops, not BLAS: every draw's sums in the same order whatever the batch
            step = -np.einsum("bk,pk->bp", gradient[active], inverse_normal)
        size = np.linalg.norm(step, axis=1)
        if model.step_tolerance is None:
            small = size <= model.xtol * (1.0 + np.linalg.norm(x[active] / scale, axis=1))
        else:
            small = np.all(np.abs(step) <= model.step_tolerance, axis=1)
        x[active[small]] += step[small] * scale
        converged[active[small]] = True
        stalled = ~small & ~(size <= _SHRINK * previous[active])
        failed[active[stalled]] = True
        going = ~small & ~stalled
        if correction == max_corrections or not going.any():
            break
        active, step, size = active[going], step[going], size[going]
        trial = x[active] + step * scale
        new_cost, new_normal, new_gradient = _evaluate(problem, trial, active, inverse_normal is None)
        iterations[active] += 1
        better = np.isfinite(new_cost) & (new_cost <= cost[active] * (1.0 + _COST_SLACK))
        failed[active[~better]] = True
        accepted = active[better]
        x[accepted], previous[accepted] = trial[better], size[better]
        cost[accepted], gradient[accepted] = new_cost[better], new_gradient[better]
        if normal is not None:
            normal[accepted] = new_normal[better]
    failed |= ~np.isfinite(x).all(axis=1)
    return converged & ~failed, iterations, cost


def _evaluate(problem, x: np.ndarray, index: np.ndarray, with_normal: bool):
    """Cost, normal matrix (None unless ``with_normal``) and gradient of the draws ``index`` at ``x``; a lone draw
    as a stack of two (see ``refine_batch``)."""
    lone = index.size == 1
    if lone:
        x, index = np.r_[x, x], np.r_[index, index]
    if with_normal:
        cost, normal, gradient = problem.normal_equations(x, index)
    else:
        (cost, gradient), normal = problem.gradient(x, index), None
    if lone:
        cost, gradient = cost[:1], gradient[:1]
        normal = None if normal is None else normal[:1]
    return cost, normal, gradient
