"""Validation helpers of the I/O edge: pydantic errors and CSV cells become one clear :class:`InputError`
naming the file, line and key or column.

Every reader of a user file goes through :func:`read_text_file`, :func:`csv_rows` or
:func:`parse_json_text`, so that hostile input (binary bytes, a line of 200,000 characters, JSON
nested 100,000 deep, a 5,000-digit number) ends in one :class:`InputError` naming the file and
never in a traceback or an unbounded allocation.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Annotated, TypeVar

from pydantic import AllowInfNan, BaseModel, BeforeValidator, Strict, ValidationError

from robotcal.errors import InputError

#: Largest text input file read [bytes]: far above any capture (10^5 points ~ 20 MB) or scenario.
MAX_FILE_BYTES = 512 * 1024 * 1024
#: Longest CSV line accepted [characters]: a capture row of a 6-joint robot is ~150 characters.
MAX_LINE_CHARS = 10_000
#: Deepest JSON/TOML nesting accepted: robotcal's own files nest 4 levels.
MAX_NESTING = 64

# The value types of the TOML tables (scenario, robot). pydantic's lax mode reads `true` as 1, `"5"` as 5 and 1 as
# `true`: a boolean written where a number belongs would silently become a 1 kg payload or seed 1 (issue 30).
#: A TOML integer: a boolean, a float (``1000.0``) or a text (``"5"``) is refused, never converted.
TomlInt = Annotated[int, Strict()]
#: A TOML number (an integer is a number): a boolean or a text is refused, and so are ``nan`` and ``inf``.
TomlFloat = Annotated[float, Strict(), AllowInfNan(False)]
#: A TOML boolean: ``true`` or ``false``, never a number or a text.
TomlBool = Annotated[bool, Strict()]
# The JSON files (the parameter JSON) use the same three types: JSON's numbers, booleans and texts are TOML's.


def _three_values(value):
    if isinstance(value, list | tuple) and len(value) != 3:
        raise ValueError(f"must be [x, y, z]; got {len(value)} values")
    return value


#: A position or vector [x, y, z]; a list of another length is refused with that message.
XYZ = Annotated[tuple[TomlFloat, TomlFloat, TomlFloat], BeforeValidator(_three_values)]
#: The same, kept as the list the file wrote (a key whose validated value is echoed as written).
XYZList = Annotated[list[TomlFloat], BeforeValidator(_three_values)]


def _four_values(value):
    if isinstance(value, list | tuple) and len(value) != 4:
        raise ValueError(f"must be a row of 4 numbers; got {len(value)} values")
    return value


def _four_rows(value):
    if isinstance(value, list | tuple) and len(value) != 4:
        raise ValueError(f"must be a 4x4 matrix; got {len(value)} rows")
    return value


#: A 4x4 matrix, rows of numbers (a homogeneous transform [mm]); another count of rows or columns is refused.
Matrix4 = Annotated[list[Annotated[list[TomlFloat], BeforeValidator(_four_values)]], BeforeValidator(_four_rows)]


#: What a byte that is not UTF-8 most likely is, for the message: exports of Windows tools (Leica's, among them)
#: write Latin-1 / cp1252, whose "µ" (0xb5) and "°" (0xb0) appear in their unit headers ("[µm]", "[°C]").
_LEGACY_HINT = "cp1252"


def read_text_file(path, *, kind: str = "file", encoding: str = "utf-8", encoding_option: str | None = None) -> str:
    """The text of ``path`` (UTF-8 by default; a UTF-8 BOM is dropped); every failure is an :class:`InputError`.

    Refused with a message naming the file: a missing file, a folder, an unreadable file, a file
    over :data:`MAX_FILE_BYTES`, bytes that are not text in ``encoding`` (the message names the byte, how it reads
    in cp1252, and the ``--encoding`` to give) and text holding NUL characters (binary).
    ``kind`` names what was expected ("capture CSV", "scenario TOML", ...); ``encoding`` a Python codec name;
    ``encoding_option`` the command-line option that sets it, named in the message (readers with one).
    """
    path = Path(path)
    try:
        "".encode(encoding)
    except LookupError:
        raise InputError(f"{path}: unknown text encoding {encoding!r} (e.g. utf-8, cp1252, latin-1)") from None
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise InputError(f"{path}: {size:,} bytes is too large for a {kind} (limit {MAX_FILE_BYTES:,})")
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, not a {kind}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    codec = "utf-8-sig" if encoding.replace("_", "-").lower() in ("utf-8", "utf8") else encoding
    try:
        text = raw.decode(codec)
    except UnicodeDecodeError as exc:
        byte = raw[exc.start]
        line = raw.count(b"\n", 0, exc.start) + 1
        legacy = bytes([byte]).decode(_LEGACY_HINT, errors="replace")
        name = "UTF-8" if codec == "utf-8-sig" else encoding
        hint = (
            f"; if it was written in another encoding, give it: {encoding_option} {_LEGACY_HINT}"
            if encoding_option
            else ""
        )
        raise InputError(
            f"{path}: not a {name} text file (byte {exc.start} is 0x{byte:02x}); expected a {kind}; line {line} "
            f"holds that byte ({legacy!r} in {_LEGACY_HINT}){hint}"
        ) from None
    if "\x00" in text:
        raise InputError(f"{path}: holds NUL characters (a binary file?); expected a {kind}")
    return text


def csv_rows(text: str, path) -> list[tuple[int, list[str]]]:
    """``(line number, cells)`` of every CSV record of ``text``; lines over :data:`MAX_LINE_CHARS` refused.

    Line numbers are 1-based as an editor shows them (the line where the record starts).
    """
    for number, line in enumerate(text.splitlines(), start=1):
        if len(line) > MAX_LINE_CHARS:
            raise InputError(
                f"{path}: line {number} is {len(line):,} characters long (limit {MAX_LINE_CHARS:,}); "
                "is this the right file?"
            )
    reader = csv.reader(io.StringIO(text))
    rows = []
    try:
        for row in reader:
            rows.append((reader.line_num - (sum(cell.count("\n") for cell in row)), row))
    except csv.Error as exc:
        raise InputError(f"{path}: line {reader.line_num}: not valid CSV ({exc})") from None
    return rows


def check_nesting(text: str, source: str, *, kind: str) -> None:
    """Refuse ``text`` whose brackets nest deeper than :data:`MAX_NESTING` (before a recursive parser sees it).

    Brackets inside strings are counted too, which only over-estimates the depth.
    """
    depth = deepest = 0
    for char in text:
        if char in "[{":
            depth += 1
            if depth > deepest:
                deepest = depth
                if deepest > MAX_NESTING:
                    raise InputError(f"{source}: {kind} nested more than {MAX_NESTING} levels deep")
        elif char in "]}":
            depth -= 1


def parse_json_text(text: str, source: str):
    """``json.loads(text)`` with every failure (syntax, nesting, huge numbers) as an :class:`InputError`."""
    check_nesting(text, source, kind="JSON")
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise InputError(f"{source}: not valid JSON: {exc}") from None


def read_json_file(path, *, kind: str = "JSON file"):
    """Parse a JSON file; every failure is an :class:`InputError` naming the file."""
    return parse_json_text(read_text_file(path, kind=kind), str(path))


def _digits(value: int) -> int:
    return int(abs(value).bit_length() * math.log10(2)) + 1


def _short(value) -> str:
    if isinstance(value, int) and not isinstance(value, bool) and abs(value).bit_length() > 200:
        return f"an integer of ~{_digits(value)} digits"
    try:
        text = repr(value)
    except ValueError:  # an integer past Python's int-to-str digit limit
        return "a value that cannot be printed"
    return text if len(text) <= 60 else text[:57] + "..."


def _location(loc) -> str:
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text or "(top level)"


def as_toml(value) -> str:
    """``value`` as TOML writes it (``true``, ``"5"``, ``[1, 2.5]``, ``nan``), shortened like :func:`_short`."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, int):
        return _short(value)
    elif isinstance(value, float):
        text = repr(value)  # as TOML: 2.5, 1e-05, nan, inf, -inf
    elif isinstance(value, str):
        text = json.dumps(value, ensure_ascii=False)
    elif isinstance(value, list | tuple):
        text = "[" + ", ".join(as_toml(item) for item in value[:8]) + (", ...]" if len(value) > 8 else "]")
    elif isinstance(value, dict):
        items = list(value.items())
        text = (
            "{"
            + ", ".join(f"{key} = {as_toml(item)}" for key, item in items[:4])
            + (", ...}" if len(items) > 4 else "}")
        )
    else:
        return _short(value)
    return text if len(text) <= 60 else text[:57] + "..."


