"""Issue 31: one front door per thing a user does; each command gives the numbers its API function gives.

Every test runs a command on a small case and calls the function of :mod:`robotcal.api` the command goes
through, with the same inputs; the tolerances are those of the files' decimals. The Monte Carlo takes one
settings object, passed through unchanged.
"""

from __future__ import annotations

import csv
import doctest
import json
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

import robotcal
from robotcal import api
from robotcal.cli import app
from robotcal.errors import InputError
from robotcal.io import load_robot, load_scenario, read_capture, write_capture, write_parameters
from robotcal.io.formats.trajectory_csv import read_trajectory, write_trajectory
from robotcal.kinematics.model import ParameterSet
from robotcal.uncertainty.montecarlo import MonteCarloSettings

runner = CliRunner()
THESIS = load_scenario("thesis-laser-tracker")


def invoke(*args):
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result


@pytest.mark.parametrize("module", ["robotcal.deploy", "robotcal.studies", "robotcal.resolve"])
def test_the_examples_of_the_front_door_modules_run(module):
    """The Examples of the modules behind robotcal.api (tests/unit/test_doctests.py runs robotcal.api's own)."""
    import importlib

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", robotcal.errors.RobotcalWarning)
        failed, _ = doctest.testmod(importlib.import_module(module), optionflags=doctest.ELLIPSIS)
    assert failed == 0


def test_the_front_door_names_load_from_robotcal_and_the_modules_that_define_them():
    for name in ("predict", "export_model", "import_capture", "iso9283", "optimise_plan", "plan_tcp_p95", "sensitivity"):
        assert getattr(robotcal, name) is getattr(api, name)
    from robotcal.deploy import compensate
    from robotcal.resolve import TCPTargets, capture_targets, seed_from, tcp_targets
    from robotcal.studies import check_plan, diagnose_joints

    assert (api.compensate, api.check_plan, api.diagnose_joints) == (compensate, check_plan, diagnose_joints)
    assert (api.seed_from, api.capture_targets, api.tcp_targets, api.TCPTargets) == (
        seed_from, capture_targets, tcp_targets, TCPTargets,
    )  # fmt: skip


# ------------------------------------------------------------------------------ one Monte Carlo settings object


def test_monte_carlo_uses_the_settings_it_is_given_unchanged():
    settings = MonteCarloSettings(iterations=200, coverage=0.9, interval="shortest", batch_size=64, workers=1)
    given = api.monte_carlo(THESIS, settings=settings, rng=5)
    built = api.monte_carlo(THESIS, draws=200, coverage=0.9, interval="shortest", batch_size=64, rng=5)
    assert given.settings == built.settings
    assert given.settings.batch_size == 64 and given.settings.coverage == 0.9
    # the same draws: the same numbers, bit for bit
    np.testing.assert_array_equal(given.summary.std_uncertainty, built.summary.std_uncertainty)
    np.testing.assert_array_equal(given.draws, built.draws)
    # a keyword that agrees with the settings is accepted
    agreeing = api.monte_carlo(THESIS, settings=settings, draws=200, coverage=0.9, rng=5)
    np.testing.assert_array_equal(agreeing.draws, given.draws)


@pytest.mark.parametrize(
    ("keyword", "value", "field"),
    [("draws", 300, "iterations"), ("coverage", 0.95, "coverage"), ("workers", 2, "workers"), ("keep_draws", False, "keep_draws")],
)
def test_monte_carlo_refuses_a_keyword_that_disagrees_with_its_settings(keyword, value, field):
    settings = MonteCarloSettings(iterations=200, coverage=0.9)
    with pytest.raises(InputError, match=rf"`settings` and `{keyword}` disagree: settings\.{field} = .*{keyword} = "):
        api.monte_carlo(THESIS, settings=settings, rng=1, **{keyword: value})


