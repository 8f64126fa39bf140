"""Model export: URDF (loaded by yourdfpy), UR calibration YAML, DH / MDH tables, each checked by an
independent forward-kinematics composer against robotcal's forward_kinematics."""

from __future__ import annotations

import csv
import io
import re

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io import load_robot
from robotcal.io.formats.export import (
    UR_JOINT_NAMES,
    dh_table,
    mdh_table,
    parameters_to_ur_yaml,
    parameters_to_urdf,
    table_to_csv,
    table_to_markdown,
)
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.model import ParameterSet

# FK agreement: the exports write floats round-trip exact (repr), so only double rounding of ~10
# matrix products on ~1000 mm lengths remains (~1e-12 mm); the bound is 1e-9 mm / 1e-9 rad.
TOL_MM = 1e-9
TOL_RAD = 1e-9


def _perturbed(name: str, seed: int, *, zero_beta: bool = False) -> ParameterSet:
    robot = load_robot(name)
    rng = np.random.default_rng(seed)
    scale = np.array([0.5, 0.01, 0.5, 0.01, 0.01])  # mm / rad, a calibrated-looking deviation
    values = robot.nominal + rng.normal(size=robot.nominal.shape) * scale * ~robot.structurally_fixed
    if zero_beta:
        values[:, 4] = 0.0
    return ParameterSet(robot=robot, values=values)


# independent elementary transforms (not robotcal's)
def _rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _rx(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])


def _ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0, s, 0], [0, 1.0, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]])


def _tr(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def _rpy(x, y, z, roll, pitch, yaw):
    return _tr(x, y, z) @ _rz(yaw) @ _ry(pitch) @ _rx(roll)


def _assert_same_pose(actual_mm, expected_mm):
    np.testing.assert_allclose(actual_mm[..., :3, 3], expected_mm[..., :3, 3], rtol=0, atol=TOL_MM)
    np.testing.assert_allclose(actual_mm[..., :3, :3], expected_mm[..., :3, :3], rtol=0, atol=TOL_RAD)


@pytest.mark.parametrize("joint_variable", ["reading", "model"])
def test_urdf_matches_forward_kinematics_in_yourdfpy(tmp_path, joint_variable):
    yourdfpy = pytest.importorskip("yourdfpy")
    # krc robot: reading signs -1 and offsets; J2 Hayati with a non-zero beta (an origin rpy)
    parameters = _perturbed("kuka-kr5-sixx-r650-krc", 3)
    assert abs(parameters.values[1, 4]) > 1e-4 and np.any(parameters.robot.reading_sign < 0)
    tool = np.array([12.5, -3.0, 80.0])
    path = tmp_path / "robot.urdf"
    path.write_text(parameters_to_urdf(parameters, tool=tool, joint_variable=joint_variable))
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False, load_collision_meshes=False)
    n_poses = 1000 if joint_variable == "reading" else 100
    rng = np.random.default_rng(5)
    readings = rng.uniform(-np.pi, np.pi, (n_poses, 6))
    q = parameters.robot.model_joint_variables(readings)
    values = readings if joint_variable == "reading" else q
    flange = []
    for row in values:
        urdf.update_cfg(row)
        flange.append(urdf.get_transform("flange", "base_link"))
    flange = np.array(flange)
    flange[:, :3, 3] *= 1000.0  # URDF lengths are metres
    tool0 = urdf.get_transform("tool0", "flange")
    expected = forward_kinematics(parameters.values, q)
    _assert_same_pose(flange, expected)
    np.testing.assert_allclose(tool0[:3, 3] * 1000.0, tool, rtol=0, atol=TOL_MM)
    np.testing.assert_allclose(tool0[:3, :3], np.eye(3), rtol=0, atol=TOL_RAD)


def test_urdf_names_links_and_limits():
    parameters = _perturbed("kuka-kr5-sixx-r650-krc", 4)
    text = parameters_to_urdf(parameters, prefix="kr5_")
    for name in ["kr5_base_link", "kr5_link_6", "kr5_flange", "kr5_joint_1", "kr5_flange_joint"]:
        assert f'"{name}"' in text
    assert "tool0" not in text
    lower, upper = parameters.robot.limits[0]
    assert f'lower="{float(lower)!r}" upper="{float(upper)!r}"' in text


