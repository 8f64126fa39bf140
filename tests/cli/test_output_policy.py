"""The output-safety policy (robotcal.io.results.output) and literal user text: what may be replaced, what never,
how robotcal recognises its own files, the lock, and brackets printed as typed."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import typer
from rich.table import Table
from typer.testing import CliRunner

from robotcal.api import simulate
from robotcal.cli import app
from robotcal.cli._common import SEED_BOUND, console, error_console, handle_errors
from robotcal.errors import InputError
from robotcal.io import load_scenario, write_capture, write_parameters
from robotcal.io.formats.capture_csv import capture_to_csv
from robotcal.io.results.output import (
    MARKER,
    check_output_file,
    check_output_folder,
    is_robotcal_file,
    is_robotcal_folder,
    output_lock,
    result_folder,
    write_marker,
)
from robotcal.kinematics.model import ParameterSet

runner = CliRunner()


def test_a_user_file_added_to_a_robotcal_folder_is_never_replaced_without_force(tmp_path):
    # review finding: a marked folder used to be replaced whole, whatever else the user had put in it
    out = tmp_path / "res"
    with result_folder(out, command="test") as folder:
        (folder / "a.txt").write_text("1")
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match=r"files robotcal did not write \(notes.txt\)"):
        check_output_folder(out)
    result = runner.invoke(app, ["uncertainty", "thesis-laser-tracker", "-n", "200", "--out", str(out)])
    assert result.exit_code == 2 and (out / "notes.txt").read_text() == "mine"
    check_output_folder(out, force=True)  # consent
    check_output_folder(out, keeps_other_files=True)  # run replaces only its own entries


def test_a_robot_file_named_by_the_scenario_is_an_input(tmp_path):
    # review finding: a result folder holding the scenario's robot TOML was replaced whole
    from robotcal.io.schema.builtins import data_path

    res = tmp_path / "res"
    res.mkdir()
    (res / "myrobot.toml").write_text(data_path("robots", "kuka-kr5-sixx-r650.toml").read_text())
    write_marker(res, command="test")
    scenario = data_path("scenarios", "thesis-laser-tracker.toml").read_text()
    scenario = scenario.replace('robot = "kuka-kr5-sixx-r650"', 'robot = "res/myrobot.toml"')
    (tmp_path / "scen.toml").write_text(scenario)
    assert load_scenario(str(tmp_path / "scen.toml")).files[-1] == str(res / "myrobot.toml")
    result = runner.invoke(app, ["uncertainty", str(tmp_path / "scen.toml"), "-n", "200", "--force", "--out", str(res)])
    assert result.exit_code == 2 and "holds an input" in result.output
    assert (res / "myrobot.toml").is_file()


def test_a_run_folder_marker_lists_only_the_runs_entries(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    write_marker(out, command="robotcal run", files=["run.json", "capture.csv"])  # as `run` marks its folder
    with pytest.raises(InputError, match="notes.txt"):
        check_output_folder(out)


def test_a_robotcal_folder_is_replaced_atomically_and_a_user_folder_only_with_force(tmp_path):
    out = tmp_path / "res"
    with result_folder(out, command="test") as folder:
        (folder / "a.txt").write_text("1")
    assert is_robotcal_folder(out) and (out / "a.txt").read_text() == "1"
    with result_folder(out, command="test") as folder:  # its own folder: replaced, old content gone
        (folder / "b.txt").write_text("2")
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "b.txt"]
    user = tmp_path / "user"
    user.mkdir()
    (user / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="not written by robotcal"):
        check_output_folder(user)
    assert check_output_folder(user, force=True) == user.resolve()
    empty = tmp_path / "empty"
    empty.mkdir()
    assert check_output_folder(empty) == empty.resolve()  # an empty folder is fine


def test_an_interrupted_block_leaves_the_old_folder_and_no_temporary(tmp_path):
    out = tmp_path / "res"
    with result_folder(out, command="test") as folder:
        (folder / "a.txt").write_text("old")
    with pytest.raises(KeyboardInterrupt), result_folder(out, command="test") as folder:
        (folder / "a.txt").write_text("half")
        raise KeyboardInterrupt
    assert (out / "a.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]  # no .partial, no lock


def test_inputs_are_never_replaced_even_with_force(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    capture = data / "c.csv"
    capture.write_text("x")
    link = tmp_path / "link.csv"
    link.symlink_to(capture)
    with pytest.raises(InputError, match="holds an input"):
        check_output_folder(data, inputs=[capture], force=True)
    with pytest.raises(InputError, match="holds an input"):
        check_output_folder(tmp_path, inputs=[capture], force=True)  # a parent of an input
    with pytest.raises(InputError, match="overwrite an input"):
        check_output_file(capture, inputs=[capture], force=True)
    with pytest.raises(InputError, match="overwrite an input"):
        check_output_file(link, inputs=[capture], force=True)  # the same file through a link
    assert check_output_file(tmp_path / "other.json", inputs=[capture]) == (tmp_path / "other.json").resolve()


@pytest.mark.parametrize("where", ["/", "~", ".", ".."])
def test_forbidden_locations_even_with_force(where, tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    with pytest.raises(InputError, match="refusing to write over"):
        check_output_folder(where, force=True)


def test_robotcal_files_are_recognised_and_others_are_not(tmp_path):
    scenario = load_scenario("thesis-noise-free")
    capture = simulate(scenario, rng=1)
    write_capture(tmp_path / "c.csv", capture)
    write_parameters(tmp_path / "p.json", ParameterSet.nominal(scenario.robot), {"method": "test"})
    (tmp_path / "report.html").write_text('<html><head><meta name="generator" content="robotcal 1.0"></head>')
    assert is_robotcal_file(tmp_path / "c.csv") and is_robotcal_file(tmp_path / "p.json")
    assert is_robotcal_file(tmp_path / "report.html")
    # a measured capture (tracker export: other decimals), a user JSON, a user page, bytes
    text = (tmp_path / "c.csv").read_text().splitlines()
    measured = [text[0]] + [
        ",".join(cell[:-6] if "." in cell else cell for cell in line.split(",")) for line in text[1:]
    ]
    (tmp_path / "m.csv").write_text("\n".join(measured) + "\n")
    (tmp_path / "u.json").write_text(json.dumps({"joints": [], "robot": "x"}))
    (tmp_path / "u.html").write_text("<html>mine</html>")
    (tmp_path / "b.json").write_bytes(bytes(range(256)))
    for name in ("m.csv", "u.json", "u.html", "b.json"):
        assert not is_robotcal_file(tmp_path / name), name
        with pytest.raises(InputError, match="--force"):
            check_output_file(tmp_path / name)
    assert check_output_file(tmp_path / "c.csv") == (tmp_path / "c.csv").resolve()


def test_lock_refuses_a_second_writer_and_takes_over_a_stale_lock(tmp_path):
    out = tmp_path / "res"
    with output_lock(out) as lock:
        assert lock.read_text().splitlines()[0] == str(os.getpid())
        with pytest.raises(InputError, match=rf"another robotcal process \(pid {os.getpid()}\)"):
            with output_lock(out):
                pass
    assert not lock.exists()
    # a lock left by a process that is gone: a child that exited
    child = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    lock.write_text(child.stdout)
    with output_lock(out):
        assert lock.read_text().splitlines()[0] == str(os.getpid())
    assert not lock.exists()


def test_cli_refuses_while_another_process_holds_the_lock(tmp_path):
    out = tmp_path / "mc"
    with output_lock(out):
        result = runner.invoke(app, ["uncertainty", "thesis-noise-free", "-n", "50", "--out", str(out)])
    assert result.exit_code == 2
    assert "another robotcal process" in result.output and not out.exists()


def test_help_texts_keep_their_brackets():
    result = runner.invoke(app, ["simulate", "--help"])
    assert result.exit_code == 0
    assert "[validation]" in result.output and "[truth]" in result.output
    result = runner.invoke(app, ["report", "--help"])
    assert "[default: DIR/report.html]" in " ".join(result.output.split())


def test_user_text_is_printed_literally(capsys):
    @handle_errors
    def fails():
        raise InputError("robot [/x] in a[bold]b[/bold].csv, cell [/b]")

    with pytest.raises(typer.Exit) as info:
        fails()
    assert info.value.exit_code == 2
    err = capsys.readouterr().err
    assert "error: robot [/x] in a[bold]b[/bold].csv, cell [/b]" in err
    table = Table(title="robot [/x]")
    table.add_column("[bold]name")
    table.add_row("a[bold]b[/bold]")
    console.print(table)
    error_console.print("warn [/red] literal")
    captured = capsys.readouterr()
    assert "robot [/x]" in captured.out and "a[bold]b[/bold]" in captured.out and "[bold]name" in captured.out
    assert "warn [/red] literal" in captured.err


def test_seed_bound_is_numpy_compatible():
    # numpy accepts any non-negative seed; files record seeds as int64: the bound is 2^63
    assert SEED_BOUND == 2**63
    np.random.default_rng(SEED_BOUND - 1)
    assert np.int64(SEED_BOUND - 1) == SEED_BOUND - 1
    with pytest.raises(OverflowError):
        np.array([SEED_BOUND], dtype=np.int64)


def test_an_interrupt_between_the_renames_restores_the_old_folder(tmp_path, monkeypatch):
    out = tmp_path / "res"
    with result_folder(out, command="test") as folder:
        (folder / "a.txt").write_text("old")
    real_replace = os.replace
    calls = []

    def interrupted_replace(src, dst):
        calls.append((src, dst))
        # 1: the marker file, 2: the old folder aside, 3: the new folder in: Ctrl-C just before it
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", interrupted_replace)
    with pytest.raises(KeyboardInterrupt), result_folder(out, command="test") as folder:
        (folder / "a.txt").write_text("new")
    monkeypatch.setattr(os, "replace", real_replace)
    # the old folder had been moved aside (call 2) and was put back (call 4)
    assert len(calls) == 4 and calls[1][0] == out and calls[3][1] == out
    assert (out / "a.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]


def test_a_capture_with_target_and_u95_columns_is_recognised(tmp_path):
    """The optional ``target``/``u95_mm`` columns (robotcal import) keep a capture robotcal's own."""
    scenario = load_scenario("thesis-noise-free")
    text = capture_to_csv(simulate(scenario, rng=1)).splitlines()
    tagged = [text[0] + ",target,u95_mm"] + [line + ",T1,0.025" for line in text[1:]]
    (tmp_path / "t.csv").write_text("\n".join(tagged) + "\n")
    assert is_robotcal_file(tmp_path / "t.csv")
    # one measured coordinate among them (3 decimals): not robotcal's, target column or not
    cells = tagged[1].split(",")
    cells[-3] = f"{float(cells[-3]):.3f}"  # z
    (tmp_path / "m.csv").write_text("\n".join([tagged[0], ",".join(cells), *tagged[2:]]) + "\n")
    assert not is_robotcal_file(tmp_path / "m.csv")
