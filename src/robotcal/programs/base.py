"""What the robot-program readers share: a program as its files' exact text, the points in it, and a writer that
changes numbers only (issue 28, "the robot's own programs in, the same programs out").

A reader (:mod:`robotcal.programs.krl`, :mod:`~robotcal.programs.rapid`, :mod:`~robotcal.programs.urscript`) keeps
every file's text exactly as read and records, for each motion target, where each of its numbers sits (a
:class:`NumberSpan`). Filtering replaces those spans and nothing else (:func:`replace_numbers`), so a diff of the input
and the output shows numbers only: comments, speeds, I/O, blank lines and line endings stay byte-identical.

Units: every :class:`ProgramPoint` carries its target in robotcal's units whatever the language writes
(``frame_mm``: the tool frame in the program's base/work-object frame, 4x4, mm; ``joints_deg``: controller axis
values, degrees), next to the numbers as written (``values``, in the language's own units).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError

__all__ = [
    "NumberSpan", "ProgramPoint", "Program", "Render", "replace_numbers", "format_number", "read_program_text",
    "joint_values",
]  # fmt: skip


@dataclass(frozen=True, slots=True)
class NumberSpan:
    """Where one number sits: ``texts[file][start:end]`` of a :class:`Program` is its text as written."""

    file: str
    start: int
    end: int


@dataclass(frozen=True, slots=True, kw_only=True)
class ProgramPoint:
    """One motion target of a program.

    Attributes
    ----------
    label : str
        The user's name for it: the declared point name (``XP1``, ``p10``, ``home``), else ``"<file>:<line>"`` for an
        inline literal.
    file : str
        Key into :attr:`Program.texts` of the file that holds its numbers.
    line : int
        1-based line of its numbers in that file (for messages and the per-point table).
    kind : {"cartesian", "joint"}
    values : tuple of float
        The numbers as written, in the language's units and order (KRL ``X, Y, Z, A, B, C`` [mm, deg]; RAPID ``x, y,
        z, q1, q2, q3, q4`` [mm]; URScript ``x, y, z, rx, ry, rz`` [m, rad]; joint targets: the axis values in the
        language's unit).
    spans : tuple of NumberSpan
        Where each of ``values`` sits, in the same order.
    frame_mm : ndarray (4, 4) or None
        Cartesian targets: the tool frame in the base / work-object frame the program names [mm].
    joints_deg : ndarray (n,) or None
        Joint targets: the controller axis values [deg].
    config : mapping of str to int
        Configuration data as written (KRL ``S``, ``T``; RAPID ``cf1``, ``cf4``, ``cf6``, ``cfx``); empty where the
        language has none (URScript) or the point omits it.
    config_spans : mapping of str to NumberSpan
        Where each entry of ``config`` sits.
    tool : str or None
        Name of the tool frame in force (a key of :attr:`Program.frames`), None for the flange.
    base : str or None
        Name of the base / work object in force (a key of :attr:`Program.frames`), None for the robot's base frame.
    motion : str
        The instruction that uses it (``PTP``, ``LIN``, ``CIRC``, ``MoveL``, ``movej``...), or ``"declaration"`` for
        a declared point no motion uses.
    """

    label: str
    file: str
    line: int
    kind: Literal["cartesian", "joint"]
    values: tuple[float, ...]
    spans: tuple[NumberSpan, ...]
    frame_mm: np.ndarray | None = None
    joints_deg: np.ndarray | None = None
    config: Mapping[str, int] = field(default_factory=dict)
    config_spans: Mapping[str, NumberSpan] = field(default_factory=dict)
    tool: str | None = None
    base: str | None = None
    motion: str = ""


@dataclass(frozen=True, slots=True, kw_only=True)
class Program:
    """A robot program as read: its files' exact text, its points, its frames, and what could not be read.

    Attributes
    ----------
    language : {"krl", "rapid", "urscript"}
    texts : dict of str to str
        Every file's text exactly as read (keys: the file names, e.g. ``"weld.src"``, ``"weld.dat"``).
    points : list of ProgramPoint
        Every motion target with literal numbers, in file order.
    frames : dict of str to ndarray (4, 4)
        Tool and base / work-object frames declared in the program or given by the user [mm]: a tool in the flange
        frame, a base in the robot's base frame.
    skipped : list of (str, int, str)
        ``(file, line, why)`` for targets the reader found but cannot filter (an expression, an offset function, a
        point declared nowhere in the given files).
    """

    language: Literal["krl", "rapid", "urscript"]
    texts: dict[str, str]
    points: list[ProgramPoint]
    frames: dict[str, np.ndarray] = field(default_factory=dict)
    skipped: list[tuple[str, int, str]] = field(default_factory=list)


class Render(Protocol):
    """What each language's ``render`` is (:func:`robotcal.programs.filter.renderer`): the new text of every number of
    ``point`` for a new target, in the language's own units and notation.

    Parameters
    ----------
    point : ProgramPoint
        A point of a :class:`Program` read by the language's ``read_program``.
    frame_mm : array_like (4, 4), optional
        Cartesian points: the new tool frame in the point's base / work-object frame [mm].
    joints_deg : array_like (6,), optional
        Joint points: the new axis values [deg]. No language writes a Cartesian point from joint values.
    config : mapping of str to int, optional
        New configuration data, where the language has it.

    Returns
    -------
    dict of NumberSpan to str
        Each number's replacement, for :func:`replace_numbers`.

    Raises
    ------
    InputError
        The wrong kind of target for the point (a frame for a joint point, joints for a Cartesian one), a frame that
        is not rigid, a wrong number of joints, or configuration data the point cannot take.
    """

    def __call__(
        self, point: ProgramPoint, *, frame_mm: ArrayLike | None = None, joints_deg: ArrayLike | None = None,
        config: Mapping[str, int] | None = None,
    ) -> dict[NumberSpan, str]: ...


def format_number(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` fixed decimals, never ``-0.000``; trailing zeros kept (programs align numbers)."""
    text = f"{value:.{decimals}f}"
    if float(text) == 0.0:
        text = f"{0.0:.{decimals}f}"
    return text


