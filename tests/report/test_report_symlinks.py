"""Issue 12: ``report.html`` never embeds a file through a symbolic link or from outside the run folder
(read_run refuses them; build_report shows the refusals as problems)."""

from __future__ import annotations

import os

from robotcal.report.html import build_report


def test_symlinked_files_are_refused_and_noted(run_folder, tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("name,value\nroot-password-line,SECRET-42\n")
    evaluation = run_folder / "evaluation" / "evaluation.csv"
    evaluation.unlink()
    os.symlink(secret, evaluation)  # a CSV the report reads
    parameters = run_folder / "uncertainty" / "parameters.json"
    parameters.unlink()
    os.symlink("/etc/passwd", parameters)  # a JSON the report reads
    figure = next((run_folder / "joints").glob("*.png"))
    os.symlink(figure, run_folder / "joints" / "zz-link.png")  # a figure inside the folder, but a link
    report = build_report(run_folder)
    assert "SECRET-42" not in report.html
    assert "root:" not in report.html
    refused = [p for p in report.problems if "refused: a symbolic link" in p]
    assert any(p.startswith("evaluation/evaluation.csv") for p in refused), report.problems
    assert any(p.startswith("uncertainty/parameters.json") for p in refused), report.problems
    assert any(p.startswith("joints/zz-link.png") for p in refused), report.problems


def test_linked_folder_is_refused(run_folder, tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "summary.csv").write_text("joint,SECRET-43\n1,2\n")
    os.rename(run_folder / "joints", tmp_path / "joints-moved")
    os.symlink(outside, run_folder / "joints")
    report = build_report(run_folder)
    assert "SECRET-43" not in report.html
