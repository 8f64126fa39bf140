"""The interval for the measurand of a Monte Carlo simulated at an estimate (issue 24, item 3).

``MonteCarloResult.interval`` is the draws' interval moved by twice the Monte Carlo's bias against the robot it
was simulated at (``robotcal.uncertainty.statistics.bias_corrected_interval``, checked against closed forms in
test_statistics.py); here: that the result applies it per parameter as documented, to the identified
parameters only, whatever turn the simulated angles are written in, and for the offsets of a measured capture.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from robotcal.api import monte_carlo
from robotcal.io import load_scenario
from robotcal.kinematics.model import ANGLE_COLUMNS
from robotcal.simulation.perturb import perturb_parameters


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("thesis-igps")


@pytest.fixture(scope="module")
def at_estimate(scenario):
    # a Monte Carlo simulated at a perturbed robot (an "estimate"): its CPA bias is visible in J3.a and J4.theta
    estimate = perturb_parameters(scenario.robot, length_sd_mm=0.2, angle_sd_deg=0.05, include_base=True, rng=4)
    return monte_carlo(scenario, parameters=estimate, draws=2000, rng=3), estimate


def test_interval_is_the_draws_interval_moved_by_twice_the_bias(at_estimate):
    result, estimate = at_estimate
    identified = result.identified
    # centre = mean + (estimate - mean) with the angles' difference wrapped: a few ulps of values up to ~400
    np.testing.assert_allclose(result.centre[identified], estimate.values[identified], rtol=0, atol=1e-12)
    bias = result.summary.mean - estimate.values
    np.testing.assert_allclose(result.bias[identified], bias[identified], rtol=0, atol=1e-12)
    assert np.all(result.bias[~identified] == 0.0)
    draws_low, draws_high = result.draws_interval()
    np.testing.assert_array_equal(draws_low, result.summary.symmetric_low)  # the settings' default kind
    low, high = result.interval()
    # mm and rad of values up to ~400: 1e-12 is a few ulps of the sums
    np.testing.assert_allclose(low[identified], (draws_low - 2.0 * bias)[identified], rtol=0, atol=1e-12)
    np.testing.assert_allclose(high[identified], (draws_high - 2.0 * bias)[identified], rtol=0, atol=1e-12)
    # parameters the capture does not determine keep their value in every draw: no interval to move
    np.testing.assert_array_equal(low[~identified], draws_low[~identified])
    np.testing.assert_array_equal(high[~identified], draws_high[~identified])
    # the move is visible: J3.a's CPA bias on the iGPS scenario is about -0.14 u (docs/validation.md)
    j3a = (2, 2)
    assert bias[j3a] < -0.05 * result.summary.std_uncertainty[j3a]
    assert low[j3a] > draws_low[j3a] and high[j3a] > draws_high[j3a]


def test_centre_is_taken_in_the_turn_of_the_draws(at_estimate):
    # the same robot written with every angle a whole turn away gives the same interval
    result, _ = at_estimate
    turned = result.true_values.copy()
    turned[:, list(ANGLE_COLUMNS)] += 2.0 * math.pi
    other = dataclasses.replace(result, true_values=turned)
    # a turn of 2 pi added and taken off again: rounding of ~4 pi, 1e-15 relative
    np.testing.assert_allclose(other.centre, result.centre, rtol=0, atol=1e-12)
    for mine, theirs in zip(other.interval(), result.interval(), strict=True):
        np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12)


def test_shortest_interval_is_moved_the_same_way(at_estimate):
    result, _ = at_estimate
    shortest = dataclasses.replace(result, settings=dataclasses.replace(result.settings, interval="shortest"))
    low, high = shortest.interval()
    shift = 2.0 * shortest.bias
    np.testing.assert_allclose(low, result.summary.shortest_low - shift, rtol=0, atol=1e-12)
    np.testing.assert_allclose(high, result.summary.shortest_high - shift, rtol=0, atol=1e-12)
