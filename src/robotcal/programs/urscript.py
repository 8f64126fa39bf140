"""Universal Robots URScript programs (e-Series): their motion targets read, and written back with new numbers only.

The language is described in Universal Robots, "The URScript Programming Language" (the script manual of the
e-Series, PolyScope 5). A script is usually one ``def name():`` ... ``end`` function, but top-level statements are
valid too; comments start with ``#``; blocks (``def``, ``thread``, ``sec``, ``if``, ``while``) close with ``end``.

What is read
------------
- Move instructions ``movej(q, a=1.4, v=1.05, t=0, r=0)``, ``movel(pose, a=1.2, v=0.25, t=0, r=0)``,
  ``movep(pose, a=1.2, v=0.25, r=0)`` and ``movec(pose_via, pose_to, a=1.2, v=0.25, r=0, mode=0)`` (two points),
  with the targets as positional or keyword arguments. A target written as
  a literal pose ``p[x, y, z, rx, ry, rz]`` (metres; rotation vector = unit axis * angle, radians) is a Cartesian
  point; a literal joint list ``[q1, ..., q6]`` (radians) is a joint point, whatever the instruction (``movel``,
  ``movep`` and ``movec`` accept joint positions, which the controller turns into a pose by forward kinematics).
  ``movej`` to a pose is a Cartesian point whose motion is ``"movej"`` (the controller solves the inverse
  kinematics; the caller treats it as any Cartesian target).
- Variables assigned a literal (``approach = p[...]``, ``global home_q = [...]``) and used as a move's target: one
  point labelled with the variable's name, at the assignment's line, its motion the first move that uses it. A use
  refers to the last assignment above it in the file; a use above every assignment (a function defined before the
  variable) to the only assignment, if there is one.
- Numbers: ``0.1``, ``-.25``, ``1e-3``, ``3``, with an optional sign. ``values`` keep them as written (metres,
  radians); ``frame_mm`` holds the pose in mm (the rotation vector as a matrix), ``joints_deg`` the joints in
  degrees. ``config`` is empty: a UR robot has no configuration data (the caller picks the inverse-kinematics
  branch nearest the previous point).
- Tools: ``set_tcp(p[...])`` (the tool in the flange frame, metres and rotation vector) sets the tool in force for
  the moves after it in the file. It is named ``"tcp@<line>"`` (the line of the ``set_tcp``), or after the variable
  for ``set_tcp(name)``; :attr:`Program.frames` holds it as a 4x4 transform [mm]. Before any ``set_tcp`` the tool
  is None: the flange as far as the script says. The TCP of the robot's installation, which is in force until
  the first ``set_tcp``, is not part of the script; a caller that knows it applies it to the points whose tool
  is None. A joint target needs no tool frame; its ``tool`` names the tool in force all the same, which after a
  ``set_tcp`` of an expression is ``"tcp@<line>"`` with no entry in :attr:`Program.frames`.
- Bases: URScript has no base or work-object frame for a literal target; every point's ``base`` is None (the
  robot's base frame).

What is not filtered (:attr:`Program.skipped`, with the reason)
---------------------------------------------------------------
Targets that are expressions (``pose_trans(...)``, ``pose_add(...)``, ``get_actual_tcp_pose()``,
``get_inverse_kin(...)``, arithmetic), literals with an expression inside (``pi``, ``d2r(90)``, ``-pi/2``),
variables assigned an expression, changed element by element, assigned nowhere in the file, or a function's
parameter; Cartesian targets whose tool was set by ``set_tcp`` of an expression (tool frame unknown); literal poses
held in variables that no move uses directly (an offset for ``pose_trans``); and ``servoj``/``servoc`` targets
(streamed servo set points, out of scope). A Cartesian variable used by moves under two different tools is a point
for the first; each later use under another tool is listed.

The file order stands for the order of execution (the tool in force, the assignment a use refers to), as a reader
of the text sees it; a script whose functions are called in another order than written may differ at run time.
"""

