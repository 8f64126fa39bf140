"""Batched orthogonal plane fit and in-plane circle fit of 3-D points (CPA, thesis ch. 4.4.1 step 3).

Shapes: ``points (..., n_points, 3)`` [mm]; every result carries the same leading axes, so one call
fits one circle or a whole Monte Carlo batch of circles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from robotcal.errors import DegenerateGeometryError, InputError

__all__ = ["PlaneFit", "CircleFit", "fit_plane", "fit_circle_3d", "check_points"]

#: Smallest ratio of the second to the first singular value of the centred points before the
#: points are called collinear (a 100 mm circle arc would need a sagitta below ~1e-7 mm).
COLLINEAR_RATIO = 1e-9


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


def fit_plane(points) -> PlaneFit:
    """Fit planes to ``points (..., n_points, 3)`` by orthogonal (total) least squares.

    The normal is the right singular vector of the centred points with the smallest singular value,
    so the fit minimises ``sum_k ((p_k - centroid) . n)^2``.

    Raises
    ------
    DegenerateGeometryError
        If the points of a batch item are (nearly) collinear or coincident.
    """
    points = check_points(points)
    centroid = points.mean(axis=-2)
    centred = points - centroid[..., None, :]
    _, singular, vt = np.linalg.svd(centred, full_matrices=False)
    degenerate = singular[..., 1] <= COLLINEAR_RATIO * np.maximum(singular[..., 0], 1e-300)
    if np.any(degenerate):
        where = "" if degenerate.ndim == 0 else f" (batch item {np.argwhere(degenerate)[0].tolist()})"
        raise DegenerateGeometryError(
            f"points are collinear or coincident{where}: they do not define a plane or a circle"
        )
    normal = vt[..., 2, :]
    u = vt[..., 0, :]
    v = np.cross(normal, u)
    residuals = np.einsum("...ki,...i->...k", centred, normal)
    return PlaneFit(
        centroid=centroid,
        normal=normal,
        basis=np.stack([u, v], axis=-2),
        residuals=residuals,
        rms=np.sqrt(np.mean(residuals**2, axis=-1)),
    )


def _fit_circle_2d_algebraic(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kasa fit: minimise ``sum_k (|u_k|^2 + D u_k + E v_k + F)^2`` (linear in D, E, F)."""
    scale = np.sqrt(np.mean(np.sum(uv**2, axis=-1), axis=-1))[..., None, None]
    w = uv / scale
    design = np.concatenate([w, np.ones(w.shape[:-1] + (1,))], axis=-1)
    rhs = -np.sum(w**2, axis=-1)
    normal_matrix = np.einsum("...ki,...kj->...ij", design, design)
    coefficients = np.linalg.solve(normal_matrix, np.einsum("...ki,...k->...i", design, rhs)[..., None])
    coefficients = coefficients[..., 0]
    centre = -0.5 * coefficients[..., :2]
    radius = np.sqrt(np.maximum(np.sum(centre**2, axis=-1) - coefficients[..., 2], 0.0))
    return centre * scale[..., 0], radius * scale[..., 0, 0]


def _refine_circle_2d_geometric(
    uv: np.ndarray, centre: np.ndarray, radius: np.ndarray, *, max_iterations: int, tolerance: float
) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Batched Levenberg-Marquardt on ``sum_k (|u_k - c| - R)^2`` over ``(c, R)``.

    Written by hand because it runs over a whole batch of independent 3-unknown problems at once,
    which ``scipy.optimize.least_squares`` cannot; the tests compare it with scipy circle by circle.
    """
    params = np.concatenate([centre, radius[..., None]], axis=-1)
    damping = np.full(params.shape[:-1], 1e-3)

    def residuals_and_jacobian(p):
        diff = uv - p[..., None, :2]
        dist = np.sqrt(np.sum(diff**2, axis=-1))
        res = dist - p[..., None, 2]
        jac = np.empty(diff.shape[:-1] + (3,))
        jac[..., :2] = -diff / np.maximum(dist, 1e-300)[..., None]
        jac[..., 2] = -1.0
        return res, jac

    res, jac = residuals_and_jacobian(params)
    cost = np.sum(res**2, axis=-1)
    active = np.ones(params.shape[:-1], dtype=bool)
    iterations = 0
    for iteration in range(1, max_iterations + 1):
        iterations = iteration
        jtj = np.einsum("...ki,...kj->...ij", jac, jac)
        jtr = np.einsum("...ki,...k->...i", jac, res)
        diag = np.einsum("...ii->...i", jtj)
        lhs = jtj + (damping[..., None] * diag)[..., None, :] * np.eye(3)
        step = -np.linalg.solve(lhs, jtr[..., None])[..., 0]
        step = np.where(active[..., None], step, 0.0)
        trial = params + step
        trial_res, trial_jac = residuals_and_jacobian(trial)
        trial_cost = np.sum(trial_res**2, axis=-1)
        better = (trial_cost <= cost) & active
        params = np.where(better[..., None], trial, params)
        res = np.where(better[..., None], trial_res, res)
        jac = np.where(better[..., None, None], trial_jac, jac)
        cost = np.where(better, trial_cost, cost)
        damping = np.where(better, damping * 0.1, damping * 10.0)
        small_step = np.max(np.abs(step), axis=-1) <= tolerance * np.maximum(params[..., 2], 1.0)
        active &= ~(small_step | (damping > 1e12))
        if not np.any(active):
            break
    converged = bool(not np.any(active))
    return params[..., :2], params[..., 2], iterations, converged


def fit_circle_3d(
    points,
    *,
    method: Literal["geometric", "algebraic"] = "geometric",
    max_iterations: int = 50,
    tolerance: float = 1e-13,
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
    plane = fit_plane(points)
    points = np.asarray(points, dtype=float)
    centred = points - plane.centroid[..., None, :]
    uv = np.einsum("...ki,...ji->...kj", centred, plane.basis)
    centre_uv, radius = _fit_circle_2d_algebraic(uv)
    iterations, converged = 0, True
    if method == "geometric":
        centre_uv, radius, iterations, converged = _refine_circle_2d_geometric(
            uv, centre_uv, radius, max_iterations=max_iterations, tolerance=tolerance
        )
    radial = np.sqrt(np.sum((uv - centre_uv[..., None, :]) ** 2, axis=-1)) - radius[..., None]
    centre = plane.centroid + np.einsum("...j,...ji->...i", centre_uv, plane.basis)
    return CircleFit(
        centre=centre,
        normal=plane.normal,
        radius=radius,
        plane_residuals=plane.residuals,
        radial_residuals=radial,
        plane_rms=plane.rms,
        circle_rms=np.sqrt(np.mean(radial**2, axis=-1)),
        method=method,
        iterations=iterations,
        converged=converged,
    )
