"""Inverse kinematics (issue 28): every branch's closed-form solution lands on the pose (FK(IK(x)) = x), the eight
branches are all the solutions there are (checked against scipy's least squares from random starts), the branch
labels are consistent, and the calibrated model is solved on every branch."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

import robotcal
from robotcal.errors import InputError
from robotcal.io import load_robot
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.inverse import (
    BRANCH_NAMES,
    arm_family,
    branch_of,
    inverse_kinematics,
    nominal_solutions,
    rotation_vector,
    wrap_readings,
)
from robotcal.kinematics.model import ParameterSet, RobotModel

ROBOTS = {
    "kuka-kr5-sixx-r650": "spherical-wrist",
    "kuka-kr5-sixx-r650-krc": "spherical-wrist",  # KUKA reading signs
    "abb-irb120": "spherical-wrist",
    "fanuc-style-coupled": "spherical-wrist",  # J3's reading coupled to J2
    "ur5e": "parallel-wrist",
}


def _random_poses(robot, count, seed):
    limits = np.clip(robot.limits, -np.pi, np.pi)
    return np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], (count, robot.n_joints))


def _pose_error(parameters: ParameterSet, readings, frames):
    """Position [mm] and rotation [deg] between the model's flange at ``readings (P, B, n)`` and ``frames (P, 4, 4)``."""
    count, branches, n = readings.shape
    reached = forward_kinematics(parameters.values, parameters.model_joint_variables(readings.reshape(-1, n)))
    reached = reached.reshape(count, branches, 4, 4)
    position = np.linalg.norm(reached[..., :3, 3] - frames[:, None, :3, 3], axis=-1)
    turn = rotation_vector(reached[..., :3, :3] @ np.swapaxes(frames[:, None, :3, :3], -1, -2))
    return position, np.degrees(np.linalg.norm(turn, axis=-1))


@pytest.mark.parametrize("name", ROBOTS)
def test_every_branch_lands_on_the_pose(name):
    """3,000 random poses per robot: every existing branch solution reproduces the pose to 1e-9 mm and 1e-9 deg
    after one Newton polish (the closed form alone: 2e-9 mm, rounding in arccos near the roots' boundary), and
    the taught readings are always one of the branches."""
    robot = load_robot(name)
    assert arm_family(robot) == ROBOTS[name]
    readings = _random_poses(robot, 3000, seed=1)
    frames = forward_kinematics(robot.nominal, robot.model_joint_variables(readings))
    closed, exists = nominal_solutions(robot, frames, reference=readings)
    position, angle = _pose_error(ParameterSet.nominal(robot), closed, frames)
    assert position[exists].max() < 1e-8 and angle[exists].max() < 1e-8
    assert exists.sum(axis=1).min() >= 2 and exists.mean() > 0.8  # most poses have all eight
    found = np.abs(np.angle(np.exp(1j * (closed - readings[:, None, :])))).max(axis=-1) < 1e-7
    assert found.any(axis=1).all()
    solved = inverse_kinematics(ParameterSet.nominal(robot), frames, reference=readings)
    position, angle = _pose_error(ParameterSet.nominal(robot), solved.readings, frames)
    assert position[exists].max() <= 1e-9 and angle[exists].max() <= 1e-9
    assert solved.reached[exists].all()
    # the branch of each branch's solution is that branch (away from the boundaries where two coincide)
    distinct = exists & (np.sort(np.abs(closed[:, :, None, :] - closed[:, None, :, :]).max(-1), axis=-1)[..., 1] > 1e-3)
    labels = branch_of(robot, closed[distinct])
    assert (labels == np.nonzero(distinct)[1]).all()


