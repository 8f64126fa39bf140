"""Refinement of the extended model (issue 22): gravity compliance and harmonic joint errors recovered from free
poses with three flange targets, the geometric model's held-out error beside it, and the model choice by
cross-validation."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import robotcal
from robotcal.errors import IdentifiabilityWarning
from robotcal.identification.model_choice import CrossValidation, choose_model, pose_folds
from robotcal.identification.refine import refine_parameters
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io import load_robot
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.generator import simulate_target_poses

TRACKER = np.array([[1.0, 0, 0, 1800.0], [0, 1.0, 0, 0], [0, 0, 1.0, 600.0], [0, 0, 0, 1.0]])
TARGETS = (
    Target(name="A", frame="flange", positions=[60.0, 40.0, 30.0]),
    Target(name="B", frame="flange", positions=[-50.0, 60.0, 20.0]),
    Target(name="C", frame="flange", positions=[0.0, -70.0, 40.0]),
)
NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)
TRACKER_NOISE = Instrument(name="laser tracker", a_mm=0.010, b_mm_per_m=0.0025, noise="normal")


@pytest.fixture(scope="module")
def kr5():
    return load_robot("kuka-kr5-sixx-r650")


def _truth(robot, rng, *, harmonic_deg=0.01):
    """A perturbed KR 5 with J2/J3 compliance (the issue's 5e-5 and 2e-4 rad/(N m)), a 3 kg payload and first-order
    harmonic errors on every joint."""
    values = robot.nominal.copy()
    free = ~robot.structurally_fixed
    lengths = np.zeros((6, 5), dtype=bool)
    lengths[:, [0, 2]] = True
    values[free & lengths] += rng.normal(0.0, 0.3, int((free & lengths).sum()))
    values[free & ~lengths] += rng.normal(0.0, np.deg2rad(0.1), int((free & ~lengths).sum()))
    masses = robot.masses.with_payload(3.0, [0.0, 0.0, 60.0])
    model = JointModel.build(robot, compliance_joints=[1, 2], masses=masses, harmonic_joints=range(6))
    extras = np.r_[5e-5, 2e-4, rng.normal(0.0, np.deg2rad(harmonic_deg), 12)]
    return ParameterSet(robot=robot, values=values, joint_model=model.with_values(extras))


def _poses(robot, rng, count):
    return rng.uniform(robot.limits[:, 0] * 0.9, robot.limits[:, 1] * 0.9, (count, 6))


def _capture(robot, truth, readings, instrument, rng):
    return simulate_target_poses(robot, readings, TARGETS, instrument, TRACKER, true_parameters=truth, rng=rng)[0]


def _held_out_rms(robot, parameters, truth, readings) -> float:
    """RMS distance between the fitted and the true flange target A at held-out poses [mm]."""
    fitted = _capture(robot, parameters, readings, NOISE_FREE, 0).points
    true = _capture(robot, truth, readings, NOISE_FREE, 0).points
    return float(np.sqrt(np.mean(np.sum((fitted - true) ** 2, axis=1))))


def test_noise_free_recovery_of_compliance_and_harmonics(kr5):
    """The issue's test: every parameter to <= 1e-8 (mm, deg) and k to <= 1e-6 relative from the nominal start;
    the geometric model on the same data at least 50x worse on held-out poses."""
    rng = np.random.default_rng(3)
    truth = _truth(kr5, rng)
    capture = _capture(kr5, truth, _poses(kr5, rng, 60), NOISE_FREE, rng)
    structure = truth.joint_model.with_values(np.zeros(truth.joint_model.size))
    start = ParameterSet(robot=kr5, values=kr5.nominal, joint_model=structure)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IdentifiabilityWarning)  # every parameter is determined
        result = refine_parameters(capture, start, TARGETS, tracker_from_base=TRACKER)
    assert result.success and result.model == "compliance+harmonic" and result.identifiability.held == ()
    difference = result.parameters.difference(truth)
    difference[:, 1:] = np.rad2deg(difference[:, 1:])
    assert np.abs(difference).max() <= 1e-8  # mm, deg
    fitted = result.parameters.joint_model.values
    assert np.all(np.abs(fitted[:2] / truth.joint_model.values[:2] - 1.0) <= 1e-6)  # k, relative
    assert np.rad2deg(np.abs(fitted[2:] - truth.joint_model.values[2:])).max() <= 1e-8  # harmonic amplitudes, deg
    held_out = _poses(kr5, rng, 40)
    geometric = refine_parameters(capture, ParameterSet.nominal(kr5), TARGETS, tracker_from_base=TRACKER)
    extended_error = _held_out_rms(kr5, result.parameters, truth, held_out)
    geometric_error = _held_out_rms(kr5, geometric.parameters, truth, held_out)
    assert geometric_error >= 50.0 * max(extended_error, 1e-9) and geometric_error > 0.1  # mm: the sag is real


def _auto_picks(kr5, seed) -> str:
    rng = np.random.default_rng(seed)
    truth = _truth(kr5, rng)
    capture = _capture(kr5, truth, _poses(kr5, rng, 40), TRACKER_NOISE, rng)
    # the robot as the user gives it: its link masses with the payload on the flange
    loaded = dataclasses.replace(kr5, masses=truth.joint_model.masses)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = robotcal.refine(capture, loaded, targets=TARGETS, tracker_from_base=TRACKER, model="auto", health="off")
    assert result.model_choice.chosen == result.model
    assert {c.model for c in result.model_choice.candidates} == {
        "geometric", "compliance", "harmonic", "compliance+harmonic"
    }
    return result.model


def test_auto_picks_the_true_model(kr5):
    """Reduced version (3 seeds, every one right) of the slow test below."""
    assert [_auto_picks(kr5, seed) for seed in range(3)] == ["compliance+harmonic"] * 3


@pytest.mark.slow
def test_auto_picks_the_true_model_in_nine_of_ten_seeds(kr5):
    """The issue's criterion: noisy data (laser tracker, 40 poses x 3 targets), at least 9 of 10 seeds."""
    picks = [_auto_picks(kr5, seed) for seed in range(100, 110)]
    assert picks.count("compliance+harmonic") >= 9, picks


def test_cross_validation_deals_whole_poses_into_folds(kr5):
    rng = np.random.default_rng(5)
    capture = _capture(kr5, ParameterSet.nominal(kr5), _poses(kr5, rng, 23), NOISE_FREE, rng)
    folds = pose_folds(capture, 5, seed=0)
    # every target of a pose (3 rows of the same readings) lands in the same fold; the folds are balanced
    assert np.all(folds.reshape(23, 3) == folds.reshape(23, 3)[:, :1])
    assert sorted(np.bincount(folds[::3])) == [4, 4, 5, 5, 5]
    np.testing.assert_array_equal(folds, pose_folds(capture, 5, seed=0))
    assert not np.array_equal(folds, pose_folds(capture, 5, seed=1))


def _validation(model, unknowns, mse, se):
    return CrossValidation(
        model=model, unknowns=unknowns, folds=5, seed=0, calibration_rms_mm=0.0, cv_rms_mm=mse**0.5,
        fold_mse_mm2=np.full(5, mse), se_mm2=se,
    )  # fmt: skip


def test_one_standard_error_rule():
    candidates = [
        _validation("geometric", 24, 0.0700, 0.002),
        _validation("compliance", 26, 0.0205, 0.001),
        _validation("harmonic", 36, 0.0400, 0.002),
        _validation("compliance+harmonic", 38, 0.0200, 0.001),
    ]
    # 0.0205 <= 0.0200 + 0.001: compliance is within one SE of the best and simpler
    choice = choose_model(candidates)
    assert choice.chosen == "compliance" and "within one standard error" in choice.reason
    candidates[1] = _validation("compliance", 26, 0.0215, 0.001)  # now outside: the best model is kept
    choice = choose_model(candidates)
    assert choice.chosen == "compliance+harmonic" and "outside one standard error" in choice.reason
