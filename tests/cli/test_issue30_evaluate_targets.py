"""Issue 30, item 4, from the command line: ``evaluate`` with a parameter JSON that estimated some unknown targets
but not the one the capture's points are labelled with used that target's ``guess_mm`` with no note (15.4 mm), and
``settings.target_offsets`` listed only the nominal set. Now a warning names the set and the target, and the
settings record, per set, the offsets it did not estimate itself and what was used instead."""

from __future__ import annotations

import json
import warnings

import numpy as np
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.identification.evaluation import GuessedOffsetWarning
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io import load_robot, write_capture, write_parameters
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.generator import simulate_target_poses
from robotcal.simulation.poses import random_poses

runner = CliRunner()
TRUE = {"T1": [60.0, 0.0, 30.0], "T2": [0.0, 55.0, 40.0]}
CELL = """robot = "kuka-kr5-sixx-r650"
tracker_from_base = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
[[targets]]
name = "T1"
flange_mm = "unknown"
guess_mm = [50.0, 5.0, 25.0]
[[targets]]
name = "T2"
flange_mm = "unknown"
guess_mm = [10.0, 45.0, 30.0]
"""


def _files(tmp_path, estimated: dict):
    robot = load_robot("kuka-kr5-sixx-r650")
    scenario = tmp_path / "cell.toml"
    scenario.write_text(CELL, encoding="utf-8")
    target = Target(name="T2", frame="flange", positions=np.zeros(3), known=False)
    readings = random_poses(robot, 12, rng=np.random.default_rng(2))
    exact = Instrument(name="exact", a_mm=0.0, b_mm_per_m=0.0)
    capture, _ = simulate_target_poses(robot, readings, [target], exact, np.eye(4), true_offsets=[TRUE["T2"]], rng=0)
    write_capture(tmp_path / "held.csv", capture)
    targets = {name: {"frame": "flange", "known": False, "flange_mm": TRUE[name], "u_mm": None} for name in estimated}
    write_parameters(tmp_path / "p.json", ParameterSet.nominal(robot), {}, targets=targets)
    return scenario


def _evaluate(tmp_path, scenario, out):
    args = ["evaluate", "-s", scenario, "-p", tmp_path / "p.json", "-c", tmp_path / "held.csv", "-o", tmp_path / out]
    with warnings.catch_warnings():
        warnings.simplefilter("always", GuessedOffsetWarning)  # printed by the CLI as "warning: ..."
        result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    document = json.loads((tmp_path / out / "evaluation.json").read_text(encoding="utf-8"))
    rows = {(row["parameter_set"], row["view"]): row["mean_error_mm"] for row in document["rows"]}
    return " ".join(result.output.split()), document["settings"].get("target_offsets"), rows


def test_a_target_the_set_did_not_estimate_is_named_and_recorded(tmp_path):
    scenario = _files(tmp_path, estimated=["T1"])  # the points are on T2
    said, notes, rows = _evaluate(tmp_path, scenario, "eval")
    for label in ("nominal", "p"):
        assert f"warning: parameter set '{label}' estimated no offset for target T2" in said, said
    assert notes == dict.fromkeys(("nominal", "p"), "T2 at its guess (guess_mm): p did not estimate it")
    assert rows[("p", "points")] > 1.0  # the guess is ~15 mm off


def test_a_set_that_estimated_it_is_used_quietly_and_lent_to_the_nominal_set(tmp_path):
    scenario = _files(tmp_path, estimated=["T1", "T2"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", GuessedOffsetWarning)
        said, notes, rows = _evaluate(tmp_path, scenario, "eval")
    assert "warning" not in said
    assert set(notes) == {"nominal"} and notes["nominal"].startswith("unknown target offsets estimated by p (")
    assert rows[("p", "points")] < 1e-6 and rows[("nominal", "points")] < 1e-6  # the nominal robot is the truth
