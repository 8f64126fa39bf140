"""The run's ``iso9283`` stage: a simulated ISO 9283 test, its files equal to what read_run gives back."""

from __future__ import annotations

import numpy as np

from robotcal.api import perturb
from robotcal.diagnostics.iso9283 import simulate_iso_study
from robotcal.io import load_scenario
from robotcal.io.results.run_folder import read_document
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline.figures import FigureJobs
from robotcal.pipeline.stages import ISO_TARGETS_MM, iso9283_stage


def test_iso9283_stage_writes_the_study_it_computed(tmp_path):
    scenario = load_scenario("kr5-demo")
    truth = perturb(scenario, rng=1)
    models = {"nominal": ParameterSet.nominal(scenario.robot), "truth": truth}
    figures = FigureJobs()
    output = iso9283_stage(scenario, truth=truth, models=models, seed=5, out=tmp_path, figures=figures)
    assert [path.name for path in figures.paths()] == ["iso9283.png"]
    # the documents are what the folder holds
    for name, document in output.documents.items():
        relative = name.removeprefix("iso9283/")
        if name.endswith((".csv", ".json")):
            assert read_document(tmp_path / "iso9283", relative) == document, name
        else:
            assert document == tmp_path / name and document.is_file()
    # the same study as the library's, seed for seed (the stage adds files, not numbers)
    again = simulate_iso_study(
        scenario.robot,
        models,
        seed=5,
        true_parameters=truth,
        targets_mm=ISO_TARGETS_MM,
        tracker_from_base=scenario.tracker_from_base,
        joint_errors=scenario.joint_errors,
        instrument=scenario.instrument,
    )
    for model in models:
        np.testing.assert_array_equal(output.value.results[model].ap, again.results[model].ap)
    table = output.documents["iso9283/iso9283.csv"]
    ap = {(row[0], row[1]): row[5] for row in table.rows if row[5]}
    assert len(ap) == 2 * 5
    # three targets: orientation measured; the true model is far more accurate than the nominal one
    assert all(row[11] for row in table.rows if row[5])
    nominal, true = output.value.results["nominal"], output.value.results["truth"]
    assert np.max(true.ap) < 0.25 * np.max(nominal.ap)
    assert output.documents["iso9283/study.json"]["cycles"] == 30
