"""Property: a noise-free capture of a perturbed robot is refined exactly (issue 11 item 2).

Hypothesis draws the robot (every parameter the model does not fix moved by up to 0.5 mm /
0.2 deg, J6's own ones optionally), the tracker (anywhere within 3 m, any orientation), the targets
(per-joint or one flange target, 100-300 mm off their axes), the plan (sweeps of 60-300 deg, 6-12
points per circle, one or both directions, J6 turned or not), the criterion, the base-frame mode
(given and held, or estimated) and the start (nominal, or CPA where CPA can run). Both criteria must
recover every parameter the data determine to <= 1e-9 mm / 1e-9 deg, fit the capture exactly and
never end above the start's cost.
"""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityWarning, InputError
from robotcal.identification import identify_cpa
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.instruments import Instrument
from robotcal.kinematics import ParameterSet, ReflectorMount
from robotcal.simulation import CapturePlan, simulate_capture
from thesis_data import TABLE_4_2_DEG, kr5_robot

ROBOT = kr5_robot()
D, THETA, A, ALPHA, BETA = range(5)
#: What CPA identifies on the KR5 (docs/conventions.md): d1, d3..d5, theta1..5, a1..5, alpha1..5, beta2.
CPA_IDENTIFIABLE = np.zeros((6, 5), dtype=bool)
CPA_IDENTIFIABLE[[0, 2, 3, 4], D] = True
CPA_IDENTIFIABLE[:5, [THETA, A, ALPHA]] = True
CPA_IDENTIFIABLE[1, BETA] = True
# 1e-9 mm / 1e-9 deg (the bound); the solver stops at ~1e-12
TOLERANCE = np.array([1e-9, np.deg2rad(1e-9), 1e-9, np.deg2rad(1e-9), np.deg2rad(1e-9)])


def _floats(low, high):
    return st.floats(low, high, allow_nan=False, allow_infinity=False)


@st.composite
def cases(draw):
    flange = draw(st.booleans())
    n_targets = 1 if flange else 6
    criterion = draw(st.sampled_from(["points", "distances"]))
    # J6 still behind a flange target: the target is a fixed point of frame 5 and one of J5's d, theta,
    # a, alpha is held. Which one the start's rank test holds (alpha5) could leave the truth out of reach
    # for targets close to axis 5 (a ~0.03 mm noise-free residual); the rank test at the solution picks
    # another and the refit is exact (250 examples of that layout checked, refine.py module notes)
    joint6_moves = draw(st.booleans())
    return {
        "length_moves": draw(arrays(np.float64, (6, 5), elements=_floats(-0.5, 0.5))),
        "angle_moves": np.deg2rad(draw(arrays(np.float64, (6, 5), elements=_floats(-0.2, 0.2)))),
        "perturb_joint6": draw(st.booleans()),
        "rotation_vector": draw(arrays(np.float64, 3, elements=_floats(-np.pi, np.pi))),
        "translation": draw(arrays(np.float64, 3, elements=_floats(-3000.0, 3000.0))),
        "flange": flange,
        # targets on a 1 mm / 1 deg grid: one 1e-7 mm off a special plane (alpha_n = 0 and the target
        # in the x-y plane of frame n) is numerically on it, and its 1e-8 mm second-order effects
        # cannot meet a 1e-9 bound; exactly on it (0) is covered
        "radius": draw(arrays(np.int64, n_targets, elements=st.integers(100, 300))).astype(float),
        "azimuth": np.deg2rad(draw(arrays(np.int64, n_targets, elements=st.integers(-180, 180))).astype(float)),
        "height": draw(arrays(np.int64, n_targets, elements=st.integers(-150, 150))).astype(float),
        "sweep": np.deg2rad(draw(arrays(np.float64, 6, elements=_floats(60.0, 300.0))))
        * draw(arrays(np.float64, 6, elements=st.sampled_from([-1.0, 1.0]))),
        "points": draw(arrays(np.int64, 6, elements=st.integers(6, 12))),
        # Table 4.2 starts moved by whole degrees up to 20 (all-zero starts put the KR5's wrist in its
        # singularity for circles 4 and 6; Table 4.2's rows 1 and 4 are equal, and readings 1e-100 deg
        # apart would be distinct poses at one point, which the distances criterion rightly refuses)
        "start_offset": np.deg2rad(draw(arrays(np.int64, (6, 6), elements=st.integers(-20, 20))).astype(float)),
        "bidirectional": draw(st.booleans()),
        "joint6_moves": joint6_moves,
        "criterion": criterion,
        "estimate_base": criterion == "points" and draw(st.booleans()),
        "cpa_start": joint6_moves and draw(st.booleans()),  # CPA needs a circle per joint
    }


