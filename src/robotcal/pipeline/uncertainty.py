"""GUM Supplement 1 Monte Carlo of a calibration (thesis ch. 5.2): the computation and the files of its folder.

``robotcal uncertainty`` and the uncertainty stage of a run call :func:`compute_uncertainty` and
:func:`write_uncertainty_folder`.

Importing this module is light (``robotcal uncertainty`` forks its figure worker before the numeric
modules load, so that both import at the same time): the Monte Carlo engine and the file writers are
imported by the functions.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Callable

    from robotcal.io.scenario import Scenario
    from robotcal.kinematics.model import ParameterSet
    from robotcal.pipeline.result import Document
    from robotcal.plots.background import FigureRenderer
    from robotcal.uncertainty.montecarlo import MonteCarloResult, MonteCarloSettings, ProgressCallback

__all__ = ["compute_uncertainty", "write_uncertainty_folder"]

#: The histogram figures, named for :meth:`FigureRenderer.submit` (matplotlib is imported where they are drawn).
HISTOGRAMS = "robotcal.plots.montecarlo:write_histograms"
#: Their pages made and drawn once ahead, while the draws run (:func:`robotcal.plots.montecarlo.prepare_histograms`).
PREPARE_HISTOGRAMS = "robotcal.plots.montecarlo:prepare_histograms"


def compute_uncertainty(
    scenario: Scenario,
    settings: MonteCarloSettings,
    *,
    seed: int,
    true_parameters: ParameterSet | None = None,
    progress: ProgressCallback | None = None,
    model: str = "cpa",
    criterion: str = "points",
    renderer: FigureRenderer | None = None,
    render: Callable | None = None,
) -> MonteCarloResult:
    """Prepare (all input checks happen here, before any draw) and run the Monte Carlo.

    ``model="cpa"`` draws capture -> CPA around ``true_parameters`` (default: nominal), the thesis's
    study; ``model="refined"`` draws capture -> CPA -> refinement (``criterion``), the deployed model.
    ``progress(done, total)`` is called after every block when given. With a ``renderer`` (whose worker
    will draw the histograms, :func:`write_uncertainty_folder`), its worker makes the histogram pages
    meanwhile (:data:`PREPARE_HISTOGRAMS`: the figures, their axes and ticks, the fonts), so that after
    the draws it draws only their data; the figures are the same. ``render`` does the same through a
    stage's render callable (:mod:`robotcal.pipeline.figures`; the run's figure worker).
    """
    from robotcal.uncertainty.montecarlo import run_monte_carlo
    from robotcal.workflow import scenario_monte_carlo

    problem = scenario_monte_carlo(scenario, true_parameters=true_parameters, model=model, criterion=criterion)
    if renderer is not None:
        renderer.submit(PREPARE_HISTOGRAMS, problem.identified, settings.coverage)  # its outcome: on wait()
    elif render is not None:
        render(PREPARE_HISTOGRAMS, problem.identified, settings.coverage)  # a run collects it with its figures
    return run_monte_carlo(problem, settings, seed=seed, progress=progress)


def write_uncertainty_folder(
    folder: Path,
    result: MonteCarloResult,
    scenario: Scenario,
    *,
    save_draws: bool,
    renderer: FigureRenderer | None = None,
    meanwhile: Callable[[], object] | None = None,
    figures: bool = True,
) -> dict[str, Document]:
    """Write ``parameters.csv``, ``parameters.json``, the histograms (with ``figures``) and (optionally)
    ``draws.npz`` into ``folder`` (an existing, normally temporary, folder). A run draws the histograms
    later, in the background, into the final folder (``render(HISTOGRAMS, result, folder)``).

    With a ``renderer`` (:class:`robotcal.plots.background.FigureRenderer`) the histograms are drawn by its
    worker while this process writes the other files, then calls ``meanwhile()`` (the command prints its
    summary then); without one, ``meanwhile()`` is called before the histograms are drawn here. The files
    are the same. This returns when every file is written, and on any exception (a figure's error, an
    interrupt) the renderer's unfinished jobs are stopped before it propagates: nothing writes into
    ``folder`` once this has returned or raised.

    Returns the documents by file name; the two parameter files are written by
    :mod:`robotcal.io.uncertainty_files` and read back once (:func:`robotcal.pipeline.folder.read_document`).
    """
    from robotcal.io.uncertainty_files import write_uncertainty_csv, write_uncertainty_json
    from robotcal.pipeline.folder import read_document
    from robotcal.workflow import versions

    job = renderer.submit(HISTOGRAMS, result, folder) if renderer is not None and figures else None  # meanwhile
    try:
        echo = {"name": scenario.name, "source": scenario.source, "settings": scenario.settings}
        write_uncertainty_csv(folder / "parameters.csv", result)
        write_uncertainty_json(folder / "parameters.json", result, scenario=echo, versions=versions())
        documents: dict[str, Document] = {
            name: read_document(folder, name) for name in ("parameters.csv", "parameters.json")
        }
        if save_draws:
            from robotcal.io.draws_npz import write_draws

            write_draws(
                folder / "draws.npz", result.robot, result.draws, result.identified, seed=result.seed, model=result.model
            )
            documents["draws.npz"] = folder / "draws.npz"
        if meanwhile is not None:
            meanwhile()
        if not figures:
            histograms = []
        elif job is None:
            from robotcal.plots.montecarlo import write_histograms  # matplotlib only when writing figures

            histograms = write_histograms(result, folder)
        else:
            histograms = job.result()
    except BaseException:
        if job is not None:
            renderer.cancel()  # no histogram is written into the folder after this
        raise
    for path in histograms:
        documents[Path(path).name] = Path(path)
    return documents
