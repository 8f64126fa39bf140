"""``robotcal report DIR [--out FILE]``: same page as the library, errors as exit status 2."""

from __future__ import annotations

import re

from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io.results.run_folder import read_run
from robotcal.report.html import render_report

runner = CliRunner()


def _strip_time(text: str) -> str:
    return re.sub(r"Report generated [^<]* by", "", text)


def test_report_command_writes_the_library_page(run_folder):
    result = runner.invoke(app, ["report", str(run_folder)])
    assert result.exit_code == 0, result.output
    assert "wrote" in result.output and "12 of 12 sections" in result.output
    written = (run_folder / "report.html").read_text(encoding="utf-8")
    assert _strip_time(written) == _strip_time(render_report(read_run(run_folder)).html)


def test_report_command_out_option_and_missing_stages(run_folder, tmp_path):
    (run_folder / "evaluation" / "evaluation.csv").unlink()
    (run_folder / "uncertainty" / "parameters.csv").unlink()
    import shutil

    shutil.rmtree(run_folder / "joints")
    out = tmp_path / "elsewhere" / "page.html"
    result = runner.invoke(app, ["report", str(run_folder), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.is_file() and not (run_folder / "report.html").exists()
    assert "not in this run: Joint diagnostics" in result.output


def test_report_command_errors(tmp_path):
    result = runner.invoke(app, ["report", str(tmp_path / "nope")])
    assert result.exit_code == 2
    assert "error:" in result.output and "run folder not found" in result.output
    result = runner.invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 2 and "no results found" in result.output
