"""``robotcal uncertainty --capture CAPTURE.csv --params REFINED.json --scenario S``: the Monte Carlo of a
measured capture (issue 14, item 3), from the files ``robotcal refine`` writes: the files, the numbers
against the library, and the errors."""

from __future__ import annotations

import csv
import json
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from robotcal.api import measured_monte_carlo
from robotcal.cli import app
from robotcal.errors import IdentifiabilityWarning
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io import load_scenario, read_capture, read_parameters
from robotcal.io.formats.capture_csv import write_capture
from robotcal.io.formats.parameters_json import read_targets
from robotcal.io.results.uncertainty_files import read_uncertainty_csv
from robotcal.io.schema.robots import load_robot
from robotcal.simulation.generator import simulate_target_poses
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses

runner = CliRunner()
ROBOT = load_robot("abb-irb120")
TRACKER = [[0.0, -1.0, 0.0, 2100.0], [1.0, 0.0, 0.0, -150.0], [0.0, 0.0, 1.0, -420.0], [0.0, 0.0, 0.0, 1.0]]
OFFSETS = np.array([[60.0, 0.0, 25.0], [-30.0, 52.0, 30.0], [-30.0, -52.0, 35.0]])
U95_MM = 0.03


def _scenario_text(*, instrument: bool) -> str:
    targets = "".join(
        f'[[targets]]\nname = "T{k + 1}"\nflange_mm = "unknown"\nguess_mm = {(OFFSETS[k] + 4.0).tolist()}\n'
        for k in range(3)
    )
    table = '[instrument]\na_um = 30.0\nb_um_per_m = 0.0\nnoise = "normal"\ncoverage_factor = 2.0\n' if instrument else ""
    return f'robot = "abb-irb120"\ntracker_from_base = {TRACKER}\n{table}[identification]\nbase_frame = "given"\n{targets}'


def invoke(*args, code: int = 0):
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
    assert result.exit_code == code, result.output
    return " ".join(result.output.split())


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cell")
    truth = perturb_parameters(ROBOT, length_sd_mm=0.3, angle_sd_deg=0.05, rng=np.random.default_rng(7))
    targets = tuple(Target(name=f"T{k + 1}", frame="flange", positions=OFFSETS[k], known=False) for k in range(3))
    tracker = Instrument(name="tracker", a_mm=U95_MM, b_mm_per_m=0.0, noise="normal", coverage_factor=2.0)
    readings = random_poses(ROBOT, 25, rng=np.random.default_rng(5))
    capture, _ = simulate_target_poses(
        ROBOT, readings, targets, tracker, np.array(TRACKER), true_parameters=truth, true_offsets=OFFSETS,
        u95_mm=U95_MM, rng=6,
    )  # fmt: skip
    capture_path = folder / "capture.csv"
    write_capture(capture_path, capture)
    scenario = folder / "cell.toml"
    scenario.write_text(_scenario_text(instrument=False), encoding="utf-8")
    refined = folder / "refined.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)  # J6's four held: by design
        invoke("refine", capture_path, "--scenario", scenario, "--out", refined)
    out = folder / "mc"
    said = invoke(
        "uncertainty", "--capture", capture_path, "--params", refined, "--scenario", scenario, "-n", 30,
        "--seed", 4, "--workers", 1, "--save-draws", "--out", out,
    )  # fmt: skip
    return folder, capture_path, scenario, refined, out, said


def test_writes_the_files_with_the_measured_model(cell):
    _, _, _, _, out, said = cell
    for name in ("parameters.csv", "parameters.json", "targets.csv", "draws.npz"):
        assert (out / name).is_file(), name
    document = json.loads((out / "parameters.json").read_text(encoding="utf-8"))
    assert document["model"] == "measured capture" and document["draws"] == 30 and document["seed"] == 4
    assert "U95/2" in document["method"] and "U(95)" in document["noise"]
    assert document["capture"]["points"] == 75 and {row["name"] for row in document["targets"]} == {"T1", "T2", "T3"}
    assert "measured capture" in said and "30 draws" in said


