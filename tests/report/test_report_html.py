"""The HTML report builder on a run folder (tests/report/conftest.py): sections, numbers, robustness."""

from __future__ import annotations

import base64
import json
import math
import re
import shutil

import numpy as np
import pytest
from report_run import (
    CONSISTENCY_MM,
    ELLIPSOID_MM,
    U_ANGLE_DEG,
    U_LENGTH_MM,
    U_REFINED_ANGLE_DEG,
    U_REFINED_LENGTH_MM,
    U_TCP_MM,
    WORKSPACE_U_MM,
)

from robotcal.errors import InputError
from robotcal.report.html import REPORT_NAME, _fmt, _label, _length, build_report, render_report

SECTION_IDS = [
    "summary",
    "parameters",
    "evaluation",
    "joints",
    "montecarlo",
    "tcp",
    "workspace",
    "planning",
    "view3d",
    "provenance",
]


def _row(page: str, name: str) -> list[str]:
    """Cells of the first table row whose first cell starts with ``name``."""
    match = re.search(rf"<tr[^>]*><td class=rc-text>{re.escape(name)}( <small>.*?</small>)?</td>(.*?)</tr>", page)
    assert match, f"no row {name}"
    return re.findall(r"<td[^>]*>(.*?)</td>", match.group(2))


def test_full_run_folder_gives_every_section_in_the_issue_order(run_folder):
    report = build_report(run_folder)
    assert report.path == run_folder / REPORT_NAME
    assert [s.id for s in report.sections] == SECTION_IDS
    assert all(s.present for s in report.sections)
    assert report.problems == ()
    # conftest writes 5 PNG figures and the capture gives one 3-D view
    assert (report.figures, report.canvases) == (5, 1)
    page = report.path.read_text(encoding="utf-8")
    assert page == report.html
    positions = [page.index(f'<section id="{anchor}">') for anchor in SECTION_IDS]
    assert positions == sorted(positions)
    assert not [p for p in run_folder.iterdir() if p.name.startswith(f".{REPORT_NAME}")]  # atomic: no temp left


def test_page_is_self_contained(run_folder):
    page = render_report(run_folder).html
    assert "Content-Security-Policy" in page and "default-src 'none'" in page
    # no external resource of any kind: every src is a data: URI, no stylesheet links, no CSS imports/urls
    assert re.findall(r'\ssrc="(?!data:)', page) == []
    assert "<link" not in page and "@import" not in page and "url(" not in page
    assert "http://" not in page and "https://" not in page
    assert page.count("<script>") == 3  # errors.js, viewer3d.js, check.js: no other inline code
    assert 'type="application/json"' in page


def test_figures_are_embedded_byte_for_byte(run_folder):
    page = render_report(run_folder).html
    uris = re.findall(r'<img src="data:image/png;base64,([^"]+)"', page)
    assert len(uris) == 5
    convergence = (run_folder / "evaluation" / "convergence.png").read_bytes()
    assert base64.b64encode(convergence).decode("ascii") in uris
    assert "evaluation/convergence.png" in page


def test_headline_numbers(run_folder):
    page = render_report(run_folder).html
    # evaluation.csv, validation capture, points view: nominal mean 0.9 mm, last set ("points") 0.05 mm
    assert "900 µm → 50 µm" in page
    assert "nominal → points" in page
    # tcp/pose/tcp.json: largest semi-axis of the ellipsoid
    assert f"largest semi-axis of the 95 % ellipsoid {max(ELLIPSOID_MM) * 1e3:.3g} µm" in page
    # largest identified standard uncertainties: the deployed (refined) model's, CPA's beside them
    assert f"{U_REFINED_LENGTH_MM * 1e3:.3g} µm" in page and f"{U_REFINED_ANGLE_DEG:.3g}°" in page
    assert "refined model (deployed)" in page
    assert f"CPA alone: {U_LENGTH_MM * 1e3:.3g} µm" in page and f"CPA alone: {U_ANGLE_DEG:.3g}°" in page
    # consistency: expected = sqrt(30^2 + 16^2) = 34 um against the observed 91 um, with the verdict
    expected = math.hypot(CONSISTENCY_MM["predicted_rms_mm"], CONSISTENCY_MM["instrument_rms_mm"]) * 1e3
    assert f"{expected:.3g} µm → {CONSISTENCY_MM['observed_rms_mm'] * 1e3:.3g} µm" in page
    assert "the kinematic model does not hold" in page
    # TCP at the pose: u_X = u_Y = u_Z = U_TCP_MM, so u_pos = sqrt(3) U_TCP_MM
    assert f"{math.sqrt(3) * U_TCP_MM * 1e3:.3g} µm" in page
    # workspace: u_pos = sqrt(3) u per pose; median of 5 values is the 3rd; the 95th percentile by
    # linear interpolation lies at rank 0.95 * 4 = 3.8 between the 4th and 5th values
    u = np.sqrt(3) * np.array(WORKSPACE_U_MM) * 1e3
    p95 = u[3] + 0.8 * (u[4] - u[3])
    assert f"{u[2]:.3g} µm / {p95:.3g} µm" in page
    # largest circle-fit RMS comes from the CPA provenance
    circles = json.loads((run_folder / "cpa" / "parameters.json").read_text())["provenance"]["circles"]
    worst = max(c["circle_rms_mm"] for c in circles)
    assert f"{worst * 1e3:.2f} µm" in page


