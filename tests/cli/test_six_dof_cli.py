"""A 6-DoF probe through the CLI (issue 29): refine identifies the probe's frame, evaluate reports orientation
errors [deg] under the points and absolute views."""

from __future__ import annotations

import json
import warnings

import numpy as np
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.errors import IdentifiabilityWarning
from robotcal.geometry.transforms import rot_x, rot_z
from robotcal.identification.targets import Target
from robotcal.io.formats.capture_csv import write_capture
from robotcal.io.schema.instruments import make_instrument
from robotcal.io.schema.robots import load_robot
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses
from robotcal.simulation.probe import simulate_probe_poses

runner = CliRunner()
ROBOT = load_robot("kuka-kr5-sixx-r650")
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.2, angle_sd_deg=0.05, rng=np.random.default_rng(5))
TRACKER = np.array([[1.0, 0.0, 0.0, 1800.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 400.0], [0.0, 0.0, 0.0, 1.0]])
ROTATION = (rot_z(np.deg2rad(-40.0)) @ rot_x(np.deg2rad(12.0)))[:3, :3]
OFFSET = np.array([30.0, 20.0, 90.0])
SCENARIO = """robot = "kuka-kr5-sixx-r650"
[instrument]
preset = "6dof-probe"
noise = "normal"
[[targets]]
name = "probe"
flange_mm = "unknown"
[identification]
base_frame = "registered"
"""


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _write(path, poses, seed):
    instrument = make_instrument(preset="6dof-probe", noise="normal")
    probe = Target(name="probe", frame="flange", positions=np.zeros(3), known=False)
    capture, _, _ = simulate_probe_poses(
        ROBOT, random_poses(ROBOT, poses, rng=np.random.default_rng(seed)), probe, ROTATION, instrument, TRACKER,
        true_parameters=TRUTH, true_offset=OFFSET, u95_mm=0.03, u95_deg=0.01, rng=seed,
    )  # fmt: skip
    write_capture(path, capture)


def test_refine_and_evaluate_a_six_dof_capture(tmp_path):
    (tmp_path / "cell.toml").write_text(SCENARIO, encoding="utf-8")
    _write(tmp_path / "capture.csv", 40, 1)
    _write(tmp_path / "heldout.csv", 15, 2)
    refined = tmp_path / "refined.json"
    with warnings.catch_warnings():
        warnings.simplefilter("always", IdentifiabilityWarning)
        result = invoke("refine", tmp_path / "capture.csv", "--scenario", tmp_path / "cell.toml", "--out", refined,
                        "--folds", "0")  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "probe" in result.output
    probe = json.loads(refined.read_text())["probe"]
    assert probe["target"] == "probe" and all(u is not None and u < 0.01 for u in probe["u_deg"])
    out = tmp_path / "evaluation"
    result = invoke("evaluate", "--scenario", tmp_path / "cell.toml", "--params", refined, "--capture",
                    tmp_path / "heldout.csv", "--absolute", "--out", out)  # fmt: skip
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "heldout: orientation, points view" in said and "heldout: orientation, absolute view" in said
    rows = json.loads((out / "evaluation.json").read_text())["orientation"]
    assert {row["view"] for row in rows} == {"points", "absolute"}
    for row in rows:  # a noise of 0.005 deg per component: errors of that order, never the probe's 40 deg turn
        assert row["parameter_set"] == "refined" and 0.001 < row["rms_error_deg"] < 0.03, row