from __future__ import annotations

import bisect
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.programs.base import NumberSpan, Program, ProgramPoint, format_number, joint_values, read_program_text

__all__ = ["DECIMALS", "MOVES", "read_program", "render"]

#: Decimals written for metres and radians: a round trip keeps positions to 5e-8 mm and angles to 5e-11 rad.
DECIMALS = 10
#: The move instructions read, with their target parameters in order.
MOVES = {"movej": ("q",), "movel": ("pose",), "movep": ("pose",), "movec": ("pose_via", "pose_to")}
#: Servo instructions: streamed set points, listed in ``skipped``, never filtered.
_SERVOS = frozenset({"servoj", "servoc"})
#: Keywords that open a block closed by ``end``.
_FUNCTIONS = frozenset({"def", "thread", "sec"})
_CONDITIONALS = frozenset({"if", "while"})
_KEYWORDS = frozenset(
    """def thread sec if elif else while end return break continue halt global local run join kill
    and or not xor True False pi enter_critical exit_critical""".split()
)
_POSE_LENGTH = 6
_JOINT_COUNT = 6
_OPENERS = {"(": ")", "[": "]", "{": "}"}
_CLOSERS = frozenset(_OPENERS.values())
_LEXEME = re.compile(
    r"""
      (?P<nl>\r\n|\r|\n)
    | (?P<space>[^\S\r\n]+)
    | (?P<comment>\#[^\r\n]*)
    | (?P<str>"(?:[^"\\\r\n]|\\.)*"|'(?:[^'\\\r\n]|\\.)*')
    | (?P<num>(?:\d+\.\d*|\.\d+|\d+)(?:[eE][+-]?\d+)?)
    | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
    | (?P<op>==|!=|<=|>=|.)
    """,
    re.VERBOSE,
)
_NUMBER_TAIL = re.compile(r"[\w.]+")
_LINE_BREAK = re.compile(r"\r\n|\r|\n")


# ---------------------------------------------------------------------------------------------------- reading ---


@dataclass(frozen=True, slots=True)
class _Token:
    kind: str  # "nl", "str", "num", "name" or "op"
    text: str
    start: int
    end: int


@dataclass(frozen=True, slots=True)
class _Element:
    """One element of a ``p[...]`` or ``[...]`` literal: a signed number (``value``, ``span``) or an expression."""

    text: str
    value: float | None
    start: int
    end: int


@dataclass(frozen=True, slots=True)
class _Aggregate:
    """A ``p[...]`` pose or ``[...]`` list as written."""

    kind: str  # "pose" or "list"
    start: int  # offset of ``p`` or ``[``
    elements: tuple[_Element, ...]

    def expression(self) -> _Element | None:
        """The first element that is not a number, or None."""
        return next((element for element in self.elements if element.value is None), None)


@dataclass(slots=True)
class _Assignment:
    name: str
    index: int  # token index of the name
    line: int
    kind: str  # "pose", "list", "expression" or "modified"
    aggregate: _Aggregate | None
    text: str  # right-hand side as written (one line, shortened)
    used: bool = False
    point: ProgramPoint | None = None


@dataclass(frozen=True, slots=True)
class _Call:
    name: str
    index: int
    line: int
    #: (parameter name or None for a positional argument, token indices of the value)
    arguments: tuple[tuple[str | None, tuple[int, ...]], ...]
    parameters: frozenset[str]  # parameters of the function around the call


@dataclass(frozen=True, slots=True)
class _Tool:
    """The tool in force from token ``index`` on: ``name`` (None: flange), or unknown (``unknown`` says why)."""

    index: int
    name: str | None
    unknown: str = ""


