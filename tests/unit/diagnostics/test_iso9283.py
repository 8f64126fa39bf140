"""ISO 9283 characteristics against hand-computed values, test-pose geometry, the plan's IK, a
simulated study with the joint error model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotcal.diagnostics.iso9283 import (
    iso_cube_corners,
    iso_plan_readings,
    iso_test_positions,
    pose_characteristics,
    simulate_attained_positions,
)
from robotcal.errors import InputError
from robotcal.io import load_robot
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.generator import JointErrorModel

# Small fixed data set: 3 cycles, 2 test poses.
COMMANDED = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]
ATTAINED = [
    [[1.0, 0.0, 0.0], [12.0, 0.0, 0.0]],
    [[3.0, 0.0, 0.0], [12.0, 0.0, 0.0]],
    [[2.0, 3.0, 0.0], [12.0, 0.0, 0.0]],
]


def test_characteristics_match_hand_computed_values():
    r = pose_characteristics(ATTAINED, COMMANDED, distance_pair=(0, 1))
    # P1: barycentre (1+3+2, 0+0+3, 0)/3 = (2, 1, 0); AP = (2, 1, 0), |AP| = sqrt(5) = 2.2360680
    np.testing.assert_allclose(r.barycentre[0], [2.0, 1.0, 0.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(r.ap_xyz[0], [2.0, 1.0, 0.0], rtol=0, atol=1e-15)
    assert r.ap[0] == pytest.approx(2.2360679775, abs=1e-10)
    # l_j = |(-1,-1,0)|, |(1,-1,0)|, |(0,2,0)| = 1.4142136, 1.4142136, 2; l_bar = 1.6094757
    # deviations -(2 - sqrt 2)/3 (twice), +2 (2 - sqrt 2)/3; sum of squares 6 (2 - sqrt 2)^2 / 9 = 0.2287638
    # S_l = sqrt(0.2287638 / 2) = (2 - sqrt 2) / sqrt 3 = 0.3382040; RP = 1.6094757 + 3 x 0.3382040 = 2.6240876
    assert r.l_bar[0] == pytest.approx(1.6094757082, abs=1e-10)
    assert r.s_l[0] == pytest.approx(0.3382039575, abs=1e-10)
    assert r.rp[0] == pytest.approx(2.6240875806, abs=1e-9)
    # P2: every cycle at (12, 0, 0): AP = 2, RP = 0
    assert r.ap[1] == pytest.approx(2.0, abs=1e-15) and r.rp[1] == pytest.approx(0.0, abs=1e-15)
    # distances P1-P2: 11, 9, |(10,-3,0)| = 10.4403065; D_bar = 10.1467688; D_c = 10 -> AD = 0.1467688
    # deviations 0.8532312, -1.1467688, 0.2935377; squares 0.7280034 + 1.3150788 + 0.0861644 = 2.1292466
    # S_D = sqrt(2.1292466 / 2) = 1.0318058; RD = 3 S_D = 3.0954175
    assert r.ad == pytest.approx(0.1467688, abs=1e-7)
    assert r.rd == pytest.approx(3.0954175, abs=1e-7)


def test_characteristics_are_invariant_to_cycle_order_and_validate():
    shuffled = np.asarray(ATTAINED)[[2, 0, 1]]
    a = pose_characteristics(ATTAINED, COMMANDED, distance_pair=(0, 1))
    b = pose_characteristics(shuffled, COMMANDED, distance_pair=(0, 1))
    np.testing.assert_allclose([a.ap, a.rp], [b.ap, b.rp], rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="n_cycles >= 2"):
        pose_characteristics(np.zeros((1, 5, 3)), np.zeros((5, 3)))
    with pytest.raises(InputError, match="distance_pair"):
        pose_characteristics(ATTAINED, COMMANDED, distance_pair=(1, 3))


def test_test_positions_on_the_diagonal_plane():
    side = 200.0
    centre = np.array([400.0, 50.0, 300.0])
    p = iso_test_positions(centre, side)
    corners = iso_cube_corners(centre, side)
    np.testing.assert_allclose(p[0], centre, rtol=0, atol=1e-12)
    # 10 % of the diagonal (the cube's space diagonal, side sqrt 3 = 346.41 mm) from each corner: 34.641 mm
    np.testing.assert_allclose(np.linalg.norm(p[1:] - corners, axis=1), 0.1 * side * math.sqrt(3), rtol=1e-12)
    # the plane C1-C2-C7-C8 is y - z = const through the centre
    np.testing.assert_allclose((p[:, 1] - p[:, 2]) - (centre[1] - centre[2]), 0.0, rtol=0, atol=1e-12)


def _study_setup():
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    nominal = ParameterSet.nominal(robot)
    start = np.radians([0.0, -90.0, 90.0, 0.0, 45.0, 0.0])
    target = np.array([60.0, 40.0, 30.0])
    frame = forward_kinematics(nominal.values, robot.model_joint_variables(start))[0]
    centre = frame[:3, :3] @ target + frame[:3, 3]
    positions = iso_test_positions(centre, 150.0)
    readings = iso_plan_readings(nominal, positions, start, target=target, n_cycles=4)
    return robot, nominal, start, target, positions, readings


def test_plan_readings_reach_the_test_positions_with_the_start_orientation():
    robot, nominal, start, target, positions, readings = _study_setup()
    assert readings.shape == (20, 6)
    np.testing.assert_array_equal(readings[:5], readings[15:])  # cycles repeat the same commands
    frames = forward_kinematics(nominal.values, robot.model_joint_variables(readings[:5]))
    reached = frames[:, :3, :3] @ target + frames[:, :3, 3]
    np.testing.assert_allclose(reached, positions, rtol=0, atol=1e-8)  # IK stops at 1e-9 mm
    start_rotation = forward_kinematics(nominal.values, robot.model_joint_variables(start))[0, :3, :3]
    np.testing.assert_allclose(frames[:, :3, :3], np.broadcast_to(start_rotation, (5, 3, 3)), atol=1e-11)


def test_simulated_study_with_joint_errors():
    robot, nominal, _, target, positions, readings = _study_setup()
    # no joint error: the model's own robot attains the commands exactly
    exact = simulate_attained_positions(nominal, readings, target=target).reshape(4, 5, 3)
    r = pose_characteristics(exact, positions)
    np.testing.assert_allclose([r.ap.max(), r.rp.max(), abs(r.ad), r.rd], 0.0, rtol=0, atol=1e-8)
    # joint errors: random part only (0.01 mm, 20 urad per term) -> repeatability > 0, of that order
    sd = np.tile([0.01, 0.01, 0.01, 2e-5, 2e-5], (6, 1))
    errors = JointErrorModel(
        amplitude=np.zeros((6, 5)), period=np.full((6, 5), 2 * np.pi), phase=np.zeros((6, 5)), noise_sd=sd
    )
    noisy = simulate_attained_positions(nominal, readings, target=target, joint_errors=errors, rng=3).reshape(4, 5, 3)
    r = pose_characteristics(noisy, positions)
    assert np.all(r.rp > 0.005) and np.all(r.rp < 1.0)
