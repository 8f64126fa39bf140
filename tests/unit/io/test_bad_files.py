"""Issue 12, input side: each hostile file the review found ends in one InputError naming the file (and
the line, key or circle), never a traceback; through ``robotcal identify`` it exits 2 with one line.

The random counterpart is tests/unit/io/test_parser_fuzz.py; these are the named regressions.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from robotcal.api import identify, simulate
from robotcal.capture import Capture
from robotcal.cli import app
from robotcal.errors import DegenerateGeometryError, InputError
from robotcal.io import load_scenario, read_capture, read_parameters
from robotcal.io.formats.capture_csv import write_capture
from robotcal.io.formats.draws_npz import read_draws, write_draws
from robotcal.io.formats.trajectory_csv import read_trajectory
from robotcal.io.schema._validation import MAX_LINE_CHARS
from robotcal.io.schema.robots import load_robot

runner = CliRunner()
SCENARIO = "thesis-noise-free"


@pytest.fixture(scope="module")
def capture():
    return simulate(load_scenario(SCENARIO), rng=1)


def _with(capture: Capture, **changes) -> Capture:
    fields = dict(circle=capture.circle, direction=capture.direction, readings=capture.readings)
    fields.update(points=capture.points, source="c.csv")
    fields.update(changes)
    return Capture(**fields)


def test_huge_csv_cell_names_the_line(tmp_path):
    path = tmp_path / "c.csv"
    path.write_text("circle,direction,q1,x,y,z\n1,1,0," + "9" * 200_000 + ",0,0\n")  # line 2: 200,010 chars
    with pytest.raises(InputError, match=rf"c.csv: line 2 is 200,010 characters long \(limit {MAX_LINE_CHARS:,}\)"):
        read_capture(path)
    with pytest.raises(InputError, match="c.csv: line 2 is"):
        read_trajectory(path)


@pytest.mark.parametrize("reader", [read_capture, read_trajectory, load_robot, load_scenario])
def test_random_bytes_are_not_text(tmp_path, reader):
    path = tmp_path / "f.toml"
    path.write_bytes(np.random.default_rng(0).bytes(300) + b"\xff")  # 0xff never occurs in UTF-8
    with pytest.raises(InputError, match=r"f.toml: not a UTF-8 text file \(byte \d+ is 0x[0-9a-f]{2}\)"):
        reader(path)


def test_nul_bytes_mean_binary(tmp_path):
    path = tmp_path / "c.csv"
    path.write_bytes(b"circle,direction,q1,x,y,z\n1,1,0,\x00,0,0\n")
    with pytest.raises(InputError, match="c.csv: holds NUL characters"):
        read_capture(path)


def test_a_folder_is_not_a_file(tmp_path):
    with pytest.raises(InputError, match="is a folder, not a capture CSV"):
        read_capture(tmp_path)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (10**401, r"key `joints\[0\].d`: must be a finite number; got an integer of ~402 digits$"),
        ("12", r'key `joints\[0\].d`: must be a number; got "12"$'),  # the value as the JSON writes it
        ([1], r"key `joints\[0\].d`: must be a number; got \[1\]$"),
        (True, r"key `joints\[0\].d`: must be a number; got true$"),
    ],
)
def test_parameter_json_wrong_values(tmp_path, value, message):
    robot = load_robot("kuka-kr5-sixx-r650")
    joints = [{"d": 0.0, "theta": 0.0, "a": 0.0, "alpha": 0.0} for _ in range(6)]
    joints[0]["d"] = value
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"robot": robot.name, "joints": joints}))
    with pytest.raises(InputError, match=message):
        read_parameters(path, robot)


def test_deeply_nested_json_and_toml(tmp_path):
    robot = load_robot("kuka-kr5-sixx-r650")
    (tmp_path / "run.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(InputError, match="run.json: JSON nested more than 64 levels deep"):
        read_parameters(tmp_path / "run.json", robot)
    (tmp_path / "s.toml").write_text("a = " + "[" * 100_000 + "]" * 100_000)
    with pytest.raises(InputError, match="s.toml: TOML nested more than 64 levels deep"):
        load_scenario(tmp_path / "s.toml")


@pytest.mark.parametrize("robot_json", ["{not json", "[" * 10_000, json.dumps({"name": "x"}), "[]"])
def test_corrupt_robot_json_in_draws(tmp_path, robot_json):
    robot = load_robot("kuka-kr5-sixx-r650")
    path = write_draws(tmp_path / "d.npz", robot, np.repeat(robot.nominal[None], 2, 0), np.ones((6, 5)), seed=1)
    with np.load(path) as archive:
        keys = {key: archive[key] for key in archive.files}
    keys["robot_json"] = np.array(robot_json)
    np.savez(path, **keys)
    with pytest.raises(InputError, match=r"d.npz: key `robot_json`"):
        read_draws(path)


def test_1e308_value_names_the_circle_and_row(capture):
    points = capture.points.copy()
    points[20, 1] = 1e308  # row 20 is on circle 2 (15 points on circle 1)
    with pytest.raises(InputError, match=r"c.csv: circle 2, point 21 \(CSV line 22\): a coordinate is not finite"):
        identify(_with(capture, points=points), load_scenario(SCENARIO))


def test_identical_points_name_the_circle(capture):
    points = capture.points.copy()
    rows = np.flatnonzero(capture.circle == 3)
    points[rows] = points[rows[0]]
    with pytest.raises(DegenerateGeometryError, match=r"c.csv: circle 3: all 30 points \(points 36..65\) are the same"):
        identify(_with(capture, points=points), load_scenario(SCENARIO))


def test_cli_identify_gives_one_line_exit_2(tmp_path, capture):
    path = tmp_path / "c.csv"
    write_capture(path, _with(capture, points=capture.points / 1000.0))  # metres
    result = runner.invoke(app, ["identify", str(path), "--scenario", SCENARIO, "--out", str(tmp_path / "p.json")])
    assert result.exit_code == 2, result.output
    assert "look like metres" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "p.json").exists()
    path.write_text("circle,direction,q1,q2,q3,q4,q5,q6,x,y,z\n" + "1" * 200_000 + "\n")
    result = runner.invoke(app, ["identify", str(path), "--scenario", SCENARIO, "--out", str(tmp_path / "p.json")])
    assert result.exit_code == 2, result.output
    assert "line 2 is 200,000 characters long" in result.output
    assert len(result.output.strip().splitlines()) <= 3  # one message (Rich may wrap long paths)


def test_pose_csv_refuses_readings_no_joint_has(tmp_path):
    # issue 24: q = 1e308 deg was predicted without a word; 1e6 deg (2,778 turns) is still read
    path = tmp_path / "poses.csv"
    path.write_text("pose,q1,q2\n1,1e6,-1e6\n2,0,1e308\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"poses.csv: line 3 \(pose 2\), column `q2`: 1e308 deg is no joint reading"):
        read_trajectory(path)
    path.write_text("pose,q1,q2\n1,1e6,-1e6\n", encoding="utf-8")
    np.testing.assert_allclose(read_trajectory(path), np.radians([[1e6, -1e6]]), rtol=1e-15)


def test_recorded_base_frame_of_a_parameter_json(tmp_path):
    from robotcal.io.formats.parameters_json import read_tracker_from_base, write_parameters
    from robotcal.kinematics.model import ParameterSet

    nominal = ParameterSet.nominal(load_robot("kuka-kr5-sixx-r650"))
    path = tmp_path / "p.json"
    write_parameters(path, nominal, {"tracker_from_base": None})  # a distances-criterion refinement
    assert read_tracker_from_base(path) is None
    frame = np.eye(4)
    frame[:3, 3] = [1000.0, 2.0, -3.0]
    write_parameters(path, nominal, {"tracker_from_base": frame.tolist()})
    np.testing.assert_array_equal(read_tracker_from_base(path), frame)
    write_parameters(path, nominal, {"tracker_from_base": (2.0 * np.eye(4)).tolist()})
    with pytest.raises(InputError, match=r"p.json: key `provenance.tracker_from_base` must be a 4x4 rigid transform"):
        read_tracker_from_base(path)
