"""TCP propagation of an extended model's draws (issue 22): each draw turns the joints by its own deflection.
Checked against forward kinematics draw by draw (the independent truth), and the linearised propagation against
the Monte Carlo for a small spread."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.geometry.euler import kuka_abc_from_matrix, wrap_angle_near
from robotcal.io import load_robot
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ParameterSet
from robotcal.uncertainty.tcp import position_covariance, propagate_to_tcp

TOOL = np.array([15.0, -25.0, 110.0])


@pytest.fixture(scope="module")
def draws():
    robot = load_robot("kuka-kr5-sixx-r650")
    model = JointModel.build(robot, compliance_joints=[1, 2], masses=robot.masses, harmonic_joints=range(6))
    rng = np.random.default_rng(12)
    n_draws = 400
    values = robot.nominal + rng.normal(0.0, 1e-3, (n_draws, 6, 5)) * ~robot.structurally_fixed
    centre = np.r_[1e-5, 4e-5, np.full(12, 1e-4)]
    extras = centre + rng.normal(0.0, 1.0, (n_draws, model.size)) * np.r_[2e-6, 5e-6, np.full(12, 2e-5)]
    readings = np.deg2rad([[10.0, 40.0, 30.0, 5.0, 45.0, 20.0], [-60.0, 10.0, -20.0, 90.0, -30.0, 150.0]])
    return robot, model, values, extras, readings


def _brute_force(robot, model, values, extras, readings):
    """X, Y, Z, A, B, C of every draw at every pose through ParameterSet.model_joint_variables: (M, P, 6)."""
    out = np.empty((values.shape[0], readings.shape[0], 6))
    tool = np.eye(4)
    tool[:3, 3] = TOOL
    for k in range(values.shape[0]):
        draw = ParameterSet(robot=robot, values=values[k], joint_model=model.with_values(extras[k]))
        frames = forward_kinematics(values[k], draw.model_joint_variables(readings)) @ tool
        out[k, :, :3] = frames[:, :3, 3]
        out[k, :, 3:] = kuka_abc_from_matrix(frames)
    return out


def test_extended_draws_against_forward_kinematics(draws):
    robot, model, values, extras, readings = draws
    result = propagate_to_tcp(
        robot, values, readings, tool=TOOL, keep_draws=True, joint_model=model, extra_draws=extras, batch_size=64
    )
    expected = _brute_force(robot, model, values, extras, readings)
    expected[..., 3:] = wrap_angle_near(expected[..., 3:], result.draws[..., 3:])
    # the same products in another order: rounding of coordinates ~700 mm and of angles
    np.testing.assert_allclose(result.draws[..., :3], expected[..., :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(result.draws[..., 3:], expected[..., 3:], rtol=0, atol=1e-12)
    covariance = position_covariance(robot, values, readings, tool=TOOL, joint_model=model, extra_draws=extras)
    centred = expected[..., :3] - expected[..., :3].mean(axis=0)
    np.testing.assert_allclose(
        covariance, np.einsum("mpi,mpj->pij", centred, centred) / (values.shape[0] - 1), rtol=1e-9, atol=0
    )
    # the deflection matters: without it the coordinates move by ~0.3 mm (the sag of the mean compliance)
    geometric = propagate_to_tcp(robot, values, readings, tool=TOOL)
    assert np.abs(geometric.summary.mean[:, :3] - result.summary.mean[:, :3]).max() > 0.05


def test_linearised_extended_propagation_matches_the_monte_carlo(draws):
    """For draws of small spread the law of propagation (joint-model columns included) equals the sample
    covariance to first order: within 3 % (the second-order terms are ~1e-3 relative; the sampling noise of a
    covariance of 400 draws is not involved, both come from the same draws)."""
    robot, model, values, extras, readings = draws
    result = propagate_to_tcp(robot, values, readings, tool=TOOL, joint_model=model, extra_draws=extras)
    u_mc = np.sqrt(np.diagonal(result.covariance[:, :3, :3], axis1=1, axis2=2))
    u_lpu = np.sqrt(np.diagonal(result.lpu_covariance[:, :3, :3], axis1=1, axis2=2))
    np.testing.assert_allclose(u_lpu, u_mc, rtol=0.03)
    with pytest.raises(Exception, match="extra_draws"):
        propagate_to_tcp(robot, values, readings, joint_model=model, extra_draws=extras[:, :3])
