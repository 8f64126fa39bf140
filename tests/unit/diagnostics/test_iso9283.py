"""ISO 9283 characteristics against hand-computed values (positions and orientations), test-pose
geometry, the plan's IK, the targets' registration, a simulated study with the joint error model."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from robotcal.capture import Capture
from robotcal.diagnostics.iso9283 import (
    IsoModel,
    iso_cube_corners,
    iso_from_capture,
    iso_plan_readings,
    iso_test_positions,
    orientation_deviations,
    pose_characteristics,
    pose_visits,
    register_flange_poses,
    scenario_flange_point,
    simulate_attained_positions,
    simulate_iso_study,
)
from robotcal.errors import InputError
from robotcal.geometry.transforms import apply_transform, rot_x, rot_y, rot_z, rotation_about_line
from robotcal.io import load_robot, load_scenario
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


# --- orientation -------------------------------------------------------------------------------------

DEG = math.pi / 180.0


def _r(matrix):
    return np.asarray(matrix)[:3, :3]


def test_orientation_characteristics_match_hand_computed_values():
    # P1 commanded identity, attained Rx(0.1 deg), Rx(0.3 deg), Ry(0.3 deg): the rotation vectors are
    # (0.1, 0, 0), (0.3, 0, 0), (0, 0.3, 0) deg exactly.
    # P2 commanded Rz(90 deg), attained Rz(90) Rx(0.2 deg) every cycle: a turn of 0.2 deg about the commanded
    # flange x axis, which is the base y axis: base axes (0, 0.2, 0), flange axes (0.2, 0, 0); RP = 0.
    commanded_rotations = np.array([np.eye(3), _r(rot_z(90 * DEG))])
    p2 = _r(rot_z(90 * DEG)) @ _r(rot_x(0.2 * DEG))
    attained_rotations = np.array(
        [[_r(rot_x(0.1 * DEG)), p2], [_r(rot_x(0.3 * DEG)), p2], [_r(rot_y(0.3 * DEG)), p2]]
    )
    r = pose_characteristics(
        ATTAINED, COMMANDED, distance_pair=(0, 1),
        attained_rotations=attained_rotations, commanded_rotations=commanded_rotations,
    )  # fmt: skip
    assert r.has_orientation and r.orientation_axes == "base"
    # a: 0.1, 0.3, 0 -> APa = 0.4 / 3 = 0.1333333; deviations -0.0333333, 0.1666667, -0.1333333
    # squares 0.0011111 + 0.0277778 + 0.0177778 = 0.0466667; S_a = sqrt(0.0466667 / 2) = 0.1527525; RPa = 0.4582576
    # b: 0, 0, 0.3 -> APb = 0.1; deviations -0.1, -0.1, 0.2; squares sum 0.06; S_b = sqrt(0.03) = 0.1732051
    # RPb = 0.5196152; c: all 0
    np.testing.assert_allclose(np.rad2deg(r.ap_abc[0]), [0.4 / 3, 0.1, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.rad2deg(r.s_abc[0]), [0.1527525232, 0.1732050808, 0.0], rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.rad2deg(r.rp_abc[0]), [0.4582575695, 0.5196152423, 0.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(r.ap_abc[1]), [0.0, 0.2, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.rp_abc[1], 0.0, rtol=0, atol=1e-15)
    # the positions are those of the position-only call
    plain = pose_characteristics(ATTAINED, COMMANDED, distance_pair=(0, 1))
    np.testing.assert_array_equal(r.ap, plain.ap)
    assert plain.ap_abc is None and not plain.has_orientation
    # about the commanded flange axes: P2's turn is about flange x; P1's commanded is identity (same as base)
    f = pose_characteristics(
        ATTAINED, COMMANDED, distance_pair=(0, 1), attained_rotations=attained_rotations,
        commanded_rotations=commanded_rotations, orientation_axes="flange",
    )  # fmt: skip
    np.testing.assert_allclose(np.rad2deg(f.ap_abc[1]), [0.2, 0.0, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(f.ap_abc[0], r.ap_abc[0], rtol=0, atol=1e-15)
    with pytest.raises(InputError, match="both"):
        pose_characteristics(ATTAINED, COMMANDED, distance_pair=(0, 1), attained_rotations=attained_rotations)
    with pytest.raises(InputError, match="orientation axes"):
        orientation_deviations(attained_rotations, commanded_rotations, axes="tool")


def test_known_small_rotation_of_a_known_pose_is_recovered_through_the_targets():
    """Closed form: every attained flange pose is the commanded one turned by a known rotation about a
    known axis through a known point, and measured on three targets; APa/b/c are that rotation vector."""
    robot = load_robot("kuka-kr5-sixx-r650")
    nominal = ParameterSet.nominal(robot)
    readings = np.radians([[10.0, 80.0, -80.0, 20.0, 40.0, 30.0], [-20.0, 70.0, -60.0, -30.0, 50.0, -40.0]])
    commanded = forward_kinematics(nominal.values, robot.model_joint_variables(readings))  # P1, P2
    axis = np.array([1.0, -2.0, 2.0]) / 3.0
    angle = 0.05 * DEG
    turn = rotation_about_line(axis, [500.0, 100.0, 400.0], angle)  # in the base frame
    offsets = np.array([[60.0, 40.0, 30.0], [-50.0, 30.0, 20.0], [0.0, -60.0, 40.0]])
    attained = turn @ commanded
    points = np.einsum("pij,tj->pti", attained[:, :3, :3], offsets) + attained[:, None, :3, 3]  # (2 poses, 3, 3)
    tracker_from_base = rot_z(0.3) @ rot_x(0.1)
    tracker_from_base[:3, 3] = [1800.0, -20.0, 600.0]
    n_cycles = 3
    rows = np.tile(points, (n_cycles, 1, 1)).reshape(-1, 3)
    capture = Capture(
        circle=np.zeros(rows.shape[0], int), direction=np.ones(rows.shape[0], int),
        readings=np.repeat(np.tile(readings, (n_cycles, 1)), 3, axis=0),
        points=apply_transform(tracker_from_base, rows), target=np.tile([0, 1, 2], 2 * n_cycles),
        target_names=("a", "b", "c"),
    )  # fmt: skip
    targets = dict(zip("abc", offsets, strict=True))
    model = IsoModel(parameters=nominal, tracker_from_base=tracker_from_base)
    r = iso_from_capture(capture, {"nominal": model}, targets=targets, n_test_poses=2, distance_pair=(0, 1))["nominal"]
    np.testing.assert_allclose(r.ap_abc, np.tile(angle * axis, (2, 1)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.rp_abc, 0.0, rtol=0, atol=1e-12)
    # about the commanded flange axes: R_c^T v
    f = iso_from_capture(
        capture, {"nominal": model}, targets=targets, n_test_poses=2, distance_pair=(0, 1), orientation_axes="flange"
    )["nominal"]
    expected = np.einsum("pji,j->pi", commanded[:, :3, :3], angle * axis)
    np.testing.assert_allclose(f.ap_abc, expected, rtol=0, atol=1e-12)
    # position of the targets' centroid: moved by the turn about the line
    centroid = offsets.mean(axis=0)
    moved = apply_transform(attained, centroid) - apply_transform(commanded, centroid)
    np.testing.assert_allclose(r.ap_xyz, moved, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.registration_rms, 0.0, rtol=0, atol=1e-9)
    # a given flange point instead of the centroid
    point = np.array([0.0, 0.0, 150.0])
    g = iso_from_capture(capture, {"m": model}, point=point, targets=targets, n_test_poses=2, distance_pair=(0, 1))
    moved = apply_transform(attained, point) - apply_transform(commanded, point)
    np.testing.assert_allclose(g["m"].ap_xyz, moved, rtol=0, atol=1e-9)
    # a model's own offsets win over the given ones: wrong offsets show in the registration's RMS
    wrong = IsoModel(parameters=nominal, tracker_from_base=tracker_from_base, target_offsets={"a": [70.0, 40.0, 30.0]})
    w = iso_from_capture(capture, {"w": wrong}, targets=targets, n_test_poses=2, distance_pair=(0, 1))["w"]
    assert np.all(w.registration_rms > 1.0)
    # a model with neither its own offsets nor given ones: the error names the model and the ways out
    with pytest.raises(InputError, match=r"model 'nominal' has no flange offset for target 'b'.*--targets-mm.*--no-nominal"):
        iso_from_capture(capture, {"nominal": model}, targets={"a": offsets[0]}, n_test_poses=2, distance_pair=(0, 1))


def test_registration_of_flange_poses_and_its_errors():
    frame = rot_z(0.4) @ rot_y(-0.2) @ rot_x(1.1)
    frame[:3, 3] = [300.0, -40.0, 500.0]
    offsets = np.array([[60.0, 40.0, 30.0], [-50.0, 30.0, 20.0], [0.0, -60.0, 40.0], [10.0, 10.0, 90.0]])
    points = apply_transform(frame, offsets)
    transforms, rms = register_flange_poses(offsets, np.stack([points, points]))
    np.testing.assert_allclose(transforms, np.stack([frame, frame]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rms, 0.0, rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="collinear"):
        register_flange_poses([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]], points[:3])
    with pytest.raises(InputError, match=">= 3"):
        register_flange_poses(offsets[:2], points[:2])


def test_pose_visits_and_incomplete_visits():
    readings = np.repeat(np.radians([[0.0] * 6, [10.0] * 6, [10.0] * 6]), 2, axis=0)
    # visits: rows 0-1 (a, b), rows 2-3 (a, b; readings changed), rows 4-5 (a repeats: new visit at the same readings)
    capture = Capture(
        circle=np.zeros(6, int), direction=np.ones(6, int), readings=readings, points=np.zeros((6, 3)),
        target=[0, 1, 0, 1, 0, 1], target_names=("a", "b"),
    )  # fmt: skip
    np.testing.assert_array_equal(pose_visits(capture), [0, 0, 1, 1, 2, 2])
    with pytest.raises(InputError, match="three or more"):
        iso_from_capture(capture, {}, targets={"a": [0, 0, 1], "b": [0, 1, 0]}, n_test_poses=1)
    missing = Capture(
        circle=np.zeros(5, int), direction=np.ones(5, int), readings=np.zeros((5, 6)), points=np.zeros((5, 3)),
        target=[0, 1, 2, 0, 1], target_names=("a", "b", "c"),
    )  # fmt: skip
    with pytest.raises(InputError, match="visit 2 .* measured 2 of the 3 targets"):
        iso_from_capture(missing, {}, n_test_poses=1)


# --- simulated study ----------------------------------------------------------------------------------


SCENARIO = load_scenario("kr5-demo")
THREE_TARGETS = {"a": [60.0, 40.0, 30.0], "b": [-50.0, 30.0, 20.0], "c": [0.0, -60.0, 40.0]}


def test_simulated_study_of_an_exact_robot_gives_zero_for_its_own_model():
    from robotcal.api import perturb

    truth = perturb(SCENARIO)
    nominal = ParameterSet.nominal(SCENARIO.robot)
    study = simulate_iso_study(
        SCENARIO.robot, {"truth": truth, "nominal": nominal}, cycles=3, seed=1, targets_mm=THREE_TARGETS,
        true_parameters=truth, tracker_from_base=SCENARIO.tracker_from_base,
    )  # fmt: skip
    r = study.results["truth"]
    np.testing.assert_allclose([r.ap.max(), r.rp.max(), abs(r.ad), r.rd], 0.0, rtol=0, atol=1e-8)
    np.testing.assert_allclose([np.abs(r.ap_abc).max(), r.rp_abc.max()], 0.0, rtol=0, atol=1e-11)
    # the nominal model misses the truth's deviations (0.2 mm, 0.05 deg sd): AP of that order, RP still 0
    n = study.results["nominal"]
    assert np.all(n.ap > 0.05) and np.all(n.ap < 5.0) and n.rp.max() < 1e-8
    # default cube (docs/iso9283.md): centre = the targets' centroid at the start readings; side = 20 % of the
    # reach: links 2..6 of the KR 5 (270 + 90 + 295 + 0 + 80 mm, sqrt(a^2 + d^2)) + |centroid (3.33, 3.33, 30)|
    # = 735 + 30.37 = 765.37 mm -> floor(153.07) = 153 mm, reachable at once
    assert study.side_mm == 153.0
    np.testing.assert_allclose(study.point_mm, [10.0 / 3, 10.0 / 3, 30.0], rtol=0, atol=1e-12)
    frame = forward_kinematics(nominal.values, SCENARIO.robot.model_joint_variables(study.start_readings))[0]
    np.testing.assert_allclose(study.center_mm, apply_transform(frame, study.point_mm), rtol=0, atol=1e-9)
    reached = apply_transform(forward_kinematics(nominal.values, study.readings), study.point_mm)
    np.testing.assert_allclose(reached, iso_test_positions(study.center_mm, 153.0), rtol=0, atol=1e-8)
    lower, upper = SCENARIO.robot.limits[:, 0], SCENARIO.robot.limits[:, 1]
    assert np.all((study.readings >= lower) & (study.readings <= upper))


def test_simulated_study_with_random_joint_errors_has_repeatability_of_their_order():
    sd = np.tile([0.01, 0.01, 0.01, 2e-5, 2e-5], (6, 1))
    errors = JointErrorModel(
        amplitude=np.zeros((6, 5)), period=np.full((6, 5), 2 * np.pi), phase=np.zeros((6, 5)), noise_sd=sd
    )
    nominal = ParameterSet.nominal(SCENARIO.robot)
    study = simulate_iso_study(
        SCENARIO.robot, {"nominal": nominal}, cycles=30, seed=4, targets_mm=THREE_TARGETS, true_parameters=nominal,
        joint_errors=errors, tracker_from_base=SCENARIO.tracker_from_base,
    )  # fmt: skip
    r = study.results["nominal"]
    # 6 joints x (3 shifts of 10 um + 2 tilts of 20 urad at lever arms up to ~0.8 m): a flange displacement sd of
    # a few 10 um per axis, so l_bar + 3 S_l is tens of um up to ~0.1 mm; the mean (AP) shrinks as 1 / sqrt(30)
    assert np.all(r.rp > 0.02) and np.all(r.rp < 0.3)
    assert np.all(r.ap < r.rp)
    # orientation: 12 tilts of 20 urad -> sd about 2e-5 sqrt(12 / 3) = 4e-5 rad per axis; RPa = 3 S_a ~ 1.2e-4 rad
    assert np.all(r.rp_abc > 3e-5) and np.all(r.rp_abc < 5e-4)


@pytest.fixture(scope="module")
def kr5_models():
    """CPA and refined models of a simulated kr5-demo capture (the demo's own path, ~3 s)."""
    from robotcal.api import identify, perturb, refine, simulate

    truth = perturb(SCENARIO)
    capture = simulate(SCENARIO, true_parameters=truth)
    cpa = identify(capture, SCENARIO, health="off").parameters
    with warnings.catch_warnings():  # J6's flange parameters are not identifiable from the circles: held
        warnings.simplefilter("ignore")
        refined = refine(capture, SCENARIO, cpa, health="off").parameters
    return truth, cpa, refined


def test_simulated_study_on_kr5_demo_refined_beats_nominal(kr5_models):
    truth, cpa, refined = kr5_models
    models = {"nominal": ParameterSet.nominal(SCENARIO.robot), "cpa": cpa, "refined": refined}
    study = simulate_iso_study(
        SCENARIO.robot, models, seed=7, true_parameters=truth, tracker_from_base=SCENARIO.tracker_from_base,
        joint_errors=SCENARIO.joint_errors, instrument=SCENARIO.instrument,
        targets_mm={"point": scenario_flange_point(SCENARIO)},
    )  # fmt: skip
    ap = {label: r.ap for label, r in study.results.items()}
    assert np.all(ap["refined"] < ap["nominal"])
    assert ap["refined"].max() < 0.5 * ap["nominal"].max()
    # RP does not depend on the model (same points, same base frame)
    np.testing.assert_allclose(study.results["refined"].rp, study.results["nominal"].rp, rtol=0, atol=1e-12)
    assert not study.results["nominal"].has_orientation  # kr5-demo declares one flange target


# --- cycle structure (issue 24: non-ISO cycles gave RP of 100-1000 mm without a word) -------------------


def _iso_capture(order, *, n_cycles=3):
    """A capture of the kr5-demo nominal robot at the rows ``order`` of 5 test poses x ``n_cycles`` cycles
    (cycle-major: index ``cycle * 5 + pose``); 20 extra distinct poses at indices 15.. for unrepeated ones."""
    robot = SCENARIO.robot
    nominal = ParameterSet.nominal(robot)
    start = np.radians([0.0, 90.0, -90.0, 0.0, 45.0, 0.0])
    poses = start + np.radians(np.arange(25)[:, None] * np.array([2.0, 1.0, -1.0, 0.5, 1.5, 3.0]))
    readings = np.vstack([np.tile(poses[:5], (n_cycles, 1)), poses[5:]])[order]
    frames = forward_kinematics(nominal.values, robot.model_joint_variables(readings))
    points = apply_transform(SCENARIO.tracker_from_base, frames[:, :3, 3])
    n = readings.shape[0]
    capture = Capture(circle=np.zeros(n, int), direction=np.ones(n, int), readings=readings, points=points)
    return capture, {"nominal": IsoModel(parameters=nominal, tracker_from_base=SCENARIO.tracker_from_base)}


def test_iso_cycles_in_order_are_accepted():
    capture, models = _iso_capture(np.arange(15))
    r = iso_from_capture(capture, models, point=[0.0, 0.0, 0.0])["nominal"]
    assert r.n_cycles == 3
    np.testing.assert_allclose([r.ap.max(), r.rp.max()], 0.0, rtol=0, atol=1e-9)  # exact robot, exact readings


@pytest.mark.parametrize(
    ("order", "message"),
    [
        # pose-major: P1 P1 P1 P2 P2 P2 ...
        (np.arange(15).reshape(3, 5).T.reshape(-1), r"pose-major order \(data rows 1 and 2 visit the same pose\)"),
        # 15 unrepeated poses
        (np.r_[0:5, 15:25], r"15 pose visits hold 15 distinct poses \(0 repeated\); expected 3 cycles of the same 5"),
        # P1 and P2 swapped in cycle 2 (rows 6, 7)
        (np.r_[0:5, 6, 5, 7:15], r"cycle 2 \(data row 6\) visits P2 where P1 belongs \(its order: P2, P1, P3, P4, P5\)"),
        # ... and in cycle 1: the other cycles' order is P1..P5
        (np.r_[1, 0, 2:15], r"cycle 1 \(data row 1\) visits P2 where P1 belongs"),
        # three distinct poses only
        (np.r_[0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2], r"hold only 3 distinct poses; expected 5 test poses"),
    ],
    ids=["pose-major", "unrepeated", "swapped-in-cycle-2", "swapped-in-cycle-1", "three-poses"],
)
def test_capture_that_is_not_iso_cycles_is_refused(order, message):
    capture, models = _iso_capture(order)
    with pytest.raises(InputError, match=r"not ISO 9283 cycles: .*" + message):
        iso_from_capture(capture, models, point=[0.0, 0.0, 0.0])


def test_cycle_structure_of_a_three_target_capture_names_the_data_row():
    study = simulate_iso_study(
        SCENARIO.robot, {"nominal": ParameterSet.nominal(SCENARIO.robot)}, cycles=3, seed=1, targets_mm=THREE_TARGETS,
        tracker_from_base=SCENARIO.tracker_from_base,
    )  # fmt: skip
    capture = study.capture
    # swap the visits P1 and P2 of cycle 3 (3 rows per visit: rows 31-33 and 34-36)
    order = np.r_[0:30, 33:36, 30:33, 36:45]
    swapped = capture.select(order)
    with pytest.raises(InputError, match=r"cycle 3 \(data row 31\) visits P2 where P1 belongs"):
        iso_from_capture(swapped, {"nominal": IsoModel(parameters=ParameterSet.nominal(SCENARIO.robot),
                                                       tracker_from_base=SCENARIO.tracker_from_base)},
                         targets=THREE_TARGETS)  # fmt: skip
