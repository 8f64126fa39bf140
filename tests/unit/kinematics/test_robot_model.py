"""RobotModel, ParameterSet and ReflectorMount: validation, structure and the reading map."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.kinematics import ParameterSet, ReflectorMount, RobotModel
from thesis_data import KR5_HAYATI, kr5_nominal

DEG = np.pi / 180.0
HAYATI_J2 = KR5_HAYATI


_kr5_nominal = kr5_nominal


def _robot(**changes):
    arguments = {"name": "kr5", "nominal": _kr5_nominal(), "hayati": HAYATI_J2} | changes
    return RobotModel(**arguments)


def test_structure_of_the_kr5_model():
    robot = _robot()
    assert robot.n_joints == 6
    assert robot.parameter_names[:5] == ("J1.d", "J1.theta", "J1.a", "J1.alpha", "J1.beta")
    assert robot.parameter_names[9] == "J2.beta" and len(robot.parameter_names) == 30
    fixed = robot.structurally_fixed
    # d of the Hayati joint and beta of every DH joint are fixed by the model
    expected = np.zeros((6, 5), dtype=bool)
    expected[1, 0] = True
    expected[[0, 2, 3, 4, 5], 4] = True
    np.testing.assert_array_equal(fixed, expected)
    np.testing.assert_array_equal(robot.reading_sign, np.ones(6))  # identity reading map by default
    np.testing.assert_array_equal(robot.reading_offset, np.zeros(6))
    np.testing.assert_array_equal(robot.limits, np.tile([-np.inf, np.inf], (6, 1)))


def test_model_arrays_are_read_only_copies():
    nominal = _kr5_nominal()
    robot = _robot(nominal=nominal)
    nominal[0, 0] = 0.0
    assert robot.nominal[0, 0] == 335.0  # the model keeps its own copy
    with pytest.raises(ValueError, match="read-only"):
        robot.nominal[0, 0] = 1.0


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"nominal": _kr5_nominal()[:, :4]}, r"`nominal` must have shape \(n_joints, 5\)"),
        ({"hayati": [False, True]}, "`hayati` must have 6 entries"),
        ({"reading_sign": [1, 1, 1, 1, 1, 2]}, "`reading_sign` must be 6 values of \\+1 or -1"),
        ({"reading_sign": [1, -1]}, "`reading_sign` must be 6 values"),
        ({"reading_offset": [0, 0, 0, 0, 0, np.nan]}, "`reading_offset` must be 6 finite values"),
        ({"limits": np.tile([1.0, -1.0], (6, 1))}, r"`limits` must be 6 pairs \(lower < upper\)"),
    ],
)
def test_robot_model_validation(changes, message):
    with pytest.raises(InputError, match=message):
        _robot(**changes)


def test_hayati_joint_with_d_is_rejected():
    nominal = _kr5_nominal()
    nominal[1, 0] = 5.0
    with pytest.raises(InputError, match="Hayati joints have d = 0 by definition; J2 give d != 0"):
        _robot(nominal=nominal)


def test_dh_joint_with_beta_is_rejected():
    nominal = _kr5_nominal()
    nominal[3, 4] = 0.01
    with pytest.raises(InputError, match="DH joints have beta = 0; J4 give beta != 0"):
        _robot(nominal=nominal)


def test_nan_nominal_is_rejected():
    nominal = _kr5_nominal()
    nominal[2, 2] = np.nan
    with pytest.raises(InputError, match="NaN or infinite"):
        _robot(nominal=nominal)


def test_reading_map_closed_form_and_round_trip():
    sign = np.array([-1, -1, -1, -1, 1, -1])
    offset = np.deg2rad([0.0, -90.0, 90.0, 0.0, 0.0, 180.0])
    robot = _robot(reading_sign=sign, reading_offset=offset)
    readings = np.deg2rad(np.array([[60.0, 80.0, -45.0, 200.0, 125.0, 280.0], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]]))
    q = robot.model_joint_variables(readings)
    # q = sign * reading + offset, written out here (rounding only)
    np.testing.assert_allclose(q, sign * readings + offset, rtol=0, atol=1e-15)
    np.testing.assert_allclose(robot.readings_from_model(q), readings, rtol=0, atol=1e-14)  # exact inverse


def test_thesis_tcp_reading_map():
    # docs/conventions.md: readings (60, 80, -45, 200, 125, 280) with signs (-,-,-,-,+,-) are model
    # q = (-60, -80, 45, -200, 125, -280) deg
    robot = _robot(reading_sign=[-1, -1, -1, -1, 1, -1])
    q = robot.model_joint_variables(np.deg2rad([60.0, 80.0, -45.0, 200.0, 125.0, 280.0]))
    np.testing.assert_allclose(np.rad2deg(q), [-60.0, -80.0, 45.0, -200.0, 125.0, -280.0], rtol=0, atol=1e-12)


def test_parameter_set_nominal_and_difference():
    robot = _robot()
    nominal = ParameterSet.nominal(robot)
    np.testing.assert_array_equal(nominal.values, robot.nominal)
    assert not nominal.identified.any()
    values = robot.nominal.copy()
    values[4, 1] = np.deg2rad(-179.0)  # theta5 nominal 180 deg: 1 deg away across the wrap
    values[0, 0] += 0.25
    other = ParameterSet(robot=robot, values=values)
    difference = other.difference(nominal)
    expected = np.zeros((6, 5))
    expected[4, 1] = np.deg2rad(1.0)
    expected[0, 0] = 0.25
    # angles wrapped to (-pi, pi]: -179 - 180 = -359 deg is +1 deg (rounding of 2 pi)
    np.testing.assert_allclose(difference, expected, rtol=0, atol=1e-12)
    replaced = other.replace(identified=np.ones((6, 5), dtype=bool))
    assert replaced.identified.all() and replaced.values is not None


def test_parameter_set_validation():
    robot = _robot()
    values = robot.nominal.copy()
    values[1, 0] = 1.0
    with pytest.raises(InputError, match="fixed at 0 by the model have other values: J2.d"):
        ParameterSet(robot=robot, values=values)
    with pytest.raises(InputError, match=r"shape \(\.\.\., 6, 5\)"):
        ParameterSet(robot=robot, values=np.zeros((5, 5)))
    with pytest.raises(InputError, match="holds one set"):
        ParameterSet(robot=robot, values=np.zeros((2, 6, 5)))
    with pytest.raises(InputError, match=r"`identified` must have shape \(6, 5\)"):
        ParameterSet(robot=robot, values=robot.nominal, identified=np.zeros(6, dtype=bool))


def test_reflector_mount():
    flange = ReflectorMount(frame="flange", positions=[1.0, 2.0, 3.0])
    assert flange.positions.shape == (1, 3)  # a single position becomes a batch of one
    joint = ReflectorMount(frame="joint", positions=np.ones((6, 3)))
    assert joint.positions.shape == (6, 3)
    with pytest.raises(InputError, match="reflector frame must be 'joint' or 'flange'; got 'tool'"):
        ReflectorMount(frame="tool", positions=[0.0, 0.0, 0.0])
    with pytest.raises(InputError, match=r"a flange reflector is one position \(3,\); got 2"):
        ReflectorMount(frame="flange", positions=np.zeros((2, 3)))
    with pytest.raises(InputError, match=r"must be finite \(n, 3\)"):
        ReflectorMount(frame="joint", positions=[[0.0, np.nan, 0.0]])
    with pytest.raises(InputError, match=r"must be finite \(n, 3\)"):
        ReflectorMount(frame="joint", positions=np.zeros((6, 2)))
