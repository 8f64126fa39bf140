"""The HTML report: render_report on a RunResult (in memory or read from a folder), build_report on a folder.

The run folder is tests/report/report_run.py's (conftest.py); its synthetic figures are the truths the
headline numbers are checked against.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import io
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from report_run import (
    BACKLASH_MM,
    CONSISTENCY_MM,
    CRITERION_RMS_MM,
    ELLIPSOID_MM,
    NOISE_FLOOR_UM,
    POINT_RMS_MM,
    U_ANGLE_DEG,
    U_LENGTH_MM,
    U_REFINED_ANGLE_DEG,
    U_REFINED_LENGTH_MM,
    U_TCP_MM,
    WORKSPACE_U_MM,
    load_run,
)

from robotcal.errors import InputError
from robotcal.io.results.run_folder import RunResult, Table
from robotcal.io.results.run_summary import Summary
from robotcal.report.html import REPORT_NAME, build_report, render_report
from robotcal.report.page import _CAPTIONS, _fmt, _label, _length

SECTION_IDS = [
    "summary",
    "parameters",
    "model",
    "evaluation",
    "joints",
    "montecarlo",
    "tcp",
    "workspace",
    "iso9283",
    "planning",
    "view3d",
    "provenance",
]


def _rows(page: str, name: str) -> list[list[str]]:
    """Cells (after the first) of every table row whose first cell is ``name``."""
    found = re.findall(rf'<tr[^>]*><td class="rc-text">{re.escape(name)}( <small>.*?</small>)?</td>(.*?)</tr>', page)
    assert found, f"no row {name}"
    return [re.findall(r"<td[^>]*>(.*?)</td>", cells) for _, cells in found]


def _section(page: str, anchor: str) -> str:
    start = page.index(f'<section id="{anchor}">')
    return page[start : page.index("</section>", start)]


def _render(folder) -> str:
    return render_report(load_run(folder)).html


def test_full_run_folder_gives_every_section_in_order(run_folder):
    report = build_report(run_folder)
    assert report.path == run_folder / REPORT_NAME
    assert [s.id for s in report.sections] == SECTION_IDS
    assert all(s.present for s in report.sections)
    assert report.problems == ()
    # report_run.py writes 5 PNG figures and the capture gives one 3-D view
    assert (report.figures, report.canvases) == (5, 1)
    page = report.path.read_text(encoding="utf-8")
    assert page == report.html
    positions = [page.index(f'<section id="{anchor}">') for anchor in SECTION_IDS]
    assert positions == sorted(positions)
    assert not [p for p in run_folder.iterdir() if p.name.startswith(f".{REPORT_NAME}")]  # atomic: no temp left


def test_page_is_self_contained(run_folder):
    page = _render(run_folder)
    assert "Content-Security-Policy" in page and "default-src &#39;none&#39;" in page
    # no external resource of any kind: every src is a data: URI, no stylesheet links, no CSS imports/urls
    assert re.findall(r'\ssrc="(?!data:)', page) == []
    assert "<link" not in page and "@import" not in page and "url(" not in page
    assert "http://" not in page and "https://" not in page
    assert page.count("<script>") == 3  # errors.js, viewer3d.js, check.js: no other inline code
    assert 'type="application/json"' in page


def test_figures_are_embedded_byte_for_byte(run_folder):
    page = _render(run_folder)
    uris = re.findall(r'<img src="data:image/png;base64,([^"]+)"', page)
    assert len(uris) == 5
    convergence = (run_folder / "evaluation" / "convergence.png").read_bytes()
    assert base64.b64encode(convergence).decode("ascii") in uris
    assert "evaluation/convergence.png" in page


def test_headline_numbers(run_folder):
    page = _render(run_folder)
    # evaluation.json headline: nominal mean 0.9 mm, the points criterion's 0.05 mm
    assert "900 µm → 50 µm" in page
    assert "nominal → points (refined, points criterion)" in page
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
    circles = load_run(run_folder).json("cpa/parameters.json")["provenance"]["circles"]
    worst = max(c["circle_rms_mm"] for c in circles)
    assert f"{worst * 1e3:.2f} µm" in page


def test_summary_is_computed_once(run_folder):
    """render_report uses RunResult.summary when the run has one (a marked summary shows in the page), and
    computes it from the documents when the run has none."""
    result = load_run(run_folder)
    marked = Summary(validation_before_mm=0.123, validation_after_mm=0.0456)
    assert "123 µm → 45.6 µm" in render_report(dataclasses.replace(result, summary=marked)).html
    assert "900 µm → 50 µm" in render_report(dataclasses.replace(result, summary=None)).html


def test_parameter_tables_join_sources_by_name(run_folder):
    page = _render(run_folder)
    result = load_run(run_folder)
    cpa, truth = result.json("cpa/parameters.json"), result.json("truth.json")
    for joint, kind in ((1, "a"), (2, "a"), (3, "theta"), (2, "beta")):
        name = f"J{joint}.{kind}"
        values, uncertainty = _rows(page, name)[:2]
        cpa_value = cpa["joints"][joint - 1][kind]
        truth_value = truth["joints"][joint - 1][kind]
        # values: nominal, truth, CPA, CPA − truth, refined (points)
        assert values[1] == f"{truth_value:.4f}"
        assert values[2] == f"{cpa_value:.4f}"
        assert float(values[3]) == pytest.approx(cpa_value - truth_value, abs=5.1e-5)  # 4 decimals shown
        assert values[4] == f"{cpa_value:.4f}"  # refine/points.json holds the CPA values
        # uncertainty: refined MC mean, u, interval, CPA MC mean, u, interval
        angle = kind in ("theta", "beta")
        assert uncertainty[1] == f"{U_REFINED_ANGLE_DEG if angle else U_REFINED_LENGTH_MM:.3g}"
        assert uncertainty[4] == f"{U_ANGLE_DEG if angle else U_LENGTH_MM:.3g}"
        low, high = (float(v) for v in uncertainty[5].split(" … "))
        assert high - low == pytest.approx(4 * (U_ANGLE_DEG if angle else U_LENGTH_MM), abs=2e-4)
    section = _section(page, "parameters")
    # the structurally fixed parameters (beta of DH joints, d of the Hayati J2) have no row
    assert '<td class="rc-text">J1.beta' not in section and '<td class="rc-text">J2.d<' not in section
    # J6.d cannot be identified by CPA: shown, marked
    assert "J6.d <small>(not identified)</small>" in section
    assert "<th>nominal (mm)</th>" in section and "<th>CPA (deg)</th>" in section
    assert "<th>refined u (mm)</th>" in section and "<th>CPA 95 % interval (deg)</th>" in section


def test_refine_provenance_facts_carry_their_units(run_folder):
    section = _section(_render(run_folder), "parameters")
    facts = dict(
        (entry, unit)
        for entry, _, unit in re.findall(
            r'<tr><td class="rc-text">([^<]*)</td><td class="rc-text">([^<]*)</td><td class="rc-text">([^<]*)</td>',
            section,
        )
    )
    assert facts["standard uncertainty › J1.a"] == "mm"
    assert facts["standard uncertainty › J1.alpha"] == "deg"
    assert facts["residual rms"] == "mm"
    assert facts["points"] == "—" and facts["method"] == ""


def test_the_rms_figures_are_named(run_folder):
    section = _section(_render(run_folder), "parameters")
    criterion = _rows(section, "criterion RMS (convergence figure)")[0]
    assert criterion[0] == _length(CRITERION_RMS_MM) and "per coordinate" in criterion[1]
    points = _rows(section, "RMS point distance |T p − m|")[0]
    assert points[0] == _length(POINT_RMS_MM) and "√3" in points[1]
    validation = _rows(section, "validation RMS error")[0]
    assert validation[0] == _length(0.05 * 1.1)  # evaluation.csv: rms = 1.1 mean of the points set
    assert "convergence" in _CAPTIONS["convergence.png"].lower() and "per coordinate" in _CAPTIONS["convergence.png"]


def test_statistics_tables_choose_their_columns(run_folder):
    page = _render(run_folder)
    montecarlo = _section(page, "montecarlo")
    assert "<th>u (mm)</th>" in montecarlo and "<th>u (deg)</th>" in montecarlo
    assert "<th>min (mm)</th>" not in montecarlo  # left to the file
    assert "<th>mean error (mm)</th>" in page and "<th>improvement (%)</th>" in page  # evaluation.csv
    tcp = _section(page, "tcp")
    # the pose number is an identifier: no unit in its header (issue 13: "pose (mm)")
    assert "<th>pose (mm)" not in page and "<th>pose</th>" in tcp
    assert "<th>X" not in tcp and "<th>u (mm)</th>" in tcp and "<th>u (deg)</th>" in tcp


def test_wide_csv_is_split_into_tables_of_few_columns(run_folder):
    result = load_run(run_folder)
    header = ("pose", "name", *(f"c{k}_mm" for k in range(12)))
    documents = dict(result.documents)
    documents["plan/wide.csv"] = Table(header=header, rows=(("1", "X", *(str(k) for k in range(12))),))
    page = render_report(RunResult(record=result.record, documents=documents)).html
    tables = [t for t in re.findall(r"<table>.*?</table>", _section(page, "planning")) if "plan/wide.csv" in t]
    assert len(tables) == 2
    for table in tables:
        headers = re.findall(r"<th(?: [^>]*)?>(.*?)</th>", table)
        assert len(headers) <= 8 and headers[:2] == ["pose", "name"]  # the key columns repeat


def test_noise_floor_in_the_joints_table(run_folder):
    """The floor of joints/summary.csv (per joint), beside the mean backlash and their ratio."""
    result = load_run(run_folder)
    section = _section(render_report(result).html, "joints")
    assert "<th>noise floor (µm)</th>" in section and "the instrument noise alone gives" in section
    for joint, backlash in enumerate(BACKLASH_MM, start=1):
        cells = re.search(rf"<tr><td>{joint}</td><td>14</td><td>([^<]*)</td>(.*?)</tr>", section)
        assert cells, joint
        assert float(cells.group(1)) == pytest.approx(backlash * 1e3)  # shown in µm
        floor, ratio = re.findall(r"<td[^>]*>(.*?)</td>", cells.group(2))[-2:]
        assert float(floor) == NOISE_FLOOR_UM
        assert float(ratio) == pytest.approx(backlash * 1e3 / NOISE_FLOOR_UM, abs=0.005)


def test_no_noise_floor_is_said(run_folder):
    """A run written before the noise floor existed: the table says there is none."""
    result = load_run(run_folder)
    documents = dict(result.documents)
    summary = documents["joints/summary.csv"]
    keep = [k for k, name in enumerate(summary.header) if name != "noise_floor_um"]
    documents["joints/summary.csv"] = Table(
        header=tuple(summary.header[k] for k in keep), rows=tuple(tuple(row[k] for k in keep) for row in summary.rows)
    )
    section = _section(render_report(RunResult(record=result.record, documents=documents)).html, "joints")
    assert "noise floor (µm)" not in section and "No noise floor in the tables of this run" in section


def test_captions_name_the_unit_of_their_figure():
    """The joints figures plot µm (plots/joints.py), the TCP and convergence figures mm."""
    for name in ("backlash_xyz.png", "backlash_magnitude.png", "eccentricity_axial.png", "eccentricity_radial.png"):
        assert "(µm)" in _CAPTIONS[name] and "(mm)" not in _CAPTIONS[name], name
    for name in ("convergence.png", "scatter.png", "workspace.png", "ellipsoid.png", "backlash_vectors.png"):
        assert "(mm" in _CAPTIONS[name] and "µm" not in _CAPTIONS[name], name
    assert "(deg)" in _CAPTIONS["histograms.png"] and "(mm)" in _CAPTIONS["histograms.png"]


def test_long_csv_shows_its_first_rows(run_folder):
    page = _render(run_folder)
    # tcp/trajectory/tcp.csv: 60 poses x 3 length rows; the mm table shows 40 of 180
    assert "First 40 of 180 rows" in page


def test_number_formatting():
    assert _fmt(-0.00001, ".4f", exponent=False) == "0.0000"  # no negative zero
    assert _fmt(-0.00001) == "-1.000e-05"
    assert _fmt(None) == "n/a" and _fmt(3) == "3" and _fmt(True) == "yes"
    assert (_length(0.0123), _length(1.234), _length(None)) == ("12.3 µm", "1.23 mm", "n/a")
    assert _label("plane_rms_mm") == "plane rms (mm)" and _label("b_um_per_m") == "b (µm/m)"
    assert _label("improvement_pct") == "improvement (%)" and _label("points") == "points"


def test_page_text_is_escaped(run_folder):
    result = load_run(run_folder)
    record = {**result.record, "robot": "<b>robot</b>", "notes": ["<script>alert(1)</script>"]}
    page = render_report(RunResult(record=record, documents=result.documents)).html
    assert "<b>robot</b>" not in page and "&lt;b&gt;robot&lt;/b&gt;" in page
    assert "<script>alert(1)</script>" not in page
    assert "<li>&lt;script&gt;alert(1)&lt;/script&gt;</li>" in _section(page, "summary")  # the run's notes


def test_rebuild_gives_the_same_page(run_folder):
    first = build_report(run_folder).html
    second = build_report(run_folder).html

    def strip(text):
        return re.sub(r"Report generated [^<]* by", "", text)

    assert strip(first) == strip(second)


def test_in_memory_run_without_a_folder_or_figures(run_folder):
    """render_report reads no file but figures: a run whose folder is gone, figures left out, renders whole."""
    result = load_run(run_folder)
    documents = {name: doc for name, doc in result.documents.items() if not isinstance(doc, Path)}
    shutil.rmtree(run_folder)
    report = render_report(RunResult(record=result.record, documents=documents))
    assert [s.id for s in report.sections if s.present] == SECTION_IDS
    assert (report.figures, report.canvases, report.problems) == (0, 1, ())
    assert "from a run held in memory" in report.html and "900 µm → 50 µm" in report.html


def test_render_opens_no_file_but_the_figures(run_folder, monkeypatch):
    """Every file opened while rendering a run read from its folder is one of its figure documents (the
    package's templates and assets are loaded once, by a first render)."""
    result = load_run(run_folder)
    render_report(result)
    opened = []
    real_open, real_read_bytes = io.open, Path.read_bytes

    def recording_open(file, *args, **kwargs):
        opened.append(str(file))
        return real_open(file, *args, **kwargs)

    def recording_read_bytes(self):
        opened.append(str(self))
        return real_read_bytes(self)

    monkeypatch.setattr("builtins.open", recording_open)
    monkeypatch.setattr(io, "open", recording_open)
    monkeypatch.setattr(Path, "read_bytes", recording_read_bytes)
    report = render_report(result)
    figures = sorted(str(doc) for doc in result.documents.values() if isinstance(doc, Path) and doc.suffix == ".png")
    assert report.figures == len(figures) == 5
    assert sorted(set(opened)) == figures


def test_hand_made_run():
    """A RunResult built by hand: a cpa result and a workspace map only."""
    documents = {
        "cpa/parameters.json": {
            "robot": "hand-made",
            "joints": [{"d": 100.0, "theta": 0.0, "a": 10.0, "alpha": 90.0, "hayati": False}],
            "identified": ["J1.d", "J1.a"],
        },
        "tcp/workspace/tcp.json": {"poses": [{"position_uncertainty_mm": 0.002}, {"position_uncertainty_mm": 0.004}]},
    }
    report = render_report(RunResult(documents=documents))
    present = {s.id for s in report.sections if s.present}
    assert present == {"summary", "parameters", "workspace", "provenance"}
    assert "Calibration report: hand-made" in report.html
    assert "3 µm / 3.9 µm" in report.html  # median 3 um; 95th percentile 2 + 0.95 * 2 = 3.9 um
    assert _rows(report.html, "J1.a")[0][0] == "10.0000" and "J1.theta <small>(not identified)</small>" in report.html


def test_missing_figure_file_is_a_problem_not_an_error(run_folder):
    result = load_run(run_folder)
    documents = {**result.documents, "joints/gone.png": run_folder / "joints" / "gone.png"}
    report = render_report(RunResult(record=result.record, documents=documents))
    assert any(p.startswith("joints/gone.png: could not read the figure") for p in report.problems)
    assert report.figures == 5


def test_missing_stages_give_notes_not_errors(run_folder):
    for name in ("evaluation", "joints", "uncertainty", "uncertainty-refined", "tcp", "refine", "plan", "iso9283"):
        shutil.rmtree(run_folder / name)
    for name in ("run.json", "truth.json", "validation.csv"):
        (run_folder / name).unlink()
    report = render_report(load_run(run_folder))
    present = {s.id: s.present for s in report.sections}
    assert present == {
        "summary": True,
        "parameters": True,
        "model": False,
        "evaluation": False,
        "joints": False,
        "montecarlo": False,
        "tcp": False,
        "workspace": False,
        "iso9283": False,
        "planning": False,
        "view3d": True,
        "provenance": True,
    }
    for folder in ("evaluation/", "joints/", "uncertainty/", "tcp/pose/", "tcp/trajectory/", "tcp/workspace/"):
        assert f"Stage not run: this run has no <code>{folder}</code>" in report.html
    assert report.figures == 0 and report.problems == ()
    assert "uncertainty stage not run" in report.html  # summary card says why it shows n/a


def test_folder_with_only_a_capture(run_folder, tmp_path):
    only = tmp_path / "only"
    only.mkdir()
    shutil.copy(run_folder / "capture.csv", only / "capture.csv")
    report = render_report(load_run(only))
    assert report.canvases == 1
    assert "No identified parameters to show" in report.html


def test_unreadable_files_are_reported_in_the_page(run_folder):
    (run_folder / "uncertainty" / "parameters.json").write_text("{not json")
    (run_folder / "joints" / "broken.png").write_text("not a png")
    with (run_folder / "joints" / "summary.csv").open("a") as stream:
        stream.write("7,0.1\n")
    report = build_report(run_folder)
    assert any(p.startswith("uncertainty/parameters.json: not a readable JSON file") for p in report.problems)
    assert "joints/broken.png: not a PNG file" in report.problems
    assert any(p.startswith("joints/summary.csv: row 8 has") for p in report.problems)
    assert "Some result files could not be read" in report.html
    assert "joints/broken.png: not a PNG file" in report.html
    assert report.figures == 5  # the broken PNG is not embedded


def test_invalid_run_folders(tmp_path):
    with pytest.raises(InputError, match="run folder not found"):
        build_report(tmp_path / "nope")
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        build_report(tmp_path / "file.txt")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no results found"):
        build_report(tmp_path / "empty")
    assert not (tmp_path / "empty" / REPORT_NAME).exists()


def test_out_elsewhere(run_folder, tmp_path):
    report = build_report(run_folder, tmp_path / "sub" / "r.html")
    assert report.path.read_text(encoding="utf-8") == report.html
    assert not (run_folder / REPORT_NAME).exists()


def test_angle_differences_are_within_a_half_turn():
    """"CPA − truth" of an angle near ±180 deg: two values a turn apart differ by their error, not 360 deg."""
    from robotcal.report.page import _difference

    assert _difference("J5.theta", 179.74, -179.92) == pytest.approx(-0.34, abs=1e-9)
    assert _difference("J5.theta", 179.74, 180.08) == pytest.approx(-0.34, abs=1e-9)
    assert _difference("J2.alpha", -0.5, 0.25) == pytest.approx(-0.75, abs=1e-12)
    assert _difference("J1.a", 400.0, 10.0) == 390.0  # lengths are not angles


def _sensitivity_tables(page: str) -> list[list[str]]:
    """The headers of the tables of plan/sensitivity/sensitivity.csv in the planning section."""
    tables = re.findall(r"<table>.*?</table>", _section(page, "planning"))
    return [re.findall(r"<th(?: [^>]*)?>(.*?)</th>", t) for t in tables if "plan/sensitivity/sensitivity.csv" in t]


def test_sensitivity_table_heads_each_column_with_its_own_unit(run_folder):
    """Issue 24: the statistics take the rows' unit; the varied sweep is in degrees whatever the rows' unit, Cpk
    is a pure number, the draws a count; the key ``capture.sweep_deg.4`` reads as the setting it is."""
    headers = _sensitivity_tables(_render(run_folder))
    assert headers == [
        ["case", "J4 sweep (deg)", "name", f"nominal ({unit})", f"mean ({unit})", f"u ({unit})", "Cpk", "draws"]
        for unit in ("mm", "deg")
    ]


def test_labels_of_varied_settings():
    assert _label("capture.sweep_deg.4") == "J4 sweep (deg)"
    assert _label("capture.start_deg.2") == "J2 start (deg)"
    assert _label("capture.points") == "capture points" and _label("montecarlo.iterations") == "montecarlo iterations"
    assert _label("instrument.a_um") == "instrument a (µm)"


def _tcp_card(page: str) -> str:
    """The text of the summary card of the TCP position uncertainty at the pose."""
    summary = _section(page, "summary")
    start = summary.index("TCP position uncertainty at the pose")
    end = summary.find('<div class="rc-card', start)
    return html.unescape(re.sub(r"<[^>]+>", " ", summary[start : end if end > 0 else None]))


def _with_tcp_pose(folder, readings_deg, warned_deg=None):
    """The run of ``folder`` with its TCP pose at ``readings_deg`` (the Table 5.8 pose's provenance) and the
    TCP stage's joint-limit warning of readings ``warned_deg`` (default: the pose's own), as robotcal writes
    them (``uncertainty.tcp.check_readings``'s message in run.json)."""
    import json
    import warnings

    from robotcal.errors import JointLimitWarning
    from robotcal.io import load_robot
    from robotcal.uncertainty.tcp import check_readings

    result = load_run(folder)
    documents = dict(result.documents)
    pose = json.loads(json.dumps(documents["tcp/pose/tcp.json"]))
    pose["poses"][0]["readings_deg"] = list(readings_deg)
    shown = ", ".join(f"{v:g}" for v in readings_deg)
    pose["provenance"]["pose"] = f"thesis Table 5.8 pose, KUKA readings ... = readings {shown} deg of kuka-kr5-sixx-r650"
    documents["tcp/pose/tcp.json"] = pose
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", JointLimitWarning)
        check_readings(load_robot("kuka-kr5-sixx-r650"), np.deg2rad([warned_deg or readings_deg]), name="tcp.pose_deg")
    stages = {**result.record.get("stages", {}), "tcp": {"status": "done", "warnings": [str(w.message) for w in caught]}}
    return RunResult(record={**result.record, "stages": stages}, documents=documents)


def test_the_tcp_headline_says_when_its_pose_is_outside_the_joint_limits(run_folder):
    """Issue 24: the thesis's Table 5.8 pose (model readings -60, -80, 45, -200, 125, -280 deg of the KR 5) lies
    outside the limits of J2, J4 and J5; the headline card says so."""
    card = " ".join(_tcp_card(render_report(_with_tcp_pose(run_folder, [-60, -80, 45, -200, 125, -280])).html).split())
    assert "at the thesis's Table 5.8 pose, outside the joint limits of J2, J4, J5" in card
    assert "readings -60, -80, 45, -200, 125, -280 deg" in card
    # a pose within the limits: no such words
    inside = " ".join(_tcp_card(render_report(_with_tcp_pose(run_folder, [-60, -30, 45, -100, 60, -80])).html).split())
    assert "outside" not in inside and "Table 5.8 pose" in inside
    # a warning about another pose 1 (the trajectory's) does not put this pose outside the limits
    other = _with_tcp_pose(run_folder, [-60, -30, 45, -100, 60, -80], warned_deg=[-60, -80, 45, -200, 125, -280])
    assert "outside" not in _tcp_card(render_report(other).html)
