"""Tracker exports in: a tracker's point export + a joint-angle log -> a capture (docs/real-robot.md).

Three export layouts are read:

* **Leica** (recognised from its header): ``X [mm],Y [mm],Z [mm],U(95) [mm],...,Time Stamp``, with
  a point name column when there is one (``Name``, ``Point``, ``Point ID``, ``ID``, ``Label``);
  units read from the brackets ([mm], [m], [in]); the other columns are ignored.
* **plain** ``name;x;y;z`` lines without a header (the point export of tracker software); the unit
  must then be given (``units``), since nothing in the file states it.
* **generic** delimited text with a header and a column map ``{"x": "X [mm]", "y": ..., "z": ...,
  "name": ..., "u95": ..., "target": ..., "circle": ..., "direction": ...}`` (header names, or
  1-based column numbers for a file without a header).

Delimiters ``,``, ``;``, tab or runs of spaces and decimal ``.`` or ``,`` are detected (or given). A
unit given both by ``units`` and by the header must agree; conversions are exact (1 m = 1000 mm,
1 in = 25.4 mm, 1 um = 0.001 mm; ``µm``, written with the micro sign or the Greek mu, is ``um``). Every data row has as many fields as the header (or, without a header, as the first
row; a plain export exactly four): a longer or shorter row is an :class:`InputError` naming the file
and line, never read in part (a comma-delimited file with decimal commas splits its numbers into
extra fields, which this check catches). Empty fields after the last column (a trailing delimiter)
are allowed.

The joint-angle log is a CSV with a header: ``name`` (needed to join by name) and ``q1..qN`` in
degrees (``j1..jN`` or ``a1..aN`` also accepted), optionally ``circle``, ``direction`` and
``target``. Points are joined to log rows **by name** (each point's name is a pose of the log; with
a ``target`` column several points, one per target, share a pose) or **by order** (point k <-> row
k). A point without a reading, a reading without a point, or a name (or name and target) given
twice is an :class:`InputError` naming the file, line and column.

The result is a :class:`robotcal.capture.Capture` with the optional ``target`` and ``u95`` columns
(U(95) [mm], k = 2, normal), written by :func:`robotcal.io.formats.capture_csv.write_capture`.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.io.formats.orientation import ORIENTATION_KEYS, orientation_columns
from robotcal.io.schema._validation import MAX_LINE_CHARS, csv_rows, read_text_file

__all__ = [
    "UNITS_MM",
    "TrackerPoints",
    "JointLog",
    "parse_column_map",
    "read_tracker_export",
    "read_joint_log",
    "join_points_to_readings",
    "import_tracker_capture",
]

#: Length units a tracker export may use, in mm per unit (exact).
UNITS_MM = {"mm": 1.0, "m": 1000.0, "in": 25.4, "um": 1e-3}
_UNIT_ALIASES = {
    "mm": "mm", "m": "m", "in": "in", "inch": "in", "inches": "in", '"': "in",
    "um": "um", "µm": "um", "μm": "um", "micron": "um", "microns": "um",  # Leica exports: "[µm]" (micro sign or mu)
}  # fmt: skip
#: Header names of a point-name column (lower case).
NAME_HEADERS = ("name", "point", "point name", "point id", "pointid", "id", "label", "pose")
MAP_KEYS = ("x", "y", "z", "name", "u95", "target", "circle", "direction", *ORIENTATION_KEYS)
#: A unit bracket ends a header: ``X [mm]``. Only square brackets: ``U(95)`` is a name, not the unit "95".
_UNIT_IN_HEADER = re.compile(r"^(?P<base>.*?)\s*\[(?P<unit>[^\[\]]*)\]\s*$")
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+([eE][+-]?\d+)?$")


@dataclass(frozen=True, slots=True, kw_only=True)
class TrackerPoints:
    """The points of a tracker export, converted to mm.

    Attributes
    ----------
    points : ndarray, shape (n_points, 3)
        Coordinates in the tracker frame [mm].
    names : tuple of str or None
        Point names (None when the export has no name column).
    u95 : ndarray, shape (n_points,), or None
        Expanded uncertainty U(95) [mm] of each point (k = 2), when the export gives one.
    target, circle, direction : tuple or ndarray or None
        Optional per-point columns (target names; circle and direction as integers).
    orientation, orientation_u95 : ndarray or None
        A 6-DoF probe's orientation per point, ``(n_points, 3, 3)`` (probe to tracker frame), and its U(95) [rad]
        (:func:`robotcal.io.formats.orientation.orientation_columns`).
    lines : ndarray of int, shape (n_points,)
        Line of the file each point was read from (for error messages).
    layout : str
        ``"leica"``, ``"plain"`` or ``"generic"``.
    unit : str
        Unit of the file's coordinates (``"mm"``, ``"m"``, ``"in"``).
    source : str
    """

    points: np.ndarray
    names: tuple[str, ...] | None
    lines: np.ndarray
    layout: str
    unit: str
    source: str
    u95: np.ndarray | None = None
    target: tuple[str, ...] | None = None
    circle: np.ndarray | None = None
    direction: np.ndarray | None = None
    orientation: np.ndarray | None = None
    orientation_u95: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "points", _frozen(np.asarray(self.points, dtype=float)))
        object.__setattr__(self, "lines", _frozen(np.asarray(self.lines), int))
        if self.u95 is not None:
            object.__setattr__(self, "u95", _frozen(np.asarray(self.u95, dtype=float)))

    @property
    def n_points(self) -> int:
        return self.points.shape[0]


@dataclass(frozen=True, slots=True, kw_only=True)
class JointLog:
    """The joint readings of a joint-angle log.

    Attributes
    ----------
    readings : ndarray, shape (n_rows, n_joints)
        Controller readings [rad].
    names : tuple of str or None
        Pose names (None without a ``name`` column).
    lines : ndarray of int, shape (n_rows,)
    circle, direction : ndarray of int or None
    target : tuple of str or None
    source : str
    """

    readings: np.ndarray
    names: tuple[str, ...] | None
    lines: np.ndarray
    source: str
    circle: np.ndarray | None = None
    direction: np.ndarray | None = None
    target: tuple[str, ...] | None = field(default=None)

    @property
    def n_rows(self) -> int:
        return self.readings.shape[0]


# --------------------------------------------------------------------------------------------------
# delimited text


#: The delimiter name of runs of spaces (fields separated by one or more spaces).
SPACES = " "
_DELIMITER_NAMES = {"tab": "\t", "\\t": "\t", "semicolon": ";", "comma": ",", "space": SPACES, "spaces": SPACES}


def _detect_delimiter(first_line: str, delimiter: str | None, source) -> str:
    if delimiter is not None:
        delimiter = _DELIMITER_NAMES.get(delimiter.lower(), delimiter) if delimiter.strip() else SPACES
        if delimiter not in (",", ";", "\t", SPACES):
            raise InputError(f"{source}: delimiter must be ',', ';', tab or space; got {delimiter!r}")
        return delimiter
    for candidate in ("\t", ";", ","):
        if candidate in first_line:
            return candidate
    if len(first_line.split()) > 1:  # neither tab, ';' nor ',': fields separated by spaces
        return SPACES
    return ","


def _detect_decimal(rows: list[list[str]], delimiter: str, decimal: str | None, source) -> str:
    if decimal is not None:
        if decimal not in (".", ","):
            raise InputError(f"{source}: decimal separator must be '.' or ','; got {decimal!r}")
        if decimal == "," and delimiter == ",":
            raise InputError(f"{source}: decimal ',' needs another delimiter (';' or tab) than ','")
        return decimal
    if delimiter == ",":
        return "."
    for row in rows[:50]:
        if any(_DECIMAL_COMMA.match(cell.strip()) for cell in row):
            return ","
    return "."


def _table(path, *, kind: str, delimiter: str | None, decimal: str | None, encoding: str = "utf-8"):
    """``(records, delimiter, decimal)``: the non-empty ``(line, cells)`` of a delimited text file."""
    text = read_text_file(path, kind=kind, encoding=encoding, encoding_option="--encoding")
    first = next((line for line in text.splitlines() if line.strip()), "")
    if not first:
        raise InputError(f"{path}: empty file; expected a {kind}")
    delimiter = _detect_delimiter(first, delimiter, path)
    records = [
        (number, [cell.strip() for cell in row])
        for number, row in _csv_records(text, path, delimiter)
        if any(cell.strip() for cell in row)
    ]
    header = records[0][1]
    while header and not header[-1]:  # a trailing delimiter after the last name
        header.pop()
    decimal = _detect_decimal([row for _, row in records[1:]] or [records[0][1]], delimiter, decimal, path)
    return records, delimiter, decimal


def _csv_records(text: str, path, delimiter: str):
    if delimiter == ",":
        return csv_rows(text, path)
    for number, line in enumerate(text.splitlines(), start=1):  # the line-length check of every reader
        if len(line) > MAX_LINE_CHARS:
            raise InputError(f"{path}: line {number} is {len(line):,} characters long (limit {MAX_LINE_CHARS:,})")
    if delimiter == SPACES:  # no quoting: a field is a run of non-space characters
        return [(number, line.split()) for number, line in enumerate(text.splitlines(), start=1)]
    reader = csv.reader(io.StringIO(text), delimiter=delimiter)
    rows = []
    try:
        for row in reader:
            rows.append((reader.line_num - sum(cell.count("\n") for cell in row), row))
    except csv.Error as exc:
        raise InputError(f"{path}: line {reader.line_num}: not valid delimited text ({exc})") from None
    return rows


def _check_width(row: list[str], line: int, expected: int, source, *, of: str, delimiter: str) -> list[str]:
    """``row`` with exactly ``expected`` fields (empty fields after the last one dropped), else an error.

    ``of`` says where ``expected`` comes from ("in the header (line 1)", ...). A comma-delimited row
    that is too long gets a hint: decimal commas split its numbers in two.
    """
    if len(row) > expected and not any(row[expected:]):
        row = row[:expected]
    if len(row) == expected:
        return row
    hint = ""
    if delimiter == "," and len(row) > expected:
        hint = (
            "; a comma-delimited file with decimal commas? Each decimal comma splits a number in two: "
            "export with ';' or tab as delimiter, or with '.' as decimal separator"
        )
    raise InputError(f"{source}: line {line} has {len(row)} fields; expected {expected}, as {of}{hint}")


def _number(cell: str, decimal: str, where: str) -> float:
    text = cell.strip()
    if decimal == ",":
        if "." in text:
            raise InputError(f"{where}: {text!r} is not a number with decimal comma")
        text = text.replace(",", ".")
    try:
        value = float(text)
    except ValueError:
        hint = " (a decimal comma? give --decimal ,)" if decimal == "." and _DECIMAL_COMMA.match(text) else ""
        raise InputError(f"{where}: {cell.strip()!r} is not a number{hint}") from None
    if not np.isfinite(value):
        raise InputError(f"{where}: {cell.strip()!r} is not a finite number")
    return value


def _texts(cells: list[float | int | str]) -> tuple[str, ...]:
    """The cells of a text column (``name``, ``target``: :func:`_cell` keeps them as written)."""
    return tuple(str(cell) for cell in cells)


def _cell(key: str, cell: str, decimal: str, where: str) -> float | int | str:
    """A cell of column ``key``: a number (``x``, ``y``, ``z``, ``u95``, joint readings), a whole number
    (``circle``, ``direction``) or a non-empty text (``name``, ``target``)."""
    if key in ("circle", "direction"):
        number = _number(cell, decimal, where)
        if number != round(number):
            raise InputError(f"{where}: must be a whole number; got {cell!r}")
        return int(number)
    if key in ("name", "target"):
        if not cell:
            raise InputError(f"{where}: empty {key}")
        return cell
    return _number(cell, decimal, where)


def _is_number(cell: str, decimal: str) -> bool:
    try:
        _number(cell, decimal, "")
    except InputError:
        return False
    return True


def _split_unit(header: str) -> tuple[str, str | None]:
    """``"X [mm]"`` -> ``("x", "mm")``; ``"x"`` and ``"U(95)"`` -> ``(base, None)`` (base in lower case; only
    ``[...]`` is a unit bracket)."""
    match = _UNIT_IN_HEADER.match(header.strip())
    if match is None:
        return header.strip().lower(), None
    return match["base"].strip().lower(), match["unit"].strip().lower()


def _length_unit(unit: str, where: str) -> str:
    if unit not in _UNIT_ALIASES:
        raise InputError(f"{where}: unknown unit {unit!r}; known: {', '.join(UNITS_MM)}")
    return _UNIT_ALIASES[unit]


def parse_column_map(text: str | None) -> dict[str, str]:
    """``'x="X [mm]",y=Y,name=Point'`` -> ``{"x": "X [mm]", "y": "Y", "name": "Point"}``.

    Values may be double-quoted (to hold commas); keys are those of :data:`MAP_KEYS`.
    """
    if text is None or not text.strip():
        return {}
    items, current, quoted = [], "", False
    for char in text:
        if char == '"':
            quoted = not quoted
        elif char == "," and not quoted:
            items.append(current)
            current = ""
            continue
        current += char
    if quoted:
        raise InputError(f"--columns: unbalanced quote in {text!r}")
    items.append(current)
    mapping = {}
    for item in items:
        key, sep, value = item.partition("=")
        key, value = key.strip().lower(), value.strip()
        if len(value) >= 2 and value[0] == value[-1] == '"':
            value = value[1:-1]
        if not sep or not key or not value:
            raise InputError(f"--columns: expected KEY=COLUMN items separated by commas; got {item.strip()!r}")
        if key not in MAP_KEYS:
            raise InputError(f"--columns: unknown key {key!r}; known: {', '.join(MAP_KEYS)}")
        if key in mapping:
            raise InputError(f"--columns: key {key!r} given twice")
        mapping[key] = value
    missing = [key for key in ("x", "y", "z") if key not in mapping]
    if missing:
        raise InputError(f"--columns: the map must name x, y and z; missing {', '.join(missing)}")
    return mapping


# --------------------------------------------------------------------------------------------------
# the tracker export


def _auto_columns(header: list[str]) -> tuple[dict[str, int], str]:
    """Column positions recognised in a header without a map, and the layout name."""
    positions: dict[str, int] = {}
    bases = [_split_unit(cell)[0] for cell in header]
    for position, base in enumerate(bases):
        key = None
        if base in ("x", "y", "z"):
            key = base
        elif re.fullmatch(r"u\s*\(?\s*95\s*\)?|u95|u95_mm", base):
            key = "u95"
        elif base in NAME_HEADERS:
            key = "name"
        elif base in ("target", "circle", "direction", "qw", "qx", "qy", "qz", "u95_deg"):  # others: --columns
            key = base
        if key is not None and key not in positions:
            positions[key] = position
    leica = "u95" in positions or any(base == "time stamp" for base in bases)
    return positions, "leica" if leica else "generic"


def _mapped_columns(header: list[str] | None, mapping: dict[str, str], width: int, line: int, source) -> dict[str, int]:
    """Positions of the mapped columns; a number must be a column of the file (1..``width``, the
    fields of its first line ``line``)."""
    positions = {}
    lowered = [cell.strip().lower() for cell in header] if header is not None else None
    for key, column in mapping.items():
        if lowered is not None and column.strip().lower() in lowered:
            positions[key] = lowered.index(column.strip().lower())
        elif column.isdigit() and 1 <= int(column) <= width:
            positions[key] = int(column) - 1
        elif column.isdigit():
            raise InputError(
                f"{source}: --columns {key}={column}: no column {int(column)}; line {line} has {width} fields "
                f"(expected a column number 1..{width} or a header name)"
            )
        else:
            known = ", ".join(repr(cell) for cell in header) if header else "(no header)"
            raise InputError(f"{source}: --columns {key}={column!r}: no such column; the header has {known}")
    return positions


def read_tracker_export(
    path,
    *,
    columns: dict[str, str] | str | None = None,
    delimiter: str | None = None,
    decimal: str | None = None,
    units: str | None = None,
    check_names: bool = True,
    encoding: str = "utf-8",
) -> TrackerPoints:
    """Read a tracker's point export (Leica, plain ``name;x;y;z`` or a mapped generic layout), in mm.

    Parameters
    ----------
    path : path-like
    columns : dict or str, optional
        Column map (see :func:`parse_column_map`); without it the layout is recognised.
    delimiter : {",", ";", "\\t", " "}, optional
        Detected from the first line when omitted (tab, then ``;``, then ``,``, else runs of spaces when
        the line has several words); ``"tab"``, ``"space"`` name them too.
    decimal : {".", ","}, optional
        Detected from the data when omitted (``,`` only with another delimiter).
    units : {"mm", "m", "in"}, optional
        Unit of the coordinates; read from the header's ``[mm]`` when omitted; both given must agree.
    check_names : bool
        Refuse repeated names (repeated ``(name, target)`` with a target column). False: left to
        :func:`join_points_to_readings`, where a joint log's target column may tell the points apart.
    encoding : str
        The export's text encoding (default UTF-8; Windows tools often write cp1252: "[µm]", "[°C]" headers).

    Returns
    -------
    TrackerPoints
    """
    source = Path(path)
    mapping = parse_column_map(columns) if isinstance(columns, str) or columns is None else dict(columns)
    if units is not None:
        units = _length_unit(units.strip().lower(), f"{source}: --units")
    records, delimiter, decimal = _table(
        source, kind="tracker export", delimiter=delimiter, decimal=decimal, encoding=encoding
    )
    layout = _export_layout(records, mapping, decimal, source)
    header, positions = layout.header, layout.positions
    if not layout.data:
        raise InputError(f"{source}: no data rows")

    def column_name(key: str) -> str:
        return header[positions[key]] if header is not None else f"{key} (column {positions[key] + 1})"

    unit, u95_unit = _export_units(header, positions, units, source, column_name("x"))
    values: dict[str, list[float | int | str]] = {key: [] for key in positions}
    lines = []
    for line, row in layout.data:
        row = _check_width(row, line, layout.width, source, of=layout.of, delimiter=delimiter)
        lines.append(line)
        for key, position in positions.items():
            where = f"{source}: line {line}, column `{column_name(key)}`"
            values[key].append(_cell(key, row[position], decimal, where))
    points = np.column_stack([values[key] for key in ("x", "y", "z")]) * UNITS_MM[unit]
    u95 = None
    if "u95" in values:
        u95 = np.asarray(values["u95"]) * UNITS_MM[u95_unit]
        bad = np.flatnonzero(u95 <= 0.0)
        if bad.size:
            raise InputError(
                f"{source}: line {lines[bad[0]]}, column `{column_name('u95')}`: U(95) must be > 0; "
                f"got {values['u95'][bad[0]]!r}"
            )
    names = _texts(values["name"]) if "name" in values else None
    target = _texts(values["target"]) if "target" in values else None
    orientation, orientation_u95 = orientation_columns(values, source=str(source))
    if check_names:
        _check_unique_names(names, target, lines, source, column_name("name") if names else "")
    return TrackerPoints(
        points=points,
        names=names,
        lines=np.asarray(lines),
        layout=layout.name,
        unit=unit,
        source=str(source),
        u95=u95,
        target=target,
        circle=np.asarray(values["circle"]) if "circle" in values else None,
        direction=np.asarray(values["direction"]) if "direction" in values else None,
        orientation=orientation,
        orientation_u95=orientation_u95,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class _Layout:
    """Where an export's columns are: ``header`` (None: none), the data records, the column of each key, the
    layout's name, and the width every row must have (``of``: where that width comes from, for the message)."""

    header: list[str] | None
    data: list
    positions: dict[str, int]
    name: str
    width: int
    of: str


