"""Direction-dependent backlash term of the generator's joint error model, against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.instruments import Instrument
from robotcal.io import scenario_from_dict
from robotcal.kinematics import ReflectorMount
from robotcal.kinematics.forward import joint_frames
from robotcal.simulation import CapturePlan, JointErrorModel, simulate_capture
from robotcal.simulation.generator import motion_direction
from thesis_data import OFF_AXIS_REFLECTORS_MM, TABLE_5_1_POINTS, TABLE_5_1_START_DEG, TABLE_5_1_SWEEP_DEG, kr5_robot

NOISE_FREE = Instrument(a_mm=0.0, b_mm_per_m=0.0)
LASER = Instrument(a_mm=0.010, b_mm_per_m=0.0025)


def _plan(bidirectional=True):
    return CapturePlan(
        start=np.deg2rad(TABLE_5_1_START_DEG),
        sweep=np.deg2rad(TABLE_5_1_SWEEP_DEG),
        points=TABLE_5_1_POINTS,
        reflector=ReflectorMount(frame="joint", positions=OFF_AXIS_REFLECTORS_MM),
        bidirectional=bidirectional,
    )


def _model(backlash=None, lash=None):
    zeros = np.zeros((6, 5))
    return JointErrorModel(
        amplitude=zeros, period=np.full((6, 5), 2 * np.pi), phase=zeros, noise_sd=zeros, backlash=backlash, lash=lash
    )


def _pairs(capture, joint):
    """(forward row, return row) at equal readings of ``joint`` and whether they are the turnaround."""
    rows = np.flatnonzero(capture.circle == joint)
    forward = rows[capture.direction[rows] == 1]
    back = rows[capture.direction[rows] == -1]
    pairs = []
    for f in forward:
        r = back[capture.readings[back, joint - 1] == capture.readings[f, joint - 1]][0]
        pairs.append((f, r, r == f + 1))
    return pairs


def test_motion_direction_follows_the_last_motion():
    q = np.array([[0.0, 5.0], [1.0, 5.0], [2.0, 5.0], [2.0, 4.0], [1.0, 4.0], [1.0, 4.0], [1.5, 6.0]])
    expected = np.array([[1, 1], [1, 1], [1, 1], [1, -1], [-1, -1], [-1, -1], [1, 1]])
    np.testing.assert_array_equal(motion_direction(q), expected)


def test_zero_lash_changes_nothing_bitwise():
    robot, plan = kr5_robot(), _plan()
    base = np.eye(4)
    plain, _ = simulate_capture(robot, plan, LASER, base, joint_errors=_model(), rng=5)
    explicit, _ = simulate_capture(robot, plan, LASER, base, joint_errors=_model(np.zeros(6), np.zeros((6, 3))), rng=5)
    none, _ = simulate_capture(robot, plan, LASER, base, rng=5)
    np.testing.assert_array_equal(plain.points, explicit.points)
    np.testing.assert_array_equal(plain.points, none.points)


def test_angular_backlash_turns_return_points_by_the_lash():
    robot, plan = kr5_robot(), _plan()
    lash = np.deg2rad([0.01, 0.02, 0.03, 0.04, 0.05, 0.06])
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, np.eye(4), joint_errors=_model(backlash=lash), rng=0)
    for joint in range(1, 7):
        r = OFF_AXIS_REFLECTORS_MM[joint - 1]
        rho = np.hypot(r[0], r[1])  # distance of the target from axis i (reflector in frame {i-1})
        for f, b, turnaround in _pairs(capture, joint):
            chord = np.linalg.norm(capture.points[b] - capture.points[f])
            if turnaround:  # the robot did not move: same pose, same lash state
                assert chord == 0.0
                continue
            # a turn by the lash about the axis: chord 2 rho sin(b/2); 4 m-free coordinates, 1e-10 mm rounding
            np.testing.assert_allclose(chord, 2 * rho * np.sin(lash[joint - 1] / 2), rtol=0, atol=1e-10)
            frame = joint_frames(robot.nominal, capture.readings[f][None])[0, joint - 1]
            axis, centre = frame[:3, 2], frame[:3, :3] @ [0.0, 0.0, r[2]] + frame[:3, 3]
            turn = np.cross(capture.points[f] - centre, capture.points[b] - centre) @ axis
            assert turn > 0  # the return point lies ahead: the forward sweep lags behind the command


def test_a_measured_negative_backlash_turns_return_points_back_by_its_size():
    """A measured mean lash may be negative (noise on a lash of about zero, robotcal.uncertainty.joint_errors):
    a model stated for a robot refuses it (test_invalid_lash_is_refused), a measured model simulates it as a lash
    that lags the other way: the same chord as the positive lash, the return point behind the forward one."""
    from robotcal.uncertainty.joint_errors import MeasuredJointErrors

    robot, plan = kr5_robot(), _plan()
    lash = np.deg2rad([0.01, 0.02, 0.03, 0.04, 0.05, 0.06])
    zeros = np.zeros((6, 5))
    measured = MeasuredJointErrors(
        amplitude=zeros, period=np.full((6, 5), 2 * np.pi), phase=zeros, noise_sd=zeros, backlash=-lash
    )
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, np.eye(4), joint_errors=measured, rng=0)
    for joint in range(1, 7):
        r = OFF_AXIS_REFLECTORS_MM[joint - 1]
        rho = np.hypot(r[0], r[1])
        for f, b, turnaround in _pairs(capture, joint):
            if turnaround:
                continue
            chord = np.linalg.norm(capture.points[b] - capture.points[f])
            np.testing.assert_allclose(chord, 2 * rho * np.sin(lash[joint - 1] / 2), rtol=0, atol=1e-10)
            frame = joint_frames(robot.nominal, capture.readings[f][None])[0, joint - 1]
            axis, centre = frame[:3, 2], frame[:3, :3] @ [0.0, 0.0, r[2]] + frame[:3, 3]
            assert np.cross(capture.points[f] - centre, capture.points[b] - centre) @ axis < 0


def test_translational_lash_shifts_return_points_by_the_lash_in_frame_before_the_joint():
    robot, plan = kr5_robot(), _plan()
    lash = np.array([[0.01, -0.02, 0.03]] * 6) * np.arange(1, 7)[:, None]
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, np.eye(4), joint_errors=_model(lash=lash), rng=0)
    for joint in range(1, 7):
        for f, b, turnaround in _pairs(capture, joint):
            difference = capture.points[b] - capture.points[f]
            frame = joint_frames(robot.nominal, capture.readings[f][None])[0, joint - 1]  # base_from_{i-1}
            expected = np.zeros(3) if turnaround else frame[:3, :3] @ lash[joint - 1]
            np.testing.assert_allclose(difference, expected, rtol=0, atol=1e-10)  # rounding of ~1 m coordinates


def test_one_directional_capture_has_no_lash_effect_within_a_circle():
    """Without a return sweep every point of a circle carries the same state: a rigid turn of the circle."""
    robot, plan = kr5_robot(), _plan(bidirectional=False)
    lash = np.full(6, np.deg2rad(0.05))
    with_lash, _ = simulate_capture(robot, plan, NOISE_FREE, np.eye(4), joint_errors=_model(backlash=lash), rng=0)
    plain, _ = simulate_capture(robot, plan, NOISE_FREE, np.eye(4), rng=0)
    rows = with_lash.circle == 6
    # pairwise distances within circle 6 are unchanged by a common turn (1e-10 mm rounding)
    d_lash = np.linalg.norm(with_lash.points[rows][:, None] - with_lash.points[rows][None], axis=-1)
    d_plain = np.linalg.norm(plain.points[rows][:, None] - plain.points[rows][None], axis=-1)
    np.testing.assert_allclose(d_lash, d_plain, rtol=0, atol=1e-10)


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"backlash": -np.ones(6)}, "backlash.*>= 0"),
        ({"backlash": np.zeros(5)}, "backlash.*shape"),
        ({"lash": np.zeros((6, 2))}, "lash.*shape"),
        ({"lash": np.full((6, 3), np.nan)}, "lash.*NaN"),
    ],
)
def test_invalid_lash_is_refused(changes, match):
    zeros = np.zeros((6, 5))
    with pytest.raises(InputError, match=match):
        JointErrorModel(amplitude=zeros, period=zeros + 1, phase=zeros, noise_sd=zeros, **changes)


def test_scenario_keys_convert_to_core_units():
    data = {
        "robot": "kuka-kr5-sixx-r650",
        "instrument": {"a_um": 0.0, "b_um_per_m": 0.0},
        "capture": {
            "start_deg": [0.0] * 6,
            "sweep_deg": [10.0] * 6,
            "points": [3] * 6,
            "reflector_mm": [[100.0, 0.0, 0.0]] * 6,
            "joint_errors": [{"joint": 4, "backlash_deg": 0.02, "lash_mm": [0.0, 0.01, 0.0]}],
        },
    }
    model = scenario_from_dict(data).joint_errors
    np.testing.assert_array_equal(model.backlash, np.deg2rad([0, 0, 0, 0.02, 0, 0]))
    np.testing.assert_array_equal(model.lash[3], [0.0, 0.01, 0.0])
    data["capture"]["joint_errors"][0]["backlash_deg"] = -1.0
    with pytest.raises(InputError, match="backlash_deg"):
        scenario_from_dict(data)
