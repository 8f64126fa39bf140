"""``robotcal simulate --free-poses N`` / ``--poses CSV``: several flange targets at free poses from the CLI
(issue 24: three-target random-pose captures could only be simulated from Python).

The CLI's capture equals the library's (``random_poses`` + ``simulate_target_poses`` with the same seeded
generator), and goes on through ``refine`` to the true target offsets, as tests/cli/test_real_cell.py does
with an imported capture.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io import load_scenario, read_capture, write_parameters
from robotcal.io.formats.trajectory_csv import write_trajectory
from robotcal.kinematics.model import ParameterSet, ReflectorMount
from robotcal.simulation.generator import simulate_target_poses
from robotcal.simulation.poses import random_poses

runner = CliRunner()
OFFSETS = {"T1": [60.0, 0.0, 25.0], "T2": [-30.0, 52.0, 30.0], "T3": [-30.0, -52.0, 35.0]}
TRUE_MM = ";".join(f"{name}={','.join(str(v) for v in offset)}" for name, offset in OFFSETS.items())
CELL = """robot = "abb-irb120"
tracker_from_base = [[0.0, -1.0, 0.0, 2100.0], [1.0, 0.0, 0.0, -150.0], [0.0, 0.0, 1.0, -420.0], [0.0, 0.0, 0.0, 1.0]]
[instrument]
a_um = {a_um}
b_um_per_m = 0.0
noise = "normal"
coverage_factor = 2.0
[[targets]]
name = "T1"
flange_mm = "unknown"
guess_mm = [55.0, 5.0, 20.0]
[[targets]]
name = "T2"
flange_mm = "unknown"
guess_mm = [-25.0, 45.0, 25.0]
[[targets]]
name = "T3"
flange_mm = [-30.0, -52.0, 35.0]
[[targets]]
name = "ring"
reflector_mm = [[100, 0, 0], [200, 0, 0], [0, 50, 0], [20, 0, 0], [0, 80, 0], [0, 60, 0]]
"""


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _cell(tmp_path, a_um=15.0):
    path = tmp_path / "cell.toml"
    path.write_text(CELL.format(a_um=a_um), encoding="utf-8")
    return path


def test_free_pose_capture_of_three_targets_equals_the_library(tmp_path):
    cell = _cell(tmp_path)
    out = tmp_path / "sim.csv"
    result = invoke("simulate", cell, "--free-poses", 40, "--targets-mm", TRUE_MM, "--seed", 3, "--out", out)
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "120 points: 40 random poses x targets T1, T2, T3" in said and "seed 3" in said
    capture = read_capture(out, n_joints=6)
    assert capture.target_names == ("T1", "T2", "T3")
    assert capture.point_targets[:6] == ("T1", "T2", "T3", "T1", "T2", "T3")  # pose by pose
    assert np.all(capture.circle == 0)
    # the library, same seed: poses within the limits less 5 deg ([validation] default), then the noise
    scenario = load_scenario(str(cell))
    rng = np.random.default_rng(3)
    offsets = np.array(list(OFFSETS.values()))
    readings = random_poses(
        scenario.robot, 40, margin_deg=5.0, reflector=ReflectorMount(frame="flange", positions=offsets.mean(axis=0)),
        rng=rng,
    )  # fmt: skip
    targets = [t for t in scenario.targets if t.name in OFFSETS]
    library, _ = simulate_target_poses(
        scenario.robot, readings, targets, scenario.instrument, scenario.tracker_from_base, true_offsets=offsets,
        rng=rng,
    )  # fmt: skip
    # the CSV holds 12 decimals of mm and deg
    np.testing.assert_allclose(capture.points, library.points, rtol=0, atol=1e-9)
    np.testing.assert_allclose(capture.readings, library.readings, rtol=0, atol=1e-13)


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")  # J6's frame held: by design
def test_simulated_three_target_capture_refines_to_the_true_offsets(tmp_path):
    cell = _cell(tmp_path)
    out, refined = tmp_path / "sim.csv", tmp_path / "refined.json"
    assert invoke("simulate", cell, "--free-poses", 40, "--targets-mm", TRUE_MM, "--seed", 5, "--out", out).exit_code == 0
    result = invoke("refine", out, "--scenario", cell, "--out", refined)
    assert result.exit_code == 0, result.output
    document = json.loads(refined.read_text(encoding="utf-8"))
    for name in ("T1", "T2"):  # the unknown ones: within 4.5 reported standard uncertainties of the truth
        entry = document["targets"][name]
        assert np.all(np.abs(np.array(entry["flange_mm"]) - OFFSETS[name]) < 4.5 * np.array(entry["u_mm"])), entry


def test_given_poses_true_params_offsets_and_a_subset_of_targets(tmp_path):
    cell = _cell(tmp_path, a_um=0.0)  # exact measurement
    scenario = load_scenario(str(cell))
    readings = np.radians([[10.0, -20.0, 30.0, 40.0, 50.0, 60.0], [-15.0, 25.0, -35.0, 45.0, -55.0, 65.0]])
    poses = tmp_path / "poses.csv"
    write_trajectory(poses, readings)
    values = scenario.robot.nominal.copy()
    values[1, 2] += 0.5
    truth = tmp_path / "truth.json"
    # a refinement's JSON carries estimated offsets: they are the truth of its unknown targets
    write_parameters(truth, ParameterSet(robot=scenario.robot, values=values), {}, targets={
        "T2": {"frame": "flange", "known": False, "flange_mm": OFFSETS["T2"], "u_mm": None}})  # fmt: skip
    out = tmp_path / "sim.csv"
    result = invoke("simulate", cell, "--poses", poses, "--targets", "T3,T2", "--true-params", truth, "--out", out)
    assert result.exit_code == 0, result.output
    capture = read_capture(out, n_joints=6)
    assert capture.point_targets == ("T3", "T2", "T3", "T2")
    from robotcal.kinematics.forward import forward_kinematics

    flange = scenario.tracker_from_base @ forward_kinematics(values, scenario.robot.model_joint_variables(readings))
    expected = [(flange[p] @ np.append(OFFSETS[name], 1.0))[:3] for p in range(2) for name in ("T3", "T2")]
    # pose CSV: 9 decimals of a degree; capture CSV: 12 decimals of mm
    np.testing.assert_allclose(capture.points, expected, rtol=0, atol=1e-7)


def test_free_pose_errors_are_one_line_and_write_nothing(tmp_path):
    cell = _cell(tmp_path)
    out = tmp_path / "sim.csv"
    for extra, message in [
        (["--free-poses", 5], "target 'T1' is declared with an unknown offset (flange_mm = \"unknown\")"),
        (["--free-poses", 5, "--targets", "T3,T9"], "--targets T9: no such flange target"),
        (["--free-poses", 5, "--targets", "ring"], "ring: per-joint reflectors, circle points only"),
        (["--free-poses", 5, "--targets", "T3", "--targets-mm", "T1=1,2,3"], "--targets-mm T1: not among"),
        (["--free-poses", 5, "--validation"], "--free-poses/--poses replace it"),
        (["--free-poses", 5, "--poses", cell], "not both"),
        (["--targets", "T3"], "--targets and --targets-mm go with --free-poses N or --poses CSV"),
    ]:
        result = invoke("simulate", cell, *extra, "--out", out)
        lines = [line for line in result.output.splitlines() if line.strip()]
        assert result.exit_code == 2, result.output
        assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.output
    assert not out.exists()
    # the circle capture of a plan-less scenario still names the missing plan
    result = invoke("simulate", cell, "--out", out)
    assert result.exit_code == 2 and "capture.start_deg" in result.output
