"""``robotcal iso9283-plan`` and ``robotcal iso9283``: plan (and its robot program) written, numbers
equal to the library's, orientation from three targets per pose."""

from __future__ import annotations

import csv

import numpy as np
from typer.testing import CliRunner

from robotcal.capture import Capture
from robotcal.cli import app
from robotcal.diagnostics.iso9283 import iso_test_positions, pose_characteristics
from robotcal.geometry.transforms import apply_transform
from robotcal.io import load_scenario, write_capture, write_parameters
from robotcal.io.formats.trajectory_csv import read_trajectory
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


KUKA_SIGNS = np.array([-1.0, -1.0, -1.0, -1.0, 1.0, -1.0])  # KRC counts A1-A4, A6 opposite to the model


def _plan(tmp_path, *extra):
    robot = SCENARIO.robot
    start = np.radians([0.0, 90.0, -90.0, 0.0, 45.0, 0.0])
    frame = forward_kinematics(ParameterSet.nominal(robot).values, robot.model_joint_variables(start))[0]
    centre = frame[:3, :3] @ TARGET + frame[:3, 3]
    plan = tmp_path / "iso.csv"
    result = invoke(
        "iso9283-plan", "--scenario", "kr5-demo", "--center", ",".join(f"{v:.6f}" for v in centre),
        "--side", "150", "--start", "0,90,-90,0,45,0", "--cycles", "3", "--out", plan, *extra,
    )  # fmt: skip
    return plan, result


def test_plan_as_a_robot_program(tmp_path):
    import re

    plan, result = _plan(tmp_path, "--program", "krl", "--controller", "kuka-kr5-sixx-r650-krc", "--dwell", "1.5")
    assert result.exit_code == 0, result.output
    readings = read_trajectory(plan, n_joints=6)
    text = (tmp_path / "iso.src").read_text()  # default: --out with the language's suffix
    moves = np.radians([[float(v) for v in re.findall(r"A\d+ (-?[\d.]+)", line)] for line in text.splitlines()
                        if "PTP {" in line])  # fmt: skip
    # the same poses in the controller's convention (model readings times KUKA's signs), 6 decimals of a degree
    np.testing.assert_allclose(moves, readings * KUKA_SIGNS, rtol=0, atol=np.radians(0.6e-6) + np.radians(1e-9))
    assert re.findall(r"WAIT SEC ([\d.]+)", text) == ["1.5"] * 15
    labels = re.findall(r"; ISO 9283 cycle (\d) P(\d)", text)
    assert labels == [(str(c), str(p)) for c in (1, 2, 3) for p in (1, 2, 3, 4, 5)]
    # URScript to a named file, in model readings (no --controller)
    out = tmp_path / "iso.script"
    plan, result = _plan(tmp_path, "--program", "urscript", "--program-out", out, "--force")
    assert result.exit_code == 0, result.output
    moves = [[float(v) for v in m.split(",")] for m in re.findall(r"movej\(\[([^\]]+)\]", out.read_text())]
    np.testing.assert_allclose(moves, read_trajectory(plan, n_joints=6), rtol=0, atol=1e-9 + np.radians(1e-9))
    _, result = _plan(tmp_path, "--program", "gcode", "--force")
    assert result.exit_code == 2 and "--program must be one of krl, rapid, urscript" in result.output
    _, result = _plan(tmp_path, "--program-out", tmp_path / "x.src", "--force")
    assert result.exit_code == 2 and "--program-out needs --program" in result.output


