"""The GUM law of propagation for the Monte Carlo's problem: the covariances JCGM 101 §8 compares the draws with.

CPA's covariance by central differences over the measured coordinates, the refinement's first-order covariance
at the noise-free solution (:func:`robotcal.uncertainty.refined.refined_covariance`); the comparison itself is
:func:`robotcal.uncertainty.montecarlo.linearised_uncertainty`.

References
----------
JCGM 100:2008 §5.1 (law of propagation); JCGM 101:2008 §8; thesis ch. 5.2.3.
"""

from __future__ import annotations

from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from robotcal.identification.cpa import identify_cpa_batch
from robotcal.uncertainty.montecarlo_problem import MonteCarloProblem, coordinate_variance

__all__ = ["LinearisedResult"]


@dataclass(frozen=True, slots=True, kw_only=True)
class LinearisedResult:
    """GUM law of propagation of uncertainty (linearised) for the same capture, and its §8 check.

    Attributes
    ----------
    estimate : ndarray, shape (n_joints, 5)
        ``f(x)``: CPA of the noise-free capture [mm, rad].
    covariance : ndarray, shape (n_params, n_params)
        ``J U_x J^T`` over every parameter (joint-major, ``n_params = 5 n_joints``) [mm^2, mm rad, rad^2].
    std_uncertainty : ndarray, shape (n_joints, 5)
    coverage_low, coverage_high : ndarray, shape (n_joints, 5)
        ``f(x) -+ k_p u`` with ``k_p`` the normal quantile for coverage p.
    agrees : ndarray of bool, shape (n_joints, 5)
        JCGM 101 §8.2: both ``|y - U_p - y_low|`` and ``|y + U_p - y_high|`` are within the numerical
        tolerance of ``ndig`` significant digits of u (identified parameters only; True elsewhere).
    endpoint_difference : ndarray, shape (n_joints, 5)
        The larger of the two endpoint differences [mm, rad].
    tolerance : ndarray, shape (n_joints, 5)
    step_mm : float
        Central-difference step of the Jacobian.
    """

    estimate: np.ndarray
    covariance: np.ndarray
    std_uncertainty: np.ndarray
    coverage_low: np.ndarray
    coverage_high: np.ndarray
    agrees: np.ndarray
    endpoint_difference: np.ndarray
    tolerance: np.ndarray
    step_mm: float


def linearised_result(
    *,
    estimate: np.ndarray,
    covariance: np.ndarray,
    std: np.ndarray,
    tolerance: np.ndarray,
    coverage: float,
    drawn: tuple[np.ndarray, np.ndarray] | None,
    determined: np.ndarray,
    step_mm: float,
) -> LinearisedResult:
    """The :class:`LinearisedResult` of ``estimate`` with the standard uncertainties ``std`` (of ``covariance``):
    the interval ``estimate -+ k_p std`` for ``coverage`` compared endpoint by endpoint with the Monte Carlo
    interval ``drawn`` (JCGM 101 §8.2) within ``tolerance``, agreeing wherever a parameter is not ``determined``;
    without ``drawn`` no comparison (NaN differences, every parameter agrees)."""
    k = NormalDist().inv_cdf(0.5 + coverage / 2.0)  # statistics, not scipy.stats: no slow import
    low, high = estimate - k * std, estimate + k * std
    if drawn is not None:
        mc_low, mc_high = drawn
        difference = np.maximum(np.abs(low - mc_low), np.abs(high - mc_high))
        agrees = (difference <= tolerance) | ~determined
    else:
        difference = np.full(std.shape, np.nan)
        agrees = np.ones(std.shape, dtype=bool)
    return LinearisedResult(
        estimate=estimate,
        covariance=covariance,
        std_uncertainty=std,
        coverage_low=low,
        coverage_high=high,
        agrees=agrees,
        endpoint_difference=difference,
        tolerance=tolerance,
        step_mm=step_mm,
    )


def _input_variance(problem: MonteCarloProblem) -> np.ndarray:
    """Variance of each measured coordinate ``(n_points, 3)`` [mm^2]: U^2/3 (uniform) or (U/k)^2."""
    return coordinate_variance(problem.instrument, problem.error_bound) + problem.repeatability_sd**2


def _refined_full_covariance(problem: MonteCarloProblem, cpa_covariance: np.ndarray) -> np.ndarray:
    """Joint-major covariance of the refined model: the refinement's linearised covariance for the
    parameters it estimates (:func:`robotcal.uncertainty.refined.refined_covariance`, exact to first
    order); CPA's for identified parameters the refinement holds at their CPA value (their
    cross-covariance with the refined ones is left out)."""
    from robotcal.uncertainty.refined import refined_covariance

    model = problem.refined
    assert model is not None  # called for the refined model only
    free_cov = refined_covariance(model, problem.exact_points, _input_variance(problem))
    mask = model.free.reshape(-1)
    index = np.flatnonzero(mask)
    covariance = cpa_covariance.copy()
    covariance[mask, :] = 0.0
    covariance[:, mask] = 0.0
    covariance[np.ix_(index, index)] = free_cov[: index.size, : index.size]
    return covariance


def _cpa_covariance(problem: MonteCarloProblem, step: float) -> np.ndarray:
    """``J U_x J^T`` of CPA, J by central differences over the measured coordinates [mm, rad]."""
    n_points = problem.n_points
    n_inputs = 3 * n_points
    perturbation = np.zeros((2 * n_inputs, n_points, 3))
    index = np.arange(n_inputs)
    perturbation[index, index // 3, index % 3] = step
    perturbation[n_inputs + index, index // 3, index % 3] = -step
    values = identify_cpa_batch(
        problem.exact_points + perturbation, problem.structure, problem.tracker_from_base, residuals=False
    ).values
    flat = values.reshape(2 * n_inputs, -1)
    jacobian = ((flat[:n_inputs] - flat[n_inputs:]) / (2.0 * step)).T  # (n_params, n_inputs)
    variance = _input_variance(problem).reshape(-1)
    return np.einsum("ik,jk->ij", jacobian * variance, jacobian)  # not BLAS: see _covariance
