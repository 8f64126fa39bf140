"""Batched orthogonal plane fit and in-plane circle fit of 3-D points (CPA, thesis ch. 4.4.1 step 3).

Shapes: ``points (..., n_points, 3)`` [mm]; every result carries the same leading axes, so one call
fits one circle or a whole Monte Carlo batch of circles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import DegenerateGeometryError, InputError
from robotcal.geometry._vectors import cross as _cross
from robotcal.geometry._vectors import dot as _dot

__all__ = ["PlaneFit", "CircleFit", "fit_plane", "fit_circle_3d", "check_points"]

#: Smallest ratio of the second to the first singular value of the centred points before the
#: points are called collinear (a 100 mm chord would need a sagitta below ~1e-4 mm). The ratio is
#: computed from the scatter matrix's eigenvalues, which resolve it down to ~sqrt(eps) = 1.5e-8.
COLLINEAR_RATIO = 1e-6

#: Relative rounding floor of the circle-fit cost: a step raising the cost by less is still taken
#: (see ``_refine_circle_2d_geometric``).
COST_TOLERANCE = 1e-10


def check_points(points: ArrayLike, name: str = "points", *, min_points: int = 3) -> np.ndarray:
    """Coerce ``points`` to float ``(..., n_points, 3)`` with ``n_points >= min_points``, all finite."""
    points = _check_shape(points, name, min_points=min_points)
    if not np.all(np.isfinite(points)):
        raise InputError(f"`{name}` contains NaN or infinite coordinates")
    return points


@dataclass(frozen=True, slots=True, kw_only=True)
class PlaneFit:
    """Total-least-squares plane: minimises the sum of squared orthogonal distances.

    Attributes
    ----------
    centroid : ndarray, shape (..., 3)
        Mean of the points, a point of the plane [mm].
    normal : ndarray, shape (..., 3)
        Unit normal (sign arbitrary until oriented by the caller).
    basis : ndarray, shape (..., 2, 3)
        Orthonormal in-plane axes ``u, v`` with ``u x v = normal``.
    residuals : ndarray, shape (..., n_points)
        Signed distance of each point to the plane [mm] (axial deviation); None when a circle was
        fitted with ``residuals=False``.
    rms : ndarray, shape (...)
        RMS of ``residuals`` [mm] (None with them).
    """

    centroid: np.ndarray
    normal: np.ndarray
    basis: np.ndarray
    residuals: np.ndarray | None
    rms: np.ndarray | None


@dataclass(frozen=True, slots=True, kw_only=True)
class CircleFit:
    """Circle in 3-D: the plane of :class:`PlaneFit` and a circle fitted to the projected points.

    Attributes
    ----------
    centre : ndarray, shape (..., 3)
        Circle centre, a point of the joint axis [mm].
    normal : ndarray, shape (..., 3)
        Unit plane normal, the joint axis direction (sign arbitrary until oriented).
    radius : ndarray, shape (...)
        Circle radius [mm].
    plane_residuals : ndarray, shape (..., n_points)
        Signed distance of each point to the plane [mm] (axial deviation).
    radial_residuals : ndarray, shape (..., n_points)
        Signed in-plane distance of each projected point to the circle, outward positive [mm].
    plane_rms, circle_rms : ndarray, shape (...)
        RMS of the two residuals [mm]. The residuals and their RMS are None when fitted with
        ``residuals=False`` (Monte Carlo draws).
    method : str
        ``"geometric"`` or ``"algebraic"``.
    iterations : int
        Gauss-Newton iterations of the geometric refinement (0 for algebraic).
    converged : bool
        Whether the geometric refinement met its step tolerance for every circle in the batch.
    in_plane : ndarray, shape (..., n_points, 2), optional
        The projected points relative to the centre along the plane's axes ``u, v`` (``u x v = normal``)
        [mm]: the sense of turning about the normal is the sign of their 2-D cross products.
    """

    centre: np.ndarray
    normal: np.ndarray
    radius: np.ndarray
    plane_residuals: np.ndarray | None
    radial_residuals: np.ndarray | None
    plane_rms: np.ndarray | None
    circle_rms: np.ndarray | None
    method: str
    iterations: int
    converged: bool
    in_plane: np.ndarray | None = None


def _smallest_eigenpair(xx, yy, zz, xy, xz, yz):
    """Eigenvalues (ascending) and the smallest-eigenvalue eigenvector of batched symmetric 3x3 matrices.

    Closed form: eigenvalues by the trigonometric solution of the characteristic cubic (Smith 1961),
    then the eigenvector as the largest cross product of two rows of ``S - lambda_min I``. For a
    scatter matrix of circle points the error of the vector is ~eps * lambda_max / lambda_mid, and
    it is ~10x cheaper than ``np.linalg.eigh`` on a batch. Written out by components (no stacked
    ``(..., 3, 3)`` temporaries): a Monte Carlo batch calls it once per circle.
    """
    mean = (xx + yy + zz) / 3.0
    a, d, f = xx - mean, yy - mean, zz - mean
    p = np.sqrt((a * a + d * d + f * f + 2.0 * (xy * xy + xz * xz + yz * yz)) / 6.0)
    safe = np.where(p > 0.0, p, 1.0)
    det = (a * (d * f - yz * yz) - xy * (xy * f - yz * xz) + xz * (xy * yz - d * xz)) / (safe * safe * safe)
    phi = np.arccos(np.clip(det / 2.0, -1.0, 1.0)) / 3.0
    largest = mean + 2.0 * p * np.cos(phi)
    smallest = mean + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    middle = 3.0 * mean - largest - smallest
    # rows (a0, xy, xz), (xy, b1, yz), (xz, yz, c2) of S - smallest I and their cross products
    a0, b1, c2 = xx - smallest, yy - smallest, zz - smallest
    c01 = (xy * yz - xz * b1, xz * xy - a0 * yz, a0 * b1 - xy * xy)
    c02 = (xy * c2 - xz * yz, xz * xz - a0 * c2, a0 * yz - xy * xz)
    c12 = (b1 * c2 - yz * yz, yz * xz - xy * c2, xy * yz - b1 * xz)
    n01, n02, n12 = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2] for c in (c01, c02, c12))
    use01 = (n01 >= n02) & (n01 >= n12)  # the first of the largest, as argmax picks it
    use02 = ~use01 & (n02 >= n12)
    vector = np.empty(np.shape(xx) + (3,))
    for i in range(3):
        vector[..., i] = np.where(use01, c01[i], np.where(use02, c02[i], c12[i]))
    vector /= np.sqrt(np.where(use01, n01, np.where(use02, n02, n12)))[..., None]
    return np.stack([smallest, middle, largest], axis=-1), vector


def _row_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``sum(a * b, axis=-1)`` in one pass, without the product array."""
    return np.einsum("...i,...i->...", a, b)


