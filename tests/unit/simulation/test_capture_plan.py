"""Capture plans (thesis 5.2.1, Table 5.1; Table 4.2 start matrices): the visited readings."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io import load_robot
from robotcal.kinematics import ReflectorMount, RobotModel
from robotcal.simulation import CapturePlan
from thesis_data import TABLE_4_2_DEG, TABLE_5_1_POINTS, TABLE_5_1_START_DEG, TABLE_5_1_SWEEP_DEG, kr5_robot

#: Thesis Table 5.1 [deg, points] and Table 4.2 (tests/thesis_data.py)
START_DEG = TABLE_5_1_START_DEG
SWEEP_DEG = TABLE_5_1_SWEEP_DEG
POINTS = TABLE_5_1_POINTS
REFLECTOR = ReflectorMount(frame="joint", positions=np.full((6, 3), 100.0))


def _plan(**changes):
    arguments = {
        "start": np.deg2rad(START_DEG),
        "sweep": np.deg2rad(SWEEP_DEG),
        "points": POINTS,
        "reflector": REFLECTOR,
    } | changes
    return CapturePlan(**arguments)


def _expected_forward_readings(start_deg, sweep_deg, points):
    """Readings [deg] written out point by point: joint i steps by sweep_i / (N_i - 1) from start_i,
    earlier joints rest at start + sweep, later joints wait at their start."""
    rows, circles = [], []
    current = np.array(start_deg, dtype=float)
    for i in range(6):
        for k in range(points[i]):
            row = current.copy()
            row[i] = start_deg[i] + k * sweep_deg[i] / (points[i] - 1)
            rows.append(row)
            circles.append(i + 1)
        current[i] = start_deg[i] + sweep_deg[i]
    return np.array(circles), np.array(rows)


def test_table_5_1_readings():
    circle, direction, readings = _plan().readings()
    expected_circle, expected_deg = _expected_forward_readings(START_DEG, SWEEP_DEG, POINTS)
    assert readings.shape == (135, 6)  # 15 + 20 + 30 + 15 + 25 + 30 points
    np.testing.assert_array_equal(circle, expected_circle)
    np.testing.assert_array_equal(direction, 1)
    # linspace vs start + k * step: rounding of angles up to 5 rad (~1e-15)
    np.testing.assert_allclose(readings, np.deg2rad(expected_deg), rtol=0, atol=1e-14)
    # the last point is the final configuration q_F of Table 5.1 (docs/conventions.md), endpoints inclusive
    np.testing.assert_allclose(np.rad2deg(readings[-1]), [60.0, 80.0, 100.0, 50.0, 200.0, 300.0], rtol=0, atol=1e-12)
    end = np.deg2rad(START_DEG + SWEEP_DEG)
    for i in range(6):
        rows = readings[circle == i + 1]
        np.testing.assert_allclose(rows[0, i], np.deg2rad(START_DEG[i]), atol=1e-15)  # first point: the start
        np.testing.assert_allclose(rows[-1, i], end[i], atol=1e-14)  # last point: start + sweep, inclusive
        # earlier joints rest at their end values, later joints wait at their start, within the circle
        np.testing.assert_allclose(rows[:, :i], np.broadcast_to(end[:i], (len(rows), i)), atol=1e-14)
        np.testing.assert_array_equal(
            rows[:, i + 1 :], np.broadcast_to(np.deg2rad(START_DEG)[i + 1 :], (len(rows), 5 - i))
        )


def test_bidirectional_plan_returns_over_the_same_angles():
    circle, direction, readings = _plan(bidirectional=True).readings()
    assert readings.shape == (270, 6)  # every circle twice
    start = np.deg2rad(START_DEG)
    position = 0
    for i in range(6):
        n = POINTS[i]
        forward = slice(position, position + n)
        back = slice(position + n, position + 2 * n)
        np.testing.assert_array_equal(circle[position : position + 2 * n], i + 1)
        np.testing.assert_array_equal(direction[forward], 1)
        np.testing.assert_array_equal(direction[back], -1)
        # the return sweep visits the same readings in reverse order (exact copies)
        np.testing.assert_array_equal(readings[back], readings[forward][::-1])
        # and ends back at the circle's start, where the joint then rests for the later circles
        np.testing.assert_array_equal(readings[back][-1, i], start[i])
        np.testing.assert_array_equal(readings[forward][:, :i], np.broadcast_to(start[:i], (n, i)))
        position += 2 * n
    np.testing.assert_array_equal(readings[-1], start)  # the whole plan ends where it started


def test_start_matrix_uses_each_row():
    sweep = np.deg2rad([40.0, 30.0, -60.0, 90.0, 120.0, 180.0])
    points = np.array([5, 6, 7, 8, 9, 10])
    plan = _plan(start=np.deg2rad(TABLE_4_2_DEG), sweep=sweep, points=points)
    circle, direction, readings = plan.readings()
    position = 0
    for i in range(6):
        rows = readings[position : position + points[i]]
        expected = np.tile(np.deg2rad(TABLE_4_2_DEG[i]), (points[i], 1))
        expected[:, i] = np.deg2rad(TABLE_4_2_DEG[i, i]) + np.arange(points[i]) * sweep[i] / (points[i] - 1)
        # circle i starts from row i of the matrix and only joint i turns (rounding only)
        np.testing.assert_allclose(rows, expected, rtol=0, atol=1e-14)
        np.testing.assert_array_equal(circle[position : position + points[i]], i + 1)
        position += points[i]
    assert position == readings.shape[0]
    np.testing.assert_array_equal(direction, 1)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"sweep": np.deg2rad([45.0, 80.0, 0.0, 50.0, 200.0, 300.0])}, "circle 3 has a zero sweep; joint J3 must turn"),
        ({"points": np.array([15, 2, 30, 15, 25, 30])}, "circle 2 has 2 points; a circle needs at least 3"),
        ({"points": np.array([15, 20, 30, 15, 25])}, "`points` must be 6 whole numbers"),
        ({"points": np.array([15, 20.5, 30, 15, 25, 30])}, "`points` must be 6 whole numbers"),
        ({"start": np.zeros(5)}, r"`start` must have shape \(6,\) or \(6, 6\); got \(5,\)"),
        ({"start": np.zeros((6, 5))}, r"`start` must have shape \(6,\) or \(6, 6\)"),
        ({"sweep": np.zeros((6, 1))}, "`sweep` must be one angle per joint"),
        ({"start": np.r_[np.nan, np.zeros(5)]}, "`start` contains NaN"),
        ({"sweep": np.r_[np.inf, np.ones(5)]}, "`sweep` contains NaN or infinite"),
        (
            {"reflector": ReflectorMount(frame="joint", positions=np.ones((5, 3)))},
            "5 reflector positions for 6 circles",
        ),
    ],
)
def test_plan_validation(changes, message):
    with pytest.raises(InputError, match=message):
        _plan(**changes)


def test_flange_reflector_plan_and_read_only_arrays():
    plan = _plan(reflector=ReflectorMount(frame="flange", positions=[0.0, 0.0, 50.0]))
    assert plan.n_joints == 6
    with pytest.raises(ValueError, match="read-only"):
        plan.sweep[0] = 1.0


# -- coupled readings (RobotModel.reading_coupling): a circle turns the MODEL joint alone -------------


def _coupled_robot(seed):
    """A 6-joint robot with random signs, offsets and a random coupling (J3 coupled to J2 at least)."""
    rng = np.random.default_rng(seed)
    coupling = rng.uniform(-1.0, 1.0, (6, 6)) * (rng.uniform(size=(6, 6)) < 0.4)
    np.fill_diagonal(coupling, 0.0)
    coupling[2, 1] = -1.0
    return kr5_robot(
        reading_sign=rng.choice([-1.0, 1.0], 6), reading_offset=rng.uniform(-1.0, 1.0, 6), reading_coupling=coupling
    )


@pytest.mark.parametrize("name", ["kuka-kr5-sixx-r650", "kuka-kr5-sixx-r650-krc"])
@pytest.mark.parametrize("bidirectional", [False, True])
@pytest.mark.parametrize("start", ["vector", "matrix"])
def test_uncoupled_robot_gives_the_same_readings_bit_for_bit(name, bidirectional, start):
    starts = {"vector": np.deg2rad(START_DEG), "matrix": np.deg2rad(TABLE_4_2_DEG)}
    plan = _plan(start=starts[start], bidirectional=bidirectional)
    for without, with_robot in zip(plan.readings(), plan.readings(load_robot(name)), strict=True):
        np.testing.assert_array_equal(without, with_robot)


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("bidirectional", [False, True])
@pytest.mark.parametrize("start", ["vector", "matrix"])
def test_coupled_circle_turns_the_model_joint_alone(seed, bidirectional, start):
    robot = _coupled_robot(seed)
    assert robot.is_coupled
    starts = {"vector": np.deg2rad(START_DEG), "matrix": np.deg2rad(TABLE_4_2_DEG)}
    plan = _plan(start=starts[start], bidirectional=bidirectional)
    circle, direction, readings = plan.readings(robot)
    plain_circle, plain_direction, plain = plan.readings()
    np.testing.assert_array_equal(circle, plain_circle)
    np.testing.assert_array_equal(direction, plain_direction)
    q = robot.model_joint_variables(readings)
    # the model variables are solved independently of the plan's arithmetic (numpy's solver)
    q_solved = np.linalg.solve(robot.reading_matrix, readings.T).T + robot.reading_offset
    np.testing.assert_allclose(q, q_solved, rtol=0, atol=1e-12)
    sweep = np.deg2rad(SWEEP_DEG)
    for i in range(6):
        rows = circle == i + 1
        # the plan's reading i is swept exactly as on an uncoupled robot (start and sweep in readings) ...
        if start == "matrix":  # every circle starts from its own row, so reading i matches the plain plan
            np.testing.assert_array_equal(readings[rows, i], plain[rows, i])
        np.testing.assert_allclose(np.ptp(readings[rows, i]), abs(sweep[i]), rtol=0, atol=1e-14)
        # ... model joint i turns by the same angle (|M[i, i]| = 1), every other model joint rests
        # (cond(M) < 10 and angles < 10 rad: rounding ~1e-14 rad)
        others = np.arange(6) != i
        np.testing.assert_allclose(q[rows][:, others] - q[rows][0, others], 0.0, rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.ptp(q[rows, i]), abs(sweep[i]), rtol=0, atol=1e-13)
    if start == "vector":  # the generator sequence: each circle starts where the previous one ended,
        for i in range(1, 6):  # the readings that followed included
            first = np.flatnonzero(circle == i + 1)[0]
            np.testing.assert_array_equal(readings[first], readings[first - 1])


def test_plan_and_robot_must_agree_on_the_joint_count():
    robot = RobotModel(name="planar", nominal=[[0, 0, 300, 0, 0], [0, 0, 200, 0, 0]], hayati=[False, False])
    with pytest.raises(InputError, match="capture plan has 6 circles but robot 'planar' has 2 joints"):
        _plan().readings(robot)
