"""Console tables that fit the terminal without breaking a number or cutting a name.

Rich shrinks a table that is wider than the console by wrapping or cutting *any* column: a number ends
split over two lines ("2.39e-" / "03"), a name is cut ("kuka-kr5…"). This happens at 80 columns and
whenever the output is piped (CI logs, ``| tee``), where Rich assumes 80 columns. A :class:`FittedTable`
decides its layout when it is printed, from the width it is given:

1. the table fits as it is: printed as Rich lays it out (nothing wraps);
2. it does not: number and name columns keep their widest cell (a header may wrap between its words),
   text columns wrap between words; if even that does not fit, the columns marked ``narrow`` are left
   out (a note names them and says where they are) or moved under the table as ``key: value`` lines;
3. nothing fits (a very narrow terminal): every row is printed as ``header: value`` lines.

So a number, a parameter name (``J2.beta``) or a robot name is always printed whole, at any width.
Rich is imported when a table is built or printed, not with this module.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from rich.console import Console, ConsoleOptions, RenderResult
    from rich.padding import Padding
    from rich.table import Table
    from rich.text import Text

__all__ = ["Column", "FittedTable"]

#: Padding (left + right) and border of each column of Rich's default box, plus the closing border.
_PER_COLUMN = 3
_EDGE = 1


@dataclass(frozen=True, slots=True)
class Column:
    """One column of a :class:`FittedTable`.

    ``kind``: ``"number"`` (right-aligned, never broken), ``"name"`` (left-aligned, never broken: parameter,
    robot, file names) or ``"text"`` (wraps between words). ``narrow``: 0 = always shown; 1, 2, ... =
    left out, lowest first, while the table is too wide for the console. ``below``: a column left out
    is printed under the table, one ``first cell: value`` line per row, instead of being omitted.
    ``min_width``: the narrowest a text column is worth showing (a description wrapped into a dozen
    characters reads badly); where it does not fit, the column counts as too wide.
    """

    header: str
    kind: Literal["number", "name", "text"] = "number"
    narrow: int = 0
    below: bool = False
    min_width: int = 0
    justify: Literal["left", "right", "center"] | None = None

    @property
    def align(self) -> Literal["left", "right", "center"]:
        return self.justify or ("right" if self.kind == "number" else "left")


def _plain(cell) -> str:
    return cell.plain if hasattr(cell, "plain") else str(cell)


def _width(text: str) -> int:
    from rich.cells import cell_len

    return max((cell_len(line) for line in text.splitlines()), default=0)


def _longest_word(text: str) -> int:
    from rich.cells import cell_len

    return max((cell_len(word) for word in text.split()), default=0)


class FittedTable:
    """A Rich renderable table that fits the console's width without breaking numbers or names.

    Build it like a :class:`rich.table.Table` (:meth:`add_row`) and print it with ``console.print``; the
    layout is chosen at print time (module docstring). ``elsewhere`` names where the columns left out of
    a narrow table can be read in full (e.g. ``"parameters.csv"``).
    """

    def __init__(
        self,
        title: str | None,
        columns: list[Column] | tuple[Column, ...],
        *,
        show_header: bool = True,
        elsewhere: str | None = None,
    ) -> None:
        self.title = title
        self.columns = tuple(columns)
        self.show_header = show_header
        self.elsewhere = elsewhere
        self.rows: list[tuple] = []

    def add_row(self, *cells) -> None:
        """One row: a ``str`` or :class:`rich.text.Text` per column (``""`` for an empty cell)."""
        if len(cells) != len(self.columns):
            raise ValueError(f"a row needs {len(self.columns)} cells; got {len(cells)}")
        self.rows.append(tuple("" if cell is None else cell for cell in cells))

    # -- measuring ---------------------------------------------------------------------------------------

    def _range(self, index: int) -> tuple[int, int]:
        """(narrowest, widest) content width of column ``index``: a number or name keeps its widest cell;
        text and headers may wrap between words."""
        column = self.columns[index]
        cells = [_plain(row[index]) for row in self.rows]
        header = column.header if self.show_header else ""
        widest = max([_width(header), *(_width(c) for c in cells)])
        if column.kind == "text":
            narrowest = max([_longest_word(header), *(_longest_word(c) for c in cells)])
            narrowest = max(narrowest, min(column.min_width, widest))
        else:
            narrowest = max([_longest_word(header), *(_width(c) for c in cells)])
        return max(narrowest, 1), max(widest, 1)

    def layout(self, width: int) -> tuple[list[int], list[int] | None]:
        """``(shown column indices, content widths or None)`` for a console ``width`` columns wide;
        ``None`` widths: the table fits as it is. An empty list of indices: print records instead."""
        shown = list(range(len(self.columns)))
        ranges = [self._range(i) for i in shown]

        def total(indices, which) -> int:
            return sum(ranges[i][which] for i in indices) + _PER_COLUMN * len(indices) + _EDGE

        if total(shown, 1) <= width:
            return shown, None
        for index in sorted((i for i in shown if self.columns[i].narrow), key=lambda i: self.columns[i].narrow):
            if total(shown, 0) <= width:
                break
            shown.remove(index)
        if total(shown, 1) <= width:
            return shown, None
        if total(shown, 0) > width:
            return [], None
        widths = {i: ranges[i][0] for i in shown}
        spare = width - total(shown, 0)
        # text columns first (their lines are what wrapping multiplies), then the headers of the others
        for kinds in (("text",), ("number", "name")):
            wanted = {i: ranges[i][1] - widths[i] for i in shown if self.columns[i].kind in kinds}
            need = sum(wanted.values())
            if need <= 0 or spare <= 0:
                continue
            if need <= spare:
                given = wanted
            else:
                given = {i: want * spare // need for i, want in wanted.items()}
                for i in sorted(wanted, key=lambda i: wanted[i] - given[i], reverse=True)[
                    : spare - sum(given.values())
                ]:
                    given[i] += 1
            for i, extra in given.items():
                widths[i] += extra
            spare -= sum(given.values())
        return shown, [widths[i] for i in shown]

    # -- rendering ---------------------------------------------------------------------------------------

    def _table(self, shown: list[int], widths: list[int] | None) -> Table:
        from rich.table import Table

        table = Table(title=self.title, title_justify="left", show_header=self.show_header)
        for k, index in enumerate(shown):
            column = self.columns[index]
            fixed = None if widths is None else widths[k]
            table.add_column(column.header, justify=column.align, width=fixed, overflow="fold")
        for row in self.rows:
            table.add_row(*(row[index] for index in shown))
        return table

    def record_lines(self) -> list[Text | Padding]:
        """Every row as ``header: value`` lines, the first cell as a heading (nothing fits side by side)."""
        from rich.padding import Padding
        from rich.text import Text

        lines: list[Text | Padding] = [Text(self.title, style="italic")] if self.title else []
        for row in self.rows:
            lines.append(Text(_plain(row[0]), style="bold"))
            for column, cell in zip(self.columns[1:], row[1:], strict=True):
                if _plain(cell):
                    line = Text(f"{column.header}: " if column.header else "")
                    line.append_text(cell if isinstance(cell, Text) else Text(str(cell)))
                    lines.append(Padding(line, (0, 0, 0, 2)))
        return lines

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        from rich.padding import Padding
        from rich.text import Text

        width = options.max_width
        shown, widths = self.layout(width)
        if not shown:
            yield from self.record_lines()
            return
        yield self._table(shown, widths)
        hidden = [i for i in range(len(self.columns)) if i not in shown]
        for index in (i for i in hidden if self.columns[i].below):
            column = self.columns[index]
            yield Text(f"{column.header}:")
            for row in self.rows:
                if _plain(row[index]):
                    line = Text(f"{_plain(row[0])}: ")
                    line.append_text(row[index] if isinstance(row[index], Text) else Text(str(row[index])))
                    yield Padding(line, (0, 0, 0, 2))
        omitted = [self.columns[i].header for i in hidden if not self.columns[i].below]
        if omitted:
            where = f" (in {self.elsewhere})" if self.elsewhere else ""
            yield Text(f"{', '.join(omitted)}: not shown at {width} columns{where}", style="dim")
