"""Propagation of Monte Carlo parameter draws to the tool centre point (thesis ch. 5.3, Table 5.8).

Every parameter draw ``(n_joints, 5)`` is pushed through the forward kinematics at every pose (thesis
5.3: "se han verificado todas las combinaciones de parámetros cinemáticos obtenidas mediante la
calibración"), giving a TCP position X, Y, Z [mm] and a KUKA orientation A, B, C per draw and pose.
The draws of those six coordinates are then summarised like the parameters (JCGM 101 §7.6-7.7:
mean, standard uncertainty, coverage interval, min, max), the position's 3x3 covariance gives a
coverage ellipsoid (JCGM 102 §6.5.3, §7.7), and a linearised propagation (the draws' parameter
covariance through the kinematic Jacobian, JCGM 102 §6.2) is given beside it.

Orientation: KUKA ``A, B, C`` with ``R = Rz(A) Ry(B) Rx(C)`` (A about Z, B about Y, C about X;
:mod:`robotcal.geometry.euler`). The thesis's Table 5.8 lists the same three angles in X, Y, Z order.
Lengths in mm, angles in radians in every array here; the I/O layer writes degrees.

Memory stays bounded for any number of draws and poses: poses are handled in chunks whose six
coordinates for every draw fit in ``max_bytes`` (one chunk in flight, shared by the threads), and
within a chunk the draws go through the kinematics ``batch_size`` at a time. Only the 6 coordinates per
draw and pose of the chunk in flight are held (with as much again for their centred copies), and the link
transforms ``B_i`` of every draw when they fit in ``max(max_bytes, _LINK_BYTES)`` (else those of one batch,
recomputed for every pose chunk), never the 4x4 frames of all draws and poses.

Speed (``benchmarks/bench_tcp.py``): the chunk holds the draws *last*, ``(poses, 6, draws)``, so one
vectorised partition and two sorts of the 5 % tails per chunk give every order statistic of both
coverage intervals and the min/max (a full sort took twice as long); the chain is carried as
``(3 P, 4)`` blocks ``[R | t]`` per draw whose first two columns are adjacent, so that ``Rz(q)`` is one
in-place complex product ``(column_0 + i column_1) exp(-i q)`` and ``B_i`` one ``(3 P, 4) @ (4, 4)``
product (2 to 2.5x cheaper than turning separate column slabs); the first joint is applied
analytically (``Rz(q_1)`` turns X, Y per chunk and adds ``q_1`` to A); each angle is the nominal's plus
the angle of its vector turned by the nominal, ``arctan2(y', x')``, so that no quadrant fix or wrap is
needed (:func:`_angle_from`). Chunks hold as many poses as ``max_bytes`` allows (the per-draw products
cost less per pose the more poses they carry); the threads share each chunk, its batches of draws
first, then its poses for the statistics (numpy releases the GIL), with one reused pair of buffers.
The results equal the plain composition (4x4 frames, :func:`~robotcal.uncertainty.statistics.summarize_draws`)
to 1e-10 mm/rad (``tests/unit/uncertainty/test_tcp_reference.py``). :func:`position_covariance` is
the position part alone (a point carried from the tool end), for checks that need only the spread of
a point.
"""

from __future__ import annotations

import math
import os
import warnings
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, field

import numpy as np

from robotcal.errors import InputError, JointLimitWarning
from robotcal.execution import single_blas_thread
from robotcal.kinematics.model import RobotModel, check_parameter_array
from robotcal.uncertainty.statistics import SampleSummary, _interval_length, check_coverage
from robotcal.uncertainty.tcp_kinematics import (
    _ANGLE_KINDS,
    _abc_near,
    _chain_columns,
    _chain_points,
    _coordinates,
    _pose_independent_links,
    check_tool,
    tcp_coordinates,
    tcp_jacobian,
)

__all__ = [
    "TCP_COORDINATES",
    "TCP_UNITS",
    "ORIENTATION_CONVENTION",
    "CoverageEllipsoid",
    "TCPUncertainty",
    "check_readings",
    "check_tool",
    "tcp_coordinates",
    "tcp_jacobian",
    "position_covariance",
    "coverage_ellipsoid",
    "propagate_to_tcp",
]

#: Names of the six TCP coordinates, in the column order of every ``(..., 6)`` array.
TCP_COORDINATES = ("X", "Y", "Z", "A", "B", "C")
#: Units of the six coordinates in files and reports (the arrays here hold radians for A, B, C).
TCP_UNITS = ("mm", "mm", "mm", "deg", "deg", "deg")
ORIENTATION_CONVENTION = (
    "KUKA A, B, C: R = Rz(A) Ry(B) Rx(C), A about Z, B about Y, C about X (scipy Rotation 'ZYX'); "
    "thesis Table 5.8 lists the same angles in X, Y, Z order, i.e. (C, B, A)"
)
#: Draw-poses per kinematics call when ``batch_size`` is not given (~2 MB per temporary block).
_BLOCK_FRAMES = 20_000
#: The link factors ``B_i`` of every draw (128 bytes per draw and joint) are computed once per call when they take
#: at most ``max(max_bytes, _LINK_BYTES)``: 100,000 draws of 6 joints take 77 MB; beyond, once per batch and pose chunk.
_LINK_BYTES = 256 * 2**20
#: Threads filling the draw batches of a pose chunk (numpy releases the GIL in the kinematics).
_THREADS = min(2, os.cpu_count() or 1)


