"""``robotcal run SCENARIO --out DIR``: the whole calibration pipeline into one run folder.

A thin command over :mod:`robotcal.pipeline`: :func:`~robotcal.pipeline.plan_run` checks everything up front,
:func:`~robotcal.pipeline.run_calibration` runs the stages (docs/pipeline.md, docs/results.md) under a Rich
progress display, and the headline figures of the run's summary are printed at the end.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from robotcal.cli._common import SEED_BOUND, Force, ScenarioArgument, app_command, command_app, console, error_console
from robotcal.errors import RobotcalError
from robotcal.limits import REFINED_DRAWS, SEED_OFFSETS

#: The largest seed of a whole run (``--seed``): each part of the run draws from the seed plus its SEED_OFFSETS entry.
RUN_SEED_MAX = SEED_BOUND - 1 - max(SEED_OFFSETS.values())

if TYPE_CHECKING:  # the pipeline loads when a run starts, not for --help
    from robotcal.pipeline.plan import RunPlan

__all__ = ["run", "run_and_print", "run_with_display"]

app = command_app()


#: Narrowest console that shows each stage's result text beside its bar (below it: in the Stages table only).
DETAIL_MIN_WIDTH = 110


def _progress_columns(width: int, totals: list[int]) -> tuple:
    """The progress display's columns for a console ``width`` columns wide: the stage name and the counts
    never shrink (a stage name cut to "uncerta…" says nothing); the bar shrinks; the stage's result text is
    shown only where it has room (it is in the Stages table after the run anyway)."""
    from rich.progress import BarColumn, MofNCompleteColumn, SpinnerColumn, TextColumn, TimeElapsedColumn
    from rich.table import Column

    from robotcal.io.results.run_folder import STAGES

    def whole(min_width: int | None = None) -> Column:
        return Column(no_wrap=True, min_width=min_width)

    counts = max(len(f"{total}/{total}") for total in totals)
    columns = (
        SpinnerColumn(finished_text="[green]✓[/green]", table_column=whole()),
        TextColumn("{task.fields[stage]}", markup=False, table_column=whole(max(map(len, STAGES)))),
        BarColumn(bar_width=30),
        MofNCompleteColumn(table_column=whole(counts)),
        TextColumn("{task.fields[unit]}", markup=False, table_column=whole()),
        TimeElapsedColumn(table_column=whole()),
    )
    if width < DETAIL_MIN_WIDTH:
        return columns
    return (*columns, TextColumn("{task.fields[detail]}", style="dim", markup=False, table_column=Column(overflow="fold")))


def run_with_display(plan: RunPlan):
    """:func:`robotcal.pipeline.run_calibration` under one Rich progress display (a task per stage; draws
    for the Monte Carlo); returns its :class:`~robotcal.io.results.run_folder.RunResult`."""
    import time

    from rich.progress import Progress

    from robotcal.io.results.run_folder import STAGES
    from robotcal.pipeline.plan import STEPS
    from robotcal.pipeline.run import run_calibration

    totals = {
        name: plan.montecarlo.iterations + plan.refined_montecarlo.iterations if name == "uncertainty" else STEPS[name]
        for name in STAGES
    }
    columns = _progress_columns(console.width, list(totals.values()))
    with Progress(*columns, console=console, transient=False) as display:
        tasks = {}
        for name in STAGES:
            unit = "draws" if name == "uncertainty" else "steps"
            tasks[name] = display.add_task(name, total=totals[name], stage=name, unit=unit, detail="", start=False)

        started: dict[str, float] = {}
        lines = not console.is_terminal  # a file, a pipe, a CI log: Rich shows the display only at the end

        def update(stage: str, done: int, total: int | None, detail: str = "") -> None:
            task = tasks[stage]
            if done == 0 and detail == "running":
                display.start_task(task)
                started[stage] = time.monotonic()
                return
            if done < 0:  # stage finished
                display.update(task, completed=display.tasks[task].total, detail=detail)
                display.stop_task(task)
                if lines:  # one line as each stage ends, so that the log shows the run advance
                    seconds = time.monotonic() - started.get(stage, time.monotonic())
                    display.console.print(f"stage {stage} done in {seconds:.1f} s", highlight=False, markup=False)
                return
            display.update(task, completed=done, detail=detail if stage != "uncertainty" else "")

        try:
            return run_calibration(plan, progress=update)
        except BaseException:
            for task in display.tasks:
                if task.started and not task.finished:
                    display.update(task.id, detail="failed")
                    display.stop_task(task.id)
            raise


def _print_summary(result) -> None:
    from robotcal.cli._tables import Column, FittedTable

    stages = FittedTable(
        "Stages", [Column("stage", "name"), Column("status", "name"), Column("time (s)"), Column("result", "text")]
    )
    for name, entry in result.record["stages"].items():
        stages.add_row(name, entry["status"], f"{entry['seconds']:.1f}", str(entry.get("detail") or ""))
    console.print(stages)
    for message in result.summary.notes:  # recorded in run.json; the run went on
        error_console.print(f"note: {message}", highlight=False)
    for line in result.summary.console_lines():
        console.print(line, highlight=False)


def _print_heading(command: str, description: str) -> None:
    """A rule titled ``command: description``; where that does not fit the console, the rule names the
    command and the description follows on its own (wrapped) line, never cut short."""
    from rich.cells import cell_len

    title = f"{command}: {description}" if description else command
    if cell_len(title) + 6 <= console.width:  # Rule: the title, a space either side, and some line
        console.rule(title)
        return
    console.rule(command)
    console.print(description, highlight=False)


def _command_line(command: str, *arguments, **options) -> str:
    """The command as a user would type it, for ``run.json``."""
    parts = ["robotcal", command, *(str(a) for a in arguments if a is not None)]
    for name, value in options.items():
        if value is not None:
            parts += [f"--{name.replace('_', '-')}", str(value)]
    return " ".join(parts)


def run_and_print(plan: RunPlan):
    """The ``run``/``demo`` command body: display, summary, and the report's path and total time."""
    started = time.perf_counter()
    _print_heading(f"robotcal run {plan.scenario.name}", plan.scenario.description)
    try:
        result = run_with_display(plan)
    except RobotcalError as exc:
        record = getattr(exc, "robotcal_record", None)
        if record is None:
            raise  # refused before any stage ran (output policy, lock)
        assert plan.out is not None  # `run` and `demo` always plan a folder
        done = [name for name, entry in record["stages"].items() if entry["status"] == "done"]
        raise RobotcalError(
            f"stage {record.get('failed_stage', '?')!r} failed: {exc}. Earlier stages ({', '.join(done) or 'none'}) "
            f"are intact in {plan.out}; {plan.out / 'run.json'} records the failure"
        ) from None
    _print_summary(result)
    console.print(
        f"wrote {result.file('report.html').resolve()} (open it in a browser) in "
        f"{time.perf_counter() - started:.1f} s",
        highlight=False,
        soft_wrap=True,
    )
    return result


