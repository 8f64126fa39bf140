"""Batched orthogonal plane fit and in-plane circle fit of 3-D points (CPA, thesis ch. 4.4.1 step 3).

Shapes: ``points (..., n_points, 3)`` [mm]; every result carries the same leading axes, so one call
fits one circle or a whole Monte Carlo batch of circles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

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


def check_points(points, name: str = "points", *, min_points: int = 3) -> np.ndarray:
    """Coerce ``points`` to float ``(..., n_points, 3)`` with ``n_points >= min_points``, all finite."""
    try:
        points = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"`{name}` must be numeric; got {type(points).__name__}") from exc
    if points.ndim < 2 or points.shape[-1] != 3 or points.shape[-2] < min_points:
        raise InputError(f"`{name}` must have shape (n_points, 3) with n_points >= {min_points}; got {points.shape}")
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
        Signed distance of each point to the plane [mm] (axial deviation).
    rms : ndarray, shape (...)
        RMS of ``residuals`` [mm].
    """

    centroid: np.ndarray
    normal: np.ndarray
    basis: np.ndarray
    residuals: np.ndarray
    rms: np.ndarray


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
        RMS of the two residuals [mm].
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
    plane_residuals: np.ndarray
    radial_residuals: np.ndarray
    plane_rms: np.ndarray
    circle_rms: np.ndarray
    method: str
    iterations: int
    converged: bool
    in_plane: np.ndarray | None = None


def _smallest_eigenpair(xx, yy, zz, xy, xz, yz):
    """Eigenvalues (ascending) and the smallest-eigenvalue eigenvector of batched symmetric 3x3 matrices.

    Closed form: eigenvalues by the trigonometric solution of the characteristic cubic (Smith 1961),
    then the eigenvector as the largest cross product of two rows of ``S - lambda_min I``. For a
    scatter matrix of circle points the error of the vector is ~eps * lambda_max / lambda_mid, and
    it is ~10x cheaper than ``np.linalg.eigh`` on a batch.
    """
    off = xy * xy + xz * xz + yz * yz
    mean = (xx + yy + zz) / 3.0
    a, d, f = xx - mean, yy - mean, zz - mean
    p = np.sqrt((a * a + d * d + f * f + 2.0 * off) / 6.0)
    safe = np.where(p > 0.0, p, 1.0)
    det = (a * (d * f - yz * yz) - xy * (xy * f - yz * xz) + xz * (xy * yz - d * xz)) / safe**3
    phi = np.arccos(np.clip(det / 2.0, -1.0, 1.0)) / 3.0
    largest = mean + 2.0 * p * np.cos(phi)
    smallest = mean + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    middle = 3.0 * mean - largest - smallest
    row0 = np.stack([xx - smallest, xy, xz], axis=-1)
    row1 = np.stack([xy, yy - smallest, yz], axis=-1)
    row2 = np.stack([xz, yz, zz - smallest], axis=-1)
    candidates = np.stack([_cross(row0, row1), _cross(row0, row2), _cross(row1, row2)], axis=-2)
    norms = _dot(candidates, candidates)
    best = np.argmax(norms, axis=-1)
    vector = np.take_along_axis(candidates, best[..., None, None], axis=-2)[..., 0, :]
    vector = vector / np.sqrt(np.take_along_axis(norms, best[..., None], axis=-1))
    return np.stack([smallest, middle, largest], axis=-1), vector


