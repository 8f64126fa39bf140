"""The extended model on the command line (issue 22): refine --model/--poses/--backlash, compensate, program
--compensate, export's note, and uncertainty --model refined of an extended estimate."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

import robotcal
from robotcal.cli import app
from robotcal.io import write_capture
from robotcal.io.formats.trajectory_csv import read_trajectory, write_trajectory
from robotcal.kinematics.forward import forward_kinematics

runner = CliRunner()
# the demo's J6.alpha is behind the flange target of its calibration poses: the refinement holds it and says so
pytestmark = pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """The demo's files and an extended refinement of them by the command line."""
    folder = tmp_path_factory.mktemp("extended")
    scenario = robotcal.load_scenario("kr5-demo")
    truth = robotcal.perturb(scenario, rng=11)
    write_capture(folder / "capture.csv", robotcal.simulate(scenario, rng=1, true_parameters=truth))
    write_capture(folder / "poses.csv", robotcal.simulate_poses(scenario, kind="calibration", rng=3, true_parameters=truth))
    assert invoke("identify", folder / "capture.csv", "-s", "kr5-demo", "-o", folder / "cpa.json").exit_code == 0
    assert invoke("joints", folder / "capture.csv", "-s", "kr5-demo", "-o", folder / "joints").exit_code == 0
    result = invoke(
        "refine", folder / "capture.csv", "-s", "kr5-demo", "--start", folder / "cpa.json", "-o", folder / "ref.json",
        "--poses", folder / "poses.csv", "--backlash", folder / "joints" / "summary.csv", "--model", "auto",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    return folder, scenario, truth, result.output


def test_refine_auto_reports_every_model_and_writes_the_joint_model(calibrated):
    folder, scenario, truth, output = calibrated
    assert "Model choice (5-fold cross-validation by pose)" in output and "model: compliance" in output
    document = json.loads((folder / "ref.json").read_text())
    names = [p["name"] for p in document["joint_model"]["parameters"]]
    assert names == ["J2.k", "J3.k"] and document["provenance"]["model"] == "compliance"
    assert document["joint_model"]["backlash_deg"][1] > 0.005  # J2's lash, from the joints stage
    k = np.array([p["value"] for p in document["joint_model"]["parameters"]])
    u = np.array([p["u"] for p in document["joint_model"]["parameters"]])
    # the truth's compliances within 3 standard uncertainties
    assert np.all(np.abs(k - truth.joint_model.values) <= 3 * u), (k, u)
    assert {c["model"] for c in document["provenance"]["model_choice"]["candidates"]} == {
        "geometric", "compliance", "harmonic", "compliance+harmonic"
    }


def test_refine_output_says_what_its_start_column_and_times_are(calibrated):
    """Issue 30: the "vs start" table headed the start (CPA) values "nominal"; with --model auto the "time [s]"
    was the chosen model's fit alone, not the refinement's 24 fits."""
    output = calibrated[3]
    table = output.split("vs start", 1)[1].split("Refinement", 1)[0]
    header = next(line for line in table.splitlines() if line.startswith("┃"))
    assert [cell.strip() for cell in header.split("┃")[1:-1]] == ["parameter", "unit", "start", "identified", "difference"]
    summary = output.split("Refinement", 1)[1].split("Joint model", 1)[0]
    rows = [line.split("│")[1:3] for line in summary.splitlines() if line.startswith("│")]
    labels, values = (" ".join(row[k].strip() for row in rows) for k in (0, 1))  # the cells wrap at 80 columns
    assert "time [s]" not in labels and "time of the chosen model's fit [s]" in labels
    assert "time of the whole refinement [s]" in labels
    assert "(24 fits: each of 4 models on all points and in 5 cross-validation folds)" in values


def test_refine_time_rows_name_what_was_timed():
    from types import SimpleNamespace

    from robotcal.cli.refine import time_rows

    single = SimpleNamespace(wall_time_s=1.5, cross_validation=None, model_choice=None)
    assert time_rows(single, 1.6) == [("time of the fit [s]", "1.50")]
    validated = SimpleNamespace(wall_time_s=1.5, cross_validation=SimpleNamespace(folds=5), model_choice=None)
    assert time_rows(validated, 9.0) == [
        ("time of the fit [s]", "1.50"),
        ("time of the whole refinement [s]", "9.00 (6 fits: the model on all points and in 5 cross-validation folds)"),
    ]


def test_compensate_round_trip_and_its_file(calibrated, tmp_path):
    folder, scenario, _, _ = calibrated
    calibrated_model = robotcal.read_parameters(folder / "ref.json", scenario.robot)
    taught = np.deg2rad([[10.0, 40.0, 30.0, 5.0, 45.0, 0.0], [-30.0, 70.0, -20.0, 40.0, -60.0, 90.0]])
    write_trajectory(tmp_path / "taught.csv", taught)
    out = tmp_path / "commands.csv"
    result = invoke("compensate", folder / "ref.json", "--poses", tmp_path / "taught.csv", "-o", out, "--tool", "0,0,100")
    assert result.exit_code == 0, result.output
    commands = read_trajectory(out, n_joints=6)
    tool = np.eye(4)
    tool[:3, 3] = [0.0, 0.0, 100.0]
    wanted = forward_kinematics(scenario.robot.nominal, scenario.robot.model_joint_variables(taught)) @ tool
    reached = forward_kinematics(calibrated_model.values, calibrated_model.model_joint_variables(commands)) @ tool
    # the pose CSV holds 9 decimals of degrees: 1e-9 deg x 700 mm ~ 1e-8 mm
    assert np.abs(reached[:, :3, 3] - wanted[:, :3, 3]).max() < 1e-6
    assert out.read_text().startswith("# written by robotcal")
    # robotcal's own file is replaced without --force
    assert invoke("compensate", folder / "ref.json", "--poses", tmp_path / "taught.csv", "-o", out).exit_code == 0
    # Cartesian targets in predict's format give the same commands (the taught readings as seeds)
    predicted = tmp_path / "targets.csv"
    assert invoke("predict", folder / "ref.json", "--poses", tmp_path / "taught.csv", "--robot", "kuka-kr5-sixx-r650",
                  "-o", predicted).exit_code == 0  # fmt: skip
    rows = list(csv.DictReader(predicted.open()))
    assert set(rows[0]) >= {"x", "y", "z", "A", "B", "C"}


def test_export_says_what_a_geometric_format_leaves_out(calibrated, tmp_path):
    folder, _, _, _ = calibrated
    result = invoke("export", folder / "ref.json", "--format", "urdf", "-o", tmp_path / "robot.urdf")
    assert result.exit_code == 0, result.output
    assert "note: the calibrated model also has a joint model" in result.output and "compensate" in result.output
    text = (tmp_path / "robot.urdf").read_text()
    assert "J2.k" in text and "only its geometric part is written here" in text
    # a DH table (of a set standard DH can express: the nominal geometry with the fitted joint model) says it too,
    # in a first comment that keeps the file robotcal's: a second export replaces it without --force
    fitted = robotcal.read_parameters(folder / "ref.json", robotcal.load_robot("kuka-kr5-sixx-r650"))
    robotcal.write_parameters(tmp_path / "nominal.json", fitted.replace(values=fitted.robot.nominal))
    for _ in range(2):
        result = invoke("export", tmp_path / "nominal.json", "--format", "dh", "-o", tmp_path / "dh.csv")
        assert result.exit_code == 0, result.output
    assert (tmp_path / "dh.csv").read_text().startswith("# written by robotcal: the calibrated model also has")


def test_program_compensate(calibrated, tmp_path):
    from robotcal.io.schema.builtins import data_path

    folder, _, _, _ = calibrated
    # the demo's plan turns J5 by 200 deg, beyond its limits: a program of a plan within them
    text = data_path("scenarios", "kr5-demo.toml").read_text()
    feasible = tmp_path / "feasible.toml"
    feasible.write_text(text.replace("200.0, 300.0]", "100.0, 300.0]").replace('joint_limits = "ignore"', ""))
    plain, compensated = tmp_path / "plain.src", tmp_path / "comp.src"
    assert invoke("program", feasible, "-o", plain).exit_code == 0
    result = invoke("program", feasible, "-o", compensated, "--compensate", folder / "ref.json")
    assert result.exit_code == 0, result.output
    assert "compensated" in result.output and "compensated with the calibrated model" in compensated.read_text()
    assert plain.read_text() != compensated.read_text()


def test_refine_refuses_bad_model_options(calibrated, tmp_path):
    folder, _, _, _ = calibrated
    base = ["refine", folder / "capture.csv", "-s", "kr5-demo", "-o", tmp_path / "r.json"]
    result = invoke(*base, "--model", "quadratic")
    assert result.exit_code != 0 and "--model" in result.output
    result = invoke(*base, "--folds", "1")
    assert result.exit_code != 0 and "--folds" in result.output
    result = invoke(*base, "--model", "auto", "--folds", "0")
    assert result.exit_code != 0 and "cross-validation" in result.output
    assert not (tmp_path / "r.json").exists()
