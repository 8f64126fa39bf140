"""Harmonic model of joint errors: exact fits, delta-method uncertainties, JSON export, compensation."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from scipy import stats

from robotcal.diagnostics import HarmonicModel, analyze_joints, fit_harmonic_series, fit_harmonics
from robotcal.errors import InputError
from robotcal.instruments import Instrument
from robotcal.io import load_scenario
from robotcal.simulation import JointErrorModel, simulate_capture

SCENARIO = load_scenario("thesis-laser-tracker")
NOISE_FREE = Instrument(a_mm=0.0, b_mm_per_m=0.0)


def test_series_recovers_known_coefficients_and_converts_to_amplitude_and_phase():
    theta = np.deg2rad(np.linspace(10.0, 250.0, 31))
    values = 0.004 + 0.010 * np.sin(theta + 0.7) + 0.025 * np.sin(2 * theta - 1.2)
    fit = fit_harmonic_series(theta, values, order=2, quantity="axial")
    # exact data: QR least squares reproduces the coefficients to rounding (values ~1e-2 mm)
    np.testing.assert_allclose(fit.offset, 0.004, atol=1e-14)
    np.testing.assert_allclose(fit.amplitude, [0.010, 0.025], atol=1e-13)
    np.testing.assert_allclose(fit.phase, [0.7, -1.2], atol=1e-10)
    np.testing.assert_allclose(fit.evaluate(theta), values, atol=1e-14)
    assert fit.rms_after < 1e-14 and fit.explained == pytest.approx(1.0) and fit.p_value == 0.0
    assert fit.dof == 31 - 5


def test_uncertainties_and_f_test_match_monte_carlo_and_scipy():
    """Delta-method u(C_k), u(phi_k) against the spread of 2000 noisy refits (seeded)."""
    rng = np.random.default_rng(3)
    theta = np.deg2rad(np.linspace(0.0, 300.0, 40))
    truth = 0.02 * np.sin(2 * theta + 0.4) + 0.015 * np.sin(theta - 0.3)
    sigma = 0.003
    fits = [fit_harmonic_series(theta, truth + rng.normal(0, sigma, theta.size), order=2) for _ in range(2000)]
    amplitude = np.array([f.amplitude for f in fits])
    phase = np.array([f.phase for f in fits])
    reported_a = np.mean([f.amplitude_uncertainty for f in fits], axis=0)
    reported_p = np.mean([f.phase_uncertainty for f in fits], axis=0)
    # 2000 draws: relative standard error of a standard deviation ~1.6 %; the delta method is first
    # order (amplitude / u > 15 here), so 8 % covers both
    np.testing.assert_allclose(np.std(amplitude, axis=0), reported_a, rtol=0.08)
    np.testing.assert_allclose(np.std(phase, axis=0), reported_p, rtol=0.08)
    one = fits[0]
    f_expected = ((one.rms_before**2 - one.rms_after**2) * 40 / 5) / one.sigma**2  # (TSS - RSS) / p / s^2
    np.testing.assert_allclose(one.f_statistic, f_expected, rtol=1e-12)
    np.testing.assert_allclose(one.p_value, stats.f.sf(one.f_statistic, 5, 35), rtol=1e-10)
    pure_noise = fit_harmonic_series(theta, rng.normal(0, sigma, theta.size), order=2)
    assert pure_noise.p_value > 0.01 and pure_noise.explained < 0.5  # nothing to explain (seeded draw)


@pytest.mark.parametrize(
    ("theta", "values", "order", "match"),
    [
        (np.arange(5.0), np.zeros(5), 2, "needs more than 5 values"),
        (np.arange(8.0), np.zeros(7), 2, "same shape"),
        (np.arange(8.0), np.zeros(8), 0, "order"),
        (np.arange(8.0), np.r_[np.zeros(7), np.nan], 1, "finite"),
        (np.r_[np.zeros(4), np.ones(4)], np.zeros(8), 2, "too few distinct angles"),
    ],
)
def test_invalid_series_input_is_refused(theta, values, order, match):
    with pytest.raises(InputError, match=match):
        fit_harmonic_series(theta, values, order=order)


def _full_turn_capture(errors, instrument, rng=0, n=24):
    """Thesis plan with J6 swept uniformly over a full turn (n points, both ways)."""
    plan = dataclasses.replace(
        SCENARIO.plan,
        sweep=np.r_[SCENARIO.plan.sweep[:5], 2 * np.pi * (n - 1) / n],
        points=np.r_[SCENARIO.plan.points[:5], n],
        bidirectional=True,
    )
    return simulate_capture(
        SCENARIO.robot,
        plan,
        instrument,
        SCENARIO.tracker_from_base,
        joint_errors=errors,
        joint_limits="ignore",
        rng=rng,
    )


def _errors():
    amplitude, phase = np.zeros((6, 5)), np.zeros((6, 5))
    amplitude[5, 2], phase[5, 2] = 0.03, np.deg2rad(40.0)  # axial order 2
    return JointErrorModel(
        amplitude=amplitude,
        period=np.full((6, 5), np.pi),
        phase=phase,
        noise_sd=np.zeros((6, 5)),
        backlash=np.deg2rad([0, 0, 0, 0, 0, 0.04]),
    )


def _residuals(model, diagnostics, predicted, measured):
    circle = diagnostics.circle(6)
    rows = circle.rows
    compensated = model.apply(6, circle.reading, predicted[rows], circle.state)
    before = np.sqrt(np.mean(np.sum((measured[rows] - predicted[rows]) ** 2, axis=1)))
    after = np.sqrt(np.mean(np.sum((measured[rows] - compensated) ** 2, axis=1)))
    return before, after


def test_compensation_removes_injected_eccentricity_and_backlash():
    predicted, _ = _full_turn_capture(None, NOISE_FREE)
    measured, _ = _full_turn_capture(_errors(), NOISE_FREE)
    diagnostics = analyze_joints(measured)
    model = fit_harmonics(diagnostics, order=2)
    before, after = _residuals(model, diagnostics, predicted.points, measured.points)
    assert before > 0.02
    # what is left is second order: the chord's mid-point lies rho (1 - cos(b/2)) ~ 4e-6 mm inside the circle
    assert after < 1e-5


def test_compensation_reduces_the_residual_down_to_the_noise():
    predicted, _ = _full_turn_capture(None, NOISE_FREE)
    measured, exact = _full_turn_capture(_errors(), SCENARIO.instrument, rng=2)
    diagnostics = analyze_joints(measured)
    model = fit_harmonics(diagnostics, order=2)
    before, after = _residuals(model, diagnostics, predicted.points, measured.points)
    rows = diagnostics.circle(6).rows
    noise = np.sqrt(np.mean(np.sum((measured.points[rows] - exact[rows]) ** 2, axis=1)))
    assert after < 0.6 * before
    # the fitted model adds its own estimation error, about sqrt(p / n) of the noise (p = 5..15, n = 48)
    assert after < 1.3 * noise


def test_json_round_trip_keeps_predictions():
    measured, _ = _full_turn_capture(_errors(), SCENARIO.instrument, rng=2)
    diagnostics = analyze_joints(measured)
    model = fit_harmonics(diagnostics, order=3)
    text = json.dumps(model.to_dict(), allow_nan=False)
    again = HarmonicModel.from_dict(json.loads(text))
    assert again.order == 3 and len(again.fits) == len(model.fits) == 6 * 5
    theta = np.linspace(0, 2 * np.pi, 50)
    for fit in model.fits:
        np.testing.assert_allclose(again.predict(fit.joint, fit.quantity, theta), fit.evaluate(theta), rtol=1e-15)
        np.testing.assert_allclose(again.fit(fit.joint, fit.quantity).amplitude_uncertainty, fit.amplitude_uncertainty)
    circle = diagnostics.circle(6)
    np.testing.assert_allclose(
        again.apply(6, circle.reading, circle.points, circle.state),
        model.apply(6, circle.reading, circle.points, circle.state),
        rtol=0,
        atol=1e-12,
    )
    document = model.to_dict()
    assert document["units"] == {"length": "mm", "angle": "deg"}
    term = document["joints"][5]["terms"]["axial"]["harmonics"][1]
    assert term["k"] == 2 and abs(term["amplitude_mm"] - 0.03) < 3 * term["amplitude_u_mm"]


def test_invalid_model_documents_and_calls_are_refused():
    measured, _ = _full_turn_capture(_errors(), NOISE_FREE)
    model = fit_harmonics(analyze_joints(measured))
    document = model.to_dict()
    with pytest.raises(InputError, match="not a robotcal harmonic model"):
        HarmonicModel.from_dict({"format": "x"}, source="h.json")
    broken = json.loads(json.dumps(document))
    broken["joints"][0]["terms"]["axial"]["coefficients_mm"] = [0.0]
    with pytest.raises(InputError, match="h.json: J1 axial: order 2 needs 5 finite"):
        HarmonicModel.from_dict(broken, source="h.json")
    broken = json.loads(json.dumps(document))
    del broken["joints"][0]["centre_mm"]
    with pytest.raises(InputError, match="missing or invalid key"):
        HarmonicModel.from_dict(broken, source="h.json")
    with pytest.raises(InputError, match="state"):
        model.apply(6, [0.0], [[1000.0, 0.0, 0.0]], state=[2])
    with pytest.raises(InputError, match="points"):
        model.apply(6, [0.0, 1.0], [[1000.0, 0.0, 0.0]])
    with pytest.raises(InputError, match="quantity"):
        model.predict(6, "tilt", [0.0])
    with pytest.raises(InputError, match="order"):
        fit_harmonics(analyze_joints(measured), order=0)


def test_json_carries_the_noise_floor_of_each_joint():
    measured, _ = _full_turn_capture(_errors(), SCENARIO.instrument, rng=2)
    diagnostics = analyze_joints(measured)
    document = fit_harmonics(diagnostics, order=2).to_dict()
    again = HarmonicModel.from_dict(json.loads(json.dumps(document, allow_nan=False)))
    for entry, circle, geometry in zip(document["joints"], diagnostics.circles, again.circles, strict=True):
        assert entry["noise_floor_um"] == pytest.approx(circle.backlash_noise_floor * 1000.0, abs=1e-4)
        assert entry["noise_sigma_um"] == pytest.approx(circle.noise_sigma * 1000.0, abs=1e-4)
        assert geometry.backlash_noise_floor == pytest.approx(circle.backlash_noise_floor, abs=1e-7)
    # documents written before the noise floor still read, with NaN
    for entry in document["joints"]:
        del entry["noise_floor_um"], entry["noise_sigma_um"]
    assert np.isnan(HarmonicModel.from_dict(document).circles[0].backlash_noise_floor)
