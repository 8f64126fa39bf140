"""Identifiability of kinematic parameters from a capture: rank, conditioning, correlations.

The check works on the *column-scaled* Jacobian ``J S`` (``S = diag(x_scale)``: 1 mm for lengths,
``1/L`` rad for angles with L the size of the measured point cloud), so that a column's size means
"how many mm the points move for a typical change of this parameter" and a condition number
compares like with like.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Conditioning", "select_identifiable", "conditioning", "correlation_from_covariance", "triangular_factor"]


def triangular_factor(matrix) -> np.ndarray:
    """R of a thin QR of a tall ``matrix (m, p)``, else the matrix itself.

    ``R^T R = J^T J``: column norms, angles between columns, singular values and right singular
    vectors are those of J, at the cost of a p x p matrix (168,000 pair residuals reduce to 24 rows).
    """
    matrix = np.asarray(matrix, dtype=float)
    if matrix.shape[0] > matrix.shape[1] > 0:
        return np.linalg.qr(matrix, mode="r")  # type: ignore[return-value]  # numpy's stubs: a QRResult; mode "r" gives R
    return matrix


@dataclass(frozen=True, slots=True, kw_only=True)
class Conditioning:
    """Singular values and condition number of a column-scaled Jacobian.

    Attributes
    ----------
    singular_values : ndarray, shape (n_free,)
        Descending [mm per scaled unit].
    condition_number : float
        ``s_max / s_min`` (inf when a column is dependent).
    """

    singular_values: np.ndarray
    condition_number: float


def select_identifiable(scaled_jacobian, candidates, *, tolerance: float = 1e-7) -> np.ndarray:
    """Greedy, ordered rank-revealing selection of the columns the data can determine.

    Columns are taken in the order given; a column is kept when the part of it orthogonal to the
    columns kept so far is larger than ``tolerance`` times its own norm, and the column itself is
    larger than ``tolerance`` times the largest candidate column (a unit change that moves the
    points by less than that is not determined by any realistic data). A parameter whose effect on the residuals is a combination of earlier parameters' (a
    gauge freedom, a joint that never moves, joint n's offsets behind a per-joint reflector) is
    therefore held, and the earlier ones stay free: the order says which of a dependent group is
    kept.

    Parameters
    ----------
    scaled_jacobian : array_like, shape (n_residuals, n_columns)
    candidates : array_like of bool, shape (n_columns,)
        Columns that may be freed; the others are skipped.
    tolerance : float
        Relative size of the independent part below which a column counts as dependent. Exact
        dependencies give ~1e-12 in double precision; 1e-7 leaves room for rounding while flagging
        only what no realistic data can resolve.

    Returns
    -------
    ndarray of bool, shape (n_columns,)
        True for the columns kept.
    """
    jacobian = triangular_factor(scaled_jacobian)
    candidates = np.asarray(candidates, dtype=bool)
    norms = np.linalg.norm(jacobian, axis=0)
    largest = norms[candidates].max() if np.any(candidates) else 0.0
    basis = np.empty((jacobian.shape[0], 0))
    keep = np.zeros(jacobian.shape[1], dtype=bool)
    for column in np.flatnonzero(candidates):
        if norms[column] <= tolerance * max(largest, 1e-300):
            continue
        vector = jacobian[:, column] / norms[column]
        for _ in range(2):  # Gram-Schmidt twice: orthogonal to working precision
            vector = vector - basis @ (basis.T @ vector)
        size = np.linalg.norm(vector)
        if size > tolerance:
            basis = np.column_stack([basis, vector / size])
            keep[column] = True
    return keep


def conditioning(scaled_jacobian) -> Conditioning:
    """Singular values and condition number of ``scaled_jacobian (n_residuals, n_columns)``."""
    jacobian = triangular_factor(scaled_jacobian)
    if jacobian.shape[1] == 0:
        return Conditioning(singular_values=np.zeros(0), condition_number=1.0)
    singular = np.linalg.svd(jacobian, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    singular.setflags(write=False)
    return Conditioning(singular_values=singular, condition_number=condition)


def correlation_from_covariance(covariance) -> np.ndarray:
    """Correlation matrix ``C_ij / sqrt(C_ii C_jj)`` (NaN rows for zero variance)."""
    covariance = np.asarray(covariance, dtype=float)
    sd = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        correlation = covariance / np.outer(sd, sd)
    return correlation
