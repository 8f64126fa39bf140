"""Measurement sessions through the CLI (issue 29): ``import --session``, a scenario with a re-seated target
(``per_session = true``), ``refine`` writing each session's base frame, ``evaluate --absolute`` flagging a capture
from another station."""

from __future__ import annotations

import json
import warnings

import numpy as np
from typer.testing import CliRunner

from robotcal.capture import join_captures
from robotcal.cli import app
from robotcal.errors import IdentifiabilityWarning
from robotcal.geometry.transforms import rot_z
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.formats.capture_csv import read_capture, write_capture
from robotcal.io.schema.robots import load_robot
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses
from robotcal.simulation.sessions import SimulatedSession, simulate_sessions

runner = CliRunner()
ROBOT = load_robot("kuka-kr5-sixx-r650")
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.2, angle_sd_deg=0.05, rng=np.random.default_rng(3))
STATION_1 = np.array([[1.0, 0.0, 0.0, 1800.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 400.0], [0.0, 0.0, 0.0, 1.0]])
STATION_2 = STATION_1 @ rot_z(np.deg2rad(-11.0))
STATION_2[:3, 3] += [-300.0, 420.0, 80.0]
OFFSETS = np.array([[60.0, 0.0, 30.0], [0.0, 55.0, 40.0]])
TARGETS = (
    Target(name="A", frame="flange", positions=np.zeros(3), known=False, per_session=True),
    Target(name="B", frame="flange", positions=[0.0, 55.0, 40.0]),
)
SCENARIO = """robot = "kuka-kr5-sixx-r650"
[[targets]]
name = "A"
flange_mm = "unknown"
per_session = true
[[targets]]
name = "B"
flange_mm = [0.0, 55.0, 40.0]
[identification]
base_frame = "registered"
"""
NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _session(name, station, offsets, seed, poses=25):
    readings = random_poses(ROBOT, poses, rng=np.random.default_rng(seed))
    return SimulatedSession(name=name, readings=readings, tracker_from_base=station, true_offsets=offsets)


def test_refine_and_evaluate_over_two_stations(tmp_path):
    day2 = OFFSETS + [[0.6, 0.7, -0.4], [0.0, 0.0, 0.0]]
    parts = [
        simulate_sessions(ROBOT, (session,), TARGETS, NOISE_FREE, true_parameters=TRUTH)[0]
        for session in (_session("day1", STATION_1, OFFSETS, 1), _session("day2", STATION_2, day2, 2))
    ]
    capture = join_captures([(part, None) for part in parts], source="both days")
    write_capture(tmp_path / "capture.csv", capture)
    (tmp_path / "cell.toml").write_text(SCENARIO, encoding="utf-8")
    refined = tmp_path / "refined.json"
    with warnings.catch_warnings():
        warnings.simplefilter("always", IdentifiabilityWarning)  # printed by the CLI as "warning: ..."
        result = invoke("refine", tmp_path / "capture.csv", "--scenario", tmp_path / "cell.toml",
                        "--out", refined, "--folds", "0")  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "session day2" in " ".join(result.output.split())
    data = json.loads(refined.read_text())
    assert list(data["sessions"]) == ["day1", "day2"]
    np.testing.assert_allclose(data["targets"]["A@day2"]["flange_mm"], day2[0], rtol=0, atol=1e-7)
    # held out: day 2's station again, and a station nobody registered
    elsewhere = STATION_2 @ rot_z(np.deg2rad(9.0))
    elsewhere[:3, 3] += [500.0, 0.0, 0.0]
    for name, station in (("same", STATION_2), ("moved", elsewhere)):
        held = simulate_sessions(ROBOT, (_session("day2", station, day2, 7, 10),), TARGETS, NOISE_FREE,
                                 true_parameters=TRUTH)[0]  # fmt: skip
        write_capture(tmp_path / f"{name}.csv", held)
        assert read_capture(tmp_path / f"{name}.csv").session_names == ("day2",)
    out = tmp_path / "evaluation"
    result = invoke("evaluate", "--scenario", tmp_path / "cell.toml", "--params", refined, "--capture",
                    tmp_path / "same.csv", "--capture", tmp_path / "moved.csv", "--absolute", "--out", out)  # fmt: skip
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "refined on moved: FLAGGED" in said and "refined on same: FLAGGED" not in said
    document = json.loads((out / "evaluation.json").read_text())
    assert {entry["capture"] for entry in document["station_moved"]} >= {"moved"}
    rows = {(r["capture"], r["parameter_set"], r["view"]): r for r in document["rows"]}
    assert float(rows["same", "refined", "absolute"]["max_error_mm"]) < 1e-7
    assert float(rows["moved", "refined", "points"]["max_error_mm"]) < 1e-7


def test_import_session_option(tmp_path):
    files = {
        "plain.txt": "P1;1000;0;500\nP2;1010;0;500\nP3;1010;10;500\n",
        "joints.csv": "name,q1,q2,q3,q4,q5,q6\nP1,0,0,0,0,0,0\nP2,1,0,0,0,0,0\nP3,2,0,0,0,0,0\n",
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    out = tmp_path / "capture.csv"
    result = invoke("import", tmp_path / "plain.txt", "--joints", tmp_path / "joints.csv", "--session", "station-2",
                    "--units", "mm", "--out", out)  # fmt: skip
    assert result.exit_code == 0, result.output
    assert out.read_text().splitlines()[0].endswith(",x,y,z,session")
    assert read_capture(out).point_sessions == ("station-2",) * 3
