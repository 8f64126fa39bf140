"""FittedTable (robotcal.cli._tables): numbers and names whole at any console width (issue 24)."""

from __future__ import annotations

import io
import re

import pytest
from rich.console import Console
from rich.measure import Measurement

from robotcal.cli._tables import Column, FittedTable

NAMES = ["J1.d", "J2.beta", "kuka-kr5-sixx-r650-krc"]
NUMBERS = ["335.00265", "-1.166e-02", "2.39e-03"]


def _table() -> FittedTable:
    table = FittedTable(
        "A table with a long title that wraps in a narrow console, between its words",
        [
            Column("parameter", "name"),
            Column("mean"),
            Column("u"),
            Column("standard uncertainty (GUM)", narrow=2),
            Column("verdict", "name", narrow=1),
            Column("description", "text", narrow=3, below=True, min_width=20),
        ],
        elsewhere="parameters.csv",
    )
    for name, number in zip(NAMES, NUMBERS, strict=True):
        table.add_row(name, number, number, number, "differs", f"{name} is described in several words here")
    return table


def _render(renderable, width: int) -> str:
    console = Console(width=width, file=io.StringIO(), color_system=None, markup=False)
    console.print(renderable)
    return console.file.getvalue()


@pytest.mark.parametrize("width", [200, 120, 100, 80, 70, 60, 40, 30])
def test_numbers_and_names_stay_whole_at_any_width(width):
    output = _render(_table(), width)
    assert "…" not in output
    tokens = set(re.split(r"[\s│┃]+", output))
    for whole in [*NAMES, *NUMBERS]:
        assert whole in tokens, (width, whole, output)
    assert all(len(line.rstrip()) <= width for line in output.splitlines()), output


def test_a_table_that_fits_is_left_as_rich_lays_it_out():
    table = _table()
    shown, widths = table.layout(200)
    assert shown == list(range(6)) and widths is None
    natural = Measurement.get(Console(width=200), Console(width=200).options, table._table(shown, None)).maximum
    assert natural <= 200
    output = _render(table, 200)
    assert "not shown" not in output and "standard uncertainty (GUM)" in output


def test_narrow_columns_are_left_out_lowest_first_and_said_so():
    table = _table()
    # 80 columns: the verdict (narrow=1) and the linearised u (2) are left out
    shown, _ = table.layout(80)
    assert [table.columns[i].header for i in shown] == ["parameter", "mean", "u", "description"]
    # 60 columns: the description (3) moves under the table too, one line per row
    shown, _ = table.layout(60)
    headers = [table.columns[i].header for i in shown]
    assert headers == ["parameter", "mean", "u"]
    output = _render(table, 60)
    assert "description:" in output and "J2.beta: J2.beta is described in several words here" in output
    said = " ".join(output.split())  # the note wraps between words
    assert "standard uncertainty (GUM), verdict: not shown at 60 columns (in parameters.csv)" in said


def test_the_widths_fill_the_console_exactly_when_wrapping_is_needed():
    table = FittedTable("t", [Column("name", "name"), Column("text", "text"), Column("value")])
    table.add_row("J2.beta", "words " * 30, "1.000e-03")
    shown, widths = table.layout(60)
    assert widths is not None and sum(widths) + 3 * len(widths) + 1 == 60
    assert widths[0] >= len("J2.beta") and widths[2] >= len("1.000e-03")
    rendered = _render(table, 60).splitlines()
    assert max(len(line.rstrip()) for line in rendered) == 60


def test_records_when_nothing_fits_side_by_side():
    output = _render(_table(), 30)
    lines = output.splitlines()
    assert "J2.beta" in lines and any(line.strip() == "mean: -1.166e-02" for line in lines)


def test_a_row_must_have_a_cell_per_column():
    with pytest.raises(ValueError, match="needs 6 cells; got 2"):
        _table().add_row("J1.d", "1")
