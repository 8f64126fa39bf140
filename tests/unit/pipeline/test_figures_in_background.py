"""The run's figures are drawn by a worker process (robotcal.pipeline.figures): the same documents as
drawing them at once, and a figure's failure fails the run at the report stage, naming the figure."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import robotcal.plots.iso9283 as iso_plots
from robotcal.errors import InputError
from robotcal.pipeline import plan_run, run_calibration
from robotcal.pipeline import run as run_module
from robotcal.pipeline.figures import draw_now, figure_paths

DRAWS, REFINED_DRAWS, WORKSPACE = 100, 50, 10


def _plan(out: Path):
    return plan_run("kr5-demo", out, draws=DRAWS, refined_draws=REFINED_DRAWS, workspace=WORKSPACE, workers=1)


def test_figure_paths_of_values_and_jobs(tmp_path):
    from concurrent.futures import Future

    job = Future()
    job.set_result([str(tmp_path / "a.png"), tmp_path / "b.png"])
    assert figure_paths(job) == [tmp_path / "a.png", tmp_path / "b.png"]
    assert figure_paths(tmp_path / "c.png") == [tmp_path / "c.png"]
    assert figure_paths(None) == []
    assert draw_now("os.path:join", "a", "b") == "a/b"


def test_every_figure_is_a_document_and_a_file(tmp_path):
    out = tmp_path / "run"
    result = run_calibration(_plan(out))
    figures = sorted(name for name in result.documents if name.endswith(".png"))
    on_disk = sorted(path.relative_to(out).as_posix() for path in out.rglob("*.png"))
    assert figures == on_disk
    # every stage that draws has its figures: joints, evaluation, histograms, TCP, ISO 9283, plan
    for prefix in ("joints/", "evaluation/", "uncertainty/", "uncertainty-refined/", "tcp/", "iso9283/", "plan/"):
        assert any(name.startswith(prefix) for name in figures), prefix
    assert not [path for path in out.rglob("*") if ".tmp" in path.name]


def test_a_failing_figure_fails_the_run_at_the_report_stage(tmp_path, monkeypatch):
    def broken(results, path):
        raise InputError("the ISO figure cannot be drawn")

    # the worker is forked when the run starts: it sees the patched module, as the jobs name it by string
    monkeypatch.setattr(iso_plots, "plot_iso_results", broken)
    out = tmp_path / "run"
    with pytest.raises(InputError, match="cannot be drawn") as caught:
        run_calibration(_plan(out))
    assert caught.value.robotcal_stage == "report"
    record = json.loads((out / "run.json").read_text(encoding="utf-8"))
    assert record["status"] == "failed" and record["failed_stage"] == "report"
    assert "plot_iso_results" in record["error"]  # the job is named
    assert not (out / "report.html").exists()
    assert not (out / "iso9283" / "iso9283.png").exists()


def test_the_worker_is_gone_after_the_run(tmp_path):
    import multiprocessing

    run_calibration(_plan(tmp_path / "run"))
    assert not [child for child in multiprocessing.active_children() if child.name == "robotcal-figures"]
    assert run_module.FIGURE_MODULES  # the worker preloads the plot modules


def test_the_run_process_never_imports_matplotlib(tmp_path):
    """Only the figure worker draws: the run's own process writes files and imports no matplotlib (the plan
    stage's file writers once pulled it in, about 0.8 s of CPU in the demo's critical path)."""
    import subprocess
    import sys

    script = (
        "import sys\n"
        "from robotcal.pipeline import plan_run, run_calibration\n"
        f"plan = plan_run('kr5-demo', {str(tmp_path / 'run')!r}, draws={DRAWS}, refined_draws={REFINED_DRAWS}, "
        f"workspace={WORKSPACE}, workers=1)\n"
        "run_calibration(plan)\n"
        "print(sorted(name for name in sys.modules if name.split('.')[0] == 'matplotlib')[:5])\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=True)
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout
    assert (tmp_path / "run" / "plan" / "plan_check.png").is_file()  # drawn all the same, by the worker