def _setup(case):
    values = ROBOT.nominal.copy()
    free = ~ROBOT.structurally_fixed
    if not case["perturb_joint6"]:
        free[5] = False
    kinds = np.array([True, False, True, False, False])  # lengths: d, a
    values += np.where(free, np.where(kinds, case["length_moves"], case["angle_moves"]), 0.0)
    truth = ParameterSet(robot=ROBOT, values=values)
    tracker = np.eye(4)
    tracker[:3, :3] = Rotation.from_rotvec(case["rotation_vector"]).as_matrix()
    tracker[:3, 3] = case["translation"]
    targets = np.c_[case["radius"] * np.cos(case["azimuth"]), case["radius"] * np.sin(case["azimuth"]), case["height"]]
    if case["flange"]:
        reflector = ReflectorMount(frame="flange", positions=targets[0])
    else:
        reflector = ReflectorMount(frame="joint", positions=targets)
    start = np.deg2rad(TABLE_4_2_DEG) + case["start_offset"]
    if not case["joint6_moves"]:
        start[:, 5] = start[0, 5]  # J6 still: one reading throughout (1 deg apart would be a 1 deg "circle")
    plan = CapturePlan(
        start=start,
        sweep=case["sweep"],
        points=case["points"],
        reflector=reflector,
        bidirectional=case["bidirectional"],
    )
    capture, _ = simulate_capture(
        ROBOT, plan, Instrument(a_mm=0.0, b_mm_per_m=0.0), tracker, true_parameters=truth, joint_limits="ignore"
    )
    if not case["joint6_moves"]:
        keep = capture.circle != 6
        capture = Capture(
            circle=capture.circle[keep],
            direction=capture.direction[keep],
            readings=capture.readings[keep],
            points=capture.points[keep],
        )
    return truth, tracker, reflector, capture


#: Found by hypothesis: the distances criterion from the nominal start, every angle 0.19 deg off, 60 deg sweeps of
#: 6 points, flange target. The rank test at the nominal start (target 5.2 mm off the x-z plane of frame 6) holds
#: J6.alpha; with alpha6 held at 0 no J6.d, theta, a reach the true circle of the target, and the solver stopped
#: "converged" at a 7.4e-4 mm residual with the target on the x-z plane, where J6.a is the dependent one. The rank
#: test at that solution holds J6.a instead, and the refit from there is exact (refine.py, module notes).
_STOPS_SHORT = {
    "length_moves": np.zeros((6, 5)), "angle_moves": np.full((6, 5), 0.00327249), "perturb_joint6": True,
    "rotation_vector": np.zeros(3), "translation": np.zeros(3), "flange": True, "radius": np.array([100.0]),
    "azimuth": np.array([1.51843645]), "height": np.array([42.0]), "sweep": np.full(6, -1.04719755),
    "points": np.full(6, 6), "start_offset": np.zeros((6, 6)), "bidirectional": False, "joint6_moves": True,
    "criterion": "distances", "estimate_base": False, "cpa_start": False,
}  # fmt: skip


# derandomized: CI runs the same examples every time (a new search finding lives in an @example, as above)
@settings(max_examples=12, deadline=None, derandomize=True)
@given(cases())
@example(_STOPS_SHORT)
def test_noise_free_refinement_is_exact_from_nominal_and_cpa(case):
    truth, tracker, reflector, capture = _setup(case)
    if case["cpa_start"]:
        start = identify_cpa(capture, ROBOT, reflector, tracker_from_base=tracker).parameters
    else:
        start = ParameterSet.nominal(ROBOT)
    given_base = case["criterion"] == "points" and not case["estimate_base"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine_parameters(
            capture,
            start,
            reflector,
            tracker_from_base=tracker if case["criterion"] == "points" else None,
            settings=RefinementSettings(
                criterion=case["criterion"],
                estimate_base=case["estimate_base"] if case["criterion"] == "points" else None,
            ),
        )
    assert result.success, result.message
    assert result.fit.cost_history[-1] <= result.fit.start_cost

    # every parameter the data determine on their own is the truth
    names = np.array(ROBOT.parameter_names).reshape(6, 5)
    determined = result.identifiability.free & ~np.isin(names, result.identifiability.confounded)
    error = np.abs(result.parameters.difference(truth))
    bound = np.broadcast_to(TOLERANCE, error.shape)
    assert np.all(error[determined] <= bound[determined]), names[determined][
        np.argmax(error[determined] / bound[determined])
    ]
    # held parameters need not be the truth, but the capture is fitted exactly (noise-free data)
    assert result.fit.residual_max < 1e-9

    # and the rank test holds no more than the layout requires (module notes of refine): where CPA
    # identifies its 20 parameters (every circle a proper circle), the refinement determines them too
    if case["flange"] and not given_base:
        assert set(result.identifiability.gauge) == {"J1.d", "J1.theta"}
    else:
        assert result.identifiability.gauge == ()
    if case["joint6_moves"]:
        try:
            identify_cpa(capture, ROBOT, reflector, tracker_from_base=tracker)
        except InputError:  # a degenerate circle (target on an axis): no CPA reference for this layout
            return
        expected = CPA_IDENTIFIABLE.copy()
        if case["flange"] and not given_base:
            expected[0, [D, THETA]] = False  # gauge: a base motion, or invisible to distances
        missing = expected & ~determined
        assert not missing.any(), names[missing]
