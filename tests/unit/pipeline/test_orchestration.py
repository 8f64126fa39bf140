"""run_calibration's record keeping, with the stages replaced by instant fakes: the final record is what the
report sees, a failing report stage is recorded as such, warnings are kept, an interrupt is recorded."""

from __future__ import annotations

import json
import warnings
from types import SimpleNamespace

import pytest

import robotcal.report.html as report_html
from robotcal.io.results.run_folder import STAGES, write_json
from robotcal.pipeline import plan_run, run_calibration
from robotcal.pipeline import stages as pipeline_stages
from robotcal.pipeline.stages import StageOutput


@pytest.fixture
def fake_stages(monkeypatch):
    """Every computing stage replaced by a fake that returns at once (simulate writes truth.json)."""
    parameters = SimpleNamespace(parameters="P")

    def simulate(scenario, seeds, out, step):
        document = write_json(out / "truth.json", {"robot": scenario.robot.name})
        value = SimpleNamespace(truth="T", capture="C", validation="V", poses=None)
        return StageOutput(value, {"truth.json": document}, "fake")

    def joints(*args, **kwargs):
        warnings.warn("J4 shows no backlash", UserWarning, stacklevel=1)
        return StageOutput(("D", "M"), {}, "fake")

    fakes = {
        "simulate_stage": simulate,
        "identify_stage": lambda *a, **k: StageOutput(parameters, {}, "fake"),
        "refine_stage": lambda *a, **k: StageOutput({"points": parameters, "distances": parameters}, {}, "fake"),
        "evaluate_stage": lambda *a, **k: StageOutput([], {}, "fake"),
        "joints_stage": joints,
        "uncertainty_stage": lambda *a, **k: StageOutput({"cpa": "A", "refined": "B"}, {}, "fake"),
        "tcp_stage": lambda *a, **k: StageOutput({}, {}, "fake"),
        "iso9283_stage": lambda *a, **k: StageOutput({}, {}, "fake"),
        "plan_stage": lambda *a, **k: StageOutput({}, {}, "fake"),
    }
    for name, fake in fakes.items():
        monkeypatch.setattr(pipeline_stages, name, fake)
    return fakes


def _record(out):
    return json.loads((out / "run.json").read_text(encoding="utf-8"))


def test_the_report_sees_the_final_record(tmp_path, fake_stages, monkeypatch):
    seen = []

    def render(result):
        seen.append(result)
        return SimpleNamespace(html="<!DOCTYPE html><title>fake</title>", figures=0)

    monkeypatch.setattr(report_html, "render_report", render)
    out = tmp_path / "run"
    result = run_calibration(plan_run("kr5-demo", out, draws=100, workers=1))
    assert len(seen) == 1 and seen[0].record["status"] == "done"
    assert seen[0].record == result.record == _record(out)
    assert all(entry["status"] == "done" for entry in result.record["stages"].values())
    assert result.record["stages"]["report"]["outputs"] == ["report.html"]
    assert result.record["stages"]["simulate"]["outputs"] == ["truth.json"]
    assert result.record["stages"]["joints"]["warnings"] == ["J4 shows no backlash"]
    assert (out / "report.html").read_text(encoding="utf-8") == "<!DOCTYPE html><title>fake</title>"
    assert result.documents["truth.json"] == {"robot": "kuka-kr5-sixx-r650"}
    assert "J4 shows no backlash" in result.summary.notes  # the stage warnings reach the summary once


def test_a_failing_report_is_recorded_and_leaves_the_stages(tmp_path, fake_stages, monkeypatch):
    def render(result):
        raise RuntimeError("template exploded")

    monkeypatch.setattr(report_html, "render_report", render)
    out = tmp_path / "run"
    with pytest.raises(RuntimeError, match="template exploded") as caught:
        run_calibration(plan_run("kr5-demo", out, draws=100, workers=1))
    assert caught.value.robotcal_stage == "report"
    record = _record(out)
    assert caught.value.robotcal_record == record
    assert record["status"] == "failed" and record["failed_stage"] == "report"
    assert record["error"] == "RuntimeError: template exploded"
    assert "finished" not in record and "outputs" not in record["stages"]["report"]
    assert [name for name in STAGES if record["stages"][name]["status"] == "done"] == list(STAGES[:-1])
    assert record["stages"]["report"]["status"] == "failed"
    assert (out / "truth.json").is_file() and not (out / "report.html").exists()


def test_an_interrupt_is_recorded(tmp_path, fake_stages, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline_stages, "tcp_stage", interrupted)
    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):
        run_calibration(plan_run("kr5-demo", out, draws=100, workers=1))
    record = _record(out)
    assert record["status"] == "interrupted" and record["failed_stage"] == "tcp"
    assert record["error"] == "interrupted (SIGINT, Ctrl-C)"
    assert record["stages"]["tcp"]["status"] == "interrupted" and record["stages"]["iso9283"]["status"] == "pending"
    assert record["stages"]["uncertainty"]["status"] == "done" and record["stages"]["plan"]["status"] == "pending"
