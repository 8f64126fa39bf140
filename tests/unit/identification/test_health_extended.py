"""Fit health on a robot that sags (issue 24's done-when, issue 22's model): the geometric fit of a cell whose
truth has gravity compliance reports MODEL ERROR with the unexplained millimetres; the compliance model, or a truth
without sag, reports OK."""

from __future__ import annotations

import warnings

import pytest

import robotcal
from robotcal.errors import FitHealthWarning, IdentifiabilityWarning


@pytest.fixture(scope="module")
def demo():
    scenario = robotcal.load_scenario("kr5-demo")
    return scenario, robotcal.perturb(scenario, rng=11)  # J2, J3 compliance: a sag of ~0.3 mm at reach


def _fit(scenario, truth, model):
    capture = robotcal.simulate(scenario, rng=1, true_parameters=truth, joint_errors=None)
    poses = robotcal.simulate_poses(scenario, kind="calibration", rng=3, true_parameters=truth)
    fitted = robotcal.calibration_capture(scenario, capture, poses)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)  # J6.alpha behind the flange target
        warnings.simplefilter("ignore", FitHealthWarning)
        return robotcal.refine(fitted, scenario, robotcal.identify(capture, scenario), model=model, folds=0)


def test_a_sagging_robot_fitted_geometrically_is_a_model_error(demo):
    scenario, truth = demo
    geometric = _fit(scenario, truth, "geometric").health
    assert geometric.verdict == "MODEL ERROR" and geometric.ratio > 3.0
    # the unexplained part is the sag the chain cannot hold: tens of micrometres RMS per point
    assert 0.03 < geometric.unexplained_mm < 0.3
    assert "--model compliance" in geometric.advice[0]
    assert _fit(scenario, truth, "compliance").health.verdict == "OK"
    assert _fit(scenario, truth.geometric(), "geometric").health.verdict == "OK"
