"""Capture plans (thesis 5.2.1, Table 5.1; Table 4.2 start matrices): the visited readings."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.kinematics import ReflectorMount
from robotcal.simulation import CapturePlan
from thesis_data import TABLE_4_2_DEG, TABLE_5_1_POINTS, TABLE_5_1_START_DEG, TABLE_5_1_SWEEP_DEG

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
