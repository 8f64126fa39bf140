"""KUKA KRL programs (KUKA System Software 8.x): read the motion targets of a ``.src`` / ``.dat`` pair, write them
back with new numbers and nothing else changed (issue 28).

The language as described in "KUKA System Software 8.x, Operating and Programming Instructions for System
Integrators" (motion statements, inline forms, aggregates, the ``$TOOL`` / ``$BASE`` system variables and ``BAS``)
and "KUKA System Software 8.x, Expert Programming" (KRL data types ``E6POS``, ``POS``, ``E6AXIS``, ``AXIS``,
``FRAME``, ``FDAT``; ``DEFDAT`` lists). KRL ignores case in keywords and names; so does this reader.

What is read
------------
- Declarations with an aggregate, in the ``.dat`` (and ``DECL`` lines of the ``.src``, and a ``$config.dat``):
  ``DECL [GLOBAL] [CONST] E6POS XP1={X 100.0,Y 200.0,...,S 6,T 27,E1 0.0}``, the same without ``DECL``
  (``E6POS XP1={...}``), element initialisations ``TOOL_DATA[1]={X ...}`` of an array declared ``DECL FRAME
  TOOL_DATA[16]``, typed aggregates ``{E6POS: X ...}``. Cartesian types ``E6POS``, ``POS``, ``FRAME``; joint types
  ``E6AXIS``, ``AXIS``; an untyped aggregate is Cartesian or joint by its components. ``FDAT`` supplies
  ``TOOL_NO``, ``BASE_NO``, ``IPO_FRAME``; ``PDAT``, ``LDAT`` and every other type are read past.
- Motions ``PTP``, ``LIN``, ``CIRC aux, end``, ``SPTP``, ``SLIN``, ``SCIRC aux, end``, ``SPL`` to a declared point
  (``PTP XP1``, ``LIN XPOS[3]``) or to an inline aggregate (``LIN {X 400, Y 0, Z 300, A 0, B 90, C 0}``), with any
  trailing words (``C_PTP``, ``C_DIS``, ``, CA 90``, ``WITH ...``).
- The tool and base in force, in the order of the ``.src`` lines: ``$TOOL = TOOL_DATA[1]``, ``$BASE =
  BASE_DATA[2]``, ``$TOOL = $NULLFRAME`` (the flange), ``$BASE = $WORLD`` or ``$NULLFRAME`` (the robot's base:
  robotcal assumes ``$ROBROOT`` is the world frame), a user frame ``$BASE = MY_TABLE``, ``BAS(#TOOL, 1)``,
  ``BAS(#BASE, 2)``, ``FDAT_ACT = FP1`` of the inline forms (``TOOL_NO 0`` / ``BASE_NO 0``: flange / robot base),
  ``$IPO_MODE``, and a spline motion's ``WITH $TOOL = STOOL2(FP1), $BASE = SBASE(FP1.BASE_NO)`` (for that motion
  only).

What is listed in :attr:`~robotcal.programs.base.Program.skipped` instead
-----------------------------------------------------------------------
Relative motions (``PTP_REL``, ``LIN_REL``...); targets that are expressions (``LIN XP1 : $NULLFRAME``, function
calls, ``$POS_ACT``, an inline component that is not a literal number); aggregates that give only some of the six
components; a point declared in none of the files read; a Cartesian target whose tool or base is unknown (none
selected before it, or selected by an expression, an FDAT declared nowhere) or that moves with an external TCP
(``IPO_FRAME #TCP``). Warnings, with the point still read: a declared point used with another tool or base than at
its first use (its numbers are filtered for the first use's tool and base), a declared point the ``.src`` changes at
run time, and a declared point no motion uses (not in ``points``).

The program order is the order of the ``.src`` lines: control flow (``IF``, loops, subprogram calls) is not followed.
Points are listed in the order of their first use.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.geometry.euler import GIMBAL_TOLERANCE, kuka_abc_from_matrix, matrix_from_kuka_abc
from robotcal.programs.base import NumberSpan, Program, ProgramPoint, format_number, joint_values, read_program_text

__all__ = ["DECIMALS", "JOINT_DECIMALS", "IntegerSpan", "read_program", "render"]

#: Decimals written for mm and degrees (a round trip reproduces the value to 5e-7).
DECIMALS = 6
#: Decimals of axis values [deg]: 5e-9 deg of rounding moves a 1 m arm's tool by under 1e-7 mm per axis (6 decimals
#: would leave up to 6e-6 mm over six axes).
JOINT_DECIMALS = 8

_CARTESIAN = ("X", "Y", "Z", "A", "B", "C")
_AXES = ("A1", "A2", "A3", "A4", "A5", "A6")
_CONFIG = ("S", "T")
_CARTESIAN_TYPES = frozenset({"E6POS", "POS", "FRAME"})
_JOINT_TYPES = frozenset({"E6AXIS", "AXIS"})
#: A KRL REAL or INT literal as a target component (``1.5``, ``-2``, ``1.0E+02``, ``.5``).
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
#: A KRL INT literal for S and T: decimal, binary ``'B010'`` / ``'B 010'``, or hexadecimal ``'H1B'``.
_INTEGER = re.compile(r"\+?(?P<decimal>\d+)|'(?P<radix>[BbHh])\s*(?P<digits>[0-9A-Fa-f]+)'")
_NAME = re.compile(r"\$?[A-Za-z_][\w$]*")
_COMPONENT_NAME = re.compile(r"[A-Za-z_$][\w$]*(?:\[[^\]]*\])?")
_TYPE_PREFIX = re.compile(r"\s*([A-Za-z_$][\w$]*)\s*:")
_DECLARATION = re.compile(
    r"\s*(?P<decl>DECL\s+)?(?:(?:GLOBAL|CONST)\s+)*(?:(?P<type>[A-Za-z_]\w*)\s+)?"
    r"(?P<name>[A-Za-z_$][\w$]*\s*(?:\[[^\]]*\])?)\s*=\s*(?=\{)",
    re.IGNORECASE,
)
_TYPE_ONLY = re.compile(
    r"\s*(?:DECL\s+)?(?:(?:GLOBAL|CONST)\s+)*(?P<type>E6POS|POS|E6AXIS|AXIS|FRAME)\s+(?P<names>[^=]+)$", re.IGNORECASE
)
_MOTION = re.compile(r"\s*(?P<keyword>SPTP|SLIN|SCIRC|SPL|PTP|LIN|CIRC)(?P<relative>_REL)?(?![\w$])", re.IGNORECASE)
_SYSTEM_FRAME = re.compile(r"\s*\$(?P<which>TOOL|BASE|IPO_MODE)\s*=(?!=)\s*(?P<value>.*?)\s*$", re.IGNORECASE)
_BAS_FRAME = re.compile(r"\s*BAS\s*\(\s*#(?P<which>TOOL|BASE)\s*,\s*(?P<value>[^)]*?)\s*\)\s*$", re.IGNORECASE)
_FDAT_ACT = re.compile(r"\s*FDAT_ACT\s*=(?!=)\s*(?P<value>.*?)\s*$", re.IGNORECASE)
_ASSIGNMENT = re.compile(r"\s*(?P<name>[A-Za-z_]\w*\s*(?:\[[^\]]*\])?)\s*(?:\.\s*[A-Za-z_]\w*\s*)*=(?!=)")
_WITH = re.compile(r"(?<![\w$])WITH(?![\w$])", re.IGNORECASE)


@dataclass(frozen=True, slots=True)
class IntegerSpan(NumberSpan):
    """Where an integer (KRL ``S``, ``T``) sits, and how it is written: ``radix`` 10 (``6``), 2 (``'B010'``) or 16
    (``'H1B'``); for radix 2 and 16 the span covers the digits only (``010``) and ``digits`` is their count, so that
    :func:`render` writes a new value in the same notation and width.

    Not in :mod:`robotcal.programs.base`: only KRL writes integers in more than one notation.
    """

    radix: int = 10
    digits: int = 1


@dataclass(frozen=True, slots=True)
class _Line:
    file: str
    number: int
    start: int  # offset of the line's first character in the file's text
    code: str  # the line without its end and its comment

    @property
    def where(self) -> str:
        return f"{self.file}, line {self.number}"


@dataclass(frozen=True, slots=True)
class _Value:
    text: str
    start: int  # offsets in the file's text
    end: int
    nested: _Aggregate | None


@dataclass(frozen=True, slots=True)
class _Aggregate:
    line: _Line
    type_name: str | None
    values: dict[str, _Value]


@dataclass(frozen=True, slots=True)
class _Declaration:
    label: str  # as written, blanks removed
    type_name: str | None
    aggregate: _Aggregate


@dataclass(frozen=True, slots=True)
class _Frame:
    """A tool or base in force: ``name`` (None: flange / robot base), or why it is unknown."""

    name: str | None = None
    problem: str | None = None


@dataclass(frozen=True, slots=True)
class _Target:
    text: str
    name: str | None = None  # a point's name as written
    aggregate: _Aggregate | None = None

    @property
    def simple(self) -> bool:
        """A name or an aggregate, not an expression."""
        return self.name is not None or self.aggregate is not None


def read_program(
    src_path: str | os.PathLike[str], *, dat_path: str | os.PathLike[str] | None = None,
    config_dat: str | os.PathLike[str] | None = None, encoding: str = "utf-8",
) -> Program:
    """Read a KRL program: its ``.src``, its ``.dat`` and, optionally, a ``$config.dat``.

    Parameters
    ----------
    src_path : path-like
        The ``.src`` file.
    dat_path : path-like, optional
        Its data list. Default: the file beside it with the same stem and the extension ``.dat`` in any case
        (``weld.src`` -> ``weld.dat`` or ``weld.DAT``); none there is fine (points declared nowhere are then
        listed in ``skipped``). A ``dat_path`` given must exist.
    config_dat : path-like, optional
        A ``$config.dat`` (or an excerpt) declaring ``TOOL_DATA[n]``, ``BASE_DATA[n]`` and global points.
    encoding : str
        Text encoding of all files (KUKA controllers often write ``cp1252``).

    Returns
    -------
    Program
        ``language="krl"``; ``texts`` keyed by file name (``"weld.src"``, ``"weld.dat"``...); ``points`` in the order
        of their first use, each declared point once (``label`` its name as written in its declaration, ``file`` /
        ``line`` where its numbers are), each inline aggregate on its own (``label`` ``"<file>:<line>"``, the
        auxiliary point of a circular motion ``"<file>:<line> aux"``); ``values`` ``X, Y, Z, A, B, C`` [mm, deg] or
        ``A1..A6`` [deg] (external axes ``E1..E6`` are read past), ``config`` ``S`` / ``T`` where written (spans
        are :class:`IntegerSpan`); ``tool`` / ``base`` ``"TOOL_DATA[1]"``, ``"BASE_DATA[2]"``, a user frame's name
        in upper case, or None for the flange / robot base; ``frames``: every complete ``TOOL_DATA[n]`` /
        ``BASE_DATA[n]`` of the files read and the user frames the program selects (a frame declared nowhere is
        absent); ``skipped``: see the module's docstring.

    Raises
    ------
    InputError
        A file missing or not decodable, an unterminated or malformed aggregate, a bad number in a point, a point
        declared twice in one file, a circular motion with one point, a motion without a target: the message names
        the file and line.
    """
    src_path = Path(src_path)
    if dat_path is None:
        dat_path = _beside(src_path)
    paths = [("src", src_path), ("dat", None if dat_path is None else Path(dat_path))]
    if config_dat is not None:
        paths.append(("config", Path(config_dat)))
    texts: dict[str, str] = {}
    lines: dict[str, list[_Line]] = {}
    names: dict[str, str] = {}
    for role, path in paths:
        if path is None:
            continue
        if path.name in texts:
            raise InputError(f"{path}: two of the files read are named {path.name!r}; rename one")
        texts[path.name] = read_program_text(path, encoding, "file")
        lines[role] = _split_lines(path.name, texts[path.name])
        names[role] = path.name

    array_types: dict[str, str] = {}
    for role in ("config", "dat", "src"):
        for line in lines.get(role, ()):
            _note_array_types(line, array_types)
    declarations: dict[str, dict[str, _Declaration]] = {
        role: _declarations(lines.get(role, ()), array_types, strict=True, declared_only=role == "src")
        for role in ("src", "dat", "config")
    }
    reader = _Reader(names, declarations)
    for line in lines["src"]:
        reader.statement(line)
    reader.unused()
    return Program(
        language="krl", texts=texts, points=list(reader.points.values()), frames=reader.frames(), skipped=reader.skipped
    )


def render(
    point: ProgramPoint, *, frame_mm: ArrayLike | None = None, joints_deg: ArrayLike | None = None,
    config: Mapping[str, int] | None = None,
) -> dict[NumberSpan, str]:
    """KRL's :class:`~robotcal.programs.base.Render`: the new text of every number of a KRL ``point``.

    ``frame_mm`` (the tool frame in the point's base) writes ``X, Y, Z`` and the ``A, B, C`` triple nearest the
    point's present angles among the equivalent ones (``(A + 180, 180 - B, C + 180)``; at ``B = +-90`` every split of
    ``A -+ C``), each within [-180, 180] deg, with :data:`DECIMALS` decimals. ``joints_deg`` writes ``A1..A6`` with
    :data:`JOINT_DECIMALS` decimals (KRL cannot write axis values into an ``E6POS``). ``config``: new ``S`` / ``T``,
    written only where they differ from the point's and the point writes them, in the point's notation (``'B010'``
    stays binary, with at least as many digits); keys the point does not write are left out (no number to change).
    """
    out: dict[NumberSpan, str] = {}
    if point.kind == "cartesian":
        if frame_mm is None or joints_deg is not None:
            raise InputError(
                f"point {point.label!r} ({point.file}, line {point.line}) is Cartesian: give frame_mm, not joints_deg "
                "(KRL cannot write axis values into a Cartesian point)"
            )
        frame = _check_frame(frame_mm, point)
        angles = _abc_near(frame, point.values[3:6])
        new: tuple | np.ndarray = (*frame[:3, 3], *angles)
    else:
        if joints_deg is None or frame_mm is not None:
            raise InputError(
                f"point {point.label!r} ({point.file}, line {point.line}) is a joint point: give joints_deg, not frame_mm"
            )
        new = joint_values(point, joints_deg)
    decimals = DECIMALS if point.kind == "cartesian" else JOINT_DECIMALS
    for span, value in zip(point.spans, new, strict=True):
        out[span] = format_number(float(value), decimals)
    for key, value in (config or {}).items():
        name = str(key).upper()
        if name not in _CONFIG:
            raise InputError(f"KRL points have configuration S and T; got {key!r}")
        try:
            whole = not isinstance(value, bool) and float(value).is_integer() and value >= 0
        except (TypeError, ValueError):
            whole = False
        if not whole:
            raise InputError(f"{name} must be a whole number >= 0; got {value!r}")
        if name in point.config_spans and int(value) != point.config[name]:
            out[point.config_spans[name]] = _format_integer(int(value), point.config_spans[name])
    return out


# ----------------------------------------------------------------------------------------------------------- files


def _beside(src_path: Path) -> Path | None:
    """The ``.dat`` beside ``src_path``: same stem, extension in any case (the stem's case too, if unique)."""
    wanted = (src_path.stem + ".dat").lower()
    try:
        found = [path for path in src_path.parent.iterdir() if path.name.lower() == wanted and path.is_file()]
    except OSError:
        return None
    exact = [path for path in found if path.stem == src_path.stem]
    if len(found) > 1 and len(exact) != 1:
        raise InputError(f"{src_path}: several data lists beside it ({', '.join(sorted(p.name for p in found))})")
    chosen = exact or found
    return chosen[0] if chosen else None


def _split_lines(name: str, text: str) -> list[_Line]:
    """Every line of ``text`` with its comment cut off (``;`` outside quotes; ``;FOLD`` lines are comments)."""
    out = []
    for number, match in enumerate(re.finditer(r"[^\r\n]*(?:\r\n|\r|\n)?", text), start=1):
        if match.start() == match.end():
            break
        body = match.group().rstrip("\r\n").replace("\ufeff", " ")
        quote, end = None, len(body)
        for index, char in enumerate(body):
            if quote:
                quote = None if char == quote else quote
            elif char in "\"'":
                quote = char
            elif char == ";":
                end = index
                break
        out.append(_Line(name, number, match.start(), body[:end]))
    return out


# ------------------------------------------------------------------------------------------------------ aggregates


def _skip_blanks(code: str, index: int) -> int:
    while index < len(code) and code[index] in " \t\f\v":
        index += 1
    return index


def _parse_aggregate(line: _Line, index: int) -> tuple[_Aggregate, int]:
    """The aggregate ``{...}`` starting at ``line.code[index]``, and the index after its ``}``."""
    code = line.code
    index += 1
    type_name = None
    prefix = _TYPE_PREFIX.match(code, index)
    if prefix:
        type_name, index = prefix.group(1).upper(), prefix.end()
    values: dict[str, _Value] = {}
    index = _skip_blanks(code, index)
    if index < len(code) and code[index] == "}":
        return _Aggregate(line, type_name, values), index + 1
    while True:
        index = _skip_blanks(code, index)
        if index >= len(code):
            raise InputError(f"{line.where}: unterminated aggregate (no closing '}}' on the line)")
        match = _COMPONENT_NAME.match(code, index)
        if not match:
            raise InputError(f"{line.where}: malformed aggregate: expected a component name at {code[index:][:20]!r}")
        name = re.sub(r"\s+", "", match.group()).upper()
        index = _skip_blanks(code, match.end())
        if index < len(code) and code[index] == "{":
            nested, end = _parse_aggregate(line, index)
            value = _Value(code[index:end], line.start + index, line.start + end, nested)
        else:
            end = _value_end(line, index)
            text = code[index:end].rstrip()
            if not text:
                raise InputError(f"{line.where}: malformed aggregate: component {name} has no value")
            value = _Value(text, line.start + index, line.start + index + len(text), None)
        if name in values:
            raise InputError(f"{line.where}: component {name} appears twice in one aggregate")
        values[name] = value
        index = _skip_blanks(code, end)
        if index >= len(code):
            raise InputError(f"{line.where}: unterminated aggregate (no closing '}}' on the line)")
        if code[index] == "}":
            return _Aggregate(line, type_name, values), index + 1
        if code[index] != ",":
            raise InputError(f"{line.where}: malformed aggregate: expected ',' or '}}' at {code[index:][:20]!r}")
        index += 1


def _unquoted(text: str, start: int, opens: str, closes: str) -> Iterator[tuple[int, str, int]]:
    """``(position, char, depth)`` of every character of ``text`` from ``start`` that is neither quoted nor a bracket
    of ``opens`` / ``closes``; ``depth`` counts the brackets open before it."""
    depth, quote = 0, None
    for position in range(start, len(text)):
        char = text[position]
        if quote:
            quote = None if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in opens:
            depth += 1
        elif char in closes:
            depth -= 1
        else:
            yield position, char, depth


def _value_end(line: _Line, index: int) -> int:
    """Index of the ``,`` or ``}`` that ends the component value starting at ``index``."""
    for position, char, depth in _unquoted(line.code, index, "([", ")]"):
        if char in ",}" and depth <= 0:
            return position
    raise InputError(f"{line.where}: unterminated aggregate (no closing '}}' on the line)")


def _note_array_types(line: _Line, array_types: dict[str, str]) -> None:
    """``DECL FRAME TOOL_DATA[16]``, ``DECL E6POS XP1``: remember the type of each name declared without a value."""
    if "=" in line.code:
        return
    match = _TYPE_ONLY.match(line.code)
    if match:
        for name in re.finditer(r"([A-Za-z_$][\w$]*)\s*(?:\[[^\]]*\])?", match.group("names")):
            array_types[name.group(1).upper()] = match.group("type").upper()


def _declarations(lines, array_types, *, strict: bool, declared_only: bool) -> dict[str, _Declaration]:
    """Every ``[DECL] [type] name = {aggregate}`` of a file (only ``DECL`` lines when ``declared_only``)."""
    out: dict[str, _Declaration] = {}
    for line in lines:
        match = _DECLARATION.match(line.code)
        if not match or (declared_only and not match.group("decl")):
            continue
        label = re.sub(r"\s+", "", match.group("name"))
        key = label.upper()
        type_name = (match.group("type") or "").upper() or array_types.get(key.split("[")[0])
        aggregate, end = _parse_aggregate(line, match.end())
        if line.code[end:].strip():
            raise InputError(f"{line.where}: unexpected text after the aggregate: {line.code[end:].strip()[:30]!r}")
        type_name = type_name or aggregate.type_name
        if key in out:
            raise InputError(
                f"{line.where}: {label} is declared twice in {line.file} (also line {out[key].aggregate.line.number})"
            )
        declaration = _Declaration(label, type_name, aggregate)
        kind = _kind(aggregate, type_name)
        if kind is not None:
            _numbers(aggregate, kind, strict=strict)  # a bad number is an error even in a point no motion uses
        out[key] = declaration
    return out


def _kind(aggregate: _Aggregate, type_name: str | None) -> Literal["cartesian", "joint"] | None:
    """``"cartesian"``, ``"joint"`` or None (not a position) of an aggregate of type ``type_name``."""
    if type_name in _CARTESIAN_TYPES:
        return "cartesian"
    if type_name in _JOINT_TYPES:
        return "joint"
    if type_name is not None:
        return None
    names = set(aggregate.values)
    cartesian, joint = names & {*_CARTESIAN, *_CONFIG}, names & set(_AXES)
    if cartesian and not joint:
        return "cartesian"
    if joint and not cartesian:
        return "joint"
    return None


def _numbers(aggregate: _Aggregate, kind: str, *, strict: bool):
    """The numbers of a position aggregate: ``(values, spans, config, config_spans)``, or a str saying why it cannot
    be filtered (a component missing or not a literal). Bad numbers raise; a non-literal raises when ``strict``."""
    line = aggregate.line
    names = _CARTESIAN if kind == "cartesian" else _AXES
    other = _AXES if kind == "cartesian" else (*_CARTESIAN, *_CONFIG)
    present = [name for name in names if name in aggregate.values]
    values, spans, config, config_spans = [], [], {}, {}
    problem = None
    for name in [*present, *(c for c in _CONFIG if kind == "cartesian" and c in aggregate.values)]:
        value = aggregate.values[name]
        number = _NUMBER.fullmatch(value.text) if name not in _CONFIG else _INTEGER.fullmatch(value.text)
        if number is None:
            if value.nested is not None or value.text[0] in "+-.0123456789'":
                raise InputError(f"{line.where}: bad number {value.text!r} for {name}")
            if strict:
                raise InputError(f"{line.where}: {name} {value.text!r} is not a literal number")
            problem = problem or f"component {name} is not a literal number ({value.text})"
            continue
        if name in _CONFIG:
            radix = {"B": 2, "H": 16}.get((number.group("radix") or "").upper(), 10)
            group = "decimal" if radix == 10 else "digits"
            try:
                config[name] = int(number.group(group), radix)
            except ValueError:
                raise InputError(f"{line.where}: bad number {value.text!r} for {name}") from None
            config_spans[name] = IntegerSpan(
                line.file,
                value.start + number.start(group),
                value.start + number.end(group),
                radix=radix,
                digits=len(number.group(group)),
            )
        else:
            values.append(float(value.text))
            spans.append(NumberSpan(line.file, value.start, value.end))
    if problem:
        return problem
    mixed = [name for name in other if name in aggregate.values]
    if mixed:
        return f"holds {', '.join(mixed)}, which a {kind} target has not"
    if len(present) < len(names):
        given = ", ".join(present) or "none of them"
        return f"gives only some components ({given}; a {kind} target needs {', '.join(names)})"
    return tuple(values), tuple(spans), config, config_spans


def _frame_from(values) -> np.ndarray:
    """4x4 of ``X, Y, Z`` [mm] and ``A, B, C`` [deg]: ``R = Rz(A) Ry(B) Rx(C)``."""
    frame = np.eye(4)
    frame[:3, :3] = matrix_from_kuka_abc(np.deg2rad(values[3:6]))
    frame[:3, 3] = values[:3]
    return frame


# ----------------------------------------------------------------------------------------------------- the program


class _Reader:
    """Walks the ``.src`` lines in order, keeping the tool and base in force."""

    def __init__(self, names: dict[str, str], declarations: dict[str, dict[str, _Declaration]]):
        self.names = names
        self.declarations = declarations
        self.src = names["src"]
        self.tool = _Frame(problem=f"no tool is selected in {self.src} before this motion")
        self.base = _Frame(problem=f"no base is selected in {self.src} before this motion")
        self.ipo: str | None = None
        self.points: dict[str, ProgramPoint] = {}  # declared points by key, inline ones by label
        self.first_use: dict[str, tuple[int, str | None, str | None]] = {}
        self.used: set[str] = set()
        self.selected_frames: set[str] = set()
        self.skipped: list[tuple[str, int, str]] = []
        self.point_keys = {
            key
            for table in declarations.values()
            for key, item in table.items()
            if _kind(item.aggregate, item.type_name) is not None
        }

    def skip(self, line: _Line, why: str) -> None:
        self.skipped.append((line.file, line.number, why))

    # --- look-ups

    def declaration(self, key: str) -> _Declaration | None:
        for role in ("src", "dat", "config"):
            if key in self.declarations[role]:
                return self.declarations[role][key]
        return None

    def fdat(self, name: str, line: _Line) -> tuple[_Frame, _Frame, str | None]:
        """Tool, base and external-TCP problem of the FDAT ``name``."""
        found = self.declaration(name.strip().upper())
        if found is None or found.type_name not in (None, "FDAT"):
            why = f"FDAT {name.strip()} ({line.where}) is " + (
                "declared in none of the files read" if found is None else f"a {found.type_name}, not an FDAT"
            )
            return _Frame(problem=why), _Frame(problem=why), None
        values = found.aggregate.values
        out = []
        for which, component in (("TOOL", "TOOL_NO"), ("BASE", "BASE_NO")):
            text = values[component].text if component in values else ""
            if re.fullmatch(r"\+?\d+", text):
                number = int(text)
                out.append(_Frame(name=f"{which}_DATA[{number}]" if number else None))
            else:
                out.append(_Frame(problem=f"{component} of FDAT {name} is not a number ({line.where})"))
        ipo = values.get("IPO_FRAME")
        tcp = ipo is not None and ipo.text.strip().upper() == "#TCP"
        return out[0], out[1], f"external TCP (IPO_FRAME #TCP in FDAT {name}, {line.where})" if tcp else None

    def frame_reference(self, which: str, value: str, line: _Line) -> _Frame:
        """The tool or base named by the right-hand side of ``$TOOL = ...`` / ``$BASE = ...``."""
        compact = re.sub(r"\s+", "", value).upper()
        if compact in ("$NULLFRAME", "$WORLD"):
            return _Frame()
        match = re.fullmatch(r"STOOL2\((\w+)\)" if which == "TOOL" else r"SBASE\((\w+)\.BASE_NO\)", compact)
        if match:
            tool, base, _ = self.fdat(match.group(1), line)
            return tool if which == "TOOL" else base
        if re.fullmatch(r"[A-Z_]\w*(?:\[\d+\])?", compact) and not compact.startswith("$"):
            self.selected_frames.add(compact)
            return _Frame(name=compact)
        return _Frame(problem=f"${which} is set by an expression ({value.strip()}) at {line.where}")

    def ipo_reference(self, value: str, line: _Line) -> str | None:
        compact = re.sub(r"\s+", "", value).upper()
        if compact == "#BASE":
            return None
        if compact == "#TCP":
            return f"external TCP ($IPO_MODE = #TCP at {line.where})"
        match = re.fullmatch(r"SIPO_MODE\((\w+)\.IPO_FRAME\)", compact)
        if match:
            return self.fdat(match.group(1), line)[2]
        return f"$IPO_MODE is set by an expression ({value.strip()}) at {line.where}"

    # --- statements

    def statement(self, line: _Line) -> None:
        code = line.code
        if not code.strip():
            return
        motion = _MOTION.match(code)
        if motion:
            self.motion(line, motion)
            return
        match = _SYSTEM_FRAME.match(code)
        if match:
            which, value = match.group("which").upper(), match.group("value")
            if which == "IPO_MODE":
                self.ipo = self.ipo_reference(value, line)
            elif which == "TOOL":
                self.tool = self.frame_reference("TOOL", value, line)
            else:
                self.base = self.frame_reference("BASE", value, line)
            return
        match = _BAS_FRAME.match(code)
        if match:
            which, value = match.group("which").upper(), match.group("value")
            if re.fullmatch(r"\+?\d+", value):
                frame = _Frame(name=f"{which}_DATA[{int(value)}]" if int(value) else None)
            else:
                frame = _Frame(problem=f"BAS(#{which}, {value}) selects a number given by an expression ({line.where})")
            if which == "TOOL":
                self.tool = frame
            else:
                self.base = frame
            return
        match = _FDAT_ACT.match(code)
        if match:
            self.tool, self.base, self.ipo = self.fdat(match.group("value"), line)
            return
        match = _ASSIGNMENT.match(code)
        if match and not re.match(r"\s*DECL\b", code, re.IGNORECASE):
            key = re.sub(r"\s+", "", match.group("name")).upper()
            if key in self.point_keys:
                self.skip(
                    line,
                    f"{match.group('name').strip()} is changed at run time here; its "
                    "declared numbers are filtered, not the values this line gives it",
                )

    def motion(self, line: _Line, motion: re.Match) -> None:
        code = line.code
        keyword = motion.group("keyword").upper()
        rest = code[motion.end() :].strip()
        if not rest:
            raise InputError(f"{line.where}: {keyword} without a target")
        for name in re.finditer(r"([A-Za-z_][\w$]*)(?:\s*\[([\d\s,]+)\])?", rest):
            subscript = re.sub(r"\s+", "", name.group(2) or "")
            self.used.add(name.group(1).upper() + (f"[{subscript}]" if subscript else ""))
        if motion.group("relative"):
            self.skip(line, f"{keyword}_REL {rest}: a relative motion; not filtered")
            return
        circular = keyword in ("CIRC", "SCIRC")
        first, index = _target(line, motion.end())
        targets = [first]
        if circular and first.simple:
            if index >= len(code):
                raise InputError(f"{line.where}: {keyword} needs an auxiliary point and an end point")
            if code[index] == ",":
                second, index = _target(line, index + 1)
                targets.append(second)
        follow = code[index : index + 1]
        allowed = not follow or re.match(r"[A-Za-z_]", follow) or (circular and follow == ",")
        if not (all(target.simple for target in targets) and len(targets) == 1 + circular and allowed):
            self.skip(line, f"{keyword} target is an expression ({rest}); not filtered")
            return
        tool, base, ipo = self.tool, self.base, self.ipo
        trailing = code[index:]
        with_clause = _WITH.search(trailing)
        if with_clause:
            for part in _split_top_level(trailing[with_clause.end() :]):
                left, _, right = part.partition("=")
                which = left.strip().upper()
                if which == "$TOOL":
                    tool = self.frame_reference("TOOL", right, line)
                elif which == "$BASE":
                    base = self.frame_reference("BASE", right, line)
                elif which == "$IPO_MODE":
                    ipo = self.ipo_reference(right, line)
        for position, target in enumerate(targets):
            auxiliary = circular and position == 0
            self.target(line, keyword, target, auxiliary, tool, base, ipo)

    def target(self, line, keyword, target: _Target, auxiliary: bool, tool: _Frame, base: _Frame, ipo) -> None:
        if target.aggregate is not None:
            aggregate, label = target.aggregate, f"{line.file}:{line.number}" + (" aux" if auxiliary else "")
            key = label
            kind = _kind(aggregate, aggregate.type_name)
            if kind is None:
                self.skip(line, f"{keyword} {target.text}: not a position aggregate")
                return
        else:
            assert target.name is not None  # a simple target: a name when not an aggregate
            key = re.sub(r"\s+", "", target.name).upper()
            if key.startswith("$"):
                self.skip(line, f"{keyword} {target.name}: a system variable, not a point of the program")
                return
            if "[" in key and not re.fullmatch(r"[^\[]+\[\d+(?:,\d+)*\]", key):
                self.skip(line, f"{keyword} {target.name}: the index is an expression; not filtered")
                return
            declaration = self.declaration(key)
            if declaration is None:
                files = " or ".join(self.names[role] for role in ("dat", "config") if role in self.names)
                self.skip(line, f"{target.name} is declared in none of the files read ({files or 'no .dat'})")
                return
            aggregate, label = declaration.aggregate, declaration.label
            kind = _kind(aggregate, declaration.type_name)
            if kind is None:
                self.skip(line, f"{keyword} {target.name}: {label} is a {declaration.type_name}, not a position")
                return
        numbers = _numbers(aggregate, kind, strict=False)
        if isinstance(numbers, str):
            self.skip(line, f"{keyword} {target.text}: {numbers}; not filtered")
            return
        if kind == "cartesian":
            problems = [frame.problem for frame in (tool, base) if frame.problem] + ([ipo] if ipo else [])
            if problems:
                self.skip(line, f"{keyword} {target.text}: {'; '.join(problems)}")
                return
        if key in self.points:
            first_line, first_tool, first_base = self.first_use[key]
            if kind == "cartesian" and (first_tool, first_base) != (tool.name, base.name):
                self.skip(
                    line,
                    f"{label} is used here with tool {tool.name}, base {base.name}, but with "
                    f"tool {first_tool}, base {first_base} at line {first_line}; its numbers are filtered for the "
                    "first use only",
                )
            return
        values, spans, config, config_spans = numbers
        self.points[key] = ProgramPoint(
            label=label,
            file=aggregate.line.file,
            line=aggregate.line.number,
            kind=kind,
            values=values,
            spans=spans,
            frame_mm=_frame_from(values) if kind == "cartesian" else None,
            joints_deg=np.array(values) if kind == "joint" else None,
            config=config,
            config_spans=config_spans,
            tool=tool.name,
            base=base.name,
            motion=keyword,
        )
        self.first_use[key] = (line.number, tool.name, base.name)

    # --- results

    def unused(self) -> None:
        for role in ("src", "dat"):
            for key, item in self.declarations[role].items():
                kind = _kind(item.aggregate, item.type_name)
                frame = item.type_name == "FRAME" or key.startswith(("TOOL_DATA[", "BASE_DATA["))
                if kind is None or frame or key in self.used or key in self.selected_frames:
                    continue
                line = item.aggregate.line
                self.skip(line, f"{item.label} declared, used by no motion")

    def frames(self) -> dict[str, np.ndarray]:
        out = {}
        for role in ("config", "dat", "src"):
            for key, item in self.declarations[role].items():
                if not (key.startswith(("TOOL_DATA[", "BASE_DATA[")) or key in self.selected_frames):
                    continue
                numbers = _numbers(item.aggregate, "cartesian", strict=False)
                if not isinstance(numbers, str) and _kind(item.aggregate, item.type_name) == "cartesian":
                    out[key] = _frame_from(numbers[0])
        return out


def _target(line: _Line, index: int) -> tuple[_Target, int]:
    """The motion target starting at ``line.code[index]`` (a name, a name with an index, an aggregate; else an
    expression: ``_Target`` with neither) and the index of the next non-blank character after it."""
    code = line.code
    index = _skip_blanks(code, index)
    if index >= len(code):
        raise InputError(f"{line.where}: a motion without a target")
    if code[index] == "{":
        aggregate, end = _parse_aggregate(line, index)
        return _Target(code[index:end], aggregate=aggregate), _skip_blanks(code, end)
    match = _NAME.match(code, index)
    if not match:
        return _Target(code[index:].strip()), len(code)
    end = _skip_blanks(code, match.end())
    if end < len(code) and code[end] == "[":
        close = code.find("]", end)
        if close < 0:
            raise InputError(f"{line.where}: unterminated index (no closing ']')")
        end = close + 1
    else:
        end = match.end()
    return _Target(code[index:end], name=code[index:end]), _skip_blanks(code, end)


def _split_top_level(text: str) -> list[str]:
    """``text`` split at the commas outside brackets and quotes (the assignments of a ``WITH`` clause)."""
    parts, start = [], 0
    for position, char, depth in _unquoted(text, 0, "([{", ")]}"):
        if char == "," and depth == 0:
            parts.append(text[start:position])
            start = position + 1
    parts.append(text[start:])
    return parts


# ---------------------------------------------------------------------------------------------------------- render


def _check_frame(frame_mm, point: ProgramPoint) -> np.ndarray:
    frame = np.asarray(frame_mm, dtype=float)
    if frame.shape != (4, 4) or not np.all(np.isfinite(frame)):
        raise InputError(
            f"point {point.label!r}: frame_mm must be a finite 4x4 transform [mm]; got shape {frame.shape}"
        )
    rotation = frame[:3, :3]
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-6) or np.linalg.det(rotation) <= 0:
        raise InputError(f"point {point.label!r}: the rotation of frame_mm is not a proper rotation")
    return frame