def _export_layout(records, mapping: dict[str, str], decimal: str, source) -> _Layout:
    """The export's layout: mapped by ``--columns``, a headerless ``name;x;y;z``, or recognised from its header."""
    first_line, first = records[0]
    if mapping:
        by_position = all(value.isdigit() and int(value) >= 1 for value in mapping.values())
        if by_position and all(
            int(mapping[key]) <= len(first) and _is_number(first[int(mapping[key]) - 1], decimal) for key in "xyz"
        ):
            header, data = None, records
        else:
            header, data = first, records[1:]
        of = f"in the header (line {first_line})" if header is not None else f"on line {first_line}"
        positions = _mapped_columns(header, mapping, len(first), first_line, source)
        return _Layout(header=header, data=data, positions=positions, name="generic", width=len(first), of=of)
    if len(first) >= 4 and all(_is_number(cell, decimal) for cell in first[1:4]):
        return _Layout(
            header=None, data=records, positions={"name": 0, "x": 1, "y": 2, "z": 3}, name="plain", width=4,
            of="in a plain name;x;y;z export (map a wider file with --columns)",
        )  # fmt: skip
    positions, name = _auto_columns(first)
    missing = [key for key in ("x", "y", "z") if key not in positions]
    if missing:
        raise InputError(
            f"{source}: no column {', '.join(missing)} in the header ({', '.join(first)}); "
            'name the columns with --columns x="...",y="...",z="..."'
        )
    return _Layout(
        header=first, data=records[1:], positions=positions, name=name, width=len(first),
        of=f"in the header (line {first_line})",
    )  # fmt: skip


