"""Instrument error model U(L) = A + B L and its noise policies (thesis 5.2.1.1 item 6, 5.2.3)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from robotcal.errors import InputError
from robotcal.instruments import NOISE_POLICIES, Instrument

#: Monte Carlo assertions allow this many standard errors (fixed seeds: deterministic, and a
#: correct sampler fails a 5-sigma bound with probability ~6e-7)
N_SIGMA = 5.0


def _points(n, rng):
    """Points at 1..10 m from the instrument (at the tracker origin), random directions [mm]."""
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return directions * rng.uniform(1000.0, 10000.0, (n, 1))


def test_error_bound_closed_form():
    instrument = Instrument(a_mm=0.015, b_mm_per_m=0.006)
    points = np.array([[0.0, 0.0, 0.0], [3000.0, 4000.0, 0.0], [0.0, 0.0, -2500.0]])
    # U = A + B L with L in metres: 0.015, 0.015 + 0.006 * 5, 0.015 + 0.006 * 2.5 (rounding only)
    np.testing.assert_allclose(instrument.error_bound(points), [0.015, 0.045, 0.030], rtol=1e-14)


def test_uniform_noise_is_bounded_with_std_u_over_sqrt3():
    rng = np.random.default_rng(0)
    points = _points(100_000, rng)
    instrument = Instrument(a_mm=0.01, b_mm_per_m=0.005, noise="uniform")
    noise = instrument.sample_noise(points, rng=1)
    bound = 0.01 + 0.005 * np.linalg.norm(points, axis=1) / 1000.0
    assert noise.shape == points.shape
    assert np.all(np.abs(noise) <= bound[:, None])  # uniform in [-U, U] per coordinate: a hard bound
    scaled = (noise / bound[:, None]).ravel()  # uniform on [-1, 1]: mean 0, variance 1/3, mu4 = 1/5
    n = scaled.size
    # standard errors of the sample mean and variance of U(-1, 1): sqrt(1/3 / n), sqrt((1/5 - 1/9) / n)
    assert abs(scaled.mean()) < N_SIGMA * np.sqrt(1.0 / 3.0 / n)
    assert abs(scaled.var() - 1.0 / 3.0) < N_SIGMA * np.sqrt((1.0 / 5.0 - 1.0 / 9.0) / n)
    # the reported standard uncertainty is U / sqrt(3) (closed form, rounding only)
    np.testing.assert_allclose(instrument.standard_uncertainty(points), bound / np.sqrt(3.0), rtol=1e-14)
    # the bound is reached: the largest |e|/U of 3e5 uniform draws is within 1e-4 of 1 (P(miss) ~ e^-30)
    assert np.max(np.abs(scaled)) > 1.0 - 1e-4


@pytest.mark.parametrize("coverage_factor", [2.0, 3.0])
def test_normal_noise_has_sigma_u_over_k(coverage_factor):
    rng = np.random.default_rng(2)
    points = _points(100_000, rng)
    instrument = Instrument(a_mm=0.02, b_mm_per_m=0.01, noise="normal", coverage_factor=coverage_factor)
    noise = instrument.sample_noise(points, rng=3)
    sigma = (0.02 + 0.01 * np.linalg.norm(points, axis=1) / 1000.0) / coverage_factor
    scaled = (noise / sigma[:, None]).ravel()  # standard normal
    n = scaled.size
    # standard errors of the mean (1/sqrt(n)) and of the variance (sqrt(2/n)) of N(0, 1)
    assert abs(scaled.mean()) < N_SIGMA / np.sqrt(n)
    assert abs(scaled.var() - 1.0) < N_SIGMA * np.sqrt(2.0 / n)
    np.testing.assert_allclose(instrument.standard_uncertainty(points), sigma, rtol=1e-14)  # U / k
    # fraction inside +-U = +-k sigma: 95.45 % (k = 2) or 99.73 % (k = 3), binomial standard error
    expected = 2.0 * norm.cdf(coverage_factor) - 1.0
    inside = np.mean(np.abs(scaled) <= coverage_factor)
    assert abs(inside - expected) < N_SIGMA * np.sqrt(expected * (1.0 - expected) / n)


def test_seeded_noise_is_reproducible():
    points = _points(50, np.random.default_rng(4))
    instrument = Instrument(a_mm=0.01, b_mm_per_m=0.005)
    first = instrument.sample_noise(points, rng=7)
    np.testing.assert_array_equal(instrument.sample_noise(points, rng=7), first)  # same seed, same draws
    np.testing.assert_array_equal(instrument.sample_noise(points, rng=np.random.default_rng(7)), first)
    assert not np.array_equal(instrument.sample_noise(points, rng=8), first)
    # seed 0 is a seed, not "no seed"
    np.testing.assert_array_equal(instrument.sample_noise(points, rng=0), instrument.sample_noise(points, rng=0))
    # a Generator passed in is advanced: two calls give different draws
    generator = np.random.default_rng(9)
    assert not np.array_equal(
        instrument.sample_noise(points, rng=generator), instrument.sample_noise(points, rng=generator)
    )


def test_batched_points_keep_their_shape():
    points = _points(24, np.random.default_rng(5)).reshape(4, 6, 3)
    instrument = Instrument(a_mm=0.01, b_mm_per_m=0.0, noise="normal")
    assert instrument.sample_noise(points, rng=0).shape == (4, 6, 3)
    assert instrument.error_bound(points).shape == (4, 6)


def test_noise_free_instrument():
    instrument = Instrument(a_mm=0.0, b_mm_per_m=0.0)
    assert instrument.is_noise_free
    assert not Instrument(a_mm=0.0, b_mm_per_m=0.001).is_noise_free
    # U = 0: the draws are exactly zero
    np.testing.assert_array_equal(instrument.sample_noise(np.ones((3, 3)), rng=0), 0.0)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"a_mm": -0.01, "b_mm_per_m": 0.0}, "`a_mm` must be a finite number >= 0; got -0.01"),
        ({"a_mm": 0.01, "b_mm_per_m": float("nan")}, "`b_mm_per_m` must be a finite number >= 0"),
        ({"a_mm": 0.01, "b_mm_per_m": float("inf")}, "`b_mm_per_m` must be a finite number >= 0"),
        ({"a_mm": "0.01", "b_mm_per_m": 0.0}, "`a_mm` must be a finite number >= 0"),
        ({"a_mm": 0.01, "b_mm_per_m": 0.0, "coverage_factor": 0.0}, "`coverage_factor` must be > 0"),
        ({"a_mm": 0.01, "b_mm_per_m": 0.0, "coverage_factor": -2.0}, "`coverage_factor` must be a finite number"),
        ({"a_mm": 0.01, "b_mm_per_m": 0.0, "noise": "triangular"}, "`noise` must be one of"),
    ],
)
def test_instrument_validation(arguments, message):
    with pytest.raises(InputError, match=message):
        Instrument(name="tracker", **arguments)


def test_noise_policies():
    assert NOISE_POLICIES == ("uniform", "normal")