def _compose_ur_yaml(text: str, readings) -> np.ndarray:
    """Independent reader: each entry an origin xyz/rpy [m, rad], joint about +z (ur_description)."""
    entries: dict[str, dict[str, float]] = {}
    current = None
    for line in text.splitlines():
        if line.startswith("#") or not line.strip() or line.strip() == "kinematics:":
            continue
        key, value = (part.strip() for part in line.split(":", 1))
        if not value:
            current = entries.setdefault(key, {})
        else:
            current[key] = float(value)
    assert list(entries) == list(UR_JOINT_NAMES)
    out = []
    for row in readings:
        m = np.eye(4)
        for joint, r in zip(UR_JOINT_NAMES, row, strict=True):
            e = entries[joint]
            m = m @ _rpy(e["x"] * 1000, e["y"] * 1000, e["z"] * 1000, e["roll"], e["pitch"], e["yaw"]) @ _rz(r)
        out.append(m)
    return np.array(out)


def test_ur_yaml_matches_forward_kinematics():
    # the plain KR 5 (readings = model variables) with J6's a, alpha at 0: the format can hold it
    parameters = _perturbed("kuka-kr5-sixx-r650", 6)
    values = parameters.values.copy()
    values[5, 2:] = 0.0
    parameters = parameters.replace(values=values)
    readings = np.random.default_rng(7).uniform(-np.pi, np.pi, (1000, 6))
    composed = _compose_ur_yaml(parameters_to_ur_yaml(parameters), readings)
    _assert_same_pose(composed, forward_kinematics(parameters.values, readings))


def test_ur_yaml_refuses_what_it_cannot_hold():
    parameters = _perturbed("kuka-kr5-sixx-r650", 6)
    values = parameters.values.copy()
    values[5, 2] = 0.3  # a flange offset after wrist_3
    values[5, 3] = 0.0
    with pytest.raises(InputError, match=r"J6\.a != 0"):
        parameters_to_ur_yaml(parameters.replace(values=values))
    with pytest.raises(InputError, match="reading_sign = -1"):
        parameters_to_ur_yaml(_perturbed("kuka-kr5-sixx-r650-krc", 6))


def _refusal(export, parameters) -> str:
    with pytest.raises(InputError) as raised:
        export(parameters)
    return str(raised.value)


# Issue 30: `export --format dh` pointed to URDF with "exact equivalents that hold it: --format urdf (...)", the UR
# YAML's and the coupled robot's refusals with "(export --format urdf instead)": every refusal now ends the same way.
POINTER = r"; exact equivalents? that holds? it: --format urdf \("


def test_dh_beta_refusal_points_to_the_exact_formats():
    assert re.search(POINTER, _refusal(dh_table, _perturbed("kuka-kr5-sixx-r650-krc", 12)))


def test_ur_yaml_reading_sign_refusal_points_the_same_way():
    message = _refusal(parameters_to_ur_yaml, _perturbed("kuka-kr5-sixx-r650-krc", 6))
    assert re.search(POINTER + r"each joint turning about its own axis, -z included\)$", message), message
    assert "instead" not in message


def test_ur_yaml_flange_offset_refusal_points_the_same_way():
    parameters = _perturbed("kuka-kr5-sixx-r650", 6)
    values = parameters.values.copy()
    values[5, 2:] = [0.3, 0.0, 0.0]
    message = _refusal(parameters_to_ur_yaml, parameters.replace(values=values))
    assert re.search(POINTER + r"the flange offset as its fixed flange joint\)$", message), message


def test_coupled_robot_refusals_point_the_same_way():
    parameters = _perturbed("fanuc-style-coupled", 8, zero_beta=True)
    message = _refusal(parameters_to_ur_yaml, parameters)
    assert re.search(r"; exact equivalent that holds it: --format urdf --joint-variable model \(the model variables", message)
    message = _refusal(dh_table, parameters)
    assert re.search(r"; exact equivalent that holds it: --joint-variable model \(the model variables", message), message


def _rows(text: str) -> list[dict]:
    return list(csv.DictReader(io.StringIO(text)))


