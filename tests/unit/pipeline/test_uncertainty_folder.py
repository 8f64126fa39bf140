"""The uncertainty folder (robotcal.pipeline.uncertainty): the same files whether the histograms are drawn
here or by a figure worker, the summary callback's place, and a figure error or an interrupt that leaves
nothing writing into the folder."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

import robotcal.plots.montecarlo as histograms
from robotcal.errors import InputError
from robotcal.io import load_scenario
from robotcal.pipeline.uncertainty import write_uncertainty_folder
from robotcal.plots.background import FigureRenderer
from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo
from robotcal.workflow import scenario_monte_carlo

SCENARIO = "thesis-laser-tracker"
PATIENCE_S = 60.0


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(SCENARIO)


@pytest.fixture(scope="module")
def result(scenario):
    settings = MonteCarloSettings(iterations=400, block_size=400, batch_size=400)
    return run_monte_carlo(scenario_monte_carlo(scenario), settings, seed=11)


def _contents(folder: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir())}


@pytest.mark.parametrize("save_draws", [False, True])
def test_a_figure_worker_writes_the_same_folder(result, scenario, tmp_path, save_draws):
    here, worker = tmp_path / "here", tmp_path / "worker"
    here.mkdir()
    worker.mkdir()
    seen = {}

    def summary_here():
        seen["here"] = sorted(path.name for path in here.iterdir())

    def summary_worker():
        seen["worker"] = sorted(path.name for path in worker.iterdir() if not path.name.startswith("hist_"))

    expected = write_uncertainty_folder(here, result, scenario, save_draws=save_draws, meanwhile=summary_here)
    with FigureRenderer(preload=("robotcal.plots.montecarlo",)) as renderer:
        documents = write_uncertainty_folder(
            worker, result, scenario, save_draws=save_draws, renderer=renderer, meanwhile=summary_worker
        )
    assert list(documents) == list(expected)
    assert _contents(worker) == _contents(here)
    names = set(_contents(here))
    assert {"parameters.csv", "parameters.json"} <= names and sum(n.startswith("hist_J") for n in names) >= 2
    assert ("draws.npz" in names) is save_draws
    # the summary comes once the other files are written, before the histograms are drawn here
    assert seen["here"] == seen["worker"] == sorted(n for n in names if not n.startswith("hist_"))


def _refuse(result, folder, **kwargs):
    raise InputError("cannot draw the histograms: no space left")


def _stall(result, folder, **kwargs):
    (Path(folder) / "drawing").write_text(str(os.getpid()))
    time.sleep(PATIENCE_S)


def test_a_figure_error_comes_out_of_the_folder_writer(result, scenario, tmp_path, monkeypatch):
    monkeypatch.setattr(histograms, "write_histograms", _refuse)  # before the fork: the worker has it too
    renderer = FigureRenderer(preload=())
    with pytest.raises(InputError, match="no space left") as caught:
        write_uncertainty_folder(tmp_path, result, scenario, save_draws=False, renderer=renderer)
    renderer.close()
    assert any("robotcal.plots.montecarlo.write_histograms" in note for note in caught.value.__notes__)
    assert not any(path.name.startswith("hist_") for path in tmp_path.iterdir())


def test_an_interrupt_while_the_figures_draw_stops_them(result, scenario, tmp_path, monkeypatch):
    monkeypatch.setattr(histograms, "write_histograms", _stall)
    renderer = FigureRenderer(preload=())

    def interrupted():
        deadline = time.monotonic() + PATIENCE_S
        while not (tmp_path / "drawing").exists():  # the figure job is under way
            assert time.monotonic() < deadline
            time.sleep(0.02)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_uncertainty_folder(tmp_path, result, scenario, save_draws=False, renderer=renderer, meanwhile=interrupted)
    worker = int((tmp_path / "drawing").read_text())
    assert renderer._worker is None  # stopped before the interrupt went on
    with pytest.raises(ProcessLookupError):
        os.kill(worker, 0)  # reaped: nothing writes into the folder any more
    renderer.close()
