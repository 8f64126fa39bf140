"""``robotcal plan check|optimise SCENARIO``: the capture plan in the cell, and a better plan (docs/planning.md).

Exit status of ``plan check``: 0 feasible, 1 infeasible (a point fails a check), 2 input errors.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from robotcal.cli._common import ScenarioArgument, Scheduler, app_command, command_app, console, progress_bar

if TYPE_CHECKING:  # numpy and the planning library load in the commands: a fast --help
    from robotcal.cli._tables import FittedTable

app = command_app()

__all__ = ["plan_app", "check_table"]

plan_app = typer.Typer(help="Capture planning: check a plan in the cell, optimise it.", no_args_is_help=True)
app.add_typer(plan_app, name="plan")

#: Exit status of `plan check` when the plan is infeasible (2 is reserved for input errors).
INFEASIBLE_EXIT = 1

_Acceptance = Annotated[
    float | None,
    typer.Option("--acceptance-deg", help="Reflector acceptance half-angle [deg] (default: the instrument preset's)."),
]
_NoAcceptance = Annotated[
    bool, typer.Option("--no-acceptance", help="Skip the acceptance check (an active target follows the tracker).")
]
_Aim = Annotated[str, typer.Option(help="Where each circle's target faces the tracker: middle | start.")]
_Force = Annotated[bool, typer.Option("--force", help="Replace an output not written by robotcal.")]


def check_table(check) -> FittedTable:
    from robotcal.cli._tables import Column, FittedTable

    headers = ("circle", "points", "feasible", "planned (deg)", "usable (deg)", "first blocked")
    table = FittedTable(
        "Cell check per circle (forward sweep)",
        [*(Column(header) for header in headers), Column("why", "text")],
    )
    for c in check.circles:  # ranges as one word ("15.0..60.0"): a narrow console never splits them
        usable = "none" if c.usable_deg is None else f"{c.usable_deg[0]:.1f}..{c.usable_deg[1]:.1f}"
        table.add_row(
            str(c.circle),
            str(c.points),
            str(c.feasible_points),
            f"{c.start_deg:.1f}..{c.end_deg:.1f}",
            usable,
            "" if c.first_failure is None else str(c.first_failure),
            ", ".join(c.first_reasons),
        )
    return table


def _write_folder(out: Path | None, inputs, force: bool, command: str, write) -> None:
    if out is None:
        return
    from robotcal.io.results.output import result_folder

    with result_folder(out, inputs=inputs, force=force, command=command) as folder:
        write(folder)


@app_command(plan_app, "check")
def check(
    scenario: ScenarioArgument,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Folder for plan_check.json/.csv/.png.")] = None,
    acceptance_deg: _Acceptance = None,
    no_acceptance: _NoAcceptance = False,
    aim: _Aim = "middle",
    force: _Force = False,
) -> None:
    """Check every capture point: joint limits, measuring range, reflector acceptance, line of sight."""
    from robotcal import api
    from robotcal.io import load_scenario
    from robotcal.io.results.output import existing_inputs
    from robotcal.planning.cell import REASONS
    from robotcal.planning.scenario import cell_from_scenario

    loaded = load_scenario(scenario)
    cell, notes = cell_from_scenario(loaded, acceptance_deg=acceptance_deg, no_acceptance=no_acceptance, aim=aim)
    result = api.check_plan(loaded, cell=cell)
    console.print(check_table(result))
    for note in notes:
        console.print(f"note: {note}", highlight=False)

    def write(folder: Path) -> None:
        from robotcal.planning.files import check_document, write_check_files
        from robotcal.plots.planning import plot_check

        document = check_document(result, scenario=loaded.source, cell=cell, notes=notes)
        write_check_files(folder, result, document)
        plot_check(result, folder / "plan_check.png", acceptance_deg=document["cell"]["acceptance_deg"])

    _write_folder(out, existing_inputs(*loaded.files), force, "robotcal plan check", write)
    bad = int((~result.ok).sum())
    counts = ", ".join(f"{reason} {int(result.failures[:, k].sum())}" for k, reason in enumerate(REASONS))
    console.print(f"points failing each check: {counts}", highlight=False)
    if bad:
        console.print(f"infeasible: {bad} of {result.ok.size} points fail a check", highlight=False)
        raise typer.Exit(code=INFEASIBLE_EXIT)
    console.print("feasible: every point passes every check")


def optimise_summary(baseline: float, optimised: float, *, draws: int, evaluations: int, executor: str) -> str:
    """The last line of ``plan optimise``: the Monte Carlo's workspace p95 TCP uncertainty [mm] of the baseline and
    the optimised plan, and how they compare: "2.4x lower" (or "5.0 % lower" under 1.1x), "24 % higher: no better
    than the baseline" when the search did worse, "no better" when they agree to the printed 0.1 um."""
    if f"{baseline:.4f}" == f"{optimised:.4f}":
        change = "no better: the same at this precision"
    elif optimised > baseline:
        change = f"{100.0 * (optimised / baseline - 1.0):.0f} % higher: " if baseline > 0 else "higher: "
        change += "no better than the baseline"
    elif optimised <= 0:
        change = "lower"
    else:
        ratio = baseline / optimised
        change = f"{ratio:.1f}x lower" if ratio >= 1.1 else f"{100.0 * (1.0 - optimised / baseline):.1f} % lower"
    return (
        f"Monte Carlo ({draws} draws): workspace p95 TCP position uncertainty {baseline:.4f} -> {optimised:.4f} mm "
        f"({change}); {evaluations} candidates on {executor}"
    )


