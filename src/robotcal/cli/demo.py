"""``robotcal demo``: the thesis laser-tracker scenario end to end (simulate, identify, table)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from robotcal.cli import app
from robotcal.cli._common import circle_table, console, handle_errors, parameter_table
from robotcal.io import load_scenario, write_capture, write_parameters
from robotcal.kinematics.model import ParameterSet
from robotcal.workflow import cpa_provenance, identify_scenario, simulate_scenario

DEMO_SCENARIO = "thesis-laser-tracker"


@app.command()
@handle_errors
def demo(
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for the demo's files.")] = Path("robotcal-demo"),
    seed: Annotated[int | None, typer.Option(min=0, help="Seed of the simulated measurement noise.")] = None,
) -> None:
    """Simulate the thesis laser-tracker capture of the KUKA KR 5 sixx R650 and identify it by CPA."""
    started = time.perf_counter()
    scenario = load_scenario(DEMO_SCENARIO)
    console.rule(f"robotcal demo: {scenario.description}")
    run = simulate_scenario(scenario, seed=seed)
    capture_path = write_capture(out / "capture.csv", run.capture)
    result = identify_scenario(run.capture, scenario)
    params_path = write_parameters(
        out / "parameters.json", result.parameters, cpa_provenance(result, run.capture, scenario)
    )
    nominal = ParameterSet.nominal(scenario.robot)
    console.print(
        parameter_table(nominal, result.parameters, "Nominal (Table 3.1) vs identified by CPA from the noisy capture")
    )
    console.print(circle_table(result))
    difference = np.abs(result.parameters.difference(nominal))
    identified = result.parameters.identified
    is_length = np.zeros_like(identified)
    is_length[:, [0, 2]] = True
    console.print(
        f"instrument {scenario.instrument.name}: U(L) = {scenario.instrument.a_mm * 1e3:g} um + "
        f"{scenario.instrument.b_mm_per_m * 1e3:g} um/m, {scenario.instrument.noise} noise, seed {run.seed}",
        highlight=False,
    )
    console.print(
        f"{int(identified.sum())} parameters identified. The simulated robot is nominal, so every difference is the "
        f"effect of measurement noise: largest {difference[identified & is_length].max():.4f} mm and "
        f"{np.rad2deg(difference[identified & ~is_length].max()):.4f} deg.",
        highlight=False,
    )
    console.print(f"wrote {capture_path} and {params_path} in {time.perf_counter() - started:.1f} s", highlight=False)
