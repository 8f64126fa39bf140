"""Coverage of the stated 95 % intervals over repeated simulated captures of one known truth (issues 11, 24).

The default test is a reduced study (few captures, few draws) whose checks are loose enough to pass
by chance with probability > 99 % when the intervals are right, yet fail for the known defect they
guard against (the refinement's hard-coded d1/theta1 gauge gave J1.a a coverage of 11 %). The full
studies of docs/validation.md (K = 300, iGPS and laser tracker, every parameter in the 99 % binomial
band) and a biased case (the draws' own percentiles adding the bias twice) are marked slow.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robotcal.api import coverage_study
from robotcal.errors import InputError
from robotcal.io import load_scenario
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.perturb import perturb_parameters
from robotcal.uncertainty.coverage import binomial_band


def _short_j4_arc(scenario):
    """Table 5.5's plan with J4 turned through 30 deg instead of 50 (scripts/make_coverage_section.py's
    ``thesis-igps-short-j4`` case)."""
    sweep = np.array(scenario.plan.sweep, dtype=float)
    sweep[3] = np.deg2rad(30.0)
    return dataclasses.replace(scenario.plan, sweep=sweep)


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("thesis-laser-tracker")


@pytest.fixture(scope="module")
def truth(scenario):
    return perturb_parameters(scenario.robot, length_sd_mm=0.2, angle_sd_deg=0.05, include_base=True, rng=3)


def test_binomial_band_matches_the_issue_figures():
    # issue 11 quotes 0.918..0.982 at K = 300: the normal approximation 0.95 +- 2.576 sqrt(0.95 0.05 / 300).
    # The band used is the exact binomial one, 275/300 .. 294/300 (scipy.stats.binom.interval), within
    # one count of it.
    low, high = binomial_band(300)
    assert (low, high) == (275 / 300, 294 / 300)
    half = 2.576 * np.sqrt(0.95 * 0.05 / 300)
    np.testing.assert_allclose([low, high], [0.95 - half, 0.95 + half], atol=1 / 300)


def test_study_validates_its_arguments(scenario, truth):
    with pytest.raises(InputError, match="captures"):
        coverage_study(scenario, truth, captures=3, draws=500)
    with pytest.raises(InputError, match="draws"):
        coverage_study(scenario, truth, captures=20, draws=10)
    with pytest.raises(InputError, match="methods"):
        coverage_study(scenario, truth, captures=20, draws=500, methods=("bootstrap",))


@pytest.fixture(scope="module")
def reduced(scenario, truth):
    return coverage_study(scenario, truth, captures=12, draws=250, rng=5)


def test_reduced_study_covers(reduced):
    study = reduced
    # d1 and theta1 are identifiable with per-joint reflectors: they are checked too (20 parameters)
    assert "J1.d" in study.names and "J1.theta" in study.names
    assert len(study.names) == 20
    for method in study.contained:
        per_parameter = study.empirical(method)
        # 12 x 20 (parameter, capture) pairs, correlated within a capture: the mean over parameters
        # has a standard error of at most sqrt(0.95 * 0.05 / 12) = 0.063 (fully correlated) and about
        # 0.014 if independent; 0.80 is 2.4 of the worst-case ones below 0.95.
        assert per_parameter.mean() >= 0.80, (method, per_parameter.mean())
        # a parameter covering in fewer than 8 of 12 captures has probability 2e-4 at p = 0.95 (1 % over
        # the 60 checks); the gauge defect this guards against gave J1.a 11 %
        assert per_parameter.min() >= 8 / 12, (method, dict(zip(study.names, per_parameter, strict=True)))
    for method, inside in study.tcp_contained.items():
        assert inside.mean() >= 8 / 12, method
    # the refinement's stated u is that of the deployed model: far below CPA's for the base parameters
    j1a = study.names.index("J1.a")
    assert np.median(study.std_uncertainty["refined-mc"][:, j1a]) < 0.2 * np.median(
        study.std_uncertainty["cpa-mc"][:, j1a]
    )


def test_recorded_monte_carlos_give_back_the_checked_intervals(reduced):
    # the study keeps, per capture, each Monte Carlo's estimate, bias and draws' interval: the stated interval is
    # the draws' one moved by -2 bias, and both are checked against the truth as recorded
    study = reduced
    index = [study.truth.robot.parameter_names.index(name) for name in study.names]
    truth = study.truth.values.reshape(-1)[index]
    for method in ("cpa-mc", "refined-mc"):
        low, high = study.draws_low[method], study.draws_high[method]
        shift = 2.0 * study.bias[method]
        np.testing.assert_array_equal(study.contained_draws[method], (low <= truth) & (truth <= high))
        np.testing.assert_array_equal(study.contained[method], (low - shift <= truth) & (truth <= high - shift))
        # the Monte Carlo's bias estimate is small against its u on this scenario (laser tracker: < 0.03 u at 10^3
        # draws, docs/validation.md); at 250 draws its own standard error is u / sqrt(250) = 0.063 u, and 480
        # values are checked: 5 standard errors
        assert np.all(np.abs(study.bias[method]) < 5.0 / np.sqrt(250) * study.std_uncertainty[method])
        assert study.centre[method].shape == (study.captures, len(study.names))
    assert set(study.tcp_contained_corrected) == set(study.tcp_contained) == {"cpa-mc", "refined-mc"}


@pytest.mark.slow
@pytest.mark.parametrize("case, seed", [("thesis-igps", 11), ("thesis-laser-tracker", 12)])
def test_full_study_every_parameter_in_the_binomial_band(case, seed):
    # the studies of docs/validation.md (scripts/make_coverage_section.py: same truth, K, draws and seeds)
    scenario = load_scenario(case)
    truth = perturb_parameters(scenario.robot, length_sd_mm=0.2, angle_sd_deg=0.05, include_base=True, rng=3)
    study = coverage_study(scenario, truth, captures=300, draws=1000, rng=seed)
    low, high = study.band
    for method in ("cpa-mc", "refined-mc"):
        value = study.empirical(method)
        outside = {name: v for name, v in zip(study.names, value, strict=True) if not low <= v <= high}
        assert not outside, (method, outside)
    for method, inside in study.tcp_contained.items():
        assert low <= inside.mean() <= high, (method, inside.mean())
    # the linearised interval assumes homoscedastic noise (docs/validation.md): its mean must cover, and
    # no parameter may fall more than 2 captures below the band
    linearised = study.empirical("refined-linearised")
    assert low <= linearised.mean() <= high
    assert linearised.min() >= low - 2 / study.captures


@pytest.mark.slow
def test_biased_case_draws_percentiles_under_cover_and_the_stated_interval_does_not():
    # Table 5.5's plan with J4 turned through 30 deg instead of 50, the nominal robot as the truth: CPA's bias is
    # -0.24 u (J3.d), -0.34 u (J3.a), -0.43 u (J4.theta) (docs/uncertainty.md, K = 1000, seed 32, the study
    # below). The draws' own percentile interval is centred 2 bias off and covers 0.905, 0.811, 0.852; the stated
    # interval 0.941, 0.918 and 0.999 (J4.theta's u at the estimate is 1.5x the spread of the estimates: it
    # over-covers whatever the centre). Margins below: >= 3 binomial standard errors (0.007 at K = 1000).
    scenario = load_scenario("thesis-igps")
    study = coverage_study(
        scenario,
        ParameterSet.nominal(scenario.robot),
        captures=1000,
        draws=1000,
        plan=_short_j4_arc(scenario),
        methods=("cpa-mc",),
        rng=32,
    )
    low, high = study.band
    stated = dict(zip(study.names, study.empirical("cpa-mc"), strict=True))
    draws = dict(zip(study.names, study.empirical("cpa-mc", draws=True), strict=True))
    bias_u = study.error["cpa"].mean(axis=0) / study.std_uncertainty["cpa-mc"].mean(axis=0)
    bias = dict(zip(study.names, bias_u, strict=True))
    for name in ("J3.d", "J3.a", "J4.theta"):
        assert bias[name] < -0.15, (name, bias[name])  # a clear bias against u
        assert draws[name] < low - 0.02, (name, draws[name])  # the double bias: far below the band
        assert stated[name] > draws[name] + 0.03, (name, stated[name], draws[name])
    assert low <= stated["J3.d"] <= high
    assert stated["J3.a"] >= 0.90  # from 0.811: most, not all, of the loss recovered (docs/uncertainty.md)
    assert stated["J4.theta"] >= low  # over-covers: u too large at the estimate, not a centring error
    assert low <= np.mean(list(stated.values())) <= high