def _export_units(header, positions: dict[str, int], units: str | None, source, x_column: str) -> tuple[str, str]:
    """The unit of the coordinates and of U(95): from the header's ``[mm]`` of x, y, z (which must agree) and/or
    ``--units`` (which must agree with the header)."""
    header_unit = None
    if header is not None:
        found = {}
        for key in ("x", "y", "z"):
            unit = _split_unit(header[positions[key]])[1]
            if unit is not None:
                found[key] = _length_unit(unit, f"{source}: column `{header[positions[key]]}`")
        if len(set(found.values())) > 1:
            raise InputError(f"{source}: the coordinate columns disagree on the unit: {found}")
        header_unit = next(iter(found.values()), None)
    if units is not None and header_unit is not None and units != header_unit:
        raise InputError(
            f"{source}: --units {units} contradicts the header, whose coordinates are in {header_unit} "
            f"(column `{x_column}`)"
        )
    unit = units or header_unit
    if unit is None:
        raise InputError(f"{source}: the export does not state its unit; give --units {'|'.join(UNITS_MM)}")
    u95_unit = unit
    if "u95" in positions and header is not None:
        stated = _split_unit(header[positions["u95"]])[1]
        if stated is not None:
            u95_unit = _length_unit(stated, f"{source}: column `{header[positions['u95']]}`")
    return unit, u95_unit


