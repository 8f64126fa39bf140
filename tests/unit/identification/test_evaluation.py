"""Before/after evaluation (thesis Tables 4.10/4.11): both views, improvement, invariance."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.identification.evaluation import distance_errors, evaluate_parameters, point_errors
from robotcal.instruments import Instrument
from robotcal.io import load_robot
from robotcal.kinematics.model import ParameterSet, ReflectorMount
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses, simulate_poses

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")
FLANGE = ReflectorMount(frame="flange", positions=[60.0, 40.0, 30.0])
EXACT = Instrument(name="exact", a_mm=0.0, b_mm_per_m=0.0)
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.3, angle_sd_deg=0.05, rng=3)


def _validation(tracker):
    readings = random_poses(ROBOT, 40, rng=1)
    capture, _ = simulate_poses(ROBOT, readings, FLANGE, EXACT, tracker, true_parameters=TRUTH)
    return capture


def test_true_parameters_have_zero_error_in_both_views_whatever_the_tracker_frame():
    tracker = np.eye(4)
    tracker[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    tracker[:3, 3] = [2500.0, -300.0, 100.0]
    capture = _validation(tracker)
    # noise-free: only rounding (~1e-12 mm on 1e3 mm coordinates) and Horn's eigen-solution (~1e-10)
    assert point_errors(capture, TRUTH, FLANGE).max() < 1e-8
    assert distance_errors(capture, TRUTH, FLANGE).max() < 1e-9
    nominal_points = point_errors(capture, ParameterSet.nominal(ROBOT), FLANGE)
    again = point_errors(_validation(np.eye(4)), ParameterSet.nominal(ROBOT), FLANGE)
    np.testing.assert_allclose(nominal_points, again, atol=1e-8)  # invariant to the tracker frame


def test_distance_view_matches_a_direct_computation():
    capture = _validation(np.eye(4))
    errors = distance_errors(capture, ParameterSet.nominal(ROBOT), FLANGE)
    from robotcal.kinematics.forward import target_positions

    predicted = target_positions(
        ROBOT.nominal, ROBOT.model_joint_variables(capture.readings), np.zeros(40, int), FLANGE
    )
    expected = [
        abs(np.linalg.norm(predicted[i] - predicted[j]) - np.linalg.norm(capture.points[i] - capture.points[j]))
        for i in range(40)
        for j in range(i + 1, 40)
    ]
    np.testing.assert_allclose(errors, expected, atol=1e-10)


def test_rows_and_improvement_against_the_first_set():
    capture = _validation(np.eye(4))
    rows = evaluate_parameters(
        {"validation": capture}, {"nominal": ParameterSet.nominal(ROBOT), "truth": TRUTH}, FLANGE
    )
    assert [(r.parameter_set, r.view) for r in rows] == [
        ("nominal", "points"),
        ("truth", "points"),
        ("nominal", "distances"),
        ("truth", "distances"),
    ]
    for row in rows:
        if row.parameter_set == "nominal":
            assert row.improvement_pct == 0.0 and row.mean_error_mm > 0.1
        else:
            assert row.improvement_pct == pytest.approx(100.0, abs=1e-6)
    assert rows[2].n_errors == 40 * 39 // 2
    assert rows[0].max_error_mm >= rows[0].rms_error_mm >= rows[0].mean_error_mm


def test_evaluation_validation():
    capture = _validation(np.eye(4))
    with pytest.raises(InputError, match="unknown evaluation view"):
        evaluate_parameters({"v": capture}, {"n": TRUTH}, FLANGE, views=("angles",))
    with pytest.raises(InputError, match="at least one capture"):
        evaluate_parameters({}, {"n": TRUTH}, FLANGE)
    with pytest.raises(InputError, match="no reflector"):
        evaluate_parameters({"v": capture}, {"n": TRUTH}, {"other": FLANGE})
