"""Cpk (thesis eq. 5-5) on known draws, vary parsing, and a small sensitivity study."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.planning.scenario import scenario_document, set_key
from robotcal.planning.sensitivity import capability_limits, parse_vary, process_capability, run_sensitivity


def test_cpk_eq_5_5_on_known_draws():
    draws = np.array([0.01, 0.03, 0.02, 0.04, 0.00])  # mean 0.02, sample sd sqrt(0.001/4) = 0.0158114
    mean, sd = draws.mean(), draws.std(ddof=1)
    # eq. 5-5 by hand with limits -+0.1: min(0.1 - 0.02, 0.02 + 0.1) / (3 * 0.0158114) = 0.08 / 0.0474342
    assert process_capability(mean, sd, -0.1, 0.1) == pytest.approx(0.08 / (3 * np.sqrt(0.001 / 4)), rel=1e-12)
    assert process_capability(0.15, 0.01, -0.1, 0.1) == pytest.approx(-5.0 / 3.0)  # mean beyond the limit
    assert process_capability(0.0, 0.0, -0.1, 0.1) == np.inf


def test_capability_limits_length_and_angle():
    nominal = np.zeros((2, 5))
    low, high = capability_limits(nominal, length_mm=0.1, angle_deg=0.01)
    np.testing.assert_allclose(high[0], [0.1, np.deg2rad(0.01), 0.1, np.deg2rad(0.01), np.deg2rad(0.01)])
    np.testing.assert_allclose(low, -high)
    with pytest.raises(InputError, match="positive"):
        capability_limits(nominal, length_mm=0.0)


def test_parse_vary_and_set_key():
    assert parse_vary(["capture.sweep_deg.4=15,40", "capture.points=10"]) == [
        ("capture.sweep_deg.4", [15, 40]),
        ("capture.points", [10]),
    ]
    for bad in ("capture.points", "=1", "capture.points="):
        with pytest.raises(InputError, match="KEY=V1"):
            parse_vary([bad])
    document, *_ = scenario_document("thesis-laser-tracker")
    assert set_key(document, "capture.sweep_deg.4", 90)["capture"]["sweep_deg"] == [45, 80, 100, 90, 200, 300]
    assert set_key(document, "capture.points", 10)["capture"]["points"] == [10] * 6
    assert document["capture"]["points"] == [15, 20, 30, 15, 25, 30]  # the original is untouched
    with pytest.raises(InputError, match="element 7"):
        set_key(document, "capture.sweep_deg.7", 1)


def test_sensitivity_study_points_raise_cpk():
    """More points per circle lower u and so raise Cpk (thesis Fig. 5.16); Cpk matches eq. 5-5."""
    document, base, name, source = scenario_document("thesis-laser-tracker")
    study = run_sensitivity(document, base, name, source, [("capture.points", [10, 100])], seed=3, iterations=300)
    few, many = study.cases
    assert few.values == {"capture.points": 10} and many.n_draws == 300
    ident = few.identified
    # u scales like 1/sqrt(points) for a circle fit: 10x the points, ~3x lower u; a loose 1.8x bound
    # keeps the test far from Monte Carlo noise at 300 draws (relative standard error of u ~ 4 %)
    assert np.median(few.std_uncertainty[ident] / many.std_uncertainty[ident]) > 1.8
    low, high = capability_limits(study.nominal)
    np.testing.assert_allclose(many.cpk, process_capability(many.mean, many.std_uncertainty, low, high))