def _check_unique_names(names, target, lines, source, column: str) -> None:
    if names is None:
        return
    seen: dict[tuple, int] = {}
    for k, name in enumerate(names):
        key = (name, None if target is None else target[k])
        if key in seen:
            what = f"name {name!r}" if target is None else f"name {name!r} with target {target[k]!r}"
            raise InputError(
                f"{source}: line {lines[k]}, column `{column}`: {what} already on line {seen[key]}; "
                "point names must be unique (one point per pose and target)"
            )
        seen[key] = lines[k]


# --------------------------------------------------------------------------------------------------
# the joint-angle log


def _check_pose_names(names, targets, lines, source, column: str) -> None:
    """A log's pose names are unique (per target when it has a ``target`` column)."""
    seen: dict[tuple, int] = {}
    for k, name in enumerate(names):
        key = (name, None if targets is None else targets[k])
        if key in seen:
            what = f"pose name {name!r}" + ("" if targets is None else f" with target {targets[k]!r}")
            raise InputError(
                f"{source}: line {lines[k]}, column `{column}`: {what} already on line {seen[key]}; "
                "pose names must be unique" + ("" if targets is None else " per target")
            )
        seen[key] = lines[k]


_JOINT_COLUMN = re.compile(r"^(?:q|j|a)(\d{1,3})$")


