"""Random validation poses, captures at free poses, the thesis test-2 plan and the perturbed truth."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.instruments import Instrument
from robotcal.kinematics.forward import target_positions
from robotcal.kinematics.model import ParameterSet, ReflectorMount
from robotcal.simulation.perturb import perturb_parameters, perturbable_mask
from robotcal.simulation.poses import random_poses, simulate_poses, thesis_test2_plan
from thesis_data import kr5_robot

FLANGE = ReflectorMount(frame="flange", positions=[60.0, 40.0, 30.0])


def _limited_robot():
    return kr5_robot(limits=np.deg2rad([[-170, 170], [-45, 190], [-166, 119], [-190, 190], [-120, 120], [-350, 350]]))


def test_random_poses_are_seeded_and_within_limits_less_margin():
    robot = _limited_robot()
    poses = random_poses(robot, 500, margin_deg=5.0, rng=3)
    assert poses.shape == (500, 6)
    np.testing.assert_array_equal(poses, random_poses(robot, 500, margin_deg=5.0, rng=3))
    assert np.all(poses >= robot.limits[:, 0] + np.deg2rad(5.0) - 1e-12)
    assert np.all(poses <= robot.limits[:, 1] - np.deg2rad(5.0) + 1e-12)


def test_random_poses_respect_the_floor():
    robot = _limited_robot()
    poses = random_poses(robot, 50, min_height_mm=200.0, reflector=FLANGE, rng=1)
    heights = target_positions(robot.nominal, robot.model_joint_variables(poses), np.zeros(50, int), FLANGE)[:, 2]
    assert np.all(heights >= 200.0)


def test_random_poses_validation():
    with pytest.raises(InputError, match="unbounded joint limits"):
        random_poses(kr5_robot(), 3)
    with pytest.raises(InputError, match="n_poses"):
        random_poses(_limited_robot(), 0)
    with pytest.raises(InputError, match="n_poses"):
        random_poses(_limited_robot(), True)  # a bool is not a count
    with pytest.raises(InputError, match="n_poses"):
        random_poses(_limited_robot(), np.True_)
    with pytest.raises(InputError, match="leaves no range"):
        random_poses(_limited_robot(), 3, margin_deg=200.0)


def test_simulate_poses_gives_circle_zero_capture_of_the_true_robot():
    robot = _limited_robot()
    truth = perturb_parameters(robot, length_sd_mm=0.5, angle_sd_deg=0.1, rng=2)
    readings = random_poses(robot, 20, rng=4)
    tracker = np.eye(4)
    tracker[:3, 3] = [1000.0, 0.0, 0.0]
    noise_free = Instrument(name="exact", a_mm=0.0, b_mm_per_m=0.0)
    capture, exact = simulate_poses(robot, readings, FLANGE, noise_free, tracker, true_parameters=truth, rng=0)
    assert np.all(capture.circle == 0) and np.all(capture.direction == 1)
    expected = target_positions(truth.values, robot.model_joint_variables(readings), np.zeros(20, int), FLANGE)
    np.testing.assert_allclose(capture.points, expected + [1000.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_array_equal(capture.points, exact)
    with pytest.raises(InputError, match="flange reflector"):
        simulate_poses(robot, readings, ReflectorMount(frame="joint", positions=np.zeros((6, 3))), noise_free, tracker)


def test_thesis_test2_plan_has_580_points_in_table_4_1_ranges():
    plan = thesis_test2_plan()
    circle, direction, readings = plan.readings()
    assert circle.size == 580  # Table 4.4: "Total de puntos capturados = 580"
    first = readings[(circle == 1) & (direction == 1)]
    np.testing.assert_allclose(np.rad2deg(first[[0, -1], 0]), [167.0, -167.0])
    np.testing.assert_allclose(np.rad2deg(first[0, 1:]), [-90.0, 90.0, 0.0, -90.0, 0.0])  # Table 4.2 row 1


def test_perturbation_touches_only_identifiable_parameters():
    robot = kr5_robot()
    truth = perturb_parameters(robot, length_sd_mm=0.3, angle_sd_deg=0.05, rng=1)
    changed = truth.values != robot.nominal
    mask = perturbable_mask(robot)
    assert not np.any(changed & ~mask)
    assert mask.sum() == 18  # 20 CPA-identifiable (docs/conventions.md) less the base gauge d1, theta1
    assert not mask[-1].any() and not mask[0, :2].any()
    assert perturbable_mask(robot, include_base=True).sum() == 20
    np.testing.assert_array_equal(
        truth.values, perturb_parameters(robot, length_sd_mm=0.3, angle_sd_deg=0.05, rng=1).values
    )
    assert isinstance(truth, ParameterSet)
    with pytest.raises(InputError, match="length_sd_mm"):
        perturb_parameters(robot, length_sd_mm=-1.0, angle_sd_deg=0.0)
