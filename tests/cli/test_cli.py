"""The CLI end to end: thin commands, same numbers as the library, clear errors, no half outputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from robotcal.api import identify
from robotcal.cli import app
from robotcal.io import load_scenario, read_capture, read_parameters, write_parameters
from robotcal.kinematics import ParameterSet

runner = CliRunner()
NOMINAL_KR5 = {
    "d": [335, 0, 0, 295, 0, 80],
    "theta": [0, 0, 90, 0, 180, 0],
    "a": [75, 270, 90, 0, 0, 0],
    "alpha": [90, 0, 90, 90, 90, 0],
}


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_catalog_commands_list_builtins():
    for command, expected in (
        ("robots", "kuka-kr5-sixx-r650-krc"),
        ("instruments", "leica-at960"),
        ("scenarios", "thesis-igps"),
    ):
        result = invoke(command)
        assert result.exit_code == 0, result.output
        assert expected in result.output.replace("\n", "")


def test_scenarios_lists_the_points_a_capture_measures():
    """Issue 30: kr5-demo was listed with 135 points, its bidirectional capture has 270."""
    from robotcal.io import list_scenarios

    result = invoke("scenarios")
    assert result.exit_code == 0, result.output
    rows = {line.split("│")[1].strip(): line for line in result.output.splitlines() if line.startswith("│ ")}
    for scenario in list_scenarios():
        circle, _, _ = scenario.plan.readings(scenario.robot)  # the points `robotcal simulate` writes
        if scenario.name in rows:  # the row's first line (a wrapped instrument cell continues below it)
            assert f"│ {circle.size:<6} │" in rows[scenario.name], (scenario.name, circle.size, rows[scenario.name])
    assert rows["kr5-demo"].count("270") == 1
    assert "kr5-demo: 2 x 135" in " ".join(result.output.split())


def test_noise_free_simulate_identify_gives_table_3_1(tmp_path):
    capture = tmp_path / "capture.csv"
    params = tmp_path / "params.json"
    assert invoke("simulate", "thesis-noise-free", "--out", capture).exit_code == 0
    result = invoke("identify", capture, "--scenario", "thesis-noise-free", "--out", params)
    assert result.exit_code == 0, result.output
    joints = json.loads(params.read_text())["joints"]
    for kind, nominal in NOMINAL_KR5.items():
        # thesis Table 5.3: noise-free CPA reproduces Table 3.1 to rounding; the CSV keeps 12 decimals
        np.testing.assert_allclose([j[kind] for j in joints], nominal, rtol=0, atol=1e-9)


def test_cli_and_library_give_the_same_numbers(tmp_path):
    capture = tmp_path / "capture.csv"
    params = tmp_path / "params.json"
    assert invoke("simulate", "thesis-laser-tracker", "--out", capture, "--seed", 7).exit_code == 0
    assert invoke("identify", capture, "-s", "thesis-laser-tracker", "-o", params).exit_code == 0
    scenario = load_scenario("thesis-laser-tracker")
    library = identify(read_capture(capture), scenario).parameters
    from_cli = read_parameters(params, scenario.robot)
    # the JSON stores degrees as floats: conversion round trip only
    np.testing.assert_allclose(from_cli.values, library.values, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(from_cli.identified, library.identified)


def _scenario_file(tmp_path: Path, tracker: np.ndarray, extra: str = "") -> Path:
    rows = ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in tracker)
    text = f"""