def read_joint_log(
    path,
    *,
    n_joints: int | None = None,
    delimiter: str | None = None,
    decimal: str | None = None,
    check_names: bool = True,
    encoding: str = "utf-8",
) -> JointLog:
    """Read a joint-angle log: header with ``name`` (optional) and ``q1..qN`` [deg] (``j``/``a`` prefixes too).

    A ``[rad]`` unit in a joint column's header is converted; ``[deg]`` or none means degrees.
    Optional columns ``circle``, ``direction``, ``target``. Pose names must be unique, per target
    with a ``target`` column (one row per pose and target); ``check_names = False`` leaves that to
    :func:`join_points_to_readings` (``--join order`` does not use the names).
    """
    source = Path(path)
    records, delimiter, decimal = _table(
        source, kind="joint-angle log", delimiter=delimiter, decimal=decimal, encoding=encoding
    )
    header = records[0][1]
    joints, scale = _joint_columns(header, n_joints, source)
    count = len(joints)
    bases = [_split_unit(cell)[0] for cell in header]
    optional = {
        key: bases.index(alias)
        for key, aliases in (
            ("name", NAME_HEADERS),
            ("circle", ("circle",)),
            ("direction", ("direction",)),
            ("target", ("target",)),
        )
        for alias in aliases
        if alias in bases
    }
    data = records[1:]
    if not data:
        raise InputError(f"{source}: no data rows")
    readings = np.empty((len(data), count))
    extra: dict[str, list[float | int | str]] = {key: [] for key in optional}
    lines = []
    for row_index, (line, row) in enumerate(data):
        row = _check_width(
            row, line, len(header), source, of=f"in the header (line {records[0][0]})", delimiter=delimiter
        )
        lines.append(line)
        for k, position in enumerate(joints):
            where = f"{source}: line {line}, column `{header[position]}`"
            readings[row_index, k] = _number(row[position], decimal, where) * scale[k]
        for key, position in optional.items():
            extra[key].append(_cell(key, row[position], decimal, f"{source}: line {line}, column `{header[position]}`"))
    names = _texts(extra["name"]) if "name" in extra else None
    if names is not None and check_names:
        _check_pose_names(names, extra.get("target"), lines, source, header[optional["name"]])
    return JointLog(
        readings=readings,
        names=names,
        lines=np.asarray(lines),
        source=str(source),
        circle=np.asarray(extra["circle"]) if "circle" in extra else None,
        direction=np.asarray(extra["direction"]) if "direction" in extra else None,
        target=_texts(extra["target"]) if "target" in extra else None,
    )