def _row_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``sum(a * b, axis=-1)`` in one pass, without the product array (~3x faster on a batch)."""
    return np.einsum("...i,...i->...", a, b)


def _row_sum(a: np.ndarray) -> np.ndarray:
    """``sum(a, axis=-1)`` (einsum: ~2x faster than ``ndarray.sum`` over short rows)."""
    return np.einsum("...i->...", a)


def _plane_fit(points) -> tuple[PlaneFit, np.ndarray, np.ndarray]:
    """:func:`fit_plane` and the in-plane coordinates ``(u, v)`` of the points, ``(..., n_points)`` each.

    The centred coordinates are held as three contiguous ``(..., n_points)`` arrays (one transposing
    copy), so that every later pass reads contiguous rows rather than every third number.
    """
    points = check_points(points)
    centroid = points.mean(axis=-2)
    centred = np.ascontiguousarray(np.moveaxis(points, -1, -2))  # (..., 3, n_points)
    centred -= centroid[..., :, None]
    x, y, z = centred[..., 0, :], centred[..., 1, :], centred[..., 2, :]
    _, normal = _smallest_eigenpair(
        _row_dot(x, x), _row_dot(y, y), _row_dot(z, z), _row_dot(x, y), _row_dot(x, z), _row_dot(y, z)
    )
    # u: the normal crossed with the coordinate axis it is least aligned with
    least = np.argmin(np.abs(normal), axis=-1)
    axis = np.zeros(normal.shape)
    np.put_along_axis(axis, least[..., None], 1.0, axis=-1)
    u = _cross(normal, axis)
    u = u / np.sqrt(_dot(u, u))[..., None]
    v = _cross(normal, u)
    # Collinearity from the in-plane 2x2 scatter, whose smaller eigenvalue is accurate to ~eps * largest
    # (the cubic's double root near 0 is only accurate to ~sqrt(eps) * largest).
    cu = x * u[..., None, 0] + y * u[..., None, 1] + z * u[..., None, 2]
    cv = x * v[..., None, 0] + y * v[..., None, 1] + z * v[..., None, 2]
    suu, svv, suv = _row_dot(cu, cu), _row_dot(cv, cv), _row_dot(cu, cv)
    half_trace, radius = 0.5 * (suu + svv), np.sqrt((0.5 * (suu - svv)) ** 2 + suv**2)
    spread_small = np.sqrt(np.maximum(half_trace - radius, 0.0))
    spread_large = np.sqrt(np.maximum(half_trace + radius, 0.0))
    degenerate = spread_small <= COLLINEAR_RATIO * np.maximum(spread_large, 1e-300)
    if np.any(degenerate):
        where = "" if np.ndim(degenerate) == 0 else f" (batch item {np.argwhere(degenerate)[0].tolist()})"
        raise DegenerateGeometryError(
            f"points are collinear or coincident{where}: they do not define a plane or a circle"
        )
    residuals = x * normal[..., None, 0] + y * normal[..., None, 1] + z * normal[..., None, 2]
    plane = PlaneFit(
        centroid=centroid,
        normal=normal,
        basis=np.stack([u, v], axis=-2),
        residuals=residuals,
        rms=np.sqrt(_row_dot(residuals, residuals) / residuals.shape[-1]),
    )
    return plane, cu, cv


def fit_plane(points) -> PlaneFit:
    """Fit planes to ``points (..., n_points, 3)`` by orthogonal (total) least squares.

    The normal is the eigenvector of the centred points' scatter matrix ``S = sum_k c_k c_k^T``
    (``c_k = p_k - centroid``) with the smallest eigenvalue, so the fit minimises
    ``sum_k (c_k . n)^2``. The scatter matrix of a batch is six sums and its eigenpair has a closed
    form (see ``_smallest_eigenpair``); the in-plane axes ``u, v`` are any orthonormal pair with
    ``u x v = normal`` (the circle fit does not depend on their orientation in the plane).

    Raises
    ------
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


