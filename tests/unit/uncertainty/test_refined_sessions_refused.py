"""Issue 29: the refined Monte Carlo's kernel models one tracker station and positions only, so a capture with
sessions (or probe orientations) is refused with a pointer to the measured Monte Carlo, never run silently wrong."""

from __future__ import annotations

import pytest

import robotcal
from robotcal.errors import InputError
from robotcal.uncertainty.refined import prepare_refined_model


def test_a_capture_with_sessions_is_refused():
    scenario = robotcal.load_scenario("thesis-laser-tracker")
    capture = robotcal.simulate(scenario, rng=1).with_session("day1")
    start = robotcal.identify(capture, scenario, health="off").parameters
    with pytest.raises(InputError, match="sessions or probe orientations.*measured Monte Carlo"):
        prepare_refined_model(capture, start, scenario.plan.reflector, tracker_from_base=scenario.tracker_from_base)
