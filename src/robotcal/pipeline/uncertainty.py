"""GUM Supplement 1 Monte Carlo of a calibration (thesis ch. 5.2): the computation and the files of its folder.

``robotcal uncertainty`` and the uncertainty stage of a run call :func:`compute_uncertainty` and
:func:`write_uncertainty_folder`.
"""

from __future__ import annotations

from pathlib import Path

from robotcal.io.draws_npz import write_draws
from robotcal.io.scenario import Scenario
from robotcal.io.uncertainty_files import write_uncertainty_csv, write_uncertainty_json
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline.folder import read_document
from robotcal.pipeline.result import Document
from robotcal.uncertainty.montecarlo import MonteCarloResult, MonteCarloSettings, ProgressCallback, run_monte_carlo
from robotcal.workflow import scenario_monte_carlo, versions

__all__ = ["compute_uncertainty", "write_uncertainty_folder"]


def compute_uncertainty(
    scenario: Scenario,
    settings: MonteCarloSettings,
    *,
    seed: int,
    true_parameters: ParameterSet | None = None,
    progress: ProgressCallback | None = None,
    model: str = "cpa",
    criterion: str = "points",
) -> MonteCarloResult:
    """Prepare (all input checks happen here, before any draw) and run the Monte Carlo.

    ``model="cpa"`` draws capture -> CPA around ``true_parameters`` (default: nominal), the thesis's
    study; ``model="refined"`` draws capture -> CPA -> refinement (``criterion``), the deployed model.
    ``progress(done, total)`` is called after every block when given.
    """
    problem = scenario_monte_carlo(scenario, true_parameters=true_parameters, model=model, criterion=criterion)
    return run_monte_carlo(problem, settings, seed=seed, progress=progress)


def write_uncertainty_folder(
    folder: Path, result: MonteCarloResult, scenario: Scenario, *, save_draws: bool
) -> dict[str, Document]:
    """Write ``parameters.csv``, ``parameters.json``, the histograms and (optionally) ``draws.npz``
    into ``folder`` (an existing, normally temporary, folder).

    Returns the documents by file name; the two parameter files are written by
    :mod:`robotcal.io.uncertainty_files` and read back once (:func:`robotcal.pipeline.folder.read_document`).
    """
    from robotcal.plots.montecarlo import write_histograms  # matplotlib only when writing figures

    echo = {"name": scenario.name, "source": scenario.source, "settings": scenario.settings}
    write_uncertainty_csv(folder / "parameters.csv", result)
    write_uncertainty_json(folder / "parameters.json", result, scenario=echo, versions=versions())
    documents: dict[str, Document] = {name: read_document(folder, name) for name in ("parameters.csv", "parameters.json")}
    if save_draws:
        write_draws(
            folder / "draws.npz", result.robot, result.draws, result.identified, seed=result.seed, model=result.model
        )
        documents["draws.npz"] = folder / "draws.npz"
    for path in write_histograms(result, folder):
        documents[Path(path).name] = Path(path)
    return documents