def test_dh_table_is_exact():
    parameters = _perturbed("kuka-kr5-sixx-r650-krc", 8, zero_beta=True)
    rows = _rows(table_to_csv(dh_table(parameters)))
    readings = np.random.default_rng(9).uniform(-np.pi, np.pi, (200, 6))
    composed = []
    for pose in readings:
        m = np.eye(4)
        for row, r in zip(rows, pose, strict=True):
            q = int(row["reading_sign"]) * r + np.radians(float(row["reading_offset_deg"]))
            theta, alpha = np.radians(float(row["theta_deg"])), np.radians(float(row["alpha_deg"]))
            m = m @ _rz(theta + q) @ _tr(0, 0, float(row["d_mm"])) @ _tr(float(row["a_mm"]), 0, 0) @ _rx(alpha)
        composed.append(m)
    q = parameters.robot.model_joint_variables(readings)
    # the table's angles pass through degrees (x pi/180 twice): a few ulp of 1 rad, ~1e-13 mm at 600 mm
    _assert_same_pose(np.array(composed), forward_kinematics(parameters.values, q))


def test_mdh_table_is_exact():
    parameters = _perturbed("kuka-kr5-sixx-r650-krc", 10, zero_beta=True)
    rows = _rows(table_to_csv(mdh_table(parameters)))
    assert [r["joint"] for r in rows] == ["J1", "J2", "J3", "J4", "J5", "J6", "flange"]
    readings = np.random.default_rng(11).uniform(-np.pi, np.pi, (200, 6))
    composed = []
    for pose in readings:
        m = np.eye(4)
        for k, row in enumerate(rows):
            q = 0.0
            if k < 6:
                q = int(row["reading_sign"]) * pose[k] + np.radians(float(row["reading_offset_deg"]))
            alpha, theta = np.radians(float(row["alpha_prev_deg"])), np.radians(float(row["theta_deg"]))
            m = m @ _rx(alpha) @ _tr(float(row["a_prev_mm"]), 0, 0) @ _rz(theta + q) @ _tr(0, 0, float(row["d_mm"]))
        composed.append(m)
    q = parameters.robot.model_joint_variables(readings)
    _assert_same_pose(np.array(composed), forward_kinematics(parameters.values, q))


@pytest.mark.parametrize("table", [dh_table, mdh_table])
def test_tables_refuse_beta_naming_the_joint(table):
    parameters = _perturbed("kuka-kr5-sixx-r650-krc", 12)
    with pytest.raises(InputError, match=r"J2\.beta"):
        table(parameters)


def test_markdown_table_has_a_row_per_joint():
    parameters = _perturbed("kuka-kr5-sixx-r650", 13, zero_beta=True)
    text = table_to_markdown(dh_table(parameters), title="DH")
    assert text.count("\n| J") == 6 and text.startswith("# DH")