@dataclass
class _Reader:
    """One script's text, its tokens, and what a pass over them finds."""

    text: str
    file: str
    tokens: list[_Token] = field(default_factory=list)
    partner: dict[int, int] = field(default_factory=dict)
    depth: list[int] = field(default_factory=list)
    assignments: dict[str, list[_Assignment]] = field(default_factory=dict)
    calls: list[_Call] = field(default_factory=list)
    points: list[ProgramPoint] = field(default_factory=list)
    frames: dict[str, np.ndarray] = field(default_factory=dict)
    skipped: list[tuple[str, int, str]] = field(default_factory=list)
    tools: list[_Tool] = field(default_factory=list)
    line_starts: list[int] = field(default_factory=list, init=False)

    def __post_init__(self):
        self.line_starts = [0] + [match.end() for match in _LINE_BREAK.finditer(self.text)]
        self._tokenize()
        self._match_brackets()

    # ----------------------------------------------------------------------------------------------- helpers ---

    def line(self, offset: int) -> int:
        """1-based line of character ``offset``."""
        return bisect.bisect_right(self.line_starts, offset)

    def error(self, offset: int, message: str) -> InputError:
        return InputError(f"{self.file}: line {self.line(offset)}: {message}")

    def source(self, indices) -> str:
        """The text of tokens ``indices`` (a contiguous run) on one line, shortened for a message."""
        indices = list(indices)
        if not indices:
            return ""
        text = " ".join(self.text[self.tokens[indices[0]].start : self.tokens[indices[-1]].end].split())
        return text if len(text) <= 60 else text[:57] + "..."

    # -------------------------------------------------------------------------------------------- tokenizing ---

    def _tokenize(self) -> None:
        text, position = self.text, 0
        while position < len(text):
            match = _LEXEME.match(text, position)
            assert match is not None and match.lastgroup is not None  # `nl` and `op` take any one character
            kind, lexeme = match.lastgroup, match.group()
            if kind == "num":
                tail = _NUMBER_TAIL.match(text, match.end())
                if tail:
                    raise self.error(position, f"bad number `{lexeme + tail.group()}`")
            elif kind == "op" and lexeme in "\"'":
                raise self.error(position, "unterminated string (no closing quote on its line)")
            if kind not in ("space", "comment"):
                self.tokens.append(_Token(kind, lexeme, position, match.end()))
            position = match.end()

    def _match_brackets(self) -> None:
        stack: list[int] = []
        for index, token in enumerate(self.tokens):
            self.depth.append(len(stack))
            if token.kind != "op":
                continue
            if token.text in _OPENERS:
                stack.append(index)
            elif token.text in _CLOSERS:
                if not stack:
                    raise self.error(token.start, f"`{token.text}` closes nothing")
                opener = stack.pop()
                if _OPENERS[self.tokens[opener].text] != token.text:
                    raise self.error(
                        self.tokens[opener].start,
                        f"unterminated `{self._opener_text(opener)}`: closed by `{token.text}` at line "
                        f"{self.line(token.start)}",
                    )
                self.partner[opener] = index
                self.depth[index] = len(stack)
        if stack:
            opener = stack[-1]
            raise self.error(
                self.tokens[opener].start, f"unterminated `{self._opener_text(opener)}`: not closed by the end of file"
            )

    def _opener_text(self, index: int) -> str:
        token = self.tokens[index]
        before = self.tokens[index - 1] if index else None
        if before is not None and before.kind == "name" and before.end == token.start:
            return before.text + token.text
        return token.text

    def _is(self, index: int, kind: str, text: str | None = None) -> bool:
        if not 0 <= index < len(self.tokens):
            return False
        token = self.tokens[index]
        return token.kind == kind and (text is None or token.text == text)

    def _statement_start(self, index: int) -> bool:
        """Token ``index`` begins a statement (first on its line, outside brackets)."""
        return self.depth[index] == 0 and (index == 0 or self.tokens[index - 1].kind == "nl")

    def _statement_end(self, index: int) -> int:
        """Index of the line break (or the end) that ends the statement holding token ``index``."""
        while index < len(self.tokens) and self.tokens[index].kind != "nl":
            index = self.partner.get(index, index) + 1
        return index

    def _split(self, opener: int) -> list[list[int]]:
        """Token indices of each comma-separated item between ``opener`` and its partner, line breaks left out."""
        items: list[list[int]] = [[]]
        index, closer = opener + 1, self.partner[opener]
        while index < closer:
            token = self.tokens[index]
            if token.kind == "op" and token.text == ",":
                items.append([])
                index += 1
                continue
            stop = self.partner.get(index, index)
            items[-1] += [i for i in range(index, stop + 1) if self.tokens[i].kind != "nl"]
            index = stop + 1
        if items == [[]]:
            return []
        return items

    # ------------------------------------------------------------------------------------------- first pass ---

    def scan(self) -> None:
        """Find the assignments, the calls of moves, servos and ``set_tcp``, and the functions' parameters."""
        blocks: list[frozenset[str]] = []
        tokens = self.tokens
        for index, token in enumerate(tokens):
            if token.kind != "name":
                continue
            if self._statement_start(index):
                if token.text in _FUNCTIONS:
                    blocks.append(self._parameters(index))
                    continue
                if token.text in _CONDITIONALS:
                    blocks.append(blocks[-1] if blocks else frozenset())
                    continue
                if token.text == "end":
                    if blocks:
                        blocks.pop()
                    continue
            if self._starts_assignment(index):
                self._assignment(index)
            elif (token.text in MOVES or token.text in _SERVOS or token.text == "set_tcp") and self._is(
                index + 1, "op", "("
            ):
                if self._is(index - 1, "op", ".") or (index and tokens[index - 1].text in _FUNCTIONS):
                    continue  # a member, or the name of a function being defined
                arguments: list[tuple[str | None, tuple[int, ...]]] = []
                for item in self._split(index + 1):
                    if not item:
                        raise self.error(token.start, f"`{token.text}(...)` has an empty argument")
                    if len(item) > 2 and self._is(item[0], "name") and self._is(item[1], "op", "="):
                        arguments.append((tokens[item[0]].text, tuple(item[2:])))
                    else:
                        arguments.append((None, tuple(item)))
                self.calls.append(
                    _Call(
                        token.text,
                        index,
                        self.line(token.start),
                        tuple(arguments),
                        blocks[-1] if blocks else frozenset(),
                    )
                )

    def _parameters(self, index: int) -> frozenset[str]:
        """Parameter names of the ``def name(a, b=1):`` at token ``index``."""
        if not (self._is(index + 1, "name") and self._is(index + 2, "op", "(")):
            return frozenset()
        return frozenset(
            self.tokens[item[0]].text for item in self._split(index + 2) if item and self._is(item[0], "name")
        )

    def _starts_assignment(self, index: int) -> bool:
        """Token ``index`` is the name assigned by ``name = ...``, ``name[i] = ...`` or ``global name = ...``."""
        declared = (
            index > 0
            and self.tokens[index - 1].kind == "name"
            and self.tokens[index - 1].text in ("global", "local")
            and self._statement_start(index - 1)
        )
        if not (self._statement_start(index) or declared) or self.tokens[index].text in _KEYWORDS:
            return False
        after = index + 1
        if self._is(after, "op", "["):
            after = self.partner[after] + 1
        return self._is(after, "op", "=")

    def _assignment(self, index: int) -> None:
        token = self.tokens[index]
        line = self.line(token.start)
        modified = self._is(index + 1, "op", "[")
        equals = self.partner[index + 1] + 1 if modified else index + 1
        value = [i for i in range(equals + 1, self._statement_end(equals + 1)) if self.tokens[i].kind != "nl"]
        kind, content = ("modified", None) if modified else self._classify(value)
        if kind in ("pose", "list"):
            assert isinstance(content, _Aggregate)  # _classify: the literal of a pose or a list
            assignment = _Assignment(token.text, index, line, kind, content, self.source(value))
        else:  # an expression, or another variable's name
            assignment = _Assignment(
                token.text, index, line, "expression" if kind != "modified" else kind, None, self.source(value)
            )
        self.assignments.setdefault(token.text, []).append(assignment)

    def _classify(self, item) -> tuple[str, _Aggregate | str]:
        """``("pose" | "list", _Aggregate)``, ``("name", str)`` or ``("expression", text)`` of a value's tokens."""
        item = list(item)
        tokens = self.tokens
        if not item:
            return "expression", ""
        if (
            len(item) >= 3
            and tokens[item[0]].kind == "name"
            and tokens[item[0]].text == "p"
            and self._is(item[1], "op", "[")
            and self.partner[item[1]] == item[-1]
        ):
            return "pose", self._aggregate("pose", item[1], tokens[item[0]].start)
        if self._is(item[0], "op", "[") and self.partner[item[0]] == item[-1]:
            return "list", self._aggregate("list", item[0], tokens[item[0]].start)
        if len(item) == 1 and tokens[item[0]].kind == "name" and tokens[item[0]].text not in _KEYWORDS:
            return "name", tokens[item[0]].text
        return "expression", self.source(item)

    def _aggregate(self, kind: str, opener: int, start: int) -> _Aggregate:
        elements = []
        for item in self._split(opener):
            if not item:
                raise self.error(
                    start,
                    f"empty element in `{self.source(range(opener - (kind == 'pose'), self.partner[opener] + 1))}`",
                )
            first, last = self.tokens[item[0]], self.tokens[item[-1]]
            value = None
            if len(item) == 1 and first.kind == "num":
                value = float(first.text)
            elif len(item) == 2 and first.kind == "op" and first.text in "+-" and last.kind == "num":
                value = -float(last.text) if first.text == "-" else float(last.text)
            elements.append(_Element(self.source(item), value, first.start, last.end))
        return _Aggregate(kind, start, tuple(elements))

    # ------------------------------------------------------------------------------------------ second pass ---

    def resolve(self) -> None:
        """Tools first (``set_tcp`` may name a variable), then every move's targets."""
        for call in self.calls:
            if call.name == "set_tcp":
                self._set_tcp(call)
        for call in self.calls:
            if call.name in MOVES:
                self._move(call)
            elif call.name in _SERVOS:
                self.skipped.append(
                    (self.file, call.line, f"`{call.name}` sets a streamed servo target (out of scope): not filtered")
                )
        for assignments in self.assignments.values():
            for assignment in assignments:
                if assignment.kind == "pose" and not assignment.used:
                    self.skipped.append(
                        (
                            self.file,
                            assignment.line,
                            f"pose `{assignment.name}` is the target of no move instruction (movej, movel, movep, "
                            "movec), at most a value in an expression: not filtered",
                        )
                    )
        self.points.sort(key=lambda point: point.spans[0].start if point.spans else 0)
        self.skipped.sort(key=lambda entry: entry[1])

    def _set_tcp(self, call: _Call) -> None:
        where = f"set_tcp at line {call.line}"
        if len(call.arguments) != 1:
            raise InputError(
                f"{self.file}: line {call.line}: set_tcp takes one pose; got {len(call.arguments)} arguments"
            )
        item = call.arguments[0][1]
        kind, content = self._classify(item)
        name: str | None = None
        aggregate: _Aggregate | None = None
        why = ""
        if kind == "pose":
            assert isinstance(content, _Aggregate)  # _classify: a pose's literal
            name, aggregate = f"tcp@{call.line}", content
        elif kind == "name":
            assert isinstance(content, str)  # _classify: a variable's name
            assignment, why = self._lookup(content, call.index, call)
            if assignment is not None:
                assignment.used = True
                if assignment.kind == "pose":
                    name, aggregate = content, assignment.aggregate
                else:
                    why = f"`{content}` (line {assignment.line}) is no pose"
        else:
            why = f"`{content}` is an expression"
        if aggregate is not None:
            assert name is not None  # set with the aggregate
            self._check_length(aggregate, _POSE_LENGTH, where)
            element = aggregate.expression()
            if element is None:
                frame = _frame_from_pose([number.value for number in aggregate.elements])
                if name in self.frames and not np.allclose(self.frames[name], frame, rtol=0, atol=1e-12):
                    name = f"{name}@{call.line}"
                self.frames[name] = frame
            else:
                why = f"`p[...]` has the expression `{element.text}`"
        if why:
            self.tools.append(_Tool(call.index, f"tcp@{call.line}", f"set_tcp at line {call.line}: {why}"))
        else:
            self.tools.append(_Tool(call.index, name))

    def _tool_at(self, index: int) -> _Tool:
        position = bisect.bisect_left([tool.index for tool in self.tools], index)
        return self.tools[position - 1] if position else _Tool(-1, None)

    def _lookup(self, name: str, index: int, call: _Call) -> tuple[_Assignment | None, str]:
        """The assignment a use of ``name`` at token ``index`` refers to, else None and why not."""
        if name in call.parameters:
            return None, f"`{name}` is a parameter of the function around it (its value comes from the call)"
        assignments = self.assignments.get(name, [])
        before = [assignment for assignment in assignments if assignment.index < index]
        if before:
            assignment = before[-1]
        elif len(assignments) == 1:
            assignment = assignments[0]
        elif assignments:
            lines = ", ".join(str(assignment.line) for assignment in assignments)
            return (
                None,
                f"`{name}` is assigned at lines {lines}, all below this use (which one holds depends on the calls)",
            )
        else:
            return None, f"`{name}` is assigned nowhere in {self.file} (an installation variable, or set elsewhere)"
        if assignment.kind == "modified":
            return None, f"`{name}` is changed element by element at line {assignment.line}"
        if assignment.kind == "expression":
            assignment.used = True
            return None, f"`{name}` is assigned the expression `{assignment.text}` at line {assignment.line}"
        return assignment, ""

    def _check_length(self, aggregate: _Aggregate, length: int, where: str) -> None:
        if len(aggregate.elements) != length:
            what = "a pose p[x, y, z, rx, ry, rz]" if aggregate.kind == "pose" else "a UR joint target [q1, ..., q6]"
            raise self.error(aggregate.start, f"{where}: {what} needs {length} numbers; got {len(aggregate.elements)}")

    def _move(self, call: _Call) -> None:
        parameters = MOVES[call.name]
        targets: dict[str, tuple[int, ...]] = {}
        positional = [item for keyword, item in call.arguments if keyword is None]
        for parameter, item in zip(parameters, positional, strict=False):
            targets[parameter] = item
        for keyword, item in call.arguments:
            if keyword in parameters:
                targets[keyword] = item
        missing = [parameter for parameter in parameters if parameter not in targets]
        if missing:
            raise InputError(f"{self.file}: line {call.line}: `{call.name}` without its target ({', '.join(missing)})")
        for parameter in parameters:
            self._target(call, targets[parameter])

    def _target(self, call: _Call, item: tuple[int, ...]) -> None:
        line = self.line(self.tokens[item[0]].start)
        where = f"{call.name} target"
        kind, content = self._classify(item)
        if kind == "expression":
            self.skipped.append(
                (self.file, line, f"{where} `{content}` is an expression (computed by the controller): not filtered")
            )
            return
        if kind == "name":
            assert isinstance(content, str)  # _classify: a variable's name
            assignment, why = self._lookup(content, call.index, call)
            if assignment is None:
                self.skipped.append((self.file, line, f"{where}: {why}: not filtered"))
                return
            assignment.used = True
            self._variable_point(call, line, assignment)
            return
        assert isinstance(content, _Aggregate)  # _classify: a pose's or a list's literal
        aggregate = content
        self._check_length(aggregate, _POSE_LENGTH if kind == "pose" else _JOINT_COUNT, f"{where}")
        element = aggregate.expression()
        if element is not None:
            self.skipped.append(
                (self.file, line, f"{where} `{self.source(item)}` has the expression `{element.text}`: not filtered")
            )
            return
        tool = self._tool_at(call.index)
        if kind == "pose" and tool.unknown:
            self.skipped.append((self.file, line, f"{where} on a tool of unknown frame ({tool.unknown}): not filtered"))
            return
        self.points.append(self._point(f"{self.file}:{line}", aggregate, call.name, tool))

    def _variable_point(self, call: _Call, line: int, assignment: _Assignment) -> None:
        aggregate = assignment.aggregate
        assert aggregate is not None  # _lookup returns the assignments of a pose or a list only
        where = f"`{assignment.name}` ({call.name} target at line {line})"
        self._check_length(aggregate, _POSE_LENGTH if aggregate.kind == "pose" else _JOINT_COUNT, where)
        element = aggregate.expression()
        if element is not None:
            self.skipped.append(
                (
                    self.file,
                    line,
                    f"{call.name} target `{assignment.name}` (line {assignment.line}) has the expression "
                    f"`{element.text}`: not filtered",
                )
            )
            return
        tool = self._tool_at(call.index)
        if aggregate.kind == "pose" and tool.unknown:
            self.skipped.append(
                (
                    self.file,
                    line,
                    f"{call.name} target `{assignment.name}` on a tool of unknown frame ({tool.unknown}): not filtered",
                )
            )
            return
        if assignment.point is None:
            assignment.point = self._point(assignment.name, aggregate, call.name, tool)
            self.points.append(assignment.point)
        elif aggregate.kind == "pose" and tool.name != assignment.point.tool:
            self.skipped.append(
                (
                    self.file,
                    line,
                    f"{call.name} target `{assignment.name}` is used here with tool {tool.name or 'flange'} but is "
                    f"filtered for tool {assignment.point.tool or 'flange'} (its first move, "
                    f"{assignment.point.motion}): not filtered for this move",
                )
            )

    def _point(self, label: str, aggregate: _Aggregate, motion: str, tool: _Tool) -> ProgramPoint:
        values = tuple(element.value for element in aggregate.elements if element.value is not None)
        assert len(values) == len(aggregate.elements)  # the callers skip an aggregate holding an expression
        spans = tuple(NumberSpan(self.file, element.start, element.end) for element in aggregate.elements)
        line = self.line(aggregate.elements[0].start)
        pose = aggregate.kind == "pose"
        return ProgramPoint(
            label=label,
            file=self.file,
            line=line,
            kind="cartesian" if pose else "joint",
            values=values,
            spans=spans,
            frame_mm=_frame_from_pose(values) if pose else None,
            joints_deg=None if pose else np.rad2deg(np.asarray(values, dtype=float)),
            tool=tool.name,
            motion=motion,
        )