def _row_sum(a: np.ndarray) -> np.ndarray:
    """``sum(a, axis=-1)`` (einsum: one pass over short rows, where ``ndarray.sum`` loops per row)."""
    return np.einsum("...i->...", a)


def _project(centred: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """``centred (..., 3, n_points)`` projected on ``direction (..., 3)``: ``(..., n_points)`` in one pass
    (rather than three broadcast products and two sums)."""
    return np.einsum("...jn,...j->...n", centred, direction)


def _check_shape(points, name: str = "points", *, min_points: int = 3) -> np.ndarray:
    """:func:`check_points` without the pass over every coordinate for non-finite values."""
    try:
        points = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"`{name}` must be numeric; got {type(points).__name__}") from exc
    if points.ndim < 2 or points.shape[-1] != 3 or points.shape[-2] < min_points:
        raise InputError(f"`{name}` must have shape (n_points, 3) with n_points >= {min_points}; got {points.shape}")
    return points


def _plane_fit(points, *, residuals: bool = True) -> tuple[PlaneFit, np.ndarray, np.ndarray, tuple]:
    """:func:`fit_plane`, the in-plane coordinates ``u, v`` of the points, ``(..., n_points)`` each, and
    their scatter sums ``(suu, suv, svv)``.

    The centred coordinates are held as three contiguous ``(..., n_points)`` rows (one transposing
    copy), so that every later pass reads contiguous rows rather than every third number. The points
    are checked for NaN or infinite coordinates through their sums: a non-finite coordinate makes its
    item's centroid non-finite, so only then is every coordinate inspected (for the message). With
    ``residuals=False`` the plane residuals and their RMS are not computed (``None``).
    """
    points = _check_shape(points)
    n_points = points.shape[-2]
    centred = np.ascontiguousarray(np.moveaxis(points, -1, -2))  # (..., 3, n_points)
    centroid = _row_sum(centred) / n_points
    if not np.all(np.isfinite(centroid)):
        check_points(points)  # raises for a NaN or infinite coordinate
        raise InputError("`points` has coordinates too large to fit (their sum overflows)")
    centred -= centroid[..., :, None]
    x, y, z = centred[..., 0, :], centred[..., 1, :], centred[..., 2, :]
    sxx, syy, szz = _row_dot(x, x), _row_dot(y, y), _row_dot(z, z)
    sxy, sxz, syz = _row_dot(x, y), _row_dot(x, z), _row_dot(y, z)
    _, normal = _smallest_eigenpair(sxx, syy, szz, sxy, sxz, syz)
    # u: the normal crossed with the coordinate axis it is least aligned with
    least = np.argmin(np.abs(normal), axis=-1)
    axis = np.zeros(normal.shape)
    np.put_along_axis(axis, least[..., None], 1.0, axis=-1)
    u = _cross(normal, axis)
    u = u / np.sqrt(_dot(u, u))[..., None]
    v = _cross(normal, u)

    # In-plane scatter u^T S u, u^T S v, v^T S v: the sums of squares and products of the projected
    # coordinates, without a pass over them; like those sums, accurate to ~eps * largest eigenvalue.
    def scatter_times(w):
        return (
            sxx * w[..., 0] + sxy * w[..., 1] + sxz * w[..., 2],
            sxy * w[..., 0] + syy * w[..., 1] + syz * w[..., 2],
            sxz * w[..., 0] + syz * w[..., 1] + szz * w[..., 2],
        )

    su0, su1, su2 = scatter_times(u)
    suu = u[..., 0] * su0 + u[..., 1] * su1 + u[..., 2] * su2
    suv = v[..., 0] * su0 + v[..., 1] * su1 + v[..., 2] * su2
    sv0, sv1, sv2 = scatter_times(v)
    svv = v[..., 0] * sv0 + v[..., 1] * sv1 + v[..., 2] * sv2
    # Collinearity from the in-plane 2x2 scatter, whose smaller eigenvalue is accurate to ~eps * largest
    # (the cubic's double root near 0 is only accurate to ~sqrt(eps) * largest).
    half_trace, radius = 0.5 * (suu + svv), np.sqrt((0.5 * (suu - svv)) ** 2 + suv**2)
    spread_small = np.sqrt(np.maximum(half_trace - radius, 0.0))
    spread_large = np.sqrt(np.maximum(half_trace + radius, 0.0))
    degenerate = spread_small <= COLLINEAR_RATIO * np.maximum(spread_large, 1e-300)
    if np.any(degenerate):
        where = "" if np.ndim(degenerate) == 0 else f" (batch item {np.argwhere(degenerate)[0].tolist()})"
        raise DegenerateGeometryError(
            f"points are collinear or coincident{where}: they do not define a plane or a circle"
        )
    plane_residuals = rms = None
    if residuals:
        plane_residuals = _project(centred, normal)
        rms = np.sqrt(_row_dot(plane_residuals, plane_residuals) / n_points)
    plane = PlaneFit(
        centroid=centroid,
        normal=normal,
        basis=np.stack([u, v], axis=-2),
        residuals=plane_residuals,
        rms=rms,
    )
    return plane, _project(centred, u), _project(centred, v), (suu, suv, svv)


