"""``robotcal robots``, ``robotcal instruments``, ``robotcal scenarios``: what ships with robotcal.

The catalog (:mod:`robotcal.io`) and Rich's tables are imported by the commands, so that their
``--help`` starts fast (docs/cli.md, "For contributors: how commands load").
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robotcal.cli._common import app_command, command_app, console

if TYPE_CHECKING:
    from robotcal.cli._tables import FittedTable

app = command_app()

#: Narrowest description column of the catalog tables; narrower, the descriptions follow the table.
DESCRIPTION_WIDTH = 30


def _catalog_table(title: str, columns: list) -> FittedTable:
    """A catalog table of ``columns`` and, last, the entries' descriptions (below the table where it is narrow)."""
    from robotcal.cli._tables import Column, FittedTable

    description = Column("description", "text", narrow=1, below=True, min_width=DESCRIPTION_WIDTH)
    return FittedTable(title, [*columns, description])


@app_command(app)
def robots() -> None:
    """List the built-in robots (usable by name in a scenario's `robot` key)."""
    from robotcal.cli._tables import Column
    from robotcal.io import list_robots

    table = _catalog_table(
        "Built-in robots",
        [Column("name", "name"), Column("joints", "name"), Column("Hayati joints", "text"), Column("reading signs", "name")],
    )
    models = list_robots()
    for robot in models:
        hayati = ", ".join(f"J{i + 1}" for i, parallel in enumerate(robot.hayati) if parallel) or "-"
        table.add_row(robot.name, str(robot.n_joints), hayati, reading_signs(robot), robot.description)
    console.print(table)
    coupled = [robot for robot in models if robot.is_coupled]
    if coupled:
        robot = coupled[0]
        joint = next(j for j in range(robot.n_joints) if any(robot.reading_coupling[j] != 0.0))
        console.print(
            f"reading signs: in brackets, the other joints a coupled reading counts; e.g. {robot.name} "
            f"J{joint + 1}: {reading_formula(robot, joint)} (q model joint variables, o reading offsets; "
            "docs/conventions.md, coupled readings)",
            highlight=False,
        )


def reading_signs(robot) -> str:
    """``"+ + -(-J2) + + +"``: each joint's reading sign, and the terms of a coupled joint's reading."""
    signs = []
    for joint, sign in enumerate(robot.reading_sign):
        text = "+" if sign > 0 else "-"
        terms = [
            _coupling_term(coefficient, other)
            for other, coefficient in enumerate(robot.reading_coupling[joint])
            if coefficient != 0.0
        ]
        signs.append(text + (f"({' '.join(terms)})" if terms else ""))
    return " ".join(signs)


def reading_formula(robot, joint: int) -> str:
    """``"reading_3 = -(q3 - o3) - (q2 - o2)"``: one joint's row of the reading map (0-based ``joint``)."""
    text = f"reading_{joint + 1} = {'' if robot.reading_sign[joint] > 0 else '-'}(q{joint + 1} - o{joint + 1})"
    for other, coefficient in enumerate(robot.reading_coupling[joint]):
        if coefficient != 0.0:
            factor = "" if abs(coefficient) == 1.0 else f"{abs(coefficient):g} "
            text += f" {'+' if coefficient > 0 else '-'} {factor}(q{other + 1} - o{other + 1})"
    return text


def _coupling_term(coefficient: float, other: int) -> str:
    """``-J2`` for -1, ``+0.5J2`` for 0.5: one term of a coupled reading (0-based ``other``)."""
    if abs(coefficient) == 1.0:
        return f"{'+' if coefficient > 0 else '-'}J{other + 1}"
    return f"{coefficient:+g}J{other + 1}"


@app_command(app)
def instruments() -> None:
    """List the instrument presets, U(L) = A + B*L (L in m)."""
    from robotcal.cli._tables import Column
    from robotcal.io import instrument_presets

    columns = [Column("preset", "name"), Column("A (um)", justify="left"), Column("B (um/m)", justify="left")]
    table = _catalog_table("Instrument presets", columns)
    presets = instrument_presets()
    for name, entry in sorted(presets.items()):
        table.add_row(name, f"{entry['a_um']:g}", f"{entry['b_um_per_m']:g}", entry.get("description", ""))
    console.print(table)


@app_command(app)
def scenarios() -> None:
    """List the built-in scenarios (the thesis's Tables 5.1, 5.2/5.4 and 5.5)."""
    from robotcal.cli._tables import Column
    from robotcal.io import list_scenarios

    columns = [Column("scenario", "name"), Column("robot", "name"), Column("instrument (noise)", "text")]
    table = _catalog_table("Built-in scenarios", [*columns, Column("points", justify="left")])
    loaded = list_scenarios()
    both_ways = []
    for scenario in loaded:
        instrument = scenario.instrument
        terms = (
            f"{instrument.name} ({instrument.a_mm * 1e3:g} um + {instrument.b_mm_per_m * 1e3:g} um/m, "
            f"{instrument.noise})"
        )
        table.add_row(scenario.name, scenario.robot.name, terms, str(captured_points(scenario.plan)), scenario.description)
        if scenario.plan.bidirectional:
            both_ways.append(f"{scenario.name}: 2 x {int(scenario.plan.points.sum())}")
    console.print(table)
    if both_ways:
        console.print(
            f"points: every point the capture measures; a bidirectional plan sweeps each circle forward and back "
            f"({'; '.join(both_ways)})",
            highlight=False,
            soft_wrap=True,
        )


def captured_points(plan) -> int:
    """The points a capture of ``plan`` measures: ``points`` per circle and direction, both directions of a
    bidirectional plan (what ``robotcal simulate`` writes)."""
    return int(plan.points.sum()) * (2 if plan.bidirectional else 1)