def _frame_from_pose(values) -> np.ndarray:
    """4x4 transform [mm] of a URScript pose ``x, y, z`` [m], rotation vector ``rx, ry, rz`` [rad]."""
    from scipy.spatial.transform import Rotation

    frame = np.eye(4)
    frame[:3, :3] = Rotation.from_rotvec(np.asarray(values[3:6], dtype=float)).as_matrix()
    frame[:3, 3] = np.asarray(values[:3], dtype=float) * 1000.0
    return frame


def read_program(path: str | Path, *, encoding: str = "utf-8") -> Program:
    """Read a URScript file: its exact text, its motion targets, its tool frames, and what cannot be filtered.

    Parameters
    ----------
    path : str or path-like
        The script (``.script``, ``.urscript`` or any name); its file name is the key of :attr:`Program.texts`.
    encoding : str
        Text encoding of the file. Line endings are kept as written.

    Returns
    -------
    Program
        ``language="urscript"``; ``points`` in file order (literal targets of ``movej``/``movel``/``movep``/
        ``movec``, directly or through a variable); ``frames``: the ``set_tcp`` tools [mm]; ``skipped``: the
        targets that are expressions and the other cases the module docstring lists.

    Raises
    ------
    InputError
        The file cannot be read or decoded, or it holds a bad number (``0.1.2``, ``1e``), an unterminated string,
        bracket or literal, a move without its target, or a pose or joint target without 6 numbers; the message
        names the file and the line.
    """
    path = Path(path)
    text = read_program_text(path, encoding, "URScript file")
    reader = _Reader(text, path.name)
    reader.scan()
    reader.resolve()
    return Program(
        language="urscript",
        texts={path.name: text},
        points=reader.points,
        frames=reader.frames,
        skipped=reader.skipped,
    )


