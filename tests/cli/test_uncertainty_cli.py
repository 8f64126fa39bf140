"""``robotcal uncertainty``: files, same numbers as the library, validation before work, no half output."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

import robotcal.io.results.uncertainty_files as uncertainty_files
from robotcal.api import monte_carlo_problem
from robotcal.cli import app
from robotcal.errors import InputError
from robotcal.io import load_scenario
from robotcal.io.formats.draws_npz import read_draws
from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo

runner = CliRunner()
DESIGN_COLUMNS = ["name", "unit", "nominal", "mean", "std_uncertainty", "coverage_low", "coverage_high", "min", "max"]


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("mc") / "result"
    arguments = ["uncertainty", "thesis-laser-tracker", "-n", "2000", "--seed", "9", "--workers", "1"]
    result = runner.invoke(app, arguments + ["--save-draws", "--interval", "shortest", "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out, result.output


def test_writes_the_documented_files(run_folder):
    out, output = run_folder
    names = sorted(path.name for path in out.iterdir())
    expected = [".robotcal", "parameters.csv", "parameters.json", "draws.npz"] + [f"hist_J{i}.png" for i in range(1, 6)]
    assert names == sorted(expected)  # .robotcal: the output-policy marker
    assert "wrote" in output and "draws/s" in output
    with (out / "parameters.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert list(rows[0])[:9] == DESIGN_COLUMNS
    assert [row["name"] for row in rows] == list(load_scenario("thesis-laser-tracker").robot.parameter_names)
    document = json.loads((out / "parameters.json").read_text())
    assert document["seed"] == 9 and document["draws"] == 2000 and document["interval"] == "shortest"
    assert len(document["covariance"]["names"]) == 20
    assert document["scenario"]["name"] == "thesis-laser-tracker"
    assert set(document["versions"]) >= {"robotcal", "numpy", "scipy"}


def test_cli_numbers_equal_the_library(run_folder):
    out, _ = run_folder
    scenario = load_scenario("thesis-laser-tracker")
    problem = monte_carlo_problem(scenario)
    library = run_monte_carlo(problem, MonteCarloSettings(iterations=2000, interval="shortest"), seed=9)
    with (out / "parameters.csv").open() as stream:
        rows = {row["name"]: row for row in csv.DictReader(stream)}
    row = rows["J4.d"]
    assert float(row["std_uncertainty"]) == pytest.approx(library.summary.std_uncertainty[3, 0], rel=1e-10)
    # coverage_low is the interval for the measurand: the draws' (shortest) interval moved by twice the bias
    assert float(row["coverage_low"]) == pytest.approx(library.interval()[0][3, 0], rel=1e-10)
    assert float(row["draws_low"]) == pytest.approx(library.summary.shortest_low[3, 0], rel=1e-10)
    theta = rows["J3.theta"]
    assert theta["unit"] == "deg"
    assert float(theta["mean"]) == pytest.approx(np.rad2deg(library.summary.mean[2, 1]), rel=1e-10)
    draws = read_draws(out / "draws.npz")
    np.testing.assert_allclose(draws.values, library.draws, rtol=0, atol=1e-9)
    assert draws.seed == 9 and draws.robot.name == scenario.robot.name


@pytest.mark.parametrize(
    "options, message",
    [
        (["-n", "0"], "`iterations` must be a positive integer; got 0"),
        (["-n", "-3"], "`iterations` must be a positive integer"),
        (["--coverage", "1.2"], r"`coverage` must be a probability in \(0, 1\)"),
        (["--interval", "widest"], "`interval` must be one of"),
    ],
)
def test_bad_options_are_refused_before_any_work(tmp_path, options, message):
    out = tmp_path / "never"
    result = runner.invoke(app, ["uncertainty", "thesis-laser-tracker", "--out", str(out)] + options)
    assert result.exit_code == 2
    assert "error:" in result.output and any(part in result.output for part in message.split("`")[1:2])
    assert not out.exists()


def test_unidentifiable_scenario_is_refused_with_the_key(tmp_path):
    scenario = tmp_path / "two-points.toml"
    text = (
        'robot = "kuka-kr5-sixx-r650"\n[instrument]\npreset = "thesis-laser-tracker"\n[capture]\n'
        "start_deg = [15, 0, 0, 0, 0, 0]\nsweep_deg = [45, 80, 100, 50, 200, 300]\npoints = [2, 20, 30, 15, 25, 30]\n"
        "reflector_mm = [[100,0,0],[200,0,0],[0,50,0],[20,0,0],[0,80,0],[0,60,0]]\n"
    )
    scenario.write_text(text)
    out = tmp_path / "never"
    result = runner.invoke(app, ["uncertainty", str(scenario), "-n", "100", "--out", str(out)])
    assert result.exit_code == 2
    assert "circle 1 has 2 points" in result.output
    assert not out.exists()


def test_interrupted_run_leaves_no_output_folder(tmp_path, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(uncertainty_files, "write_uncertainty_folder", interrupted)
    out = tmp_path / "result"
    result = runner.invoke(
        app, ["uncertainty", "thesis-laser-tracker", "-n", "100", "--workers", "1", "--out", str(out)]
    )
    assert result.exit_code == 130
    assert list(tmp_path.iterdir()) == []  # neither the folder nor its hidden partial sibling


# ----------------------------------------------------------------------------------------------- figures


def test_a_figure_error_leaves_no_output_folder(tmp_path, monkeypatch):
    import robotcal.plots.montecarlo as histograms

    def refuse(result, folder, **kwargs):
        raise InputError("cannot draw: no space left on the device")

    monkeypatch.setattr(histograms, "write_histograms", refuse)
    out = tmp_path / "result"
    result = runner.invoke(app, ["uncertainty", "thesis-laser-tracker", "-n", "200", "--workers", "1", "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "error: cannot draw: no space left on the device" in result.output
    assert list(tmp_path.iterdir()) == []  # neither the folder nor its hidden partial sibling
