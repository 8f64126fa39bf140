"""Refinement: the free set is decided again at the solution (module notes of refine, "at the solution").

Two constructed noise-free captures whose rank at the nominal start differs from the rank at the truth:

* a known flange target on axis 6 of the nominal robot (0, 0, 30 mm in frame 6, a6 = alpha6 = 0): at the nominal
  it is a fixed point of frame 5, so J5's parameters look undeterminable and are held; the true robot has
  a6 = 1 mm, so joint 6 turns the target on a 1 mm circle that places axis 6 and determines J5 (the truth's rank
  is higher). Held at the nominal, they leave a noise-free residual; decided again at the solution, every
  parameter the data determine comes back to 1e-9 of the truth.
* an unknown flange offset on axis 6 of the true robot: joint 6 turns it nowhere, so J5.a and J5.alpha are not
  determined at the truth, while the rank test at the guess (moved 50 mm off the axis) frees them. They are
  reported held at their start values, the capture is still fitted exactly, and what depends on them is listed
  as confounded.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import refine_options
import robotcal.identification.refine as refine_module
from robotcal.errors import IdentifiabilityError, IdentifiabilityWarning
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io import load_robot
from robotcal.kinematics.model import ParameterSet, ReflectorMount
from robotcal.simulation import CapturePlan, simulate_capture
from robotcal.simulation.generator import simulate_target_poses
from robotcal.simulation.perturb import perturbable_mask
from robotcal.simulation.poses import random_poses

ROBOT = load_robot("kuka-kr5-sixx-r650")
EXACT = Instrument(name="exact", a_mm=0.0, b_mm_per_m=0.0)
TRACKER = np.array([[0.0, 1.0, 0.0, 1800.0], [-1.0, 0.0, 0.0, 5.0], [0.0, 0.0, 1.0, 600.0], [0.0, 0.0, 0.0, 1.0]])
NAMES = np.array(ROBOT.parameter_names).reshape(6, 5)
# noise-free: the solver stops at ~1e-11 here (condition number ~1e5: J5 seen through a 1 mm circle)
EXACT_TOL = np.array([1e-9, np.deg2rad(1e-9), 1e-9, np.deg2rad(1e-9), np.deg2rad(1e-9)])
ON_AXIS6 = ReflectorMount(frame="flange", positions=[0.0, 0.0, 30.0])


def _truth(seed, *, joint6=(0.0, 0.0, 0.0)):
    """Joints 1-5 moved by up to 0.4 mm / 0.1 deg; joint 6's d [mm], theta [rad], a [mm] moved by ``joint6``."""
    rng = np.random.default_rng(seed)
    mask = perturbable_mask(ROBOT, include_base=True)
    mask[5] = False
    bound = np.array([0.4, np.deg2rad(0.1), 0.4, np.deg2rad(0.1), np.deg2rad(0.1)])
    values = ROBOT.nominal + np.where(mask, rng.uniform(-1.0, 1.0, (6, 5)) * bound, 0.0)
    values[5, :3] += joint6
    return ParameterSet(robot=ROBOT, values=values)


