"""The deployed value and its interval agree (issue 29 item 1).

The pipeline's Monte Carlo simulates the joint errors the capture's own joints stage measured (never the scenario's
simulation settings), and the value deployed is the refinement's estimate corrected for the bias the Monte Carlo
measures: the centre of the stated interval, which therefore contains it."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import robotcal
from robotcal import api
from robotcal.instruments import Instrument
from robotcal.pipeline import stages
from robotcal.simulation.generator import JointErrorModel
from robotcal.uncertainty.joint_errors import measured_joint_errors

NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)


@pytest.fixture(scope="module")
def demo():
    scenario = robotcal.load_scenario("kr5-demo")
    return scenario, robotcal.perturb(scenario, rng=11).geometric()


def _run_out(n: int, joint: int, amplitude: float, phase: float) -> JointErrorModel:
    """A once-per-turn run-out of the axis of ``joint`` (0-based): dx = A sin(q + phi), dy = A cos(q + phi)."""
    model = JointErrorModel.zeros(n)
    amplitudes, phases = np.array(model.amplitude), np.array(model.phase)
    amplitudes[joint, :2] = amplitude
    phases[joint, :2] = phase, phase + np.pi / 2
    return dataclasses.replace(model, amplitude=amplitudes, phase=phases)


def test_the_joints_stage_measures_backlash_and_a_run_out_into_the_simulations_form(demo):
    scenario, truth = demo
    errors = _run_out(6, 5, 0.030, 0.7)  # J6 sweeps 300 deg: its circle shows the run-out
    errors = dataclasses.replace(errors, backlash=np.deg2rad([0.0, 0.01, 0.0, 0.0, 0.0, 0.0]))
    exact = dataclasses.replace(scenario, instrument=NOISE_FREE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        capture = robotcal.simulate(exact, rng=1, true_parameters=truth, joint_errors=errors)
    joints = api.diagnose_joints(capture, exact)
    model = measured_joint_errors(joints.diagnostics, truth, scenario.plan, scenario.tracker_from_base)
    assert np.rad2deg(model.backlash[1]) == pytest.approx(0.01, rel=0.05)
    assert np.all(model.noise_sd == 0.0)
    assert model.amplitude[5, 0] == pytest.approx(0.030, rel=0.1) and model.amplitude[5, 1] == model.amplitude[5, 0]
    assert np.angle(np.exp(1j * (model.phase[5, 0] - 0.7))) == pytest.approx(0.0, abs=0.1)
    # J1 sweeps 45 deg: the circle fit takes a run-out of that arc for the axis position, and nothing is made up
    assert np.all(model.amplitude[[0, 3], :] < 1e-3)


def _calibration(scenario, truth, errors, instrument_seed):
    """The circles and calibration poses of ``truth`` with ``errors`` (the poses without lash), their CPA and
    geometric refinement, as the pipeline's :func:`stages.calibration_fit` refits it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        capture = robotcal.simulate(scenario, rng=instrument_seed, true_parameters=truth, joint_errors=errors)
        poses = robotcal.simulate_poses(
            scenario, kind="calibration", true_parameters=truth, joint_errors=errors, rng=instrument_seed + 1
        )
        cpa = robotcal.identify(capture, scenario).parameters
        fitted = api.calibration_capture(scenario, capture, poses)
        refined = api.refine(fitted, scenario, cpa, model="geometric", health="off", folds=0)
    joints = api.diagnose_joints(capture, scenario)
    return joints, stages.calibration_fit(scenario, capture, poses, cpa, refined)