def test_iso9283_with_three_targets_per_pose_measures_the_orientation(tmp_path):
    from robotcal.diagnostics.iso9283 import IsoModel, iso_from_capture

    plan, result = _plan(tmp_path)
    assert result.exit_code == 0, result.output
    readings = read_trajectory(plan, n_joints=6)
    robot = SCENARIO.robot
    offsets = {"t1": [60.0, 40.0, 30.0], "t2": [-50.0, 30.0, 20.0], "t3": [0.0, -60.0, 40.0]}
    # a scenario for a real cell: robot, base frame and the three declared targets, no plan, no instrument
    scenario = tmp_path / "cell.toml"
    base = ",\n".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in SCENARIO.tracker_from_base)
    targets = "".join(f'\n[[targets]]\nname = "{k}"\nflange_mm = {v}\n' for k, v in offsets.items())
    scenario.write_text(f'robot = "kuka-kr5-sixx-r650"\ntracker_from_base = [\n{base}\n]\n{targets}')
    # the real robot: J3.a 0.2 mm longer; per-point noise 5 um; targets measured t3, t1, t2 at every pose
    true_values = ParameterSet.nominal(robot).values.copy()
    true_values[2, 2] += 0.2
    frames = forward_kinematics(true_values, robot.model_joint_variables(readings))
    order = ["t3", "t1", "t2"]
    base_points = np.einsum("pij,tj->pti", frames[:, :3, :3], np.array([offsets[k] for k in order]))
    base_points = (base_points + frames[:, None, :3, 3]).reshape(-1, 3)
    base_points += np.random.default_rng(8).normal(0.0, 0.005, base_points.shape)
    n = base_points.shape[0]
    capture = Capture(
        circle=np.zeros(n, int), direction=np.ones(n, int), readings=np.repeat(readings, 3, axis=0),
        points=apply_transform(SCENARIO.tracker_from_base, base_points), target=np.tile([0, 1, 2], 15),
        target_names=tuple(order),
    )  # fmt: skip
    capture_path = tmp_path / "capture.csv"
    write_capture(capture_path, capture)
    out = tmp_path / "iso.out.csv"
    result = invoke("iso9283", capture_path, "--scenario", scenario, "--out", out)
    assert result.exit_code == 0, result.output
    rows = {(r["model"], r["pose"]): r for r in csv.DictReader(out.open())}
    model = IsoModel(parameters=ParameterSet.nominal(robot), tracker_from_base=SCENARIO.tracker_from_base)
    expected = iso_from_capture(capture, {"nominal": model}, targets=offsets)["nominal"]
    got = np.array([[float(rows["nominal", f"P{k + 1}"][c]) for c in ("APa", "APb", "APc", "RPa", "RPb", "RPc")]
                    for k in range(5)])  # fmt: skip
    np.testing.assert_allclose(got, np.rad2deg(np.c_[expected.ap_abc, expected.rp_abc]), rtol=0, atol=2e-6)
    got_ap = np.array([float(rows["nominal", f"P{k + 1}"]["AP"]) for k in range(5)])
    np.testing.assert_allclose(got_ap, expected.ap, rtol=0, atol=2e-6)
    # the J3.a error tilts nothing (a length): the orientation error is the noise's, a few millidegrees;
    # the position error is of J3.a's order
    assert np.abs(got[:, :3]).max() < 0.02 and 0.05 < got_ap.max() < 0.5
    # --targets-mm overrides the scenario's offsets: wrong ones change the results
    result = invoke("iso9283", capture_path, "--scenario", scenario, "--out", out, "--force",
                    "--targets-mm", "t1=60,40,30;t2=-50,30,20;t3=0,-60,45")  # fmt: skip
    assert result.exit_code == 0, result.output
    moved = {(r["model"], r["pose"]): r for r in csv.DictReader(out.open())}
    assert moved["nominal", "P1"]["APa"] != rows["nominal", "P1"]["APa"]
    result = invoke("iso9283", capture_path, "--scenario", scenario, "--out", out, "--force",
                    "--targets-mm", "t1=60,40,30;t2=-50,30,20")  # fmt: skip
    assert result.exit_code == 2 and "no flange offset for target 't3'" in result.output
    # the message names the model and the ways out
    said = " ".join(result.output.split())
    assert "model 'nominal' has no flange offset" in said and "--targets-mm" in said and "--no-nominal" in said
    result = invoke("iso9283", capture_path, "--scenario", scenario, "--out", out, "--force",
                    "--orientation-axes", "tool")  # fmt: skip
    assert result.exit_code == 2 and "--orientation-axes must be one of base, flange" in result.output


