"""run_calibration on a small kr5-demo run: the documents in memory are the files, the capture is the CSV's,
the report is rendered once from memory, and the typed results are there for Python users."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

import robotcal.report.html as report_html
from robotcal.api import identify
from robotcal.capture import Capture
from robotcal.cli import app
from robotcal.io import load_scenario, read_capture
from robotcal.io.results.run_folder import STAGES, RunResult, Table, read_run
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline import plan_run, run_calibration
from robotcal.uncertainty.montecarlo import MonteCarloResult

#: Small enough for the test machine, large enough for every stage: a 95 % interval needs >= 21 draws.
DRAWS, REFINED_DRAWS, WORKSPACE = 100, 50, 10


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("pipeline") / "run"
    plan = plan_run("kr5-demo", out, draws=DRAWS, refined_draws=REFINED_DRAWS, workspace=WORKSPACE, workers=1)
    calls = []
    render = report_html.render_report

    def counted(result):
        calls.append(result)
        return render(result)

    events = []
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(report_html, "render_report", counted)
        result = run_calibration(plan, progress=lambda stage, done, total, detail: events.append((stage, done)))
    return out, result, calls, events


def test_every_stage_is_done_and_recorded(small_run):
    out, result, _, events = small_run
    assert isinstance(result, RunResult) and result.folder == out
    assert result.record["status"] == "done" and list(result.record["stages"]) == list(STAGES)
    assert all(entry["status"] == "done" for entry in result.record["stages"].values())
    assert result.record["seeds"] == {
        "capture": 1, "truth": 11, "validation": 2, "montecarlo": 1, "workspace": 0, "iso9283": 6, "poses": 3
    }  # fmt: skip
    # each stage announced its start (0) and end (-1) to the progress callback, in order
    starts = [stage for stage, done in events if done == 0]
    ends = [stage for stage, done in events if done == -1]
    assert starts == list(STAGES) and ends == list(STAGES)


def test_documents_in_memory_equal_the_folder_read_back(small_run):
    out, result, _, _ = small_run
    back = read_run(out)
    assert back.problems == ()
    assert sorted(back.documents) == sorted(result.documents)
    for name, document in result.documents.items():
        assert back.documents[name] == document, name
    assert back.record == result.record
    assert back.summary == result.summary
    # the kinds: JSON -> dict, CSV -> Table of strings, figures and draws -> the file's path in the run folder
    assert isinstance(result.documents["cpa/parameters.json"], dict)
    table = result.table("evaluation/evaluation.csv")
    assert isinstance(table, Table) and table.header[0] == "parameter_set"
    assert all(isinstance(cell, str) for row in table.rows for cell in row)
    assert result.file("uncertainty-refined/draws.npz") == out / "uncertainty-refined" / "draws.npz"
    paths = [document for document in result.documents.values() if not isinstance(document, dict | Table)]
    assert paths and all(path.is_file() and path.is_relative_to(out) for path in paths)
    # run.json as written is the final record: the report was rendered from it
    assert json.loads((out / "run.json").read_text(encoding="utf-8")) == result.record


def test_the_capture_in_memory_is_the_csv_file_bit_for_bit(small_run, tmp_path):
    out, result, _, _ = small_run
    scenario = load_scenario("kr5-demo")
    from_file = read_capture(out / "capture.csv", n_joints=scenario.robot.n_joints)
    kept = result.results["capture"]
    assert isinstance(kept, Capture)
    for name in ("circle", "direction", "readings", "points"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(from_file, name), strict=True)
    # the simulation's own numbers are not the file's (12 decimals): the rounding is what makes them equal
    assert result.results["validation"].points.shape[1] == 3
    # the stand-alone command on the run's capture reproduces the run's CPA exactly
    cpa_file = tmp_path / "cpa.json"
    outcome = CliRunner().invoke(
        app, ["identify", str(out / "capture.csv"), "--scenario", "kr5-demo", "--out", str(cpa_file)]
    )
    assert outcome.exit_code == 0, outcome.output
    stand_alone = json.loads(cpa_file.read_text(encoding="utf-8"))
    run_cpa = result.json("cpa/parameters.json")
    for key in ("joints", "identified"):  # every parameter value, as written with full precision
        assert stand_alone[key] == run_cpa[key], key
    np.testing.assert_array_equal(identify(from_file, scenario).parameters.values, result.results["cpa"].values)


def test_report_is_rendered_once_from_the_final_record(small_run):
    out, result, calls, _ = small_run
    assert len(calls) == 1
    rendered = calls[0]
    assert rendered.record["status"] == "done" and rendered.record["seconds"] == result.record["seconds"]
    assert rendered.record["stages"]["report"]["status"] == "done"
    assert "report.html" not in rendered.documents  # not yet written when rendered
    assert result.file("report.html") == out / "report.html"
    assert (out / "report.html").read_text(encoding="utf-8") == result.results["report"].html


def test_typed_results_for_python_users(small_run):
    _, result, _, _ = small_run
    results = result.results
    assert isinstance(results["cpa"], ParameterSet) and isinstance(results["truth"], ParameterSet)
    # both criteria, and the geometric fit beside the demo's extended deployed model (its [joint_model] is auto)
    assert set(results["refined"]) == {"points", "distances", "geometric"}
    assert results["refined"]["points"].model != "geometric" and results["refined"]["geometric"].model == "geometric"
    assert isinstance(results["montecarlo"]["cpa"], MonteCarloResult)
    assert results["montecarlo"]["cpa"].n_draws == DRAWS
    assert results["montecarlo"]["refined"].n_draws == REFINED_DRAWS
    assert results["tcp"]["workspace"].n_poses == WORKSPACE
    assert results["tcp"]["pose"].n_poses == 1
    # the same numbers as the files: the workspace map's per-pose uncertainty is in tcp/workspace/tcp.json
    document = result.json("tcp/workspace/tcp.json")
    assert len(document["poses"]) == WORKSPACE
    # the headline rows of evaluation.json are the typed evaluation rows
    rows = {(r.parameter_set, r.view, r.capture): r.mean_error_mm for r in results["evaluation"]}
    headline = result.json("evaluation/evaluation.json")["headline"]
    assert rows[("points", "points", "validation")] == headline["after_mean_mm"]