@app_command(app, "run")
def run(
    scenario: ScenarioArgument,
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Run folder to write (a run folder of robotcal's is replaced).")
    ],
    seed: Annotated[
        int | None,
        typer.Option(
            min=0,
            max=RUN_SEED_MAX,
            help="Seed of the whole run (capture N, truth N+1, validation N+2, Monte Carlo N+3, workspace N+4).",
        ),
    ] = None,
    draws: Annotated[
        int | None,
        typer.Option("--draws", min=1, help="Monte Carlo draws (default: the scenario's montecarlo.iterations)."),
    ] = None,
    workspace: Annotated[
        int | None,
        typer.Option("--workspace", min=1, help="Random workspace poses (default: tcp.workspace_poses, 1000)."),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option("--workers", min=1, help="Monte Carlo worker processes (default: CPU count, at most 4)."),
    ] = None,
    refined_draws: Annotated[
        int | None,
        typer.Option(
            "--refined-draws",
            min=1,
            help="Draws of the refined-model Monte Carlo (default: the scenario's montecarlo.refined_iterations, "
            f"else {REFINED_DRAWS:,}; at most --draws).",
        ),
    ] = None,
    force: Force = False,
) -> None:
    """Run the whole pipeline (simulate, CPA, joints, refine, evaluate, Monte Carlo, TCP, plan, ISO 9283) and write
    DIR/report.html."""
    options = dict(seed=seed, draws=draws, workspace=workspace, workers=workers, refined_draws=refined_draws)
    from robotcal.pipeline.plan import plan_run

    plan = plan_run(scenario, out, **options, command=_command_line("run", scenario, out=out, **options), force=force)
    run_and_print(plan)
