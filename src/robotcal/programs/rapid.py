"""ABB RAPID modules (RobotWare 6 and 7): read their motion targets, write them back with new numbers only.

A RAPID module (``.mod``, ``.modx``, ``.prg``, ``.sys``) is read as text, kept exactly as read, and scanned for

- data declarations ``[LOCAL|TASK] CONST|PERS|VAR type name := value;`` of the types ``robtarget``,
  ``jointtarget``, ``tooldata`` and ``wobjdata`` (module data and routine data; a declaration may span lines);
- motion instructions ``MoveJ``, ``MoveL``, ``MoveC``, ``MoveAbsJ`` and their variants ``MoveJDO``, ``MoveLDO``,
  ``MoveCDO``, ``MoveJSync``, ``MoveLSync``, ``MoveCSync``, ``MoveJAO``/``MoveLAO``/``MoveCAO``,
  ``MoveJGO``/``MoveLGO``/``MoveCGO``, ``TriggJ``, ``TriggL``, ``TriggC``, whose targets are named data or inline
  aggregates, and whose tool and optional ``\\WObj:=`` argument name the frames in force.

The data layouts are those of the ABB "Technical reference manual - RAPID Instructions, Functions and Data types"
(RobotWare 6/7):

- ``robtarget``: ``[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [eax_a, ..., eax_f]]``, position [mm] and
  orientation as a unit quaternion ``q1 + q2 i + q3 j + q4 k`` (``q1`` the scalar part), configuration integers and
  six external axis values (``9E+09`` where there is no axis). The pose is the tool frame (TCP) in the object frame
  of the work object in force.
- ``jointtarget``: ``[[rax_1, ..., rax_6], [eax_a, ..., eax_f]]``, robot axes [deg].
- ``tooldata``: ``[robhold, tframe, tload]``; ``tframe = [[x, y, z], [q1..q4]]`` is the TCP in the flange (wrist)
  frame when ``robhold`` is TRUE. ``robhold`` FALSE is a stationary tool (the robot holds the work object): the
  tool is recorded in :attr:`Program.frames`, but the targets moved with it are not filtered (listed in
  :attr:`Program.skipped`).
- ``wobjdata``: ``[robhold, ufprog, ufmec, uframe, oframe]``; the target is in ``oframe``, ``oframe`` is in
  ``uframe``, ``uframe`` in the world frame. robotcal takes world = robot base frame (a single robot without a
  base-frame offset), so the work object's frame in the robot base is ``uframe @ oframe``
  (:attr:`Program.frames` under the wobjdata's name). A work object held by the robot (``robhold`` TRUE) or moved
  by a mechanical unit (``ufprog`` FALSE) is not supported: its targets are listed in :attr:`Program.skipped`.

``tool0`` (the flange) gives ``ProgramPoint.tool`` None, and no ``\\WObj`` or ``wobj0`` (the robot base/world
frame) gives ``ProgramPoint.base`` None. External axis values are never spans: they are left as written.

Not filtered, but listed in :attr:`Program.skipped` with the reason (never silently dropped): targets written as
expressions (``Offs(p10, 0, 0, 50)``, ``RelTool(...)``, ``CRobT()``: computed at run time from other points),
array elements and arrays of robtargets, points assigned at run time (``p10 := ...``), routine parameters, names
declared in no module of the file, declarations whose value is not a literal aggregate, search instructions
(``SearchL``...), stationary tools and moving work objects, and declared points no motion uses. A point moved with
different tools or work objects is filtered for its first use, and each conflicting use is listed.

RAPID is case-insensitive: keywords, instruction names and identifiers are matched without regard to case;
:class:`ProgramPoint` and :attr:`Program.frames` use the spelling of the declaration.
"""

from __future__ import annotations

import bisect
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, NoReturn

import numpy as np

from robotcal.errors import InputError
from robotcal.programs.base import NumberSpan, Program, ProgramPoint, read_program_text
from robotcal.programs.rapid_values import CONFIG_KEYS, frame_from_pose, quaternion_from_frame, render

__all__ = ["EXTENSIONS", "read_program", "render", "frame_from_pose", "quaternion_from_frame"]

#: File name endings read as RAPID text modules (lower case).
EXTENSIONS = (".mod", ".modx", ".prg", ".sys", ".sysx")


@dataclass(frozen=True, slots=True)
class _Motion:
    """Shape of a motion instruction's required arguments: which are targets, which is the tool."""

    name: str
    targets: tuple[int, ...]
    tool: int
    kind: Literal["cartesian", "joint"]