@pytest.mark.parametrize("name", ["kuka-kr5-sixx-r650", "ur5e"])
def test_the_eight_branches_are_every_solution(name):
    """An independent search: scipy's least squares from 60 random starts per pose finds no solution that is not one
    of the eight branches (angles compared modulo a turn)."""
    robot = load_robot(name)
    nominal = ParameterSet.nominal(robot)
    rng = np.random.default_rng(4)
    readings = _random_poses(robot, 12, seed=2)
    frames = forward_kinematics(robot.nominal, robot.model_joint_variables(readings))
    closed, exists = nominal_solutions(robot, frames, reference=readings)
    for frame, branches, present in zip(frames, closed, exists, strict=True):
        def residual(r, frame=frame):
            reached = forward_kinematics(nominal.values, robot.model_joint_variables(r[None]))[0]
            return np.r_[frame[:3, 3] - reached[:3, 3], 1e3 * rotation_vector(frame[:3, :3] @ reached[:3, :3].T)]

        for start in rng.uniform(-np.pi, np.pi, (60, 6)):
            solution = least_squares(residual, start, method="lm", xtol=1e-14, ftol=1e-14)
            if np.abs(solution.fun).max() > 1e-6:
                continue  # a local minimum, not a solution
            gap = np.abs(np.angle(np.exp(1j * (branches[present] - solution.x)))).max(axis=-1)
            assert gap.min() < 1e-5


@pytest.mark.parametrize("name", ROBOTS)
def test_calibrated_model_on_every_branch(name):
    """A perturbed model (0.2 mm, 0.05 deg per parameter): Newton from each nominal branch solution reaches the pose
    on the calibrated model to 1e-9 mm wherever the nominal branch exists away from its boundary."""
    robot = load_robot(name)
    calibrated = robotcal.perturb(robot, rng=3)
    readings = _random_poses(robot, 500, seed=3)
    frames = forward_kinematics(robot.nominal, robot.model_joint_variables(readings))
    closed, exists = nominal_solutions(robot, frames, reference=readings)
    solved = inverse_kinematics(calibrated, frames, reference=readings)
    position, angle = _pose_error(calibrated, solved.readings, frames)
    assert position[solved.reached].max() <= 1e-9 and angle[solved.reached].max() <= 1e-9
    assert solved.reached[exists].mean() > 0.97  # the rest: boundary branches the calibrated arm cannot reach
    assert "branch solutions" in repr(solved)


def test_readings_wrap_to_the_reference_and_the_limits():
    robot = load_robot("kuka-kr5-sixx-r650")  # J6 in [-350, 350] deg
    readings = np.deg2rad([[0, 90, 0, 0, 0, 300.0]])
    near = wrap_readings(readings, robot, np.deg2rad([0, 90, 0, 0, 0, -50.0]))
    assert np.rad2deg(near[0, 5]) == pytest.approx(-60.0)
    inside = wrap_readings(np.deg2rad([[0, 90, 0, 0, 0, -20.0]]), robot, np.deg2rad([0, 90, 0, 0, 0, 340.0]))
    assert np.rad2deg(inside[0, 5]) == pytest.approx(340.0)  # -20 + 360, inside +-350
    outside = wrap_readings(np.deg2rad([[0, 90, 0, 0, 0, 0.0]]), robot, np.deg2rad([0, 90, 0, 0, 0, 355.0]))
    assert np.rad2deg(outside[0, 5]) == pytest.approx(0.0)  # 360 is beyond the limit: the turn inside it


def test_arms_without_a_closed_form_are_refused():
    planar = RobotModel(name="planar-6r", nominal=[[0, 0, 100.0, 0, 0]] * 6, hayati=[False] * 6)
    with pytest.raises(InputError, match="planar-6r"):
        arm_family(planar)
    three = RobotModel(name="three", nominal=[[0, 0, 100.0, 0, 0]] * 3, hayati=[False] * 3)
    with pytest.raises(InputError, match="needs 6 joints"):
        arm_family(three)
    assert len(BRANCH_NAMES) == 8 and BRANCH_NAMES[0] == "shoulder A, elbow A, wrist A"


def test_a_free_angle_exists_only_where_its_equation_holds():
    """``a cos phi + b sin phi = c`` with a = b = 0 holds for every phi when c = 0 (a singularity: the angle is free)
    and for none otherwise; with a, b not both 0 its two roots satisfy it."""
    from robotcal.kinematics.inverse import _cos_sin_roots

    roots, exists, free = _cos_sin_roots(np.array([0.0, 0.0, 3.0]), np.array([0.0, 0.0, 4.0]), np.array([0.0, 1.0, 2.5]))
    assert free.tolist() == [True, True, False] and exists.tolist() == [True, False, True]
    assert np.allclose(3.0 * np.cos(roots[2]) + 4.0 * np.sin(roots[2]), 2.5)