#: pydantic's wording of the common errors, as robotcal words them (bounds from the error's context).
_MESSAGES = {
    "int_type": "must be an integer",
    "float_type": "must be a number",
    "finite_number": "must be a finite number",
    "bool_type": "must be true or false",
    "string_type": "must be a text",
    "list_type": "must be an array [...]",
    "tuple_type": "must be an array [...]",
    "dict_type": "must be a table {{...}}",
    "model_type": "must be a table {{...}}",
    "too_short": "must have at least {min_length} values",
    "too_long": "must have at most {max_length} values",
    "literal_error": "must be {expected}",
    "greater_than_equal": "must be >= {ge}",
    "greater_than": "must be > {gt}",
    "less_than_equal": "must be <= {le}",
    "less_than": "must be < {lt}",
}


def _problem(error) -> str:
    """One pydantic error as ``key `<k>`: <why>; got <value as written>``."""
    kind = error["type"]
    where = f"key `{_location(error['loc'])}`"
    if kind == "extra_forbidden":
        return f"{where}: unknown key"
    if kind == "missing":
        return f"{where}: missing required key"
    bounds = {key: f"{bound:g}" if isinstance(bound, float) else bound for key, bound in error.get("ctx", {}).items()}
    if kind == "value_error":  # a validator's own words (ValueError("must be +1 or -1"))
        message = str(bounds.get("error", error["msg"]))
    else:
        message = _MESSAGES[kind].format(**bounds) if kind in _MESSAGES else error["msg"]
    value = error.get("input")
    if kind == "float_type" and isinstance(value, int) and not isinstance(value, bool):  # past a float's range
        message = _MESSAGES["finite_number"]
    if not error["loc"] or isinstance(value, dict) or "got " in message:  # a table-wide check says what it saw
        return f"{where}: {message}"
    return f"{where}: {message}; got {as_toml(value)}"