def _optimised_document(scenario: str, loaded, plan, objective: str) -> dict:
    """The scenario document with the optimised plan in ``[capture]`` (rounded as written; the robot path made
    absolute when it was relative to the scenario file)."""
    import numpy as np

    from robotcal.planning.scenario import scenario_document

    document, _, _, _ = scenario_document(scenario)
    capture = dict(document["capture"])
    capture.update(
        start_deg=[round(float(v), 6) for v in np.rad2deg(plan.start)],
        sweep_deg=[round(float(v), 6) for v in np.rad2deg(plan.sweep)],
        points=[int(v) for v in plan.points],
        reflector_mm=[[round(float(v), 4) for v in row] for row in plan.reflector.positions],
        joint_limits="error",
    )
    capture.pop("flange_reflector_mm", None)
    optimised = dict(document, capture=capture)
    optimised["description"] = f"Plan optimised by robotcal plan optimise ({objective}) from {loaded.name}"
    if "robot" in optimised and not Path(str(document["robot"])).is_absolute():
        candidate = Path(loaded.source).parent / str(document["robot"])
        if candidate.exists():
            optimised["robot"] = str(candidate.resolve())
    return optimised


def _optimise_table(objective: str, loaded, result, feasible: bool, confirmed: dict) -> FittedTable:
    """Baseline and optimised plan side by side: feasibility, linearised and Monte Carlo p95, max u, points."""
    from robotcal.cli._tables import Column, FittedTable

    headers = ("p95 TCP lin. (mm)", "p95 TCP MC (mm)", "max u", "points")
    table = FittedTable(
        f"Plan optimisation ({objective})",
        [Column("plan", "name", justify="right"), Column("feasible", "name", justify="right")]
        + [Column(header) for header in headers],
    )
    for name, ok, figures, plan in (
        ("baseline", result.baseline_feasible, result.baseline_figures, loaded.plan),
        ("optimised", feasible, result.best, result.plan),
    ):
        table.add_row(
            name, str(ok), f"{figures['p95-tcp']:.4f}", f"{confirmed[name]:.4f}", f"{figures['max-u']:.4g}",
            str(int(plan.points.sum())),
        )  # fmt: skip
    return table


def _write_optimised(folder: Path, header: str, document: dict, comparison: dict, result, objective: str) -> None:
    """``optimised.toml``, ``comparison.json``/``.csv`` and ``optimisation.png`` of ``plan optimise``."""
    from robotcal.io.atomic import atomic_write_text
    from robotcal.planning.scenario import dump_toml
    from robotcal.plots.planning import plot_optimisation

    confirmed = comparison["monte_carlo_p95_tcp_mm"]
    atomic_write_text(folder / "optimised.toml", dump_toml(document, header))
    atomic_write_text(folder / "comparison.json", json.dumps(comparison, indent=2, default=float) + "\n")
    rows = ["plan,feasible,p95_tcp_linearised_mm,p95_tcp_monte_carlo_mm,max_u"]
    rows.append(
        f"baseline,{result.baseline_feasible},{result.baseline_figures['p95-tcp']:.6g},{confirmed['baseline']:.6g},"
        f"{result.baseline_figures['max-u']:.6g}"
    )
    rows.append(
        f"optimised,{comparison['optimised_feasible']},{result.best['p95-tcp']:.6g},{confirmed['optimised']:.6g},"
        f"{result.best['max-u']:.6g}"
    )
    atomic_write_text(folder / "comparison.csv", "\n".join(rows) + "\n")
    baseline_and_optimised = {k: confirmed[k] for k in ("baseline", "optimised")}
    plot_optimisation(
        result.history,
        result.baseline_figures[objective],
        baseline_and_optimised if objective == "p95-tcp" else {},
        folder / "optimisation.png",
        objective=objective,
    )


