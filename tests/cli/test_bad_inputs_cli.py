"""Issue 12 catalogue of bad inputs, CLI side: each case exits 2 with a one-line message naming the culprit,
before any work, and leaves every pre-existing file byte-identical (and creates nothing new).

One case per class of the issue that the CLI owns: data loss through ``--out`` (user folders, inputs of
the same command, ``/``, ``.``, ``..``, the home folder, a measured capture in a run folder), Rich
markup in user text, limits (seeds; memory of a Monte Carlo, workspace, validation set and distances
problem; ``[tcp]`` settings of a run) and unusable output locations.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

import robotcal.cli._common as common
from robotcal.cli import app
from robotcal.io import load_scenario

runner = CliRunner()
SCENARIO = "thesis-noise-free"


def _capture_text(rows: int = 40, cell: str | None = None) -> str:
    """A small capture CSV in robotcal's layout (6 joints); ``cell`` replaces the first x value."""
    lines = ["circle,direction,q1,q2,q3,q4,q5,q6,x,y,z"]
    for k in range(rows):
        circle = 1 + k * 6 // rows
        x = cell if (cell is not None and k == 0) else f"{100.0 + k:.12f}"
        lines.append(f"{circle},1," + ",".join(f"{k * 0.5:.12f}" for _ in range(6)) + f",{x},{2.0:.12f},{3.0:.12f}")
    return "\n".join(lines) + "\n"


def _scenario(tmp: Path, extra: str = "", replace: tuple[str, str] | None = None) -> Path:
    text = Path(load_scenario("kr5-demo").source).read_text(encoding="utf-8")
    if replace is not None:
        assert replace[0] in text
        text = text.replace(*replace)
    path = tmp / "s.toml"
    path.write_text(text + extra, encoding="utf-8")
    return path


# each case: (tmp_path) -> (argv, culprit the message must name)
def user_folder(tmp):
    (tmp / "mc").mkdir()
    (tmp / "mc" / "notes.txt").write_text("my notes")
    return ["uncertainty", SCENARIO, "-n", "50", "--out", tmp / "mc"], "not written by robotcal"


def folder_holds_input(tmp):
    (tmp / "data").mkdir()
    (tmp / "data" / "c.csv").write_text(_capture_text())
    argv = ["joints", tmp / "data" / "c.csv", "--scenario", SCENARIO, "--out", tmp / "data", "--force"]
    return argv, "holds an input"


def scenario_in_out(tmp):
    (tmp / "cfg").mkdir()
    path = _scenario(tmp / "cfg")
    return ["uncertainty", path, "-n", "50", "--out", tmp / "cfg", "--force"], "holds an input"


def tcp_reads_out(tmp):
    (tmp / "mc").mkdir()
    (tmp / "mc" / "draws.npz").write_bytes(b"PK\x03\x04 not really")
    return ["tcp", "--run", tmp / "mc", "--pose", "0,0,0,0,0,0", "--out", tmp / "mc", "--force"], "holds an input"


def identify_over_capture(tmp):
    (tmp / "c.csv").write_text(_capture_text())
    return ["identify", tmp / "c.csv", "--scenario", SCENARIO, "--out", tmp / "c.csv", "--force"], "input"


def report_over_run_json(tmp):
    (tmp / "run").mkdir()
    (tmp / "run" / "run.json").write_text('{"status": "done"}')
    return ["report", tmp / "run", "--out", tmp / "run" / "run.json", "--force"], "run.json"


def report_of_missing_folder(tmp):
    # the lock beside DIR/report.html makes DIR; it must not be left behind when the report fails
    return ["report", tmp / "nope"], "nope"


def truth_out_is_out(tmp):
    return ["simulate", SCENARIO, "--truth-out", tmp / "x.csv", "--out", tmp / "x.csv"], "x.csv"


def simulate_over_user_file(tmp):
    (tmp / "measured.csv").write_text("circle,direction,q1\n1,1,0.5\n")
    return ["simulate", SCENARIO, "--out", tmp / "measured.csv"], "--force"


def run_over_measured_capture(tmp):
    (tmp / "r").mkdir()
    (tmp / "r" / "capture.csv").write_text(_capture_text())
    return ["run", "kr5-demo", "--draws", "50", "--out", tmp / "r"], "not written by robotcal"


def out_is_home(tmp):
    return ["uncertainty", SCENARIO, "-n", "50", "--out", "~", "--force"], "home folder"


def out_is_root(tmp):
    return ["evaluate", "--scenario", SCENARIO, "--params", tmp / "p.json", "--capture", tmp / "c.csv", "--out", "/"], (
        "root"
    )


def out_is_dot(tmp):
    return ["uncertainty", SCENARIO, "-n", "50", "--out", ".", "--force"], "current folder"


def out_is_dotdot(tmp):
    return ["run", "kr5-demo", "--draws", "50", "--out", "..", "--force"], "refusing to write over"


def out_under_a_file(tmp):
    (tmp / "afile").write_text("x")
    return ["run", "kr5-demo", "--draws", "50", "--out", tmp / "afile" / "r"], "is a file"


def markup_in_path(tmp):
    return ["identify", tmp / "nope[/red].csv", "--scenario", SCENARIO, "--out", tmp / "p.json"], "nope[/red].csv"


def markup_bold_path(tmp):
    return ["identify", tmp / "a[bold]b[/bold].csv", "--scenario", SCENARIO, "--out", tmp / "p.json"], (
        "a[bold]b[/bold].csv"
    )


