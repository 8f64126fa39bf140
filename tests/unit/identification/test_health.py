"""The fit-health scale (robotcal.identification.health): OK, MODEL ERROR, FAILED, NOT CHECKED, the same word
everywhere, on the cases a real cell gives (issue 24)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotcal.identification.health import (
    CONDITION_LIMIT,
    PHYSICAL_RESIDUAL_MM,
    RESIDUAL_RATIO_LIMIT,
    FitHealthError,
    FitHealthWarning,
    assess_fit,
    report_health,
)

NOISE_MM = 0.01  # per coordinate, a laser tracker at a few metres


def test_a_fit_at_the_noise_is_ok():
    health = assess_fit("fit", 1.1 * NOISE_MM, NOISE_MM, noise_source="U(95)", condition_number=50.0)
    assert health.verdict == "OK" and health.healthy and not health.failed
    assert health.ratio == pytest.approx(1.1)
    # sqrt(3 (s^2 - u^2)): the RMS per point beyond the noise, 3 coordinates
    assert health.unexplained_mm == pytest.approx(math.sqrt(3 * (0.011**2 - 0.01**2)), rel=1e-12)
    assert health.line().startswith("OK: residual 1.1 x the stated noise (U(95))")


def test_a_good_real_fit_is_a_model_error_with_the_unexplained_mm():
    # a real three-target fit: residual 14.5 x the stated noise, well conditioned, converged
    health = assess_fit("refinement (points criterion)", 14.5 * NOISE_MM, NOISE_MM, condition_number=2.3e4)
    assert health.verdict == "MODEL ERROR" and not health.healthy and not health.failed
    assert health.unexplained_mm == pytest.approx(math.sqrt(3 * (0.145**2 - 0.01**2)), rel=1e-12)  # 0.25 mm
    assert "compliance" in health.advice[0] and "harmonic" in health.advice[0]
    assert "0.251 mm RMS per point unexplained" in health.line()


@pytest.mark.parametrize(
    ("residual", "condition", "converged", "why"),
    [
        (4.2, 8.5e8, True, "condition number 8.5e+08 exceeds 1e+08"),  # the broken real fit: 420 x, ill-conditioned
        (4.2, 50.0, True, "beyond what a calibrated robot's model errors can leave"),  # 4.2 mm: not physical
        (0.02, 50.0, False, "did not converge"),
        (0.02, math.inf, True, "condition number inf"),
    ],
)
def test_an_untrustworthy_fit_failed(residual, condition, converged, why):
    health = assess_fit("fit", residual, NOISE_MM, condition_number=condition, converged=converged)
    assert health.verdict == "FAILED" and health.failed and not health.healthy
    assert any(why in problem for problem in health.problems), health.problems
    assert "do not use these parameters" in health.advice[0]


def test_without_a_stated_noise_the_residual_is_not_checked_but_the_rest_is():
    health = assess_fit("fit", 0.3, None, noise_source="no instrument and no U(95)", condition_number=50.0)
    assert health.verdict == "NOT CHECKED" and health.healthy and health.ratio is None
    assert "not compared" in health.line()
    assert assess_fit("fit", 0.3, None, condition_number=8.5e8).verdict == "FAILED"
    assert assess_fit("fit", 0.3, 0.0).verdict == "NOT CHECKED"  # a noise-free instrument: nothing to compare


def test_the_thresholds_are_where_the_docs_say():
    at, above = RESIDUAL_RATIO_LIMIT * NOISE_MM, RESIDUAL_RATIO_LIMIT * NOISE_MM * 1.01
    assert assess_fit("fit", at, NOISE_MM).verdict == "OK"
    assert assess_fit("fit", above, NOISE_MM).verdict == "MODEL ERROR"
    assert assess_fit("fit", PHYSICAL_RESIDUAL_MM, 0.1).verdict == "MODEL ERROR"
    assert assess_fit("fit", PHYSICAL_RESIDUAL_MM * 1.01, 0.1).verdict == "FAILED"
    assert assess_fit("fit", 0.01, 0.01, condition_number=CONDITION_LIMIT).verdict == "OK"
    assert assess_fit("fit", 0.01, 0.01, condition_number=CONDITION_LIMIT * 1.01).verdict == "FAILED"


def test_report_warns_or_raises_and_names_what_is_poorly_determined():
    ok = assess_fit("fit", 0.01, 0.01)
    with pytest.warns(FitHealthWarning, match=r"c.csv: fit: fit health MODEL ERROR: the residual"):
        report_health(assess_fit("fit", 0.1, 0.01), source="c.csv")
    with pytest.raises(FitHealthError, match="fit health FAILED"):
        report_health(assess_fit("fit", 5.0, 0.01), strict=True)
    assert report_health(ok, strict=True) is ok  # OK passes --strict
    small = assess_fit("fit", 0.01, 0.01, poorly_determined=["circle 4 leaves the J4 axis uncertain by 2.6 deg"])
    assert small.verdict == "OK"
    with pytest.warns(FitHealthWarning, match="poorly determined: circle 4"):
        report_health(small)


def test_the_json_record_carries_the_verdict():
    record = assess_fit("fit", 14.5 * NOISE_MM, NOISE_MM, condition_number=np.float64(2.3e4)).as_dict()
    assert record["verdict"] == "MODEL ERROR" and record["healthy"] is False
    assert record["unexplained_mm"] == pytest.approx(0.2508, rel=1e-3) and record["ratio_limit"] == 3.0