def replace_numbers(texts: Mapping[str, str], replacements: Mapping[NumberSpan, str]) -> dict[str, str]:
    """Every file's text with the numbers at ``replacements``' spans replaced by their new text, nothing else changed.

    Raises :class:`InputError` if two spans overlap or a span lies outside its file (a reader's bug, never silently
    written).
    """
    out = dict(texts)
    by_file: dict[str, list[tuple[NumberSpan, str]]] = {}
    for span, text in replacements.items():
        if span.file not in texts or not 0 <= span.start <= span.end <= len(texts[span.file]):
            raise InputError(f"internal: number span {span} lies outside its file")
        by_file.setdefault(span.file, []).append((span, text))
    for name, items in by_file.items():
        items.sort(key=lambda item: item[0].start)
        pieces, cursor = [], 0
        source = texts[name]
        for span, text in items:
            if span.start < cursor:
                raise InputError(f"internal: number spans overlap in {name} at offset {span.start}")
            pieces += [source[cursor : span.start], text]
            cursor = span.end
        pieces.append(source[cursor:])
        out[name] = "".join(pieces)
    return out


def read_program_text(path: str | Path, encoding: str, kind: str) -> str:
    """A program file's text exactly as written (line endings and a BOM kept: the filtered file must differ in
    numbers only), or an :class:`InputError` naming the file (and the line of a byte that is not ``encoding``)."""
    path = Path(path)
    try:
        with open(path, encoding=encoding, newline="") as handle:
            return handle.read()
    except LookupError:
        raise InputError(f"{path}: unknown text encoding {encoding!r} (e.g. utf-8, cp1252)") from None
    except FileNotFoundError:
        raise InputError(f"{path}: no such {kind}") from None
    except UnicodeDecodeError as exc:
        line = exc.object[: exc.start].count(b"\n") + 1
        raise InputError(
            f"{path.name}, line {line}: not valid {encoding} text; give the file's encoding (--encoding cp1252: "
            "controllers and their editors often write it)"
        ) from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None


def joint_values(point: ProgramPoint, joints_deg: ArrayLike) -> np.ndarray:
    """``joints_deg`` as the finite axis values [deg] of the joint point ``point``, or an :class:`InputError`."""
    where = f"point {point.label!r} ({point.file}, line {point.line})"
    try:
        joints = np.asarray(joints_deg, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{where}: joints_deg must be numbers") from exc
    if joints.shape != (len(point.spans),) or not np.all(np.isfinite(joints)):
        raise InputError(f"{where}: joints_deg must be {len(point.spans)} finite values [deg]; got {joints_deg!r}")
    return joints
