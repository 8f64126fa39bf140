"""Coverage of the deployed extended model's Monte Carlo (issue 22): over repeated captures (circles and calibration
poses) of one sagging KR 5, the stated 95 % intervals of the parameters and of the compliances contain the truth as
often as they say."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import robotcal
from robotcal.uncertainty.coverage import extended_coverage_study


def _study(captures: int, draws: int, seed: int, *, joint_errors=False, measured: bool = False):
    """``joint_errors``: True, the demo's joint errors (or a JointErrorModel), on every capture (its circles, and its
    poses without lash) and every Monte Carlo (issue 31); ``measured``: each Monte Carlo simulates the joint errors
    its capture measures instead, as ``robotcal run`` (issue 29)."""
    scenario = robotcal.load_scenario("kr5-demo")
    truth = robotcal.perturb(scenario, rng=11)  # the demo's truth: J2, J3 compliance 1e-5, 4e-5 rad/(N m)
    poses = robotcal.simulate_poses(scenario, kind="calibration", rng=3, true_parameters=truth)
    return extended_coverage_study(
        scenario.robot, scenario.plan, scenario.instrument, truth, poses=poses.readings,
        poses_target=scenario.target(scenario.poses_target), captures=captures, draws=draws,
        tracker_from_base=scenario.tracker_from_base, options=scenario.identification,
        joint_limits=scenario.joint_limits, joint_errors=scenario.joint_errors if joint_errors is True else joint_errors or None, rng=seed,
        measured_joint_errors=measured,
    )  # fmt: skip


def test_extended_coverage_bookkeeping():
    """Reduced version (10 captures x 200 draws) of the slow test below: the record's shapes, the compliances among
    the checked quantities, and a coverage that is no accident (a broken interval, or joint-model draws that
    stay at 0, covers nothing: every fraction would be near 0)."""
    study = _study(10, 200, seed=5)
    assert study.names[-2:] == ("J2.k", "J3.k") and "J6.a" in study.names  # the poses' flange target shows J6
    assert study.contained.shape == study.std_uncertainty.shape == (10, len(study.names))
    assert np.all(study.std_uncertainty > 0)
    assert study.empirical().mean() >= 0.8 and study.empirical().min() >= 0.5
    # the compliances' errors are of the size of their stated u (the truth is 1e-5 and 4e-5 rad/(N m))
    z = study.error[:, -2:] / study.std_uncertainty[:, -2:]
    assert np.all(np.abs(z) < 5)


@pytest.mark.slow
def test_extended_refined_monte_carlo_covers_every_parameter():
    """The issue's proof: K = 200 captures, 1,000 draws each; every parameter and both compliances in the exact
    99 % binomial band of a 95 % coverage (0.915..0.980 at K = 200). docs/validation.md records the run."""
    study = _study(200, 1000, seed=22)
    outside = [(n, round(float(c), 3)) for n, c, ok in zip(study.names, study.empirical(), study.in_band(), strict=True)
               if not ok]  # fmt: skip
    assert outside == [], (study.band, outside)


def test_reduced_extended_study_with_joint_errors():
    """Issue 31, reduced: the Gauss-Newton draws of the extended model on a truth with the demo's joint errors."""
    study = _study(10, 200, seed=22, joint_errors=True)
    assert study.names[-2:] == ("J2.k", "J3.k")
    assert study.empirical().mean() >= 0.8 and study.empirical().min() >= 0.5


@pytest.mark.slow
def test_extended_refined_intervals_cover_with_joint_errors():
    """Issue 31: K = 200, 1,000 Gauss-Newton draws each, a truth with joint errors (docs/validation.md)."""
    study = _study(200, 1000, seed=22, joint_errors=True)
    outside = [(n, round(float(c), 3)) for n, c, ok in zip(study.names, study.empirical(), study.in_band(), strict=True)
               if not ok]  # fmt: skip
    assert outside == [], (study.band, outside)


def test_reduced_extended_study_with_the_joint_errors_the_captures_measure():
    """Issue 29, reduced (10 captures x 200 draws): every capture's Monte Carlo simulates what its joints analysis
    and its calibration poses measure, not the truth's joint errors."""
    study = _study(10, 200, seed=22, joint_errors=True, measured=True)
    assert study.names[-2:] == ("J2.k", "J3.k")
    assert study.empirical().mean() >= 0.8 and study.empirical().min() >= 0.5


@pytest.mark.slow
@pytest.mark.parametrize("j3_lobes", [True, False], ids=["demo-joint-errors", "without-J3-order-3"])
def test_extended_intervals_cover_with_the_joint_errors_the_captures_measure(j3_lobes):
    """Issue 29: K = 200, 1,000 draws each, the demo's truth, each capture's Monte Carlo simulating the joint errors
    that capture measures (docs/validation.md records both runs): with the demo's joint errors, J3's
    ``dx = 10 um sin(3 q + 30 deg)`` included (measured at the calibration poses, an order-3 group), and without that
    term. Every interval covers within the two-sided band (both 0.920-0.975)."""
    errors = robotcal.load_scenario("kr5-demo").joint_errors
    if not j3_lobes:
        amplitude = np.array(errors.amplitude)
        amplitude[2, 0] = 0.0
        errors = dataclasses.replace(errors, amplitude=amplitude)
    study = _study(200, 1000, seed=22, joint_errors=errors, measured=True)
    outside = {name: c for name, c, ok in zip(study.names, study.empirical(), study.in_band(), strict=True) if not ok}
    assert not outside and study.band[0] <= study.empirical().mean() <= study.band[1], (study.band, outside)
