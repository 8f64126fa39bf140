"""``robotcal uncertainty SCENARIO --out DIR``: GUM Supplement 1 Monte Carlo of the calibration;
``robotcal uncertainty --capture CAPTURE.csv --params REFINED.json --scenario S --out DIR``: of the
refinement of a measured capture (:mod:`robotcal.uncertainty.measured`).

The histograms are drawn by a forked worker (:class:`robotcal.plots.background.FigureRenderer`) started
as soon as the options are checked and numpy is imported: it imports matplotlib while this process
imports the scenario files and the Monte Carlo engine (on the core that would otherwise be idle), makes the
histogram pages (figures, axes, ticks, fonts) while the draws run, and draws the figures while this process
writes the other files and prints its summary. The module itself
imports only the command line's own modules, so that the fork comes early.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from robotcal.cli._common import (
    FORCE_HELP,
    SEED_BOUND,
    _line,
    check_memory,
    command_app,
    handle_errors,
    monte_carlo_bytes,
    seed_option_check,
    styled,
)
from robotcal.errors import InputError
from robotcal.pipeline.uncertainty import compute_uncertainty as run_uncertainty
from robotcal.pipeline.uncertainty import write_uncertainty_folder

if TYPE_CHECKING:
    from rich.table import Table

    from robotcal.io.scenario import Scenario
    from robotcal.kinematics.model import ParameterSet
    from robotcal.plots.background import FigureRenderer
    from robotcal.uncertainty.montecarlo import MonteCarloResult, MonteCarloSettings, ProgressCallback

app = command_app()

__all__ = ["uncertainty", "compute_uncertainty", "write_uncertainty_folder", "uncertainty_table"]

#: Modules the figure worker imports while the draws run (the histograms' own and, through them, matplotlib).
FIGURE_MODULES = ("robotcal.plots.montecarlo",)


def _console():
    from robotcal.cli._common import console

    return console


def _progress(title: str):
    """A transient Rich progress bar ``title [bar] done/total draws elapsed remaining``."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn(title),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("draws"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=_console(),
        transient=True,
    )


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
    renderer: FigureRenderer | None = None,
) -> MonteCarloResult:
    """:func:`robotcal.pipeline.uncertainty.compute_uncertainty` with a progress bar of its own when
    ``show_progress`` and no ``progress`` callback is given."""
    if progress is not None or not show_progress:
        return run_uncertainty(
            scenario, settings, seed=seed, true_parameters=true_parameters, progress=progress, model=model,
            criterion=criterion, renderer=renderer,
        )  # fmt: skip
    total = None if settings.adaptive else settings.iterations
    with _progress("Monte Carlo") as display:
        task = display.add_task("draws", total=total)

        def report(done: int, expected: int | None) -> None:
            display.update(task, completed=done, total=expected)

        return run_uncertainty(
            scenario, settings, seed=seed, true_parameters=true_parameters, progress=report, model=model,
            criterion=criterion, renderer=renderer,
        )  # fmt: skip


def _model_name(result: MonteCarloResult) -> str:
    if result.model == "refined":
        return f"refined model (CPA + {result.criterion} refinement)"
    if result.model == "cpa":
        return "CPA model"
    from robotcal.uncertainty.measured import MODEL as MEASURED_MODEL  # scipy: only for a measured capture's result

    if result.model == MEASURED_MODEL:
        return f"measured capture ({result.criterion} refinement, noise from each point's U(95))"
    return "CPA model"


