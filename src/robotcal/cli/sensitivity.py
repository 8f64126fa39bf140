"""``robotcal sensitivity SCENARIO --vary KEY=V1,V2,...``: Monte Carlo per combination, Cpk (thesis 5.2.4)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import ScenarioArgument, Scheduler, app_command, command_app, console
from robotcal.cli._tables import Column, FittedTable

app = command_app()

__all__ = ["sensitivity"]


@app_command(app)
def sensitivity(
    scenario: ScenarioArgument,
    vary: Annotated[
        list[str],
        typer.Option(
            "--vary",
            help="KEY=V1,V2,... (repeatable): e.g. capture.sweep_deg.4=15,40,90,180, capture.points=10,40,100, "
            "montecarlo.iterations=1000,10000. A 1-based index selects a list element; a scalar fills a list.",
        ),
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for sensitivity.csv/.json and figures.")],
    iterations: Annotated[
        int | None, typer.Option("--iterations", "-n", help="Draws per case (default: the scenario's).")
    ] = None,
    seed: Annotated[int, typer.Option(min=0, help="Seed shared by every case (common random numbers).")] = 1,
    length_limit: Annotated[float, typer.Option("--length-limit-mm", help="Cpk limits for lengths [mm].")] = 0.1,
    angle_limit: Annotated[
        float, typer.Option("--angle-limit-deg", help="Cpk limits for angles [deg] (0.1 mm at 573 mm).")
    ] = 0.01,
    workers: Annotated[int, typer.Option(min=1, help="Local worker processes for the cases.")] = 1,
    scheduler: Scheduler = None,
    force: Annotated[bool, typer.Option("--force", help="Replace a folder not written by robotcal.")] = False,
) -> None:
    """Mean, u and Cpk (eq. 5-5) of every parameter against the varied capture conditions (Figs 5.14-5.16)."""
    from robotcal import api
    from robotcal.io.results.output import check_output_folder, existing_inputs, result_folder
    from robotcal.planning.scenario import scenario_document
    from robotcal.planning.sensitivity import study_rows

    source = scenario_document(scenario)[3]
    inputs = existing_inputs(source)
    check_output_folder(out, inputs=inputs, force=force)
    study = api.sensitivity(
        scenario, vary, seed=seed, iterations=iterations, length_limit_mm=length_limit, angle_limit_deg=angle_limit,
        workers=workers, scheduler=scheduler,
    )  # fmt: skip
    rows = study_rows(study)
    summary = {
        "scenario": source,
        "keys": list(study.keys),
        "seed": seed,
        "length_limit_mm": length_limit,
        "angle_limit_deg": angle_limit,
        "executor": study.executor,
        "cases": [dict(case.values, draws=case.n_draws) for case in study.cases],
    }
    with result_folder(out, inputs=inputs, force=force, command="robotcal sensitivity") as folder:
        from robotcal.planning.files import write_sensitivity_files
        from robotcal.plots.planning import plot_sensitivity

        write_sensitivity_files(folder, rows, summary)
        plot_sensitivity(rows, study.keys, folder)
    table = FittedTable(
        "Lowest Cpk per case (eq. 5-5)",
        [*(Column(key, "name", justify="right") for key in study.keys), Column("worst parameter", "name")]
        + [Column("Cpk"), Column("u")],
    )
    for number in range(1, len(study.cases) + 1):
        case_rows = [r for r in rows if r["case"] == number]
        worst = min(case_rows, key=lambda r: r["cpk"])
        table.add_row(
            *[str(worst[k]) for k in study.keys],
            worst["name"],
            f"{worst['cpk']:.3g}",
            f"{worst['std_uncertainty']:.3g} {worst['unit']}",
        )
    console.print(table)
