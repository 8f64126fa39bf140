"""kr5-demo's calibration poses are measured on a target named ``flange`` (issue 30), the same reflector as its
[validation] target: a free-pose simulation measures that reflector once per pose, not once per name."""

from __future__ import annotations

import csv

from typer.testing import CliRunner

from robotcal.cli import app

runner = CliRunner()


def test_free_poses_measure_each_reflector_once(tmp_path):
    poses = tmp_path / "poses.csv"
    poses.write_text("pose,q1,q2,q3,q4,q5,q6\nA,0,90,0,0,45,0\nB,20,80,10,0,40,10\n")
    out = tmp_path / "capture.csv"
    result = runner.invoke(app, ["simulate", "kr5-demo", "--poses", str(poses), "--out", str(out)])
    assert result.exit_code == 0, result.output
    rows = [row for row in csv.DictReader(line for line in out.open() if not line.startswith("#"))]
    assert len(rows) == 2 and {row["target"] for row in rows} == {"validation"}
    # a target named explicitly is still measured
    result = runner.invoke(app, ["simulate", "kr5-demo", "--poses", str(poses), "--targets", "validation,flange",
                                 "--out", str(tmp_path / "both.csv")])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "targets validation, flange" in result.output
