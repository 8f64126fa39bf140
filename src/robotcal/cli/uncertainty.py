"""``robotcal uncertainty SCENARIO --out DIR``: GUM Supplement 1 Monte Carlo of the calibration;
``robotcal uncertainty --capture CAPTURE.csv --params REFINED.json --scenario S --out DIR``: of the
refinement of a measured capture (:mod:`robotcal.uncertainty.measured`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from robotcal.cli._common import (
    FORCE_HELP,
    SEED_BOUND,
    _line,
    app_command,
    check_memory,
    command_app,
    console,
    monte_carlo_bytes,
    progress_bar,
    seed_option_check,
    styled,
)
from robotcal.errors import InputError

if TYPE_CHECKING:
    from robotcal.cli._tables import FittedTable
    from robotcal.uncertainty.montecarlo import MonteCarloResult

app = command_app()

__all__ = ["uncertainty", "uncertainty_table"]

#: Draws of ``--capture`` without ``-n``: each draw is a full refinement (docs/uncertainty.md).
MEASURED_DEFAULT_DRAWS = 300


def _model_name(result: MonteCarloResult) -> str:
    if result.model == "refined":
        return f"refined model (CPA + {result.criterion} refinement)"
    if result.model == "cpa":
        return "CPA model"
    from robotcal.uncertainty.measured import MODEL as MEASURED_MODEL  # scipy: only for a measured capture's result

    if result.model == MEASURED_MODEL:
        return f"measured capture ({result.criterion} refinement, noise from each point's U(95))"
    return "CPA model"


def uncertainty_table(result: MonteCarloResult) -> FittedTable:
    """Identified parameters: mean, u, interval, linearised u and the JCGM 101 §8 verdict. In a narrow
    console the verdict, the linearised u and then the nominal value are left out (parameters.csv has them;
    the line under the table counts the verdicts)."""
    from robotcal.cli._tables import Column, FittedTable
    from robotcal.io.results.uncertainty_files import uncertainty_rows

    coverage = f"{result.settings.coverage:.0%}"
    rows = [row for row in uncertainty_rows(result) if row["identified"]]
    linearised = any("lpu_std_uncertainty" in row for row in rows)  # none for the refined model
    columns = [
        Column("parameter", "name"),
        Column("unit", "name"),
        Column("nominal", narrow=3),
        Column("mean"),
        Column("u"),
        Column(f"{coverage} low"),
        Column(f"{coverage} high"),
    ]
    if linearised:
        columns += [Column("u (GUM)", narrow=2), Column("§8", "name", narrow=1)]
    table = FittedTable(
        f"Monte Carlo uncertainty, {_model_name(result)} ({result.n_draws:,} draws, seed {result.seed}, {result.settings.interval} {coverage} interval)",
        columns,
        elsewhere="parameters.csv",
    )
    for row in rows:
        cells = [
            row["name"],
            row["unit"],
            f"{row['nominal']:.4f}",
            f"{row['mean']:.5f}",
            f"{row['std_uncertainty']:.2e}",
            f"{row['coverage_low']:.5f}",
            f"{row['coverage_high']:.5f}",
        ]
        if linearised:
            agrees = row.get("lpu_agrees")
            verdict = "" if agrees is None else (styled("agrees", "green") if agrees else styled("differs", "yellow"))
            cells += [f"{row['lpu_std_uncertainty']:.2e}" if "lpu_std_uncertainty" in row else "", verdict]
        table.add_row(*cells)
    return table


# The command's arguments and options (typer reads them from these annotations).
ScenarioArgument = Annotated[
    str | None, typer.Argument(help="Built-in scenario name or scenario TOML path (or --scenario).")
]
OutOption = Annotated[Path | None, typer.Option("--out", "-o", help="Result folder to write (replaced if it exists).")]
IterationsOption = Annotated[
    int | None,
    typer.Option(
        "--iterations",
        "-n",
        help="Number of draws (default: the scenario's montecarlo.iterations; with --capture, 300).",
    ),
]
AdaptiveOption = Annotated[
    bool, typer.Option("--adaptive", help="JCGM 101 §7.9 adaptive mode: blocks of 10^4 draws until stable.")
]
NdigOption = Annotated[int, typer.Option(help="Adaptive mode: significant digits of u that must be stable.")]
MaxDrawsOption = Annotated[int, typer.Option("--max-draws", help="Adaptive mode: upper limit of draws.")]
SeedOption = Annotated[
    int | None,
    typer.Option(
        min=0,
        max=SEED_BOUND - 1,
        help="Seed (default: the scenario's montecarlo.seed, else fresh entropy; recorded).",
    ),
]
CoverageOption = Annotated[
    float | None, typer.Option(help="Coverage probability in (0, 1) (default: the scenario's, 0.95).")
]
IntervalOption = Annotated[str, typer.Option(help="Interval reported as coverage_low/high: symmetric | shortest.")]
BatchSizeOption = Annotated[int, typer.Option("--batch-size", help="Draws per vectorised CPA call (bounds memory).")]
WorkersOption = Annotated[
    int | None, typer.Option(help="Parallel worker processes (default: the CPU count, at most 4).")
]
SaveDrawsOption = Annotated[bool, typer.Option("--save-draws", help="Also write every draw to draws.npz.")]
TrueParamsOption = Annotated[
    Path | None,
    typer.Option("--true-params", help="Parameter JSON of the 'real' robot to simulate (default: nominal)."),
]
ForceOption = Annotated[bool, typer.Option("--force", help=FORCE_HELP)]
ModelOption = Annotated[
    str,
    typer.Option(
        "--model",
        help="What each draw computes: cpa (capture -> CPA, the thesis's study) | refined (capture -> CPA -> "
        "refinement, the deployed parameters).",
    ),
]
CriterionOption = Annotated[
    str | None,
    typer.Option(
        "--criterion",
        help="Refinement objective of --model refined or --capture: points | distances (default: points; with "
        "--capture, the one recorded in --params).",
    ),
]
SchedulerOption = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        help="Dask scheduler address (tcp://host:8786) to run the blocks on (default: ROBOTCAL_SCHEDULER, "
        "else local worker processes). Needs robotcal[distributed].",
    ),
]
ScenarioOption = Annotated[
    str | None, typer.Option("--scenario", "-s", help="Scenario name or TOML (instead of the argument).")
]
CaptureOption = Annotated[
    Path | None,
    typer.Option(
        "--capture",
        help="Monte Carlo of this measured capture (with --params): its poses and targets are simulated on the "
        "refined parameters, each point's noise drawn from its U(95) (k = 2, normal; else the instrument's), and "
        "refined again, draw after draw.",
    ),
]
ParamsOption = Annotated[
    Path | None,
    typer.Option("--params", help="With --capture: the parameter JSON `robotcal refine` wrote for that capture."),
]
PosesOption = Annotated[
    Path | None,
    typer.Option(
        "--poses",
        help="--model refined: the calibration poses (capture CSV on one flange target) refined with the circles "
        "(default: the scenario's [calibration_poses], if any).",
    ),
]


@app_command(app)
def uncertainty(
    scenario: ScenarioArgument = None,
    out: OutOption = None,
    iterations: IterationsOption = None,
    adaptive: AdaptiveOption = False,
    ndig: NdigOption = 2,
    max_draws: MaxDrawsOption = 2_000_000,
    seed: SeedOption = None,
    coverage: CoverageOption = None,
    interval: IntervalOption = "symmetric",
    batch_size: BatchSizeOption = 2_000,
    workers: WorkersOption = None,
    save_draws: SaveDrawsOption = False,
    true_params: TrueParamsOption = None,
    force: ForceOption = False,
    model: ModelOption = "cpa",
    criterion: CriterionOption = None,
    scheduler: SchedulerOption = None,
    scenario_option: ScenarioOption = None,
    capture: CaptureOption = None,
    params: ParamsOption = None,
    poses: PosesOption = None,
) -> None:
    """Monte Carlo (GUM Supplement 1) uncertainty of the CPA or refined parameters, with the linearised comparison;
    with --capture and --params, of the refinement of a measured capture."""
    if scenario is not None and scenario_option is not None and scenario != scenario_option:
        raise InputError(f"two scenarios given: {scenario!r} and --scenario {scenario_option!r}; give one")
    scenario = scenario if scenario is not None else scenario_option
    if scenario is None:
        raise InputError("which scenario? give it as the argument or with --scenario")
    if out is None:
        raise InputError("--out is required: the result folder to write")
    if model not in ("cpa", "refined"):
        raise InputError(f"--model must be one of cpa, refined; got {model!r}")
    if criterion is not None and criterion not in ("points", "distances"):
        raise InputError(f"--criterion must be one of points, distances; got {criterion!r}")
    workers = min(os.cpu_count() or 1, 4) if workers is None else workers
    if capture is not None or params is not None:
        if capture is None or params is None:
            raise InputError("--capture and --params go together: the measured capture and its refined parameter JSON")
        if model != "cpa" or adaptive or true_params is not None or poses is not None:
            raise InputError("--capture does not combine with --model, --adaptive, --true-params or --poses")
        _measured(
            scenario, capture, params, out, iterations=iterations, seed=seed, coverage=coverage, interval=interval,
            workers=workers, scheduler=scheduler, save_draws=save_draws, criterion=criterion, force=force,
        )  # fmt: skip
        return
    _simulated(
        scenario, out, iterations=iterations, adaptive=adaptive, ndig=ndig, max_draws=max_draws, seed=seed,
        coverage=coverage, interval=interval, batch_size=batch_size, workers=workers, save_draws=save_draws,
        true_params=true_params, force=force, model=model, criterion=criterion or "points", scheduler=scheduler,
        poses=poses,
    )  # fmt: skip


def _simulated(scenario: str, out: Path, *, iterations, adaptive, ndig, max_draws, seed, coverage, interval, batch_size,
               workers, save_draws, true_params, force, model, criterion, scheduler, poses) -> None:  # fmt: skip
    """``robotcal uncertainty SCENARIO --out DIR``: the scenario's Monte Carlo, its folder and its summary."""
    from robotcal import api
    from robotcal.io.formats.parameters_json import read_parameters
    from robotcal.io.results.output import check_output_folder, existing_inputs, result_folder
    from robotcal.io.results.uncertainty_files import write_uncertainty_folder
    from robotcal.io.schema.scenario import load_scenario
    from robotcal.pipeline.figures import draw_histograms
    from robotcal.plots.montecarlo import write_histograms
    from robotcal.uncertainty.montecarlo import MonteCarloSettings

    if poses is not None and model != "refined":
        raise InputError("--poses are refined with the circles: give --model refined")
    inputs = existing_inputs(scenario, true_params, poses)
    check_output_folder(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    table = loaded.montecarlo
    settings = MonteCarloSettings(
        iterations=table.iterations if iterations is None else iterations,
        coverage=table.coverage if coverage is None else coverage,
        interval=interval,
        adaptive=adaptive,
        ndig=ndig,
        max_draws=max_draws,
        batch_size=batch_size,
        workers=workers,
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
    run_seed = api.seed_from(seed, table.seed)
    seed_option_check(run_seed, f"{loaded.source}: key `montecarlo.seed`")  # checked before any draw
    with progress_bar("Monte Carlo", "draws") as display:
        task = display.add_task("draws", total=None if settings.adaptive else settings.iterations)
        result = api.monte_carlo(
            loaded, settings=settings, parameters=truth, model=model, criterion=criterion, poses=poses, rng=run_seed,
            progress=lambda done, expected: display.update(task, completed=done, total=expected),
        )  # fmt: skip
    with result_folder(out, inputs=inputs, force=force, command="robotcal uncertainty") as folder:
        draw_histograms(
            result,
            folder,
            workers=settings.workers,
            write_files=lambda: write_uncertainty_folder(folder, result, scenario=loaded, save_draws=save_draws),
            plot=write_histograms,
        )
    _print_summary(result, settings, out)


def _print_summary(result: MonteCarloResult, settings, out: Path) -> None:
    """The table, the draws' rate, the JCGM 101 §8 verdict and the folder written."""
    import numpy as np

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


def _parameter_document(path: Path) -> dict:
    """The parameter JSON as a dict for its ``robot`` and ``provenance`` keys ({} if unreadable: then
    :func:`read_parameters` reports the problem)."""
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return document if isinstance(document, dict) else {}


def _checked_parameters(params: Path, capture: Path, loaded, measured, criterion):
    """The parameter JSON's estimate, provenance and criterion, checked against the scenario and the capture."""
    from robotcal.io.formats.parameters_json import read_parameters

    document = _parameter_document(params)
    recorded_robot = document.get("robot")
    if isinstance(recorded_robot, str) and recorded_robot != loaded.robot.name:
        raise InputError(
            f"{params}: parameters of robot {recorded_robot!r}, but the scenario's robot is {loaded.robot.name!r}: "
            "give the parameter JSON that `robotcal refine` wrote for this capture and scenario"
        )
    estimate = read_parameters(params, loaded.robot)
    provenance = document.get("provenance")
    if not isinstance(provenance, dict):
        provenance = {}
    points = provenance.get("points")
    if isinstance(points, int) and points != measured.n_points:
        raise InputError(
            f"{params}: refined on a capture of {points} points, but {capture} has {measured.n_points}: "
            "give the capture the parameters were refined on"
        )
    recorded = provenance.get("criterion")
    if criterion is None:
        criterion = recorded if recorded in ("points", "distances") else "points"
    elif recorded in ("points", "distances") and recorded != criterion:
        raise InputError(
            f"{params} was refined with the {recorded} criterion; --criterion {criterion} would repeat another "
            "refinement than the one the parameters come from"
        )
    return estimate, provenance, criterion


def _measured(scenario: str, capture: Path, params: Path, out: Path, *, iterations, seed, coverage, interval, workers,
              scheduler, save_draws, criterion, force) -> None:  # fmt: skip
    """``robotcal uncertainty --capture CAPTURE.csv --params REFINED.json --scenario S --out DIR``."""
    from robotcal import api
    from robotcal.cli._tables import Column, FittedTable
    from robotcal.io.formats.capture_csv import read_capture
    from robotcal.io.formats.parameters_json import read_targets
    from robotcal.io.results.output import check_output_folder, existing_inputs, result_folder
    from robotcal.io.results.uncertainty_files import measured_target_rows, write_measured_folder
    from robotcal.io.schema.scenario import load_scenario
    from robotcal.pipeline.figures import draw_histograms
    from robotcal.plots.montecarlo import write_histograms

    inputs = existing_inputs(scenario, capture, params)
    check_output_folder(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    estimate, provenance, criterion = _checked_parameters(params, capture, loaded, measured, criterion)
    run_seed = api.seed_from(seed, loaded.montecarlo.seed)
    seed_option_check(run_seed, f"{loaded.source}: key `montecarlo.seed`")
    draws = MEASURED_DEFAULT_DRAWS if iterations is None else iterations
    with progress_bar("Monte Carlo of the capture", "draws") as display:
        task = display.add_task("draws", total=draws)
        result = api.measured_monte_carlo(
            measured,
            loaded,
            estimate,
            draws=draws,
            rng=run_seed,
            coverage=loaded.montecarlo.coverage if coverage is None else coverage,
            interval=interval,
            workers=workers,
            scheduler=scheduler,
            criterion=criterion,
            offsets=read_targets(params),
            estimate_base=provenance.get("base_frame") == "estimated" and loaded.identification.base_frame == "given",
            weights="none" if provenance.get("weights") == "equal" else "auto",
            progress=lambda done, total: display.update(task, completed=done, total=total),
        )
    with result_folder(out, inputs=inputs, force=force, command="robotcal uncertainty --capture") as folder:
        draw_histograms(result.parameters, folder, workers=workers, write_files=lambda: write_measured_folder(
            folder, result, scenario=loaded, capture=str(capture), params=str(params), n_points=measured.n_points,
            save_draws=save_draws,
        ), plot=write_histograms)  # fmt: skip
    console.print(uncertainty_table(result.parameters))
    if result.target_summary is not None:
        headers = ("estimate", "mean", "u", "u (refine)")
        offsets = FittedTable(
            "Estimated target offsets [mm]",
            [Column("target", "name"), Column("axis", "name"), *(Column(header) for header in headers)],
        )
        for row in measured_target_rows(result):
            offsets.add_row(
                row["name"], row["axis"], f"{row['estimate']:.4f}", f"{row['mean']:.4f}",
                f"{row['std_uncertainty']:.2e}", f"{row['lpu_std_uncertainty']:.2e}",
            )  # fmt: skip
        console.print(offsets)
    timings = result.parameters.timings_s
    console.print(
        f"{result.parameters.message}; noise: {result.noise_source}; {timings['draws']:.2f} s for the draws "
        f"({timings['per_draw'] * workers:.3f} s per draw and worker, {workers} worker(s))",
        highlight=False,
    )
    console.print(f"wrote {out}", highlight=False)