robot = "kuka-kr5-sixx-r650"
tracker_from_base = [{rows}]
[instrument]
a_um = 0.0
b_um_per_m = 0.0
[capture]
start_deg = [-20, 10, -30, 15, 5, -40]
sweep_deg = [70, -60, 90, 120, 150, 200]
points = [9, 11, 13, 10, 12, 14]
reflector_mm = [[120, 30, 10], [180, -20, 40], [10, 60, -15], [30, 25, 5], [-20, 70, 10], [40, 50, 20]]
joint_limits = "ignore"
{extra}
"""
    path = tmp_path / "scenario.toml"
    path.write_text(text)
    return path


def test_true_params_round_trip_through_files(tmp_path):
    rng = np.random.default_rng(3)
    from scipy.spatial.transform import Rotation

    tracker = np.eye(4)
    tracker[:3, :3] = Rotation.random(random_state=3).as_matrix()
    tracker[:3, 3] = rng.uniform(-3000, 3000, 3)
    scenario_path = _scenario_file(tmp_path, tracker)
    robot = load_scenario(scenario_path).robot
    truth = robot.nominal.copy()
    truth[:, [0, 2]] += rng.uniform(-0.5, 0.5, (6, 2))
    truth[:, [1, 3]] += np.deg2rad(rng.uniform(-0.2, 0.2, (6, 2)))
    truth[1, 0] = 0.0
    truth[1, 4] = np.deg2rad(0.15)
    true_path = write_parameters(tmp_path / "truth.json", ParameterSet(robot=robot, values=truth))
    capture, params = tmp_path / "c.csv", tmp_path / "p.json"
    assert invoke("simulate", scenario_path, "-o", capture, "--true-params", true_path).exit_code == 0
    result = invoke("identify", capture, "-s", scenario_path, "-o", params)
    assert result.exit_code == 0, result.output
    identified = read_parameters(params, robot)
    assert identified.identified.sum() == 20
    # exact on noise-free data; the CSV's 12 decimals limit the round trip to ~1e-10
    np.testing.assert_allclose(
        identified.values[identified.identified], truth[identified.identified], rtol=0, atol=1e-8
    )
    np.testing.assert_allclose(identified.values[~identified.identified], robot.nominal[~identified.identified], atol=0)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("colour = 1", "unknown key"),
        ('[identification]\ncircle_fit = "spline"', "identification.circle_fit"),
    ],
)
def test_bad_scenario_keys_are_named(tmp_path, extra, message):
    path = _scenario_file(tmp_path, np.eye(4), extra)
    if extra.startswith("colour"):
        path.write_text("colour = 1\n" + path.read_text())
    result = invoke("simulate", path, "-o", tmp_path / "c.csv")
    assert result.exit_code == 2
    assert message in result.output
    assert not (tmp_path / "c.csv").exists()


def test_unknown_robot_and_scenario(tmp_path):
    result = invoke("simulate", "no-such-scenario", "-o", tmp_path / "c.csv")
    assert result.exit_code == 2 and "unknown scenario" in result.output
    path = _scenario_file(tmp_path, np.eye(4))
    path.write_text(path.read_text().replace("kuka-kr5-sixx-r650", "kuka-kr99"))
    result = invoke("simulate", path, "-o", tmp_path / "c.csv")
    assert result.exit_code == 2 and "unknown robot 'kuka-kr99'" in result.output


def test_non_rigid_tracker_from_base_is_refused(tmp_path):
    tracker = np.eye(4)
    tracker[0, 0] = 1.1
    result = invoke("simulate", _scenario_file(tmp_path, tracker), "-o", tmp_path / "c.csv")
    assert result.exit_code == 2
    assert "not a rigid transform" in result.output


def test_bad_capture_gives_error_and_no_output(tmp_path):
    capture = tmp_path / "c.csv"
    assert invoke("simulate", "thesis-noise-free", "-o", capture).exit_code == 0
    lines = capture.read_text().splitlines()
    cases = {
        "missing column": (
            ["circle,direction,q1,q2,q3,q4,q5,q6,x,y"] + [",".join(line.split(",")[:-1]) for line in lines[1:]],
            "missing column(s) z",
        ),
        "nan": (lines[:5] + [lines[5].rsplit(",", 1)[0] + ",nan"] + lines[6:], "line 6, column `z`"),
        "text": (lines[:3] + [lines[3].replace("1,1,", "1,forward,", 1)] + lines[4:], "line 4, column `direction`"),
        "two points": (
            [lines[0]]
            + [line for line in lines[1:] if not line.startswith("4,")]
            + [line for line in lines[1:] if line.startswith("4,")][:2],
            "circle 4 has 2 points",
        ),
        "joint count": (
            [lines[0].replace(",q6", "")]
            + [",".join(p for i, p in enumerate(line.split(",")) if i != 7) for line in lines[1:]],
            "5 joint columns",
        ),
    }
    for name, (content, message) in cases.items():
        bad = tmp_path / f"{name}.csv"
        bad.write_text("\n".join(content) + "\n")
        out = tmp_path / f"{name}.json"
        result = invoke("identify", bad, "-s", "thesis-noise-free", "-o", out)
        assert result.exit_code == 2, (name, result.output)
        assert message in result.output.replace("\n", " "), (name, result.output)
        assert not out.exists(), name
