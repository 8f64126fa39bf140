"""io.results.uncertainty_files.write_uncertainty_folder: the documents it returns are the files as read back."""

from __future__ import annotations

import pytest

from robotcal.api import monte_carlo
from robotcal.io import load_scenario
from robotcal.io.results.run_folder import read_document
from robotcal.io.results.uncertainty_files import write_uncertainty_folder


@pytest.mark.parametrize("save_draws", [False, True])
def test_returned_documents_equal_the_files_read_back(tmp_path, save_draws):
    scenario = load_scenario("thesis-laser-tracker")
    result = monte_carlo(scenario, draws=400, rng=11)
    documents = write_uncertainty_folder(tmp_path, result, scenario=scenario, save_draws=save_draws)
    assert sorted(documents) == sorted(path.name for path in tmp_path.iterdir())
    assert ("draws.npz" in documents) is save_draws
    for name in ("parameters.csv", "parameters.json"):
        assert documents[name] == read_document(tmp_path, name)
    assert documents["parameters.json"]["scenario"]["name"] == "thesis-laser-tracker"


def test_parameters_csv_keeps_its_columns_and_adds_the_interval_ones(tmp_path):
    # issue 24: coverage_low/high is the interval for the measurand (the draws' interval moved by twice the bias);
    # the draws' own interval, the bias and the simulated robot are added at the end, no column renamed or moved
    import csv
    import math

    import numpy as np

    from robotcal.io.results.uncertainty_files import CSV_COLUMNS, INTERVAL_METHOD
    from robotcal.simulation.perturb import perturb_parameters

    scenario = load_scenario("thesis-igps")
    estimate = perturb_parameters(scenario.robot, length_sd_mm=0.2, angle_sd_deg=0.05, include_base=True, rng=4)
    result = monte_carlo(scenario, parameters=estimate, draws=400, rng=11)
    documents = write_uncertainty_folder(tmp_path, result, scenario=scenario, save_draws=False)
    before = (
        "name, unit, nominal, mean, std_uncertainty, coverage_low, coverage_high, min, max, identified, "
        "symmetric_low, symmetric_high, shortest_low, shortest_high, noise_free, lpu_std_uncertainty, "
        "lpu_coverage_low, lpu_coverage_high, lpu_agrees, model"
    ).split(", ")
    added = ["centre", "bias", "draws_low", "draws_high"]
    added += ["estimate", "deployed", "bias_treatment", "correction_u"]  # issue 29: the deployed value and its bias
    assert list(CSV_COLUMNS) == before + added
    with (tmp_path / "parameters.csv").open() as stream:
        rows = {row["name"]: row for row in csv.DictReader(stream)}
    assert list(next(iter(rows.values()))) == list(CSV_COLUMNS)
    low, high = result.interval()
    draws_low, _ = result.draws_interval()
    for index, name in enumerate(scenario.robot.parameter_names):
        row = rows[name]
        scale = 180.0 / math.pi if row["unit"] == "deg" else 1.0
        joint, column = divmod(index, 5)
        # 12 significant digits in the file
        for key, value in (
            ("coverage_low", low), ("coverage_high", high), ("draws_low", draws_low), ("bias", result.bias),
            ("centre", result.centre),
        ):  # fmt: skip
            assert float(row[key]) == pytest.approx(value[joint, column] * scale, rel=1e-11, abs=1e-11)
        if row["identified"] == "true":
            moved = float(row["draws_low"]) - 2.0 * float(row["bias"])
            assert float(row["coverage_low"]) == pytest.approx(moved, rel=1e-10, abs=1e-10)
            assert float(row["mean"]) - float(row["centre"]) == pytest.approx(float(row["bias"]), abs=1e-9)
        else:
            assert float(row["bias"]) == 0.0 and row["coverage_low"] == row["draws_low"]
    document = documents["parameters.json"]
    assert document["interval_method"] == INTERVAL_METHOD
    j3a = next(p for p in document["parameters"] if p["name"] == "J3.a")
    assert {"centre", "bias", "draws_low", "draws_high", "true"} <= set(j3a)
    assert np.isclose(j3a["centre"], j3a["true"], atol=1e-9)
