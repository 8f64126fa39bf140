"""CLI: simulate (truth, validation) -> identify -> refine (both criteria) -> evaluate."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io import load_scenario, read_capture, read_parameters
from robotcal.workflow import refine_scenario

runner = CliRunner()

SCENARIO = """
description = "reduced thesis test-2 layout, laser tracker, flange target"
robot = "kuka-kr5-sixx-r650-krc"
tracker_from_base = [[0,1,0,1800.0],[-1,0,0,5.0],[0,0,1,600.0],[0,0,0,1]]
[instrument]
preset = "thesis-laser-tracker"
[capture]
start_deg = [[167,-90,90,0,-90,0],[0,-5,45,-90,-90,0],[0,-90,145,-90,-90,0],[0,-90,90,177,-90,0],[0,-90,90,0,90,0],[0,-90,90,0,0,178]]
sweep_deg = [-334,-157,-259,-354,-180,-356]
points = [12, 8, 10, 12, 8, 12]
flange_reflector_mm = [60.0, 40.0, 30.0]
seed = 1
[truth]
length_sd_mm = 0.3
angle_sd_deg = 0.05
seed = 3
[validation]
poses = 40
seed = 5
"""


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")  # J6.alpha held: expected
def test_refine_and_evaluate_end_to_end(tmp_path):
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO)
    cal, val, truth, cpa = (tmp_path / name for name in ("cal.csv", "val.csv", "truth.json", "cpa.json"))
    assert invoke("simulate", scenario, "--out", cal, "--truth-out", truth).exit_code == 0
    result = invoke("simulate", scenario, "--validation", "--true-params", truth, "--out", val)
    assert result.exit_code == 0, result.output
    assert set(read_capture(val).circle) == {0}
    assert invoke("identify", cal, "-s", scenario, "-o", cpa).exit_code == 0
    for criterion in ("points", "distances"):
        out = tmp_path / f"{criterion}.json"
        result = invoke("refine", cal, "-s", scenario, "--start", cpa, "--criterion", criterion, "--out", out)
        assert result.exit_code == 0, result.output
        assert "J6.alpha" in result.output  # held, and said so
        provenance = json.loads(out.read_text())["provenance"]
        assert provenance["criterion"] == criterion and provenance["njev"] <= 50
        assert len(provenance["convergence"]["rms_mm"]) >= 2
        # the CLI and the library give the same numbers
        loaded = load_scenario(scenario)
        library = refine_scenario(read_capture(cal), loaded, read_parameters(cpa, loaded.robot), criterion=criterion)
        np.testing.assert_allclose(read_parameters(out, loaded.robot).values, library.parameters.values, atol=1e-9)
    folder = tmp_path / "evaluation"
    result = invoke(
        "evaluate",
        "-s",
        scenario,
        "-p",
        cpa,
        "-p",
        tmp_path / "points.json",
        "-p",
        tmp_path / "distances.json",
        "-c",
        val,
        "--out",
        folder,
    )
    assert result.exit_code == 0, result.output
    assert {p.name for p in folder.iterdir()} == {".robotcal", "evaluation.csv", "evaluation.json", "convergence.png"}
    rows = list(csv.DictReader((folder / "evaluation.csv").open()))
    assert [r["parameter_set"] for r in rows[:4]] == ["nominal", "cpa", "points", "distances"]
    for row in rows:
        if row["parameter_set"] in ("points", "distances"):
            assert float(row["improvement_pct"]) >= 80.0
    report = json.loads((folder / "evaluation.json").read_text())
    assert report["reference"] == "nominal" and len(report["rows"]) == 8


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")
def test_refine_errors_are_one_line_exit_2(tmp_path):
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO)
    cal = tmp_path / "cal.csv"
    invoke("simulate", scenario, "--out", cal)
    result = invoke("refine", cal, "-s", scenario, "--criterion", "rms", "--out", tmp_path / "r.json")
    assert result.exit_code == 2
    result = invoke("refine", cal, "-s", scenario, "--strict", "--out", tmp_path / "r.json")
    assert result.exit_code == 2 and "J6.alpha" in result.output
    assert not (tmp_path / "r.json").exists()
    result = invoke("evaluate", "-s", scenario, "-p", tmp_path / "missing.json", "-c", cal, "--out", tmp_path / "e")
    assert result.exit_code == 2 and "file not found" in result.output
    assert not (tmp_path / "e").exists()
