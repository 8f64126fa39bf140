"""Issue 30, item 2: the joint model of a parameter JSON is checked when it is read.

A JSON with ``J2.k = 1.0 rad/(N m)`` was used by ``predict`` (1,063 mm from nominal) and ``simulate --true-params``
without a word, and a harmonic order of 99 was read although a scenario allows 1..4. Both files are written by
:func:`robotcal.write_parameters`, then edited, as a user would.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io import load_robot, read_parameters, write_parameters
from robotcal.io.schema.scenario import scenario_from_dict
from robotcal.kinematics.joint_model import MAX_DEFLECTION_DEG, MAX_HARMONIC_ORDER, JointModel
from robotcal.kinematics.model import ParameterSet

ROBOT = "kuka-kr5-sixx-r650"


@pytest.fixture(scope="module")
def kr5():
    return load_robot(ROBOT)


def _written(tmp_path, robot, *, payload_kg=0.0, compliance=(1e-5, 4e-5), harmonic_deg=0.01, order=1):
    """A parameter JSON of an extended KR 5 (J2, J3 compliant, J4 harmonic errors) as robotcal writes it."""
    masses = robot.masses.with_payload(payload_kg, [0.0, 0.0, 60.0])
    model = JointModel.build(
        robot, compliance_joints=[1, 2], masses=masses, harmonic_joints=[3], harmonic_order=order
    )
    values = np.r_[compliance, np.full(2 * order, np.deg2rad(harmonic_deg))]
    path = tmp_path / "extended.json"
    write_parameters(path, ParameterSet(robot=robot, values=robot.nominal, joint_model=model.with_values(values)))
    return path


def _edit(path, index: int, **changes):
    document = json.loads(path.read_text(encoding="utf-8"))
    document["joint_model"]["parameters"][index].update(changes)
    path.write_text(json.dumps(document), encoding="utf-8")
    return document["joint_model"]["parameters"][index]


def test_written_models_read_back(tmp_path, kr5):
    """The demo's compliances, and the exaggerated ones of the extended-refinement tests (2e-4 rad/(N m) with a
    3 kg payload: J3 sags by ~0.23 deg), read without a word."""
    for kwargs in ({}, {"payload_kg": 3.0, "compliance": (5e-5, 2e-4)}, {"order": MAX_HARMONIC_ORDER}):
        parameters = read_parameters(_written(tmp_path, kr5, **kwargs), kr5)
        assert parameters.joint_model is not None and parameters.joint_model.size == 2 + 2 * kwargs.get("order", 1)


def test_a_compliance_that_moves_the_flange_by_centimetres_is_refused(tmp_path, kr5):
    path = _written(tmp_path, kr5)
    _edit(path, 0, value=1.0)  # J2.k: 1 rad/(N m), 1e5 times the demo's
    with pytest.raises(InputError) as caught:
        read_parameters(path, kr5)
    message = str(caught.value)
    assert message.startswith(f"{path}: key `joint_model.parameters[0].value`: J2.k = 1 rad/(N m)")
    assert "deflects J2 by 1.73e+03 deg" in message and f"more than the {MAX_DEFLECTION_DEG:g} deg" in message


def test_a_compliance_just_above_the_bound_is_refused_and_one_below_is_read(tmp_path, kr5):
    """J2's gravity torque on the unloaded KR 5 reaches ~30 N m: 1 deg of deflection is ~5.8e-4 rad/(N m)."""
    path = _written(tmp_path, kr5)
    _edit(path, 0, value=2.5e-4)  # ~0.43 deg: a soft joint, still a joint
    read_parameters(path, kr5)
    _edit(path, 0, value=1e-3)  # ~1.7 deg
    with pytest.raises(
        InputError,
        match=r"parameters\[0\]\.value`: J2\.k = 0\.001 rad/\(N m\) deflects J2 by 1\.7\d? deg at the readings "
        r"\[[-0-9., ]+\] deg and moves the flange by \d+\.\d mm: more than",
    ):
        read_parameters(path, kr5)


def test_a_harmonic_amplitude_above_the_bound_is_refused(tmp_path, kr5):
    path = _written(tmp_path, kr5)
    _edit(path, 3, value=2.0)  # J4.b1: 2 deg
    with pytest.raises(InputError, match=r"key `joint_model\.parameters\[3\]\.value`: J4\.b1 = 2 deg deflects J4 by"):
        read_parameters(path, kr5)


@pytest.mark.parametrize("name", ["J4.a99", f"J4.b{MAX_HARMONIC_ORDER + 1}"])
def test_a_harmonic_order_outside_the_scenarios_range_is_refused(tmp_path, kr5, name):
    path = _written(tmp_path, kr5)
    _edit(path, 2, name=name)
    order = name.split(".")[1][1:]
    with pytest.raises(
        InputError,
        match=rf"{path.name}: key `joint_model\.parameters\[2\]\.name`: {name}: harmonic order {order} is outside "
        rf"1\.\.{MAX_HARMONIC_ORDER}",
    ):
        read_parameters(path, kr5)


def test_the_scenario_and_the_joint_model_share_one_range():
    base = {"robot": ROBOT}
    scenario_from_dict(base | {"joint_model": {"harmonic_order": MAX_HARMONIC_ORDER}}, source="s.toml")
    with pytest.raises(InputError, match=rf"harmonic_order`: must be <= {MAX_HARMONIC_ORDER}"):
        scenario_from_dict(base | {"joint_model": {"harmonic_order": MAX_HARMONIC_ORDER + 1}}, source="s.toml")
    with pytest.raises(InputError, match=rf"harmonic order must be 1\.\.{MAX_HARMONIC_ORDER}"):
        JointModel.build(load_robot(ROBOT), harmonic_joints=[3], harmonic_order=MAX_HARMONIC_ORDER + 1)
