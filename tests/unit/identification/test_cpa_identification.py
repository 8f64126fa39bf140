"""Circle Point Analysis (thesis ch. 4.4-4.5): round trips, invariance, batch and validation.

The truth is always the parameter set the capture was simulated from: noise-free data must give it
back to rounding (thesis Table 5.3 for the nominal robot), for every option and capture layout.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import thesis_data
from robotcal.capture import Capture
from robotcal.errors import DegenerateGeometryError, IdentifiabilityWarning, InputError
from robotcal.geometry.registration import register_points
from robotcal.geometry.transforms import apply_transform
from robotcal.identification import CPAOptions, identify_cpa, identify_cpa_batch, prepare_cpa
from robotcal.instruments import Instrument
from robotcal.kinematics import ParameterSet, ReflectorMount, RobotModel
from robotcal.kinematics.forward import target_positions
from robotcal.simulation import CapturePlan, simulate_capture
from thesis_data import (
    KR5_HAYATI,
    OFF_AXIS_REFLECTORS_MM,
    TABLE_4_2_DEG,
    TABLE_5_1_POINTS,
    TABLE_5_1_START_DEG,
    TABLE_5_1_SWEEP_DEG,
    kr5_robot,
    random_rigid,
)

NOISE_FREE = Instrument(a_mm=0.0, b_mm_per_m=0.0)
KUKA_SIGN = np.array(thesis_data.KUKA_SIGN)
D, THETA, A, ALPHA, BETA = range(5)

#: The 20 parameters CPA identifies on the KR5 (docs/conventions.md): d1, d3..d5, theta1..5, a1..5, alpha1..5, beta2
IDENTIFIABLE = np.zeros((6, 5), dtype=bool)
IDENTIFIABLE[[0, 2, 3, 4], D] = True
IDENTIFIABLE[:5, [THETA, A, ALPHA]] = True
IDENTIFIABLE[1, BETA] = True

#: Round-trip tolerance [mm and rad]: noise-free points of ~3 m coordinates are exact to ~1e-12 mm;
#: circle fits, line intersections and the chain of 5 pairs amplify this to at most 7.4e-11 (observed
#: over 600 random scenarios of this file's kind); 1e-8 leaves two orders of magnitude of margin.
ROUND_TRIP_TOL = 1e-8

TABLE_5_1 = {
    "start": np.deg2rad(TABLE_5_1_START_DEG),
    "sweep": np.deg2rad(TABLE_5_1_SWEEP_DEG),
    "points": TABLE_5_1_POINTS,
}
TABLE_4_2 = np.deg2rad(TABLE_4_2_DEG)
FIXED_REFLECTORS = ReflectorMount(frame="joint", positions=OFF_AXIS_REFLECTORS_MM)


def _kr5(reading_sign=None, hayati=tuple(KR5_HAYATI)):
    """Thesis Table 3.1 [mm, rad]."""
    return kr5_robot(hayati=list(hayati), reading_sign=reading_sign)


_rigid = random_rigid


def _perturbed_truth(robot, rng):
    """Every identifiable parameter moved by up to 0.5 mm / 0.2 deg; J6, d2 and the DH betas stay nominal."""
    values = robot.nominal.copy()
    moves = np.zeros((6, 5))
    moves[:, [D, A]] = rng.uniform(-0.5, 0.5, (6, 2))
    moves[:, [THETA, ALPHA, BETA]] = np.deg2rad(rng.uniform(-0.2, 0.2, (6, 3)))
    values[IDENTIFIABLE] += moves[IDENTIFIABLE]
    return ParameterSet(robot=robot, values=values)


def _random_reflector(rng, flange=False):
    n = 1 if flange else 6
    radius = rng.uniform(100.0, 300.0, n)
    azimuth = rng.uniform(-np.pi, np.pi, n)
    positions = np.c_[radius * np.cos(azimuth), radius * np.sin(azimuth), rng.uniform(-150.0, 150.0, n)]
    return ReflectorMount(frame="flange" if flange else "joint", positions=positions[0] if flange else positions)


def _random_plan(rng, reflector, *, start=None, bidirectional=False):
    sweep = np.deg2rad(rng.uniform(30.0, 300.0, 6) * rng.choice([-1.0, 1.0], 6))
    if start is None:
        start = np.deg2rad(rng.uniform(-90.0, 90.0, 6))
    points = rng.integers(5, 31, 6)
    return CapturePlan(start=start, sweep=sweep, points=points, reflector=reflector, bidirectional=bidirectional)


def _scenario(seed, *, reading_sign=None, flange=False, start_matrix=False, bidirectional=False):
    """Random truth, tracker pose, reflector and sweeps; returns what identification needs and the truth."""
    rng = np.random.default_rng(seed)
    robot = _kr5(reading_sign)
    truth = _perturbed_truth(robot, rng)
    tracker_from_base = _rigid(rng)
    reflector = _random_reflector(rng, flange)
    plan = _random_plan(rng, reflector, start=TABLE_4_2 if start_matrix else None, bidirectional=bidirectional)
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, tracker_from_base, true_parameters=truth)
    return robot, truth, reflector, tracker_from_base, capture


def _assert_round_trip(result, truth, robot, mask=IDENTIFIABLE):
    values = result.parameters.values
    np.testing.assert_array_equal(result.parameters.identified, IDENTIFIABLE)
    # identified parameters: the truth to rounding (ROUND_TRIP_TOL, mm and rad)
    np.testing.assert_allclose(values[mask], truth.values[mask], rtol=0, atol=ROUND_TRIP_TOL)
    # not identified (J6 d/theta/a/alpha, d2, DH betas): nominal, copied exactly
    np.testing.assert_array_equal(values[~IDENTIFIABLE], robot.nominal[~IDENTIFIABLE])
    assert result.success


# ------------------------------------------------------------------------------------- (a) Table 5.3


@pytest.mark.parametrize(
    ("circle_fit", "base_frame", "base_axis"),
    list(itertools.product(["geometric", "algebraic"], ["given", "registered"], ["registration", "circle1"])),
)
def test_table_5_1_nominal_is_identified_exactly(circle_fit, base_frame, base_axis):
    robot = _kr5()
    plan = CapturePlan(**TABLE_5_1, reflector=FIXED_REFLECTORS)
    tracker_from_base = _rigid(np.random.default_rng(0))
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, tracker_from_base)
    options = CPAOptions(circle_fit=circle_fit, base_frame=base_frame, base_axis=base_axis)
    result = identify_cpa(capture, robot, FIXED_REFLECTORS, tracker_from_base=tracker_from_base, options=options)
    values = result.parameters.values
    # thesis Table 5.3: noise-free nominal data give the nominal parameters; 1e-9 mm and 1e-9 deg
    # (observed ~2e-12 mm, ~3e-13 deg: rounding of ~3 m coordinates)
    np.testing.assert_allclose(values[:, [D, A]], robot.nominal[:, [D, A]], rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        np.rad2deg(values[:, [THETA, ALPHA, BETA]]),
        np.rad2deg(robot.nominal[:, [THETA, ALPHA, BETA]]),
        rtol=0,
        atol=1e-9,
    )
    assert result.pair_cases[1] == "nearly-parallel" and result.pair_cases[0] == "skew"
    # reference configuration: every joint where its own circle ended, q_F of Table 5.1
    np.testing.assert_allclose(
        np.rad2deg(result.reference_readings), [60.0, 80.0, 100.0, 50.0, 200.0, 300.0], atol=1e-12
    )
    np.testing.assert_array_equal(result.parameters.identified, IDENTIFIABLE)
    assert result.success and result.message == "identified"
    if base_frame == "registered":
        # noise-free nominal data: the registration is the true transform, residual ~0
        np.testing.assert_allclose(result.tracker_from_base, tracker_from_base, rtol=0, atol=1e-9)
        assert result.registration_rms < 1e-9
    else:
        np.testing.assert_array_equal(result.tracker_from_base, tracker_from_base)


# ------------------------------------------------------------------------------------- (b) round trips


#: Capture layouts, each run with 3 seeds (block offset keeps the random scenarios distinct).
LAYOUTS = {
    "per-circle targets": (0, {}),
    "flange target": (100, {"flange": True}),
    # circles start from their own configurations: axes are transported to the reference configuration
    "table 4.2 start matrix": (200, {"start_matrix": True}),
    "bidirectional": (300, {"bidirectional": True}),
    "kuka reading signs": (400, {"reading_sign": KUKA_SIGN}),
}


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_perturbed_robot_round_trip(layout, seed):
    offset, options = LAYOUTS[layout]
    robot, truth, reflector, tracker_from_base, capture = _scenario(offset + seed, **options)
    if options.get("bidirectional"):
        assert set(np.unique(capture.direction)) == {-1, 1}
    result = identify_cpa(capture, robot, reflector, tracker_from_base=tracker_from_base)
    _assert_round_trip(result, truth, robot)


@pytest.mark.parametrize("flange", [False, True])
def test_round_trip_all_layouts_together(flange):
    robot, truth, reflector, tracker_from_base, capture = _scenario(
        500, reading_sign=KUKA_SIGN, flange=flange, start_matrix=True, bidirectional=True
    )
    for circle_fit, base_axis in itertools.product(["geometric", "algebraic"], ["registration", "circle1"]):
        options = CPAOptions(circle_fit=circle_fit, base_axis=base_axis)
        result = identify_cpa(capture, robot, reflector, tracker_from_base=tracker_from_base, options=options)
        mask = IDENTIFIABLE.copy()
        if flange and base_axis == "circle1":
            # with a flange target, the angle of the first circle-1 point is predicted by the *nominal*
            # model (prepare_cpa), so theta1 absorbs the deviations of the later joints, as d1 and
            # theta1 do under registration: only the other 19 are exact
            mask[0, THETA] = False
        _assert_round_trip(result, truth, robot, mask=mask)


def test_circle1_theta1_with_flange_target_absorbs_later_deviations():
    robot, truth, reflector, tracker_from_base, capture = _scenario(501, flange=True)
    options = CPAOptions(base_axis="circle1")
    result = identify_cpa(capture, robot, reflector, tracker_from_base=tracker_from_base, options=options)
    error = result.parameters.values[0, THETA] - truth.values[0, THETA]
    # not rounding: the nominal prediction of the target azimuth is off by the perturbation's effect
    # (of order 0.5 mm / 300 mm ~ 1e-3 rad), yet bounded by the size of the perturbations (0.2 deg each)
    assert 1e-8 < abs(error) < np.deg2rad(1.0)
    # with the true robot as "nominal", circle1 gives theta1 exactly
    exact_robot = RobotModel(name="kr5", nominal=truth.values, hayati=robot.hayati)
    truth_as_nominal = ParameterSet(robot=exact_robot, values=truth.values)
    exact = identify_cpa(capture, exact_robot, reflector, tracker_from_base=tracker_from_base, options=options)
    _assert_round_trip(exact, truth_as_nominal, exact_robot)


@pytest.mark.parametrize("seed", range(2))
def test_round_trip_with_reading_offsets(seed):
    # controller zero not at the model zero: q = sign * reading + offset on every joint
    rng = np.random.default_rng(450 + seed)
    base = _kr5(KUKA_SIGN)
    offset = np.deg2rad(rng.uniform(-180.0, 180.0, 6))
    robot = RobotModel(
        name="kr5", nominal=base.nominal, hayati=base.hayati, reading_sign=KUKA_SIGN, reading_offset=offset
    )
    truth = _perturbed_truth(robot, rng)
    tracker_from_base = _rigid(rng)
    reflector = _random_reflector(rng)
    plan = _random_plan(rng, reflector, start=TABLE_4_2 if seed else None)
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, tracker_from_base, true_parameters=truth)
    result = identify_cpa(capture, robot, reflector, tracker_from_base=tracker_from_base)
    _assert_round_trip(result, truth, robot)


def test_round_trip_ignores_row_order():
    # a capture file need not list its points circle by circle: shuffling the rows changes nothing
    robot, truth, reflector, tracker_from_base, capture = _scenario(460, start_matrix=True, bidirectional=True)
    order = np.random.default_rng(461).permutation(capture.n_points)
    shuffled = Capture(
        circle=capture.circle[order],
        direction=capture.direction[order],
        readings=capture.readings[order],
        points=capture.points[order],
    )
    for base_axis in ("registration", "circle1"):
        result = identify_cpa(
            shuffled, robot, reflector, tracker_from_base=tracker_from_base, options=CPAOptions(base_axis=base_axis)
        )
        _assert_round_trip(result, truth, robot)


def test_registered_base_frame_identifies_all_but_d1_theta1():
    # the registration against the nominal model absorbs part of the robot's deviations into the base
    # frame, so d1 and theta1 are off; the other 18 only depend on the axes (docs/conventions.md, base frame)
    robot, truth, reflector, tracker_from_base, capture = _scenario(600)
    options = CPAOptions(base_frame="registered")
    result = identify_cpa(capture, robot, reflector, options=options)
    others = IDENTIFIABLE.copy()
    others[0, [D, THETA]] = False
    _assert_round_trip(result, truth, robot, mask=others)
    assert result.registration_rms > 1e-3  # the nominal model does not fit a perturbed robot exactly


# ------------------------------------------------------------------------------------- (c) invariance

OTHER_18 = IDENTIFIABLE.copy()
OTHER_18[0, [D, THETA]] = False


@pytest.mark.parametrize("base_frame", ["given", "registered"])
def test_moving_the_tracker_changes_nothing(base_frame):
    robot, truth, reflector, tracker_from_base, capture = _scenario(700)
    noisy = capture.with_points(
        capture.points + Instrument(a_mm=0.01, b_mm_per_m=0.005).sample_noise(capture.points, rng=1)
    )
    motion = _rigid(np.random.default_rng(701))
    moved = noisy.with_points(noisy.points @ motion[:3, :3].T + motion[:3, 3])
    options = CPAOptions(base_frame=base_frame)
    before = identify_cpa(noisy, robot, reflector, tracker_from_base=tracker_from_base, options=options)
    after = identify_cpa(moved, robot, reflector, tracker_from_base=motion @ tracker_from_base, options=options)
    # the 18 parameters between axes are invariant to the instrument frame: rounding and the geometric
    # fit's cost resolution (~1e-9 mm, see test_circle_fits) on noisy data, so 1e-8
    np.testing.assert_allclose(after.parameters.values[OTHER_18], before.parameters.values[OTHER_18], rtol=0, atol=1e-9)
    # with the moved base frame (given, or registered, which is equivariant) d1 and theta1 stay too
    np.testing.assert_allclose(
        after.parameters.values[0, [D, THETA]], before.parameters.values[0, [D, THETA]], atol=1e-8
    )


def test_wrong_base_frame_only_affects_d1_and_theta1():
    robot, truth, reflector, tracker_from_base, capture = _scenario(800)
    rng = np.random.default_rng(801)
    # a small unknown move of the instrument (2 deg, 50 mm) that the given base frame does not know about
    motion = np.eye(4)
    motion[:3, :3] = Rotation.from_rotvec(
        np.deg2rad(2.0) * Rotation.random(random_state=rng).apply([0, 0, 1])
    ).as_matrix()
    motion[:3, 3] = rng.normal(size=3) * 50.0 / np.sqrt(3.0)
    moved = capture.with_points(capture.points @ motion[:3, :3].T + motion[:3, 3])
    result = identify_cpa(moved, robot, reflector, tracker_from_base=tracker_from_base)
    values = result.parameters.values
    np.testing.assert_allclose(values[OTHER_18], truth.values[OTHER_18], rtol=0, atol=ROUND_TRIP_TOL)
    # d1 and theta1 absorb the frame error (here ~40 mm and ~0.9 deg): far more than rounding
    assert abs(values[0, D] - truth.values[0, D]) > 1.0
    assert abs(values[0, THETA] - truth.values[0, THETA]) > 1e-3


# ------------------------------------------------------------------------------------- (d) Hayati J2


def test_d2_is_exactly_zero_and_beta2_identified():
    robot, truth, reflector, tracker_from_base, capture = _scenario(900)
    assert truth.values[1, BETA] != 0.0
    result = identify_cpa(capture, robot, reflector, tracker_from_base=tracker_from_base)
    assert result.parameters.values[1, D] == 0.0  # structurally zero, not estimated
    assert not result.parameters.identified[1, D]
    assert result.parameters.identified[1, BETA]
    np.testing.assert_allclose(result.parameters.values[1, BETA], truth.values[1, BETA], rtol=0, atol=ROUND_TRIP_TOL)


def test_parallel_dh_pair_holds_d_at_nominal_with_warning():
    # the same nominal robot modelled with a DH J2: axes 2 and 3 are exactly parallel, d2 cannot be seen
    robot = _kr5(hayati=(False,) * 6)
    plan = CapturePlan(**TABLE_5_1, reflector=FIXED_REFLECTORS)
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, np.eye(4))
    with pytest.warns(IdentifiabilityWarning, match="J2.d cannot be identified and stays nominal"):
        result = identify_cpa(capture, robot, FIXED_REFLECTORS, tracker_from_base=np.eye(4))
    assert result.pair_cases[1] == "parallel"
    assert not result.parameters.identified[1, D]
    # the other DH parameters of the pair are still exact (rounding, 1e-9 mm/rad)
    np.testing.assert_allclose(
        result.parameters.values[1, [THETA, A, ALPHA]], robot.nominal[1, [THETA, A, ALPHA]], atol=1e-9
    )
    assert "J2.d held at nominal" in result.message


# ------------------------------------------------------------------------------------- (e) errors


def _nominal_capture(robot=None):
    robot = _kr5() if robot is None else robot
    plan = CapturePlan(**TABLE_5_1, reflector=FIXED_REFLECTORS)
    capture, _ = simulate_capture(robot, plan, NOISE_FREE, np.eye(4))
    return robot, capture


def _edited(capture, keep=None, readings=None, points=None):
    keep = np.ones(capture.n_points, dtype=bool) if keep is None else keep
    return Capture(
        circle=capture.circle[keep],
        direction=capture.direction[keep],
        readings=(capture.readings if readings is None else readings)[keep],
        points=(capture.points if points is None else points)[keep],
        source="edited.csv",
    )


def test_missing_circle():
    robot, capture = _nominal_capture()
    with pytest.raises(InputError, match=r"edited.csv: no circle for J4; CPA needs one circle per joint"):
        identify_cpa(_edited(capture, keep=capture.circle != 4), robot, FIXED_REFLECTORS, tracker_from_base=np.eye(4))


def test_circle_with_two_points():
    robot, capture = _nominal_capture()
    keep = capture.circle != 3
    keep[np.flatnonzero(capture.circle == 3)[:2]] = True
    with pytest.raises(InputError, match="circle 3 has 2 points; a circle needs at least 3"):
        identify_cpa(_edited(capture, keep=keep), robot, FIXED_REFLECTORS, tracker_from_base=np.eye(4))


def test_collinear_circle():
    robot, capture = _nominal_capture()
    points = capture.points.copy()
    rows = np.flatnonzero(capture.circle == 2)
    points[rows] = [100.0, 200.0, 300.0] + np.linspace(0.0, 50.0, rows.size)[:, None] * np.array([1.0, 0.5, 0.2])
    with pytest.raises(DegenerateGeometryError, match=r"circle 2 \(J2\): points are collinear"):
        identify_cpa(_edited(capture, points=points), robot, FIXED_REFLECTORS, tracker_from_base=np.eye(4))


def test_zero_sweep():
    robot, capture = _nominal_capture()
    readings = capture.readings.copy()
    rows = np.flatnonzero(capture.circle == 5)
    readings[rows, 4] = readings[rows[0], 4]  # J5 reading constant within its own circle
    with pytest.raises(DegenerateGeometryError, match=r"circle 5: joint J5 does not turn \(zero sweep\)"):
        identify_cpa(_edited(capture, readings=readings), robot, FIXED_REFLECTORS, tracker_from_base=np.eye(4))


def test_resting_joint_that_moves():
    robot, capture = _nominal_capture()
    readings = capture.readings.copy()
    rows = np.flatnonzero(capture.circle == 3)
    readings[rows, 0] += np.linspace(0.0, np.deg2rad(1.0), rows.size)
    with pytest.raises(InputError, match="circle 3: joint J1 moves by 1 deg while J3 turns"):
        identify_cpa(_edited(capture, readings=readings), robot, FIXED_REFLECTORS, tracker_from_base=np.eye(4))


def test_joint_count_mismatch():
    _, capture = _nominal_capture()
    five = RobotModel(name="five", nominal=_kr5().nominal[:5], hayati=[False, True, False, False, False])
    reflector = ReflectorMount(frame="joint", positions=FIXED_REFLECTORS.positions[:5])
    with pytest.raises(InputError, match="the capture has 6 joint readings per point; robot 'five' has 5 joints"):
        identify_cpa(capture, five, reflector, tracker_from_base=np.eye(4))


def test_reflector_count_mismatch():
    robot, capture = _nominal_capture()
    reflector = ReflectorMount(frame="joint", positions=FIXED_REFLECTORS.positions[:4])
    with pytest.raises(InputError, match="4 per-circle reflector positions for 6 joints"):
        identify_cpa(capture, robot, reflector, tracker_from_base=np.eye(4))


def test_given_base_frame_needs_a_transform():
    robot, capture = _nominal_capture()
    with pytest.raises(InputError, match="base_frame='given' needs `tracker_from_base`"):
        identify_cpa(capture, robot, FIXED_REFLECTORS)
    with pytest.raises(InputError, match="`tracker_from_base` is not a rigid transform"):
        identify_cpa(capture, robot, FIXED_REFLECTORS, tracker_from_base=np.diag([2.0, 1.0, 1.0, 1.0]))


def test_wrong_reading_sign_in_robot_file():
    # captured by a robot whose J3 reading follows the model's z2 ...
    _, capture = _nominal_capture(_kr5())
    # ... identified with a robot file that says the J3 reading is reversed
    wrong = _kr5(reading_sign=[1, 1, -1, 1, 1, 1])
    with pytest.raises(InputError, match=r"circle 3: J3 turns the opposite way.*check `reading_sign` of J3"):
        identify_cpa(capture, wrong, FIXED_REFLECTORS, tracker_from_base=np.eye(4))


def test_hayati_joint_with_perpendicular_axes():
    # J1 declared Hayati although axes 1 and 2 are perpendicular
    nominal = _kr5().nominal.copy()
    nominal[0, D] = 0.0  # a Hayati joint has d = 0
    robot = RobotModel(name="bad", nominal=nominal, hayati=[True, True, False, False, False, False])
    _, capture = _nominal_capture(robot)
    with pytest.raises(DegenerateGeometryError, match="J1 is a Hayati joint but axes 1 and 2 are 90 deg apart"):
        identify_cpa(capture, robot, FIXED_REFLECTORS, tracker_from_base=np.eye(4))


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"circle_fit": "kasa"}, "option `circle_fit` must be one of"),
        ({"base_frame": "guessed"}, "option `base_frame` must be one of"),
        ({"base_axis": "x"}, "option `base_axis` must be one of"),
        ({"near_parallel_deg": -1.0}, "option `near_parallel_deg` must be a finite number >= 0"),
        ({"still_tolerance_deg": float("nan")}, "option `still_tolerance_deg` must be a finite number >= 0"),
    ],
)
def test_options_validation(arguments, message):
    with pytest.raises(InputError, match=message):
        CPAOptions(**arguments)


# ------------------------------------------------------------------------------------- (f) batch


@pytest.mark.parametrize("base_axis", ["registration", "circle1"])
@pytest.mark.parametrize("base_frame", ["given", "registered"])
@pytest.mark.parametrize("circle_fit", ["geometric", "algebraic"])
def test_batch_equals_separate_calls(base_frame, circle_fit, base_axis):
    robot, truth, reflector, tracker_from_base, capture = _scenario(1000)
    instrument = Instrument(a_mm=0.01, b_mm_per_m=0.005)
    stack = capture.points + instrument.sample_noise(
        np.broadcast_to(capture.points, (5,) + capture.points.shape), rng=3
    )
    options = CPAOptions(circle_fit=circle_fit, base_frame=base_frame, base_axis=base_axis)
    structure = prepare_cpa(capture, robot, reflector, options)
    batch = identify_cpa_batch(stack, structure, tracker_from_base)
    assert batch.values.shape == (5, 6, 5)
    np.testing.assert_array_equal(batch.identified, IDENTIFIABLE)
    for k in range(5):
        single = identify_cpa(
            capture.with_points(stack[k]), robot, reflector, tracker_from_base=tracker_from_base, options=options
        )
        # One code path with a leading axis: the same numbers up to rounding. Batched and single
        # reductions differ by ~1e-15 in a plane normal; CPA amplifies that (short arcs, nearly
        # intersecting axes) to ~1e-11 mm; 1e-9 is the agreement the Monte Carlo engine promises.
        np.testing.assert_allclose(batch.values[k], single.parameters.values, rtol=0, atol=1e-9)
        if base_frame == "given":
            np.testing.assert_allclose(batch.tracker_from_base[k], single.tracker_from_base, rtol=0, atol=1e-10)
        else:  # a single identification records the base frame of the identified model (see the next test)
            predicted = target_positions(
                single.parameters.values, robot.model_joint_variables(capture.readings), capture.circle - 1, reflector
            )
            expected = register_points(predicted, stack[k]).transform
            np.testing.assert_allclose(single.tracker_from_base, expected, rtol=0, atol=1e-9)


def test_a_registered_base_frame_is_that_of_the_identified_model():
    # CPA registers the nominal model's points on the capture to locate the base (d1, theta1); the base frame it
    # records is then the identified model's own registration, so that the identified parameters predict the
    # capture in it (the nominal registration left a real robot's identify 4.65 mm off its own capture, 0.66 mm
    # after registering again)
    robot, truth, reflector, tracker_from_base, capture = _scenario(1000)
    options = CPAOptions(base_frame="registered")
    result = identify_cpa(capture, robot, reflector, options=options)
    structure = prepare_cpa(capture, robot, reflector, options)
    nominal_frame = identify_cpa_batch(capture.points[None], structure).tracker_from_base[0]
    q = robot.model_joint_variables(capture.readings)
    predicted = target_positions(result.parameters.values, q, capture.circle - 1, reflector)

    def rms(frame):
        return np.sqrt(np.mean(np.sum((apply_transform(frame, predicted) - capture.points) ** 2, axis=1)))

    # the recorded frame is the least-squares one of the identified model (its RMS is the one recorded); with a
    # registered base the identified d1, theta1 absorb part of the robot's deviations, so it is not zero
    np.testing.assert_allclose(rms(result.tracker_from_base), result.registration_rms, rtol=1e-9)
    assert rms(nominal_frame) > 2.0 * rms(result.tracker_from_base), (rms(nominal_frame), result.registration_rms)


@pytest.mark.parametrize("base_frame", ["given", "registered"])
@pytest.mark.parametrize("circle_fit", ["geometric", "algebraic"])
def test_batch_without_residuals_gives_the_same_parameters(base_frame, circle_fit):
    robot, _, reflector, tracker_from_base, capture = _scenario(1000)
    stack = capture.points + Instrument(a_mm=0.01, b_mm_per_m=0.005).sample_noise(
        np.broadcast_to(capture.points, (4,) + capture.points.shape), rng=5
    )
    structure = prepare_cpa(capture, robot, reflector, CPAOptions(circle_fit=circle_fit, base_frame=base_frame))
    full = identify_cpa_batch(stack, structure, tracker_from_base)
    lean = identify_cpa_batch(stack, structure, tracker_from_base, residuals=False)
    # the residuals are computed after the circles, from the same numbers: identical, bit for bit
    np.testing.assert_array_equal(lean.values, full.values)
    np.testing.assert_array_equal(lean.tracker_from_base, full.tracker_from_base)
    for fit in lean.circle_fits:
        assert fit.plane_residuals is None and fit.radial_residuals is None
        assert fit.plane_rms is None and fit.circle_rms is None


def test_axis_transport_equals_the_rigid_transform_about_the_axis():
    from robotcal.geometry.lines import PluckerLine
    from robotcal.geometry.transforms import rotation_about_line
    from robotcal.identification.cpa import _turned_about

    rng = np.random.default_rng(4)
    axis = PluckerLine.from_point_direction(rng.uniform(-900.0, 900.0, (7, 3)), rng.normal(size=(7, 3)))
    line = PluckerLine.from_point_direction(rng.uniform(-900.0, 900.0, (7, 3)), rng.normal(size=(7, 3)))
    for angle in (0.3, -2.9, 1e-7):
        turned = _turned_about(line, axis, angle)
        # independent route: the 4x4 rigid transform about the axis, applied to the line
        expected = line.transformed(rotation_about_line(axis.direction, axis.point, angle))
        # unit directions and moments of lines within ~1 m of the origin: rounding only (~1e-13 mm)
        np.testing.assert_allclose(turned.direction, expected.direction, rtol=0, atol=1e-14)
        np.testing.assert_allclose(turned.moment, expected.moment, rtol=0, atol=1e-11)


def test_resting_joints_need_no_axis_transport():
    from robotcal.api import monte_carlo_problem
    from robotcal.io import load_scenario

    # the demo's circles: every joint before the turning one rests where its own circle ended, so the
    # transport of every axis to the reference configuration is no rotation at all, exactly (a mean of
    # equal readings misses them by an ulp: transport angles of -1.7e-16 rad, each a rotation per batch)
    structure = monte_carlo_problem(load_scenario("kr5-demo")).structure
    n = structure.transport.shape[0]
    earlier = np.tril(np.ones((n, n), dtype=bool), k=-1)
    assert np.all(structure.transport[earlier] == 0.0)
    for rows in structure.circle_indices[1:]:  # J1 rests at its reference reading while J2..J6 turn
        assert np.all(structure.model_q[rows, 0] == structure.reference_q[0])
    plain_means = np.array([structure.model_q[rows].mean(axis=0)[0] for rows in structure.circle_indices[1:]])
    assert np.any(plain_means != structure.reference_q[0])  # what the transport was before
