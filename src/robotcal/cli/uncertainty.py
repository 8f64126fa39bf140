"""``robotcal uncertainty SCENARIO --out DIR``: GUM Supplement 1 Monte Carlo of the calibration."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table

from robotcal.cli._common import (
    FORCE_HELP,
    SEED_BOUND,
    _line,
    check_memory,
    command_app,
    console,
    handle_errors,
    monte_carlo_bytes,
    seed_option_check,
    styled,
)
from robotcal.errors import InputError
from robotcal.identification.refine import CRITERIA
from robotcal.io import load_scenario, read_parameters
from robotcal.io.output import check_output_folder, existing_inputs, result_folder
from robotcal.io.scenario import Scenario
from robotcal.io.uncertainty_files import uncertainty_rows
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline.uncertainty import compute_uncertainty as run_uncertainty
from robotcal.pipeline.uncertainty import write_uncertainty_folder
from robotcal.uncertainty.montecarlo import (
    MODELS,
    MonteCarloResult,
    MonteCarloSettings,
    ProgressCallback,
)
from robotcal.workflow import resolve_seed

app = command_app()

__all__ = ["uncertainty", "compute_uncertainty", "write_uncertainty_folder", "uncertainty_table"]


def compute_uncertainty(
    scenario: Scenario,
    settings: MonteCarloSettings,
    *,
    seed: int,
    true_parameters: ParameterSet | None = None,
    show_progress: bool = True,
    progress: ProgressCallback | None = None,
    model: str = "cpa",
    criterion: str = "points",
) -> MonteCarloResult:
    """:func:`robotcal.pipeline.uncertainty.compute_uncertainty` with a progress bar of its own when
    ``show_progress`` and no ``progress`` callback is given."""
    if progress is not None or not show_progress:
        return run_uncertainty(
            scenario, settings, seed=seed, true_parameters=true_parameters, progress=progress, model=model,
            criterion=criterion,
        )  # fmt: skip
    total = None if settings.adaptive else settings.iterations
    with Progress(
        TextColumn("Monte Carlo"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("draws"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=console,
        transient=True,
    ) as display:
        task = display.add_task("draws", total=total)

        def report(done: int, expected: int | None) -> None:
            display.update(task, completed=done, total=expected)

        return run_uncertainty(
            scenario, settings, seed=seed, true_parameters=true_parameters, progress=report, model=model,
            criterion=criterion,
        )  # fmt: skip


def _model_name(result: MonteCarloResult) -> str:
    if result.model == "refined":
        return f"refined model (CPA + {result.criterion} refinement)"
    return "CPA model"


def uncertainty_table(result: MonteCarloResult) -> Table:
    """Identified parameters: mean, u, interval, linearised u and the JCGM 101 §8 verdict."""
    coverage = f"{result.settings.coverage:.0%}"
    table = Table(
        title=f"Monte Carlo uncertainty, {_model_name(result)} ({result.n_draws:,} draws, seed {result.seed}, {result.settings.interval} {coverage} interval)",
        title_justify="left",
    )
    for column in ("parameter", "unit", "nominal", "mean", "u", f"{coverage} low", f"{coverage} high", "u (GUM)", "§8"):
        # fold rather than truncate in a narrow terminal: a number cut to "335.0…" would mislead
        table.add_column(column, justify="left" if column in ("parameter", "unit") else "right", overflow="fold")
    for row in uncertainty_rows(result):
        if not row["identified"]:
            continue
        agrees = row.get("lpu_agrees")
        verdict = "" if agrees is None else (styled("agrees", "green") if agrees else styled("differs", "yellow"))
        table.add_row(
            row["name"],
            row["unit"],
            f"{row['nominal']:.4f}",
            f"{row['mean']:.5f}",
            f"{row['std_uncertainty']:.2e}",
            f"{row['coverage_low']:.5f}",
            f"{row['coverage_high']:.5f}",
            f"{row['lpu_std_uncertainty']:.2e}" if "lpu_std_uncertainty" in row else "",
            verdict,
        )
    return table


@app.command()
@handle_errors
def uncertainty(
    scenario: Annotated[str, typer.Argument(help="Built-in scenario name or scenario TOML path.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Result folder to write (replaced if it exists).")],
    iterations: Annotated[
        int | None,
        typer.Option("--iterations", "-n", help="Number of draws (default: the scenario's montecarlo.iterations)."),
    ] = None,
    adaptive: Annotated[
        bool, typer.Option("--adaptive", help="JCGM 101 §7.9 adaptive mode: blocks of 10^4 draws until stable.")
    ] = False,
    ndig: Annotated[int, typer.Option(help="Adaptive mode: significant digits of u that must be stable.")] = 2,
    max_draws: Annotated[int, typer.Option("--max-draws", help="Adaptive mode: upper limit of draws.")] = 2_000_000,
    seed: Annotated[
        int | None,
        typer.Option(
            min=0,
            max=SEED_BOUND - 1,
            help="Seed (default: the scenario's montecarlo.seed, else fresh entropy; recorded).",
        ),
    ] = None,
    coverage: Annotated[
        float | None, typer.Option(help="Coverage probability in (0, 1) (default: the scenario's, 0.95).")
    ] = None,
    interval: Annotated[
        str, typer.Option(help="Interval reported as coverage_low/high: symmetric | shortest.")
    ] = "symmetric",
    batch_size: Annotated[
        int, typer.Option("--batch-size", help="Draws per vectorised CPA call (bounds memory).")
    ] = 2_000,
    workers: Annotated[
        int | None, typer.Option(help="Parallel worker processes (default: the CPU count, at most 4).")
    ] = None,
    save_draws: Annotated[bool, typer.Option("--save-draws", help="Also write every draw to draws.npz.")] = False,
    true_params: Annotated[
        Path | None,
        typer.Option("--true-params", help="Parameter JSON of the 'real' robot to simulate (default: nominal)."),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
    model: Annotated[
        str,
        typer.Option(
            "--model",
            help="What each draw computes: cpa (capture -> CPA, the thesis's study) | refined (capture -> CPA -> "
            "refinement, the deployed parameters).",
        ),
    ] = "cpa",
    criterion: Annotated[
        str, typer.Option("--criterion", help="Refinement objective of --model refined: points | distances.")
    ] = "points",
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            help="Dask scheduler address (tcp://host:8786) to run the blocks on (default: ROBOTCAL_SCHEDULER, "
            "else local worker processes). Needs robotcal[distributed].",
        ),
    ] = None,
) -> None:
    """Monte Carlo (GUM Supplement 1) uncertainty of the CPA or refined parameters, with the linearised comparison."""
    if model not in MODELS:
        raise InputError(f"--model must be one of {', '.join(MODELS)}; got {model!r}")
    if criterion not in CRITERIA:
        raise InputError(f"--criterion must be one of {', '.join(CRITERIA)}; got {criterion!r}")
    inputs = existing_inputs(scenario, true_params)
    check_output_folder(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    table = loaded.montecarlo
    settings = MonteCarloSettings(
        iterations=int(table["iterations"]) if iterations is None else iterations,
        coverage=float(table["coverage"]) if coverage is None else coverage,
        interval=interval,
        adaptive=adaptive,
        ndig=ndig,
        max_draws=max_draws,
        batch_size=batch_size,
        workers=min(os.cpu_count() or 1, 4) if workers is None else workers,
        scheduler=scheduler,
    )
    n_draws = settings.max_draws if settings.adaptive else settings.iterations
    check_memory(
        f"a Monte Carlo of {n_draws:,} draws",
        monte_carlo_bytes(
            n_draws,
            loaded.robot.n_joints,
            int(loaded.plan.points.sum()) * (2 if loaded.plan.bidirectional else 1),
            batch_size=settings.batch_size,
            workers=settings.workers,
        ),
        "use fewer draws (--iterations, or --max-draws in adaptive mode) or a smaller --batch-size",
    )
    truth = read_parameters(true_params, loaded.robot) if true_params is not None else None
    run_seed = resolve_seed(seed, table.get("seed"))
    seed_option_check(run_seed, f"{loaded.source}: key `montecarlo.seed`")  # checked before any draw
    result = compute_uncertainty(
        loaded, settings, seed=run_seed, true_parameters=truth, model=model, criterion=criterion
    )
    with result_folder(out, inputs=inputs, force=force, command="robotcal uncertainty") as folder:
        write_uncertainty_folder(folder, result, loaded, save_draws=save_draws)
    console.print(uncertainty_table(result))
    timings = result.timings_s
    rate = result.n_draws / max(timings["draws"], 1e-9)
    console.print(
        f"{result.message}; {timings['draws']:.2f} s for the draws ({rate:,.0f} draws/s, {settings.workers} worker(s))",
        highlight=False,
    )
    if result.linearised is not None:
        differs = int(np.sum(~result.linearised.agrees & result.identified))
        console.print(
            f"linearised (GUM) vs Monte Carlo, JCGM 101 §8 with ndig = {settings.ndig}: "
            + (
                "all intervals agree"
                if differs == 0
                else f"{differs} parameter(s) differ: the Monte Carlo result stands"
            ),
            highlight=False,
        )
    if result.adaptive is not None and not result.adaptive.stable:
        console.print(_line("warning:", "yellow", result.adaptive.reason), highlight=False)
    console.print(f"wrote {out}", highlight=False)
