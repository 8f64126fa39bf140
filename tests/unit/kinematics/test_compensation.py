"""Compensation (issue 22): the calibrated model at the compensated commands lands on the nominal model's tool
frame at the taught ones; Cartesian targets give the same commands; what cannot be reached is named."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import robotcal
from robotcal.errors import InputError
from robotcal.geometry.euler import kuka_abc_from_matrix
from robotcal.io import load_robot
from robotcal.kinematics.compensation import rotation_vector, tool_frames
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ParameterSet

TOOL_MM = [20.0, -10.0, 95.0]


@pytest.fixture(scope="module")
def calibrated():
    robot = load_robot("kuka-kr5-sixx-r650")
    truth = robotcal.perturb(robot, rng=3)
    model = JointModel.build(robot, compliance_joints=[1, 2], masses=robot.masses, harmonic_joints=range(6))
    values = np.r_[5e-5, 2e-4, np.random.default_rng(1).normal(0.0, 2e-4, 12)]
    return truth.replace(joint_model=model.with_values(values))


def _regular_poses(robot, count, seed):
    """Random poses within 80 % of the limits, away from singularities (condition number of the tool Jacobian,
    orientation scaled by 700 mm, below 100)."""
    limits = np.rad2deg(robot.limits)
    poses = np.random.default_rng(seed).uniform(limits[:, 0] * 0.8, limits[:, 1] * 0.8, (4 * count, 6))
    _, jacobian = tool_frames(ParameterSet.nominal(robot), np.deg2rad(poses), np.eye(4))
    condition = np.linalg.cond(jacobian * np.r_[1, 1, 1, 700, 700, 700][:, None])
    return poses[condition < 100][:count]


def test_round_trip_lands_on_the_taught_poses(calibrated):
    """The issue's test: <= 1e-6 mm (and 1e-9 rad) between the calibrated tool at the compensated commands and the
    nominal tool at the taught ones."""
    robot = calibrated.robot
    taught = _regular_poses(robot, 300, seed=0)
    result = robotcal.compensate(calibrated, poses_deg=taught, tool_mm=TOOL_MM)
    tool = np.eye(4)
    tool[:3, 3] = TOOL_MM
    wanted = forward_kinematics(robot.nominal, robot.model_joint_variables(np.deg2rad(taught))) @ tool
    reached = forward_kinematics(calibrated.values, calibrated.model_joint_variables(result.readings)) @ tool
    assert np.abs(reached[:, :3, 3] - wanted[:, :3, 3]).max() <= 1e-6
    assert np.abs(reached[:, :3, :3] - wanted[:, :3, :3]).max() <= 1e-9
    assert result.reached.all() and result.iterations <= 10
    # the commands did change: by about the size of the calibration (a few hundredths of a degree and more)
    assert np.abs(np.rad2deg(result.readings) - taught).max() > 0.01


def test_cartesian_targets_give_the_same_commands(calibrated):
    robot = calibrated.robot
    taught = _regular_poses(robot, 20, seed=1)
    frames = forward_kinematics(robot.nominal, robot.model_joint_variables(np.deg2rad(taught)))
    cartesian = np.c_[frames[:, :3, 3], np.rad2deg(kuka_abc_from_matrix(frames))]
    by_joints = robotcal.compensate(calibrated, poses_deg=taught)
    by_frames = robotcal.compensate(calibrated, cartesian=cartesian, start_deg=taught)
    np.testing.assert_allclose(by_frames.readings, by_joints.readings, rtol=0, atol=1e-9)


def test_unreachable_targets_are_named(calibrated):
    taught = _regular_poses(calibrated.robot, 3, seed=2)
    frames = forward_kinematics(calibrated.robot.nominal, calibrated.robot.model_joint_variables(np.deg2rad(taught)))
    cartesian = np.c_[frames[:, :3, 3], np.rad2deg(kuka_abc_from_matrix(frames))]
    cartesian[1, :3] = [5000.0, 0.0, 0.0]  # 5 m away: beyond the reach of a 650 mm arm
    with pytest.raises(InputError, match=r"cannot reach 1 target\(s\).*pose\(s\) 2\b"):
        robotcal.compensate(calibrated, cartesian=cartesian, start_deg=taught)
    with pytest.raises(InputError, match="one of them"):
        robotcal.compensate(calibrated)


def test_rotation_vector_against_scipy():
    rotations = Rotation.random(200, random_state=7)
    extremes = Rotation.from_rotvec([[np.pi, 0, 0], [0, 0, 1e-9], [0, 0, 0], [0, np.pi - 1e-7, 0]])
    for rotation in (rotations, extremes):
        ours = rotation_vector(rotation.as_matrix())
        theirs = rotation.as_rotvec()
        # the same rotation vector, or at exactly pi its opposite (the same rotation)
        same = np.minimum(np.linalg.norm(ours - theirs, axis=1), np.linalg.norm(ours + theirs, axis=1))
        assert same.max() < 1e-7
