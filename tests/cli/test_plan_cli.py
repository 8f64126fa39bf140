"""CLI of the planning commands: plan check (exit 0/1/2), program, sensitivity, plan optimise."""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.planning.cell import check_plan
from robotcal.planning.scenario import cell_from_scenario

runner = CliRunner()

#: Another robot: a column (J1) and an arm (J2), no capsule radii in the file (defaults), a plan
#: that passes every check with the tracker 2 m away.
TWO_JOINT_ROBOT = """
name = "two-joint"
[[joints]]
d = 1000.0
limits_deg = [-180.0, 180.0]
[[joints]]
a = 400.0
limits_deg = [-90.0, 90.0]
"""
TWO_JOINT_SCENARIO = """
robot = "two.toml"
tracker_from_base = [[1,0,0,-2000.0],[0,1,0,0],[0,0,1,-1000.0],[0,0,0,1]]
[instrument]
a_um = 10.0
b_um_per_m = 2.5
[capture]
start_deg = [-40.0, -60.0]
sweep_deg = [80.0, {sweep2}]
points = [5, 5]
reflector_mm = [[300.0, 0.0, 500.0], [400.0, 0.0, 0.0]]
"""


def _two_joint(tmp_path, sweep2=120.0):
    (tmp_path / "two.toml").write_text(TWO_JOINT_ROBOT)
    path = tmp_path / "cell.toml"
    path.write_text(textwrap.dedent(TWO_JOINT_SCENARIO.format(sweep2=sweep2)))
    return path


