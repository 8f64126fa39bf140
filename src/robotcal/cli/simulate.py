"""``robotcal simulate SCENARIO --out CAPTURE.csv``: a synthetic Circle Point capture."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli import app
from robotcal.cli._common import console, handle_errors
from robotcal.io import load_scenario, read_parameters, write_capture
from robotcal.workflow import simulate_scenario


@app.command()
@handle_errors
def simulate(
    scenario: Annotated[str, typer.Argument(help="Built-in scenario name or scenario TOML path.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Capture CSV to write.")],
    seed: Annotated[
        int | None, typer.Option(min=0, help="Seed of the noise generator (default: the scenario's capture.seed).")
    ] = None,
    true_params: Annotated[
        Path | None, typer.Option("--true-params", help="Parameter JSON of the 'real' robot (default: nominal).")
    ] = None,
) -> None:
    """Simulate the scenario's capture and write it as a capture CSV."""
    loaded = load_scenario(scenario)
    truth = read_parameters(true_params, loaded.robot) if true_params is not None else None
    run = simulate_scenario(loaded, seed=seed, true_parameters=truth)
    write_capture(out, run.capture)
    console.print(
        f"wrote {out}: {run.capture.n_points} points in {loaded.robot.n_joints} circles "
        f"(scenario {loaded.name}, instrument {loaded.instrument.name}, noise {loaded.instrument.noise}, seed {run.seed})",
        highlight=False,
    )