def _motion_table() -> dict[str, _Motion]:
    table = {}
    linear_or_joint = ("MoveJ", "MoveL", "MoveJDO", "MoveLDO", "MoveJSync", "MoveLSync", "MoveJAO", "MoveLAO")
    for name in (*linear_or_joint, "MoveJGO", "MoveLGO"):
        table[name.lower()] = _Motion(name, (0,), 3, "cartesian")  # ToPoint, Speed, Zone, Tool
    for name in ("MoveC", "MoveCDO", "MoveCSync", "MoveCAO", "MoveCGO"):
        table[name.lower()] = _Motion(name, (0, 1), 4, "cartesian")  # CirPoint, ToPoint, Speed, Zone, Tool
    for name in ("TriggJ", "TriggL"):
        table[name.lower()] = _Motion(name, (0,), 4, "cartesian")  # ToPoint, Speed, Trigg_1, Zone, Tool
    table["triggc"] = _Motion("TriggC", (0, 1), 5, "cartesian")  # CirPoint, ToPoint, Speed, Trigg_1, Zone, Tool
    table["moveabsj"] = _Motion("MoveAbsJ", (0,), 3, "joint")  # ToJointPos, Speed, Zone, Tool
    return table


_MOTIONS = _motion_table()
#: Motion instructions recognised but not filtered: their targets are listed in Program.skipped.
_UNSUPPORTED_MOTIONS = {
    name.lower(): name
    for name in ("SearchL", "SearchJ", "SearchC", "SearchExtJ", "MoveExtJ", "TriggJIOs", "TriggLIOs", "CSSDeactMoveL")
}
_DECLARATION_TYPES = ("robtarget", "jointtarget", "tooldata", "wobjdata")
_ROUTINE_END = {"endproc", "endfunc", "endtrap"}

_TOKEN = re.compile(
    r"""(?P<space>[ \t\f\v\r\n]+)
      | (?P<comment>![^\r\n]*)
      | (?P<string>"(?:[^"\r\n]|"")*"?)
      | (?P<number>0[xX][0-9A-Fa-f]+|0[bB][01]+|0[oO][0-7]+|(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
      | (?P<name>[A-Za-z][A-Za-z0-9_]*)
      | (?P<op>:=|<>|<=|>=|.)""",
    re.VERBOSE | re.DOTALL,
)
_LINE_BREAK = re.compile(r"\r\n|\r|\n")


@dataclass(frozen=True, slots=True)
class _Token:
    kind: str  # "string", "number", "name", "op"
    text: str
    start: int
    end: int

    @property
    def key(self) -> str:
        """Case-folded text (RAPID ignores case)."""
        return self.text.lower()


@dataclass(slots=True)
class _Leaf:
    """One element of an aggregate that is not itself an aggregate."""

    kind: str  # "number", "bool", "string", "expression"
    value: object
    start: int
    end: int


@dataclass(slots=True)
class _Declaration:
    type: str  # lower case
    name: str
    key: str
    scope: tuple[str | None, str | None]
    line: int
    start: int
    is_array: bool
    value: list | _Leaf | None  # aggregate (nested lists of _Leaf), a leaf, or None (no initial value)
    uses: list = field(default_factory=list)


def read_program(path: str | Path, *, encoding: str = "utf-8") -> Program:
    """Read one RAPID module file: its exact text, its motion targets, tool and work-object frames.

    Parameters
    ----------
    path : str or path-like
        A RAPID text module: ``.mod``, ``.modx``, ``.prg``, ``.sys`` or ``.sysx``.
    encoding : str
        Text encoding of the file. Line endings are kept exactly as written.

    Returns
    -------
    Program
        ``language="rapid"``; ``texts`` maps the file's name to its text; ``points`` holds one
        :class:`ProgramPoint` per declared robtarget/jointtarget that motions use (label: the declared name) and
        per inline target aggregate (label ``"<file>:<line>"``), in file order: Cartesian points with
        ``values = (x, y, z, q1, q2, q3, q4)`` [mm] and ``frame_mm`` (the TCP in the work object's object frame),
        joint points with ``values = joints_deg`` (six robot axes [deg]); ``frames`` holds every declared tool
        (TCP in the flange frame) and work object (``uframe @ oframe`` in the robot base frame) with a literal
        value; ``skipped`` lists ``(file, line, why)`` for every target that cannot be filtered.

    Raises
    ------
    InputError
        The file cannot be read or decoded, has another extension, or is malformed where a target, tool or work
        object is written (unterminated string or aggregate, bad number, missing ``;``, wrong aggregate shape,
        zero quaternion); the message names the file and line.
    """
    path = Path(path)
    if path.suffix.lower() not in EXTENSIONS:
        raise InputError(f"{path}: not a RAPID module file (expected one of {', '.join(EXTENSIONS)})")
    text = read_program_text(path, encoding, "RAPID module file")
    return _Reader(path.name, text, str(path)).read()