def _joint_columns(header: list[str], n_joints: int | None, source) -> tuple[list[int], list[float]]:
    """The positions of a log's joint columns ``q1..qN`` (or ``j``/``a``), in joint order, and each one's scale
    to radians (``[rad]`` in the header, else degrees)."""
    parsed = [_split_unit(cell) for cell in header]
    joint_positions: dict[str, dict[int, int]] = {}
    for position, (base, _) in enumerate(parsed):
        match = _JOINT_COLUMN.match(base)
        if match:
            joint_positions.setdefault(base[0], {})[int(match[1])] = position
    prefix = next((p for p in ("q", "j", "a") if p in joint_positions), None)
    if prefix is None:
        raise InputError(f"{source}: no joint columns q1..qN in the header ({', '.join(header)})")
    joints = joint_positions[prefix]
    count = max(joints)
    missing = [f"{prefix}{k}" for k in range(1, count + 1) if k not in joints]
    if missing:
        raise InputError(f"{source}: missing joint column(s) {', '.join(missing)}")
    if n_joints is not None and count != n_joints:
        raise InputError(
            f"{source}: {count} joint columns ({prefix}1..{prefix}{count}) but the robot has {n_joints} joints"
        )
    scale = []
    for k in range(1, count + 1):
        unit = parsed[joints[k]][1]
        if unit not in (None, "deg", "°", "degree", "degrees", "rad"):
            raise InputError(f"{source}: column `{header[joints[k]]}`: unknown angle unit {unit!r}; known: deg, rad")
        scale.append(1.0 if unit == "rad" else np.pi / 180.0)
    return [joints[k] for k in range(1, count + 1)], scale


