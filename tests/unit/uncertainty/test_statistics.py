"""GUM-S1 summaries (JCGM 101 §7.6, §7.7, §7.9.2) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.uncertainty.statistics import coverage_interval, numerical_tolerance, summarize_draws


def test_symmetric_interval_picks_the_order_statistics_of_jcgm_101_7_7_1():
    # M = 10^4, p = 0.95: q = pM = 9500, r = (M - q)/2 = 250 -> [y_(250), y_(9750)] (1-based)
    ordered = np.arange(1.0, 10_001.0)
    shuffled = np.random.default_rng(0).permutation(ordered)
    low, high = coverage_interval(shuffled, 0.95, "symmetric")
    assert (low, high) == (250.0, 9750.0)


def test_symmetric_interval_rounds_as_the_clause_says():
    # M = 1001, p = 0.95: pM = 950.95 -> q = int(pM + 1/2) = 951; (M - q)/2 = 25 -> [y_(25), y_(976)]
    low, high = coverage_interval(np.arange(1.0, 1002.0), 0.95, "symmetric")
    assert (low, high) == (25.0, 976.0)


def test_shortest_interval_of_an_exponential_starts_at_zero():
    # Exponential(1): the shortest 95 % interval is [0, -ln 0.05] = [0, 2.9957]; with 2e5 draws the
    # end is within ~0.02 (its Monte Carlo standard error is sqrt(p(1-p)/M)/f(x) = 0.0098).
    draws = np.random.default_rng(1).exponential(size=200_000)
    low, high = coverage_interval(draws, 0.95, "shortest")
    assert low == pytest.approx(0.0, abs=1e-3)
    assert high == pytest.approx(-np.log(0.05), abs=0.03)
    sym_low, sym_high = coverage_interval(draws, 0.95, "symmetric")
    assert high - low < sym_high - sym_low  # the shortest interval is shorter for a skewed law


def test_summary_of_a_normal_sample():
    # N(3, 2^2), 2e5 draws: mean SE 0.0045, std SE 0.0032, 2.5 % quantile SE ~0.012
    draws = np.random.default_rng(2).normal(3.0, 2.0, size=(200_000, 2))
    summary = summarize_draws(draws, 0.95)
    np.testing.assert_allclose(summary.mean, 3.0, atol=0.02)
    np.testing.assert_allclose(summary.std_uncertainty, 2.0, atol=0.015)
    np.testing.assert_allclose(summary.symmetric_low, 3.0 - 1.959964 * 2.0, atol=0.05)
    np.testing.assert_allclose(summary.shortest_high - summary.shortest_low, 2 * 1.959964 * 2.0, atol=0.08)
    np.testing.assert_array_equal(summary.minimum, draws.min(axis=0))
    assert summary.interval("shortest")[0].shape == (2,)


def test_summary_keeps_trailing_shape():
    draws = np.random.default_rng(3).normal(size=(500, 4, 6))
    summary = summarize_draws(draws)
    assert summary.mean.shape == summary.shortest_high.shape == (4, 6)
    np.testing.assert_allclose(summary.std_uncertainty, draws.std(axis=0, ddof=1), rtol=1e-12)


@pytest.mark.parametrize(
    "u, ndig, delta",
    [
        (0.01234, 2, 0.0005),
        (1.5, 2, 0.05),
        (0.98, 2, 0.005),
        (0.93, 1, 0.05),
        (0.98, 1, 0.5),
        (123.0, 3, 0.5),
        (0.0996, 2, 0.005),
    ],
)
def test_numerical_tolerance_of_jcgm_101_7_9_2(u, ndig, delta):
    assert numerical_tolerance(u, ndig) == pytest.approx(delta)


def test_numerical_tolerance_of_a_fixed_parameter_is_infinite():
    assert numerical_tolerance(np.array([0.0]), 2)[0] == np.inf


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: summarize_draws(np.array([[np.nan], [1.0], [2.0]])), "non-finite values in 1 draw"),
        (lambda: summarize_draws(np.ones((1, 3))), "at least 2 draws"),
        (lambda: summarize_draws(np.ones((100, 3)), coverage=1.0), r"probability in \(0, 1\)"),
        (lambda: summarize_draws(np.ones((100, 3)), coverage=0.0), r"probability in \(0, 1\)"),
        (lambda: coverage_interval(np.ones(10), 0.95), "needs more draws than 10"),
        (lambda: coverage_interval(np.ones(100), 0.95, "widest"), "`kind` must be one of"),
        (lambda: numerical_tolerance(1.0, 0), "`ndig` must be a positive integer"),
    ],
)
def test_bad_input(call, message):
    with pytest.raises(InputError, match=message):
        call()