@app_command(plan_app, "optimise")
def optimise(
    scenario: ScenarioArgument,
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for optimised.toml, comparison.json/.csv, figure.")],
    budget: Annotated[int | None, typer.Option(help="Points per direction in all (default: the scenario's).")] = None,
    objective: Annotated[str, typer.Option(help="p95-tcp | max-u | d-opt | e-opt.")] = "p95-tcp",
    generations: Annotated[int, typer.Option(min=1, help="Search generations.")] = 60,
    population: Annotated[int, typer.Option(min=1, help="Mutants per generation.")] = 8,
    seed: Annotated[int, typer.Option(min=0, help="Seed of the search and of the workspace sample.")] = 0,
    workspace_poses: Annotated[int, typer.Option("--workspace-poses", min=10, help="Workspace sample size.")] = 200,
    confirm_draws: Annotated[
        int, typer.Option("--confirm-draws", min=100, help="Monte Carlo draws confirming baseline and winner.")
    ] = 10_000,
    acceptance_deg: _Acceptance = None,
    no_acceptance: _NoAcceptance = False,
    aim: _Aim = "middle",
    workers: Annotated[int, typer.Option(min=1, help="Local worker processes for the candidates.")] = 1,
    scheduler: Scheduler = None,
    force: _Force = False,
) -> None:
    """Search start angles, sweeps, points per circle and reflector positions for a lower uncertainty,
    within the cell check; confirm baseline and winner by Monte Carlo; write the optimised scenario."""
    from robotcal import api
    from robotcal.io import load_scenario
    from robotcal.io.results.output import check_output_folder, existing_inputs
    from robotcal.planning.scenario import cell_from_scenario

    loaded = load_scenario(scenario)
    inputs = existing_inputs(*loaded.files)
    check_output_folder(out, inputs=inputs, force=force)
    cell, notes = cell_from_scenario(loaded, acceptance_deg=acceptance_deg, no_acceptance=no_acceptance, aim=aim)
    with progress_bar("plan search", "generations") as display:  # a bar, or a line every few seconds when piped
        task = display.add_task("search", total=generations)
        result = api.optimise_plan(
            loaded, cell, objective=objective, budget=budget, generations=generations, population=population,
            seed=seed, workspace_poses=workspace_poses, workers=workers, scheduler=scheduler,
            progress=lambda done, total: display.update(task, completed=done, total=total),
        )  # fmt: skip
    feasible = api.check_plan(loaded, result.plan, cell=cell).feasible
    confirmed = {}
    with progress_bar("Monte Carlo of baseline and optimised plans", "draws") as display:
        task = display.add_task("confirm", total=2 * confirm_draws)
        for k, (name, plan) in enumerate((("baseline", loaded.plan), ("optimised", result.plan))):

            def advance(done: int, _total: int | None, before: int = k * confirm_draws) -> None:
                display.update(task, completed=before + done)

            confirmed[name] = api.plan_tcp_p95(
                loaded, plan, draws=confirm_draws, rng=seed + 1, workspace_poses=workspace_poses, workspace_seed=seed,
                progress=advance,
            )  # fmt: skip
    comparison = {
        "scenario": loaded.source,
        "objective": objective,
        "budget": int(result.plan.points.sum()),
        "seed": seed,
        "executor": result.executor,
        "evaluations": result.evaluations,
        "feasible_evaluations": result.feasible_evaluations,
        "baseline_feasible": result.baseline_feasible,
        "optimised_feasible": feasible,
        "linearised": {"baseline": result.baseline_figures, "optimised": result.best},
        "monte_carlo_p95_tcp_mm": confirmed
        | {"draws": confirm_draws, "improvement": confirmed["baseline"] / confirmed["optimised"]},
        "notes": notes,
    }
    document = _optimised_document(scenario, loaded, result.plan, objective)
    header = f"robotcal plan optimise {loaded.name} --objective {objective} --seed {seed}"
    _write_folder(
        out, inputs, force, "robotcal plan optimise",
        lambda folder: _write_optimised(folder, header, document, comparison, result, objective),
    )  # fmt: skip
    console.print(_optimise_table(objective, loaded, result, feasible, confirmed))
    console.print(
        optimise_summary(
            confirmed["baseline"], confirmed["optimised"], draws=confirm_draws, evaluations=result.evaluations,
            executor=result.executor,
        ),  # fmt: skip
        highlight=False,
    )
