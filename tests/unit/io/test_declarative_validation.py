"""Issue 31, item 3: the scenario, robot, instrument presets and parameter JSON are validated by schema.

Types and ranges are stated once next to each key; the message is generated from the schema's verdict by one
formatter and names the file, the key path and the value as the file wrote it (``true``, ``"12"``).
"""

from __future__ import annotations

import json
import re

import pytest

from robotcal.errors import InputError
from robotcal.io.formats.parameters_json import read_parameters, read_targets
from robotcal.io.schema._validation import validate_model
from robotcal.io.schema.instruments import InstrumentPreset, instrument_presets, make_instrument
from robotcal.io.schema.robots import load_robot
from robotcal.io.schema.scenario import scenario_from_dict

ROBOT = "kuka-kr5-sixx-r650"


def _scenario_error(**tables) -> str:
    with pytest.raises(InputError) as caught:
        scenario_from_dict({"robot": ROBOT, **tables}, source="s.toml")
    return str(caught.value)


@pytest.mark.parametrize(
    ("tables", "expected"),
    [
        (
            {"tracker_from_base": [[1.0, 0.0, 0.0, 0.0]] * 3},
            "key `tracker_from_base`: must be a 4x4 matrix; got 3 rows",
        ),
        (
            {"tracker_from_base": [[1.0, 0.0, 0.0]] + [[0.0, 1.0, 0.0, 0.0]] * 3},
            "key `tracker_from_base[0]`: must be a row of 4 numbers; got 3 values",
        ),
        ({"capture": {"flange_reflector_mm": [0.0, 50.0]}}, "key `capture.flange_reflector_mm`: must be [x, y, z]"),
        ({"capture": {"reflector_mm": [[0.0, 1.0]]}}, "key `capture.reflector_mm[0]`: must be [x, y, z]; got 2 values"),
        ({"truth": {"compliance_rad_per_nm": [0.0, -1e-5]}}, "key `truth.compliance_rad_per_nm[1]`: must be >= 0"),
        ({"joint_model": {"compliance_joints": [0, 2]}}, "key `joint_model.compliance_joints[0]`: must be >= 1; got 0"),
        ({"joint_model": {"folds": 1}}, "key `joint_model`: folds must be 0 (no cross-validation) or at least 2"),
        ({"capture": {"joint_limits": "never"}}, "key `capture.joint_limits`: must be 'warn', 'error' or 'ignore'"),
        ({"capture": 5}, "key `capture`: must be a table {...}; got 5"),
        ({"instrument": {"preset": "laser-9000"}}, "key `instrument.preset`: unknown instrument preset 'laser-9000'"),
        ({"instrument": {"a_um": 10.0}}, "key `instrument`: an instrument needs a `preset` or both"),
    ],
)
def test_scenario_schema_messages(tables, expected):
    message = _scenario_error(**tables)
    assert message.startswith("s.toml: ") and expected in message, message
    assert "Value error" not in message and "Input should" not in message


def test_instrument_presets_file_has_a_schema():
    presets = instrument_presets()
    assert presets["thesis-laser-tracker"]["a_um"] == 10.0 and "reflector_acceptance_deg" not in presets["thesis-igps"]
    presets["thesis-igps"]["a_um"] = -1.0  # a copy: the validated presets stay as read
    assert instrument_presets()["thesis-igps"]["a_um"] == 200.0
    for entry, expected in [
        ({"a_um": True, "b_um_per_m": 1.0}, "key `a_um`: must be a number; got true"),
        ({"a_um": 1.0, "b_um_per_m": -1.0}, "key `b_um_per_m`: must be >= 0; got -1.0"),
        ({"a_um": 1.0, "b_um_per_m": 1.0, "range_m": 3.0}, "key `range_m`: unknown key"),
        ({"a_um": 1.0, "b_um_per_m": 1.0, "min_distance_m": 5.0, "max_distance_m": 2.0}, "min_distance_m must be"),
    ]:
        with pytest.raises(InputError, match=re.escape(expected)):
            validate_model(InstrumentPreset, entry, "instruments.toml")