# ----------------------------------------------------------------------------------------------- checks
def chi2_quantile(probability: float, degrees: int) -> float:
    """``chi2.ppf(probability, degrees)``: the chi-squared quantile, from ``scipy.special.chdtri`` (its upper
    tail inverse): ``scipy.stats`` is slow to import for a command's start-up. Imported here, where it is used:
    the figure worker imports this module for its types and never needs scipy."""
    from scipy.special import chdtri

    return float(chdtri(degrees, 1.0 - probability))


def check_readings(robot: RobotModel, readings, *, name: str = "readings", source: str = "") -> np.ndarray:
    """Coerce controller readings to ``(n_poses, n_joints)`` [rad]; warn for readings outside the limits.

    Parameters
    ----------
    robot : RobotModel
    readings : array_like, shape (n_poses, n_joints) or (n_joints,)
        Controller joint readings [rad] (mapped to model joint variables by the robot's
        ``reading_sign`` and ``reading_offset``).
    name, source : str
        Argument name and file used in messages; poses are numbered from 1.

    Raises
    ------
    InputError
        Wrong joint count or non-finite values (naming the pose).

    Warns
    -----
    JointLimitWarning
        Readings outside the robot file's software limits (naming pose, joint and limits),
        attributed to the caller of this function.
    """
    return _check_readings(robot, readings, name=name, source=source, stacklevel=3)


