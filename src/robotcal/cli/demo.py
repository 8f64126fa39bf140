"""``robotcal demo``: ``robotcal run`` on the built-in ``kr5-demo`` scenario (a perturbed "true" robot)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import Force, app_command, command_app
from robotcal.cli.run import RUN_SEED_MAX, _command_line, run_and_print

app = command_app()

DEMO_SCENARIO = "kr5-demo"


@app_command(app)
def demo(
    out: Annotated[Path, typer.Option("--out", "-o", help="Run folder for the demo's files.")] = Path("robotcal-demo"),
    seed: Annotated[
        int | None, typer.Option(min=0, max=RUN_SEED_MAX, help="Seed of the whole run (default: the scenario's seeds).")
    ] = None,
    draws: Annotated[
        int | None, typer.Option("--draws", min=1, help="Monte Carlo draws (default: 100,000, the scenario's).")
    ] = None,
    force: Force = False,
) -> None:
    """The whole calibration of a simulated KUKA KR 5 sixx R650 with a perturbed "true" robot: writes
    OUT/report.html (run `robotcal run kr5-demo --out OUT`)."""
    from robotcal.pipeline.plan import plan_run

    command = _command_line("demo", out=out, seed=seed, draws=draws)
    run_and_print(plan_run(DEMO_SCENARIO, out, seed=seed, draws=draws, command=command, force=force))
