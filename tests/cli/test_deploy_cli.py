"""Deployment on the command line (issue 28): compensate writes every row under its own name with a status and says
which rows are not ok (exit 3); filter writes the filtered program, points.csv and filter.html, numbers only."""

from __future__ import annotations

import csv
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import robotcal
from robotcal.cli import app
from robotcal.geometry.euler import kuka_abc_from_matrix
from robotcal.kinematics.forward import forward_kinematics

runner = CliRunner()
PROGRAMS = Path(__file__).resolve().parents[2] / "examples" / "programs"
NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _rows(path: Path) -> list[dict]:
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    return list(csv.DictReader(lines))


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("deploy")
    for name in ("kuka-kr5-sixx-r650", "ur5e"):
        robotcal.write_parameters(folder / f"{name}.json", robotcal.perturb(robotcal.load_robot(name), rng=3))
    return folder


def test_compensate_keeps_the_rows_names_and_flags_what_is_not_ok(calibrated, tmp_path):
    robot = robotcal.load_robot("kuka-kr5-sixx-r650")
    taught = np.array([[10.0, 40.0, 30.0, 5.0, 45.0, 0.0], [-30.0, 70.0, -20.0, 40.0, -60.0, 90.0],
                       [20.0, 60.0, 10.0, 0.0, 50.0, 10.0]])  # fmt: skip
    frames = forward_kinematics(robot.nominal, robot.model_joint_variables(np.deg2rad(taught)))
    cartesian = np.c_[frames[:, :3, 3], np.rad2deg(kuka_abc_from_matrix(frames))]
    cartesian[1, 0] += 3000.0  # 3 m further out: beyond the arm's reach
    poses = tmp_path / "targets.csv"
    lines = ["pose,x,y,z,a,b,c,q1,q2,q3,q4,q5,q6"]
    for name, target, seed in zip(("P10", "far", "P30"), cartesian, taught, strict=True):
        lines.append(",".join([name, *(f"{v:.9f}" for v in target), *(f"{v:.6f}" for v in seed)]))
    poses.write_text("\n".join(lines) + "\n")
    out = tmp_path / "commands.csv"
    result = invoke("compensate", calibrated / "kuka-kr5-sixx-r650.json", "--poses", poses, "-o", out)
    assert result.exit_code == 3, result.output
    assert "1 unreachable" in result.output and "unreachable: far" in result.output
    rows = _rows(out)
    assert [r["pose"] for r in rows] == ["P10", "far", "P30"]
    assert [r["status"] for r in rows] == ["ok", "unreachable", "ok"]
    assert rows[1]["q1"] == "" and float(rows[0]["position_error_mm"]) < 1e-6
    assert float(rows[2]["largest_change_deg"]) < 2.0
    # joint targets without a pose column: rows named 1, 2, 3; all ok, exit 0
    joints = tmp_path / "taught.csv"
    joints.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(f"{v:g}" for v in row) for row in taught) + "\n")
    result = invoke("compensate", calibrated / "kuka-kr5-sixx-r650.json", "--poses", joints, "-o", out)
    assert result.exit_code == 0, result.output
    assert [r["pose"] for r in _rows(out)] == ["1", "2", "3"]
    # an error names the row by its own name
    bad = tmp_path / "bad.csv"
    bad.write_text("pose,q1,q2,q3,q4,q5,q6\nH01,0,0,0,0,0,0\nH03,0,x,0,0,0,0\n")
    result = invoke("compensate", calibrated / "kuka-kr5-sixx-r650.json", "--poses", bad, "-o", tmp_path / "c.csv")
    assert result.exit_code == 2 and "pose H03" in result.output and not (tmp_path / "c.csv").exists()