def test_monte_carlo_without_settings_keeps_its_defaults():
    """The scenario's [montecarlo] draws and coverage, else 10^4 and 0.95; the class's defaults for the rest."""
    from robotcal.resolve import monte_carlo_settings

    robot_only = monte_carlo_settings(None, None, draws=None, coverage=None, interval=None, adaptive=None,
                                      workers=None, scheduler=None, keep_draws=None, batch_size=None)  # fmt: skip
    assert robot_only == MonteCarloSettings(iterations=10_000, coverage=0.95)
    from_scenario = monte_carlo_settings(None, THESIS, draws=None, coverage=None)
    assert (from_scenario.iterations, from_scenario.coverage) == (THESIS.montecarlo.iterations, THESIS.montecarlo.coverage)


def test_the_run_plan_settings_reach_the_monte_carlo_unchanged(monkeypatch, tmp_path):
    """The uncertainty stage hands plan_run's MonteCarloSettings to api.monte_carlo as they are."""
    from robotcal.pipeline import stages

    plan = robotcal.plan_run("kr5-demo", draws=500, refined_draws=300, workers=1)
    seen = []

    def spy(scenario, *, settings=None, **keywords):
        seen.append((settings, {k for k in keywords if k in ("draws", "coverage", "workers")}))
        raise KeyboardInterrupt  # stop after the first call: the settings are what this test checks

    monkeypatch.setattr(stages.api, "monte_carlo", spy)
    nominal = ParameterSet.nominal(plan.scenario.robot)
    with pytest.raises(KeyboardInterrupt):
        stages.uncertainty_stage(
            plan.scenario, montecarlo=plan.montecarlo, refined_montecarlo=plan.refined_montecarlo, seed=1,
            cpa=nominal, deployed=nominal, out=tmp_path, figures=None,
        )  # fmt: skip
    assert seen[0][0] is plan.montecarlo and seen[0][1] == set()  # no keyword rebuilds it


# ---------------------------------------------------------------------------------- the CLI and the library


def test_predict_cli_equals_the_library(tmp_path):
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    values = robot.nominal.copy()
    values[1, 2] += 0.3
    params = tmp_path / "p.json"
    write_parameters(params, ParameterSet(robot=robot, values=values))
    poses = tmp_path / "poses.csv"
    write_trajectory(poses, np.random.default_rng(2).uniform(robot.limits[:, 0], robot.limits[:, 1], (5, 6)))
    out = tmp_path / "pred.csv"
    invoke("predict", params, "--poses", poses, "--target", "10,-20,150", "--out", out)
    rows = list(csv.DictReader(out.open()))
    cli = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    frames = api.predict(params, np.rad2deg(read_trajectory(poses, n_joints=6)), robot, tool_mm=[10, -20, 150])
    np.testing.assert_allclose(cli, frames[:, :3, 3], rtol=0, atol=1e-9)  # the CSV holds 9 decimals


@pytest.mark.parametrize("format", ["dh", "mdh", "urdf", "ur-yaml", "json"])
def test_export_cli_writes_the_text_of_the_library(tmp_path, format):
    out = tmp_path / f"model.{format}"
    invoke("export", "--nominal", "kuka-kr5-sixx-r650", "--format", format, "--out", out)
    provenance = {"method": "nominal parameters of the robot file", "robot_file": "kuka-kr5-sixx-r650"}
    robot = load_robot("kuka-kr5-sixx-r650")
    assert out.read_text(encoding="utf-8") == api.export_model(robot, format, provenance=provenance)