def test_plan_with_the_default_cube(tmp_path):
    from robotcal.diagnostics.iso9283 import default_iso_start

    plan = tmp_path / "iso.csv"
    result = invoke("iso9283-plan", "--scenario", "kr5-demo", "--cycles", "2", "--out", plan)
    assert result.exit_code == 0, result.output
    readings = read_trajectory(plan, n_joints=6)
    nominal = ParameterSet.nominal(SCENARIO.robot)
    # P1 = the cube's centre = the flange target at the default start readings
    np.testing.assert_allclose(readings[0], default_iso_start(nominal, TARGET), rtol=0, atol=1e-9)
    # side: 20 % of links 2..6 (270 + 90 + 295 + 0 + 80 = 735 mm) + |(60, 40, 30)| = 78.10 mm -> floor(162.6) = 162
    assert "side 162 mm" in plan.read_text().splitlines()[0]
    reached = forward_kinematics(nominal.values, SCENARIO.robot.model_joint_variables(readings[:5]))
    reached = reached[:, :3, :3] @ TARGET + reached[:, :3, 3]
    np.testing.assert_allclose(reached, iso_test_positions(reached[0], 162.0), rtol=0, atol=1e-8)


def test_iso9283_refuses_captures_that_are_not_iso_cycles(tmp_path):
    # issue 24: pose-major order, unrepeated poses and P1/P2 swapped in one cycle gave RP of 100-1000 mm, exit 0
    robot = SCENARIO.robot
    nominal = ParameterSet.nominal(robot)
    start = np.radians([0.0, 90.0, -90.0, 0.0, 45.0, 0.0])
    poses = start + np.radians(np.arange(15)[:, None] * np.array([2.0, 1.0, -1.0, 0.5, 1.5, 3.0]))
    cycle_major = np.tile(poses[:5], (3, 1))
    cases = {
        "pose-major": (np.repeat(poses[:5], 3, axis=0), "pose-major order (data rows 1 and 2 visit the same pose)"),
        "unrepeated": (poses, "15 pose visits hold 15 distinct poses"),
        "swapped": (cycle_major[np.r_[0:10, 11, 10, 12:15]], "cycle 3 (data row 11) visits P2 where P1 belongs"),
    }
    out = tmp_path / "iso.out.csv"
    out.write_text("kept\n", encoding="utf-8")  # a file of robotcal's? no: it must stay as it is either way
    for name, (readings, message) in cases.items():
        frames = forward_kinematics(nominal.values, robot.model_joint_variables(readings))
        tracker = apply_transform(SCENARIO.tracker_from_base, frames[:, :3, :3] @ TARGET + frames[:, :3, 3])
        path = tmp_path / f"{name}.csv"
        write_capture(path, Capture(circle=np.zeros(15, int), direction=np.ones(15, int), readings=readings, points=tracker))
        result = invoke("iso9283", path, "--scenario", "kr5-demo", "--out", out, "--force")
        lines = [line for line in result.output.splitlines() if line.strip()]
        assert result.exit_code == 2, (name, result.output)
        assert len(lines) == 1 and lines[0].startswith("error: ") and "not ISO 9283 cycles" in lines[0], result.output
        assert message in lines[0], result.output
        assert out.read_text(encoding="utf-8") == "kept\n"
    # the same poses cycle-major are ISO cycles: RP 0 for the exact robot and its own model
    frames = forward_kinematics(nominal.values, robot.model_joint_variables(cycle_major))
    tracker = apply_transform(SCENARIO.tracker_from_base, frames[:, :3, :3] @ TARGET + frames[:, :3, 3])
    path = tmp_path / "iso-cycles.csv"
    write_capture(path, Capture(circle=np.zeros(15, int), direction=np.ones(15, int), readings=cycle_major, points=tracker))
    result = invoke("iso9283", path, "--scenario", "kr5-demo", "--out", tmp_path / "good.csv")
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader((tmp_path / "good.csv").open()))
    assert max(float(r["RP"]) for r in rows if r["RP"]) < 1e-6
