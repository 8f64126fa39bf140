"""Analytic Jacobian of target positions vs central finite differences of the forward kinematics."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.kinematics.forward import target_positions
from robotcal.kinematics.jacobian import target_jacobian
from robotcal.kinematics.model import ReflectorMount
from thesis_data import OFF_AXIS_REFLECTORS_MM, kr5_robot


def _finite_differences(parameters, q, turning, reflector, step=1e-6):
    out = np.zeros(q.shape[:1] + (3,) + parameters.shape)
    for i in range(parameters.shape[0]):
        for k in range(5):
            up, down = parameters.copy(), parameters.copy()
            up[i, k] += step
            down[i, k] -= step
            out[:, :, i, k] = (
                target_positions(up, q, turning, reflector) - target_positions(down, q, turning, reflector)
            ) / (2 * step)
    return out


@pytest.mark.parametrize(
    "reflector",
    [
        ReflectorMount(frame="flange", positions=[60.0, 40.0, 30.0]),
        ReflectorMount(frame="joint", positions=OFF_AXIS_REFLECTORS_MM),
    ],
    ids=["flange", "per-joint"],
)
def test_jacobian_matches_central_differences(reflector):
    rng = np.random.default_rng(7)
    robot = kr5_robot()
    # a perturbed robot with beta on every joint: the formula must hold off the nominal structure too
    parameters = robot.nominal + rng.normal(0.0, 0.02, robot.nominal.shape)
    q = rng.uniform(-np.pi, np.pi, (9, 6))
    turning = rng.integers(0, 6, 9)
    points, jacobian = target_jacobian(parameters, q, turning, reflector)
    np.testing.assert_allclose(points, target_positions(parameters, q, turning, reflector), atol=1e-9)
    # central differences with h = 1e-6: truncation ~h^2 * |p| ~ 1e-9 mm, rounding ~eps |p| / h ~ 2e-7 mm
    np.testing.assert_allclose(jacobian, _finite_differences(parameters, q, turning, reflector), atol=2e-6)


@pytest.mark.parametrize(
    "reflector",
    [
        ReflectorMount(frame="flange", positions=[60.0, 40.0, 30.0]),
        ReflectorMount(frame="joint", positions=OFF_AXIS_REFLECTORS_MM),
    ],
    ids=["flange", "per-joint"],
)
def test_joint_variable_derivatives_and_stacks(reflector):
    """``d p / d q`` against central differences in q (the turning joint of a per-joint target included), and a
    stack of parameter sets with their own joint variables against one set at a time (the Monte Carlo's use)."""
    rng = np.random.default_rng(8)
    robot = kr5_robot()
    stack = robot.nominal + rng.normal(0.0, 0.02, (3,) + robot.nominal.shape)
    q = rng.uniform(-np.pi, np.pi, (3, 7, 6))
    turning = rng.integers(0, 6, 7)
    points, jacobian, joint_jacobian = target_jacobian(stack, q, turning, reflector, joint_variables=True)
    assert joint_jacobian.shape == (3, 7, 3, 6)
    step = 1e-6
    for b in range(3):
        one_points, one_jacobian = target_jacobian(stack[b], q[b], turning, reflector)
        np.testing.assert_allclose(points[b], one_points, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jacobian[b], one_jacobian, rtol=0, atol=1e-12)
        for j in range(6):
            up, down = q[b].copy(), q[b].copy()
            up[:, j] += step
            down[:, j] -= step
            numeric = (target_positions(stack[b], up, turning, reflector) - target_positions(stack[b], down, turning, reflector)) / (2 * step)
            # the same bound as above: rounding ~eps |p| / h ~ 2e-7 mm
            np.testing.assert_allclose(joint_jacobian[b, :, :, j], numeric, atol=2e-6)


def test_per_joint_target_does_not_depend_on_its_own_or_later_joints():
    robot = kr5_robot()
    reflector = ReflectorMount(frame="joint", positions=OFF_AXIS_REFLECTORS_MM)
    q = np.zeros((6, 6))
    _, jacobian = target_jacobian(robot.nominal, q, np.arange(6), reflector)
    for point in range(6):
        assert np.all(jacobian[point, :, point:, :] == 0.0)
        assert np.any(jacobian[point, :, :point, :] != 0.0) or point == 0


def test_jacobian_rejects_bad_inputs():
    robot = kr5_robot()
    reflector = ReflectorMount(frame="joint", positions=OFF_AXIS_REFLECTORS_MM)
    with pytest.raises(InputError, match="a set of shape"):
        target_jacobian(np.zeros(5), np.zeros((1, 6)), [0], reflector)
    with pytest.raises(InputError, match="joint variables"):
        target_jacobian(np.zeros((2, 6, 5)), np.full((2, 1, 6), np.nan), [0], reflector)
    with pytest.raises(InputError, match="turning_joint"):
        target_jacobian(robot.nominal, np.zeros((2, 6)), [0, 6], reflector)
