"""workflow.validation_consistency: predicted vs observed error at the validation poses (issue 11)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robotcal.api import simulate_poses, validation_consistency, validation_target
from robotcal.errors import InputError
from robotcal.instruments import Instrument
from robotcal.io import load_scenario
from robotcal.kinematics.forward import target_positions
from robotcal.simulation.generator import JointErrorModel
from robotcal.simulation.perturb import perturb_parameters


@pytest.fixture(scope="module")
def case():
    scenario = load_scenario("kr5-demo")
    noise_free = dataclasses.replace(scenario, instrument=Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0))
    truth = perturb_parameters(scenario.robot, length_sd_mm=0.2, angle_sd_deg=0.05, rng=4)
    validation = simulate_poses(noise_free, rng=3, true_parameters=truth, joint_errors=JointErrorModel.zeros(6))
    return scenario, noise_free, truth, validation


def test_closed_form_for_a_base_rotation_spread(case):
    _, noise_free, truth, validation = case
    # draws that differ from the truth only by theta1 ~ N(0, s^2): to first order the validation target
    # moves by r_p * dtheta, r_p its distance from the first joint axis (base z), so the predicted RMS
    # position uncertainty is s * sqrt(mean r_p^2); the second-order term is (s r)^2 / 2 ~ 1e-8 mm here
    s = 1e-5
    rng = np.random.default_rng(0)
    draws = np.repeat(truth.values[None], 4000, axis=0)
    draws[:, 0, 1] += rng.normal(0.0, s, 4000)
    result = validation_consistency(validation, truth, draws, noise_free, model="test")
    q = noise_free.robot.model_joint_variables(validation.readings)
    points = target_positions(truth.values, q, np.zeros(validation.n_points, int), validation_target(noise_free))
    radius2 = points[:, 0] ** 2 + points[:, 1] ** 2
    sample_s = draws[:, 0, 1].std(ddof=1)  # the draws' own spread, so the check is exact, not statistical
    np.testing.assert_allclose(result["predicted_rms_mm"], sample_s * np.sqrt(radius2.mean()), rtol=1e-4)
    # noise-free capture of the truth, evaluated at the truth, base frame given: no observed error, no
    # instrument contribution
    assert result["observed_rms_mm"] == pytest.approx(0.0, abs=1e-9)
    assert result["instrument_rms_mm"] == 0.0
    assert result["expected_rms_mm"] == pytest.approx(result["predicted_rms_mm"])
    assert result["base_frame"] == "given" and result["poses"] == validation.n_points


def test_instrument_term_is_the_uniform_noise_variance(case):
    scenario, _, truth, validation = case
    draws = np.repeat(truth.values[None], 100, axis=0)  # no parameter spread
    result = validation_consistency(validation, truth, draws, scenario, model="test")
    # uniform +-U per coordinate: variance U^2/3 per coordinate, 3 coordinates -> U^2 per point
    bound = scenario.instrument.error_bound(np.asarray(validation.points))
    assert result["predicted_rms_mm"] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(result["instrument_rms_mm"], np.sqrt(np.mean(bound**2)), rtol=1e-12)


def test_measured_joint_errors_the_model_cannot_compensate_add_to_the_expected_error(case):
    """A run-out of J1, ``E_1 = T(A sin q1, A cos q1, 0)``, translates everything beyond J1 by a vector of length A:
    at every validation pose the target moves by exactly A, so ``uncompensated_rms_mm`` is A and the expected RMS
    is ``sqrt(predicted^2 + A^2)`` (noise-free instrument); a lash, which a free pose does not show, adds nothing."""
    _, noise_free, truth, validation = case
    draws = np.repeat(truth.values[None], 50, axis=0)
    draws[:, 1, 0] += np.linspace(-1e-3, 1e-3, 50)
    amplitude, phase = np.zeros((6, 5)), np.zeros((6, 5))
    amplitude[0, :2], phase[0, 1] = 0.02, np.pi / 2
    run_out = JointErrorModel(
        amplitude=amplitude, period=np.full((6, 5), 2 * np.pi), phase=phase, noise_sd=np.zeros((6, 5)),
        backlash=np.deg2rad([0.0, 0.01, 0.0, 0.0, 0.0, 0.0]),
    )  # fmt: skip
    plain = validation_consistency(validation, truth, draws, noise_free)
    counted = validation_consistency(validation, truth, draws, noise_free, joint_errors=run_out)
    assert "uncompensated_rms_mm" not in plain
    assert counted["uncompensated_rms_mm"] == pytest.approx(0.02, rel=1e-9)
    assert counted["expected_rms_mm"] == pytest.approx(np.hypot(plain["expected_rms_mm"], 0.02), rel=1e-9)
    assert counted["observed_rms_mm"] == plain["observed_rms_mm"]
    with pytest.raises(InputError, match="joint errors are of 5 joints"):
        validation_consistency(validation, truth, draws, noise_free, joint_errors=JointErrorModel.zeros(5))