def test_import_cli_writes_the_capture_of_the_library(tmp_path):
    export = tmp_path / "points.csv"
    export.write_text("name;x;y;z\nP1;1000.5;-20.25;300\nP2;1001;-19.5;301.125\n", encoding="utf-8")
    log = tmp_path / "joints.csv"
    log.write_text("name,q1,q2,q3,q4,q5,q6\nP1,0,-90,90,0,30,0\nP2,5,-85,90,0,30,0\n", encoding="utf-8")
    out = tmp_path / "capture.csv"
    invoke("import", export, "--joints", log, "--robot", "kuka-kr5-sixx-r650", "--units", "mm", "--out", out)
    capture, points = api.import_capture(export, log, load_robot("kuka-kr5-sixx-r650"), units="mm")
    written = read_capture(out, n_joints=6)
    assert points.unit == "mm"
    np.testing.assert_allclose(written.points, capture.points, rtol=0, atol=1e-9)  # 12 decimals of mm
    np.testing.assert_allclose(written.readings, capture.readings, rtol=0, atol=1e-13)


def test_iso9283_cli_equals_the_library(tmp_path):
    scenario = load_scenario("kr5-demo")
    test_poses = np.array([[0, 90, -90, 0, 45, 0], [10, 80, -80, 0, 40, 0], [-10, 95, -85, 5, 50, 0],
                           [5, 85, -95, -5, 45, 10], [-5, 90, -90, 0, 35, -10]], dtype=float)  # fmt: skip
    capture = api.simulate_poses(scenario, np.tile(test_poses, (3, 1)), rng=3)
    path = tmp_path / "iso-capture.csv"
    write_capture(path, capture)
    out = tmp_path / "iso.csv"
    invoke("iso9283", path, "--scenario", "kr5-demo", "--out", out)
    rows = {(r["model"], r["pose"]): r for r in csv.DictReader(out.open())}
    library = api.iso9283(read_capture(path, n_joints=6), scenario)["nominal"]
    cli = np.array([[float(rows["nominal", f"P{k + 1}"][c]) for c in ("AP", "RP")] for k in range(5)])
    np.testing.assert_allclose(cli, np.c_[library.ap, library.rp], rtol=0, atol=1e-6)  # 6 decimals
    assert float(rows["nominal", "P2-P4"]["AD"]) == pytest.approx(library.ad, abs=1e-6)


def test_sensitivity_cli_equals_the_library(tmp_path):
    from robotcal.planning.sensitivity import study_rows

    out = tmp_path / "sens"
    vary = "capture.points=10,20"
    invoke("sensitivity", "thesis-laser-tracker", "--vary", vary, "-n", "100", "--seed", "4", "--out", out)
    study = api.sensitivity("thesis-laser-tracker", [vary], iterations=100, seed=4)
    library = study_rows(study)
    with (out / "sensitivity.csv").open() as stream:
        cli = list(csv.DictReader(stream))
    assert len(cli) == len(library)
    for written, row in zip(cli, library, strict=True):
        assert written["name"] == row["name"]
        assert float(written["std_uncertainty"]) == pytest.approx(row["std_uncertainty"], rel=1e-12)
        assert float(written["cpk"]) == pytest.approx(row["cpk"], rel=1e-12)
    # a mapping of keys to values is the same study
    again = api.sensitivity("thesis-laser-tracker", {"capture.points": [10, 20]}, iterations=100, seed=4)
    assert [r["std_uncertainty"] for r in study_rows(again)] == [r["std_uncertainty"] for r in library]


def test_plan_optimise_cli_confirms_with_the_library(tmp_path):
    out = tmp_path / "opt"
    invoke("plan", "optimise", "thesis-laser-tracker", "--out", out, "--generations", "1", "--population", "2",
           "--confirm-draws", "200", "--workspace-poses", "20", "--seed", "3")  # fmt: skip
    comparison = json.loads((out / "comparison.json").read_text())
    baseline = api.plan_tcp_p95(THESIS, draws=200, rng=4, workspace_poses=20, workspace_seed=3)
    assert comparison["monte_carlo_p95_tcp_mm"]["baseline"] == pytest.approx(baseline, rel=1e-12)
    search = api.optimise_plan(THESIS, generations=1, population=2, seed=3, workspace_poses=20)
    assert comparison["linearised"]["optimised"]["p95-tcp"] == pytest.approx(search.best["p95-tcp"], rel=1e-12)