def test_cli_numbers_equal_the_library(cell):
    folder, capture_path, scenario_path, refined, out, _ = cell
    scenario = load_scenario(scenario_path)
    capture = read_capture(capture_path, n_joints=6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        estimate = read_parameters(refined, scenario.robot)
    library = measured_monte_carlo(capture, scenario, estimate, draws=30, rng=4, offsets=read_targets(refined))
    rows = {row["name"]: row for row in read_uncertainty_csv(out / "parameters.csv")}
    u = library.parameters.summary.std_uncertainty
    for (i, k), flag in np.ndenumerate(library.parameters.identified):
        name = ROBOT.parameter_names[5 * i + k]
        scale = 1.0 if k in (0, 2) else 180.0 / np.pi
        assert rows[name]["identified"] == bool(flag)
        # the CSV holds 12 significant digits
        np.testing.assert_allclose(rows[name]["std_uncertainty"], u[i, k] * scale, rtol=1e-10, atol=0)
    with (out / "targets.csv").open(encoding="utf-8") as stream:
        targets = list(csv.DictReader(stream))
    assert len(targets) == 9
    expected = library.target_summary.std_uncertainty.ravel()
    np.testing.assert_allclose([float(r["std_uncertainty"]) for r in targets], expected, rtol=1e-10)
    # the offsets scatter about the estimate by a few U(95) at most
    assert np.all(np.abs([float(r["mean"]) - float(r["estimate"]) for r in targets]) < 0.05)
    # the linearised u is the refinement's rescaled to the stated noise, and the JSON says so
    np.testing.assert_allclose(
        [float(r["lpu_std_uncertainty"]) for r in targets], library.target_linearised_u.ravel(), rtol=1e-10
    )
    linearised = json.loads((out / "parameters.json").read_text(encoding="utf-8"))["linearised"]
    assert "(u_stated / sigma_hat)^2" in linearised["method"]
    np.testing.assert_allclose(linearised["stated_u_mm"], U95_MM / 2.0, rtol=1e-12)
    np.testing.assert_allclose(linearised["residual_sigma_mm"], library.residual_sigma_mm, rtol=1e-9)


def test_errors_name_the_problem(cell, tmp_path):
    folder, capture_path, scenario, refined, _, _ = cell
    said = invoke("uncertainty", "--capture", capture_path, "--scenario", scenario, "--out", tmp_path / "a", code=2)
    assert "--capture and --params go together" in said
    # a capture without u95_mm and a scenario without [instrument]: no noise to simulate
    no_u95 = tmp_path / "no_u95.csv"
    text = capture_path.read_text(encoding="utf-8").splitlines()
    no_u95.write_text("\n".join(",".join(line.split(",")[:-1]) for line in text) + "\n", encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        said = invoke("uncertainty", "--capture", no_u95, "--params", refined, "--scenario", scenario, "-n", 25,
                      "--out", tmp_path / "b", code=2)  # fmt: skip
    assert "no `u95_mm` column" in said and "[instrument] table" in said
    # parameters of another robot
    other = tmp_path / "other.json"
    document = json.loads(refined.read_text(encoding="utf-8"))
    document["robot"] = "kuka-kr5-sixx-r650"
    other.write_text(json.dumps(document), encoding="utf-8")
    said = invoke("uncertainty", "--capture", capture_path, "--params", other, "--scenario", scenario, "--out",
                  tmp_path / "c", code=2)  # fmt: skip
    assert "parameters of robot 'kuka-kr5-sixx-r650'" in said and "abb-irb120" in said
    # parameters refined on another capture (another number of points)
    fewer = tmp_path / "fewer.csv"
    fewer.write_text("\n".join(text[:-3]) + "\n", encoding="utf-8")
    said = invoke("uncertainty", "--capture", fewer, "--params", refined, "--scenario", scenario, "--out",
                  tmp_path / "d", code=2)  # fmt: skip
    assert "refined on a capture of 75 points" in said
    said = invoke("uncertainty", "--capture", capture_path, "--params", refined, "--scenario", scenario,
                  "--criterion", "distances", "--out", tmp_path / "e", code=2)  # fmt: skip
    assert "refined with the points criterion" in said
    for name in "abcde":
        assert not (tmp_path / name).exists()