def _abc_near(frame: np.ndarray, reference_deg) -> np.ndarray:
    """KUKA ``A, B, C`` [deg] of ``frame``'s rotation, the equivalent triple nearest ``reference_deg``, each in
    [-180, 180]."""
    reference = np.asarray(reference_deg, dtype=float)
    a, b, c = np.rad2deg(kuka_abc_from_matrix(frame))
    if np.hypot(frame[0, 0], frame[1, 0]) < GIMBAL_TOLERANCE:
        # B = +-90: only A - C (B = +90) or A + C (B = -90) is fixed; split it as the reference does
        sign = 1.0 if b > 0 else -1.0
        triples = []
        for turns in (-1, 0, 1):
            shift = (reference[0] - a + 360.0 * turns + sign * reference[2]) / 2.0
            triples.append((a + shift, b, sign * shift))
    else:
        triples = [(a, b, c), (a + 180.0, 180.0 - b, c + 180.0)]
    best, best_distance = None, np.inf
    for triple in triples:
        choices = [
            [value + 360.0 * turns for turns in range(-3, 4) if abs(value + 360.0 * turns) <= 180.0 + 1e-9]
            for value in triple
        ]
        for candidate in np.array(np.meshgrid(*choices, indexing="ij")).reshape(3, -1).T:
            distance = float(np.sum((candidate - reference) ** 2))
            if distance < best_distance:
                best, best_distance = candidate, distance
    assert best is not None  # every triple has candidates within +-180 deg
    return best


def _format_integer(value: int, span: NumberSpan) -> str:
    radix = getattr(span, "radix", 10)
    if radix == 10:
        return str(value)
    text = format(value, "b" if radix == 2 else "X")
    return text.zfill(getattr(span, "digits", 1))