def _solve3(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve batched symmetric 3x3 systems ``matrix (..., 3, 3) x = rhs (..., 3)`` by Cramer's rule."""
    solution = _solve3_components(
        matrix[..., 0, 0], matrix[..., 0, 1], matrix[..., 0, 2], matrix[..., 1, 1], matrix[..., 1, 2],
        matrix[..., 2, 2], rhs[..., 0], rhs[..., 1], rhs[..., 2],
    )  # fmt: skip
    return np.stack(solution, axis=-1)


def _fit_circle_2d_algebraic(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kasa fit: minimise ``sum_k (|w_k|^2 + D w_k,u + E w_k,v + F)^2`` (linear in D, E, F).

    ``u, v (..., n_points)`` are in-plane coordinates [mm], scaled to unit RMS inside for conditioning.
    """
    n_points = u.shape[-1]
    scale = np.sqrt((_row_dot(u, u) + _row_dot(v, v)) / n_points)
    inverse = 1.0 / scale[..., None]
    su, sv = u * inverse, v * inverse
    squared = su * su
    squared += sv * sv  # |w|^2; the right-hand side is its negative
    uu, uv_, vv = _row_dot(su, su), _row_dot(su, sv), _row_dot(sv, sv)
    us, vs = _row_sum(su), _row_sum(sv)
    d_coefficient, e_coefficient, f_coefficient = _solve3_components(
        uu, uv_, us, vv, vs, np.full(scale.shape, float(n_points)),
        -_row_dot(su, squared), -_row_dot(sv, squared), -_row_sum(squared),
    )  # fmt: skip
    centre = -0.5 * np.stack([d_coefficient, e_coefficient], axis=-1)
    radius = np.sqrt(np.maximum(np.sum(centre**2, axis=-1) - f_coefficient, 0.0))
    return centre * scale[..., None], radius * scale


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

    Returns the centre ``(..., 2)``, the radius, the iterations, whether every item converged, the
    radial residuals ``|w_k - c| - R`` ``(..., n_points)``, their sum of squares and ``w_k - c`` as
    ``(du, dv)`` at the solution.
    """
    cu, cv, r = centre[..., 0].copy(), centre[..., 1].copy(), radius.copy()
    n_points = float(u.shape[-1])

    def evaluate(cu, cv, r):
        du, dv = u - cu[..., None], v - cv[..., None]
        dist = du * du
        dist += dv * dv
        np.sqrt(dist, out=dist)
        res = dist - r[..., None]
        return du, dv, dist, res, _row_dot(res, res)

    du, dv, dist, res, cost = evaluate(cu, cv, r)
    damping = np.zeros(cu.shape)
    active = np.ones(cu.shape, dtype=bool)
    iterations = 0
    for iteration in range(1, max_iterations + 1):
        iterations = iteration
        inverse = np.maximum(dist, 1e-300)
        np.divide(1.0, inverse, out=inverse)
        gu, gv = du * inverse, dv * inverse  # J = [-gu, -gv, -1]
        lift = 1.0 + damping
        steps = _solve3_components(
            _row_dot(gu, gu) * lift, _row_dot(gu, gv), _row_sum(gu), _row_dot(gv, gv) * lift, _row_sum(gv),
            n_points * lift, -_row_dot(gu, res), -_row_dot(gv, res), -_row_sum(res),
        )  # fmt: skip
        step_u, step_v, step_r = (np.where(active & np.isfinite(step), -step, 0.0) for step in steps)
        trial = evaluate(cu + step_u, cv + step_v, r + step_r)
        # Accept steps that do not raise the cost beyond its rounding floor: near the minimum the cost
        # cannot resolve parameter changes below ~sqrt(eps) * noise, the Gauss-Newton step can.
        better = (trial[4] <= cost * (1.0 + COST_TOLERANCE)) & active
        cu = np.where(better, cu + step_u, cu)
        cv = np.where(better, cv + step_v, cv)
        r = np.where(better, r + step_r, r)
        if np.all(better):
            du, dv, dist, res = trial[:4]
        else:  # in place: np.where would allocate four (..., n_points) arrays
            keep = better[..., None]
            for old, new in zip((du, dv, dist, res), trial[:4], strict=True):
                np.copyto(old, new, where=keep)
        cost = np.where(better, trial[4], cost)
        damping = np.where(better, damping * 0.1, np.maximum(damping * 10.0, 1e-6))
        largest = np.maximum(np.maximum(np.abs(step_u), np.abs(step_v)), np.abs(step_r))
        small_step = largest <= tolerance * np.maximum(r, 1.0)
        active &= ~(small_step | (damping > 1e12))
        if not np.any(active):
            break
    converged = bool(not np.any(active))
    return np.stack([cu, cv], axis=-1), r, iterations, converged, res, cost, (du, dv)


def fit_circle_3d(
    points,
    *,
    method: Literal["geometric", "algebraic"] = "geometric",
    max_iterations: int = 50,
    tolerance: float = 1e-12,
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

    Returns
    -------
    CircleFit

    References
    ----------
    Thesis ch. 4.4.1 (step 3) and algorithm 5.2.2.1.
    """
    if method not in ("geometric", "algebraic"):
        raise InputError(f"`method` must be 'geometric' or 'algebraic'; got {method!r}")
    plane, u, v = _plane_fit(points)  # u, v: the projected points' in-plane coordinates
    axis_u, axis_v = plane.basis[..., 0, :], plane.basis[..., 1, :]
    centre_uv, radius = _fit_circle_2d_algebraic(u, v)
    iterations, converged = 0, True
    if method == "geometric":
        centre_uv, radius, iterations, converged, radial, cost, (du, dv) = _refine_circle_2d_geometric(
            u, v, centre_uv, radius, max_iterations=max_iterations, tolerance=tolerance
        )
    else:
        du, dv = u - centre_uv[..., 0, None], v - centre_uv[..., 1, None]
        radial = np.sqrt(du * du + dv * dv) - radius[..., None]
        cost = _row_dot(radial, radial)
    centre = plane.centroid + centre_uv[..., 0, None] * axis_u + centre_uv[..., 1, None] * axis_v
    return CircleFit(
        centre=centre,
        normal=plane.normal,
        radius=radius,
        plane_residuals=plane.residuals,
        radial_residuals=radial,
        plane_rms=plane.rms,
        circle_rms=np.sqrt(cost / radial.shape[-1]),
        method=method,
        iterations=iterations,
        converged=converged,
        in_plane=np.stack([du, dv], axis=-1),
    )
