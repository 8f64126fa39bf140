"""Lumped compliance with the smallest set of terms the data determine, announced (issue 29, item 5): without link
masses `--model compliance` fitted all 18 torque shapes of J2 and J3 silently; it now starts from the largest
shape per joint and adds shapes only while cross-validation (or, without folds, an F test) supports them."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import robotcal
from robotcal.errors import IdentifiabilityWarning
from robotcal.identification.model_choice import (
    FitTask,
    ModelChoiceSettings,
    _validation,
    joint_model_for,
    pose_folds,
    run_fit,
)
from robotcal.identification.settings import RefinementSettings
from robotcal.io.schema.builtins import data_path
from robotcal.kinematics.joint_model import JointModel, lumped_levels
from robotcal.resolve import capture_targets

EXPECTED = ("J2.g1", "J2.g2", "J3.g1", "J3.g2")


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    """The kr5-demo cell (its truth sags with known masses) refined with a robot file that gives no masses."""
    folder = tmp_path_factory.mktemp("no-masses")
    robot = data_path("robots", "kuka-kr5-sixx-r650.toml").read_text()
    robot = re.sub(r"^(mass_kg|com_mm|mass_source) = .*\n", "", robot, flags=re.M)
    (folder / "kr5-no-masses.toml").write_text(robot.replace('"kuka-kr5-sixx-r650"', '"kr5-no-masses"', 1))
    text = data_path("scenarios", "kr5-demo.toml").read_text()
    (folder / "no-masses.toml").write_text(text.replace('robot = "kuka-kr5-sixx-r650"', 'robot = "kr5-no-masses.toml"'))
    no_masses = robotcal.load_scenario(folder / "no-masses.toml")
    assert no_masses.robot.masses is None
    scenario = robotcal.load_scenario("kr5-demo")
    truth = robotcal.perturb(scenario, rng=11)
    capture = robotcal.simulate(scenario, rng=1, true_parameters=truth, joint_errors=None)
    poses = robotcal.simulate_poses(scenario, kind="calibration", rng=3, true_parameters=truth)
    fitted = robotcal.calibration_capture(scenario, capture, poses)
    start = robotcal.identify(capture, no_masses)
    return no_masses, fitted, start


def _refine(cell, folds):
    no_masses, fitted, start = cell
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = robotcal.refine(fitted, no_masses, start, model="compliance", folds=folds)
    said = [str(w.message) for w in caught if issubclass(w.category, IdentifiabilityWarning) and "lumped" in str(w)]
    return result, said


def test_the_lumped_levels_are_nested_largest_shapes_first():
    scenario = robotcal.load_scenario("kr5-demo")
    model = JointModel.build(scenario.robot, compliance_joints=[1, 2])
    levels = lumped_levels(model, scenario.robot)
    assert len(levels) == 10 and levels[-1].names == model.names  # J2: 10 shapes, J3: 8
    assert levels[0].names == ("J2.g1", "J3.g1") and levels[1].names == EXPECTED
    for smaller, larger in zip(levels, levels[1:], strict=False):
        assert set(smaller.names) < set(larger.names)
    assert lumped_levels(JointModel.build(scenario.robot, harmonic_joints=[0]), scenario.robot)[0].names == (
        "J1.a1",
        "J1.b1",
    )


def test_cross_validation_keeps_the_smallest_set_that_holds_out_as_well_and_says_so(cell):
    result, said = _refine(cell, folds=5)
    assert result.parameters.joint_model.names == EXPECTED
    (note,) = said
    assert "no link masses" in note and "J2.g1, J2.g2, J3.g1, J3.g2 (J2: 2 of 10, J3: 2 of 8" in note
    assert "cross-validation chose them" in note
    # every level's CV error, each fitted on its own: the chosen set is within one standard error of the best of
    # all 10, and the set below it is not
    no_masses, fitted, start = cell
    choice = ModelChoiceSettings(model="compliance", folds=5)
    fold_of = pose_folds(fitted, 5, 0)
    full = joint_model_for("compliance", no_masses.robot, masses=None)
    records = []
    for level in lumped_levels(full, no_masses.robot):
        common = dict(
            model="compliance", capture=fitted, start=start.parameters.geometric(),
            targets=capture_targets(no_masses, fitted), settings=RefinementSettings(),
            tracker_from_base=no_masses.tracker_from_base,
            joint_model=level,
        )  # fmt: skip
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            whole = run_fit(FitTask(**common)).result
            folds = [run_fit(FitTask(**common, fold=k, fold_of=fold_of)) for k in range(5)]
        records.append(_validation(str(level.size), whole, [(f.success, f.held_out) for f in folds], choice))
    mse = np.array([record.cv_mse_mm2 for record in records])
    best = int(np.argmin(mse))
    assert mse[1] <= mse[best] + records[best].se_mm2
    assert mse[0] > mse[best] + records[best].se_mm2
    assert result.cross_validation.cv_mse_mm2 == pytest.approx(mse[1], rel=1e-9)


def test_without_folds_an_f_test_chooses_the_same_set(cell):
    result, said = _refine(cell, folds=0)
    assert result.parameters.joint_model.names == EXPECTED
    (note,) = said
    assert re.search(r"3 per joint did not lower the residual significantly \(F test, p = 0\.\d+\)", note)


def test_known_masses_are_not_lumped_and_not_announced():
    scenario = robotcal.load_scenario("kr5-demo")
    truth = robotcal.perturb(scenario, rng=11)
    capture = robotcal.simulate(scenario, rng=1, true_parameters=truth, joint_errors=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        start = robotcal.identify(capture, scenario)
    result, said = _refine((scenario, capture, start), folds=0)
    assert result.parameters.joint_model.names == ("J2.k", "J3.k") and said == []