def test_the_calibration_poses_measure_a_run_out_that_no_circle_shows(demo):
    """J1 turns 45 deg: its circle shows 0.7 % of a run-out, which CPA and the refinement take for the axis. The 30
    calibration poses turn J1 through its range: fitted jointly with the refinement (the refinement's residuals
    on the run-out's unabsorbed response), a 20 um run-out comes back within 2 % and 0.05 rad, noise-free; the
    refitted responses are linear to far better than that (amplitude 10 um, solver tolerance ~1e-10 mm)."""
    scenario, truth = demo
    # 1 nm of noise: the forward and return points of a reading differ (a noise-free copy is refused as duplicated)
    exact = dataclasses.replace(scenario, instrument=Instrument(name="nm", a_mm=1e-6, b_mm_per_m=0.0))
    joints, calibration = _calibration(exact, truth, _run_out(6, 0, 0.020, 0.4), 1)
    alone = measured_joint_errors(joints.diagnostics, truth, scenario.plan, scenario.tracker_from_base)
    assert np.all(alone.amplitude[0, :2] < 1e-3)  # the circles alone cannot show it
    model = measured_joint_errors(
        joints.diagnostics, truth, scenario.plan, scenario.tracker_from_base, calibration=calibration
    )
    assert model.amplitude[0, 0] == pytest.approx(0.020, rel=0.02) and model.amplitude[0, 1] == model.amplitude[0, 0]
    assert np.angle(np.exp(1j * (model.phase[0, 0] - 0.4))) == pytest.approx(0.0, abs=0.05)
    assert np.all(model.amplitude[1:, :3] < 1e-3)  # nothing else is made up
    # the kept fit's directions are uncertainty sources: steps of the run-out of the order of the 1 nm noise
    steps = [abs(source.amplitude[0, 0] - model.amplitude[0, 0]) for source in model.sources]
    assert 0.0 < max(steps) < 1e-4


def test_the_calibration_poses_measure_a_three_lobed_joint_that_no_circle_shows(demo):
    """J3's ``dx = 10 um sin(3 q + 30 deg)`` (the demo's): its 100 deg circle shows 4 % of an order-3 term, the
    30 calibration poses show it plainly. Noise-free (1 nm), the order-3 group of J3 alone stands out (Bonferroni
    over the six joints) and comes back within 3 % and 0.05 rad; ``uncertainty-refined/joint_errors.json`` lists it
    under ``order_3`` beside the joint's other terms."""
    scenario, truth = demo
    exact = dataclasses.replace(scenario, instrument=Instrument(name="nm", a_mm=1e-6, b_mm_per_m=0.0))
    errors = JointErrorModel.zeros(6)
    amplitude, period, phase = np.array(errors.amplitude), np.array(errors.period), np.array(errors.phase)
    amplitude[2, 0], period[2, 0], phase[2, 0] = 0.010, np.deg2rad(120.0), np.deg2rad(30.0)
    errors = dataclasses.replace(errors, amplitude=amplitude, period=period, phase=phase)
    joints, calibration = _calibration(exact, truth, errors, 1)
    model = measured_joint_errors(
        joints.diagnostics, truth, scenario.plan, scenario.tracker_from_base, calibration=calibration
    )
    lobes = model.lobes
    assert lobes is not None and np.all(lobes.amplitude[[0, 1, 3, 4, 5]] == 0.0)
    assert lobes.amplitude[2, 0] == pytest.approx(0.010, rel=0.03) and lobes.amplitude[2, 1] < 3e-4
    assert np.angle(np.exp(1j * (lobes.phase[2, 0] - np.deg2rad(30.0)))) == pytest.approx(0.0, abs=0.05)
    assert np.all(model.amplitude[:, :3] < 1e-3)  # nothing else is made up
    # the simulator adds the lobes to the terms: the model moves the points as the truth does, within the fit's 3 %
    q = np.linspace(-np.pi, np.pi, 37)[:, None] * np.ones(6)
    np.testing.assert_allclose(model.values(q)[:, 2, 0], errors.values(q)[:, 2, 0], rtol=0, atol=4e-4)
    document = stages.joint_errors_document(model)["joints"][2]
    assert document["order_3"]["dx"]["period_deg"] == pytest.approx(120.0)
    assert document["order_3"]["dx"]["amplitude_mm"] == pytest.approx(lobes.amplitude[2, 0])


