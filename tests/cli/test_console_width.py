"""Console output at 80 columns and piped (issue 24): no number split over two lines, no name cut with an
ellipsis, every stage name of the progress display whole; with room, the full tables.

The in-process runs set ``COLUMNS=80``; a width other than 80 is checked in a process of its own (Rich's
console, created once per process, keeps the ``COLUMNS`` it was created with)."""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io import list_robots, list_scenarios
from robotcal.io.results.run_folder import STAGES

runner = CliRunner()
NARROW = {"COLUMNS": "80"}
#: A whole number as the tables print them: 335.00265, -1.166e-02, 2,000, 58.52, 15.0..60.0
NUMBER = re.compile(r"[+-]?\d[\d,]*(\.\d+)?(e[+-]\d+)?(\.\.[+-]?\d[\d,]*(\.\d+)?)?")


def invoke(*args, env=NARROW):
    result = runner.invoke(app, [str(a) for a in args], env=env)
    assert result.exit_code == 0, result.output
    return result.output


def tables(output: str) -> list[list[list[str]]]:
    """Every box-drawn table of ``output`` as its body lines, each a list of (stripped) cells."""
    found, body = [], None
    for line in output.splitlines():
        edge = line[:1]
        if edge in "┏┌":
            body = []
            if edge == "┌":  # a table without a header: the body starts at once
                found.append(body)
        elif edge == "┡" and body is not None:
            found.append(body)
        elif edge == "└":
            body = None
        elif edge == "│" and body is not None:
            body.append([cell.strip() for cell in re.split("[│┃]", line)[1:-1]])
    return found


def assert_whole(output: str, names=(), width: int = 80, numbers: bool = True) -> None:
    """No ellipsis; no table line wider than the console; with ``numbers``, every number-like word in a table
    cell is a whole number ("2.39e-" fails; a number folded after a digit is caught by
    :func:`assert_rows_on_one_line`); every name in ``names`` is printed as one word."""
    assert "…" not in output, output
    for line in output.splitlines():
        if line[:1] in "┏┌│┃┡└┣":
            assert len(line.rstrip()) <= width, line
    for body in tables(output):
        for cells in body if numbers else ():
            for word in (w for cell in cells for w in cell.split()):
                if word[0].isdigit() or (word[0] in "+-" and word[1:2].isdigit()):
                    assert NUMBER.fullmatch(word.rstrip(",;)")), (word, cells)
    words = set(re.split(r"[\s│┃,;:()'\"]+", output))
    missing = [name for name in names if name not in words]
    assert missing == [], (missing, output)


def assert_rows_on_one_line(body: list[list[str]]) -> None:
    """A table of numbers: every row on one line (a wrapped number would leave a row with an empty first cell)."""
    assert body and all(cells[0] for cells in body), body


@pytest.fixture(scope="module")
def run_80(tmp_path_factory):
    out = tmp_path_factory.mktemp("run80") / "out"
    output = invoke("run", "kr5-demo", "--draws", 2000, "--workspace", 50, "--workers", 1, "--out", out)
    return out, output


def test_run_progress_and_stage_table_at_80_columns(run_80):
    out, output = run_80
    assert_whole(output, names=STAGES)
    lines = output.splitlines()
    for stage in STAGES:  # the progress display's line of every stage begins with its whole name
        assert any(re.match(rf"✓ {stage} +━", line) for line in lines), (stage, output)
    stages = tables(output)[0]
    assert [cells[0] for cells in stages if cells[0]] == list(STAGES)
    # the scenario's description is not cut to fit the heading's rule
    description = json.loads((out / "run.json").read_text())["scenario"]["description"]
    assert description in " ".join(output.split())


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")  # J6's frame held: by design
def test_identify_and_refine_tables_at_80_columns(run_80, tmp_path):
    out, _ = run_80
    names = []
    for command, path in (("identify", tmp_path / "cpa.json"), ("refine", tmp_path / "refined.json")):
        output = invoke(command, out / "capture.csv", "-s", "kr5-demo", "-o", path)
        document = json.loads(path.read_text())
        names = [f"J{i + 1}.{k}" for i in range(6) for k in ("d", "theta", "a", "alpha") if (i, k) != (1, "d")]
        names.append("J2.beta")  # J2 is a Hayati joint: beta instead of d
        assert_whole(output, names=names)
        parameters = tables(output)[0]
        assert_rows_on_one_line(parameters)
        shown = {cells[0]: cells for cells in parameters}
        # the identified value of J2.beta as the JSON holds it, whole in its cell
        assert float(shown["J2.beta"][3]) == pytest.approx(document["joints"][1]["beta"], abs=5e-7)
    circles = tables(invoke("identify", out / "capture.csv", "-s", "kr5-demo", "-o", tmp_path / "c2.json"))[1]
    assert_rows_on_one_line(circles)


