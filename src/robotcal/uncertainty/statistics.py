"""GUM Supplement 1 summaries of Monte Carlo draws: estimate, standard uncertainty, coverage intervals.

Everything here works column-wise on draws stacked along axis 0, ``samples (n_draws, ...)``, and
keeps the trailing shape, so the same code summarises 30 parameters or 75 poses x 6 TCP coordinates.

References
----------
JCGM 101:2008 (GUM Supplement 1), §7.6 (estimate and standard uncertainty), §7.7 (coverage
intervals: probabilistically symmetric §7.7.1, shortest §7.7.2), §7.9 (adaptive procedure and the
numerical tolerance of §7.9.2); thesis ch. 5.2.3 (mean, standard uncertainty, 95 % limits, max, min);
Davison & Hinkley (1997), *Bootstrap Methods and their Application*, §5.2 (bootstrap intervals, against
which :func:`bias_corrected_interval` is compared).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist
from typing import Literal

import numpy as np

from robotcal.errors import InputError

__all__ = [
    "INTERVAL_KINDS",
    "SampleSummary",
    "summarize_draws",
    "coverage_interval",
    "bias_corrected_interval",
    "widened_interval",
    "numerical_tolerance",
    "check_coverage",
]

INTERVAL_KINDS = ("symmetric", "shortest")
IntervalKind = Literal["symmetric", "shortest"]


def check_coverage(coverage: float) -> float:
    """Return ``coverage`` as a float, or raise if it is not a probability strictly inside (0, 1)."""
    try:
        value = float(coverage)
    except (TypeError, ValueError):
        raise InputError(f"`coverage` must be a probability in (0, 1); got {coverage!r}") from None
    if not 0.0 < value < 1.0 or not math.isfinite(value):
        raise InputError(f"`coverage` must be a probability in (0, 1); got {coverage!r}")
    return value


def _interval_length(n_draws: int, coverage: float) -> int:
    """q of JCGM 101 §7.7.1: pM if it is an integer, else the integer part of pM + 1/2."""
    product = coverage * n_draws
    if abs(product - round(product)) < 1e-9:
        return int(round(product))
    return int(math.floor(product + 0.5))


def coverage_interval(
    samples: np.ndarray, coverage: float = 0.95, kind: IntervalKind = "symmetric"
) -> tuple[np.ndarray, np.ndarray]:
    """Coverage interval of the distribution represented by ``samples``.

    Parameters
    ----------
    samples : array_like, shape (n_draws, ...)
        Monte Carlo draws of one or more output quantities (any unit; the interval has the same).
    coverage : float
        Coverage probability p in (0, 1).
    kind : {"symmetric", "shortest"}
        Probabilistically symmetric interval (JCGM 101 §7.7.1: the ``r``-th and ``(r+q)``-th sorted
        values with ``r = (M - q)/2``, rounded as the clause says) or the shortest interval
        (§7.7.2: the ``r`` in ``1 .. M - q`` that minimises ``y_(r+q) - y_(r)``).

    Returns
    -------
    low, high : ndarray, shape (...)
    """
    coverage = check_coverage(coverage)
    if kind not in INTERVAL_KINDS:
        raise InputError(f"`kind` must be one of {INTERVAL_KINDS}; got {kind!r}")
    return _coverage_intervals(samples, coverage, (kind,))[kind]


def bias_corrected_interval(low, high, mean, estimate) -> tuple[np.ndarray, np.ndarray]:
    """Interval for the measurand from draws simulated at an estimate: the draws' interval moved by ``-2 b``.

    A Monte Carlo simulated *at an estimate* ``y`` (the robot that produced the capture is taken to be
    the one the data were calibrated to) has draws scattered around ``y + b``, ``b = mean - y`` the
    estimator's bias near ``y``; the estimate itself lies near ``truth + b``. The draws' interval
    ``[low, high]`` is therefore centred near ``truth + 2 b``: it adds the bias twice. Moved by ``-2 b``
    it is centred on the bias-corrected estimate ``y - b``: ``[low - 2 b, high - 2 b]``, i.e. ``y - b``
    plus the draws' own offsets from their mean, ``[low - mean, high - mean]``. The shape (the skew) of
    the draws is kept as it is. Without bias it is the draws' interval.

    Parameters
    ----------
    low, high : array_like
        A coverage interval of the draws (:func:`coverage_interval`), any unit.
    mean : array_like
        Mean of the draws (same unit).
    estimate : array_like
        The value the draws were simulated at, broadcastable to ``low`` (same unit).

    Returns
    -------
    low, high : ndarray
        ``low - 2 (mean - estimate)``, ``high - 2 (mean - estimate)``.

    Notes
    -----
    Exact (coverage p whatever the bias) for ``estimate = truth + b + e`` with a fixed ``b`` and a
    symmetric error law ``e``, where it equals the "basic" bootstrap interval ``[2 y - high, 2 y - low]``
    (Davison & Hinkley 1997, §5.2). The two differ for a skewed law: the basic interval turns the skew
    round, which is exact when the error is a fixed skewed law added to the truth, and this interval
    keeps it, which is what a non-linear estimator of nearly symmetric noise needs (CPA: the skew comes
    from the geometry, not from the noise). docs/uncertainty.md compares both on the thesis scenarios.
    """
    low, high, mean, estimate = (np.asarray(v, dtype=float) for v in (low, high, mean, estimate))
    shift = 2.0 * (mean - estimate)
    return low - shift, high - shift


def _coverage_intervals(
    samples: np.ndarray, coverage: float, kinds: tuple[str, ...]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """:func:`coverage_interval` of every kind in ``kinds``, each column sorted once for all of them."""
    coverage = check_coverage(coverage)
    values = np.asarray(samples, dtype=float)
    n_draws = values.shape[0] if values.ndim else 0
    q = _interval_length(n_draws, coverage)
    if n_draws < 2 or q >= n_draws:
        raise InputError(
            f"a {coverage:g} coverage interval needs more draws than {n_draws}: at least "
            f"{math.ceil(1.0 / (1.0 - coverage))} (JCGM 101 §7.2 recommends 10^4 or more)"
        )
    trailing = values.shape[1:]
    flat = values.reshape(n_draws, -1)
    bounds = {kind: (np.empty(flat.shape[1]), np.empty(flat.shape[1])) for kind in kinds}
    half = (n_draws - q) / 2.0
    r = max(int(half) if half == int(half) else int(math.floor((n_draws - q + 1) / 2.0)), 1)
    # One column at a time keeps the sorted copy to n_draws values (memory stays ~8 MB at 10^6 draws).
    for column in range(flat.shape[1]):
        ordered = np.sort(flat[:, column])
        if "symmetric" in bounds:
            low, high = bounds["symmetric"]
            low[column], high[column] = ordered[r - 1], ordered[r - 1 + q]
        if "shortest" in bounds:
            low, high = bounds["shortest"]
            start = int(np.argmin(ordered[q:] - ordered[: n_draws - q]))
            low[column], high[column] = ordered[start], ordered[start + q]
    return {kind: (low.reshape(trailing), high.reshape(trailing)) for kind, (low, high) in bounds.items()}


@dataclass(frozen=True, slots=True, kw_only=True)
class SampleSummary:
    """Column-wise GUM-S1 summary of Monte Carlo draws; every array has the draws' trailing shape.

    Attributes
    ----------
    n_draws : int
    coverage : float
        Coverage probability p of both intervals.
    mean : ndarray
        Estimate y (average of the draws, JCGM 101 §7.6).
    std_uncertainty : ndarray
        Standard uncertainty u(y) (standard deviation with M - 1, §7.6).
    symmetric_low, symmetric_high : ndarray
        Probabilistically symmetric coverage interval (§7.7.1).
    shortest_low, shortest_high : ndarray
        Shortest coverage interval (§7.7.2).
    minimum, maximum : ndarray
        Smallest and largest draw (thesis Tables 5.6/5.7 "Min", "Max").
    """

    n_draws: int
    coverage: float
    mean: np.ndarray
    std_uncertainty: np.ndarray
    symmetric_low: np.ndarray
    symmetric_high: np.ndarray
    shortest_low: np.ndarray
    shortest_high: np.ndarray
    minimum: np.ndarray
    maximum: np.ndarray

    def interval(self, kind: IntervalKind = "symmetric") -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` of the chosen coverage interval."""
        if kind == "symmetric":
            return self.symmetric_low, self.symmetric_high
        if kind == "shortest":
            return self.shortest_low, self.shortest_high
        raise InputError(f"`interval` must be one of {INTERVAL_KINDS}; got {kind!r}")


