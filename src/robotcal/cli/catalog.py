"""``robotcal robots``, ``robotcal instruments``, ``robotcal scenarios``: what ships with robotcal.

The catalog (:mod:`robotcal.io`) and Rich's tables are imported by the commands, so that their
``--help`` starts fast (docs/cli.md, "For contributors: how commands load").
"""

from __future__ import annotations

from robotcal.cli._common import command_app, console, handle_errors

app = command_app()


@app.command()
@handle_errors
def robots() -> None:
    """List the built-in robots (usable by name in a scenario's `robot` key)."""
    from rich.table import Table

    from robotcal.io import list_robots

    table = Table(title="Built-in robots", title_justify="left")
    models = list_robots()
    table.add_column("name", no_wrap=True, min_width=max(len(r.name) for r in models))
    for column in ("joints", "Hayati joints", "reading signs", "description"):
        table.add_column(column)
    for robot in models:
        hayati = ", ".join(f"J{i + 1}" for i, parallel in enumerate(robot.hayati) if parallel) or "-"
        signs = " ".join("+" if s > 0 else "-" for s in robot.reading_sign)
        table.add_row(robot.name, str(robot.n_joints), hayati, signs, robot.description)
    console.print(table)


@app.command()
@handle_errors
def instruments() -> None:
    """List the instrument presets, U(L) = A + B*L (L in m)."""
    from rich.table import Table

    from robotcal.io import instrument_presets

    table = Table(title="Instrument presets", title_justify="left")
    presets = instrument_presets()
    table.add_column("preset", no_wrap=True, min_width=max(len(name) for name in presets))
    for column in ("A (um)", "B (um/m)", "description"):
        table.add_column(column)
    for name, entry in sorted(presets.items()):
        table.add_row(name, f"{entry['a_um']:g}", f"{entry['b_um_per_m']:g}", entry.get("description", ""))
    console.print(table)


@app.command()
@handle_errors
def scenarios() -> None:
    """List the built-in scenarios (the thesis's Tables 5.1, 5.2/5.4 and 5.5)."""
    from rich.table import Table

    from robotcal.io import list_scenarios

    table = Table(title="Built-in scenarios", title_justify="left")
    loaded = list_scenarios()
    table.add_column("scenario", no_wrap=True, min_width=max(len(s.name) for s in loaded))
    for column in ("robot", "instrument", "noise", "points", "description"):
        table.add_column(column)
    for scenario in loaded:
        instrument = scenario.instrument
        terms = f"{instrument.name} ({instrument.a_mm * 1e3:g} um + {instrument.b_mm_per_m * 1e3:g} um/m)"
        table.add_row(
            scenario.name,
            scenario.robot.name,
            terms,
            instrument.noise,
            str(int(scenario.plan.points.sum())),
            scenario.description,
        )
    console.print(table)