def assert_uncertainty_table(output: str, folder, width: int) -> list[list[str]]:
    """The Monte Carlo table of ``output``: one line per identified parameter of ``folder``/parameters.csv,
    its mean, u and interval whole numbers equal to the file's; returns the table's body."""
    with (folder / "parameters.csv").open() as stream:
        rows = [row for row in csv.DictReader(stream) if row["identified"] == "true"]
    assert_whole(output, names=[row["name"] for row in rows], width=width)
    body = tables(output)[0]
    assert_rows_on_one_line(body)
    shown = {cells[0]: cells for cells in body}
    for row in rows:  # printed with 5 decimals (u: 3 significant digits)
        cells = shown[row["name"]]
        assert float(cells[3]) == pytest.approx(float(row["mean"]), abs=5.1e-6)
        assert float(cells[4]) == pytest.approx(float(row["std_uncertainty"]), rel=5.1e-3)
        assert float(cells[5]) == pytest.approx(float(row["coverage_low"]), abs=5.1e-6)
        assert float(cells[6]) == pytest.approx(float(row["coverage_high"]), abs=5.1e-6)
    return body


def test_uncertainty_table_at_80_columns(tmp_path):
    output = invoke("uncertainty", "thesis-laser-tracker", "-n", 200, "--workers", 1, "--out", tmp_path / "mc")
    body = assert_uncertainty_table(output, tmp_path / "mc", 80)
    # the linearised u and the §8 verdict: left out, said so, and where they are (the line under the table
    # counts the verdicts)
    assert all(len(cells) == 7 for cells in body)
    said = " ".join(output.split())
    assert "u (GUM), §8: not shown at 80 columns (in parameters.csv)" in said
    assert "parameter(s) differ" in said or "parameter(s) agree" in said


def test_tcp_joints_evaluate_and_plan_tables_at_80_columns(run_80, tmp_path):
    out, _ = run_80
    output = invoke("tcp", "--run", out, "--pose", "60,80,-45,100,45,280", "--out", tmp_path / "tcp")
    assert_whole(output)
    assert_rows_on_one_line(tables(output)[0])
    output = invoke("joints", out / "capture.csv", "-s", "kr5-demo", "--out", tmp_path / "joints")
    assert_whole(output, names=[f"J{i}" for i in range(1, 7)])
    assert_rows_on_one_line(tables(output)[0])
    output = invoke(
        "evaluate", "-s", "kr5-demo", "-p", out / "cpa" / "parameters.json", "-p", out / "refine" / "points.json",
        "-c", out / "validation.csv", "--out", tmp_path / "evaluation",
    )  # fmt: skip
    assert_whole(output, names=["nominal", "parameters", "points"])
    for body in tables(output):
        assert_rows_on_one_line(body)
    result = runner.invoke(app, ["plan", "check", "thesis-laser-tracker"], env=NARROW)
    assert result.exit_code == 1, result.output  # the thesis plan is infeasible in its cell
    assert_whole(result.output, names=["acceptance", "0.0..300.0"])


def test_catalog_tables_at_80_columns():
    # descriptions hold section numbers ("thesis 4.5.1:"): names only
    robots = invoke("robots")
    assert_whole(robots, names=[robot.name for robot in list_robots()], numbers=False)
    scenarios = invoke("scenarios")
    names = [s.name for s in list_scenarios()] + ["kuka-kr5-sixx-r650", "thesis-laser-tracker"]
    assert_whole(scenarios, names=names, numbers=False)
    said = " ".join(scenarios.split())
    assert all(s.description in said for s in list_scenarios())  # under the table when it has no room beside it
    assert_whole(invoke("instruments"), names=["thesis-laser-tracker", "leica-at960"], numbers=False)


