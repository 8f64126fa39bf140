"""``robotcal predict``: FK of the flange or a flange point, equal to forward_kinematics."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.geometry.euler import kuka_abc_from_matrix, matrix_from_kuka_abc
from robotcal.io import load_robot, load_scenario, write_parameters
from robotcal.io.formats.trajectory_csv import write_trajectory
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.model import ParameterSet

runner = CliRunner()
ROBOT = load_robot("kuka-kr5-sixx-r650-krc")


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _read(path):
    rows = list(csv.DictReader(path.open()))
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    abc = np.radians([[float(r[k]) for k in "ABC"] for r in rows])
    return xyz, abc


def test_predict_matches_forward_kinematics(tmp_path):
    values = ROBOT.nominal.copy()
    values[2, 2] += 0.4
    params = tmp_path / "p.json"
    write_parameters(params, ParameterSet(robot=ROBOT, values=values))
    # within the joint limits (readings outside them are a JointLimitWarning, an error under pytest)
    readings = np.random.default_rng(1).uniform(ROBOT.limits[:, 0], ROBOT.limits[:, 1], (20, 6))
    poses = tmp_path / "poses.csv"
    write_trajectory(poses, readings)
    readings = np.radians(np.round(np.degrees(readings), 9))  # the pose CSV holds 9 decimals of degrees
    expected = forward_kinematics(values, ROBOT.model_joint_variables(readings))
    target = np.array([10.0, -20.0, 150.0])
    out = tmp_path / "pred.csv"
    assert invoke("predict", params, "--poses", poses, "--target", "10,-20,150", "--out", out).exit_code == 0
    xyz, abc = _read(out)
    # output has 9 decimals: 5e-10 mm / 5e-10 deg of rounding
    np.testing.assert_allclose(xyz, expected[:, :3, :3] @ target + expected[:, :3, 3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(matrix_from_kuka_abc(abc), expected[:, :3, :3], rtol=0, atol=1e-10)
    # flange, in a tracker frame: x,y,z = R p + t
    out2 = tmp_path / "flange.csv"
    result = invoke(
        "predict", params, "--poses", poses, "--flange", "--tracker-from-base", "1000,0,0,90,0,0", "--out", out2
    )
    assert result.exit_code == 0, result.output
    xyz, _ = _read(out2)
    rotated = expected[:, :3, 3] @ np.array([[0, -1.0, 0], [1, 0, 0], [0, 0, 1]]).T + [1000.0, 0, 0]
    np.testing.assert_allclose(xyz, rotated, rtol=0, atol=1e-8)


def test_predict_says_what_it_wrote_in_a_sentence(tmp_path):
    """Issue 30: the message was "wrote F (3 poses; given; tracker frame (given))"."""
    params = tmp_path / "p.json"
    write_parameters(params, ParameterSet.nominal(ROBOT))
    poses = tmp_path / "poses.csv"
    write_trajectory(poses, np.radians([[0.0, -90.0, 90.0, 0.0, 45.0, 0.0]] * 3))
    out = tmp_path / "pred.csv"
    result = invoke("predict", params, "--poses", poses, "--target", "60,40,30", "--tracker-from-base",
                    "1000,0,0,90,0,0", "--out", out)  # fmt: skip
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert said == (
        f"wrote {out}: 3 poses of the flange point (60, 40, 30) mm given by --target, in the tracker frame, given by "
        "--tracker-from-base"
    )
    result = invoke("predict", params, "--poses", poses, "--out", out, "--force")
    assert " ".join(result.output.split()) == f"wrote {out}: 3 poses of the flange frame, in the robot base frame"


def test_predict_errors(tmp_path):
    params = tmp_path / "p.json"
    write_parameters(params, ParameterSet.nominal(ROBOT))
    poses = tmp_path / "poses.csv"
    poses.write_text("pose,q1,q2\n1,0,0\n")
    result = invoke("predict", params, "--poses", poses, "--out", tmp_path / "o.csv")
    assert result.exit_code == 2 and "poses.csv" in result.output
    result = invoke("predict", params, "--poses", poses, "--target", "1,2,3", "--flange", "--out", tmp_path / "o.csv")
    assert result.exit_code == 2 and "not both" in result.output


# --- issue 24: readings checked, targets by name, the base frame from a parameter JSON or a scenario -----

TRACKER = np.array([[0.0, -1.0, 0.0, 2100.0], [1.0, 0.0, 0.0, -150.0], [0.0, 0.0, 1.0, -420.0], [0.0, 0.0, 0.0, 1.0]])


def _one_line_error(result, message):
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2, result.output
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.output


def test_predict_refuses_absurd_readings_and_names_readings_outside_the_limits(tmp_path):
    params = tmp_path / "p.json"
    write_parameters(params, ParameterSet.nominal(ROBOT))
    out = tmp_path / "o.csv"
    poses = tmp_path / "poses.csv"
    poses.write_text("pose,q1,q2,q3,q4,q5,q6\n1,0,-90,90,0,45,0\n2,1e308,-90,90,0,45,0\n", encoding="utf-8")
    result = invoke("predict", params, "--poses", poses, "--out", out)
    _one_line_error(result, "poses.csv: line 3 (pose 2), column `q1`: 1e308 deg is no joint reading")
    poses.write_text("pose,q1,q2,q3,q4,q5,q6\n1,0,-90,90,0,45,0\n2,0,nan,90,0,45,0\n", encoding="utf-8")
    _one_line_error(invoke("predict", params, "--poses", poses, "--out", out), "column `q2`: 'nan' is not a finite")
    assert not out.exists()


@pytest.mark.filterwarnings("default::robotcal.errors.JointLimitWarning")
def test_predict_warns_for_readings_outside_the_joint_limits(tmp_path):
    params = tmp_path / "p.json"
    write_parameters(params, ParameterSet.nominal(ROBOT))
    poses = tmp_path / "poses.csv"
    poses.write_text("pose,q1,q2,q3,q4,q5,q6\n1,0,-90,90,0,45,0\n2,0,5000,90,0,45,0\n", encoding="utf-8")
    out = tmp_path / "o.csv"
    result = invoke("predict", params, "--poses", poses, "--out", out)
    said = " ".join(result.output.split())
    assert result.exit_code == 0, result.output
    assert "warning:" in said and "pose 2: J2 = 5000 deg outside [-190, 45] deg" in said, said


def _scenario_with_targets(tmp_path, *, with_base: bool) -> Path:
    text = [
        'robot = "kuka-kr5-sixx-r650-krc"',
        *(["tracker_from_base = " + json.dumps(TRACKER.tolist())] if with_base else []),
        "[[targets]]",
        'name = "T1"',
        "flange_mm = [60.0, 0.0, 25.0]",
        "[[targets]]",
        'name = "T2"',
        'flange_mm = "unknown"',
        "guess_mm = [-30.0, 50.0, 30.0]",
    ]
    path = tmp_path / ("cell.toml" if with_base else "nobase.toml")
    path.write_text("\n".join(text) + "\n", encoding="utf-8")
    return path


def test_predict_target_by_name_and_base_frame_from_params_or_scenario(tmp_path):
    values = ROBOT.nominal.copy()
    values[1, 2] += 0.3
    params = tmp_path / "refined.json"
    estimated = {"T2": {"frame": "flange", "known": False, "flange_mm": [-31.0, 52.0, 29.0], "u_mm": None}}
    write_parameters(
        params, ParameterSet(robot=ROBOT, values=values), {"tracker_from_base": TRACKER.tolist()}, targets=estimated
    )
    readings = np.radians([[0.0, -90.0, 90.0, 0.0, 45.0, 0.0], [20.0, -80.0, 70.0, 10.0, 30.0, -20.0]])
    poses = tmp_path / "poses.csv"
    write_trajectory(poses, readings)
    frames = forward_kinematics(values, ROBOT.model_joint_variables(readings))
    scenario = _scenario_with_targets(tmp_path, with_base=True)

    def predicted(*options):
        out = tmp_path / "pred.csv"
        result = invoke("predict", params, "--poses", poses, *options, "--out", out, "--force")
        assert result.exit_code == 0, result.output
        return _read(out)[0]

    def expected(offset, world=None):
        world = np.eye(4) if world is None else world
        return (world @ frames @ np.append(offset, 1.0))[:, :3]

    # T2 from the parameter JSON's targets (the refinement's estimate), T1 from the scenario's [[targets]]
    # (9 decimals of mm written, 9 of a degree in the pose CSV: ~1e-8 mm at 1 m)
    np.testing.assert_allclose(predicted("--target", "T2"), expected([-31.0, 52.0, 29.0]), rtol=0, atol=1e-8)
    np.testing.assert_allclose(
        predicted("--target", "T1", "--scenario", scenario), expected([60.0, 0.0, 25.0]), rtol=0, atol=1e-8
    )
    # the base frame recorded in the JSON, or the scenario's, equals the same frame typed by hand
    by_hand = ",".join(f"{v:.12f}" for v in [*TRACKER[:3, 3], *np.degrees(kuka_abc_from_matrix(TRACKER[:3, :3]))])
    typed = predicted("--target", "T2", "--tracker-from-base", by_hand)
    np.testing.assert_allclose(typed, expected([-31.0, 52.0, 29.0], TRACKER), rtol=0, atol=1e-8)
    np.testing.assert_allclose(predicted("--target", "T2", "--tracker-from-base", "params"), typed, rtol=0, atol=1e-9)
    from_scenario = predicted("--target", "T2", "--tracker-from-base", "scenario", "--scenario", scenario)
    np.testing.assert_allclose(from_scenario, typed, rtol=0, atol=1e-9)
    # the existing options keep working: x,y,z target, --flange
    np.testing.assert_allclose(predicted("--target", "60,0,25"), expected([60.0, 0.0, 25.0]), rtol=0, atol=1e-8)
    np.testing.assert_allclose(predicted("--flange"), expected([0.0, 0.0, 0.0]), rtol=0, atol=1e-8)


def test_predict_target_and_base_frame_errors(tmp_path):
    params = tmp_path / "p.json"
    write_parameters(params, ParameterSet.nominal(ROBOT))  # no targets, no base frame
    poses = tmp_path / "poses.csv"
    write_trajectory(poses, np.radians([[0.0, -90.0, 90.0, 0.0, 45.0, 0.0]]))
    cell, nobase = _scenario_with_targets(tmp_path, with_base=True), _scenario_with_targets(tmp_path, with_base=False)
    out = tmp_path / "o.csv"
    for options, message in [
        (["--target", "T9", "--scenario", cell], "--target 'T9': no flange target of that name in"),
        (["--target", "T9", "--scenario", cell], "known: T1"),
        (["--target", "T2", "--scenario", cell], "declares target 'T2' with an unknown offset"),
        (["--target", "T1"], "(give --scenario for its targets)"),
        (["--tracker-from-base", "params"], "records no base frame (provenance.tracker_from_base)"),
        (["--tracker-from-base", "scenario"], "--tracker-from-base scenario needs --scenario"),
        (["--tracker-from-base", "scenario", "--scenario", nobase], "declares no tracker_from_base"),
        (["--tracker-from-base", "tracker"], "must be x,y,z,A,B,C [mm, deg], params or scenario"),
        (["--tracker-from-base", "1,2,3"], "--tracker-from-base must be 6 finite comma-separated numbers"),
    ]:
        _one_line_error(invoke("predict", params, "--poses", poses, *options, "--out", out), message)
    assert not out.exists()
    assert load_scenario(str(nobase)).tracker_from_base.tolist() == np.eye(4).tolist()  # the silent default refused
