"""Tracker exports as Windows tools write them (issue 29, item 6): cp1252 text with "[µm]" and "[°C]" headers is
refused as not UTF-8 with the byte, the line and the option to give, and read with ``encoding="cp1252"``; a length in
µm is converted exactly."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.errors import InputError
from robotcal.io.formats.tracker_import import read_tracker_export

EXPORT = "Name;X [µm];Y [µm];Z [µm];T [°C]\nP1;1000;2000;3000;20.5\nP2;1100;2000;3000;20.5\nP3;1250,5;2000;3000;20.5\n"


def test_a_cp1252_export_is_named_and_read_with_its_encoding(tmp_path):
    path = tmp_path / "leica.csv"
    path.write_bytes(EXPORT.encode("cp1252"))
    with pytest.raises(InputError, match=r"leica.csv: not a UTF-8 text file \(byte 8 is 0xb5\).*line 1.*'µ' in cp1252"):
        read_tracker_export(path)
    points = read_tracker_export(path, encoding="cp1252")
    assert points.unit == "um"
    assert points.points.tolist() == [[1.0, 2.0, 3.0], [1.1, 2.0, 3.0], [1.2505, 2.0, 3.0]]
    with pytest.raises(InputError, match="unknown text encoding 'klingon'"):
        read_tracker_export(path, encoding="klingon")


def test_import_names_the_option(tmp_path):
    (tmp_path / "leica.csv").write_bytes(EXPORT.encode("cp1252"))
    (tmp_path / "log.csv").write_text("name,q1,q2,q3,q4,q5,q6\nP1,0,0,0,0,0,0\nP2,1,0,0,0,0,0\nP3,2,0,0,0,0,0\n")
    args = ["import", str(tmp_path / "leica.csv"), "--joints", str(tmp_path / "log.csv"), "-o", str(tmp_path / "c.csv")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and "--encoding cp1252" in result.output and not (tmp_path / "c.csv").exists()
    result = CliRunner().invoke(app, [*args, "--encoding", "cp1252"])
    assert result.exit_code == 0, result.output
    assert "1.250500000000,2.000000000000,3.000000000000" in (tmp_path / "c.csv").read_text()