# --------------------------------------------------------------------------------------------------- writing ---


def _rotation_vector_near(rotation: np.ndarray, original) -> np.ndarray:
    """The rotation vector of ``rotation`` nearest ``original`` among its equivalents.

    ``u * theta`` and ``u * (theta + 2 pi k)`` are the same rotation (``k = -1``: angle ``2 pi - theta`` about
    ``-u``); near ``theta = pi`` the two shortest ones are nearly opposite vectors, and the one written must stay
    near the program's own numbers. For the identity the axis of ``original`` is used.
    """
    from scipy.spatial.transform import Rotation

    original = np.asarray(original, dtype=float)
    vector = Rotation.from_matrix(rotation).as_rotvec()
    angle = float(np.linalg.norm(vector))
    if angle > 1e-12:
        axis = vector / angle
    elif np.linalg.norm(original) > 0.0:
        axis, angle = original / np.linalg.norm(original), 0.0
    else:
        return np.zeros(3)
    turns = np.round(np.dot(original, axis) / (2.0 * np.pi) - angle / (2.0 * np.pi))
    candidates = [axis * (angle + 2.0 * np.pi * k) for k in (turns - 1, turns, turns + 1)]
    return min(candidates, key=lambda candidate: float(np.linalg.norm(candidate - original)))


