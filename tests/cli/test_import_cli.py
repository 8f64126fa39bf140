"""``robotcal import``: tracker export + joint-angle log -> capture CSV, through the CLI."""

from __future__ import annotations

import numpy as np
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io.formats.capture_csv import read_capture
from robotcal.io.formats.tracker_import import import_tracker_capture

runner = CliRunner()

LEICA_M = """Point ID;Target;X [m];Y [m];Z [m];U(95) [m];Time Stamp
P1;T1;1,2345;-0,5;0,75;0,000025;2024-05-01 10:00:00
P1;T2;1,3345;-0,5;0,75;0,00003;2024-05-01 10:00:01
P2;T1;1,25;-0,4875;0,8;0,00002;2024-05-01 10:00:05
P2;T2;1,35;-0,4875;0,8;0,00002;2024-05-01 10:00:06
"""
LOG = "name,q1,q2,q3,q4,q5,q6\nP1,10,-20,30,0,45,0\nP2,11.5,-20,30,0,45,0\n"


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_import_writes_the_capture_the_library_gives(tmp_path):
    export = tmp_path / "leica.txt"
    export.write_text(LEICA_M, encoding="utf-8")
    log = tmp_path / "joints.csv"
    log.write_text(LOG, encoding="utf-8")
    out = tmp_path / "capture.csv"
    result = invoke("import", export, "--joints", log, "--robot", "kuka-kr5-sixx-r650", "--out", out)
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())  # Rich wraps long lines
    assert "4 points at 2 poses (leica export in m, targets T1, T2, U(95) per point)" in said
    header = out.read_text().splitlines()[0]
    assert header == "circle,direction,q1,q2,q3,q4,q5,q6,x,y,z,target,u95_mm"
    capture = read_capture(out, n_joints=6)
    library = import_tracker_capture(export, log, n_joints=6)
    # the CSV holds 12 decimals of mm and deg
    np.testing.assert_allclose(capture.points, library.points, rtol=0, atol=1e-9)
    np.testing.assert_allclose(capture.readings, library.readings, rtol=0, atol=1e-13)
    np.testing.assert_allclose(capture.u95, [0.025, 0.03, 0.02, 0.02], rtol=0, atol=1e-12)
    assert capture.point_targets == ("T1", "T2", "T1", "T2")
    np.testing.assert_allclose(capture.points[0], [1234.5, -500.0, 750.0], rtol=0, atol=1e-9)
    # a second run replaces the capture (--force: io.results.output does not yet recognise a capture with the
    # optional target/u95_mm columns as robotcal's own)
    assert invoke("import", export, "--joints", log, "--out", out, "--force").exit_code == 0


def test_import_errors_are_one_line_exit_2(tmp_path):
    export = tmp_path / "leica.txt"
    export.write_text(LEICA_M, encoding="utf-8")
    log = tmp_path / "joints.csv"
    log.write_text(LOG, encoding="utf-8")
    out = tmp_path / "capture.csv"
    result = invoke("import", export, "--joints", log, "--units", "mm", "--out", out)
    assert result.exit_code == 2
    said = " ".join(result.output.split())
    assert "--units mm contradicts the header" in said and "Traceback" not in said
    result = invoke("import", export, "--joints", log, "--robot", "kuka-kr5-sixx-r650", "--out", export)
    assert result.exit_code == 2 and "refusing to overwrite an input" in " ".join(result.output.split())
    assert export.read_text(encoding="utf-8") == LEICA_M
    short = tmp_path / "short.csv"
    short.write_text("name,q1,q2,q3\nP1,1,2,3\nP2,1,2,3\n", encoding="utf-8")
    result = invoke("import", export, "--joints", short, "--robot", "kuka-kr5-sixx-r650", "--out", out)
    assert result.exit_code == 2 and "3 joint columns (q1..q3) but the robot has 6 joints" in " ".join(result.output.split())
    foreign = tmp_path / "notes.csv"
    foreign.write_text("my notes\n", encoding="utf-8")
    result = invoke("import", export, "--joints", log, "--out", foreign)
    assert result.exit_code == 2 and "not written by robotcal" in " ".join(result.output.split())
    assert invoke("import", export, "--joints", log, "--out", foreign, "--force").exit_code == 0
    assert not out.exists()


def test_import_refuses_rows_of_another_width_and_writes_nothing(tmp_path):
    # issue 24: a comma-delimited export with decimal commas was written with y = 470692512790; a
    # --columns number past the last column and a space-delimited export ended in an IndexError
    log = tmp_path / "joints.csv"
    log.write_text(LOG, encoding="utf-8")
    out = tmp_path / "capture.csv"
    decimal_commas = tmp_path / "dc.csv"
    decimal_commas.write_text(
        "Point ID,X [mm],Y [mm],Z [mm],U(95) [mm],Time Stamp,Target\n"
        "P1,1234,5,470,692512790,750,25,0,025,2024-05-01,T1\n"
        "P2,1250,0,-487,5,800,0,0,02,2024-05-01,T1\n",
        encoding="utf-8",
    )
    good = tmp_path / "good.csv"
    good.write_text("Point ID,X [mm],Y [mm],Z [mm]\nP1,1234.5,470.6,750.2\nP2,1250,-487.5,800\n", encoding="utf-8")
    for argv, message in [
        ([decimal_commas], "dc.csv: line 2 has 11 fields; expected 7, as in the header (line 1)"),
        ([good, "--columns", "x=99,y=3,z=4,name=1"], "good.csv: --columns x=99: no column 99; line 1 has 4 fields"),
    ]:
        result = invoke("import", *argv, "--joints", log, "--out", out)
        lines = [line for line in result.output.splitlines() if line.strip()]
        assert result.exit_code == 2, result.output
        assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.output
        assert not out.exists()
    spaces = tmp_path / "space.txt"
    spaces.write_text("P1 1234.5 470.6 750.2\nP2 1250 -487.5 800\n", encoding="utf-8")
    result = invoke("import", spaces, "--units", "mm", "--joints", log, "--out", out)
    assert result.exit_code == 0, result.output
    np.testing.assert_allclose(read_capture(out, n_joints=6).points, [[1234.5, 470.6, 750.2], [1250, -487.5, 800]])