def uncertainty_table(result: MonteCarloResult) -> Table:
    """Identified parameters: mean, u, interval, linearised u and the JCGM 101 §8 verdict."""
    from rich.table import Table

    from robotcal.io.uncertainty_files import uncertainty_rows

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
    scenario: Annotated[
        str | None, typer.Argument(help="Built-in scenario name or scenario TOML path (or --scenario).")
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Result folder to write (replaced if it exists).")
    ] = None,
    iterations: Annotated[
        int | None,
        typer.Option(
            "--iterations",
            "-n",
            help="Number of draws (default: the scenario's montecarlo.iterations; with --capture, 300).",
        ),
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
        str | None,
        typer.Option(
            "--criterion",
            help="Refinement objective of --model refined or --capture: points | distances (default: points; with "
            "--capture, the one recorded in --params).",
        ),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            help="Dask scheduler address (tcp://host:8786) to run the blocks on (default: ROBOTCAL_SCHEDULER, "
            "else local worker processes). Needs robotcal[distributed].",
        ),
    ] = None,
    scenario_option: Annotated[
        str | None, typer.Option("--scenario", "-s", help="Scenario name or TOML (instead of the argument).")
    ] = None,
    capture: Annotated[
        Path | None,
        typer.Option(
            "--capture",
            help="Monte Carlo of this measured capture (with --params): its poses and targets are simulated on the "
            "refined parameters, each point's noise drawn from its U(95) (k = 2, normal; else the instrument's), and "
            "refined again, draw after draw.",
        ),
    ] = None,
    params: Annotated[
        Path | None,
        typer.Option("--params", help="With --capture: the parameter JSON `robotcal refine` wrote for that capture."),
    ] = None,
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
    if capture is not None or params is not None:
        if capture is None or params is None:
            raise InputError("--capture and --params go together: the measured capture and its refined parameter JSON")
        if model != "cpa" or adaptive or true_params is not None:
            raise InputError("--capture does not combine with --model, --adaptive or --true-params")
    import numpy  # noqa: F401  (before the fork: the figure worker inherits it instead of importing it again)

    from robotcal.plots.background import FigureRenderer

    # forked now: the worker imports matplotlib while this process imports the rest, then draws
    with FigureRenderer(preload=FIGURE_MODULES) as renderer:
        if capture is not None:
            _measured_capture_command(
                scenario, capture, params, out, iterations=iterations, seed=seed, coverage=coverage,
                interval=interval, workers=workers, scheduler=scheduler, save_draws=save_draws, criterion=criterion,
                force=force, renderer=renderer,
            )  # fmt: skip
            return
        _scenario_command(
            scenario, out, iterations=iterations, adaptive=adaptive, ndig=ndig, max_draws=max_draws, seed=seed,
            coverage=coverage, interval=interval, batch_size=batch_size, workers=workers, save_draws=save_draws,
            true_params=true_params, force=force, model=model, criterion=criterion, scheduler=scheduler,
            renderer=renderer,
        )  # fmt: skip


