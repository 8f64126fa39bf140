"""GUM-S1 summaries (JCGM 101 §7.6, §7.7, §7.9.2) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.uncertainty.statistics import (
    bias_corrected_interval,
    coverage_interval,
    numerical_tolerance,
    summarize_draws,
)


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


# ------------------------------------------------------------------ the interval for the measurand (issue 24)
# A biased estimator: estimate = truth + b + e, e with mean 0. A Monte Carlo simulated at the estimate draws
# estimate + b + e*, so its percentile interval sits near truth + 2 b. Moved by -2 (mean - estimate) it sits on
# the bias-corrected estimate, estimate - b, with the draws' own offsets from their mean.


def test_bias_corrected_interval_of_exact_quantiles():
    # closed form: Gaussian error, sd 2, bias 1.5, estimate 10: the draws' exact 95 % interval is 11.5 -+ 1.96 * 2
    # and their mean 11.5; moved by -2 * 1.5 it is 8.5 -+ 1.96 * 2, centred on the truth the estimate stands for
    z = 1.959963984540054
    low, high = bias_corrected_interval(11.5 - z * 2.0, 11.5 + z * 2.0, 11.5, 10.0)
    np.testing.assert_allclose([low, high], [8.5 - z * 2.0, 8.5 + z * 2.0], rtol=0, atol=1e-12)


def test_bias_corrected_interval_keeps_the_draws_shape():
    # draws' interval [5.1, 8.0] around a mean of 6.0 (a long upper tail), estimate 5.0: bias 1.0, so the interval
    # moves by -2.0 to [3.1, 6.0], still 0.9 below and 2.0 above its centre 4.0 = estimate - bias; a negative
    # bias (-1: draws [-0.9, 2.0] around 0, estimate 1) moves it up by 2 to [1.1, 4.0]
    low, high = bias_corrected_interval(
        np.array([5.1, -0.9]), np.array([8.0, 2.0]), np.array([6.0, 0.0]), np.array([5.0, 1.0])
    )
    np.testing.assert_allclose(low, [3.1, 1.1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(high, [6.0, 4.0], rtol=0, atol=1e-12)
    # without bias it is the draws' interval itself
    low, high = bias_corrected_interval(np.array([1.0, -3.0]), np.array([5.0, 1.0]), np.array([3.5, -1.2]), [3.5, -1.2])
    np.testing.assert_array_equal(low, [1.0, -3.0])
    np.testing.assert_array_equal(high, [5.0, 1.0])


def test_symmetric_draws_give_the_basic_bootstrap_interval():
    # for draws symmetric about their mean the move equals the reflection through the estimate,
    # [2 estimate - high, 2 estimate - low] (Davison & Hinkley 1997, eq. 5.6)
    draws = np.array([-2.0, -1.0, 0.0, 1.0, 2.0]) + 7.3
    estimate = 6.9
    low, high = bias_corrected_interval(draws.min(), draws.max(), draws.mean(), estimate)
    np.testing.assert_allclose([low, high], [2 * estimate - draws.max(), 2 * estimate - draws.min()], atol=1e-12)


def _coverage_of_a_biased_estimator(bias, n_captures, n_draws, seed):
    """Empirical coverage of the draws' interval and of the bias-corrected one for ``estimate = truth + bias + e``,
    e standard normal, one Monte Carlo of ``n_draws`` per capture simulated at its estimate."""
    rng = np.random.default_rng(seed)
    truth = 3.0
    estimate = truth + bias + rng.standard_normal(n_captures)
    draws = estimate + bias + rng.standard_normal((n_draws, n_captures))
    low, high = coverage_interval(draws, 0.95, "symmetric")  # column-wise: one interval per capture
    corrected_low, corrected_high = bias_corrected_interval(low, high, draws.mean(axis=0), estimate)
    raw = np.mean((low <= truth) & (truth <= high))
    corrected = np.mean((corrected_low <= truth) & (truth <= corrected_high))
    return raw, corrected


def _exact_coverage_of_the_draws_interval(bias: float, n_draws: int) -> float:
    """P(truth in [y*_(r), y*_(r+q)]) for the model of :func:`_coverage_of_a_biased_estimator`: the truth sits at
    w = -(2 bias + e) from the draws' centre, w ~ N(-2 bias, 1), and lies between the order statistics r and r + q
    of M standard normal draws when r <= #{draws < w} <= r + q - 1, a binomial count with p = Phi(w)."""
    from scipy.integrate import quad
    from scipy.stats import binom, norm

    low, high = coverage_interval(np.arange(1.0, n_draws + 1.0), 0.95, "symmetric")  # the ranks r and r + q
    r, top = int(low), int(high)

    def integrand(w):
        return norm.pdf(w, -2.0 * bias) * (
            binom.cdf(top - 1, n_draws, norm.cdf(w)) - binom.cdf(r - 1, n_draws, norm.cdf(w))
        )

    return quad(integrand, -12.0, 12.0, limit=200)[0]


@pytest.mark.parametrize("bias", [0.0, 0.5, 1.0])
def test_bias_corrected_interval_covers_a_biased_estimator_at_the_nominal_rate(bias):
    # Bias 0, 0.5 and 1 u, M = 200 draws, 20,000 captures. The corrected interval holds the truth when -e lies
    # between the order statistics r, r + q of the M draws' errors (the estimated bias cancels: the centre
    # 2 y - mean and the offsets from the mean move together), probability q / (M + 1) = 190/201 = 0.9453 for a
    # symmetric e, whatever the bias. Tolerance 0.0065 = 4 binomial standard errors (0.0016).
    raw, corrected = _coverage_of_a_biased_estimator(bias, 20_000, 200, seed=7)
    assert corrected == pytest.approx(190 / 201, abs=0.0065)
    # the draws' own interval is centred 2 b off: 0.945, 0.834 and 0.499 exactly (integral above; Phi(1.96 - 2b)
    # - Phi(-1.96 - 2b) = 0.950, 0.830, 0.484 at M -> inf); tolerance 4 binomial standard errors
    exact = _exact_coverage_of_the_draws_interval(bias, 200)
    assert raw == pytest.approx(exact, abs=4.0 * np.sqrt(exact * (1.0 - exact) / 20_000))
