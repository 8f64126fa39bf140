"""``robotcal export``: each format written, same text as the library, clear errors."""

from __future__ import annotations

import json

import numpy as np
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io import load_robot, read_parameters, write_parameters
from robotcal.io.formats.export import dh_table, parameters_to_urdf, table_to_csv
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


def test_export_replaces_its_own_earlier_files_without_force(tmp_path):
    # issue 24: a second export refused to replace its own URDF without --force
    path, _ = _params(tmp_path)
    yaml_path = tmp_path / "model.json"  # ur-yaml needs reading signs +1: the model robot, not the KRC's
    write_parameters(yaml_path, ParameterSet.nominal(load_robot("kuka-kr5-sixx-r650")), {"note": "test"})
    cases = [
        (path, "urdf", "robot.urdf"),
        (path, "urdf", "robot.xml"),
        (yaml_path, "ur-yaml", "calibration.yaml"),
        (path, "dh", "dh.csv"),
        (path, "mdh", "mdh.csv"),
        (path, "dh", "dh.md"),
        (path, "json", "again.json"),
    ]
    for params, fmt, name in cases:
        out = tmp_path / name
        for _ in range(2):
            result = invoke("export", params, "--format", fmt, "--out", out)
            assert result.exit_code == 0, (name, result.output)
    # a user's file of the same kind is still refused without --force, and left as it was
    for name, text in [
        ("mine.urdf", '<?xml version="1.0"?>\n<robot name="mine"/>\n'),
        ("mine.yaml", "kinematics:\n  shoulder: {x: 0}\n"),
        ("mine.csv", "joint,theta_deg,d_mm\nJ1,0,1\n"),
        ("mine.md", "# my notes\n"),
    ]:
        user = tmp_path / name
        user.write_text(text, encoding="utf-8")
        fmt = {"urdf": "urdf", "yaml": "ur-yaml", "csv": "dh", "md": "dh"}[name.split(".")[1]]
        result = invoke("export", yaml_path, "--format", fmt, "--out", user)
        assert result.exit_code == 2 and "not written by robotcal" in result.output, (name, result.output)
        assert user.read_text(encoding="utf-8") == text


def test_export_nominal_writes_a_parameter_json_that_reads_back(tmp_path):
    out = tmp_path / "nominal.json"
    result = invoke("export", "--nominal", "kuka-kr5-sixx-r650-krc", "--out", out)
    assert result.exit_code == 0, result.output
    assert "nominal model of kuka-kr5-sixx-r650-krc" in result.output
    back = read_parameters(out, ROBOT)
    np.testing.assert_array_equal(back.values, ROBOT.nominal)  # exact: repr of mm and deg read back
    assert json.loads(out.read_text())["provenance"]["method"] == "nominal parameters of the robot file"
    # the same JSON exports to the other formats like any parameter file, and --nominal writes them directly
    urdf = tmp_path / "nominal.urdf"
    assert invoke("export", "--nominal", "kuka-kr5-sixx-r650-krc", "--format", "urdf", "--out", urdf).exit_code == 0
    assert urdf.read_text() == parameters_to_urdf(ParameterSet.nominal(ROBOT))
    assert invoke("export", out, "--format", "dh", "--out", tmp_path / "dh.csv").exit_code == 0
    assert (tmp_path / "dh.csv").read_text() == table_to_csv(dh_table(ParameterSet.nominal(ROBOT)))
    # a robot TOML by path
    from robotcal.io.schema.builtins import data_path

    toml = data_path("robots", "abb-irb120.toml")
    assert invoke("export", "--nominal", toml, "--out", tmp_path / "irb.json").exit_code == 0
    assert json.loads((tmp_path / "irb.json").read_text())["robot"] == load_robot(toml).name
    for argv, message in [
        (["--nominal", "nope", "--out", tmp_path / "x.json"], "unknown robot 'nope'"),
        ([out, "--nominal", "kuka-kr5-sixx-r650", "--out", tmp_path / "x.json"], "give no PARAMS file"),
        (["--nominal", "kuka-kr5-sixx-r650", "--robot", "kuka-kr5-sixx-r650", "--out", tmp_path / "x.json"], "--robot"),
        (["--out", tmp_path / "x.json"], "give a parameter JSON (PARAMS) or --nominal ROBOT"),
    ]:
        result = invoke("export", *argv)
        lines = [line for line in result.output.splitlines() if line.strip()]
        assert result.exit_code == 2 and len(lines) == 1 and message in lines[0], result.output
    assert not (tmp_path / "x.json").exists()