def _scenario_command(
    scenario: str,
    out: Path,
    *,
    iterations: int | None,
    adaptive: bool,
    ndig: int,
    max_draws: int,
    seed: int | None,
    coverage: float | None,
    interval: str,
    batch_size: int,
    workers: int | None,
    save_draws: bool,
    true_params: Path | None,
    force: bool,
    model: str,
    criterion: str | None,
    scheduler: str | None,
    renderer: FigureRenderer,
) -> None:
    """``robotcal uncertainty SCENARIO --out DIR``: the scenario's Monte Carlo, its folder and its summary."""
    import numpy as np

    from robotcal.io import load_scenario, read_parameters
    from robotcal.io.output import check_output_folder, existing_inputs, result_folder
    from robotcal.uncertainty.montecarlo import MODELS, MonteCarloSettings
    from robotcal.workflow import resolve_seed

    if model not in MODELS:
        raise InputError(f"--model must be one of {', '.join(MODELS)}; got {model!r}")
    if criterion is None:
        criterion = "points"  # the default: no need to import the refinement (scipy) to check it
    else:
        from robotcal.identification.refine import CRITERIA

        if criterion not in CRITERIA:
            raise InputError(f"--criterion must be one of {', '.join(CRITERIA)}; got {criterion!r}")
    inputs = existing_inputs(scenario, true_params)
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
        workers=min(os.cpu_count() or 1, 4) if workers is None else workers,
        scheduler=scheduler,
    )
    n_draws = settings.max_draws if settings.adaptive else settings.iterations
    # the figure worker's copy of the draws comes after the statistics' sorted copy, which the estimate counts
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
    run_seed = resolve_seed(seed, table.seed)
    seed_option_check(run_seed, f"{loaded.source}: key `montecarlo.seed`")  # checked before any draw
    result = compute_uncertainty(
        loaded, settings, seed=run_seed, true_parameters=truth, model=model, criterion=criterion, renderer=renderer
    )
    console = _console()

    def summary() -> None:  # printed while the figure worker draws the histograms
        console.print(uncertainty_table(result))
        timings = result.timings_s
        rate = result.n_draws / max(timings["draws"], 1e-9)
        console.print(
            f"{result.message}; {timings['draws']:.2f} s for the draws ({rate:,.0f} draws/s, "
            f"{settings.workers} worker(s))",
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

    with result_folder(out, inputs=inputs, force=force, command="robotcal uncertainty") as folder:
        write_uncertainty_folder(folder, result, loaded, save_draws=save_draws, renderer=renderer, meanwhile=summary)
    console.print(f"wrote {out}", highlight=False)


# ------------------------------------------------------------------ --capture: Monte Carlo of a measured capture

#: Draws of ``--capture`` without ``-n``: each draw is a full refinement (~0.1 s), see docs/uncertainty.md.
MEASURED_DEFAULT_DRAWS = 300
#: Columns of ``targets.csv`` (estimated flange offsets, mm).
TARGET_COLUMNS = (
    "name", "axis", "unit", "estimate", "mean", "std_uncertainty", "coverage_low", "coverage_high", "min", "max",
    "lpu_std_uncertainty",
)  # fmt: skip


def _parameter_document(path: Path) -> dict:
    """The parameter JSON as a dict for its ``robot`` and ``provenance`` keys ({} if unreadable: then
    :func:`read_parameters` reports the problem)."""
    import json

    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return document if isinstance(document, dict) else {}


def _measured_capture_command(
    scenario: str,
    capture: Path,
    params: Path,
    out: Path,
    *,
    iterations: int | None,
    seed: int | None,
    coverage: float | None,
    interval: str,
    workers: int | None,
    scheduler: str | None,
    save_draws: bool,
    criterion: str | None,
    force: bool,
    renderer: FigureRenderer | None = None,
) -> None:
    """``robotcal uncertainty --capture CAPTURE.csv --params REFINED.json --scenario S --out DIR``."""
    from rich.table import Table

    from robotcal.identification.refine import CRITERIA  # scipy: imported when this runs, not for --help
    from robotcal.io import load_scenario, read_capture, read_parameters
    from robotcal.io.output import check_output_folder, existing_inputs, result_folder
    from robotcal.io.parameters_json import read_targets
    from robotcal.uncertainty.measured import measured_monte_carlo
    from robotcal.uncertainty.montecarlo import MonteCarloSettings
    from robotcal.workflow import resolve_seed

    if criterion is not None and criterion not in CRITERIA:
        raise InputError(f"--criterion must be one of {', '.join(CRITERIA)}; got {criterion!r}")
    inputs = existing_inputs(scenario, capture, params)
    check_output_folder(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    document = _parameter_document(params)
    recorded_robot = document.get("robot")
    if isinstance(recorded_robot, str) and recorded_robot != loaded.robot.name:
        raise InputError(
            f"{params}: parameters of robot {recorded_robot!r}, but the scenario's robot is {loaded.robot.name!r}: "
            "give the parameter JSON that `robotcal refine` wrote for this capture and scenario"
        )
    estimate = read_parameters(params, loaded.robot)
    provenance = document.get("provenance") if isinstance(document.get("provenance"), dict) else {}
    points = provenance.get("points")
    if isinstance(points, int) and points != measured.n_points:
        raise InputError(
            f"{params}: refined on a capture of {points} points, but {capture} has {measured.n_points}: "
            "give the capture the parameters were refined on"
        )
    recorded = provenance.get("criterion")
    if criterion is None:
        criterion = recorded if recorded in CRITERIA else "points"
    elif recorded in CRITERIA and recorded != criterion:
        raise InputError(
            f"{params} was refined with the {recorded} criterion; --criterion {criterion} would repeat another "
            "refinement than the one the parameters come from"
        )
    weights = "none" if provenance.get("weights") == "equal" else "auto"
    estimate_base = provenance.get("base_frame") == "estimated" and loaded.identification.base_frame == "given"
    table = loaded.montecarlo
    settings = MonteCarloSettings(
        iterations=MEASURED_DEFAULT_DRAWS if iterations is None else iterations,
        coverage=table.coverage if coverage is None else coverage,
        interval=interval,
        workers=min(os.cpu_count() or 1, 4) if workers is None else workers,
        scheduler=scheduler,
    )
    run_seed = resolve_seed(seed, table.seed)
    seed_option_check(run_seed, f"{loaded.source}: key `montecarlo.seed`")
    with _progress("Monte Carlo of the capture") as display:
        task = display.add_task("draws", total=settings.iterations)
        result = measured_monte_carlo(
            measured,
            loaded,
            estimate,
            settings,
            seed=run_seed,
            criterion=criterion,
            targets=read_targets(params),
            estimate_base=estimate_base,
            weights=weights,
            progress=lambda done, total: display.update(task, completed=done, total=total),
        )
    echo = {"name": loaded.name, "source": loaded.source, "settings": loaded.settings}
    with result_folder(out, inputs=inputs, force=force, command="robotcal uncertainty --capture") as folder:
        _write_measured_folder(
            folder, result, echo, capture=str(capture), params=str(params), n_points=measured.n_points,
            save_draws=save_draws, renderer=renderer,
        )  # fmt: skip
    console = _console()
    console.print(uncertainty_table(result.parameters))
    if result.target_summary is not None:
        offsets = Table(title="Estimated target offsets [mm]", title_justify="left")
        for column in ("target", "axis", "estimate", "mean", "u", "u (refine)"):
            offsets.add_column(column, justify="left" if column in ("target", "axis") else "right")
        for row in _target_rows(result):
            offsets.add_row(
                row["name"], row["axis"], f"{row['estimate']:.4f}", f"{row['mean']:.4f}",
                f"{row['std_uncertainty']:.2e}", f"{row['lpu_std_uncertainty']:.2e}",
            )  # fmt: skip
        console.print(offsets)
    timings = result.parameters.timings_s
    console.print(
        f"{result.parameters.message}; noise: {result.noise_source}; {timings['draws']:.2f} s for the draws "
        f"({timings['per_draw'] * settings.workers:.3f} s per draw and worker, {settings.workers} worker(s))",
        highlight=False,
    )
    console.print(f"wrote {out}", highlight=False)


def _target_rows(result) -> list[dict]:
    """One dict per estimated offset component (mm)."""
    import numpy as np

    rows = []
    summary = result.target_summary
    if summary is None:
        return rows
    low, high = summary.interval(result.parameters.settings.interval)
    for t, name in enumerate(result.target_names):
        for a, axis in enumerate("xyz"):
            lpu = result.target_linearised_u[t, a]
            rows.append(
                {
                    "name": name,
                    "axis": axis,
                    "unit": "mm",
                    "estimate": float(result.target_estimate[t, a]),
                    "mean": float(summary.mean[t, a]),
                    "std_uncertainty": float(summary.std_uncertainty[t, a]),
                    "coverage_low": float(low[t, a]),
                    "coverage_high": float(high[t, a]),
                    "min": float(summary.minimum[t, a]),
                    "max": float(summary.maximum[t, a]),
                    "lpu_std_uncertainty": float(lpu) if np.isfinite(lpu) else None,
                }
            )
    return rows


def _write_measured_folder(
    folder: Path,
    result,
    echo: dict,
    *,
    capture: str,
    params: str,
    n_points: int,
    save_draws: bool,
    renderer: FigureRenderer | None = None,
) -> None:
    """``parameters.csv``, ``parameters.json`` (``model: "measured capture"``), ``targets.csv``, the
    histograms (drawn by ``renderer`` meanwhile, when given) and (``save_draws``) ``draws.npz`` (mm, deg)."""
    from robotcal.pipeline.uncertainty import HISTOGRAMS

    figures = None if renderer is None else renderer.submit(HISTOGRAMS, result.parameters, folder)
    try:
        _write_measured_files(folder, result, echo, capture=capture, params=params, n_points=n_points,
                              save_draws=save_draws)  # fmt: skip
        if figures is None:
            from robotcal.plots.montecarlo import write_histograms

            write_histograms(result.parameters, folder)
        else:
            figures.result()
    except BaseException:
        if figures is not None:
            renderer.cancel()  # no histogram is written into the folder after this
        raise


def _write_measured_files(
    folder: Path, result, echo: dict, *, capture: str, params: str, n_points: int, save_draws: bool
) -> None:
    """The files of :func:`_write_measured_folder` but the histograms."""
    import csv
    import io
    import json

    import numpy as np

    from robotcal.io.atomic import atomic_write_text
    from robotcal.io.draws_npz import write_draws
    from robotcal.io.uncertainty_files import write_uncertainty_csv, write_uncertainty_json
    from robotcal.uncertainty.measured import MODEL as MEASURED_MODEL  # scipy: imported when this runs, not for --help
    from robotcal.uncertainty.measured import with_model
    from robotcal.workflow import versions

    parameters = result.parameters
    write_uncertainty_csv(folder / "parameters.csv", parameters)
    # the JSON writer knows the scenario models; written as "refined", then re-labelled
    write_uncertainty_json(folder / "parameters.json", with_model(parameters, "refined"), scenario=echo, versions=versions())
    document = json.loads((folder / "parameters.json").read_text(encoding="utf-8"))
    document["model"] = MEASURED_MODEL
    document["method"] = (
        "GUM Supplement 1 Monte Carlo (JCGM 101:2008) of a measured capture: its poses and targets simulated on "
        f"the refined parameters, each point's noise N(0, (U95/2)^2) per coordinate (k = 2, normal), "
        f"{parameters.criterion} refinement repeated per draw (thesis ch. 4.5.7)"
    )
    for row in document["parameters"]:
        row["model"] = MEASURED_MODEL
    if document.get("linearised") is not None:
        document["linearised"]["method"] = (
            "the refinement's linearised covariance (robotcal refine's, sigma_hat estimated from its residuals) "
            "rescaled by (u_stated / sigma_hat)^2 to the noise the draws use, u_stated the RMS of the points' "
            "stated standard uncertainties (U(95) / 2, or the instrument's)"
        )
        document["linearised"]["stated_u_mm"] = float(result.stated_u_mm) if np.isfinite(result.stated_u_mm) else None
        document["linearised"]["residual_sigma_mm"] = (
            float(result.residual_sigma_mm) if np.isfinite(result.residual_sigma_mm) else None
        )
        document["linearised"]["step_mm"] = None
        document["linearised"]["validation"] = (
            "JCGM 101 §8.2: both interval ends within the numerical tolerance of one significant digit of u "
            "(what a few hundred draws resolve)"
        )
    document["capture"] = {"source": capture, "params": params, "points": n_points}
    document["noise"] = result.noise_source
    document["targets"] = _target_rows(result)
    document["free"] = list(result.reference.free_names)
    atomic_write_text(folder / "parameters.json", json.dumps(document, indent=2, allow_nan=False) + "\n")
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(TARGET_COLUMNS)
    for row in _target_rows(result):
        writer.writerow(["" if row[c] is None else (format(row[c], ".12g") if isinstance(row[c], float) else row[c])
                         for c in TARGET_COLUMNS])  # fmt: skip
    atomic_write_text(folder / "targets.csv", buffer.getvalue())
    if save_draws:
        write_draws(
            folder / "draws.npz", parameters.robot, parameters.draws, parameters.identified, seed=parameters.seed,
            model=MEASURED_MODEL,
        )  # fmt: skip
