"""``robotcal joints``: result folder, same numbers as the library, clear message without return sweeps."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.diagnostics import HarmonicModel, analyze_joints, fit_harmonics
from robotcal.io import read_capture

runner = CliRunner()

SCENARIO = """
robot = "kuka-kr5-sixx-r650"
[instrument]
preset = "thesis-laser-tracker"
[capture]
start_deg = [15.0, 0.0, 0.0, 0.0, 0.0, 0.0]
sweep_deg = [45.0, 80.0, 100.0, 50.0, 200.0, 300.0]
points = [8, 8, 10, 8, 10, 12]
reflector_mm = [[100.0, 0.0, 0.0], [200.0, 0.0, 0.0], [0.0, 50.0, 0.0], [20.0, 0.0, 0.0], [0.0, 80.0, 0.0], [0.0, 60.0, 0.0]]
bidirectional = {bidirectional}
joint_limits = "ignore"
seed = 3
[[capture.joint_errors]]
joint = 6
backlash_deg = 0.04
dz = {{ amplitude = 0.03, period_deg = 180.0, phase_deg = 40.0 }}
"""
PNG = b"\x89PNG\r\n\x1a\n"


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _capture(tmp_path: Path, bidirectional: bool) -> tuple[Path, Path]:
    scenario = tmp_path / "cell.toml"
    scenario.write_text(SCENARIO.format(bidirectional=str(bidirectional).lower()))
    capture = tmp_path / "capture.csv"
    result = invoke("simulate", scenario, "--out", capture)
    assert result.exit_code == 0, result.output
    return scenario, capture


def _rows(path: Path) -> list[dict]:
    with path.open() as stream:
        return list(csv.DictReader(stream))


def test_joints_writes_tables_and_figures_with_the_library_numbers(tmp_path):
    scenario, capture = _capture(tmp_path, bidirectional=True)
    out = tmp_path / "joints"
    result = invoke("joints", capture, "--scenario", scenario, "--out", out)
    assert result.exit_code == 0, result.output
    expected = {
        "summary.csv", "points.csv", "backlash.csv", "harmonics.json", "backlash_vectors.png", "backlash_xyz.png",
        "backlash_magnitude.png", "eccentricity_axial.png", "eccentricity_radial.png",
    }  # fmt: skip
    assert {p.name for p in out.iterdir()} == expected | {".robotcal"}  # the output-policy marker
    for name in expected:
        if name.endswith(".png"):
            assert (out / name).read_bytes().startswith(PNG)
    library = analyze_joints(read_capture(capture, n_joints=6))
    summary = _rows(out / "summary.csv")
    assert [row["joint"] for row in summary] == ["1", "2", "3", "4", "5", "6"]
    for row, expected_row in zip(summary, library.summary(), strict=True):
        # the CSV holds 9 decimals of mm
        np.testing.assert_allclose(float(row["backlash_mean_mm"]), expected_row.backlash_mean, atol=1e-9)
        np.testing.assert_allclose(float(row["circle_rms_mm"]), expected_row.circle_rms, atol=1e-9)
    points = _rows(out / "points.csv")
    assert len(points) == 2 * (8 + 8 + 10 + 8 + 10 + 12)
    assert list(points[0]) == ["point", "circle", "direction", "state", "reading_deg", "axial_mm", "radial_mm"]
    backlash = _rows(out / "backlash.csv")
    assert len(backlash) == 8 + 8 + 10 + 8 + 10 + 12 and sum(row["turnaround"] == "1" for row in backlash) == 6
    document = json.loads((out / "harmonics.json").read_text())
    model = HarmonicModel.from_dict(document)
    reference = fit_harmonics(library, order=2)
    theta = np.linspace(0.0, 5.0, 7)
    np.testing.assert_allclose(
        model.predict(6, "axial", theta), reference.predict(6, "axial", theta), rtol=0, atol=1e-15
    )
    assert document["provenance"]["backlash"] is True
    assert "J6" in result.output and "wrote" in result.output


def test_one_directional_capture_gets_a_clear_message(tmp_path):
    scenario, capture = _capture(tmp_path, bidirectional=False)
    out = tmp_path / "joints"
    result = invoke("joints", capture, "--scenario", scenario, "--out", out)
    assert result.exit_code == 2
    message = " ".join(result.output.split())
    assert "swept in one direction only" in message and "--no-backlash" in message
    assert not out.exists()  # nothing half-written
    result = invoke("joints", capture, "--scenario", scenario, "--out", out, "--no-backlash", "--order", "1")
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {
        ".robotcal", "summary.csv", "points.csv", "harmonics.json", "eccentricity_axial.png", "eccentricity_radial.png",
    }  # fmt: skip
    assert _rows(out / "summary.csv")[0]["backlash_mean_mm"] == ""
