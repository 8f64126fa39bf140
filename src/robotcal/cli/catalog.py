"""``robotcal robots``, ``robotcal instruments``, ``robotcal scenarios``: what ships with robotcal."""

from __future__ import annotations

import numpy as np
from rich.table import Table

from robotcal.cli import app
from robotcal.cli._common import console, handle_errors
from robotcal.io import instrument_presets, list_robots, list_scenarios


@app.command()
@handle_errors
def robots() -> None:
    """List the built-in robots (usable by name in a scenario's `robot` key)."""
    table = Table(title="Built-in robots", title_justify="left")
    for column in ("name", "joints", "Hayati joints", "reading signs", "description"):
        table.add_column(column)
    for robot in list_robots():
        hayati = ", ".join(f"J{i + 1}" for i in np.flatnonzero(robot.hayati)) or "-"
        signs = " ".join("+" if s > 0 else "-" for s in robot.reading_sign)
        table.add_row(robot.name, str(robot.n_joints), hayati, signs, robot.description)
    console.print(table)


@app.command()
@handle_errors
def instruments() -> None:
    """List the instrument presets, U(L) = A + B*L (L in m)."""
    table = Table(title="Instrument presets", title_justify="left")
    for column in ("preset", "A [um]", "B [um/m]", "description"):
        table.add_column(column)
    for name, entry in sorted(instrument_presets().items()):
        table.add_row(name, f"{entry['a_um']:g}", f"{entry['b_um_per_m']:g}", entry.get("description", ""))
    console.print(table)


@app.command()
@handle_errors
def scenarios() -> None:
    """List the built-in scenarios (the thesis's Tables 5.1, 5.2/5.4 and 5.5)."""
    table = Table(title="Built-in scenarios", title_justify="left")
    for column in ("scenario", "robot", "instrument", "noise", "points", "description"):
        table.add_column(column)
    for scenario in list_scenarios():
        instrument = scenario.instrument
        terms = f"{instrument.name} ({instrument.a_mm * 1e3:g} um + {instrument.b_mm_per_m * 1e3:g} um/m)"
        table.add_row(
            scenario.name, scenario.robot.name, terms, instrument.noise, str(int(scenario.plan.points.sum())), scenario.description
        )
    console.print(table)