def test_a_noisy_capture_without_joint_errors_gets_no_run_out_from_its_poses(demo):
    """Instrument noise alone (10 um + 2.5 um/m) passes neither the circles' nor the poses' 99 % chi-squared test
    (this seed; the test's rate of false detections is 1 %), nor the order-3 groups'. A fit the test rejects is 0 in every such capture and
    carries no uncertainty source (module notes of robotcal.uncertainty.joint_errors): the six backlashes, signed and
    each with its standard uncertainty, are the only sources."""
    scenario, truth = demo
    joints, calibration = _calibration(scenario, truth, JointErrorModel.zeros(6), 5)
    model = measured_joint_errors(
        joints.diagnostics, truth, scenario.plan, scenario.tracker_from_base, calibration=calibration
    )
    assert np.all(model.amplitude[:, :3] == 0.0) and model.lobes is None
    assert len(model.sources) == 6 and all(np.all(source.amplitude == 0.0) for source in model.sources)
    lash = np.array([row.backlash_angle_mean for row in joints.diagnostics.summary()])
    np.testing.assert_array_equal(model.backlash, lash)  # the mean as measured, negative ones included
    assert np.any(lash < 0) and np.all(np.abs(np.rad2deg(lash)) < 0.01)  # noise on no lash, both signs


def test_the_uncertainty_stage_takes_the_joint_errors_from_the_joints_stage(demo, monkeypatch, tmp_path):
    scenario, truth = demo
    capture = robotcal.simulate(scenario, rng=1, true_parameters=truth)
    joints = api.diagnose_joints(capture, scenario)
    seen = []

    def spy(scenario, *, joint_errors=None, **keywords):
        seen.append(joint_errors)
        raise KeyboardInterrupt

    monkeypatch.setattr(stages.api, "monte_carlo", spy)
    plan = robotcal.plan_run("kr5-demo", draws=500, refined_draws=300, workers=1)
    for given in (joints, None):
        with pytest.raises(KeyboardInterrupt):
            stages.uncertainty_stage(
                scenario, montecarlo=plan.montecarlo, refined_montecarlo=plan.refined_montecarlo, seed=1, cpa=truth,
                deployed=truth, out=tmp_path, figures=None, joints=given,
            )  # fmt: skip
    measured, without = seen
    assert measured is not scenario.joint_errors and without is not scenario.joint_errors
    lash = [row.backlash_angle_mean for row in joints.diagnostics.summary()]
    assert np.allclose(measured.backlash, lash)
    assert not without.has_lash and np.all(without.amplitude == 0.0) and without.sources == ()
    assert len(measured.sources) >= 6  # every joint's backlash has a standard uncertainty


def test_the_deployed_values_lie_inside_their_interval_and_correct_the_bias(demo):
    scenario, truth = demo
    errors = dataclasses.replace(scenario.joint_errors, backlash=np.zeros(6))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        capture = robotcal.simulate(scenario, rng=1, true_parameters=truth, joint_errors=errors)
        poses = robotcal.simulate_poses(scenario, kind="calibration", true_parameters=truth, rng=2)
        start = robotcal.identify(capture, scenario)
        fitted = api.calibration_capture(scenario, capture, poses)
        estimate = robotcal.refine(fitted, scenario, start, health="off", model="geometric").parameters
    result = api.monte_carlo(
        scenario, parameters=estimate, model="refined", draws=400, rng=3, joint_errors=errors, keep_draws=False,
        poses=poses,
    )  # fmt: skip
    deployed = result.corrected(estimate)
    low, high = result.interval()
    inside = (low <= deployed.values) & (deployed.values <= high)
    assert inside[result.identified].all()
    assert np.allclose(deployed.values[result.identified], (estimate.values - result.bias)[result.identified])
    assert np.array_equal(deployed.values[~result.identified], estimate.values[~result.identified])
    # the estimate itself lies far outside for the parameters the joint errors bias
    assert np.any(~((low <= estimate.values) & (estimate.values <= high))[result.identified])
    # corrected, J1.theta and J1.a, which J1's run-out biases by ~10 u, come back to the truth (the circles alone
    # leave J2.beta and J3.alpha ill-conditioned, where the bias at the estimate is not the bias at the truth)
    u = result.summary.std_uncertainty
    error_before = np.abs(estimate.difference(truth))[0, 1:3] / u[0, 1:3]
    error_after = np.abs(deployed.difference(truth))[0, 1:3] / u[0, 1:3]
    assert np.all(error_before > 5.0) and np.all(error_after < error_before / 3)