def render(
    point: ProgramPoint, *, frame_mm: ArrayLike | None = None, joints_deg: ArrayLike | None = None,
    config: Mapping[str, int] | None = None,
) -> dict[NumberSpan, str]:
    """URScript's :class:`~robotcal.programs.base.Render`: the new text of every number of ``point`` in URScript's
    units (metres, radians), :data:`DECIMALS` decimals.

    ``frame_mm``, the new tool frame in the robot's base frame, is written as ``x, y, z`` [m] and the rotation vector
    [rad] nearest the one written before (of the equivalent vectors ``u * theta`` and ``u * (theta - 2 pi)``), so that
    near an angle of pi the numbers do not flip sign; ``joints_deg`` in radians (the literal ``p[...]`` of a
    Cartesian point cannot hold joint values). URScript has no configuration data: ``config`` None or empty.
    """
    where = f"{point.file}: line {point.line}: {point.label}"
    if config:
        raise InputError(f"{where}: URScript has no configuration data; got {dict(config)}")
    if point.kind == "cartesian":
        if joints_deg is not None:
            raise InputError(f"{where}: a Cartesian target p[...] cannot be written as joint values; give frame_mm")
        if frame_mm is None:
            raise InputError(f"{where}: a Cartesian target needs frame_mm")
        from robotcal.geometry.transforms import check_rigid_transform

        frame = check_rigid_transform(frame_mm, f"frame_mm of {point.label}")
        numbers = np.concatenate([frame[:3, 3] / 1000.0, _rotation_vector_near(frame[:3, :3], point.values[3:6])])
    else:
        if frame_mm is not None:
            raise InputError(f"{where}: a joint target cannot be written as a frame; give joints_deg")
        if joints_deg is None:
            raise InputError(f"{where}: a joint target needs joints_deg")
        numbers = np.deg2rad(joint_values(point, joints_deg))
    return {span: format_number(float(value), DECIMALS) for span, value in zip(point.spans, numbers, strict=True)}
