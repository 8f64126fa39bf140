"""TCP propagation: statistics equal per-draw forward kinematics, linearised vs Monte Carlo, Jacobian,
coverage ellipsoid, angle wrapping, chunking, input validation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from robotcal.errors import InputError, JointLimitWarning
from robotcal.geometry.euler import kuka_abc_from_matrix, wrap_angle_near
from robotcal.geometry.transforms import apply_transform
from robotcal.io import load_robot
from robotcal.kinematics.forward import forward_kinematics, joint_frames
from robotcal.uncertainty.statistics import summarize_draws
from robotcal.uncertainty.tcp import (
    check_readings,
    coverage_ellipsoid,
    position_covariance,
    propagate_to_tcp,
    tcp_coordinates,
    tcp_jacobian,
)

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")
#: readings inside the limits of kuka-kr5-sixx-r650-krc [deg]
READINGS_DEG = np.array(
    [
        [10.0, -80.0, 100.0, 20.0, 50.0, -30.0],
        [-40.0, -60.0, 70.0, -60.0, 80.0, 120.0],
        [90.0, -100.0, 120.0, 150.0, -40.0, 300.0],
    ]
)
TOOL = np.array([15.0, -20.0, 120.0])


def _free(robot=ROBOT):
    free = ~robot.structurally_fixed
    free[-1, :4] = False  # joint 6 is not identified by CPA (docs/conventions.md)
    return free


def _gaussian_draws(n_draws, *, length_mm=0.05, angle_rad=2e-4, seed=0, robot=ROBOT):
    """Nominal + correlated Gaussian noise on the identified parameters; returns draws and the covariance."""
    rng = np.random.default_rng(seed)
    free = _free(robot).reshape(-1)
    k = int(free.sum())
    scale = np.where(np.isin(np.arange(robot.n_joints * 5) % 5, [1, 3, 4]), angle_rad, length_mm)[free]
    mixing = np.eye(k) + 0.4 * rng.standard_normal((k, k)) / np.sqrt(k)  # correlations between parameters
    covariance = (scale[:, None] * mixing) @ (scale[:, None] * mixing).T
    noise = rng.multivariate_normal(np.zeros(k), covariance, size=n_draws)
    flat = np.repeat(robot.nominal.reshape(1, -1), n_draws, axis=0)
    flat[:, free] += noise
    full = np.zeros((robot.n_joints * 5, robot.n_joints * 5))
    full[np.ix_(free, free)] = covariance
    return flat.reshape(n_draws, robot.n_joints, 5), full


def _direct(draws, readings, tool):
    """Per-draw forward kinematics with the reference implementation, one draw at a time."""
    q = ROBOT.model_joint_variables(readings)
    out = np.empty((draws.shape[0], q.shape[0], 6))
    for m, parameters in enumerate(draws):
        frames = forward_kinematics(parameters, q)
        out[m, :, :3] = apply_transform(frames, tool)
        out[m, :, 3:] = kuka_abc_from_matrix(frames)
    return out


def test_statistics_equal_direct_per_draw_forward_kinematics():
    draws, _ = _gaussian_draws(300, seed=1)
    readings = np.deg2rad(READINGS_DEG)
    # tiny batch and memory bound: several pose chunks and draw batches are exercised
    result = propagate_to_tcp(ROBOT, draws, readings, tool=TOOL, batch_size=7, max_bytes=48 * 300 * 2)
    direct = _direct(draws, readings, TOOL)
    nominal = _direct(ROBOT.nominal[None], readings, TOOL)[0]
    direct[..., 3:] = wrap_angle_near(direct[..., 3:], nominal[..., 3:])
    expected = summarize_draws(direct, 0.95)
    # two implementations of the same products of 4x4 matrices: rounding differences ~1e-13 mm
    np.testing.assert_allclose(result.nominal, nominal, rtol=0, atol=1e-10)
    for name in ("mean", "std_uncertainty", "symmetric_low", "symmetric_high", "shortest_low", "shortest_high"):
        np.testing.assert_allclose(getattr(result.summary, name), getattr(expected, name), rtol=0, atol=1e-10)
    np.testing.assert_allclose(result.summary.minimum, expected.minimum, rtol=0, atol=1e-10)
    np.testing.assert_allclose(result.summary.maximum, expected.maximum, rtol=0, atol=1e-10)
    centred = direct - direct.mean(axis=0)
    np.testing.assert_allclose(
        result.covariance, np.einsum("mpi,mpj->pij", centred, centred) / 299, rtol=1e-9, atol=1e-16
    )


def test_chunking_does_not_change_the_result():
    draws, _ = _gaussian_draws(200, seed=2)
    readings = np.deg2rad(READINGS_DEG)
    whole = propagate_to_tcp(ROBOT, draws, readings, keep_draws=True)
    chunked = propagate_to_tcp(ROBOT, draws, readings, batch_size=3, max_bytes=1)
    np.testing.assert_array_equal(whole.summary.symmetric_low, chunked.summary.symmetric_low)
    np.testing.assert_allclose(whole.summary.mean, chunked.summary.mean, rtol=0, atol=1e-12)
    np.testing.assert_allclose(whole.ellipsoid.semi_axes, chunked.ellipsoid.semi_axes, rtol=1e-12)
    assert whole.draws.shape == (200, 3, 6) and chunked.draws is None


def test_linearised_covariance_agrees_with_monte_carlo_at_low_noise():
    n_draws = 4000
    draws, population = _gaussian_draws(n_draws, length_mm=0.01, angle_rad=2e-5, seed=3)
    readings = np.deg2rad(READINGS_DEG)
    result = propagate_to_tcp(ROBOT, draws, readings, tool=TOOL)
    # (1) with the draws' own covariance the linearisation differs from Monte Carlo only by the
    # model's curvature, O(noise) relative (~1e-4 here)
    np.testing.assert_allclose(result.lpu_std_uncertainty, result.std_uncertainty, rtol=2e-3)
    # (2) against the *population* covariance the Monte Carlo variance carries sampling error:
    # the relative standard error of a sample variance is sqrt(2 / (M - 1)) = 0.022; allow 5 of them
    free = _free().reshape(-1)
    jacobian = tcp_jacobian(ROBOT.nominal, ROBOT.model_joint_variables(readings), tool=TOOL, free=_free())
    exact = np.einsum("pik,kl,pjl->pij", jacobian, population[np.ix_(free, free)], jacobian)
    ratio = np.diagonal(result.covariance, axis1=1, axis2=2) / np.diagonal(exact, axis1=1, axis2=2)
    assert np.all(np.abs(ratio - 1.0) < 5.0 * np.sqrt(2.0 / (n_draws - 1))), ratio


def test_jacobian_matches_the_geometric_jacobian():
    # independent truth: d p / d d_i = z_{i-1}, d p / d theta_i = z_{i-1} x (p - o_{i-1}),
    # d p / d a_i = x_i (DH joints), and a base rotation d theta_1 turns A by the same angle
    readings = np.deg2rad(READINGS_DEG)
    q = ROBOT.model_joint_variables(readings)
    jacobian = tcp_jacobian(ROBOT.nominal, q, tool=TOOL)
    frames = joint_frames(ROBOT.nominal, q)  # (P, n + 1, 4, 4)
    p = apply_transform(frames[:, -1], TOOL)
    for i in range(ROBOT.n_joints):
        z_prev, o_prev = frames[:, i, :3, 2], frames[:, i, :3, 3]
        # central differences: error ~ h^2 f''' + eps |f| / h < 1e-8 mm per unit
        np.testing.assert_allclose(jacobian[:, :3, 5 * i + 1], np.cross(z_prev, p - o_prev), rtol=0, atol=1e-6)
        if not ROBOT.hayati[i]:
            np.testing.assert_allclose(jacobian[:, :3, 5 * i + 0], z_prev, rtol=0, atol=1e-8)
            np.testing.assert_allclose(jacobian[:, :3, 5 * i + 2], frames[:, i + 1, :3, 0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(jacobian[:, 3:, 1], np.tile([1.0, 0.0, 0.0], (3, 1)), rtol=0, atol=1e-8)


def test_coverage_ellipsoid_of_gaussian_positions():
    rng = np.random.default_rng(5)
    n_draws = 20000
    axes_mm = np.array([0.3, 0.1, 0.05])
    rotation = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    covariance = rotation @ np.diag(axes_mm**2) @ rotation.T
    positions = rng.multivariate_normal([100.0, -50.0, 300.0], covariance, size=n_draws)
    ellipsoid = coverage_ellipsoid(positions, 0.95)
    k = np.sqrt(chi2.ppf(0.95, 3))
    # sample standard deviations: relative standard error 1/sqrt(2(M-1)) = 0.005; 5 of them
    np.testing.assert_allclose(ellipsoid.semi_axes[0], k * axes_mm, rtol=0.025)
    np.testing.assert_allclose(np.abs(ellipsoid.directions[0].T @ rotation), np.eye(3), atol=0.05)
    # binomial standard error of the fraction inside: sqrt(p (1 - p) / M) = 0.0015; 5 of them
    assert abs(ellipsoid.fraction_inside[0] - 0.95) < 5 * np.sqrt(0.95 * 0.05 / n_draws)
    assert abs(ellipsoid.monte_carlo_scale[0] / k - 1.0) < 0.02
    np.testing.assert_allclose(ellipsoid.monte_carlo_semi_axes, ellipsoid.semi_axes, rtol=0.02)


def test_orientation_draws_are_wrapped_around_a_nominal_near_180_deg():
    draws, _ = _gaussian_draws(500, angle_rad=1e-3, seed=6)
    readings = np.deg2rad(READINGS_DEG[:1]).copy()
    # turn joint 1 so that the nominal A is exactly 180 deg: A follows theta_1 + q_1 one to one
    a0 = tcp_coordinates(ROBOT.nominal, ROBOT.model_joint_variables(readings))[0, 3]
    readings[0, 0] += ROBOT.reading_sign[0] * (np.pi - a0)
    result = propagate_to_tcp(ROBOT, draws, readings)
    assert abs(abs(result.nominal[0, 3]) - np.pi) < 1e-9
    assert abs(abs(result.summary.mean[0, 3]) - np.pi) < 0.01  # not 0: draws at +-180 deg are averaged as neighbours
    assert result.std_uncertainty[0, 3] < 0.01


def test_parameters_that_do_not_vary_give_zero_linearised_uncertainty():
    draws = np.repeat(ROBOT.nominal[None], 30, axis=0)
    result = propagate_to_tcp(ROBOT, draws, np.deg2rad(READINGS_DEG[0]))
    np.testing.assert_array_equal(result.lpu_covariance, 0.0)
    # identical draws: only the rounding of the mean is left (~1e-13 mm on 500 mm coordinates)
    np.testing.assert_allclose(result.std_uncertainty, 0.0, atol=1e-12)


def test_readings_with_wrong_joint_count_are_refused():
    draws, _ = _gaussian_draws(50)
    with pytest.raises(InputError, match=r"must give 6 joint readings per pose .* got 5"):
        propagate_to_tcp(ROBOT, draws, np.zeros((2, 5)))


def test_non_finite_reading_names_the_pose():
    draws, _ = _gaussian_draws(50)
    readings = np.deg2rad(READINGS_DEG).copy()
    readings[2, 3] = np.nan
    with pytest.raises(InputError, match=r"pose 3, joint J4 is not a finite number"):
        propagate_to_tcp(ROBOT, draws, readings)


def test_readings_outside_the_limits_warn_naming_the_pose():
    draws, _ = _gaussian_draws(50)
    readings = np.deg2rad(READINGS_DEG).copy()
    readings[1, 4] = np.deg2rad(125.0)
    with pytest.warns(JointLimitWarning, match=r"pose 2: J5 = 125 deg outside \[-120, 120\] deg") as record:
        propagate_to_tcp(ROBOT, draws, readings)
    # the warning points at the caller of the public function (stacklevel), here this test file
    assert [w.filename for w in record] == [__file__]
    with pytest.warns(JointLimitWarning, match=r"pose 2: J5") as record:
        check_readings(ROBOT, readings, name="trajectory")
    assert [w.filename for w in record] == [__file__]
    with pytest.warns(JointLimitWarning, match=r"pose 2: J5") as record:
        position_covariance(ROBOT, draws, readings)
    assert [w.filename for w in record] == [__file__]


def test_bad_draws_tool_and_coverage_are_refused():
    draws, _ = _gaussian_draws(50)
    readings = np.deg2rad(READINGS_DEG[0])
    with pytest.raises(InputError, match=r"`parameter_draws` must have shape"):
        propagate_to_tcp(ROBOT, draws[:, :5], readings)
    with pytest.raises(InputError, match=r"at least 2 draws"):
        propagate_to_tcp(ROBOT, draws[:1], readings)
    with pytest.raises(InputError, match=r"`tool` must be three finite numbers"):
        propagate_to_tcp(ROBOT, draws, readings, tool=[1.0, 2.0])
    with pytest.raises(InputError, match=r"`coverage` must be a probability"):
        propagate_to_tcp(ROBOT, draws, readings, coverage=1.5)
    with pytest.raises(InputError, match=r"`batch_size` must be a positive integer"):
        propagate_to_tcp(ROBOT, draws, readings, batch_size=0)