def test_the_widened_interval_keeps_its_centre_and_the_draws_skew():
    from robotcal.uncertainty.statistics import widened_interval

    low, high = widened_interval(np.array([-1.0]), np.array([3.0]), np.array([0.0]), np.array([0.0]), 0.95)
    assert low[0] == -1.0 and high[0] == 3.0  # no correction uncertainty: unchanged
    low, high = widened_interval(np.array([-1.0]), np.array([3.0]), np.array([0.0]), np.array([1.0]), 0.95)
    k = 1.959963984540054
    assert low[0] == pytest.approx(-np.hypot(1.0, k)) and high[0] == pytest.approx(np.hypot(3.0, k))


def test_the_measured_backlash_uncertainty_reaches_the_interval_and_the_consistency(demo):
    scenario, truth = demo
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        capture = robotcal.simulate(scenario, rng=1, true_parameters=truth)
    joints = api.diagnose_joints(capture, scenario)
    measured = stages.measured_errors(scenario, joints, truth)
    plain = stages.measured_errors(scenario, None, truth)
    results = [
        api.monte_carlo(scenario, parameters=truth, model="refined", draws=300, rng=3, joint_errors=errors)
        for errors in (measured, plain)
    ]
    with_sources, without = results
    assert without.correction_shifts is None and np.all(without.correction_u == 0.0)
    assert with_sources.correction_shifts.shape[0] == len(measured.sources)
    assert np.any(with_sources.correction_u[with_sources.identified] > 0)
    low, high = with_sources.interval()
    draws_low, draws_high = with_sources.draws_interval()
    assert np.all((high - low) >= (draws_high - draws_low) - 1e-15)  # widened, never narrowed
    validation = robotcal.simulate_poses(scenario, rng=2, true_parameters=truth)
    checks = [api.validation_consistency(validation, truth, result, scenario) for result in results]
    assert checks[0]["predicted_rms_mm"] > checks[1]["predicted_rms_mm"]


def _measurable_study(captures: int, draws: int, seed: int):
    """docs/validation.md: the demo's backlash, a J6 run-out and a J5 axial eccentricity, which the circles show;
    every capture's Monte Carlo simulates the joint errors that capture's joints analysis measures."""
    from robotcal.simulation.perturb import perturb_parameters

    scenario = robotcal.load_scenario("kr5-demo")
    truth = perturb_parameters(scenario.robot, length_sd_mm=0.2, angle_sd_deg=0.05, include_base=True, rng=3)
    amplitude, period, phase = np.zeros((6, 5)), np.full((6, 5), 2 * np.pi), np.zeros((6, 5))
    amplitude[5, :2], phase[5, 1] = 0.02, np.pi / 2
    amplitude[4, 2], period[4, 2] = 0.015, np.pi
    errors = JointErrorModel(
        amplitude=amplitude, period=period, phase=phase, noise_sd=np.zeros((6, 5)), backlash=scenario.joint_errors.backlash
    )
    return robotcal.coverage_study(
        scenario, truth, captures=captures, draws=draws, methods=("refined-mc",), rng=seed,
        measured_joint_errors=True, joint_errors=errors,
    )  # fmt: skip


def test_reduced_coverage_with_the_joint_errors_the_captures_measure():
    coverage = _measurable_study(20, 200, seed=21).empirical("refined-mc")
    assert coverage.mean() >= 0.88 and coverage.min() >= 0.7


@pytest.mark.slow
def test_coverage_with_the_joint_errors_the_captures_measure_is_in_the_band():
    study = _measurable_study(200, 1000, seed=31)
    low, high = study.band
    coverage = study.empirical("refined-mc")
    outside = {name: round(float(c), 3) for name, c in zip(study.names, coverage, strict=True) if not low <= c <= high}
    assert not outside, (study.band, outside)
