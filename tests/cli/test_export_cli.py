"""``robotcal export``: each format written, same text as the library, clear errors."""

from __future__ import annotations

import json

import numpy as np
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io import load_robot, read_parameters, write_parameters
from robotcal.io.export import dh_table, parameters_to_urdf, table_to_csv
from robotcal.kinematics.model import ParameterSet

runner = CliRunner()
ROBOT = load_robot("kuka-kr5-sixx-r650-krc")


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _params(tmp_path, beta: float = 0.0):
    values = ROBOT.nominal.copy()
    values[0, 0] += 0.25
    values[1, 4] = beta
    parameters = ParameterSet(robot=ROBOT, values=values)
    path = tmp_path / "params.json"
    write_parameters(path, parameters, {"note": "test"})
    return path, parameters


def test_export_urdf_is_the_library_text(tmp_path):
    path, parameters = _params(tmp_path, beta=0.001)
    out = tmp_path / "robot.urdf"
    result = invoke("export", path, "--format", "urdf", "--tool", "0,0,100", "--out", out)
    assert result.exit_code == 0, result.output
    assert out.read_text() == parameters_to_urdf(parameters, tool=[0.0, 0.0, 100.0])


def test_export_json_round_trips_and_dh_markdown_csv(tmp_path):
    path, parameters = _params(tmp_path)
    out = tmp_path / "again.json"
    assert invoke("export", path, "--out", out).exit_code == 0
    np.testing.assert_array_equal(read_parameters(out, ROBOT).values, parameters.values)
    assert json.loads(out.read_text())["provenance"] == {"note": "test"}
    csv_out, md_out = tmp_path / "dh.csv", tmp_path / "mdh.md"
    assert invoke("export", path, "--format", "dh", "--out", csv_out).exit_code == 0
    assert csv_out.read_text() == table_to_csv(dh_table(parameters))
    assert invoke("export", path, "--format", "mdh", "--robot", ROBOT.name, "--out", md_out).exit_code == 0
    assert md_out.read_text().startswith("# Modified DH table")


def test_export_errors_name_the_problem(tmp_path):
    path, _ = _params(tmp_path, beta=0.001)
    result = invoke("export", path, "--format", "dh", "--out", tmp_path / "dh.csv")
    assert result.exit_code == 2 and "J2.beta" in result.output
    result = invoke("export", path, "--format", "stl", "--out", tmp_path / "x")
    assert result.exit_code == 2 and "--format must be one of" in result.output
    result = invoke("export", path, "--format", "urdf", "--tool", "1,2", "--out", tmp_path / "r.urdf")
    assert result.exit_code == 2 and "--tool" in result.output
    result = invoke("export", path, "--format", "ur-yaml", "--out", tmp_path / "ur.yaml")
    assert result.exit_code == 2 and "reading_sign = -1" in result.output


def test_export_dh_of_a_coupled_robot_with_model_variables(tmp_path):
    robot = load_robot("fanuc-style-coupled")
    values = robot.nominal.copy()
    values[:, 4] = 0.0  # DH holds no beta
    parameters = ParameterSet(robot=robot, values=values)
    path = tmp_path / "coupled.json"
    write_parameters(path, parameters, {"note": "test"})
    out = tmp_path / "coupled.csv"
    result = invoke("export", path, "--format", "dh", "--out", out)
    assert result.exit_code != 0 and "--joint-variable model" in result.output
    result = invoke("export", path, "--format", "dh", "--joint-variable", "model", "--out", out)
    assert result.exit_code == 0, result.output
    assert out.read_text() == table_to_csv(dh_table(parameters, joint_variable="model"))
    result = invoke("export", path, "--format", "ur-yaml", "--joint-variable", "model", "--out", tmp_path / "ur.yaml")
    assert result.exit_code != 0 and "written only by --format urdf, dh and mdh" in result.output
