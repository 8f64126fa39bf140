"""``robotcal iso9283-plan`` and ``robotcal iso9283``: plan written, numbers equal to the library's."""

from __future__ import annotations

import csv

import numpy as np
from typer.testing import CliRunner

from robotcal.capture import Capture
from robotcal.cli import app
from robotcal.diagnostics.iso9283 import iso_test_positions, pose_characteristics
from robotcal.geometry.transforms import apply_transform
from robotcal.io import load_scenario, write_capture, write_parameters
from robotcal.io.trajectory_csv import read_trajectory
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.model import ParameterSet

runner = CliRunner()
SCENARIO = load_scenario("kr5-demo")
TARGET = np.array([60.0, 40.0, 30.0])  # kr5-demo's [validation] flange target


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_plan_then_iso9283_equals_the_library(tmp_path):
    robot = SCENARIO.robot
    nominal = ParameterSet.nominal(robot)
    # KUKA A2 = -90, A3 = 90 as model readings of kuka-kr5-sixx-r650 (its limits are in model readings)
    start = np.radians([0.0, 90.0, -90.0, 0.0, 45.0, 0.0])
    frame = forward_kinematics(nominal.values, robot.model_joint_variables(start))[0]
    centre = frame[:3, :3] @ TARGET + frame[:3, 3]
    plan = tmp_path / "iso.csv"
    result = invoke(
        "iso9283-plan", "--scenario", "kr5-demo", "--center", ",".join(f"{v:.6f}" for v in centre),
        "--side", "150", "--start", "0,90,-90,0,45,0", "--cycles", "3", "--out", plan,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    readings = read_trajectory(plan, n_joints=6)
    assert readings.shape == (15, 6)
    # the "real" robot: nominal with J2.a 0.3 mm longer, plus per-visit noise of 5 um on the points
    true_values = nominal.values.copy()
    true_values[1, 2] += 0.3
    frames = forward_kinematics(true_values, robot.model_joint_variables(readings))
    base_points = frames[:, :3, :3] @ TARGET + frames[:, :3, 3]
    base_points += np.random.default_rng(4).normal(0.0, 0.005, base_points.shape)
    tracker = apply_transform(SCENARIO.tracker_from_base, base_points)
    capture_path = tmp_path / "capture.csv"
    n = readings.shape[0]
    write_capture(
        capture_path, Capture(circle=np.zeros(n, int), direction=np.ones(n, int), readings=readings, points=tracker)
    )
    refined = tmp_path / "refined.json"
    write_parameters(
        refined,
        ParameterSet(robot=robot, values=true_values),
        {"tracker_from_base": SCENARIO.tracker_from_base.tolist()},
    )
    out = tmp_path / "iso.out.csv"
    result = invoke("iso9283", capture_path, "--scenario", "kr5-demo", "--params", refined, "--out", out)
    assert result.exit_code == 0, result.output
    rows = {(r["model"], r["pose"]): r for r in csv.DictReader(out.open())}
    # library, from the readings the CSV holds (9 decimals of degrees)
    commanded_true = forward_kinematics(true_values, robot.model_joint_variables(readings[:5]))
    commanded_true = commanded_true[:, :3, :3] @ TARGET + commanded_true[:, :3, 3]
    expected = pose_characteristics(base_points.reshape(3, 5, 3), commanded_true)
    got = np.array([[float(rows["refined", f"P{k + 1}"][c]) for c in ("AP", "RP")] for k in range(5)])
    # CSV written with 6 decimals; the capture CSV holds 12 decimals
    np.testing.assert_allclose(got, np.c_[expected.ap, expected.rp], rtol=0, atol=2e-6)
    assert abs(float(rows["refined", "P2-P4"]["AD"]) - expected.ad) < 2e-6
    assert abs(float(rows["refined", "P2-P4"]["RD"]) - expected.rd) < 2e-6
    # the nominal model misses J2.a: its AP is larger than the refined model's
    nominal_ap = np.array([float(rows["nominal", f"P{k + 1}"]["AP"]) for k in range(5)])
    assert np.all(nominal_ap > got[:, 0])
    # P1 commanded with the nominal model is the cube's centre; the true robot is 0.3 mm (J2.a) away
    np.testing.assert_allclose(iso_test_positions(centre, 150.0)[0], commanded_true[0], rtol=0, atol=0.5)


def test_iso9283_errors(tmp_path):
    capture_path = tmp_path / "capture.csv"
    readings = np.zeros((7, 6))
    write_capture(
        capture_path,
        Capture(circle=np.zeros(7, int), direction=np.ones(7, int), readings=readings, points=np.zeros((7, 3))),
    )
    result = invoke("iso9283", capture_path, "--scenario", "kr5-demo", "--out", tmp_path / "o.csv")
    assert result.exit_code == 2 and "not whole cycles of 5" in result.output
    result = invoke("iso9283", capture_path, "--scenario", "thesis-noise-free", "--out", tmp_path / "o.csv")
    assert result.exit_code == 2 and "--target" in result.output