def fit_plane(points: ArrayLike) -> PlaneFit:
    """Fit planes to ``points (..., n_points, 3)`` by orthogonal (total) least squares.

    The normal is the eigenvector of the centred points' scatter matrix ``S = sum_k c_k c_k^T``
    (``c_k = p_k - centroid``) with the smallest eigenvalue, so the fit minimises
    ``sum_k (c_k . n)^2``. The scatter matrix of a batch is six sums and its eigenpair has a closed
    form (see ``_smallest_eigenpair``); the in-plane axes ``u, v`` are any orthonormal pair with
    ``u x v = normal`` (the circle fit does not depend on their orientation in the plane).

    Raises
    ------
    InputError
        If a coordinate is NaN or infinite.
    DegenerateGeometryError
        If the points of a batch item are (nearly) collinear or coincident.
    """
    return _plane_fit(points)[0]


def _solve3_components(a, b, c, d, e, f, r0, r1, r2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve batched symmetric 3x3 systems ``[[a, b, c], [b, d, e], [c, e, f]] x = r`` by Cramer's rule."""
    cof00, cof01, cof02 = d * f - e * e, c * e - b * f, b * e - c * d
    cof11, cof12, cof22 = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * cof00 + b * cof01 + c * cof02
    with np.errstate(divide="ignore", invalid="ignore"):
        x0 = (cof00 * r0 + cof01 * r1 + cof02 * r2) / det
        x1 = (cof01 * r0 + cof11 * r1 + cof12 * r2) / det
        x2 = (cof02 * r0 + cof12 * r1 + cof22 * r2) / det
    return x0, x1, x2


def _fit_circle_2d_algebraic(
    u: np.ndarray, v: np.ndarray, scatter: tuple | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Kasa fit: minimise ``sum_k (|w_k|^2 + D w_k,u + E w_k,v + F)^2`` (linear in D, E, F).

    ``u, v (..., n_points)`` are in-plane coordinates [mm]; ``scatter = (suu, suv, svv)``, their sums of
    squares and products, when the caller has them. The normal equations are those of the coordinates
    scaled to unit RMS (for conditioning), formed from the moments of the unscaled ones.
    """
    n_points = u.shape[-1]
    suu, suv, svv = (_row_dot(u, u), _row_dot(u, v), _row_dot(v, v)) if scatter is None else scatter
    squared = u * u
    squared += v * v  # |w|^2; the right-hand side is its negative
    swu, swv = _row_dot(u, squared), _row_dot(v, squared)
    sww = suu + svv  # sum |w|^2
    scale = np.sqrt(sww / n_points)
    inverse = 1.0 / scale
    inverse2 = inverse * inverse
    inverse3 = inverse2 * inverse
    d_coefficient, e_coefficient, f_coefficient = _solve3_components(
        suu * inverse2, suv * inverse2, _row_sum(u) * inverse, svv * inverse2, _row_sum(v) * inverse,
        np.full(scale.shape, float(n_points)), -swu * inverse3, -swv * inverse3, -sww * inverse2,
    )  # fmt: skip
    centre = -0.5 * np.stack([d_coefficient, e_coefficient], axis=-1)
    radius = np.sqrt(np.maximum(np.sum(centre**2, axis=-1) - f_coefficient, 0.0))
    return centre * scale[..., None], radius * scale


class _CircleState:
    """In-plane offsets of the points from a centre, their distances and radial residuals ``(..., n_points)``."""

    __slots__ = ("du", "dv", "dist", "res", "cost")

    def __init__(self, shape):
        """Arrays of ``shape`` to be filled (None: to be set by the caller). Each is contiguous: a ufunc on a
        strided batch (rows of one ``(..., 2, n_points)`` array, say) loops row by row, ~10 % slower here."""
        self.du, self.dv, self.dist, self.res = (None if shape is None else np.empty(shape) for _ in range(4))
        self.cost = None

    def evaluate(self, u, v, cu, cv, r) -> np.ndarray:
        """Fill the arrays for centre ``(cu, cv)`` and radius ``r`` in place; return the cost ``sum res^2``."""
        np.subtract(u, cu[..., None], out=self.du)
        np.subtract(v, cv[..., None], out=self.dv)
        np.multiply(self.du, self.du, out=self.dist)
        np.multiply(self.dv, self.dv, out=self.res)  # scratch
        self.dist += self.res
        np.sqrt(self.dist, out=self.dist)
        np.subtract(self.dist, r[..., None], out=self.res)
        self.cost = _row_dot(self.res, self.res)
        return self.cost


#: The Levenberg-Marquardt iterations go on with only the circles still iterating (a copy of their rows)
#: once at most this fraction of the rows iterated so far is left: copying a row out and back costs about
#: half of what an iteration over it costs (measured on kr5-demo batches), so fewer than half must be left.
COMPACT_FRACTION = 0.5


class _CircleIteration:
    """The Levenberg-Marquardt iterate of a set of circles ``(m, n_points)`` (or one circle ``(n_points,)``).

    ``state`` holds the offsets, distances and residuals at the current ``(cu, cv, r)``; ``trial`` and
    ``gu, gv`` are scratch arrays of the same shape, allocated once.
    """

    __slots__ = ("u", "v", "cu", "cv", "r", "cost", "damping", "active", "state", "trial", "gu", "gv")

    def __init__(self, u, v, cu, cv, r, cost, damping, active, state):
        self.u, self.v, self.cu, self.cv, self.r = u, v, cu, cv, r
        self.cost, self.damping, self.active, self.state = cost, damping, active, state
        self.trial = _CircleState(u.shape)
        self.gu, self.gv = np.empty(u.shape), np.empty(u.shape)

    def step(self, tolerance: float) -> None:
        """One iteration: every active item solves its damped normal equations and takes or refuses the step."""
        state, trial, gu, gv = self.state, self.trial, self.gu, self.gv
        cu, cv, r, active, damping = self.cu, self.cv, self.r, self.active, self.damping
        n_points = float(self.u.shape[-1])
        # J = [-gu, -gv, -1] with g = (w - c) / |w - c|, so gu^2 + gv^2 = 1 at every point
        with np.errstate(divide="ignore", invalid="ignore"):
            np.divide(state.du, state.dist, out=gu)
            np.divide(state.dv, state.dist, out=gv)
        guu, guv = _row_dot(gu, gu), _row_dot(gu, gv)
        gu_sum, gv_sum = _row_sum(gu), _row_sum(gv)
        if np.all(np.isfinite(guu) & np.isfinite(guv)):
            gvv = n_points - guu
        else:  # a point at the centre (|w - c| = 0): its direction is taken as 0, as 1 / max(dist, 1e-300) gives
            inverse = np.maximum(state.dist, 1e-300)
            np.divide(1.0, inverse, out=inverse)
            np.multiply(state.du, inverse, out=gu)
            np.multiply(state.dv, inverse, out=gv)
            guu, guv, gvv = _row_dot(gu, gu), _row_dot(gu, gv), _row_dot(gv, gv)
            gu_sum, gv_sum = _row_sum(gu), _row_sum(gv)
        lift = 1.0 + damping
        steps = _solve3_components(
            guu * lift, guv, gu_sum, gvv * lift, gv_sum, n_points * lift,
            -_row_dot(gu, state.res), -_row_dot(gv, state.res), -_row_sum(state.res),
        )  # fmt: skip
        step_u, step_v, step_r = (np.where(active & np.isfinite(step), -step, 0.0) for step in steps)
        trial_u, trial_v, trial_r = cu + step_u, cv + step_v, r + step_r
        trial_cost = trial.evaluate(self.u, self.v, trial_u, trial_v, trial_r)
        # Accept steps that do not raise the cost beyond its rounding floor: near the minimum the cost
        # cannot resolve parameter changes below ~sqrt(eps) * noise, the Gauss-Newton step can.
        better = (trial_cost <= self.cost * (1.0 + COST_TOLERANCE)) & active
        self.cu = np.where(better, trial_u, cu)
        self.cv = np.where(better, trial_v, cv)
        self.r = r = np.where(better, trial_r, r)
        # Converged items stepped by zero: their trial state equals their state. Only a rejected step of an
        # active item needs its old state kept.
        if not np.any(active & ~better):
            self.state, self.trial = trial, state
        else:
            keep = better[..., None]
            for name in ("du", "dv", "dist", "res"):
                np.copyto(getattr(state, name), getattr(trial, name), where=keep)
        self.cost = np.where(better, trial_cost, self.cost)
        self.damping = np.where(better, damping * 0.1, np.maximum(damping * 10.0, 1e-6))
        largest = np.maximum(np.maximum(np.abs(step_u), np.abs(step_v)), np.abs(step_r))
        small_step = largest <= tolerance * np.maximum(r, 1.0)
        self.active = active & ~(small_step | (self.damping > 1e12))

    def rows(self, rows: np.ndarray) -> _CircleIteration:
        """The iterate of the items ``rows`` only (copies)."""
        # np.take rather than fancy indexing, and without `out=` (which np.take buffers through a temporary)
        state = _CircleState(None)
        for name in ("du", "dv", "dist", "res"):
            setattr(state, name, np.take(getattr(self.state, name), rows, axis=0))
        taken = {
            name: np.take(getattr(self, name), rows, axis=0)
            for name in ("u", "v", "cu", "cv", "r", "cost", "damping", "active")
        }
        return _CircleIteration(**taken, state=state)

    def put(self, rows: np.ndarray, part: _CircleIteration) -> None:
        """Write the iterate ``part`` of the items ``rows`` back (what the solution needs: no scratch, no damping)."""
        for name in ("cu", "cv", "r", "cost", "active"):
            getattr(self, name)[rows] = getattr(part, name)
        for name in ("du", "dv", "res"):
            getattr(self.state, name)[rows] = getattr(part.state, name)


def _refine_circle_2d_geometric(
    u: np.ndarray, v: np.ndarray, centre: np.ndarray, radius: np.ndarray, *, max_iterations: int, tolerance: float
) -> tuple[np.ndarray, np.ndarray, int, bool, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Batched Levenberg-Marquardt on ``sum_k (|w_k - c| - R)^2`` over ``(c, R)``.

    ``u, v (..., n_points)`` are the in-plane coordinates of the points ``w_k`` [mm]. Each step
    solves ``(J^T J + lambda diag(J^T J)) delta = -J^T r`` with ``J = [-(w - c)/|w - c|, -1]``; the
    normal matrix is six sums over the points, solved in closed form. lambda starts at 0 (a pure
    Gauss-Newton step, which converges in a few steps from the algebraic start) and grows tenfold
    only for the batch items whose step did not lower the cost. Written by hand because it runs over
    a whole batch of independent 3-unknown problems at once, which ``scipy.optimize.least_squares``
    cannot; the tests compare it with scipy circle by circle.

    Every pass over the points writes into arrays allocated once (two states, current and trial, that
    swap roles when every active item takes its step). An item that has converged takes a zero step,
    so its trial state is its current state bit for bit and it never needs copying back.

    A batch ``(m, n_points)`` goes on with the items still iterating only, copied out, once at most
    ``COMPACT_FRACTION`` of the rows are left (a batch converges unevenly: in a Monte Carlo batch of
    2,000 circles often 10 % or fewer need a last iteration). Every item's arithmetic is its own row's,
    whatever the other rows (elementwise operations and row reductions; a lone item is iterated with a
    converged one beside it, as numpy reduces a stack of one with other loops), so the result is the
    same bit for bit.

    Returns the centre ``(..., 2)``, the radius, the iterations, whether every item converged, the
    radial residuals ``|w_k - c| - R`` ``(..., n_points)``, their sum of squares and ``w_k - c`` as
    ``(du, dv)`` at the solution.
    """
    cu, cv, r = centre[..., 0].copy(), centre[..., 1].copy(), radius.copy()
    state = _CircleState(u.shape)
    cost = state.evaluate(u, v, cu, cv, r)
    whole = work = _CircleIteration(u, v, cu, cv, r, cost, np.zeros(cu.shape), np.ones(cu.shape, dtype=bool), state)
    rows = None  # the rows of `whole` that `work` iterates (None: `work` is `whole`)
    iterations = 0
    for iteration in range(1, max_iterations + 1):
        iterations = iteration
        work.step(tolerance)
        if work.active.ndim != 1:  # one circle, or a batch of more than one axis: no copies
            if not np.any(work.active):
                break
            continue
        left = np.flatnonzero(work.active)
        if left.size == 0:
            break
        if left.size == 1:  # iterated with a converged row beside it (which takes zero steps)
            left = np.array([0, left[0]]) if left[0] > 0 else np.array([0, 1])
        if left.size < work.active.size and left.size <= COMPACT_FRACTION * work.active.size:
            part = work.rows(left)
            if rows is not None:
                whole.put(rows, work)
            rows = left if rows is None else rows[left]
            work = part
    if rows is not None:
        whole.put(rows, work)
    converged = bool(not np.any(whole.active))
    state = whole.state
    centre = np.stack([whole.cu, whole.cv], axis=-1)
    return centre, whole.r, iterations, converged, state.res, whole.cost, (state.du, state.dv)


def fit_circle_3d(
    points: ArrayLike,
    *,
    method: Literal["geometric", "algebraic"] = "geometric",
    max_iterations: int = 50,
    tolerance: float = 1e-12,
    residuals: bool = True,
) -> CircleFit:
    """Fit circles to ``points (..., n_points, 3)`` [mm] as CPA does: plane first, then circle in it.

    1. Orthogonal plane fit (:func:`fit_plane`); its normal is the axis direction.
    2. The points are projected orthogonally onto the plane.
    3. ``method="algebraic"``: Kasa fit of the projected points, minimising
       ``sum_k (|u_k - c|^2 - R^2)^2`` (algebraic distance).
       ``method="geometric"``: the algebraic fit refined by Levenberg-Marquardt to minimise
       ``sum_k (|u_k - c| - R)^2``, the squared in-plane radial distances of the projected points.
       This is the thesis's two-step fit, not a joint 3-D circle fit (the plane is not re-fitted).

    Parameters
    ----------
    points : array_like, shape (..., n_points, 3)
        At least 3 non-collinear points per circle [mm].
    method : {"geometric", "algebraic"}
    max_iterations, tolerance
        Limits of the geometric refinement; the step tolerance is relative to the radius.
    residuals : bool
        False: leave out the residuals and their RMS (``plane_residuals``, ``radial_residuals``,
        ``plane_rms`` and ``circle_rms`` are None), which a Monte Carlo draw does not need; the circle
        itself is the same.

    Returns
    -------
    CircleFit

    References
    ----------
    Thesis ch. 4.4.1 (step 3) and algorithm 5.2.2.1.
    """
    if method not in ("geometric", "algebraic"):
        raise InputError(f"`method` must be 'geometric' or 'algebraic'; got {method!r}")
    # u, v: the projected points' in-plane coordinates; scatter: their sums of squares and products
    plane, u, v, scatter = _plane_fit(points, residuals=residuals)
    axis_u, axis_v = plane.basis[..., 0, :], plane.basis[..., 1, :]
    centre_uv, radius = _fit_circle_2d_algebraic(u, v, scatter)
    iterations, converged = 0, True
    radial: np.ndarray | None
    cost: np.ndarray | None
    if method == "geometric":
        centre_uv, radius, iterations, converged, radial, cost, (du, dv) = _refine_circle_2d_geometric(
            u, v, centre_uv, radius, max_iterations=max_iterations, tolerance=tolerance
        )
    else:
        du, dv = u - centre_uv[..., 0, None], v - centre_uv[..., 1, None]
        radial = cost = None
        if residuals:
            radial = np.sqrt(du * du + dv * dv) - radius[..., None]
            cost = _row_dot(radial, radial)
    centre = plane.centroid + centre_uv[..., 0, None] * axis_u + centre_uv[..., 1, None] * axis_v
    return CircleFit(
        centre=centre,
        normal=plane.normal,
        radius=radius,
        plane_residuals=plane.residuals,
        radial_residuals=radial if residuals else None,
        plane_rms=plane.rms,
        circle_rms=np.sqrt(cost / u.shape[-1]) if residuals else None,
        method=method,
        iterations=iterations,
        converged=converged,
        # (..., n_points, 2) as a view of contiguous du, dv rows: one contiguous write, and in_plane[..., 0]
        # reads a contiguous row
        in_plane=np.swapaxes(np.stack([du, dv], axis=-2), -1, -2),
    )
