"""``robotcal predict``: FK of the flange or a flange point, equal to forward_kinematics."""

from __future__ import annotations

import csv

import numpy as np
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.geometry.euler import matrix_from_kuka_abc
from robotcal.io import load_robot, write_parameters
from robotcal.io.trajectory_csv import write_trajectory
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
    readings = np.radians(np.random.default_rng(1).uniform(-90, 90, (20, 6)))
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


def test_predict_errors(tmp_path):
    params = tmp_path / "p.json"
    write_parameters(params, ParameterSet.nominal(ROBOT))
    poses = tmp_path / "poses.csv"
    poses.write_text("pose,q1,q2\n1,0,0\n")
    result = invoke("predict", params, "--poses", poses, "--out", tmp_path / "o.csv")
    assert result.exit_code == 2 and "poses.csv" in result.output
    result = invoke("predict", params, "--poses", poses, "--target", "1,2,3", "--flange", "--out", tmp_path / "o.csv")
    assert result.exit_code == 2 and "not both" in result.output