class _Reader:
    """One pass over a module's tokens: declarations, motions, assignments, references; then the points."""

    def __init__(self, name: str, text: str, where: str):
        self.name, self.text, self.where = name, text, where
        self.line_starts = [0] + [match.end() for match in _LINE_BREAK.finditer(text)]
        self.tokens = self._tokenize()
        self.declarations: dict[tuple[str | None, str | None], dict[str, _Declaration]] = {}
        self.parameters: dict[tuple[str | None, str | None], set[str]] = {}
        self.assignments: dict[str, list[int]] = {}
        self.references: dict[str, list[int]] = {}
        self.inline: list[tuple[list, int, int, _Motion, dict]] = []
        self.motions: list[tuple[_Motion, int, tuple, list, dict]] = []
        self.routine_names: dict[str, str] = {}
        self.skipped: list[tuple[str, int, str]] = []

    # ---- text ----------------------------------------------------------------------------------------------
    def line_of(self, offset: int) -> int:
        return bisect.bisect_right(self.line_starts, offset)

    def fail(self, offset: int, message: str) -> NoReturn:
        raise InputError(f"{self.where}: line {self.line_of(offset)}: {message}")

    def _tokenize(self) -> list[_Token]:
        text, tokens = self.text, []
        position = _skip_header(text)
        while position < len(text):
            match = _TOKEN.match(text, position)
            assert match is not None and match.lastgroup is not None  # `op` takes any one character
            kind, value, end = match.lastgroup, match.group(), match.end()
            if kind == "string" and (len(value) < 2 or not value.endswith('"') or _open_string(value)):
                self.fail(position, f"string {value[:40]!r} is not closed on its line")
            if kind == "number" and end < len(text) and (text[end].isalnum() or text[end] in "_."):
                bad = re.match(r"[\w.+-]*", text[position:]).group()  # type: ignore[union-attr]  # `*`: always a match
                self.fail(position, f"bad number {bad!r}")
            if kind not in ("space", "comment"):
                tokens.append(_Token(kind, value, position, end))
            position = end
        return tokens

    # ---- pass over the tokens ----------------------------------------------------------------------------
    def read(self) -> Program:
        tokens, module, routine = self.tokens, None, None
        index = 0
        while index < len(tokens):
            token = tokens[index]
            key = token.key if token.kind == "name" else None
            previous = tokens[index - 1].text if index else ""
            if key is None or previous == "\\":
                index += 1
                continue
            if key == "module" and index + 1 < len(tokens):
                module, index = tokens[index + 1].text.lower(), index + 2
            elif key == "endmodule":
                module, routine, index = None, None, index + 1
            elif key in ("proc", "func", "trap"):
                routine, index = self._routine_header(index, module)
            elif key in _ROUTINE_END:
                routine, index = None, index + 1
            elif key in ("const", "pers", "var"):
                index = self._declaration(index, (module, routine))
            elif key in _MOTIONS and not _is_data_use(tokens, index):
                index = self._motion(index, _MOTIONS[key], (module, routine))
            elif key in _UNSUPPORTED_MOTIONS and not _is_data_use(tokens, index):
                index = self._unsupported_motion(index, _UNSUPPORTED_MOTIONS[key])
            else:
                self._reference(index)
                index += 1
        for motion in self.motions:  # data may be declared after the routines using it (another module of a .prg)
            self._resolve_motion(*motion)
        return self._program()

    def _routine_header(self, index: int, module) -> tuple[str | None, int]:
        """``PROC name (params)``, ``FUNC type name (params)``, ``TRAP name``: the routine's name, the next index."""
        tokens = self.tokens
        at = index + (2 if tokens[index].key == "func" else 1)
        if at >= len(tokens) or tokens[at].kind != "name":
            return None, index + 1
        routine = tokens[at].key
        self.routine_names[routine] = tokens[at].text
        parameters = self.parameters.setdefault((module, routine), set())
        at += 1
        if at < len(tokens) and tokens[at].text == "(":
            depth = 0
            while at < len(tokens):
                text = tokens[at].text if tokens[at].kind == "op" else ""
                depth += text in ("(", "{")
                depth -= text in (")", "}")
                following = tokens[at + 1].text if at + 1 < len(tokens) else ""
                if depth == 1 and tokens[at].kind == "name" and following in (",", "|", ")", "{"):
                    parameters.add(tokens[at].key)
                at += 1
                if depth == 0:
                    break
        return routine, at

    def _statement_end(self, index: int, what: str) -> int:
        """Index of the ``;`` ending the statement that starts at ``index`` (brackets balanced)."""
        tokens, stack = self.tokens, []
        pairs = {"[": "]", "(": ")", "{": "}"}
        at = index
        while at < len(tokens):
            text = tokens[at].text if tokens[at].kind == "op" else ""
            if text in pairs:
                stack.append(tokens[at])
            elif text in (")", "]", "}"):
                if not stack or pairs[stack[-1].text] != text:
                    self.fail(tokens[at].start, f"{what}: unbalanced {text!r}")
                stack.pop()
            elif text == ";":
                if stack:
                    self.fail(stack[-1].start, f"{what}: {stack[-1].text!r} is not closed before ';'")
                return at
            at += 1
        if stack:
            self.fail(stack[-1].start, f"{what}: {stack[-1].text!r} is never closed")
        self.fail(tokens[index].start, f"{what} is not ended by ';'")

    def _declaration(self, index: int, scope) -> int:
        tokens = self.tokens
        end = self._statement_end(index, f"declaration {tokens[index].text}")
        at = index + 1
        if at + 1 >= end or tokens[at].kind != "name" or tokens[at + 1].kind != "name":
            self.fail(tokens[index].start, f"{tokens[index].text} declaration without a type and a name")
        data_type, name_token = tokens[at].key, tokens[at + 1]
        at += 2
        for offset in range(at + 1, end):  # names in the dimensions and the initial value are references
            self._reference(offset)
        if data_type not in _DECLARATION_TYPES:
            return end + 1
        is_array = at < end and tokens[at].text == "{"
        while at < end and tokens[at].text != ":=":
            at += 1
        value = self._aggregate(at + 1, end) if at < end else None
        declaration = _Declaration(
            type=data_type,
            name=name_token.text,
            key=name_token.key,
            scope=scope,
            line=self.line_of(name_token.start),
            start=name_token.start,
            is_array=is_array,
            value=value,
        )
        existing = self.declarations.setdefault(scope, {})
        if name_token.key in existing:
            self.fail(
                name_token.start, f"{name_token.text} is declared twice (first at line {existing[name_token.key].line})"
            )
        existing[name_token.key] = declaration
        return end + 1

    def _aggregate(self, start: int, end: int):
        """The value in ``tokens[start:end]``: nested lists of :class:`_Leaf`, or one leaf."""
        tokens = self.tokens
        if start >= end:
            self.fail(tokens[start - 1].start, "':=' without a value")
        if tokens[start].text != "[":
            return self._leaf(start, end)
        value, at = self._bracket(start, end)
        if at != end:
            return _Leaf("expression", None, tokens[start].start, tokens[end - 1].end)
        return value

    def _bracket(self, start: int, end: int) -> tuple[list, int]:
        """Parse ``[ ... ]`` opening at ``start``: its elements and the index after its ``]``."""
        tokens, at = self.tokens, start + 1
        elements: list[list | _Leaf] = []
        if at < end and tokens[at].text == "]":
            return elements, at + 1
        while at < end:
            element: list | _Leaf
            if tokens[at].text == "[":
                element, at = self._bracket(at, end)
                if at < end and tokens[at].text not in (",", "]"):  # an aggregate inside an expression
                    first = at
                    at = self._element_end(at, end)
                    element = _Leaf("expression", None, tokens[first].start, tokens[at - 1].end)
            else:
                first = at
                at = self._element_end(at, end)
                element = self._leaf(first, at)
            elements.append(element)
            if at >= end:
                break
            if tokens[at].text == "]":
                return elements, at + 1
            at += 1  # the comma
        self.fail(tokens[start].start, "aggregate '[' is not closed")

    def _element_end(self, at: int, end: int, stops: tuple[str, ...] = (",", "]")) -> int:
        """Index of the first of ``stops`` at the top level from ``at`` (nesting skipped), else ``end``: by default the
        ``,`` or ``]`` that ends an aggregate element starting at ``at``."""
        tokens, depth = self.tokens, 0
        while at < end:
            text = tokens[at].text if tokens[at].kind == "op" else ""
            if depth == 0 and text in stops:
                return at
            depth += text in ("[", "(", "{")
            depth -= text in ("]", ")", "}")
            at += 1
        return at

    def _leaf(self, start: int, end: int) -> _Leaf:
        tokens = self.tokens
        if start >= end:
            position = tokens[start].start if start < len(tokens) else len(self.text)
            self.fail(position, "empty element in an aggregate")
        first, last = tokens[start], tokens[end - 1]
        if end - start == 1 and first.kind == "number":
            return _Leaf("number", _number(first.text), first.start, first.end)
        if end - start == 2 and first.text in ("-", "+") and last.kind == "number":
            sign = -1.0 if first.text == "-" else 1.0
            return _Leaf("number", sign * _number(last.text), first.start, last.end)
        if end - start == 1 and first.key in ("true", "false"):
            return _Leaf("bool", first.key == "true", first.start, first.end)
        if end - start == 1 and first.kind == "string":
            return _Leaf("string", first.text[1:-1].replace('""', '"'), first.start, first.end)
        for offset in range(start, end):
            self._reference(offset)
        return _Leaf("expression", None, first.start, last.end)

    def _reference(self, index: int) -> None:
        """Note a name's use; ``name :=`` or ``name.field... :=`` outside a declaration is a run-time assignment."""
        tokens = self.tokens
        token = tokens[index]
        if token.kind != "name" or (index and tokens[index - 1].text in ("\\", ".")):
            return
        self.references.setdefault(token.key, []).append(self.line_of(token.start))
        at = index + 1
        while at + 1 < len(tokens) and tokens[at].text == "." and tokens[at + 1].kind == "name":
            at += 2
        if at < len(tokens) and tokens[at].text == ":=":
            self.assignments.setdefault(token.key, []).append(self.line_of(token.start))

    # ---- motions ---------------------------------------------------------------------------------------------
    def _arguments(self, index: int, what: str) -> tuple[list[tuple[int, int]], dict[str, tuple[int, int]], int]:
        """Required arguments (token ranges, in order), optional ones by lower-case name, and the index after ';'."""
        tokens = self.tokens
        end = self._statement_end(index, what)
        required, optional, at = [], {}, index + 1
        while at < end:
            if tokens[at].text == ",":
                at += 1
                continue
            if tokens[at].text == "\\":
                if at + 1 >= end or tokens[at + 1].kind != "name":
                    self.fail(tokens[at].start, f"{what}: '\\' without an argument name")
                name, at = tokens[at + 1].key, at + 2
                if at < end and tokens[at].text in (":=", "?"):
                    first = at + 1
                    at = self._element_end(first, end, (",", "\\"))
                    optional[name] = (first, at)
                else:
                    optional[name] = (at, at)
                continue
            first = at
            at = self._element_end(at, end, (",", "\\"))
            required.append((first, at))
        return required, optional, end + 1

    def _source(self, first: int, stop: int) -> str:
        text = self.text[self.tokens[first].start : self.tokens[stop - 1].end]
        text = re.sub(r"\s+", " ", text)
        return text if len(text) <= 60 else text[:57] + "..."

    def _motion(self, index: int, motion: _Motion, scope) -> int:
        tokens = self.tokens
        line = self.line_of(tokens[index].start)
        required, optional, after = self._arguments(index, motion.name)
        needed = max(motion.tool, *motion.targets) + 1
        if len(required) < needed:
            self.fail(tokens[index].start, f"{motion.name} has {len(required)} arguments; it needs at least {needed}")
        for first, stop in required:
            for offset in range(first, stop):
                self._reference(offset)
        self.motions.append((motion, line, scope, required, optional))
        return after

    def _resolve_motion(self, motion: _Motion, line: int, scope, required: list, optional: dict) -> None:
        """A motion's tool, work object and targets, once every declaration of the file is known."""
        tool = self._frame_name(required[motion.tool], "tool", motion.name, line, scope)
        wobj = self._frame_name(optional.get("wobj"), "wobj", motion.name, line, scope)
        if tool is _UNREADABLE or wobj is _UNREADABLE:
            return
        use = {"motion": motion.name, "line": line, "tool": tool, "wobj": wobj}
        for position in motion.targets:
            first, stop = required[position]
            self._target(first, stop, motion, use, scope)

    def _frame_name(self, argument, kind: str, motion: str, line: int, scope):
        """A tool or work-object argument: None (tool0 / wobj0 / absent), its declaration, or its name as written."""
        if argument is None:
            return None
        first, stop = argument
        if stop - first != 1 or self.tokens[first].kind != "name":
            what = "tool" if kind == "tool" else "work object"
            written = "not given" if stop == first else f"the expression {self._source(first, stop)}"
            self.skipped.append((self.name, line, f"{motion}: the {what} is {written}; its targets are not filtered"))
            return _UNREADABLE
        token = self.tokens[first]
        if token.key == f"{kind}0":
            return None
        declaration = self._lookup(token.key, scope)
        expected = "tooldata" if kind == "tool" else "wobjdata"
        if declaration is not None and declaration.type == expected:
            return declaration
        return token.text

    def _lookup(self, key: str, scope) -> _Declaration | None:
        module, routine = scope
        for candidate in ((module, routine), (module, None)):
            if key in self.declarations.get(candidate, {}):
                return self.declarations[candidate][key]
        for (_, candidate_routine), names in self.declarations.items():  # another module's data of the same file
            if candidate_routine is None and key in names:
                return names[key]
        return None

    def _target(self, first: int, stop: int, motion: _Motion, use: dict, scope) -> None:
        tokens, line, name = self.tokens, use["line"], motion.name
        expected = "robtarget" if motion.kind == "cartesian" else "jointtarget"
        source = self._source(first, stop)
        if tokens[first].text == "[":
            value, at = self._bracket(first, stop)
            if at == stop:
                self.inline.append((value, line, tokens[first].start, motion, use))
                return
        elif stop - first == 1 and tokens[first].kind == "name":
            key = tokens[first].key
            declaration = self._lookup(key, scope)
            if key in self.parameters.get(scope, set()):
                routine = self.routine_names[scope[1]]
                why = f"{name} target {source} is a parameter of routine {routine}: the caller gives it; not filtered"
            elif declaration is None:
                why = f"{name} target {source} is declared nowhere in this file (another module); not filtered"
            elif declaration.type != expected:
                why = f"{name} target {source} is a {declaration.type}, not a {expected}; not filtered"
            else:
                declaration.uses.append(use)
                return
            self.skipped.append((self.name, line, why))
            return
        elif stop - first > 1 and tokens[first].kind == "name" and tokens[first + 1].text == "{":
            why = f"{name} target {source} is an array element; arrays of {expected}s are not filtered"
            self.skipped.append((self.name, line, why))
            return
        if stop - first > 1 and tokens[first].kind == "name" and tokens[first + 1].text == "(":
            why = (
                f"{name} target {source} is an expression computed at run time by {tokens[first].text}() from "
                "other points; not filtered (the points it uses are filtered where they are declared)"
            )
        elif source == "*":
            why = f"{name} target '*' has no value in the file; not filtered"
        else:
            why = f"{name} target {source} is an expression computed at run time; not filtered"
        self.skipped.append((self.name, line, why))

    def _unsupported_motion(self, index: int, name: str) -> int:
        line = self.line_of(self.tokens[index].start)
        required, _, after = self._arguments(index, name)
        for first, stop in required:
            for offset in range(first, stop):
                self._reference(offset)
        why = f"{name}: its targets are not filtered (search and external-axis motions are not supported)"
        self.skipped.append((self.name, line, why))
        return after

    # ---- points ----------------------------------------------------------------------------------------------
    def _program(self) -> Program:
        points, frames = [], {}
        for scope in self.declarations.values():
            for declaration in scope.values():
                if declaration.type in ("tooldata", "wobjdata"):
                    frame = self._frame(declaration)
                    if frame is not None:
                        frames[declaration.name] = frame
        for scope in self.declarations.values():
            for declaration in scope.values():
                if declaration.type in ("robtarget", "jointtarget"):
                    point = self._declared_point(declaration)
                    if point is not None:
                        points.append(point)
        labels: dict[str, int] = {}
        for value, line, start, motion, use in self.inline:
            where = f"{motion.name} target at line {line}"
            if motion.kind == "cartesian":
                numbers = self._robtarget_numbers(value, start, where)
            else:
                numbers = self._jointtarget_numbers(value, start, where)
            if numbers is None:
                self.skipped.append((self.name, line, f"{where}: the aggregate holds expressions; not filtered"))
                continue
            label = f"{self.name}:{self.line_of(_first_leaf(value).start)}"
            labels[label] = labels.get(label, 0) + 1
            if labels[label] > 1:  # a second inline target on the same line (MoveC via and end point)
                label = f"{label}#{labels[label]}"
            if self._use_supported(use, label, motion.kind):
                points.append(self._point(label, motion.kind, numbers, use))
        points.sort(key=lambda point: point.spans[0].start)
        self.skipped.sort(key=lambda entry: entry[1])
        return Program(
            language="rapid", texts={self.name: self.text}, points=points, frames=frames, skipped=self.skipped
        )

    def _frame(self, declaration: _Declaration) -> np.ndarray | None:
        """A tool's TCP in the flange frame, or a work object's ``uframe @ oframe``; None if not literal."""
        value, where = declaration.value, f"{declaration.type} {declaration.name}"
        needed = value[:2] if declaration.type == "tooldata" and isinstance(value, list) else value
        if declaration.is_array or not isinstance(value, list) or _has_expression(needed):
            why = "an array" if declaration.is_array else "not a literal aggregate"
            message = f"{where}: its value is {why}; its frame is unknown to the targets moved with it"
            self.skipped.append((self.name, declaration.line, message))
            return None
        if declaration.type == "tooldata":
            if len(value) != 3 or not _is_bool(value[0]):
                self.fail(declaration.start, f"{where} must be [robhold, [[x,y,z],[q1,q2,q3,q4]], tload]")
            return self._pose(value[1], declaration.start, f"{where} tframe")
        is_string = isinstance(value[2], _Leaf) and value[2].kind == "string" if len(value) > 2 else False
        if len(value) != 5 or not _is_bool(value[0]) or not _is_bool(value[1]) or not is_string:
            self.fail(declaration.start, f"{where} must be [robhold, ufprog, ufmec, uframe, oframe]")
        user_frame = self._pose(value[3], declaration.start, f"{where} uframe")
        object_frame = self._pose(value[4], declaration.start, f"{where} oframe")
        return user_frame @ object_frame

    def _pose(self, value, start: int, where: str) -> np.ndarray:
        if not (isinstance(value, list) and len(value) == 2 and _numbers(value[0], 3) and _numbers(value[1], 4)):
            self.fail(start, f"{where} must be a pose [[x,y,z],[q1,q2,q3,q4]]")
        try:
            return frame_from_pose([leaf.value for leaf in value[0]], [leaf.value for leaf in value[1]])
        except InputError as exc:
            self.fail(start, f"{where}: {exc}")

    def _robtarget_numbers(self, value, start: int, where: str):
        """The robtarget aggregate if its pose and configuration are literal numbers, None if expressions."""
        if not _shaped(value, (3, 4, 4, 6)):
            if _has_expression(value):
                return None
            self.fail(start, f"{where} must be [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,...,eax_f]]")
        if _has_expression(value[:3]):
            return None
        if not _numbers(value[0], 3) or not _numbers(value[1], 4) or not _numbers(value[2], 4):
            self.fail(start, f"{where}: position, orientation and configuration must be numbers")
        quaternion = [leaf.value for leaf in value[1]]
        if float(np.linalg.norm(quaternion)) < 1e-12:
            self.fail(value[1][0].start, f"{where}: quaternion {quaternion} has zero length")
        for leaf in value[2]:
            if leaf.value != int(leaf.value):
                self.fail(leaf.start, f"{where}: configuration value {leaf.value:g} is not a whole number")
        return value

    def _jointtarget_numbers(self, value, start: int, where: str):
        """The jointtarget aggregate if its robot axes are literal numbers, None if expressions."""
        if not _shaped(value, (6, 6)):
            if _has_expression(value):
                return None
            self.fail(start, f"{where} must be [[rax_1,...,rax_6],[eax_a,...,eax_f]]")
        if _has_expression(value[0]):
            return None
        if not _numbers(value[0], 6):
            self.fail(start, f"{where}: the robot axis values must be numbers")
        return value

    def _declared_point(self, declaration: _Declaration) -> ProgramPoint | None:
        """The point of a declared robtarget/jointtarget, or None with a skipped entry saying why."""
        kind: Literal["cartesian", "joint"] = "cartesian" if declaration.type == "robtarget" else "joint"
        where = f"{declaration.type} {declaration.name}"
        line = declaration.line
        if declaration.is_array:
            self.skipped.append((self.name, line, f"{where}: arrays of {declaration.type}s are not filtered"))
            return None
        if declaration.value is None:
            numbers = None
        elif kind == "cartesian":  # checked even if no motion uses it: a malformed target is an error
            numbers = self._robtarget_numbers(declaration.value, declaration.start, where)
        else:
            numbers = self._jointtarget_numbers(declaration.value, declaration.start, where)
        if not declaration.uses:
            named = self.references.get(declaration.key, [])
            note = f" (named at line {named[0]}, not as a filtered motion's target)" if named else ""
            self.skipped.append((self.name, line, f"{where}: declared, used by no motion{note}; not filtered"))
            return None
        if numbers is None:
            written = "has no initial value" if declaration.value is None else "has a value that is an expression"
            self.skipped.append((self.name, line, f"{where} {written}: it is computed at run time; not filtered"))
            return None
        assigned = self.assignments.get(declaration.key)
        if assigned:
            why = (
                f"{where} is assigned at run time (line {assigned[0]}): the numbers declared may not be the target "
                "moved to; not filtered"
            )
            self.skipped.append((self.name, line, why))
            return None
        supported = [use for use in declaration.uses if self._use_supported(use, where, kind)]
        if not supported:
            return None
        first = supported[0]
        if kind == "cartesian":
            for use in supported[1:]:
                if _frames_of(use) != _frames_of(first):
                    why = (
                        f"{where} is moved to here with tool {_frame_label(use['tool'], 'tool0')} and work object "
                        f"{_frame_label(use['wobj'], 'wobj0')}, but at line {first['line']} with "
                        f"{_frame_label(first['tool'], 'tool0')} and {_frame_label(first['wobj'], 'wobj0')}: it is "
                        "filtered for its first use only"
                    )
                    self.skipped.append((self.name, use["line"], why))
        return self._point(declaration.name, kind, numbers, first)

    def _use_supported(self, use: dict, where: str, kind: str) -> bool:
        """False, with a skipped entry, for a Cartesian target moved with a stationary tool or a moving work object."""
        if kind != "cartesian":
            return True
        tool, wobj = use["tool"], use["wobj"]
        why = None
        if isinstance(tool, _Declaration) and _robhold(tool) is False:
            why = f"tool {tool.name} is stationary (robhold FALSE)"
        elif isinstance(wobj, _Declaration) and _robhold(wobj) is True:
            why = f"work object {wobj.name} is held by the robot (robhold TRUE)"
        elif isinstance(wobj, _Declaration) and _ufprog(wobj) is False:
            why = f"work object {wobj.name} is moved by a mechanical unit (ufprog FALSE)"
        if why is None:
            return True
        self.skipped.append((self.name, use["line"], f"{use['motion']} {where}: {why}; not supported, not filtered"))
        return False

    def _point(self, label: str, kind: Literal["cartesian", "joint"], value: list, use: dict) -> ProgramPoint:
        if kind == "cartesian":
            numbers = value[0] + value[1]
            frame = frame_from_pose([leaf.value for leaf in value[0]], [leaf.value for leaf in value[1]])
            config = {key: int(leaf.value) for key, leaf in zip(CONFIG_KEYS, value[2], strict=True)}
            config_spans = {key: self._span(leaf) for key, leaf in zip(CONFIG_KEYS, value[2], strict=True)}
            joints = None
        else:
            numbers, frame, config, config_spans = value[0], None, {}, {}
            joints = np.array([leaf.value for leaf in numbers], dtype=float)
        return ProgramPoint(
            label=label,
            file=self.name,
            line=self.line_of(numbers[0].start),
            kind=kind,
            values=tuple(float(leaf.value) for leaf in numbers),
            spans=tuple(self._span(leaf) for leaf in numbers),
            frame_mm=frame,
            joints_deg=joints,
            config=config,
            config_spans=config_spans,
            tool=_frame_key(use["tool"]),
            base=_frame_key(use["wobj"]),
            motion=use["motion"],
        )

    def _span(self, leaf: _Leaf) -> NumberSpan:
        return NumberSpan(self.name, leaf.start, leaf.end)


