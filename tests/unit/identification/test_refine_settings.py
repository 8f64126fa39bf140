"""Issue 31: one settings object per algorithm (refinement, model choice), the result's sub-records filled by the
core, and the model choice's fits in the process pool giving the same result whatever the number of workers."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import robotcal
from robotcal.errors import IdentifiabilityWarning, InputError
from robotcal.identification.health import FitHealth
from robotcal.identification.model_choice import refine_model
from robotcal.identification.records import (
    CrossValidation,
    FitStatistics,
    Identifiability,
    ModelChoice,
    RefinementUncertainty,
)
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import ModelChoiceSettings, RefinementSettings
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
)
TRACKER_NOISE = Instrument(name="laser tracker", a_mm=0.010, b_mm_per_m=0.0025, noise="normal")


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("criterion", "rms"),
        ("estimate_base", "yes"),
        ("free", "J1.d"),
        ("free", np.ones((6, 4), bool)),
        ("on_unidentifiable", "ignore"),
        ("method", "dogbox"),
        ("max_nfev", 0),
        ("max_nfev", True),
        ("tolerance", 0.0),
        ("tolerance", "1e-9"),
        ("rank_tolerance", 2.0),
        ("weights", "equal"),
    ],
)
def test_refinement_settings_name_the_field_and_the_value(field, value):
    with pytest.raises(InputError, match=rf"`{field}` must be") as info:
        RefinementSettings(**{field: value})
    shown = repr(value) if not isinstance(value, np.ndarray) else str(value.shape)
    assert shown in str(info.value)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("model", "best", "unknown model 'best'"),
        ("folds", 1, "`folds` must be 0 .* got 1"),
        ("folds", True, "`folds` must be 0 .* got True"),
        ("seed", -1, "`seed` must be .* got -1"),
        ("harmonic_order", 0, "`harmonic_order` must be .* got 0"),
        ("compliance_joints", [-1], r"`compliance_joints` must be .* got \[-1\]"),
    ],
)
def test_model_choice_settings_name_the_field_and_the_value(field, value, message):
    with pytest.raises(InputError, match=message):
        ModelChoiceSettings(**{field: value})
    with pytest.raises(InputError, match="give at least 2 folds"):
        ModelChoiceSettings(model="auto", folds=0)


def test_settings_are_frozen_and_normalised():
    settings = RefinementSettings(free=["J2.a", "J3.a"], estimate_base=np.bool_(True))
    assert settings.free == ("J2.a", "J3.a") and settings.estimate_base is True and settings.strict
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.method = "lm"
    mask = np.zeros((6, 5), bool)
    held = RefinementSettings(free=mask).free
    mask[0, 0] = True  # the settings keep their own read-only copy
    assert not held.any() and not held.flags.writeable


@pytest.fixture(scope="module")
def small_extended():
    """A KR 5 with J2/J3 compliance and first-order harmonic errors, 30 noisy poses on two flange targets."""
    robot = load_robot("kuka-kr5-sixx-r650")
    rng = np.random.default_rng(5)
    masses = robot.masses.with_payload(3.0, [0.0, 0.0, 60.0])
    model = JointModel.build(robot, compliance_joints=[1, 2], masses=masses, harmonic_joints=range(6))
    values = robot.nominal + np.where(robot.structurally_fixed, 0.0, rng.normal(0.0, 1e-3, (6, 5)))
    truth = ParameterSet(robot=robot, values=values, joint_model=model.with_values(np.r_[5e-5, 2e-4, np.zeros(12)]))
    readings = rng.uniform(robot.limits[:, 0] * 0.9, robot.limits[:, 1] * 0.9, (30, 6))
    capture = simulate_target_poses(robot, readings, TARGETS, TRACKER_NOISE, TRACKER, true_parameters=truth, rng=rng)[0]
    return dataclasses.replace(robot, masses=masses), capture


def test_the_core_fills_every_sub_record(small_extended):
    robot, capture = small_extended
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine_parameters(
            capture, ParameterSet.nominal(robot), TARGETS, tracker_from_base=TRACKER, instrument=TRACKER_NOISE,
            settings=RefinementSettings(weights="none"),
        )  # fmt: skip
    assert isinstance(result.fit, FitStatistics) and result.fit.n_residuals == 3 * capture.n_points
    assert isinstance(result.identifiability, Identifiability)
    assert len(result.identifiability.free_names) == result.uncertainty.covariance.shape[0]
    assert isinstance(result.uncertainty, RefinementUncertainty) and np.isfinite(result.uncertainty.sigma)
    assert isinstance(result.health, FitHealth) and result.health.noise_sd_mm is not None  # the instrument's
    assert result.cross_validation is None and result.model_choice is None  # one fit: nothing to validate
    chosen = refine_model(
        capture, ParameterSet.nominal(robot), TARGETS, tracker_from_base=TRACKER, instrument=TRACKER_NOISE,
        choice=ModelChoiceSettings(model="geometric", folds=3),
    )  # fmt: skip
    assert isinstance(chosen.cross_validation, CrossValidation) and chosen.cross_validation.folds == 3
    assert chosen.model_choice is None and isinstance(chosen.health, FitHealth)
    np.testing.assert_array_equal(chosen.parameters.values, result.parameters.values)


def test_auto_gives_the_same_result_whatever_the_number_of_workers(small_extended):
    robot, capture = small_extended
    results, caught = [], []
    for workers in (1, 2):
        progress = []
        with warnings.catch_warnings(record=True) as found:
            warnings.simplefilter("always")
            results.append(
                robotcal.refine(
                    capture, robot, targets=TARGETS, tracker_from_base=TRACKER, model="auto", folds=3, health="off",
                    workers=workers, progress=lambda done, total, what, log=progress: log.append((done, total, what)),
                )  # fmt: skip
            )
        caught.append([(w.category, str(w.message)) for w in found])
        assert progress[0] == (1, 16, "geometric") and progress[-1] == (16, 16, "compliance+harmonic CV")
    serial, pooled = results
    assert isinstance(serial.model_choice, ModelChoice) and serial.model_choice.chosen == serial.model
    np.testing.assert_array_equal(serial.parameters.values, pooled.parameters.values)
    np.testing.assert_array_equal(serial.uncertainty.covariance, pooled.uncertainty.covariance)
    assert serial.model_choice.to_dict() == pooled.model_choice.to_dict()
    assert serial.cross_validation.to_dict() == pooled.cross_validation.to_dict()
    assert serial.health == pooled.health and serial.message == pooled.message
    assert caught[0] == caught[1]  # the chosen model's warnings, and those alone, once
    # what came back from a worker is as frozen as what was made here
    assert not pooled.parameters.values.flags.writeable and not pooled.uncertainty.covariance.flags.writeable


def test_api_refine_takes_the_settings_whole_or_as_keywords(small_extended):
    robot, capture = small_extended
    common = dict(targets=TARGETS, tracker_from_base=TRACKER, folds=0, health="off")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        whole = robotcal.refine(capture, robot, settings=RefinementSettings(criterion="points", weights="none"), **common)
        keywords = robotcal.refine(capture, robot, weights="none", **common)
    np.testing.assert_array_equal(whole.parameters.values, keywords.parameters.values)
    with pytest.raises(InputError, match="not both"):
        robotcal.refine(capture, robot, settings=RefinementSettings(), weights="none", **common)