def summarize_draws(samples: np.ndarray, coverage: float = 0.95) -> SampleSummary:
    """Mean, standard uncertainty, both coverage intervals, min and max of each output quantity.

    Parameters
    ----------
    samples : array_like, shape (n_draws, ...)
        Monte Carlo draws along axis 0; NaN is refused (a failed draw must be dropped or reported
        before it is summarised, never averaged in silently).
    coverage : float
        Coverage probability p in (0, 1).
    """
    values = np.asarray(samples, dtype=float)
    if values.ndim < 1 or values.shape[0] < 2:
        raise InputError(f"`samples` must hold at least 2 draws along axis 0; got shape {values.shape}")
    if not np.all(np.isfinite(values)):
        bad = np.unique(np.nonzero(~np.isfinite(values.reshape(values.shape[0], -1)))[0])
        raise InputError(f"`samples` holds non-finite values in {bad.size} draw(s), first at draw {bad[0]}")
    coverage = check_coverage(coverage)
    intervals = _coverage_intervals(values, coverage, ("symmetric", "shortest"))  # one sort per column
    symmetric, shortest = intervals["symmetric"], intervals["shortest"]
    return SampleSummary(
        n_draws=int(values.shape[0]),
        coverage=coverage,
        mean=values.mean(axis=0),
        std_uncertainty=values.std(axis=0, ddof=1),
        symmetric_low=symmetric[0],
        symmetric_high=symmetric[1],
        shortest_low=shortest[0],
        shortest_high=shortest[1],
        minimum=values.min(axis=0),
        maximum=values.max(axis=0),
    )