def test_plan_check_thesis_plan_is_infeasible(tmp_path):
    out = tmp_path / "check"
    result = runner.invoke(app, ["plan", "check", "thesis-laser-tracker", "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert "joint limit 40" in result.output
    document = json.loads((out / "plan_check.json").read_text())
    assert document["feasible"] is False and document["failures"]["joint limit"] == 40
    assert document["circles"][5]["first_reasons"][0] == "joint limit J5"
    assert (out / "plan_check.png").stat().st_size > 1000
    rows = (out / "plan_check.csv").read_text().splitlines()
    assert len(rows) == 136 and rows[0].startswith("circle,direction,q1_deg")


def test_plan_check_another_robot_feasible_and_cli_equals_library(tmp_path):
    path = _two_joint(tmp_path)
    out = tmp_path / "check"
    result = runner.invoke(app, ["plan", "check", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "no capsule_radius_mm" in result.output
    from robotcal.io import load_scenario

    scenario = load_scenario(path)
    cell, _ = cell_from_scenario(scenario)
    library = check_plan(scenario.robot, scenario.plan, cell)
    rows = (out / "plan_check.csv").read_text().splitlines()[1:]
    clearance = np.array([float(row.split(",")[6]) for row in rows])
    np.testing.assert_allclose(clearance, library.clearance, atol=1e-3)  # written with 3 decimals
    # a sweep past J2's 90 deg limit: infeasible (exit 1); a missing file: input error (exit 2)
    assert runner.invoke(app, ["plan", "check", str(_two_joint(tmp_path, sweep2=170.0))]).exit_code == 1
    assert runner.invoke(app, ["plan", "check", str(tmp_path / "missing.toml")]).exit_code == 2


def test_program_cli_round_trip(tmp_path):
    path = _two_joint(tmp_path)
    out = tmp_path / "capture.src"
    result = runner.invoke(app, ["program", str(path), "--language", "krl", "--dwell", "3", "--out", str(out)])
    assert result.exit_code == 0, result.output
    moves = [
        [float(v) for v in re.findall(r"A\d (-?[\d.]+)", line)]
        for line in out.read_text().splitlines()
        if "PTP {" in line
    ]
    expected = [[-40 + 20 * k, -60] for k in range(5)] + [[40, -60 + 30 * k] for k in range(5)]
    np.testing.assert_allclose(moves, expected, atol=1e-6)
    assert (
        runner.invoke(app, ["program", str(path), "--language", "rapid", "--out", str(tmp_path / "x.mod")]).exit_code
        == 2
    )


def test_kr5_demo_plan_is_a_program_the_robot_can_run(tmp_path):
    # issue 28: kr5-demo turned A5 to 200 deg (20 readings beyond +-120, `joint_limits = "ignore"`), so
    # `robotcal program kr5-demo` refused; its J5 now sweeps -115..115 deg and the thesis scenarios keep Table 5.1
    from robotcal.io import load_robot, load_scenario
    from robotcal.planning.program import controller_readings

    scenario = load_scenario("kr5-demo")
    assert scenario.joint_limits == "warn"
    circle, direction, readings = scenario.plan.readings(scenario.robot)
    assert readings.shape == (270, 6) and set(direction.tolist()) == {1, -1}
    # independent truth: the robot file's limits (kuka-kr5-sixx-r650.toml, Fig. 4.17) and the J5 circle by hand,
    # 25 points from -115 to 115 deg in steps of 230 / 24 deg, then back
    limits = np.array([[-170, 170], [-45, 190], [-166, 119], [-190, 190], [-120, 120], [-350, 350]], dtype=float)
    degrees = np.rad2deg(readings)
    assert np.all((degrees >= limits[:, 0]) & (degrees <= limits[:, 1]))
    j5 = -115.0 + 230.0 / 24.0 * np.arange(25)
    np.testing.assert_allclose(degrees[(circle == 5) & (direction == 1), 4], j5, atol=1e-9)
    np.testing.assert_allclose(degrees[(circle == 5) & (direction == -1), 4], j5[::-1], atol=1e-9)
    controller = load_robot("kuka-kr5-sixx-r650-krc")
    angles = controller_readings(readings, scenario.robot, controller)  # raises beyond the KRC's limits
    assert np.all((angles >= controller.limits[:, 0]) & (angles <= controller.limits[:, 1]))

    out = tmp_path / "check"
    result = runner.invoke(app, ["plan", "check", "kr5-demo", "--out", str(out)])
    # infeasible still (exit 1): one SMR cannot face the tracker over the J5 and J6 sweeps; but no joint limit
    assert result.exit_code == 1 and "joint limit 0" in result.output, result.output
    assert json.loads((out / "plan_check.json").read_text())["failures"]["joint limit"] == 0
    for language, name in (("krl", "kr5_demo.src"), ("rapid", "kr5_demo.mod"), ("urscript", "kr5_demo.script")):
        result = runner.invoke(app, ["program", "kr5-demo", "--language", language, "--out", str(tmp_path / name)])
        assert result.exit_code == 0, result.output
    moves = [
        [float(v) for v in re.findall(r"A\d (-?[\d.]+)", line)]
        for line in (tmp_path / "kr5_demo.src").read_text().splitlines()
        if "PTP {" in line
    ]
    np.testing.assert_allclose(moves, degrees, atol=1e-6)  # the model robot file reads the model variables
    krc = tmp_path / "kr5_demo_krc.src"
    result = runner.invoke(app, ["program", "kr5-demo", "--controller", "kuka-kr5-sixx-r650-krc", "--out", str(krc)])
    assert result.exit_code == 0, result.output
    # the thesis scenarios keep the thesis plan (Table 5.1: J5 through 200 deg) and say the limits are ignored
    thesis = load_scenario("thesis-laser-tracker")
    np.testing.assert_allclose(np.rad2deg(thesis.plan.sweep), [45.0, 80.0, 100.0, 50.0, 200.0, 300.0])
    assert thesis.joint_limits == "ignore"


def test_sensitivity_cli(tmp_path):
    out = tmp_path / "sens"
    result = runner.invoke(
        app,
        ["sensitivity", "thesis-laser-tracker", "--vary", "capture.sweep_deg.4=15,90", "-n", "200", "--out", str(out)],
    )
    assert result.exit_code == 0, result.output
    document = json.loads((out / "sensitivity.json").read_text())
    assert [case["capture.sweep_deg.4"] for case in document["cases"]] == [15, 90]
    d4 = {row["capture.sweep_deg.4"]: row for row in document["rows"] if row["name"] == "J4.d"}
    assert d4[90]["std_uncertainty"] < d4[15]["std_uncertainty"]  # Fig. 5.15: a wider J4 angle, a lower u
    assert (out / "sensitivity_capture_sweep_deg_4.png").exists()
    assert (out / "sensitivity.csv").read_text().startswith("case,capture.sweep_deg.4,name")


def test_plan_optimise_cli(tmp_path):
    out = tmp_path / "opt"
    result = runner.invoke(
        app,
        ["plan", "optimise", "thesis-laser-tracker", "--out", str(out), "--generations", "1", "--population", "2",
         "--confirm-draws", "200", "--workspace-poses", "20", "--no-acceptance"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    comparison = json.loads((out / "comparison.json").read_text())
    assert comparison["optimised_feasible"] is True
    assert comparison["monte_carlo_p95_tcp_mm"]["optimised"] > 0
    # the optimised scenario loads and its plan passes the check
    from robotcal.io import load_scenario

    scenario = load_scenario(out / "optimised.toml")
    cell, _ = cell_from_scenario(scenario, no_acceptance=True)
    assert check_plan(scenario.robot, scenario.plan, cell).feasible
    assert int(scenario.plan.points.sum()) == 135


def _feasible_thesis_scenario(tmp_path):
    """thesis-noise-free with J5 turned 100 deg (within the KRC's +-120): a plan that is a valid program."""
    from robotcal.io import load_scenario

    text = Path(load_scenario("thesis-noise-free").source).read_text(encoding="utf-8")
    old = "sweep_deg = [45.0, 80.0, 100.0, 50.0, 200.0, 300.0]"
    assert old in text
    path = tmp_path / "feasible.toml"
    path.write_text(text.replace(old, "sweep_deg = [45.0, 80.0, 100.0, 50.0, 100.0, 300.0]"), encoding="utf-8")
    return path


def test_program_krl_name_is_the_file_name_and_no_negative_zero(tmp_path):
    # issue 24: --name of 200 characters was written as the DEF name (KRL allows 24), the DEF name differed
    # from the file name, and zero angles of the KRC's sign convention were written -0.000000
    scenario = _feasible_thesis_scenario(tmp_path)
    base = ["program", str(scenario), "--controller", "kuka-kr5-sixx-r650-krc"]
    out = tmp_path / "kr5_capture.src"
    result = runner.invoke(app, [*base, "--out", str(out)])
    assert result.exit_code == 0, result.output
    text = out.read_text(encoding="utf-8")
    assert re.search(r"^DEF kr5_capture\(\)$", text, re.MULTILINE)
    assert "-0.000000" not in text and "A2 0.000000" in text
    for language, suffix in (("rapid", ".mod"), ("urscript", ".script")):
        other = tmp_path / f"kr5_capture{suffix}"
        assert runner.invoke(app, [*base, "--language", language, "--out", str(other)]).exit_code == 0
        assert not re.search(r"-0\.0+\b", other.read_text(encoding="utf-8"))
    before = out.read_bytes()
    for extra, message in [
        (["--name", "a" * 200, "--out", str(out)], "has 200 characters; KRL allows at most 24"),
        (["--name", "other", "--out", str(out)], "--name 'other' differs from the file name 'kr5_capture.src'"),
        (["--out", str(tmp_path / ("b" * 30 + ".src"))], "has 30 characters; KRL allows at most 24"),
        (["--out", str(tmp_path / "my-capture.src")], "'my-capture' is not a valid KRL name"),
    ]:
        result = runner.invoke(app, [*base, *extra])
        lines = [line for line in result.output.splitlines() if line.strip()]
        assert result.exit_code == 2, result.output
        assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.output
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "feasible.toml", "kr5_capture.mod", "kr5_capture.script", "kr5_capture.src",
    ]  # fmt: skip


def test_iso9283_plan_krl_program_is_named_after_its_file(tmp_path):
    out = tmp_path / "iso_poses.csv"
    result = runner.invoke(
        app,
        ["iso9283-plan", "--scenario", "kr5-demo", "--side", "150", "--start", "0,90,-90,0,45,0", "--cycles", "2",
         "--out", str(out), "--program", "krl", "--controller", "kuka-kr5-sixx-r650-krc"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    text = (tmp_path / "iso_poses.src").read_text(encoding="utf-8")
    assert re.search(r"^DEF iso_poses\(\)$", text, re.MULTILINE) and not re.search(r"-0\.0+\b", text)
