"""Least-squares refinement (thesis ch. 4.5.7): residual at truth, Jacobians, recovery, identifiability."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

import refine_options
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityError, IdentifiabilityWarning, InputError
from robotcal.identification import identify_cpa
from robotcal.identification._problem import Problem, measurement_pairs
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.instruments import Instrument
from robotcal.io import load_robot, load_scenario
from robotcal.io.results.provenance import refine_provenance
from robotcal.kinematics.forward import target_positions
from robotcal.kinematics.model import ParameterSet, ReflectorMount
from robotcal.simulation import CapturePlan, simulate_capture
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses, simulate_poses, thesis_test2_plan
from thesis_data import TABLE_5_1_REFLECTORS_MM

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")
EXACT = Instrument(name="exact", a_mm=0.0, b_mm_per_m=0.0)
TRACKER = np.array([[0.0, 1.0, 0.0, 1800.0], [-1.0, 0.0, 0.0, 5.0], [0.0, 0.0, 1.0, 600.0], [0.0, 0.0, 0.0, 1.0]])
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.3, angle_sd_deg=0.05, rng=3)
FULL_PLAN = thesis_test2_plan()
SMALL_PLAN = dataclasses.replace(FULL_PLAN, points=np.array([12, 8, 10, 12, 8, 12]), bidirectional=False)
# Thesis Table 5.1 style per-joint targets (one per circle, eq. 5-1), fewer points: circle i starts
# where circle i-1 ended, so consecutive circles share one set of readings (on different targets)
JOINT_PLAN = CapturePlan(
    start=np.deg2rad([15.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
    sweep=np.deg2rad([45.0, 80.0, 100.0, 50.0, 200.0, 300.0]),
    points=np.array([10, 10, 12, 10, 10, 12]),
    reflector=ReflectorMount(
        frame="joint",
        positions=TABLE_5_1_REFLECTORS_MM,
    ),
    bidirectional=False,
)
# 1e-6 mm / 1e-6 deg: the recovery tolerance for noise-free data
TOLERANCE = np.array([1e-6, np.deg2rad(1e-6), 1e-6, np.deg2rad(1e-6), np.deg2rad(1e-6)])


def _capture(plan, truth=TRUTH, instrument=EXACT, seed=1):
    capture, _ = simulate_capture(
        ROBOT, plan, instrument, TRACKER, true_parameters=truth, joint_limits="ignore", rng=seed
    )
    return capture


def _refine(*args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        return refine_options.refine(*args, **kwargs)


def _problem(capture, start, criterion, free=None, base_free=True):
    free = ~ROBOT.structurally_fixed if free is None else free
    pair_i = pair_j = keep = distances = None
    if criterion == "distances":
        pair_i, pair_j, keep = measurement_pairs(capture.readings)
        distances = np.linalg.norm(capture.points[pair_i] - capture.points[pair_j], axis=1)
    return Problem(
        start=start.values.copy(),
        free=free,
        base_start=TRACKER if criterion == "points" else None,
        base_free=np.full(6, base_free and criterion == "points"),
        q=ROBOT.model_joint_variables(capture.readings),
        turning=capture.circle - 1,
        reflector=FULL_PLAN.reflector,
        measured=capture.points,
        criterion=criterion,
        pair_i=pair_i,
        pair_j=pair_j,
        pair_keep=keep,
        measured_distances=distances,
    )


# -- before any solver test: the model reproduces noise-free data exactly at the truth -------------


@pytest.mark.parametrize("criterion", ["points", "distances"])
def test_residual_at_true_parameters_is_zero(criterion):
    capture = _capture(SMALL_PLAN)
    problem = _problem(capture, TRUTH, criterion)
    residuals = problem.residuals(problem.x0())
    # points ~1e3 mm computed in double precision: rounding ~1e-12 mm
    assert np.max(np.abs(residuals)) < 1e-9
    nominal = _problem(capture, ParameterSet.nominal(ROBOT), criterion)
    assert np.max(np.abs(nominal.residuals(nominal.x0()))) > 0.1


@pytest.mark.parametrize("criterion", ["points", "distances"])
def test_residual_jacobian_matches_central_differences(criterion):
    capture = _capture(SMALL_PLAN)
    problem = _problem(capture, TRUTH, criterion)
    rng = np.random.default_rng(0)
    x = problem.x0() + rng.normal(0.0, 1e-3, problem.x0().size)  # off the start: base angles non-zero
    _, jacobian = problem.evaluate(x)
    numeric = np.zeros_like(jacobian)
    step = 1e-6
    for k in range(x.size):
        up, down = x.copy(), x.copy()
        up[k] += step
        down[k] -= step
        numeric[:, k] = (problem.residuals(up) - problem.residuals(down)) / (2 * step)
    # rounding of residuals ~1e-13 mm relative to |p| ~ 2e3 mm over 2h: ~2e-7; truncation ~h^2 |p|
    np.testing.assert_allclose(jacobian, numeric, atol=2e-6)


# -- noise-free recovery ----------------------------------------------------------------------------


@pytest.mark.parametrize("criterion", ["points", "distances"])
@pytest.mark.parametrize("start_kind", ["nominal", "cpa"])
def test_noise_free_recovery_of_every_identifiable_parameter(criterion, start_kind):
    plan = FULL_PLAN if criterion == "points" else SMALL_PLAN
    capture = _capture(plan)
    if start_kind == "nominal":
        start = ParameterSet.nominal(ROBOT)
    else:
        start = identify_cpa(capture, ROBOT, plan.reflector, tracker_from_base=TRACKER).parameters
    with pytest.warns(IdentifiabilityWarning, match="J6.alpha"):
        result = refine_parameters(capture, start, plan.reflector, settings=RefinementSettings(criterion=criterion))
    assert result.success, result.message
    assert result.njev <= 50
    assert result.identifiability.gauge == ("J1.d", "J1.theta")
    assert result.identifiability.held == ("J6.alpha",)  # flange target: one of J6's d, theta, a, alpha is not seen
    difference = np.abs(result.parameters.difference(TRUTH))
    assert np.all((difference <= np.broadcast_to(TOLERANCE, difference.shape))[result.identifiability.free])
    assert result.fit.cost_history[-1] < 1e-16
    assert result.fit.cost_history[0] >= result.fit.cost_history[-1]
    if criterion == "points":
        np.testing.assert_allclose(result.tracker_from_base, TRACKER, atol=1e-8)


@pytest.mark.parametrize("criterion", ["points", "distances"])
def test_noise_free_recovery_with_perturbed_joint6(criterion):
    # J6's d, theta, a, alpha perturbed too; behind a flange target only three combinations of them
    # are seen (the target's radius about axis 6, its phase and its height), so compare what the data
    # determine: the predicted target at poses the refinement never saw.
    values = TRUTH.values.copy()
    values[5, :4] += [0.4, np.deg2rad(0.07), -0.3, np.deg2rad(0.05)]
    truth = TRUTH.replace(values=values)
    plan = FULL_PLAN if criterion == "points" else SMALL_PLAN
    capture = _capture(plan, truth=truth)
    result = _refine(capture, ParameterSet.nominal(ROBOT), plan.reflector, criterion=criterion)
    assert result.success, result.message
    assert result.identifiability.held == ("J6.alpha",)
    q = ROBOT.model_joint_variables(random_poses(ROBOT, 50, rng=5))
    turning = np.zeros(50, int)
    predicted = target_positions(result.parameters.values, q, turning, plan.reflector)
    expected = target_positions(truth.values, q, turning, plan.reflector)
    # noise-free, solver tolerance 1e-12: parameters to ~1e-11 mm/rad, lever arms ~1e3 mm
    np.testing.assert_allclose(predicted, expected, rtol=0, atol=1e-9)
    # and the visible combinations of J6 are right: the held alpha6 is absorbed by a6, theta6, d6
    assert abs(result.parameters.values[5, 3] - ROBOT.nominal[5, 3]) == 0.0
    assert np.any(np.abs(result.parameters.values[5, :3] - ROBOT.nominal[5, :3]) > 1e-3)


@pytest.mark.parametrize("criterion", ["points", "distances"])
def test_noise_free_recovery_with_per_joint_reflectors(criterion):
    # d1 and theta1 perturbed too: circle 1 does not move with them while circles 2-6 do, so they
    # are no gauge here, with a free base (points, no tracker given) or with distances
    truth = perturb_parameters(ROBOT, length_sd_mm=0.3, angle_sd_deg=0.05, rng=3, include_base=True)
    capture = _capture(JOINT_PLAN, truth=truth)
    result = _refine(capture, ParameterSet.nominal(ROBOT), JOINT_PLAN.reflector, criterion=criterion)
    assert result.success, result.message
    assert result.identifiability.gauge == () and result.identifiability.confounded == ()
    assert result.identifiability.free[0, 0] and result.identifiability.free[0, 1]
    # circle 6's target turns with q6 in frame {5}: J6's own d, theta, a, alpha never enter
    assert result.identifiability.held == ("J6.d", "J6.theta", "J6.a", "J6.alpha")
    difference = np.abs(result.parameters.difference(truth))
    assert np.all((difference <= np.broadcast_to(TOLERANCE, difference.shape))[result.identifiability.free])
    if criterion == "distances":
        # no pair is left out: no point is measured twice on the same target
        assert result.fit.n_residuals == capture.n_points * (capture.n_points - 1) // 2


def test_pairs_of_different_targets_at_the_same_readings_are_kept():
    capture = _capture(JOINT_PLAN)
    readings = capture.readings
    ends = np.cumsum(JOINT_PLAN.points)[:-1]
    # the plan really shares readings between the end of circle i and the start of circle i+1
    np.testing.assert_array_equal(readings[ends - 1], readings[ends])
    _, _, keep = measurement_pairs(readings, capture.circle - 1)
    assert keep.all()
    _, _, flange_keep = measurement_pairs(readings)  # one target: the same readings are the same point
    assert (~flange_keep).sum() == ends.size
    # bidirectional twins on one target are still left out
    twin_readings = np.vstack([readings, readings[:3]])
    _, _, twin_keep = measurement_pairs(twin_readings, np.r_[capture.circle, capture.circle[:3]] - 1)
    assert (~twin_keep).sum() == 3


def test_distance_evaluation_keeps_pairs_of_different_targets():
    from robotcal.identification.evaluation import distance_errors

    capture = _capture(JOINT_PLAN)
    errors = distance_errors(capture, ParameterSet.nominal(ROBOT), JOINT_PLAN.reflector)
    assert errors.size == capture.n_points * (capture.n_points - 1) // 2


@pytest.mark.parametrize("criterion", ["points", "distances"])
def test_no_degrees_of_freedom_left_gives_nan_sigma_and_no_covariance(criterion):
    # 6 flange points: 18 coordinates. Points: 18 residuals for up to 18 unknowns. Distances: 15
    # distances, only 3*6 - 6 = 12 independent of a rigid motion, for more unknowns.
    readings = random_poses(ROBOT, 6, rng=4)
    capture, _ = simulate_poses(ROBOT, readings, FULL_PLAN.reflector, EXACT, TRACKER, true_parameters=TRUTH)
    result = _refine(capture, ParameterSet.nominal(ROBOT), FULL_PLAN.reflector, criterion=criterion)
    assert np.isnan(result.uncertainty.sigma)
    assert result.uncertainty.covariance is None and result.uncertainty.correlation is None
    assert np.all(np.isnan(result.uncertainty.standard_uncertainty))
    assert result.message.startswith("no degrees of freedom left to estimate the noise")
    assert f"{result.fit.n_residuals} residuals" in result.message
    # the parameter JSON's provenance turns the undefined figures into null instead of failing
    scenario = load_scenario("thesis-laser-tracker")
    provenance = refine_provenance(result, capture, "nominal", scenario=scenario)
    assert provenance["sigma_mm"] is None and provenance["correlation"] is None
    json.dumps(provenance, allow_nan=False)


def test_points_criterion_with_known_base_frees_d1_theta1():
    truth = perturb_parameters(ROBOT, length_sd_mm=0.3, angle_sd_deg=0.05, rng=8, include_base=True)
    capture = _capture(FULL_PLAN, truth=truth)
    result = _refine(
        capture, ParameterSet.nominal(ROBOT), FULL_PLAN.reflector, tracker_from_base=TRACKER, estimate_base=False
    )
    free = result.identifiability.free
    assert result.identifiability.gauge == () and free[0, 0] and free[0, 1]
    difference = np.abs(result.parameters.difference(truth))
    assert np.all((difference <= np.broadcast_to(TOLERANCE, difference.shape))[result.identifiability.free])


def test_points_criterion_base_absorbs_the_d1_theta1_gauge():
    truth = perturb_parameters(ROBOT, length_sd_mm=0.3, angle_sd_deg=0.05, rng=8, include_base=True)
    capture = _capture(FULL_PLAN, truth=truth)
    result = _refine(capture, ParameterSet.nominal(ROBOT), FULL_PLAN.reflector)
    shift = truth.values[0, :2] - ROBOT.nominal[0, :2]
    # tracker_true Rz(theta1) Tz(d1) = tracker_est Rz(theta1_nom) Tz(d1_nom) => tracker_est = tracker_true Tz(dd) Rz(dtheta)
    c, s = np.cos(shift[1]), np.sin(shift[1])
    expected = TRACKER @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, shift[0]], [0, 0, 0, 1]])
    np.testing.assert_allclose(result.tracker_from_base, expected, atol=1e-8)


# -- identifiability ---------------------------------------------------------------------------------


def _still_joint_capture():
    robot = ROBOT
    readings = random_poses(robot, 60, rng=2)
    readings[:, 3] = 0.3  # J4 never moves
    capture, _ = simulate_poses(robot, readings, FULL_PLAN.reflector, EXACT, TRACKER, true_parameters=TRUTH)
    return capture


def test_joint_that_never_moves_is_named_and_its_parameters_held():
    capture = _still_joint_capture()
    with pytest.warns(IdentifiabilityWarning, match=r"never move in the capture: J4") as record:
        result = refine_parameters(capture, ParameterSet.nominal(ROBOT), FULL_PLAN.reflector)
    assert result.identifiability.still_joints == ("J4",)
    assert any(name.startswith(("J3.", "J4.", "J5.")) for name in result.identifiability.held)
    assert all(name in str(record[0].message) for name in result.identifiability.held)
    assert np.isfinite(result.identifiability.condition_number)


def test_rank_deficiency_raises_when_free_set_is_explicit_or_strict():
    capture = _still_joint_capture()
    free = ~ROBOT.structurally_fixed
    free[0, :2] = False
    with pytest.raises(IdentifiabilityError, match="J4") as info:
        refine_parameters(
            capture,
            ParameterSet.nominal(ROBOT),
            FULL_PLAN.reflector,
            settings=RefinementSettings(free=free),
        )
    assert "J6.alpha" in info.value.parameters and len(info.value.parameters) >= 3
    with pytest.raises(IdentifiabilityError):
        refine_parameters(
            capture,
            ParameterSet.nominal(ROBOT),
            FULL_PLAN.reflector,
            settings=RefinementSettings(on_unidentifiable="raise"),
        )


def test_gauge_parameter_cannot_be_freed():
    capture = _capture(SMALL_PLAN)
    with pytest.raises(IdentifiabilityError, match="rigid motion of the base") as info:
        refine_parameters(
            capture,
            TRUTH,
            SMALL_PLAN.reflector,
            settings=RefinementSettings(criterion="distances", free=["J1.d", "J2.a"]),
        )
    assert info.value.parameters == ("J1.d",)


def test_free_by_name_refines_only_those():
    capture = _capture(SMALL_PLAN)
    start = TRUTH.replace(values=TRUTH.values + np.where(np.arange(5) == 2, 0.1, 0.0) * (np.arange(6) == 2)[:, None])
    result = refine_parameters(capture, start, SMALL_PLAN.reflector, settings=RefinementSettings(free=["J3.a"]))
    assert result.identifiability.free_names[0] == "J3.a" and result.identifiability.free.sum() == 1
    np.testing.assert_allclose(result.parameters.values, TRUTH.values, atol=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"criterion": "rms"}, "`criterion` must be one of"),
        ({"method": "dogbox"}, "`method` must be"),
        ({"on_unidentifiable": "ignore"}, "`on_unidentifiable`"),
        ({"free": ["J9.d"]}, "unknown parameters"),
        ({"free": ["J2.d"]}, "model fixes at 0"),
        ({"free": np.ones((2, 5), bool)}, "bool array of shape"),
    ],
)
def test_refine_validation(kwargs, message):
    capture = _capture(SMALL_PLAN)
    with pytest.raises(InputError, match=message):
        refine_options.refine(capture, TRUTH, SMALL_PLAN.reflector, **kwargs)


def test_free_poses_need_a_flange_target():
    capture = Capture(
        circle=np.zeros(4, int), direction=np.ones(4, int), readings=np.zeros((4, 6)), points=np.eye(4, 3)
    )
    with pytest.raises(InputError, match="circle = 0"):
        refine_parameters(capture, TRUTH, ReflectorMount(frame="joint", positions=np.ones((6, 3))))


# -- laser-tracker noise ------------------------------------------------------------------------------


def _noise_study(plan, seed):
    tracker = Instrument(name="thesis-laser-tracker", a_mm=0.010, b_mm_per_m=0.0025, noise="uniform")
    capture = _capture(plan, instrument=tracker, seed=seed)
    readings = random_poses(ROBOT, 100, rng=seed + 100)
    validation, _ = simulate_poses(ROBOT, readings, plan.reflector, tracker, TRACKER, true_parameters=TRUTH, rng=seed)
    return capture, validation


def _check_noise(plan, seed):
    from robotcal.identification.evaluation import point_errors

    capture, validation = _noise_study(plan, seed)
    nominal_error = point_errors(validation, ParameterSet.nominal(ROBOT), plan.reflector).mean()
    start = identify_cpa(capture, ROBOT, plan.reflector, tracker_from_base=TRACKER).parameters
    for criterion in ("points", "distances"):
        result = _refine(capture, start, plan.reflector, criterion=criterion)
        refined_error = point_errors(validation, result.parameters, plan.reflector).mean()
        assert refined_error <= 0.2 * nominal_error  # >= 80 % better than nominal
        free = result.identifiability.free
        z = result.parameters.difference(TRUTH)[free] / result.uncertainty.standard_uncertainty[free]
        assert np.all(np.abs(z) < 3.0), (criterion, np.abs(z).max())
        # uniform noise +-(10 + 2.5 L) um with L ~ 2 m: sigma = 15 um / sqrt(3) ~ 8.7 um per coordinate
        assert 0.006 < result.uncertainty.sigma < 0.012


def test_noise_small_capture_improves_and_truth_within_3_sigma():
    _check_noise(SMALL_PLAN, seed=11)


@pytest.mark.slow
def test_noise_thesis_test2_capture_improves_and_truth_within_3_sigma():
    _check_noise(FULL_PLAN, seed=1)


@pytest.mark.slow
def test_noise_free_recovery_distances_on_580_points():
    capture = _capture(FULL_PLAN)
    result = _refine(capture, ParameterSet.nominal(ROBOT), FULL_PLAN.reflector, criterion="distances")
    assert result.fit.n_residuals == 580 * 579 // 2 - 290  # forward/return twins at one pose carry no information
    assert result.njev <= 50
    difference = np.abs(result.parameters.difference(TRUTH))
    assert np.all((difference <= np.broadcast_to(TOLERANCE, difference.shape))[result.identifiability.free])