def markup_in_cell(tmp):
    (tmp / "c.csv").write_text(_capture_text(cell="[/b]"))
    # the output's missing parent folders are not left behind either
    return ["identify", tmp / "c.csv", "--scenario", SCENARIO, "--out", tmp / "new" / "sub" / "p.json"], "[/b]"


def seed_too_large(tmp):
    return ["uncertainty", SCENARIO, "-n", "50", "--seed", str(2**63), "--out", tmp / "mc"], "--seed"


def run_seed_too_large(tmp):
    return ["run", "kr5-demo", "--seed", str(2**63 - 2), "--out", tmp / "r"], "--seed"


def iterations_too_many(tmp):
    return ["uncertainty", SCENARIO, "-n", str(10**9), "--out", tmp / "mc"], "--iterations"


def max_draws_too_many(tmp):
    return ["uncertainty", SCENARIO, "--adaptive", "--max-draws", str(10**12), "--out", tmp / "mc"], "--max-draws"


def workspace_too_many(tmp):
    (tmp / "d.npz").write_bytes(b"not read: the limit is checked first")
    return ["tcp", "--draws", tmp / "d.npz", "--workspace", str(10**8), "--out", tmp / "ws"], "--workspace"


def run_workspace_too_many(tmp):
    return ["run", "kr5-demo", "--draws", "50", "--workspace", str(10**8), "--out", tmp / "r"], "--workspace"


def validation_poses_too_many(tmp):
    path = _scenario(tmp, replace=("poses = 100\n", "poses = 100000000\n"))
    return ["run", path, "--draws", "50", "--out", tmp / "r"], "validation.poses"


def simulate_poses_too_many(tmp):
    path = _scenario(tmp, replace=("poses = 100\n", "poses = 100000000\n"))
    return ["simulate", path, "--validation", "--out", tmp / "v.csv"], "100,000,000 poses"


def distances_too_many_points(tmp):
    (tmp / "c.csv").write_text(_capture_text(rows=12_000))
    argv = ["refine", tmp / "c.csv", "--scenario", SCENARIO, "--criterion", "distances", "--out", tmp / "p.json"]
    return argv, "12000 points"


def run_tool_nan(tmp):
    path = _scenario(tmp, extra="\n[tcp]\ntool_mm = [nan, 0.0, 0.0]\n")
    return ["run", path, "--draws", "50", "--out", tmp / "r"], "tool_mm"


def run_workspace_draws_two(tmp):
    path = _scenario(tmp, extra="\n[tcp]\nworkspace_draws = 2\n")
    return ["run", path, "--draws", "50", "--out", tmp / "r"], "workspace_draws"


CASES = [
    user_folder,
    folder_holds_input,
    scenario_in_out,
    tcp_reads_out,
    identify_over_capture,
    report_over_run_json,
    report_of_missing_folder,
    truth_out_is_out,
    simulate_over_user_file,
    run_over_measured_capture,
    out_is_home,
    out_is_root,
    out_is_dot,
    out_is_dotdot,
    out_under_a_file,
    markup_in_path,
    markup_bold_path,
    markup_in_cell,
    seed_too_large,
    run_seed_too_large,
    iterations_too_many,
    max_draws_too_many,
    workspace_too_many,
    run_workspace_too_many,
    validation_poses_too_many,
    simulate_poses_too_many,
    distances_too_many_points,
    run_tool_nan,
    run_workspace_draws_two,
]


def _snapshot(root: Path) -> dict[str, bytes | None]:
    return {
        str(path.relative_to(root)): (path.read_bytes() if path.is_file() else None) for path in sorted(root.rglob("*"))
    }


@pytest.mark.parametrize("case", CASES, ids=[case.__name__ for case in CASES])
def test_bad_input_is_refused_cleanly_and_touches_nothing(case, tmp_path, tmp_path_factory, monkeypatch):
    home = tmp_path / "home"
    work = home / "work"
    work.mkdir(parents=True)
    monkeypatch.setenv("HOME", str(home))
    # matplotlib's font cache is matplotlib's, not robotcal's: where this test is the first to import matplotlib,
    # it would land in the test's HOME (~/.cache/matplotlib) and in the snapshot
    monkeypatch.setenv("MPLCONFIGDIR", str(tmp_path_factory.mktemp("matplotlib")))
    monkeypatch.chdir(work)
    # a fixed memory budget, so that the limits do not depend on the machine running the tests
    monkeypatch.setattr(common, "available_memory", lambda: 8 * 2**30)
    argv, culprit = case(work)
    before = _snapshot(tmp_path)
    result = runner.invoke(app, [str(a) for a in argv])
    assert result.exit_code == 2, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert "Traceback" not in result.output
    output = result.output
    assert culprit in output, output
    if "Usage:" not in output:  # errors of robotcal (not the argument parser) are one line
        lines = [line for line in output.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith("error: "), output
    assert _snapshot(tmp_path) == before  # every file byte-identical, nothing created or left behind


def test_home_case_really_names_the_home_folder(tmp_path, monkeypatch):
    # the "~" of the home case must resolve to the HOME set by the test, not to the tester's home
    monkeypatch.setenv("HOME", str(tmp_path))
    assert Path("~").expanduser() == tmp_path
    assert os.path.expanduser("~") == str(tmp_path)
