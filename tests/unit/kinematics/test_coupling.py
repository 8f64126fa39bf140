"""Joint coupling of the readings: ``reading = M (q - offset)``, ``M = diag(reading_sign) + reading_coupling``.

Independent truths: the Fanuc-style file's map written out by hand (q2 = r2, q3 = -r3 - r2), and the
physical property that motivates it (turning J2 alone on the controller keeps the forearm's
orientation, because J2 and J3 turn about parallel axes).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io.schema.robots import load_robot, robot_from_dict, robot_to_dict
from robotcal.kinematics.forward import forward_kinematics, joint_frames
from robotcal.kinematics.model import RobotModel


@pytest.fixture(scope="module")
def fanuc():
    return load_robot("fanuc-style-coupled")


def _random_readings(robot, n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.limits[:, 0], robot.limits[:, 1], size=(n, robot.n_joints))


def test_fanuc_file_declares_the_j3_coupling(fanuc):
    assert fanuc.is_coupled
    expected = np.eye(6)
    expected[2, 2] = -1.0
    expected[2, 1] = -1.0  # reading_3 = -(q3 - o3) - (q2 - o2)
    np.testing.assert_array_equal(fanuc.reading_matrix, expected)


def test_fk_of_coupled_readings_equals_fk_of_hand_converted_model_variables(fanuc):
    readings = _random_readings(fanuc, 200, seed=1)
    by_hand = readings.copy()  # offsets are 0 in the file: q2 = r2, q3 = -r3 - r2, others q = r
    by_hand[:, 2] = -readings[:, 2] - readings[:, 1]
    q = fanuc.model_joint_variables(readings)
    # the map is a 6x6 product of exact small integers: agreement to rounding of one add
    np.testing.assert_allclose(q, by_hand, rtol=0, atol=1e-15)
    uncoupled = RobotModel(name="fanuc-uncoupled", nominal=fanuc.nominal, hayati=fanuc.hayati)
    np.testing.assert_allclose(
        forward_kinematics(fanuc.nominal, q),
        forward_kinematics(uncoupled.nominal, uncoupled.model_joint_variables(by_hand)),
        rtol=0,
        atol=1e-9,  # mm and rotation entries; the model variables agree to 1e-15 rad, FK lever arms < 2 m
    )


def test_turning_j2_alone_keeps_the_forearm_orientation(fanuc):
    """The reason for the coupling: J3's reading is the forearm's angle to the horizontal."""
    base = np.deg2rad([20.0, 0.0, 15.0, 30.0, -40.0, 50.0])
    readings = np.tile(base, (7, 1))
    readings[:, 1] = np.deg2rad(np.linspace(-60.0, 90.0, 7))
    frames = joint_frames(fanuc.nominal, fanuc.model_joint_variables(readings))
    forearm = frames[:, 3, :3, :3]  # frame {3} carries the forearm (J4 axis)
    np.testing.assert_allclose(forearm - forearm[0], 0.0, atol=1e-12)  # rotation entries, a few roundings
    flange = frames[:, -1, :3, :3]
    np.testing.assert_allclose(flange - flange[0], 0.0, atol=1e-12)
    # while the wrist does move (not a constant function)
    assert np.ptp(frames[:, 3, 0, 3]) > 100.0


@pytest.mark.parametrize("seed", [2, 3])
def test_round_trip_readings_model_variables_with_random_coupling(seed):
    rng = np.random.default_rng(seed)
    n = 6
    coupling = rng.uniform(-1.0, 1.0, (n, n)) * (rng.uniform(size=(n, n)) < 0.4)
    np.fill_diagonal(coupling, 0.0)
    coupling[2, 1] = 0.7  # at least one coupling
    robot = RobotModel(
        name="random",
        nominal=load_robot("kuka-kr5-sixx-r650").nominal,
        hayati=[False, True, False, False, False, False],
        reading_sign=rng.choice([-1.0, 1.0], n),
        reading_offset=rng.uniform(-1.0, 1.0, n),
        reading_coupling=coupling,
    )
    readings = rng.uniform(-3.0, 3.0, (50, n))
    q = robot.model_joint_variables(readings)
    # independent: solve M (q - o) = r with numpy's solver instead of the stored inverse
    expected = np.linalg.solve(robot.reading_matrix, readings.T).T + robot.reading_offset
    np.testing.assert_allclose(q, expected, rtol=0, atol=1e-12)  # cond(M) < 10: error ~ 1e-15 * cond * |r|
    np.testing.assert_allclose(robot.readings_from_model(q), readings, rtol=0, atol=1e-12)
    np.testing.assert_allclose(robot.model_joint_variables(robot.readings_from_model(q)), q, rtol=0, atol=1e-12)
    # batched shapes: a single pose and a stack of stacks give the same numbers
    np.testing.assert_allclose(robot.model_joint_variables(readings[0]), q[0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(robot.model_joint_variables(readings.reshape(5, 10, n)), q.reshape(5, 10, n), atol=1e-15)


@pytest.mark.parametrize("name", ["kuka-kr5-sixx-r650", "kuka-kr5-sixx-r650-krc", "abb-irb120"])
def test_uncoupled_robots_keep_the_diagonal_map_exactly(name):
    robot = load_robot(name)
    assert not robot.is_coupled
    readings = _random_readings(robot, 20, seed=4)
    np.testing.assert_array_equal(
        robot.model_joint_variables(readings), readings * robot.reading_sign + robot.reading_offset
    )
    assert all("reading_coupling" not in joint for joint in robot_to_dict(robot)["joints"])


def test_robot_dict_round_trip_keeps_the_coupling(fanuc):
    data = robot_to_dict(fanuc)
    assert data["joints"][2]["reading_coupling"] == {"2": -1.0}
    again = robot_from_dict(data, "round trip")
    np.testing.assert_array_equal(again.reading_matrix, fanuc.reading_matrix)


def _kr5_with(coupling_by_joint: dict[int, dict], signs: dict[int, int] | None = None) -> dict:
    data = copy.deepcopy(robot_to_dict(load_robot("kuka-kr5-sixx-r650")))
    for joint, coupling in coupling_by_joint.items():
        data["joints"][joint - 1]["reading_coupling"] = coupling
    for joint, sign in (signs or {}).items():
        data["joints"][joint - 1]["reading_sign"] = sign
    return data


@pytest.mark.parametrize(
    ("coupling", "message"),
    [
        ({3: {"7": 1.0}}, r"joints\[2\]\.reading_coupling\.7`: 7 is not a joint number 1\.\.6"),
        ({3: {"3": 1.0}}, r"joints\[2\]\.reading_coupling\.3`: a joint is not coupled to itself"),
        ({3: {"2": float("nan")}}, r"joints\[2\]\.reading_coupling\.2`: must be a finite number"),
        ({2: {"3": 1.0}, 3: {"2": 1.0}}, r"not invertible \(condition number"),
        ({3: {"x": 1.0}}, r"reading_coupling"),
    ],
)
def test_bad_couplings_are_refused_naming_the_key(coupling, message):
    with pytest.raises(InputError, match=message):
        robot_from_dict(_kr5_with(coupling), "robot.toml")


def test_model_validates_the_matrix_itself():
    kr5 = load_robot("kuka-kr5-sixx-r650")
    with pytest.raises(InputError, match=r"shape \(6, 6\); got \(5, 5\)"):
        RobotModel(name="x", nominal=kr5.nominal, hayati=kr5.hayati, reading_coupling=np.zeros((5, 5)))
    with pytest.raises(InputError, match="J2 is coupled to itself"):
        RobotModel(name="x", nominal=kr5.nominal, hayati=kr5.hayati, reading_coupling=np.diag([0, 1.0, 0, 0, 0, 0]))
    with pytest.raises(InputError, match="NaN or infinite"):
        RobotModel(name="x", nominal=kr5.nominal, hayati=kr5.hayati, reading_coupling=np.full((6, 6), np.inf))
