"""``robotcal tcp``: files written, same numbers as the library, clear errors naming the input."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io import load_robot
from robotcal.io.formats.draws_npz import read_draws, write_draws
from robotcal.io.results.tcp_results import TCP_CSV_COLUMNS
from robotcal.uncertainty.tcp import propagate_to_tcp

runner = CliRunner()
ROBOT = load_robot("kuka-kr5-sixx-r650-krc")
POSE_DEG = [10.0, -80.0, 100.0, 20.0, 50.0, -30.0]


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def draws_file(tmp_path_factory):
    rng = np.random.default_rng(11)
    free = ~ROBOT.structurally_fixed
    free[-1, :4] = False
    scale = np.where(np.isin(np.arange(5), [1, 3, 4]), 2e-4, 0.05)
    values = ROBOT.nominal + rng.standard_normal((400, 6, 5)) * scale * free
    path = tmp_path_factory.mktemp("unc") / "uncertainty" / "draws.npz"
    write_draws(path, ROBOT, values, free, seed=11)
    return path


def _rows(path):
    with path.open() as stream:
        return list(csv.DictReader(stream))


def test_pose_writes_csv_json_and_figures_with_library_numbers(tmp_path, draws_file):
    out = tmp_path / "pose"
    result = invoke("tcp", "--draws", draws_file, "--pose", ",".join(map(str, POSE_DEG)), "--out", out)
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {".robotcal", "tcp.csv", "tcp.json", "scatter.png", "histograms.png"}
    rows = _rows(out / "tcp.csv")
    assert tuple(rows[0]) == TCP_CSV_COLUMNS
    assert [r["name"] for r in rows] == ["X", "Y", "Z", "A", "B", "C"]
    loaded = read_draws(draws_file)
    library = propagate_to_tcp(loaded.robot, loaded.values, np.deg2rad(POSE_DEG))
    factor = np.array([1, 1, 1, *[180 / np.pi] * 3])
    # the CSV keeps 12 significant digits
    for column, expected in (
        ("nominal", library.nominal[0]),
        ("mean", library.summary.mean[0]),
        ("std_uncertainty", library.std_uncertainty[0]),
        ("coverage_low", library.summary.symmetric_low[0]),
        ("max", library.summary.maximum[0]),
        ("lpu_std_uncertainty", library.lpu_std_uncertainty[0]),
    ):
        np.testing.assert_allclose([float(r[column]) for r in rows], expected * factor, rtol=1e-11, atol=1e-12)
    data = json.loads((out / "tcp.json").read_text())
    assert data["draws"] == 400 and "A about Z" in data["orientation"]
    np.testing.assert_allclose(data["poses"][0]["ellipsoid"]["semi_axes_mm"], library.ellipsoid.semi_axes[0])


@pytest.mark.filterwarnings("default::robotcal.errors.JointLimitWarning")
def test_table_5_8_pose_from_a_draws_file_gives_the_published_nominal(tmp_path, draws_file):
    out = tmp_path / "t58"
    result = invoke("tcp", "--run", draws_file.parent, "--pose", "60,80,-45,200,125,280", "--out", out)
    assert result.exit_code == 0, result.output
    assert "warning:" in result.output and "J5 = 125 deg outside" in result.output
    nominal = [float(r["nominal"]) for r in _rows(out / "tcp.csv")]
    # Table 5.8 nominal X, Y, Z, then KUKA A, B, C = the published C, B, A; 1e-3 mm / deg (print rounding)
    published = [225.8555, -346.3662, 50.3832, -148.6273, -16.3098, 1.2386]
    np.testing.assert_allclose(nominal, published, rtol=0, atol=1e-3)


def test_trajectory_and_run_folder(tmp_path, draws_file):
    out = tmp_path / "traj"
    result = invoke("tcp", "--run", draws_file.parent.parent, "--trajectory", "kr5-sweep-75", "--out", out)
    assert result.exit_code == 0, result.output
    assert len(_rows(out / "tcp.csv")) == 75 * 6
    assert (out / "trajectory.png").stat().st_size > 10_000


def test_workspace_map(tmp_path, draws_file):
    out = tmp_path / "ws"
    result = invoke("tcp", "--draws", draws_file, "--workspace", 30, "--seed", 3, "--max-draws", 100, "--out", out)
    assert result.exit_code == 0, result.output
    data = json.loads((out / "tcp.json").read_text())
    assert data["draws"] == 100 and data["workspace"]["poses"] == 30 and data["workspace"]["seed"] == 3
    assert (out / "workspace.png").is_file()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--pose", "1,2,3,4,5"], "5 joint readings but robot 'kuka-kr5-sixx-r650-krc' has 6 joints"),
        (["--pose", "1,2,x,4,5,6"], "expected comma-separated numbers"),
        (["--pose", "1,,2,3,4,5,6"], "an empty field"),
        (["--pose", "1,2,3,4,5,6", "--workspace", "3"], "exactly one of --pose, --trajectory and --workspace"),
        (["--pose", "1,2,3,4,5,6", "--tool", "1,2"], "--tool '1,2': expected 3 numbers"),
        (["--pose", "1,2,3,4,5,6", "--interval", "wide"], "--interval must be one of"),
    ],
)
def test_bad_options_exit_2_with_a_message(tmp_path, draws_file, extra, message):
    result = invoke("tcp", "--draws", draws_file, *extra, "--out", tmp_path / "x")
    assert result.exit_code == 2
    assert message in result.output.replace("\n", "")
    assert not (tmp_path / "x").exists()


def test_trajectory_with_nan_names_the_row(tmp_path, draws_file):
    path = tmp_path / "path.csv"
    path.write_text("pose,q1,q2,q3,q4,q5,q6\n1,0,-90,90,0,30,0\n2,0,-90,NaN,0,30,0\n")
    result = invoke("tcp", "--draws", draws_file, "--trajectory", path, "--out", tmp_path / "x")
    assert result.exit_code == 2
    assert "line 3 (pose 2), column `q3`: 'NaN' is not a finite number" in result.output.replace("\n", "")


def test_missing_draws_are_reported(tmp_path):
    result = invoke("tcp", "--run", tmp_path, "--pose", "0,0,0,0,0,0", "--out", tmp_path / "x")
    assert result.exit_code == 2
    assert "draws.npz" in result.output
