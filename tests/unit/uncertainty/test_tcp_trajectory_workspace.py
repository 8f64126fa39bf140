"""Pose CSV (trajectories), the built-in 75-pose trajectory, and the workspace map."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io import load_robot
from robotcal.io.formats.trajectory_csv import builtin_trajectories, load_trajectory, read_trajectory, write_trajectory
from robotcal.kinematics import RobotModel
from robotcal.uncertainty.tcp import propagate_to_tcp
from robotcal.uncertainty.workspace import PERCENTILES, sample_workspace, workspace_uncertainty

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")


def _draws(n_draws=200, seed=0):
    rng = np.random.default_rng(seed)
    free = ~ROBOT.structurally_fixed
    scale = np.where(np.isin(np.arange(5), [1, 3, 4]), 2e-4, 0.05)
    return ROBOT.nominal + rng.standard_normal((n_draws, 6, 5)) * scale * free


def test_trajectory_round_trip(tmp_path):
    readings = np.deg2rad(np.random.default_rng(1).uniform(-100, 100, (12, 6)))
    path = write_trajectory(tmp_path / "t.csv", readings, comment="a test path")
    # 9 decimals in degrees: 5e-10 deg
    np.testing.assert_allclose(read_trajectory(path, n_joints=6), readings, rtol=0, atol=1e-11)


def test_builtin_trajectory_follows_its_documented_definition():
    assert "kr5-sweep-75" in builtin_trajectories()
    readings, _ = load_trajectory("kr5-sweep-75", n_joints=6)
    s = np.linspace(0.0, 1.0, 75)
    expected = np.column_stack(
        [
            -45 + 90 * s,
            -80 + 15 * np.sin(2 * np.pi * s),
            100 - 25 * np.sin(np.pi * s),
            30 * np.sin(2 * np.pi * s),
            50 + 20 * np.cos(2 * np.pi * s),
            -90 + 180 * s,
        ]
    )
    np.testing.assert_allclose(np.rad2deg(readings), expected, rtol=0, atol=1e-8)
    assert np.all((readings >= ROBOT.limits[:, 0]) & (readings <= ROBOT.limits[:, 1]))


def test_extra_columns_and_comments_are_allowed(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("# my path\nname,q1,q2,q3,q4,q5,q6,pose\nstart,1,2,3,4,5,6,7\n\nend,0,0,0,0,0,0,8\n")
    np.testing.assert_allclose(np.rad2deg(read_trajectory(path, n_joints=6)), [[1, 2, 3, 4, 5, 6], [0] * 6])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "pose,q1,q2,q3,q4,q5,q6\n1,0,0,nan,0,0,0\n",
            r"t\.csv: line 2 \(pose 1\), column `q3`: 'nan' is not a finite number",
        ),
        ("q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0\n0,0,x,0,0,0\n", r"line 3 \(pose 2\), column `q3`: 'x' is not a number"),
        ("q1,q2,q3,q4,q5,q6\n0,0,0,0,0\n", r"line 2 \(pose 1\) has 5 fields; the header has 6"),
        ("q1,q2,q3,q4,q5\n0,0,0,0,0\n", r"5 joint columns \(q1..q5\) but the robot has 6 joints"),
        ("q1,q2,q4,q5,q6,q7\n0,0,0,0,0,0\n", r"header needs joint columns q1..qN; missing q3"),
        ("pose,a,b\n1,2,3\n", r"header needs joint columns q1..qN"),
        ("q1,q2,q3,q4,q5,q6\n", r"no poses after the header"),
        ("", r"empty file"),
    ],
)
def test_bad_trajectory_files_name_file_line_and_column(tmp_path, text, message):
    path = tmp_path / "t.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        read_trajectory(path, n_joints=6)


def test_unknown_trajectory_is_an_input_error():
    with pytest.raises(InputError, match=r"unknown trajectory 'nope'"):
        load_trajectory("nope")


def test_75_pose_trajectory_per_pose_statistics():
    readings, _ = load_trajectory("kr5-sweep-75", n_joints=6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # inside the limits: no warning
        result = propagate_to_tcp(ROBOT, _draws(), readings)
    assert result.n_poses == 75
    np.testing.assert_array_equal(result.value_range, result.summary.maximum - result.summary.minimum)
    assert np.all(result.value_range >= 2 * result.std_uncertainty)  # range of 200 draws spans > 2 u
    np.testing.assert_allclose(
        result.position_uncertainty, np.sqrt(np.sum(result.std_uncertainty[:, :3] ** 2, axis=1)), rtol=1e-10
    )


def test_workspace_sample_is_seeded_and_within_the_limits():
    first = sample_workspace(ROBOT, 500, rng=4)
    np.testing.assert_array_equal(first, sample_workspace(ROBOT, 500, rng=4))
    assert np.all((first >= ROBOT.limits[:, 0]) & (first <= ROBOT.limits[:, 1]))


def test_workspace_percentiles_summarise_the_per_pose_uncertainty():
    result = workspace_uncertainty(ROBOT, _draws(100), 40, rng=2)
    assert result.seed == 2 and result.tcp.n_poses == 40
    np.testing.assert_allclose(
        result.position_uncertainty_percentiles, np.percentile(result.position_uncertainty, PERCENTILES)
    )
    np.testing.assert_allclose(result.max_semi_axis_percentiles, np.percentile(result.max_semi_axis, PERCENTILES))
    assert result.position_uncertainty_percentiles[0] == result.position_uncertainty.min()
    assert np.all(np.diff(result.std_uncertainty_percentiles, axis=0) >= 0)


def test_workspace_needs_finite_limits_and_a_pose_count():
    unlimited = RobotModel(name="free", nominal=ROBOT.nominal, hayati=ROBOT.hayati)
    with pytest.raises(InputError, match=r"without finite `limits_deg`"):
        sample_workspace(unlimited, 10)
    with pytest.raises(InputError, match=r"`n_poses` must be a positive integer"):
        sample_workspace(ROBOT, 0)
    with pytest.raises(InputError, match=r"either `n_poses`"):
        workspace_uncertainty(ROBOT, _draws(20))