def _check_readings(robot: RobotModel, readings, *, name: str, source: str, stacklevel: int) -> np.ndarray:
    """:func:`check_readings` with the warning's ``stacklevel`` counted from this function.

    ``stacklevel=3`` points at the caller of the public function that called this one
    (:func:`check_readings` itself, or :func:`propagate_to_tcp`).
    """
    prefix = f"{source}: " if source else ""
    try:
        values = np.asarray(readings, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{prefix}`{name}` must be numeric joint readings") from exc
    if values.ndim == 1:
        values = values[None, :]
    n = robot.n_joints
    if values.ndim != 2 or values.shape[1] != n or values.shape[0] < 1:
        got = values.shape[1] if values.ndim == 2 else values.shape
        raise InputError(f"{prefix}`{name}` must give {n} joint readings per pose (robot {robot.name!r}); got {got}")
    bad = np.argwhere(~np.isfinite(values))
    if bad.size:
        pose, joint = bad[0]
        raise InputError(f"{prefix}`{name}`: pose {pose + 1}, joint J{joint + 1} is not a finite number")
    outside = (values < robot.limits[:, 0] - 1e-12) | (values > robot.limits[:, 1] + 1e-12)
    if np.any(outside):
        messages = []
        for pose, joint in np.argwhere(outside)[:5]:
            lo, hi = np.rad2deg(robot.limits[joint])
            messages.append(
                f"pose {pose + 1}: J{joint + 1} = {np.rad2deg(values[pose, joint]):.6g} deg outside [{lo:g}, {hi:g}] deg"
            )
        more = int(outside.sum()) - len(messages)
        tail = f"; and {more} more" if more > 0 else ""
        warnings.warn(
            f"{prefix}readings outside the joint limits of robot {robot.name!r}: " + "; ".join(messages) + tail,
            JointLimitWarning,
            stacklevel=stacklevel,
        )
    return values


def _check_draws(robot: RobotModel, draws) -> np.ndarray:
    draws = check_parameter_array(draws, robot.n_joints, "parameter_draws")
    if draws.ndim == 2:
        draws = draws[None]
    if draws.ndim != 3:
        raise InputError(f"`parameter_draws` must have shape (n_draws, {robot.n_joints}, 5); got {draws.shape}")
    return draws


# ------------------------------------------------------------------------------------------------ results
@dataclass(frozen=True, slots=True, kw_only=True)
class CoverageEllipsoid:
    """Coverage ellipsoids of the TCP position, one per pose (JCGM 102 §6.5.3 and §7.7).

    The region is ``(x - mean)^T V^-1 (x - mean) <= k^2`` with ``V`` the 3x3 Monte Carlo covariance.

    Attributes
    ----------
    coverage : float
        Coverage probability p.
    gaussian_scale : float
        ``k`` from the chi-squared distribution with 3 degrees of freedom, ``k^2 = chi2.ppf(p, 3)``
        (exact for a Gaussian position, JCGM 102 §6.5.3).
    semi_axes : ndarray, shape (n_poses, 3)
        ``k sqrt(lambda_j)``, largest first [mm].
    directions : ndarray, shape (n_poses, 3, 3)
        Unit axis directions in the base frame; column j goes with ``semi_axes[:, j]``.
    fraction_inside : ndarray, shape (n_poses,)
        Fraction of the draws inside the chi-squared ellipsoid: close to p when the position is
        nearly Gaussian (a check of the ellipsoid).
    monte_carlo_scale : ndarray, shape (n_poses,)
        ``k_p`` such that the fraction p of the draws lie inside (JCGM 102 §7.7.2: the
        ``round(p M)``-th smallest squared Mahalanobis distance); ``monte_carlo_scale /
        gaussian_scale`` enlarges the semi-axes to the distribution-free region.
    """

    coverage: float
    gaussian_scale: float
    semi_axes: np.ndarray
    directions: np.ndarray
    fraction_inside: np.ndarray
    monte_carlo_scale: np.ndarray

    @property
    def monte_carlo_semi_axes(self) -> np.ndarray:
        """Semi-axes of the Monte Carlo region ``k_p sqrt(lambda_j)`` [mm], ``(n_poses, 3)``."""
        return self.semi_axes * (self.monte_carlo_scale / self.gaussian_scale)[:, None]


@dataclass(frozen=True, slots=True, kw_only=True)
class TCPUncertainty:
    """Uncertainty of the TCP at one or more poses from Monte Carlo parameter draws.

    Every ``(n_poses, 6)`` array has the columns ``TCP_COORDINATES`` = X, Y, Z [mm], A, B, C [rad].

    Attributes
    ----------
    robot_name : str
    readings : ndarray, shape (n_poses, n_joints)
        Controller readings [rad].
    q : ndarray, shape (n_poses, n_joints)
        Model joint variables [rad].
    tool : ndarray, shape (3,)
        TCP in flange coordinates [mm].
    n_draws : int
    nominal : ndarray, shape (n_poses, 6)
        TCP of the nominal parameters.
    summary : SampleSummary
        Mean, standard uncertainty, both coverage intervals, min, max over the draws, each
        ``(n_poses, 6)``. Angles of the draws are taken within +-180 deg of the nominal angle.
    covariance : ndarray, shape (n_poses, 6, 6)
        Monte Carlo covariance of the six coordinates [mm^2, mm rad, rad^2].
    ellipsoid : CoverageEllipsoid
    lpu_covariance : ndarray, shape (n_poses, 6, 6)
        Linearised covariance ``J U_p J^T`` (``U_p``: sample covariance of the draws, ``J`` at the
        mean parameters).
    parameter_mean : ndarray, shape (n_joints, 5)
        Mean of the draws [mm, rad], where the Jacobian is taken.
    draws : ndarray, shape (n_draws, n_poses, 6) or None
        The coordinates of every draw, kept only with ``keep_draws=True``.
    """

    robot_name: str
    readings: np.ndarray
    q: np.ndarray
    tool: np.ndarray
    n_draws: int
    coverage: float
    nominal: np.ndarray
    summary: SampleSummary
    covariance: np.ndarray
    ellipsoid: CoverageEllipsoid
    lpu_covariance: np.ndarray
    parameter_mean: np.ndarray
    draws: np.ndarray | None = field(default=None)

    @property
    def n_poses(self) -> int:
        return self.readings.shape[0]

    @property
    def std_uncertainty(self) -> np.ndarray:
        """Monte Carlo standard uncertainty ``(n_poses, 6)`` [mm, rad]."""
        return self.summary.std_uncertainty

    @property
    def lpu_std_uncertainty(self) -> np.ndarray:
        """Linearised standard uncertainty ``(n_poses, 6)`` [mm, rad]."""
        return np.sqrt(np.clip(np.diagonal(self.lpu_covariance, axis1=-2, axis2=-1), 0.0, None))

    @property
    def value_range(self) -> np.ndarray:
        """``max - min`` over the draws per pose and coordinate (thesis Fig. 5.20) ``(n_poses, 6)``."""
        return self.summary.maximum - self.summary.minimum

    @property
    def position_covariance(self) -> np.ndarray:
        """Monte Carlo 3x3 covariance of X, Y, Z ``(n_poses, 3, 3)`` [mm^2]."""
        return self.covariance[:, :3, :3]

    @property
    def position_uncertainty(self) -> np.ndarray:
        """``sqrt(trace V)``, the root-sum-square of u(X), u(Y), u(Z) ``(n_poses,)`` [mm]."""
        return np.sqrt(np.trace(self.position_covariance, axis1=-2, axis2=-1))


# ---------------------------------------------------------------------------------------------- ellipsoid
def _eigen(covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (descending) and eigenvectors of stacked symmetric 3x3 matrices."""
    values, vectors = np.linalg.eigh(covariance)
    return values[..., ::-1], vectors[..., ::-1]


def _squared_mahalanobis(centred: np.ndarray, values: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``d^2 = c^T V^-1 c`` of ``centred (m, P, 3)``, ``V`` given by its eigenpairs; NaN where singular."""
    singular = ~(values[:, -1] > 1e-14 * np.maximum(values[:, 0], np.finfo(float).tiny))
    safe = np.where(singular[:, None], 1.0, values)
    weight = np.einsum("pij,pj,pkj->pik", vectors, 1.0 / safe, vectors)  # V^-1 per pose
    d2 = np.zeros(centred.shape[:2])
    for i in range(3):  # elementwise over (m, P): six products of coordinates, no (m, P, 3) temporaries
        d2 += weight[:, i, i] * centred[..., i] ** 2
        for j in range(i + 1, 3):
            d2 += 2.0 * weight[:, i, j] * centred[..., i] * centred[..., j]
    d2[:, singular] = np.nan
    return d2


def _rank(n_draws: int, coverage: float) -> int:
    product = coverage * n_draws
    q = int(round(product)) if abs(product - round(product)) < 1e-9 else int(math.floor(product + 0.5))
    return min(max(q, 1), n_draws)


def coverage_ellipsoid(positions, coverage: float = 0.95) -> CoverageEllipsoid:
    """Coverage ellipsoid of position draws ``(n_draws, n_poses, 3)`` [mm] (see :class:`CoverageEllipsoid`)."""
    positions = np.asarray(positions, dtype=float)
    if positions.ndim == 2:
        positions = positions[:, None, :]
    if positions.ndim != 3 or positions.shape[-1] != 3 or positions.shape[0] < 4:
        raise InputError(f"`positions` must have shape (n_draws >= 4, n_poses, 3); got {positions.shape}")
    coverage = check_coverage(coverage)
    centred = positions - positions.mean(axis=0)
    covariance = _sample_covariance(centred)
    return _ellipsoid_from(centred, covariance, coverage)


def _sample_covariance(centred: np.ndarray) -> np.ndarray:
    """``sum_m c_m c_m^T / (M - 1)`` of centred draws ``(M, P, k)`` -> ``(P, k, k)``."""
    k = centred.shape[-1]
    out = np.empty(centred.shape[1:] + (k,))
    for i in range(k):
        for j in range(i, k):
            out[:, i, j] = out[:, j, i] = np.einsum("mp,mp->p", centred[..., i], centred[..., j])
    return out / (centred.shape[0] - 1)


def _ellipsoid_from(centred: np.ndarray, covariance: np.ndarray, coverage: float) -> CoverageEllipsoid:
    values, vectors = _eigen(covariance)
    scale = math.sqrt(chi2_quantile(coverage, 3))
    d2 = _squared_mahalanobis(centred, values, vectors)
    rank = _rank(centred.shape[0], coverage)
    with np.errstate(invalid="ignore"):
        inside = np.mean(d2 <= scale**2, axis=0)
        inside = np.where(np.isnan(d2[0]), np.nan, inside)
        k_mc = np.sqrt(np.sort(d2, axis=0)[rank - 1])
    return _ellipsoid(values, vectors, scale, inside, k_mc, coverage)


def _ellipsoid(
    values: np.ndarray, vectors: np.ndarray, scale: float, inside: np.ndarray, k_mc: np.ndarray, coverage: float
) -> CoverageEllipsoid:
    """The ellipsoids of the covariances' eigenvalues ``values`` and eigenvectors ``vectors`` at the Gaussian
    ``scale``, with the draws' fraction ``inside`` and the Monte Carlo scale ``k_mc`` (of :func:`_ellipsoid_from` and
    :func:`_ellipsoid_rows`)."""
    return CoverageEllipsoid(
        coverage=coverage,
        gaussian_scale=scale,
        semi_axes=scale * np.sqrt(np.clip(values, 0.0, None)),
        directions=vectors,
        fraction_inside=inside,
        monte_carlo_scale=k_mc,
    )


def _summarize_rows(
    values: np.ndarray, coverage: float, *, mean: np.ndarray | None = None, std: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """:func:`~robotcal.uncertainty.statistics.summarize_draws` of draws laid out along the *last* axis.

    ``values (k, M)`` holds ``k`` quantities with ``M`` finite draws each, contiguous per quantity; it is
    partitioned in place. The intervals are read with exactly the order statistics of
    :func:`~robotcal.uncertainty.statistics.coverage_interval` (JCGM 101 §7.7.1 symmetric, §7.7.2
    shortest, first minimum on ties), so the numbers are those of ``summarize_draws`` on the same draws
    (mean and standard deviation up to summation order). ``mean`` and ``std`` ``(k,)``, when the caller
    has them (the mean and the square root of the covariance diagonal), are used as they are.
    """
    n_draws = values.shape[-1]
    q = _interval_length(n_draws, coverage)
    if q >= n_draws:
        raise InputError(
            f"a {coverage:g} coverage interval needs more draws than {n_draws}: at least "
            f"{math.ceil(1.0 / (1.0 - coverage))} (JCGM 101 §7.2 recommends 10^4 or more)"
        )
    out = {
        "mean": values.mean(axis=-1) if mean is None else mean,
        "std_uncertainty": values.std(axis=-1, ddof=1) if std is None else std,
    }
    # only the M - q smallest and the M - q largest draws need their order (every order statistic used
    # below lies there when q > M / 2): two single-index partitions and two sorts of the ~5 % tails instead
    # of a full sort
    tail = n_draws - q
    if tail < q:
        values.partition(q, axis=-1)
        values[:, :q].partition(tail - 1, axis=-1)
        values[:, :tail].sort(axis=-1)
        values[:, q:].sort(axis=-1)
    else:
        values.sort(axis=-1)
    half = (n_draws - q) / 2.0
    r = int(half) if half == int(half) else int(math.floor((n_draws - q + 1) / 2.0))
    r = max(r, 1)
    out["symmetric_low"], out["symmetric_high"] = values[:, r - 1].copy(), values[:, r - 1 + q].copy()
    start = np.argmin(values[:, q:] - values[:, : n_draws - q], axis=-1)
    rows = np.arange(values.shape[0])
    out["shortest_low"], out["shortest_high"] = values[rows, start], values[rows, start + q]
    out["minimum"], out["maximum"] = values[:, 0].copy(), values[:, -1].copy()
    return out


def _ellipsoid_rows(centred: np.ndarray, covariance: np.ndarray, coverage: float) -> CoverageEllipsoid:
    """:func:`_ellipsoid_from` for centred positions laid out ``(P, 3, M)`` (draws last)."""
    values, vectors = _eigen(covariance)
    scale = math.sqrt(chi2_quantile(coverage, 3))
    singular = ~(values[:, -1] > 1e-14 * np.maximum(values[:, 0], np.finfo(float).tiny))
    safe = np.where(singular[:, None], 1.0, values)
    weight = np.einsum("pij,pj,pkj->pik", vectors, 1.0 / safe, vectors)  # V^-1 per pose
    d2 = np.einsum("pim,pim->pm", centred, np.matmul(weight, centred))
    d2[singular] = np.nan
    rank = _rank(centred.shape[-1], coverage)
    with np.errstate(invalid="ignore"):
        inside = np.mean(d2 <= scale**2, axis=-1)
        inside = np.where(np.isnan(d2[:, 0]), np.nan, inside)
        d2.partition(rank - 1, axis=-1)  # the rank-th smallest (NaN last, as in a sort): 4x quicker than sorting
        k_mc = np.sqrt(d2[:, rank - 1])
    return _ellipsoid(values, vectors, scale, inside, k_mc, coverage)


def _concatenate_ellipsoids(parts: list[CoverageEllipsoid]) -> CoverageEllipsoid:
    return CoverageEllipsoid(
        coverage=parts[0].coverage,
        gaussian_scale=parts[0].gaussian_scale,
        semi_axes=np.concatenate([p.semi_axes for p in parts]),
        directions=np.concatenate([p.directions for p in parts]),
        fraction_inside=np.concatenate([p.fraction_inside for p in parts]),
        monte_carlo_scale=np.concatenate([p.monte_carlo_scale for p in parts]),
    )


def _concatenate_summaries(parts: list[SampleSummary]) -> SampleSummary:
    fields = ("mean", "std_uncertainty", "symmetric_low", "symmetric_high", "shortest_low", "shortest_high")
    arrays = {name: np.concatenate([getattr(p, name) for p in parts]) for name in fields}
    return SampleSummary(
        n_draws=parts[0].n_draws,
        coverage=parts[0].coverage,
        minimum=np.concatenate([p.minimum for p in parts]),
        maximum=np.concatenate([p.maximum for p in parts]),
        **arrays,
    )


# -------------------------------------------------------------------------------------------- propagation
def _turn_first_joint(coords: np.ndarray, cos_q1: np.ndarray, sin_q1: np.ndarray) -> None:
    """``X, Y`` of coordinates ``(P, 6, M)`` turned in place by ``Rz(q_1)`` (``cos_q1``, ``sin_q1`` ``(P, 1)``):
    ``X = x c - y s``, ``Y = x s + y c``, on contiguous rows of draws."""
    x, y = coords[:, 0], coords[:, 1]
    x_sin = x * sin_q1
    x *= cos_q1
    x -= y * sin_q1
    y *= cos_q1
    y += x_sin


def _chunk_statistics(coords: np.ndarray, centred: np.ndarray, coverage: float):
    """Summary, ellipsoid and covariance of the coordinates ``(P, 6, M)`` of a pose chunk (draws last).

    ``centred`` is a buffer of the same shape for the centred coordinates; ``coords`` is partitioned in
    place. The standard uncertainties are the square roots of the covariance diagonal (the ``ddof=1``
    standard deviation, up to summation order).
    """
    size, _, n_draws = coords.shape
    mean = coords.mean(axis=-1)
    if not np.all(np.isfinite(mean)):  # a NaN or infinite draw (or an overflowing sum of absurd ones)
        raise InputError("the TCP coordinates of some parameter draws are not finite numbers")
    centred = np.subtract(coords, mean[..., None], out=centred)
    covariance = np.empty((size, 6, 6))
    for i in range(6):  # the upper triangle, row by row (no BLAS threads; 30 % less than one 6x6 einsum)
        covariance[:, i, i:] = np.einsum("pm,pjm->pj", centred[:, i], centred[:, i:])
        covariance[:, i:, i] = covariance[:, i, i:]
    covariance /= n_draws - 1
    std = np.sqrt(np.diagonal(covariance, axis1=-2, axis2=-1))
    covariance = 0.5 * (covariance + np.swapaxes(covariance, -1, -2))
    ellipsoid = _ellipsoid_rows(centred[:, :3], covariance[:, :3, :3], coverage)
    stats = _summarize_rows(coords.reshape(size * 6, n_draws), coverage, mean=mean.reshape(-1), std=std.reshape(-1))
    stats = {name: value.reshape(size, 6) for name, value in stats.items()}
    return SampleSummary(n_draws=n_draws, coverage=coverage, **stats), ellipsoid, covariance


def _linearised(draws: np.ndarray, nominal: np.ndarray, q: np.ndarray, tool: np.ndarray, joint_model=None, extras=None):
    """Mean parameters and ``J U_p J^T`` with ``U_p`` the draws' sample covariance (the joint-model values
    included for an extended model: their columns are ``sum_i (d TCP / d q_i) C_i``, ``d/dq_i = d/dtheta_i``, at
    the mean deflection)."""
    n_draws, n = draws.shape[0], draws.shape[1]
    deviation = draws - nominal
    angles = deviation[..., _ANGLE_KINDS]
    deviation[..., _ANGLE_KINDS] = angles - (2.0 * np.pi) * np.rint(angles / (2.0 * np.pi))  # into [-pi, pi]
    flat = deviation.reshape(n_draws, n * 5)
    if extras is not None:
        flat = np.concatenate([flat, extras], axis=1)
    mean_deviation = flat.mean(axis=0)
    centred = flat - mean_deviation
    # einsum, not `centred.T @ centred`: a multi-threaded BLAS call on the transposed view is at the mercy of
    # threads contending on a loaded machine; einsum takes a steady time
    parameter_covariance = np.einsum("mi,mj->ij", centred, centred) / (n_draws - 1)
    mean = nominal + mean_deviation[: n * 5].reshape(n, 5)
    varies = np.diagonal(parameter_covariance) > 0.0
    free = varies[: n * 5].reshape(n, 5)
    if not np.any(varies):
        return mean, np.zeros((q.shape[0], 6, 6))
    turned = q if extras is None else q + joint_model.deflection(q, mean_deviation[n * 5 :])
    jacobian = tcp_jacobian(mean, turned, tool=tool, free=free) if np.any(free) else np.zeros((q.shape[0], 6, 0))
    if extras is not None:
        theta = np.zeros((n, 5), dtype=bool)
        theta[:, 1] = True
        by_joint = tcp_jacobian(mean, turned, tool=tool, free=theta)  # (P, 6, n): d TCP / d q_i
        columns = np.einsum("pki,pim->pkm", by_joint, joint_model.columns(q))
        jacobian = np.concatenate([jacobian, columns[..., varies[n * 5 :]]], axis=-1)
    index = np.flatnonzero(varies)
    covariance = jacobian @ parameter_covariance[np.ix_(index, index)] @ np.swapaxes(jacobian, -1, -2)
    return mean, 0.5 * (covariance + np.swapaxes(covariance, -1, -2))


def _propagation_inputs(robot: RobotModel, parameter_draws, readings, tool, batch_size, joint_model=None, extras=None):
    """The checked draws and readings (2-D), the model joint variables of the readings and the tool, for
    :func:`propagate_to_tcp` and :func:`position_covariance` (readings outside the limits warn at their caller),
    and the joint-model draws ``(n_draws, m)`` of an extended model (None for the geometric one)."""
    draws = _check_draws(robot, parameter_draws)
    readings = _check_readings(robot, readings, name="readings", source="", stacklevel=4)
    tool = check_tool(tool)
    if batch_size is not None and (int(batch_size) != batch_size or batch_size < 1):
        raise InputError(f"`batch_size` must be a positive integer; got {batch_size!r}")
    if draws.shape[0] < 2:
        raise InputError(f"`parameter_draws` must hold at least 2 draws; got {draws.shape[0]}")
    if (joint_model is None) != (extras is None):
        raise InputError("an extended model's draws need both `joint_model` and `extra_draws`")
    if extras is not None:
        extras = np.asarray(extras, dtype=float)
        if extras.shape != (draws.shape[0], joint_model.size) or not np.all(np.isfinite(extras)):
            raise InputError(
                f"`extra_draws` must be finite, shape ({draws.shape[0]}, {joint_model.size}) for "
                f"{', '.join(joint_model.names)}; got {extras.shape}"
            )
    return draws, readings, robot.model_joint_variables(readings), tool, extras


def _turned_cos_sin(turned: np.ndarray, cos_q: np.ndarray, sin_q: np.ndarray, turns: np.ndarray):
    """``cos`` and ``sin`` of the turned joint angles ``turned = q + turns`` ``(m, P, n)`` [rad], evaluated only for the
    joints that some draw turns: a joint no draw turns (a geometric joint of an extended model) has ``turned = q``
    exactly, whose ``cos_q``, ``sin_q`` ``(P, n)`` the caller has."""
    moving = np.flatnonzero(np.any(turns != 0.0, axis=(0, 1)))
    if moving.size == turned.shape[-1]:
        return np.cos(turned), np.sin(turned)
    cq, sq = np.broadcast_to(cos_q, turned.shape).copy(), np.broadcast_to(sin_q, turned.shape).copy()
    cq[..., moving], sq[..., moving] = np.cos(turned[..., moving]), np.sin(turned[..., moving])
    return cq, sq


def _all_links(draws: np.ndarray, max_bytes: int) -> np.ndarray | None:
    """The link factors ``B_i`` of every draw ``(n_draws, n_joints, 4, 4)`` when they fit (see ``_LINK_BYTES``), else
    None (the callers then compute those of each batch)."""
    return _pose_independent_links(draws) if draws[:, :, 0].size * 128 <= max(max_bytes, _LINK_BYTES) else None


def _turns(joint_model, extras, q: np.ndarray) -> np.ndarray | None:
    """The joints' deflection ``(n_draws, P, n)`` [rad] of every draw at the poses ``q (P, n)``; None when geometric."""
    return None if extras is None else joint_model.deflection(q, extras)


def position_covariance(
    robot: RobotModel,
    parameter_draws,
    readings,
    *,
    tool=None,
    batch_size: int | None = None,
    max_bytes: int = 64 * 2**20,
    joint_model=None,
    extra_draws=None,
) -> np.ndarray:
    """Monte Carlo covariance ``(n_poses, 3, 3)`` [mm^2] of the TCP position at poses.

    The position part of :attr:`TCPUncertainty.covariance` of :func:`propagate_to_tcp` (the same draws,
    forward kinematics and ``sum c c^T / (M - 1)``, equal up to summation order) without the
    orientation, the order statistics, the ellipsoids and the linearised propagation: for callers
    that need only the spread of a point, such as :func:`robotcal.api.validation_consistency`.
    Arguments and checks as :func:`propagate_to_tcp` (readings outside the limits warn).
    """
    with single_blas_thread():
        draws, readings, q, tool, extras = _propagation_inputs(
            robot, parameter_draws, readings, tool, batch_size, joint_model, extra_draws
        )
        n_draws, n_poses = draws.shape[0], q.shape[0]
        pose_chunk = max(1, min(n_poses, int(max_bytes) // ((24 if extras is None else 96) * n_draws)))
        batch_size = int(batch_size) if batch_size is not None else max(1, 3 * _BLOCK_FRAMES // pose_chunk)
        all_links = _all_links(draws, max_bytes)  # once, not per pose chunk
        threads = _THREADS > 1 and n_draws > batch_size
        with ThreadPoolExecutor(_THREADS) if threads else nullcontext() as pool:  # one pool for every chunk
            covariances = [
                _chunk_covariance(draws, all_links, q[start : start + pose_chunk], tool, joint_model, extras,
                                  batch_size=batch_size, pool=pool)
                for start in range(0, n_poses, pose_chunk)
            ]  # fmt: skip
        return np.concatenate(covariances)


def _chunk_covariance(draws, all_links, q, tool, joint_model, extras, *, batch_size: int, pool) -> np.ndarray:
    """:func:`position_covariance` at the poses ``q (P, n)`` of one chunk: the points of every draw, filled batch by
    batch (by the threads of ``pool``, if any), then ``sum c c^T / (M - 1)``."""
    n_draws = draws.shape[0]
    cos_q, sin_q = np.cos(q), np.sin(q)
    points = np.empty((q.shape[0], 3, n_draws))  # draws last, as in propagate_to_tcp
    turns = _turns(joint_model, extras, q)

    def fill(first: int) -> None:
        rows = slice(first, min(first + batch_size, n_draws))
        if turns is None:
            cq, sq = cos_q, sin_q
        else:  # every draw turns the joints by its own deflection
            cq, sq = _turned_cos_sin(q + turns[rows], cos_q, sin_q, turns[rows])
        links = _pose_independent_links(draws[rows]) if all_links is None else all_links[rows]
        local = _chain_points(links, cq, sq, tool)
        points[:, :, rows] = np.transpose(local, (2, 1, 0))  # before Rz(q_1), turned below

    batches = range(0, n_draws, batch_size)
    if pool is not None:
        list(pool.map(fill, batches))
    else:
        for first in batches:
            fill(first)
    if not np.all(np.isfinite(points)):
        raise InputError("the TCP coordinates of some parameter draws are not finite numbers")
    first = q[:, 0, None] if turns is None else q[:, 0, None] + turns[:, :, 0].T  # (P, 1) or (P, M)
    _turn_first_joint(points, np.cos(first), np.sin(first))
    centred = points - points.mean(axis=-1)[..., None]
    covariance = np.empty((q.shape[0], 3, 3))
    for i in range(3):  # the upper triangle row by row, as in _chunk_statistics
        covariance[:, i, i:] = np.einsum("pm,pjm->pj", centred[:, i], centred[:, i:])
        covariance[:, i:, i] = covariance[:, i, i:]
    return covariance / (n_draws - 1)


def propagate_to_tcp(
    robot: RobotModel,
    parameter_draws,
    readings,
    *,
    tool=None,
    coverage: float = 0.95,
    batch_size: int | None = None,
    max_bytes: int = 64 * 2**20,
    keep_draws: bool = False,
    joint_model=None,
    extra_draws=None,
) -> TCPUncertainty:
    """TCP position and orientation uncertainty at poses from Monte Carlo parameter draws.

    Parameters
    ----------
    robot : RobotModel
        Gives the nominal parameters (the "Nominal" row of Table 5.8) and the reading map.
    parameter_draws : array_like, shape (n_draws, n_joints, 5)
        Monte Carlo draws of ``d, theta, a, alpha, beta`` [mm, rad] (``draws.npz`` of
        ``robotcal uncertainty``); parameters that do not vary simply stay at their value.
    readings : array_like, shape (n_poses, n_joints) or (n_joints,)
        Controller joint readings [rad]; ``q = reading_sign * reading + reading_offset``. Readings
        outside the robot's limits give a :class:`~robotcal.errors.JointLimitWarning`.
    tool : array_like, shape (3,), optional
        TCP in flange coordinates [mm]; default the flange origin, as in Table 5.8.
    coverage : float
        Coverage probability of the intervals and the ellipsoid.
    batch_size : int, optional
        Draws per kinematics call; the temporaries are ``batch_size x poses-in-chunk`` 3x4 blocks.
        Default: about 20,000 draw-poses per call.
    max_bytes : int
        Bound on the coordinates held at once: poses are processed in chunks of
        ``max(1, max_bytes // (48 n_draws))``.
    keep_draws : bool
        Keep the ``(n_draws, n_poses, 6)`` coordinates in the result (for histograms and scatter
        plots of a few poses; ignores ``max_bytes``).
    joint_model : JointModel, optional
        An extended model's joint model (:mod:`robotcal.kinematics.joint_model`), with ``extra_draws``
        ``(n_draws, m)`` its values in every draw: each draw then turns the joints by ``q + C(q) e`` of its own.

    Returns
    -------
    TCPUncertainty

    Notes
    -----
    Forward kinematics ``T = A_1(q_1) ... A_n(q_n)`` (eq. 3-84) with ``A_i(q) = Rz(q) B_i``,
    ``B_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)`` (eqs 3-72, 3-82); TCP position
    ``T [tool; 1]``; orientation KUKA ``A, B, C`` of ``T``'s rotation. The statistics are those of
    :func:`robotcal.uncertainty.statistics.summarize_draws` on the full set of draws (each pose
    chunk holds every draw). Draws of A, B, C are taken within +-180 deg of the nominal angle.

    References
    ----------
    Thesis ch. 5.3, Table 5.8, Figs 5.17-5.20; JCGM 101:2008 §7.6-7.7; JCGM 102:2011 §6.2, §6.5.3, §7.7.
    """
    with single_blas_thread():
        coverage = check_coverage(coverage)
        draws, readings, q, tool, extras = _propagation_inputs(
            robot, parameter_draws, readings, tool, batch_size, joint_model, extra_draws
        )
        work = _Propagation(
            robot, draws, q, tool, extras, joint_model, coverage=coverage, batch_size=batch_size,
            max_bytes=max_bytes, keep_draws=keep_draws,
        )  # fmt: skip
        # numpy releases the GIL in the kinematics and the statistics: the threads share each chunk's work
        if _THREADS > 1:
            with ThreadPoolExecutor(_THREADS) as pool:
                parts = [part for start in work.starts for part in work.chunk(start, pool)]
        else:
            parts = [part for start in work.starts for part in work.chunk(start, None)]
        summaries = [part[0] for part in parts]
        ellipsoids = [part[1] for part in parts]
        covariances = [part[2] for part in parts]

        parameter_mean, lpu_covariance = _linearised(draws, robot.nominal, q, tool, joint_model, extras)
        return TCPUncertainty(
            robot_name=robot.name,
            readings=readings,
            q=q,
            tool=tool,
            n_draws=work.n_draws,
            coverage=coverage,
            nominal=work.nominal,
            summary=_concatenate_summaries(summaries),
            covariance=np.concatenate(covariances),
            ellipsoid=_concatenate_ellipsoids(ellipsoids),
            lpu_covariance=lpu_covariance,
            parameter_mean=parameter_mean,
            draws=work.kept,
        )


class _Propagation:
    """The work of one :func:`propagate_to_tcp` call, shared by its pose chunks and threads (module notes).

    Pose chunks: all poses when the draws are kept; else chunks whose coordinates fit in ``max_bytes``, sizes
    evened out, one at a time: its batches of draws fill the coordinates in the threads, then its poses are split
    between the threads for the statistics (as many poses as possible per chunk: the per-draw products of the chain
    cost less per pose the more poses they hold, ~15 % from 63 to 139 poses).
    """

    def __init__(self, robot, draws, q, tool, extras, joint_model, *, coverage, batch_size, max_bytes, keep_draws):
        self.draws, self.q, self.tool, self.extras, self.joint_model = draws, q, tool, extras, joint_model
        self.coverage, self.keep_draws = coverage, keep_draws
        n_draws, n_poses = draws.shape[0], q.shape[0]
        self.n_draws, self.n_poses = n_draws, n_poses
        self.nominal = _coordinates(robot.nominal[None], q, tool)[0]
        self.cos_q, self.sin_q = np.cos(q), np.sin(q)
        per_pose = 48 if extras is None else 96  # bytes per draw and pose: coordinates (and the deflections)
        largest = n_poses if keep_draws else max(1, min(n_poses, int(max_bytes) // (per_pose * n_draws)))
        n_chunks = -(-n_poses // largest)
        self.pose_chunk = pose_chunk = -(-n_poses // n_chunks)
        self.starts = range(0, n_poses, pose_chunk)
        self.batch_size = int(max(1, _BLOCK_FRAMES // pose_chunk) if batch_size is None else batch_size)
        # the link factors B_i of every draw once, when they take no more room than the coordinates of a chunk
        # (else per batch, so that memory stays bounded by the batch and the pose chunk)
        self.all_links = _all_links(draws, max_bytes)
        self.kept = np.empty((n_draws, n_poses, 6)) if keep_draws else None
        # the coordinates (draws last: contiguous rows for the statistics) and the centred coordinates, reused
        # from chunk to chunk (fresh arrays of this size cost as much in page faults as the statistics themselves)
        self.coords_buffer = np.empty((pose_chunk, 6, n_draws))
        self.centred_buffer = np.empty((pose_chunk, 6, n_draws))

    def fill(self, first: int, poses: slice, coords: np.ndarray, turns: np.ndarray | None) -> None:
        """The coordinates of the draws ``first ..`` (one batch) at ``poses``, before the first joint's turn."""
        rows = slice(first, min(first + self.batch_size, self.n_draws))
        links = _pose_independent_links(self.draws[rows]) if self.all_links is None else self.all_links[rows]
        if turns is None:
            cq, sq, first_joint = self.cos_q[poses], self.sin_q[poses], self.q[poses, 0]
        else:  # every draw turns the joints by its own deflection
            turned = self.q[poses] + turns[rows]
            cq, sq = _turned_cos_sin(turned, self.cos_q[poses], self.sin_q[poses], turns[rows])
            first_joint = turned[..., 0]
        frames = _chain_columns(links, cq, sq)
        # (m, 3, P), before Rz(q_1); the flange origin (the default tool) is the translation column itself
        tool = self.tool
        local = frames[..., 3] + frames[..., :3] @ tool if tool.any() else frames[..., 3]
        block = np.moveaxis(frames, 3, 1)  # (m, 4, 3, P): [s, k, r, p], the layout of _abc_near
        target = coords[:, :, rows]  # a view: the draws of this batch
        target[:, :3] = np.transpose(local, (2, 1, 0))  # before Rz(q_1): turned per chunk, in _turn_first_joint
        target[:, 3:] = np.transpose(_abc_near(block, first_joint, self.nominal[poses, 3:]), (2, 0, 1))

    def chunk(self, start: int, pool: ThreadPoolExecutor | None) -> list:
        """The statistics of the poses ``start ..`` (one chunk): its batches of draws, then its poses' statistics,
        shared by the threads of ``pool``."""
        q, n_draws, keep_draws = self.q, self.n_draws, self.keep_draws
        poses = slice(start, min(start + self.pose_chunk, self.n_poses))
        size = poses.stop - poses.start
        coords, centred = self.coords_buffer[:size], self.centred_buffer[:size]
        turns = _turns(self.joint_model, self.extras, q[poses])
        batches = range(0, n_draws, self.batch_size)
        if pool is not None and len(batches) > 1:  # the batches fill disjoint draws in the threads
            list(pool.map(lambda first: self.fill(first, poses, coords, turns), batches))
        else:
            for first in batches:
                self.fill(first, poses, coords, turns)
        if turns is None:
            c1, s1 = self.cos_q[poses, 0, None], self.sin_q[poses, 0, None]
        else:  # (P, M): the first joint of every draw
            c1, s1 = np.cos(q[poses, 0, None] + turns[:, :, 0].T), np.sin(q[poses, 0, None] + turns[:, :, 0].T)
        if keep_draws:
            _turn_first_joint(coords, c1, s1)
            self.kept[:, poses] = np.moveaxis(coords, -1, 0)

        def statistics(part: slice):  # X, Y turned by the first joint (unless done), then the statistics
            if not keep_draws:
                _turn_first_joint(coords[part], c1[part], s1[part])
            return _chunk_statistics(coords[part], centred[part], self.coverage)

        parts = np.array_split(np.arange(size), min(size, _THREADS if pool is not None else 1))
        slices = [slice(part[0], part[-1] + 1) for part in parts]
        if pool is None or len(slices) == 1:  # without a pool, one part
            return [statistics(slices[0])]
        return list(pool.map(statistics, slices))