def test_filter_a_krl_program(calibrated, tmp_path):
    source = tmp_path / "program"
    source.mkdir()
    for name in ("kuka_pick_place.src", "kuka_pick_place.dat", "kuka_config.dat"):
        shutil.copy(PROGRAMS / name, source / name)
    out = tmp_path / "filtered"
    args = ["filter", source / "kuka_pick_place.src", "--params", calibrated / "kuka-kr5-sixx-r650.json",
            "--controller", "kuka-kr5-sixx-r650-krc", "-o", out]  # fmt: skip
    result = invoke(*args)
    assert result.exit_code == 2 and "TOOL_DATA[1]" in result.output and "--frame" in result.output
    assert not out.exists()
    result = invoke(*args, "--config-dat", source / "kuka_config.dat")
    # the home position (A5 = 0) is a wrist singularity: flagged, exit 3
    assert result.exit_code == 3, result.output
    assert "7 ok, 1 near_singular" in result.output and "XHOME" in result.output
    assert {p.name for p in out.iterdir()} >= {"kuka_pick_place.src", "kuka_pick_place.dat", "points.csv", "filter.html"}
    original = (source / "kuka_pick_place.dat").read_bytes()
    filtered = (out / "kuka_pick_place.dat").read_bytes()
    assert filtered != original and b"\r\n" in filtered  # CRLF kept
    assert NUMBER.sub("#", filtered.decode()) == NUMBER.sub("#", original.decode())
    assert (out / "kuka_pick_place.src").read_bytes() == (source / "kuka_pick_place.src").read_bytes()
    rows = _rows(out / "points.csv")
    assert [r["label"] for r in rows if r["status"] == "ok"] == [f"XP{k}" for k in range(1, 8)]
    assert [r["note"] for r in rows if r["status"] == "not_filtered"] == ["XP9 declared, used by no motion"]
    assert next(r for r in rows if r["label"] == "XHOME")["note"].startswith("at a singularity")
    assert "XHOME" in (out / "filter.html").read_text()
    # a given frame replaces the declared one: the same points, other numbers
    again = invoke(*args, "--config-dat", source / "kuka_config.dat", "--frame", "TOOL_DATA[1]=131.25,0.42,-0.61,0,0,5",
                   "-o", tmp_path / "other")  # fmt: skip
    assert again.exit_code == 3, again.output
    assert (tmp_path / "other" / "kuka_pick_place.dat").read_bytes() != filtered


def test_filter_a_urscript_program_and_refuse_its_own_input(calibrated, tmp_path):
    shutil.copy(PROGRAMS / "ur_dispense.script", tmp_path / "ur_dispense.script")
    result = invoke("filter", tmp_path / "ur_dispense.script", "--params", calibrated / "ur5e.json", "-o",
                    tmp_path / "out")  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "17 ok" in result.output and "not filtered" in result.output
    text = (tmp_path / "out" / "ur_dispense.script").read_text()
    assert NUMBER.sub("#", text) == NUMBER.sub("#", (tmp_path / "ur_dispense.script").read_text())
    result = invoke("filter", tmp_path / "ur_dispense.script", "--params", calibrated / "ur5e.json", "-o", tmp_path)
    assert result.exit_code == 2
    result = invoke("filter", tmp_path / "ur_dispense.script", "--params", calibrated / "ur5e.json", "--language",
                    "gcode", "-o", tmp_path / "x")  # fmt: skip
    assert result.exit_code == 2 and "gcode" in result.output


def test_exports_that_carry_a_hayati_beta(calibrated, tmp_path):
    """A calibrated UR5e has betas on its parallel J2, J3: the UR calibration YAML holds them (each joint's origin as
    x, y, z, roll, pitch, yaw, the format the UR drivers read), a DH table cannot and names the forms that can."""
    parameters = robotcal.read_parameters(calibrated / "ur5e.json", robotcal.load_robot("ur5e"))
    assert np.abs(parameters.values[[1, 2], 4]).min() > 0  # the perturbation tilted both parallel axes
    result = invoke("export", calibrated / "ur5e.json", "--format", "ur-yaml", "-o", tmp_path / "calibration.yaml")
    assert result.exit_code == 0, result.output
    text = (tmp_path / "calibration.yaml").read_text()
    assert all(f"  {joint}:" in text for joint in ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"))
    result = invoke("export", calibrated / "ur5e.json", "--format", "dh", "-o", tmp_path / "dh.csv")
    assert result.exit_code == 2
    assert "J2.beta" in result.output and "--format urdf" in result.output and "--format ur-yaml" in result.output