def _closest_branches(errors: list) -> list:
    """The errors of a value that matches no type of a union (``start_deg``: numbers, or rows of numbers) for the
    types it comes closest to (fewest errors, then the deepest inside the value; every type on a tie), with
    pydantic's type tag (a location part such as ``list[float]``: key names hold no brackets) taken out of the
    location."""
    branches: dict[tuple, dict[str, list]] = {}
    kept = []
    for error in errors:
        loc = tuple(error["loc"])
        tag = next((k for k, part in enumerate(loc) if isinstance(part, str) and "[" in part), None)
        if tag is None:
            kept.append(error)
            continue
        branches.setdefault(loc[:tag], {}).setdefault(loc[tag], []).append(error | {"loc": loc[:tag] + loc[tag + 1 :]})
    for options in branches.values():
        scores = {tag: (len(found), -max(len(e["loc"]) for e in found)) for tag, found in options.items()}
        best = min(scores.values())
        kept.extend(error for tag, found in options.items() if scores[tag] == best for error in found)
    return kept


_Model = TypeVar("_Model", bound=BaseModel)


def validate_model(model: type[_Model], data: dict, source: str) -> _Model:
    """``model.model_validate(data)`` with errors as ``InputError("<source>: key <k>: <why>; got <value>")``, the
    value as the TOML file writes it (``true``, not 1)."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        problems = dict.fromkeys(_problem(error) for error in _closest_branches(exc.errors()))  # once each, in order
        raise InputError(f"{source}: " + "; ".join(problems)) from None


def parse_finite(cell: str, where: str) -> float:
    """A CSV cell as a finite float, else ``InputError("<where>: '<cell>' is not a (finite) number")``.

    ``where`` names the place, e.g. ``"capture.csv: line 7, column `x`"``.
    """
    text = cell.strip()
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{where}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise InputError(f"{where}: {text!r} is not a finite number")
    return value


def parse_whole(cell: str, where: str) -> int:
    """A CSV cell as a whole number (``3`` or ``3.0``; ``2.5`` is refused, never truncated), naming ``where``."""
    value = parse_finite(cell, where)
    if value != round(value):
        raise InputError(f"{where}: must be a whole number; got {cell.strip()!r}")
    return int(value)