def _piped(tmp_path, *args, columns: str | None = None) -> str:
    """``robotcal ARGS`` in a process of its own, stdout a pipe (not a terminal), COLUMNS as given."""
    env = {key: value for key, value in os.environ.items() if key not in ("COLUMNS", "LINES")}
    if columns is not None:
        env["COLUMNS"] = columns
    result = subprocess.run(
        [sys.executable, "-c", "from robotcal.cli import main; main()", *map(str, args)],
        cwd=tmp_path, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout


def test_piped_output_is_whole(tmp_path):
    # piped, with no COLUMNS: Rich assumes 80 columns
    output = _piped(tmp_path, "uncertainty", "thesis-laser-tracker", "-n", 100, "--workers", 1, "--out", tmp_path / "a")
    assert all(len(cells) == 7 for cells in assert_uncertainty_table(output, tmp_path / "a", 80))
    assert max(len(line.rstrip()) for line in output.splitlines()) <= 80
    # COLUMNS set for a pipe (e.g. a CI log) or a wide terminal: the full table, nothing left out
    wide = _piped(tmp_path, "uncertainty", "thesis-laser-tracker", "-n", 100, "--workers", 1, "--out", tmp_path / "b",
                  columns="140")  # fmt: skip
    body = assert_uncertainty_table(wide, tmp_path / "b", 140)
    assert all(len(cells) == 9 for cells in body) and "not shown" not in wide
    assert {cells[8] for cells in body} <= {"agrees", "differs"}


def test_simulate_message_is_one_line_at_80_columns(tmp_path):
    """Issue 30: piped (80 columns), simulate's one-line message wrapped, its seed on a line of its own."""
    folder = tmp_path / "a-folder-with-a-name-long-enough-to-push-the-message-past-80-columns"
    output = invoke(
        "simulate", "kr5-demo", "--out", folder / "capture.csv", "--truth-out", folder / "truth.json", "--seed", 12
    )
    lines = output.splitlines()
    wrote = [line for line in lines if line.startswith("wrote ")]
    assert len(wrote) == 2 and len(lines) == 2, output
    assert wrote[0].endswith(f"{folder / 'truth.json'}: perturbed 'true' robot (seed 11)"), wrote[0]  # kr5-demo's truth.seed
    assert wrote[1].startswith(f"wrote {folder / 'capture.csv'}: 270 points") and wrote[1].endswith("seed 12)"), wrote[1]


def test_model_table_has_no_empty_header():
    """Issue 30: the cross-validation table had a column with an empty header (the chosen model's mark)."""
    from types import SimpleNamespace

    from rich.console import Console

    from robotcal.cli._common import model_table

    def candidate(model, unknowns, rms):
        return SimpleNamespace(model=model, unknowns=unknowns, calibration_rms_mm=rms, cv_rms_mm=2 * rms, folds=5)

    one = candidate("geometric", 23, 0.05)
    choice = SimpleNamespace(candidates=(one, candidate("compliance", 25, 0.02)), chosen="compliance")
    for result, headers in (
        (SimpleNamespace(model_choice=None, cross_validation=one), ["model", "unknowns", "calibration RMS [mm]", "CV RMS [mm]"]),
        (SimpleNamespace(model_choice=choice, cross_validation=one), ["model", "unknowns", "calibration RMS [mm]", "CV RMS [mm]", "chosen"]),
    ):  # fmt: skip
        table = model_table(result)
        assert [column.header for column in table.columns] == headers
        console = Console(width=120, record=True, file=open(os.devnull, "w"))  # noqa: SIM115
        console.print(table)
        header_line = next(line for line in console.export_text().splitlines() if line.startswith("┃"))
        assert all(cell.strip() for cell in header_line.split("┃")[1:-1]), header_line
    assert [row[-1] for row in table.rows] == ["", "yes"]