def numerical_tolerance(std_uncertainty: np.ndarray, ndig: int) -> np.ndarray:
    """Numerical tolerance delta of JCGM 101 §7.9.2 for ``ndig`` significant decimal digits.

    ``u`` written with ``ndig`` significant digits is ``c x 10^l`` with ``c`` an ndig-digit integer;
    then ``delta = 10^l / 2``. Example: u = 0.012 34 mm, ndig = 2 -> c = 12, l = -3, delta = 0.0005 mm.
    A zero uncertainty (a parameter held fixed) gets delta = inf: it is stable by definition.
    """
    if int(ndig) != ndig or ndig < 1:
        raise InputError(f"`ndig` must be a positive integer; got {ndig!r}")
    u = np.abs(np.asarray(std_uncertainty, dtype=float))
    positive = np.where(u > 0, u, 1.0)
    exponent = np.floor(np.log10(positive)) - (int(ndig) - 1)
    # u = 0.0996 with ndig = 2 is written 0.10 (c = 10, l = -2), not 99.6e-3: round, then re-read l
    exponent = np.where(np.round(positive / 10.0**exponent) >= 10 ** int(ndig), exponent + 1, exponent)
    return np.where(u > 0, 0.5 * 10.0**exponent, np.inf)


def widened_interval(low, high, centre, u, coverage: float) -> tuple[np.ndarray, np.ndarray]:
    """An interval about ``centre`` whose half-widths also cover an independent, normal standard uncertainty ``u``:
    each end moved away from ``centre`` to ``sqrt(d^2 + (k_p u)^2)``, ``d`` its distance from it and ``k_p`` the
    normal coverage factor of ``coverage`` (JCGM 100 §5.1.2 combined in quadrature, end by end so that the draws'
    skew is kept). ``u = 0`` leaves the interval as it is."""
    u = np.asarray(u, dtype=float)
    if not np.any(u > 0):
        return np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    k = NormalDist().inv_cdf(0.5 + coverage / 2.0)
    centre = np.asarray(centre, dtype=float)
    below = np.hypot(centre - np.asarray(low, dtype=float), k * u)
    above = np.hypot(np.asarray(high, dtype=float) - centre, k * u)
    return centre - below, centre + above