_UNREADABLE = object()


def _skip_header(text: str) -> int:
    """Offset after a ``%%% ... %%%`` file header (``.prg`` / ``.sys`` files of older controllers), else 0."""
    stripped = text.lstrip("\ufeff \t\r\n")
    if not stripped.startswith("%%%"):
        return 0
    start = len(text) - len(stripped)
    close = text.find("%%%", start + 3)
    return len(text) if close < 0 else close + 3


def _open_string(token: str) -> bool:
    """True if a string token's closing quote is really an escaped ``""`` (the string runs on)."""
    body = token[1:]
    quotes = len(body) - len(body.rstrip('"'))
    return quotes % 2 == 0


def _number(text: str) -> float:
    if text[:2].lower() in ("0x", "0b", "0o"):
        return float(int(text, 0))
    return float(text)


def _is_data_use(tokens: list[_Token], index: int) -> bool:
    """A motion instruction's name used as data (``MoveL := ...``, ``MoveL(...)``, after ``\\`` or ``.``)."""
    following = tokens[index + 1].text if index + 1 < len(tokens) else ";"
    previous = tokens[index - 1].text if index else ""
    return following in (":=", "(", ".") or previous in ("\\", ".")


def _first_leaf(value) -> _Leaf:
    while isinstance(value, list):
        value = value[0]
    return value