# --------------------------------------------------------------------------------------------------
# the join


def _pick(name: str, from_points, from_log, rows: np.ndarray, points: TrackerPoints, log: JointLog):
    """A per-point column given by the export or by the log (both: they must agree)."""
    log_values = None if from_log is None else [from_log[r] for r in rows]
    if from_points is None:
        return log_values
    point_values = list(from_points)
    if log_values is not None:
        for k, (a, b) in enumerate(zip(point_values, log_values, strict=True)):
            if a != b:
                raise InputError(
                    f"{points.source}: line {points.lines[k]}: {name} {a!r} disagrees with the joint-angle log "
                    f"({log.source}: line {log.lines[rows[k]]}: {b!r})"
                )
    return point_values


def join_points_to_readings(
    points: TrackerPoints, log: JointLog, *, join: str = "name", target: str | None = None
) -> Capture:
    """Join the export's points to the log's readings (by name or by order) into a :class:`Capture`.

    Parameters
    ----------
    points : TrackerPoints
    log : JointLog
    join : {"name", "order"}
        ``"name"``: each point's name is a pose name of the log; every pose must be measured and
        every point must have a pose. A name on several rows of the log (one per target) is paired
        by occurrence: the k-th point of that name takes its k-th row; the log's ``(name, target)``
        must be unique. After the join each
        ``(name, target)`` must be unique, the target from whichever file has it: so several points,
        one per target, may share a pose name. ``"order"``: point k takes row k (equal counts);
        names are not checked.
    target : str, optional
        ``"NAME"``: one target name for every point: when neither file has a ``target`` column, or when the column
        holds one value (a reflector's serial number, as some exports write it), which it renames.
        ``"SERIAL=NAME,..."``: renames each value of the ``target`` column (every value must be named).

    Returns
    -------
    Capture
        ``circle`` and ``direction`` from the files when given (else 0 and +1: free poses), the
        ``target`` column and ``u95`` [mm] when known.
    """
    if join not in ("name", "order"):
        raise InputError(f"--join must be 'name' or 'order'; got {join!r}")
    if join == "order":
        if points.n_points != log.n_rows:
            raise InputError(
                f"joining by order needs as many points as joint readings: {points.source} has "
                f"{points.n_points} points, {log.source} has {log.n_rows} rows"
            )
        rows = np.arange(points.n_points)
    else:
        if points.names is None:
            raise InputError(f"{points.source}: no point-name column to join by name; use --join order")
        if log.names is None:
            raise InputError(f"{log.source}: no `name` column to join by name; use --join order")
        _check_pose_names(log.names, log.target, log.lines, log.source, "name")
        occurrences: dict[str, list[int]] = {}
        for k, name in enumerate(log.names):
            occurrences.setdefault(name, []).append(k)
        taken: dict[str, int] = {}
        picked = []
        for k, name in enumerate(points.names):
            index = taken.get(name, 0)
            taken[name] = index + 1
            rows_of_name = occurrences.get(name, [])
            if len(rows_of_name) == 1:  # one pose, measured on one or several targets
                index = 0
            elif points.target is not None and log.target is not None:  # both name targets: pair by them
                same = [r for r in rows_of_name if log.target[r] == points.target[k]]
                index = rows_of_name.index(same[0]) if same else index
            picked.append(rows_of_name[index] if index < len(rows_of_name) else -1)
        orphans = [k for k, row in enumerate(picked) if row < 0]
        if orphans:
            listed = ", ".join(repr(points.names[k]) for k in orphans[:5]) + (" ..." if len(orphans) > 5 else "")
            raise InputError(
                f"{points.source}: line {points.lines[orphans[0]]}: {len(orphans)} point(s) with no joint reading in "
                f"{log.source}: {listed}"
            )
        rows = np.array(picked, dtype=int)
        unused = np.setdiff1d(np.arange(log.n_rows), rows)
        if unused.size:
            listed = ", ".join(repr(log.names[k]) for k in unused[:5]) + (" ..." if unused.size > 5 else "")
            raise InputError(
                f"{log.source}: line {log.lines[unused[0]]}: {unused.size} joint reading(s) with no measured point in "
                f"{points.source}: {listed}"
            )
    targets = _pick("target", points.target, log.target, rows, points, log)
    if join == "name":
        _check_unique_names(points.names, targets, points.lines, points.source, "name")
    if target is not None:
        targets = _renamed_targets(target, targets, points.n_points)
    circle = _pick("circle", points.circle, log.circle, rows, points, log)
    direction = _pick("direction", points.direction, log.direction, rows, points, log)
    target_index: np.ndarray | None = None
    target_names: tuple[str, ...] = ()
    if targets is not None:
        target_names = tuple(dict.fromkeys(targets))
        lookup = {name: k for k, name in enumerate(target_names)}
        target_index = np.array([lookup[name] for name in targets], dtype=int)
    n = points.n_points
    return Capture(
        circle=np.zeros(n, dtype=int) if circle is None else np.asarray(circle, dtype=int),
        direction=np.ones(n, dtype=int) if direction is None else np.asarray(direction, dtype=int),
        readings=log.readings[rows],
        points=points.points,
        source=points.source,
        target=target_index,
        target_names=target_names,
        u95=points.u95,
        orientation=points.orientation,
        orientation_u95=points.orientation_u95,
    )