def test_parameter_table_joins_sources_by_name(run_folder):
    page = render_report(run_folder).html
    cpa = json.loads((run_folder / "cpa" / "parameters.json").read_text())
    truth = json.loads((run_folder / "truth.json").read_text())
    # columns: nominal, truth, CPA, CPA − truth, refined (points), MC mean, u, interval low, high
    for joint, kind in ((1, "a"), (2, "a"), (3, "theta"), (2, "beta")):
        name = f"J{joint}.{kind}"
        cells = _row(page, name)
        cpa_value = cpa["joints"][joint - 1][kind]
        truth_value = truth["joints"][joint - 1][kind]
        assert cells[1] == f"{truth_value:.4f}"
        assert cells[2] == f"{cpa_value:.4f}"
        assert float(cells[3]) == pytest.approx(cpa_value - truth_value, rel=1e-3, abs=1e-12)  # 4 digits shown
        assert cells[4] == f"{cpa_value:.4f}"  # refine/points.json holds the CPA values
        u = U_ANGLE_DEG if kind in ("theta", "beta") else U_LENGTH_MM
        assert cells[6] == f"{u:.3g}"
    # the structurally fixed parameters (beta of DH joints, d of the Hayati J2) have no row
    section = page[page.index('<section id="parameters">') : page.index('<section id="evaluation">')]
    assert "<td class=rc-text>J1.beta" not in section and "<td class=rc-text>J2.d<" not in section
    # J6.d cannot be identified by CPA: shown, marked
    assert "J6.d <small>(not identified)</small>" in section
    assert "<th>nominal (mm)</th>" in section and "<th>CPA (deg)</th>" in section


def test_csv_with_a_unit_column_is_split_with_units_in_headers(run_folder):
    page = render_report(run_folder).html
    assert "<th>std_uncertainty (mm)</th>" in page and "<th>std_uncertainty (deg)</th>" in page
    assert "<th>mean error (mm)</th>" in page and "<th>improvement (%)</th>" in page  # evaluation.csv
    assert "<th>backlash (deg)</th>" in page  # joints/summary.csv


def test_long_csv_shows_its_first_rows(run_folder):
    page = render_report(run_folder).html
    # tcp/trajectory/tcp.csv: 60 poses x 3 length rows; the mm table shows 40 of 180
    assert "First 40 of 180 rows" in page


def test_number_formatting():
    assert _fmt(-0.00001, ".4f", exponent=False) == "0.0000"  # no negative zero
    assert _fmt(-0.00001) == "-1.000e-05"
    assert _fmt(None) == "n/a" and _fmt(3) == "3" and _fmt(True) == "yes"
    assert (_length(0.0123), _length(1.234), _length(None)) == ("12.3 µm", "1.23 mm", "n/a")
    assert _label("plane_rms_mm") == "plane rms (mm)" and _label("b_um_per_m") == "b (µm/m)"
    assert _label("improvement_pct") == "improvement (%)" and _label("points") == "points"


def test_rebuild_gives_the_same_page(run_folder):
    first = build_report(run_folder).html
    second = build_report(run_folder).html

    def strip(text):
        return re.sub(r"Report generated [^<]* by", "", text)

    assert strip(first) == strip(second)


def test_missing_stages_give_notes_not_errors(run_folder):
    for name in ("evaluation", "joints", "uncertainty", "uncertainty-refined", "tcp", "refine", "plan"):
        shutil.rmtree(run_folder / name)
    for name in ("run.json", "truth.json", "validation.csv"):
        (run_folder / name).unlink()
    report = render_report(run_folder)
    present = {s.id: s.present for s in report.sections}
    assert present == {
        "summary": True,
        "parameters": True,
        "evaluation": False,
        "joints": False,
        "montecarlo": False,
        "tcp": False,
        "workspace": False,
        "planning": False,
        "view3d": True,
        "provenance": True,
    }
    for folder in ("evaluation/", "joints/", "uncertainty/", "tcp/pose/", "tcp/trajectory/", "tcp/workspace/"):
        assert f"Stage not run: this run folder has no <code>{folder}</code>" in report.html
    assert report.figures == 0 and report.problems == ()
    assert "uncertainty stage not run" in report.html  # summary card says why it shows n/a


def test_folder_with_only_a_capture(run_folder, tmp_path):
    only = tmp_path / "only"
    only.mkdir()
    shutil.copy(run_folder / "capture.csv", only / "capture.csv")
    report = render_report(only)
    assert report.canvases == 1
    assert "No identified parameters to show" in report.html


def test_unreadable_files_are_reported_in_the_page(run_folder):
    (run_folder / "uncertainty" / "parameters.json").write_text("{not json")
    (run_folder / "joints" / "broken.png").write_text("not a png")
    with (run_folder / "joints" / "summary.csv").open("a") as stream:
        stream.write("7,0.1\n")
    report = render_report(run_folder)
    assert any(p.startswith("uncertainty/parameters.json: not a readable JSON file") for p in report.problems)
    assert "joints/broken.png: not a PNG file" in report.problems
    assert any(p.startswith("joints/summary.csv: row 8 has a different number of columns") for p in report.problems)
    assert "Some result files could not be read" in report.html
    assert report.figures == 5  # the broken PNG is not embedded


def test_invalid_run_folders(tmp_path):
    with pytest.raises(InputError, match="run folder not found"):
        render_report(tmp_path / "nope")
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        render_report(tmp_path / "file.txt")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no results found"):
        build_report(tmp_path / "empty")
    assert not (tmp_path / "empty" / REPORT_NAME).exists()


def test_out_elsewhere(run_folder, tmp_path):
    report = build_report(run_folder, tmp_path / "sub" / "r.html")
    assert report.path.read_text(encoding="utf-8") == report.html
    assert not (run_folder / REPORT_NAME).exists()