def _shaped(value, lengths: tuple[int, ...]) -> bool:
    """``value`` is a list of ``len(lengths)`` lists of those lengths."""
    return (
        isinstance(value, list)
        and len(value) == len(lengths)
        and all(isinstance(part, list) and len(part) == length for part, length in zip(value, lengths, strict=True))
    )


def _numbers(values, count: int) -> bool:
    return (
        isinstance(values, list)
        and len(values) == count
        and all(isinstance(v, _Leaf) and v.kind == "number" for v in values)
    )


def _has_expression(value) -> bool:
    if isinstance(value, list):
        return any(_has_expression(element) for element in value)
    return value.kind == "expression"


def _is_bool(value) -> bool:
    return isinstance(value, _Leaf) and value.kind == "bool"


def _robhold(declaration: _Declaration) -> bool | None:
    value = declaration.value
    return value[0].value if isinstance(value, list) and value and _is_bool(value[0]) else None


def _ufprog(declaration: _Declaration) -> bool | None:
    value = declaration.value
    return value[1].value if isinstance(value, list) and len(value) > 1 and _is_bool(value[1]) else None


def _frame_key(frame) -> str | None:
    """Name of a tool/work object in Program.frames terms: the declared spelling, the name as written, or None."""
    if frame is None:
        return None
    return frame.name if isinstance(frame, _Declaration) else frame


def _frames_of(use: dict) -> tuple[str | None, str | None]:
    """The (tool, work object) of a motion, case-folded (RAPID names ignore case)."""
    tool, wobj = _frame_key(use["tool"]), _frame_key(use["wobj"])
    return (tool and tool.lower(), wobj and wobj.lower())


def _frame_label(frame, default: str) -> str:
    key = _frame_key(frame)
    return default if key is None else key