def _circles(reflector, truth):
    plan = CapturePlan(
        start=np.deg2rad([15.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        sweep=np.deg2rad([45.0, 80.0, 100.0, 50.0, 200.0, 300.0]),
        points=np.array([10, 10, 12, 10, 10, 12]),
        reflector=reflector,
    )
    capture, _ = simulate_capture(ROBOT, plan, EXACT, TRACKER, true_parameters=truth, joint_limits="ignore")
    return capture


def _determined(result):
    return result.identifiability.free & ~np.isin(NAMES, result.identifiability.confounded)


def _refine(*args, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IdentifiabilityWarning)
        result = refine_options.refine(*args, **kwargs)
    return result, [str(w.message) for w in caught if issubclass(w.category, IdentifiabilityWarning)]


@pytest.mark.parametrize("criterion", ["points", "distances"])
def test_a_parameter_held_at_the_nominal_and_determined_at_the_truth_is_freed_at_the_solution(criterion, monkeypatch):
    truth = _truth(3, joint6=(0.3, np.deg2rad(0.1), 1.0))  # a6 = 1 mm: the target 1 mm off axis 6
    capture = _circles(ON_AXIS6, truth)
    base = {"tracker_from_base": TRACKER} if criterion == "points" else {}

    # the construction: the rank test at the nominal start alone holds J5 and leaves a noise-free residual
    monkeypatch.setattr(refine_module, "_MAX_REFITS", 0)
    at_start, _ = _refine(capture, ParameterSet.nominal(ROBOT), ON_AXIS6, criterion=criterion, **base)
    assert {"J5.a", "J5.alpha"} <= set(at_start.identifiability.held)
    assert at_start.fit.residual_max > 1e-4  # (measured: 7.6e-4 mm points, 1.0e-3 mm distances)
    monkeypatch.undo()

    result, messages = _refine(capture, ParameterSet.nominal(ROBOT), ON_AXIS6, criterion=criterion, **base)
    assert result.success, result.message
    assert result.fit.refits == 1
    assert not {"J5.d", "J5.theta", "J5.a", "J5.alpha"} & set(result.identifiability.held + result.identifiability.confounded)
    # joint 6 keeps one of d, theta, a, alpha held (the target is 3 numbers in frame 6): the others confounded
    assert len([name for name in result.identifiability.held if name.startswith("J6.")]) == 1
    assert result.fit.residual_max < 1e-9
    error = np.abs(result.parameters.difference(truth))
    determined = _determined(result)
    expected = ~ROBOT.structurally_fixed
    expected[5] = False  # J6: one held, the others tied to it
    if criterion == "distances":
        expected[0, :2] = False  # d1, theta1: a rigid motion, invisible to distances (gauge)
    assert np.all(determined[expected]), NAMES[expected & ~determined]
    bound = np.broadcast_to(EXACT_TOL, error.shape)
    assert np.all(error[determined] <= bound[determined]), NAMES[determined][np.argmax(error[determined])]
    assert any("at the solution" in text and "refitted (1 refit)" in text for text in messages), messages


def test_a_parameter_not_determined_at_the_truth_is_reported_held_at_its_start_value():
    truth = _truth(5)  # joint 6 nominal: the flange frame the unknown offset is estimated in
    true_offset = np.array([[0.0, 0.0, 30.0]])  # on axis 6
    targets = [Target(name="T0", frame="flange", positions=np.zeros(3), known=False)]
    readings = random_poses(ROBOT, 15, rng=np.random.default_rng(2))
    capture, _ = simulate_target_poses(
        ROBOT, readings, targets, EXACT, TRACKER, true_parameters=truth, true_offsets=true_offset
    )
    start = ParameterSet.nominal(ROBOT)
    result, messages = _refine(capture, start, targets, tracker_from_base=TRACKER)
    assert result.success, result.message
    assert result.fit.refits >= 1
    # the target is a fixed point of frame 5: J5's d, theta, a, alpha and the offset place one circle about
    # axis 5 (3 numbers, x and y of the offset are fixed by joint 6 turning): a and alpha are held (the offset
    # comes first in the order: its guess is rough, the nominal parameters are not) at their start values
    assert {"J5.a", "J5.alpha"} <= set(result.identifiability.held)
    held = np.isin(NAMES, result.identifiability.held)
    np.testing.assert_array_equal(result.parameters.values[held], start.values[held])
    assert {"J5.d", "J5.theta", "target.T0.z"} <= set(result.identifiability.confounded)
    assert np.all(np.isnan(result.uncertainty.standard_uncertainty[held]))
    # what the data determine is fitted exactly: the capture to 1e-9 mm, joints 1-4 to the truth
    assert result.fit.residual_max < 1e-9
    error = np.abs(result.parameters.difference(truth))
    determined = _determined(result)
    assert np.all(determined[:4][~ROBOT.structurally_fixed[:4]])
    assert np.all(error[determined] <= np.broadcast_to(EXACT_TOL, error.shape)[determined])
    np.testing.assert_allclose(result.targets[0].positions[:2], true_offset[0, :2], rtol=0, atol=1e-9)
    # the held values differ from the truth's (J5.a moved), so the offset along the axis takes up the difference
    assert abs(truth.values[4, 2] - start.values[4, 2]) > 1e-3
    assert abs(result.targets[0].positions[2] - true_offset[0, 2]) > 1e-6
    assert result.identifiability.condition_number < 1e8  # the free set is well determined at the solution
    assert any("J5.a, J5.alpha" in text and "at the solution" in text for text in messages), messages

    with pytest.raises(IdentifiabilityError, match="at the solution") as info:
        refine_parameters(
            capture,
            start,
            targets,
            tracker_from_base=TRACKER,
            settings=RefinementSettings(on_unidentifiable="raise"),
        )
    assert {"J5.a", "J5.alpha"} <= set(info.value.parameters)


def test_a_capture_whose_start_decision_holds_at_the_solution_is_fitted_once():
    truth = _truth(7)
    reflector = ReflectorMount(frame="flange", positions=[60.0, 40.0, 30.0])
    result, messages = _refine(_circles(reflector, truth), ParameterSet.nominal(ROBOT), reflector)
    assert result.fit.refits == 0
    assert result.identifiability.held == ("J6.alpha",) and result.fit.residual_max < 1e-9
    assert messages and all("at the solution" in text and "refit" not in text for text in messages)


def test_a_free_set_that_does_not_settle_returns_the_last_fit_and_says_so(monkeypatch):
    """The rounds stop on a free set seen before (forced here: the test at the first solution is made to swap
    J6.a and J6.alpha, the one at the second to return the start's decision)."""
    real = refine_module.select_free
    calls = []

    def swapping(*args, **kwargs):
        chosen = real(*args, **kwargs)
        calls.append(chosen)
        if len(calls) == 2:  # the first solution: hold J6.a instead of J6.alpha
            free, held = chosen.free.copy(), chosen.held.copy()
            free[5, 2], held[5, 2], free[5, 3], held[5, 3] = False, True, True, False
            return dataclasses.replace(chosen, free=free, held=held)
        return calls[0] if len(calls) == 3 else chosen

    monkeypatch.setattr(refine_module, "select_free", swapping)
    truth = _truth(7)
    reflector = ReflectorMount(frame="flange", positions=[60.0, 40.0, 30.0])
    result, messages = _refine(_circles(reflector, truth), ParameterSet.nominal(ROBOT), reflector)
    assert len(calls) == 3 and result.fit.refits == 1
    assert result.identifiability.held == ("J6.a",)  # the last fit's free set
    assert "the free set did not settle" in result.message
    assert any("did not settle" in text and "returns to an earlier free set" in text for text in messages)
    assert result.fit.residual_max < 1e-9  # J6 is nominal in this truth: holding J6.a there is exact too


@pytest.mark.parametrize("failure", ["stops", "stalls"])
def test_a_refit_that_fails_returns_the_fit_it_started_from(failure, monkeypatch):
    """A refit (forced here, by swapping J6.a and J6.alpha at the first solution) that stops before converging,
    or stalls at its start, must not throw away the exact first fit: the first fit is returned, its free set
    reported, and the message says the refit failed."""
    from scipy.optimize import OptimizeResult

    real_select, real_solve = refine_module.select_free, refine_module.least_squares
    selections, solves = [], []

    def swapping(*args, **kwargs):
        chosen = real_select(*args, **kwargs)
        selections.append(chosen)
        if len(selections) == 2:
            free, held = chosen.free.copy(), chosen.held.copy()
            free[5, 2], held[5, 2], free[5, 3], held[5, 3] = False, True, True, False
            return dataclasses.replace(chosen, free=free, held=held)
        return chosen

    def failing_refit(fun, x0, *args, **kwargs):
        solves.append(x0)
        if len(solves) == 1:
            return real_solve(fun, x0, *args, **kwargs)
        if failure == "stops":
            return real_solve(fun, x0, *args, **{**kwargs, "max_nfev": 1})
        start = fun(x0)
        return OptimizeResult(x=x0.copy(), cost=0.5 * float(start @ start), status=2, nfev=1, njev=1, message="stalled")

    monkeypatch.setattr(refine_module, "select_free", swapping)
    monkeypatch.setattr(refine_module, "least_squares", failing_refit)
    truth = _truth(7, joint6=(0.2, np.deg2rad(0.05), 0.4))  # J6 off nominal: the refit starts far from the fit
    reflector = ReflectorMount(frame="flange", positions=[60.0, 40.0, 30.0])
    result, messages = _refine(_circles(reflector, truth), ParameterSet.nominal(ROBOT), reflector)
    assert len(solves) == 2 and result.fit.refits == 1
    assert result.success and result.identifiability.held == ("J6.alpha",)  # the first fit, with its free set
    outcome = "did not converge" if failure == "stops" else "ended at a higher cost"
    assert f"fit 1 {outcome}" in result.message and "fit 1 is returned" in result.message
    assert any("fit 1 is returned" in text for text in messages)
    # the first fit's noise-free residual (exact), not the refit's (0.01 mm^2 after one evaluation, or its start)
    assert result.fit.residual_max < 1e-9