def _renamed_targets(target: str, targets, count: int) -> list[str]:
    """The target of every point with ``--target`` applied (:func:`join_points_to_readings`)."""
    if "=" not in target:
        name = target.strip()
        if not name:
            raise InputError("--target must be a non-empty name")
        found = sorted(set(targets)) if targets is not None else []
        if len(found) > 1:
            raise InputError(
                f"--target {name}: the files' `target` column holds {len(found)} targets ({', '.join(found[:5])}); "
                "rename each: --target VALUE=NAME,VALUE=NAME"
            )
        return [name] * count
    mapping = {}
    for item in target.split(","):
        old, separator, new = (part.strip() for part in item.partition("="))
        if not separator or not old or not new or old in mapping:
            raise InputError(f"--target must be NAME or distinct VALUE=NAME pairs separated by commas; got {target!r}")
        mapping[old] = new
    if targets is None:
        raise InputError(f"--target {target}: renames the values of a `target` column, but neither file has one")
    unnamed = sorted(set(targets) - set(mapping))
    if unnamed:
        raise InputError(f"--target: the `target` column's {', '.join(unnamed[:5])} {'is' if len(unnamed) == 1 else 'are'} not renamed; name every value")
    return [mapping[value] for value in targets]


def import_tracker_capture(
    export_path,
    joints_path,
    *,
    n_joints: int | None = None,
    columns: dict[str, str] | str | None = None,
    delimiter: str | None = None,
    decimal: str | None = None,
    units: str | None = None,
    join: str = "name",
    target: str | None = None,
    log_delimiter: str | None = None,
    log_decimal: str | None = None,
    encoding: str = "utf-8",
) -> Capture:
    """Read a tracker export and a joint-angle log and join them into a :class:`Capture` (mm, rad).

    ``delimiter``/``decimal`` apply to the export; the log's are detected unless ``log_delimiter``/
    ``log_decimal`` are given; ``encoding`` to both. See :func:`read_tracker_export`, :func:`read_joint_log`,
    :func:`join_points_to_readings`.
    """
    points = read_tracker_export(
        export_path, columns=columns, delimiter=delimiter, decimal=decimal, units=units, check_names=False,
        encoding=encoding,
    )  # fmt: skip
    log = read_joint_log(
        joints_path, n_joints=n_joints, delimiter=log_delimiter, decimal=log_decimal, check_names=False,
        encoding=encoding,
    )  # fmt: skip
    return join_points_to_readings(points, log, join=join, target=target)
