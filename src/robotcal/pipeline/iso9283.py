"""The ``iso9283`` stage of a run: a simulated ISO 9283 pose test of the scenario's true robot.

The true robot with the scenario's joint error model (eq. 5-2 and backlash) and instrument noise visits
the standard's five test poses for :data:`ISO_CYCLES` cycles, measured on three flange targets
(:data:`ISO_TARGETS_MM`), and the nominal, CPA and refined models are evaluated side by side: pose
accuracy AP (APx/y/z), repeatability RP, orientation APa..c / RPa..c, distance accuracy AD and
repeatability RD (robotcal.diagnostics.iso9283, docs/iso9283.md). It says what the calibration buys
in the terms of the standard a robot's data sheet uses.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robotcal.diagnostics.iso9283 import ISO_CYCLES, simulate_iso_study
from robotcal.io.atomic import atomic_directory
from robotcal.io.iso9283_files import iso_to_csv
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline.figures import Render, draw_now
from robotcal.pipeline.folder import write_csv, write_json

__all__ = ["ISO_TARGETS_MM", "iso9283_stage"]

#: Three flange targets (a typical adapter plate) measured at each test pose, so that the orientation
#: characteristics are measured too [mm].
ISO_TARGETS_MM = {"A": (60.0, 40.0, 30.0), "B": (-50.0, 30.0, 20.0), "C": (0.0, -60.0, 40.0)}


def iso9283_stage(scenario, *, truth: ParameterSet, models: dict, seed: int, out: Path, render: Render = draw_now):
    """``iso9283/``: ``iso9283.csv`` (the ``robotcal iso9283`` columns), ``study.json`` (cube, start, cycles,
    targets, seed, models) and ``iso9283.png`` (drawn through ``render``, :mod:`robotcal.pipeline.figures`).
    Result: the :class:`IsoStudy`."""
    from robotcal.pipeline.stages import StageOutput

    study = simulate_iso_study(
        scenario, models, cycles=ISO_CYCLES, seed=seed, true_parameters=truth, targets_mm=ISO_TARGETS_MM
    )
    summary = {
        "method": (
            "simulated ISO 9283 pose test: the scenario's true robot with its joint error model and instrument "
            "noise visits P1..P5 (one unmeasured warm-up cycle); each model's commanded pose is its forward "
            "kinematics at the commanded readings (docs/iso9283.md)"
        ),
        "models": list(models),
        "cycles": ISO_CYCLES,
        "seed": seed,
        "cube": {"center_mm": study.center_mm.tolist(), "side_mm": float(study.side_mm)},
        "start_deg": np.rad2deg(study.start_readings).tolist(),
        "point_mm": study.point_mm.tolist(),
        "targets_mm": {name: np.asarray(value, dtype=float).tolist() for name, value in study.targets_mm.items()},
        "units": {"AP, RP, AD, RD, l_bar, S_l": "mm", "APa..c, RPa..c": "deg"},
    }
    with atomic_directory(out / "iso9283") as folder:
        documents = {
            "iso9283/iso9283.csv": write_csv(folder / "iso9283.csv", iso_to_csv(study.results)),
            "iso9283/study.json": write_json(folder / "study.json", summary),
        }
    drawn = render("robotcal.plots.iso9283:plot_iso_results", study.results, out / "iso9283" / "iso9283.png")
    worst = {model: float(np.max(r.ap)) * 1e3 for model, r in study.results.items()}
    detail = "max AP " + ", ".join(f"{model} {value:.0f} um" for model, value in worst.items())
    return StageOutput(study, documents, detail, figures=(drawn,))