def test_coupled_readings_export_the_model_variables_only(tmp_path):
    """A Fanuc-style robot whose J3 reading is coupled to J2: a URDF joint (or a table's reading columns,
    or the UR YAML) turns by one value, so only the model-variable export is exact; its FK in yourdfpy
    equals robotcal's at random readings, and its limits are the readings' where q follows one reading."""
    yourdfpy = pytest.importorskip("yourdfpy")
    parameters = _perturbed("fanuc-style-coupled", 8)
    robot = parameters.robot
    assert robot.is_coupled
    without_beta = _perturbed("fanuc-style-coupled", 8, zero_beta=True)  # so DH/MDH could hold the geometry
    for export in (parameters_to_urdf, parameters_to_ur_yaml, dh_table, mdh_table):
        with pytest.raises(InputError, match=r"J3 are coupled.*--joint-variable model"):
            export(without_beta)
    # the UR YAML has no model-variable form: its error says so instead of suggesting an option it ignores
    with pytest.raises(InputError, match=r"cannot hold a coupled robot; exact equivalent that holds it: --format urdf --joint-variable model"):
        parameters_to_ur_yaml(without_beta)
    # dh / mdh with joint_variable="model": reading_sign 1, offset 0, and the table composes FK at q = M^-1 r + o
    readings = np.random.default_rng(21).uniform(-1.0, 1.0, (100, 6))
    q_model = robot.model_joint_variables(readings)
    expected = forward_kinematics(without_beta.values, q_model)
    for table in (dh_table, mdh_table):
        rows = _rows(table_to_csv(table(without_beta, joint_variable="model")))
        joints = [row for row in rows if row["joint"] != "flange"]
        assert len(joints) == 6
        assert all(int(r["reading_sign"]) == 1 and float(r["reading_offset_deg"]) == 0.0 for r in joints)
        composed = []
        for pose in q_model:
            m = np.eye(4)
            for k, row in enumerate(rows):
                q = pose[k] if k < 6 else 0.0
                theta, d = np.radians(float(row["theta_deg"])) + q, float(row["d_mm"])
                if table is dh_table:
                    alpha, a = np.radians(float(row["alpha_deg"])), float(row["a_mm"])
                    m = m @ _rz(theta) @ _tr(0, 0, d) @ _tr(a, 0, 0) @ _rx(alpha)
                else:
                    alpha, a = np.radians(float(row["alpha_prev_deg"])), float(row["a_prev_mm"])
                    m = m @ _rx(alpha) @ _tr(a, 0, 0) @ _rz(theta) @ _tr(0, 0, d)
            composed.append(m)
        _assert_same_pose(np.array(composed), expected)
    with pytest.raises(InputError, match="`joint_variable` must be 'reading' or 'model'"):
        dh_table(without_beta, joint_variable="q")
    path = tmp_path / "robot.urdf"
    path.write_text(parameters_to_urdf(parameters, joint_variable="model"))
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False, load_collision_meshes=False)
    readings = np.random.default_rng(9).uniform(-1.0, 1.0, (200, 6))
    q = robot.model_joint_variables(readings)
    flange = []
    for row in q:
        urdf.update_cfg(row)
        flange.append(urdf.get_transform("flange", "base_link"))
    flange = np.array(flange)
    flange[:, :3, 3] *= 1000.0
    _assert_same_pose(flange, forward_kinematics(parameters.values, q))
    # q3 = -(r3 + r2 ...) follows two readings: no per-joint limit can hold it; J1 keeps its own
    assert '<joint name="joint_3" type="continuous">' in path.read_text()
    lower, upper = np.sort(robot.reading_sign[0] * robot.limits[0] + robot.reading_offset[0])
    assert f'lower="{float(lower)!r}" upper="{float(upper)!r}"' in path.read_text()


def test_every_export_text_is_recognised_as_robotcal_output(tmp_path):
    # issue 24: the output policy must recognise what export wrote (io.results.output.is_robotcal_file), so that a
    # second export replaces it without --force; a user's file of the same kind is not recognised
    from robotcal.io.results.output import is_robotcal_file

    robot = load_robot("kuka-kr5-sixx-r650")  # reading signs +1: every format holds it
    values = robot.nominal.copy()
    values[0, 0] += 1e-5  # a value repr writes with an exponent
    parameters = ParameterSet(robot=robot, values=values)
    texts = {
        "robot.urdf": parameters_to_urdf(parameters, tool=[0.0, 0.0, 100.0]),
        "robot.xml": parameters_to_urdf(parameters, joint_variable="model"),
        "calibration.yaml": parameters_to_ur_yaml(parameters),
        "dh.csv": table_to_csv(dh_table(parameters)),
        "mdh.csv": table_to_csv(mdh_table(parameters)),
        "dh.md": table_to_markdown(dh_table(parameters), title=f"DH table of {robot.name} [mm, deg]"),
    }
    for name, text in texts.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
        assert is_robotcal_file(tmp_path / name), name
    for name, text in {
        "user.urdf": '<?xml version="1.0"?>\n<robot name="mine"/>\n',
        "user.yaml": "# my calibration\nkinematics: {}\n",
        "user.csv": "joint,theta_deg,d_mm,a_mm,alpha_deg,reading_sign,reading_offset_deg\nJ1,0,1,2,3,1,0,note\n",
        "user.md": "# DH notes\n",
        "late.urdf": '<?xml version="1.0"?>\n<robot name="x">\n<!-- written by robotcal -->\n',
    }.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
        assert not is_robotcal_file(tmp_path / name), name
