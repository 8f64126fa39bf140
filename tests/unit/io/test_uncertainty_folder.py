"""io.uncertainty_files.write_uncertainty_folder: the documents it returns are the files as read back."""

from __future__ import annotations

import pytest

from robotcal.api import monte_carlo
from robotcal.io import load_scenario
from robotcal.io.run_folder import read_document
from robotcal.io.uncertainty_files import write_uncertainty_folder


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
