"""Monte Carlo outputs made faster (issue 13): covariance, coverage factor, one sort per column,
histograms drawn by several processes, uncompressed draws.npz; each against an independent truth."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest
from scipy.stats import norm

from robotcal.api import monte_carlo_problem
from robotcal.io import load_scenario
from robotcal.io.formats.draws_npz import read_draws, write_draws
from robotcal.uncertainty.montecarlo import MonteCarloSettings, draw_covariance, linearised_uncertainty, run_monte_carlo
from robotcal.uncertainty.statistics import coverage_interval, summarize_draws


@pytest.fixture(scope="module")
def laser():
    return monte_carlo_problem(load_scenario("thesis-laser-tracker"))


@pytest.fixture(scope="module")
def small_result(laser):
    return run_monte_carlo(laser, MonteCarloSettings(iterations=300, block_size=300, batch_size=300), seed=5)


def test_covariance_equals_numpy_cov(laser):
    rng = np.random.default_rng(3)
    identified = laser.identified
    draws = rng.normal(size=(5_000,) + identified.shape) * rng.uniform(1e-3, 1.0, identified.shape)
    covariance, correlation = draw_covariance(draws, identified)
    flat_mask = identified.reshape(-1)
    expected = np.cov(draws.reshape(draws.shape[0], -1)[:, flat_mask], rowvar=False)
    # einsum and BLAS sum in other orders: a few ulps of the largest entry (variances <= 1)
    np.testing.assert_allclose(covariance[np.ix_(flat_mask, flat_mask)], expected, rtol=0, atol=1e-14)
    assert np.all(covariance[~flat_mask] == 0.0) and np.all(covariance[:, ~flat_mask] == 0.0)
    np.testing.assert_allclose(np.diag(correlation), 1.0, rtol=0, atol=0)


@pytest.mark.parametrize("coverage", [0.6827, 0.95, 0.99])
def test_linearised_interval_uses_the_normal_quantile(laser, coverage):
    linear = linearised_uncertainty(laser, None, MonteCarloSettings(coverage=coverage))
    mask = laser.identified & (linear.std_uncertainty > 0)
    std = linear.std_uncertainty[mask]
    k = (linear.coverage_high - linear.estimate)[mask] / std
    # statistics.NormalDist replaced scipy.stats.norm (import time); both are exact to ~1 ulp. Recovering k
    # from the interval cancels the estimate: allow 4 ulps of |estimate| + |high| relative to u.
    rounding = 4.0 * np.finfo(float).eps * (np.abs(linear.estimate) + np.abs(linear.coverage_high))[mask] / std
    assert np.all(np.abs(k - norm.ppf(0.5 + coverage / 2.0)) <= rounding + 1e-14)


def test_summary_intervals_equal_separate_interval_calls():
    rng = np.random.default_rng(8)
    samples = rng.gamma(2.0, size=(2_001, 3, 2))  # skewed: the two interval kinds differ
    summary = summarize_draws(samples, 0.9)
    for kind in ("symmetric", "shortest"):
        low, high = coverage_interval(samples, 0.9, kind)
        np.testing.assert_array_equal(summary.interval(kind)[0], low)
        np.testing.assert_array_equal(summary.interval(kind)[1], high)
    np.testing.assert_array_equal(summary.minimum, samples.min(axis=0))
    assert not np.array_equal(summary.shortest_low, summary.symmetric_low)


def _png_bytes(paths):
    return {path.name: path.read_bytes() for path in paths}


def test_draws_file_is_uncompressed_and_old_compressed_files_still_read(small_result, tmp_path):
    path = write_draws(tmp_path / "draws.npz", small_result.robot, small_result.draws, small_result.identified, seed=5)
    with zipfile.ZipFile(path) as archive:
        assert {info.compress_type for info in archive.infolist()} == {zipfile.ZIP_STORED}
    # the same archive compressed, as earlier versions wrote it, reads back to the same draws
    compressed = tmp_path / "compressed.npz"
    with np.load(path, allow_pickle=False) as archive:
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **{key: archive[key] for key in archive.files})
    compressed.write_bytes(buffer.getvalue())
    with zipfile.ZipFile(compressed) as archive:
        assert {info.compress_type for info in archive.infolist()} == {zipfile.ZIP_DEFLATED}
    new, old = read_draws(path), read_draws(compressed)
    np.testing.assert_array_equal(new.values, old.values)
    np.testing.assert_allclose(new.values, small_result.draws, rtol=1e-15, atol=1e-12)  # deg <-> rad round trip


