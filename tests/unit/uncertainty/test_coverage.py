"""Coverage of the stated 95 % intervals over repeated simulated captures of one known truth (issue 11).

The default test is a reduced study (few captures, few draws) whose checks are loose enough to pass
by chance with probability > 99 % when the intervals are right, yet fail for the known defect they
guard against (the refinement's hard-coded d1/theta1 gauge gave J1.a a coverage of 11 %). The full
study (K = 300, every parameter in the 99 % binomial band) is marked slow.
"""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.api import coverage_study
from robotcal.errors import InputError
from robotcal.io import load_scenario
from robotcal.simulation.perturb import perturb_parameters
from robotcal.uncertainty.coverage import binomial_band


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


def test_reduced_study_covers(scenario, truth):
    study = coverage_study(scenario, truth, captures=12, draws=250, rng=5)
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


@pytest.mark.slow
def test_full_study_every_parameter_in_the_binomial_band(scenario, truth):
    # the study of docs/validation.md (scripts/make_coverage_section.py, same truth, K, draws and seed)
    study = coverage_study(scenario, truth, captures=300, draws=1000, rng=11)
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