def test_make_instrument_validates_its_terms():
    assert make_instrument(a_um=10, b_um_per_m=2).a_mm == pytest.approx(0.01)  # an integer is a number
    with pytest.raises(InputError, match=r"^instrument: key `noise`: must be 'uniform' or 'normal'; got \"gauss\"$"):
        make_instrument(a_um=1.0, b_um_per_m=0.0, noise="gauss")


def _parameter_file(tmp_path, **changes) -> str:
    robot = load_robot(ROBOT)
    joints = [{"d": 0.0, "theta": 0.0, "a": 0.0, "alpha": 0.0, "hayati": bool(h)} for h in robot.hayati]
    document = {"robot": ROBOT, "joints": joints, "comment": "ignored: an extension"} | changes
    path = tmp_path / "p.json"
    path.write_text(json.dumps(document))
    with pytest.raises(InputError) as caught:
        read_parameters(path, robot)
    return str(caught.value)


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"units": {"length": "m", "angle": "deg"}}, "key `units`: must be {'length': 'mm', 'angle': 'deg'}"),
        ({"identified": ["J1.d", 3]}, "key `identified[1]`: must be a text; got 3"),
        ({"robot": 5}, "key `robot`: must be a text; got 5"),
        ({"joints": [{"d": 0.0}]}, "key `joints[0].theta`: missing required key"),
        ({"joint_model": {"parameters": [], "gravity_mps2": [0.0, True, -9.81]}}, "key `joint_model.gravity_mps2[1]`"),
        (
            {"joint_model": {"parameters": [{"name": "J2.k", "value": "1e-5"}]}},
            'parameters[0].value`: must be a number; got "1e-5"',
        ),
    ],
)
def test_parameter_json_schema_messages(tmp_path, changes, expected):
    message = _parameter_file(tmp_path, **changes)
    assert message.startswith(str(tmp_path / "p.json")) and expected in message, message


def test_parameter_json_hayati_is_a_boolean(tmp_path):
    robot = load_robot(ROBOT)
    joints = [{"d": 0.0, "theta": 0.0, "a": 0.0, "alpha": 0.0} for _ in range(robot.n_joints)]
    joints[1]["hayati"] = 1  # a number is no boolean (bool(1) was read as true)
    message = _parameter_file(tmp_path, joints=joints)
    assert "key `joints[1].hayati`: must be true or false; got 1" in message


def test_parameter_json_targets(tmp_path):
    path = tmp_path / "p.json"
    targets = {"T": {"frame": "flange", "flange_mm": [1, 2.5, 3]}, "J": {"frame": "joint", "reflector_mm": [[0, 0, 0]]}}
    path.write_text(json.dumps({"targets": targets}))
    assert read_targets(path) == {"T": (1.0, 2.5, 3.0)}
    path.write_text(json.dumps({"targets": {"T": {"flange_mm": [1.0, 2.0]}}}))
    with pytest.raises(InputError, match=r"key `targets\.T\.flange_mm`: must be \[x, y, z\]; got 2 values"):
        read_targets(path)


def test_a_joint_number_is_whole(tmp_path):
    from robotcal.io.results.joints_files import read_backlash

    path = tmp_path / "summary.csv"
    header = "joint,backlash_angle_mean_deg,backlash_exceeds_noise\n"
    path.write_text(header + "2,0.01,1\n")
    assert read_backlash(path, 6)[1] == 0.01
    path.write_text(header + "2.5,0.01,1\n")  # read as joint 2 before
    with pytest.raises(InputError, match=r"line 2, column `joint`: must be a whole number; got '2\.5'$"):
        read_backlash(path, 6)


def test_recorded_base_frame_is_a_4x4_matrix_by_type(tmp_path):
    from robotcal.io.formats.parameters_json import read_tracker_from_base

    path = tmp_path / "p.json"
    path.write_text(json.dumps({"provenance": {"tracker_from_base": [[1.0, 0.0, 0.0, 0.0]] * 3, "points": 40}}))
    with pytest.raises(InputError, match=r"key `provenance\.tracker_from_base`: must be a 4x4 matrix; got 3 rows$"):
        read_tracker_from_base(path)
    path.write_text(json.dumps({"provenance": {"tracker_from_base": None}}))
    assert read_tracker_from_base(path) is None
