"""Synthetic Circle Point generator (thesis 5.2.1.1, eqs 5-1..5-4) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robotcal.errors import InputError, JointLimitWarning
from robotcal.instruments import Instrument
from robotcal.kinematics import ParameterSet, ReflectorMount, RobotModel
from robotcal.simulation import CapturePlan, JointErrorModel, simulate_capture
from thesis_data import (
    OFF_AXIS_REFLECTORS_MM,
    TABLE_5_1_POINTS,
    TABLE_5_1_START_DEG,
    TABLE_5_1_SWEEP_DEG,
    kr5_robot,
    random_rigid,
)

NOISE_FREE = Instrument(a_mm=0.0, b_mm_per_m=0.0)
REFLECTORS = OFF_AXIS_REFLECTORS_MM
_kr5 = kr5_robot


def _table_5_1_plan(**changes):
    arguments = {
        "start": np.deg2rad(TABLE_5_1_START_DEG),
        "sweep": np.deg2rad(TABLE_5_1_SWEEP_DEG),
        "points": TABLE_5_1_POINTS,
        "reflector": ReflectorMount(frame="joint", positions=REFLECTORS),
    } | changes
    return CapturePlan(**arguments)


def _tracker_from_base(seed=0):
    return random_rigid(np.random.default_rng(seed))


def _homogeneous(rotation=np.eye(3), shift=np.zeros(3)):  # noqa: B008 - read-only defaults
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = shift
    return matrix


def _frame_before(nominal, q, i):
    """F_{i-1}: product of the first i links Rz(theta + q) Tz(d) Tx(a) Rx(alpha) Ry(beta), built with scipy."""
    frame = np.eye(4)
    for j in range(i):
        d, theta, a, alpha, beta = nominal[j]
        frame = (
            frame
            @ _homogeneous(Rotation.from_euler("z", theta + q[j]).as_matrix(), [0.0, 0.0, d])
            @ _homogeneous(Rotation.from_euler("XY", [alpha, beta]).as_matrix(), [a, 0.0, 0.0])
        )
    return frame


def test_noise_free_points_lie_on_circles_about_the_nominal_axes():
    robot = _kr5()
    tracker_from_base = _tracker_from_base(1)
    capture, exact = simulate_capture(robot, _table_5_1_plan(), NOISE_FREE, tracker_from_base, rng=0)
    np.testing.assert_array_equal(capture.points, exact)  # a noise-free instrument adds nothing
    q = capture.readings  # identity reading map
    for k, point in enumerate(capture.points):
        i = capture.circle[k] - 1
        frame = tracker_from_base @ _frame_before(robot.nominal, q[k], i)
        local = frame[:3, :3].T @ (point - frame[:3, 3])  # the point in DH frame {i-1}
        r = REFLECTORS[i]
        # eq. 5-1: local = Rz(q_i) r_i, a circle about z_{i-1}: same height, same radius, angle advanced by q_i
        # (rounding of ~4 m coordinates: 1e-9 mm; angles 1e-12 rad at radii >= 80 mm)
        np.testing.assert_allclose(local[2], r[2], rtol=0, atol=1e-9)
        np.testing.assert_allclose(np.hypot(local[0], local[1]), np.hypot(r[0], r[1]), rtol=0, atol=1e-9)
        turned = np.arctan2(local[1], local[0]) - np.arctan2(r[1], r[0])
        np.testing.assert_allclose(np.angle(np.exp(1j * (turned - q[k, i]))), 0.0, atol=1e-12)


def test_flange_reflector_points_follow_the_flange():
    robot = _kr5()
    target = np.array([20.0, -30.0, 60.0])
    plan = _table_5_1_plan(reflector=ReflectorMount(frame="flange", positions=target))
    tracker_from_base = _tracker_from_base(2)
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, tracker_from_base)
    for k in (0, 40, 134):
        flange = tracker_from_base @ _frame_before(robot.nominal, capture.readings[k], 6)
        # base_p = F_n r (rounding of ~4 m coordinates)
        np.testing.assert_allclose(capture.points[k], (flange @ np.r_[target, 1.0])[:3], rtol=0, atol=1e-9)


def test_reading_sign_is_applied_before_the_kinematics():
    sign = np.array([-1, -1, -1, -1, 1, -1])
    robot = _kr5(reading_sign=sign)
    tracker_from_base = _tracker_from_base(3)
    capture, _ = simulate_capture(robot, _table_5_1_plan(), NOISE_FREE, tracker_from_base)
    for k in (5, 50, 120):
        q = sign * capture.readings[k]  # model variables
        i = capture.circle[k] - 1
        frame = tracker_from_base @ _frame_before(robot.nominal, q, i)
        turn = _homogeneous(Rotation.from_euler("z", q[i]).as_matrix())
        expected = (frame @ turn @ np.r_[REFLECTORS[i], 1.0])[:3]
        np.testing.assert_allclose(capture.points[k], expected, rtol=0, atol=1e-9)  # rounding of ~4 m chains


def test_dz_error_on_joint_3_shifts_points_along_axis_3():
    robot = _kr5()
    amplitude, period, phase = 0.05, np.deg2rad(120.0), 0.3
    errors = JointErrorModel.zeros(6)
    values = np.array(errors.amplitude)
    values[2, 2] = amplitude  # only dz of J3
    periods = np.array(errors.period)
    periods[2, 2] = period
    phases = np.zeros((6, 5))
    phases[2, 2] = phase
    model = JointErrorModel(amplitude=values, period=periods, phase=phases, noise_sd=np.zeros((6, 5)))
    tracker_from_base = _tracker_from_base(4)
    plan = _table_5_1_plan()
    clean, _ = simulate_capture(robot, plan, NOISE_FREE, tracker_from_base)
    shifted, _ = simulate_capture(robot, plan, NOISE_FREE, tracker_from_base, joint_errors=model)
    for k in range(clean.n_points):
        q = clean.readings[k]
        if clean.circle[k] < 3:
            # circles 1 and 2 do not pass through joint 3: untouched (exact same arithmetic)
            np.testing.assert_allclose(shifted.points[k], clean.points[k], rtol=0, atol=1e-12)
            continue
        axis = (tracker_from_base @ _frame_before(robot.nominal, q, 2))[:3, 2]  # z_2 in the tracker frame
        dz = amplitude * np.sin(2 * np.pi / period * q[2] + phase)  # eq. 5-2, closed form
        # E_3 = T(0, 0, dz) acts in frame {2}: every later point moves by dz along z_2 (rounding of ~4 m)
        np.testing.assert_allclose(shifted.points[k] - clean.points[k], dz * axis, rtol=0, atol=1e-9)


def test_joint_error_values_closed_form_and_resting_noise():
    rng = np.random.default_rng(5)
    amplitude = rng.uniform(0.0, 0.1, (6, 5))
    period = rng.uniform(0.5, 7.0, (6, 5))
    phase = rng.uniform(-np.pi, np.pi, (6, 5))
    model = JointErrorModel(amplitude=amplitude, period=period, phase=phase, noise_sd=np.zeros((6, 5)))
    _, _, readings = _table_5_1_plan().readings()
    values = model.values(readings)
    expected = amplitude * np.sin(2 * np.pi / period * readings[:, :, None] + phase)
    np.testing.assert_allclose(values, expected, rtol=0, atol=1e-15)  # eq. 5-2 without noise, same formula

    noisy = JointErrorModel(amplitude=np.zeros((6, 5)), period=period, phase=phase, noise_sd=np.full((6, 5), 0.01))
    draws = noisy.values(readings, rng=6)
    for joint in range(6):
        changes = np.r_[True, np.diff(readings[:, joint]) != 0.0]
        segments = np.cumsum(changes)
        for segment in np.unique(segments):
            block = draws[segments == segment, joint]
            # the random part is drawn once per new reading and kept while the joint rests (exact copy)
            np.testing.assert_array_equal(block, np.broadcast_to(block[0], block.shape))
    # new readings get new draws
    assert len(np.unique(draws[:, 0, 0])) == len(np.unique(readings[:, 0]))


def test_seeded_noise_is_reproducible_and_bounded():
    robot = _kr5()
    tracker_from_base = _tracker_from_base(6)
    instrument = Instrument(a_mm=0.01, b_mm_per_m=0.005)
    errors = JointErrorModel(
        amplitude=np.zeros((6, 5)), period=np.ones((6, 5)), phase=np.zeros((6, 5)), noise_sd=np.full((6, 5), 1e-3)
    )
    first, exact = simulate_capture(
        robot, _table_5_1_plan(), instrument, tracker_from_base, joint_errors=errors, rng=11
    )
    again, _ = simulate_capture(robot, _table_5_1_plan(), instrument, tracker_from_base, joint_errors=errors, rng=11)
    other, _ = simulate_capture(robot, _table_5_1_plan(), instrument, tracker_from_base, joint_errors=errors, rng=12)
    np.testing.assert_array_equal(again.points, first.points)  # same seed: identical capture
    assert not np.array_equal(other.points, first.points)
    np.testing.assert_array_equal(again.readings, first.readings)  # readings are never noisy
    bound = instrument.error_bound(exact)[:, None]
    assert np.all(np.abs(first.points - exact) <= bound)  # uniform policy: |e| <= U per coordinate
    assert first.source == "simulated capture"


def test_joint_limit_warning_and_error():
    limits = np.deg2rad(np.tile([-170.0, 170.0], (6, 1)))
    robot = _kr5(limits=limits)
    plan = _table_5_1_plan()  # J5 reaches 200 deg and J6 300 deg
    with pytest.warns(JointLimitWarning, match=r"J5 reaches 200 deg \(circle 5\).*J6 reaches 300 deg \(circle 6\)"):
        simulate_capture(robot, plan, NOISE_FREE, np.eye(4))
    with pytest.raises(InputError, match="capture plan leaves the joint limits of robot 'kr5'"):
        simulate_capture(robot, plan, NOISE_FREE, np.eye(4), joint_limits="error")
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, np.eye(4), joint_limits="ignore")  # no warning
    assert capture.n_points == 135


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"joint_limits": "sometimes"}, "`joint_limits` must be 'warn', 'error' or 'ignore'"),
        ({"tracker_from_base": np.diag([1.0, 1.0, -1.0, 1.0])}, "`tracker_from_base` is not a rigid transform"),
        ({"joint_errors": JointErrorModel.zeros(5)}, "joint error model has 5 joints; robot has 6"),
    ],
)
def test_simulate_capture_validation(arguments, message):
    arguments = {"tracker_from_base": np.eye(4)} | arguments
    with pytest.raises(InputError, match=message):
        simulate_capture(_kr5(), _table_5_1_plan(), NOISE_FREE, **arguments)


def test_plan_and_parameters_must_match_the_robot():
    five = RobotModel(name="five", nominal=_kr5().nominal[:5], hayati=[False, True, False, False, False])
    with pytest.raises(InputError, match="capture plan has 6 circles but robot 'five' has 5 joints"):
        simulate_capture(five, _table_5_1_plan(), NOISE_FREE, np.eye(4))
    with pytest.raises(InputError, match="true parameters have 5 joints; robot 'kr5' has 6"):
        simulate_capture(_kr5(), _table_5_1_plan(), NOISE_FREE, np.eye(4), true_parameters=ParameterSet.nominal(five))


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"period": np.ones((6, 4))}, r"`period` must have shape \(n_joints, 5\); got \(6, 4\)"),
        ({"period": np.zeros((6, 5))}, "every `period` must be > 0"),
        ({"noise_sd": np.full((6, 5), -1.0)}, "`noise_sd` must be >= 0"),
        ({"phase": np.full((6, 5), np.nan)}, "`phase` contains NaN"),
    ],
)
def test_joint_error_model_validation(changes, message):
    arguments = {
        "amplitude": np.zeros((6, 5)),
        "period": np.ones((6, 5)),
        "phase": np.zeros((6, 5)),
        "noise_sd": np.zeros((6, 5)),
    } | changes
    with pytest.raises(InputError, match=message):
        JointErrorModel(**arguments)
