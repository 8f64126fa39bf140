"""The run folder: the one place that reads it back (:func:`read_run`) and the writer of in-memory documents.

A run folder (docs/results.md) holds one file per :data:`~robotcal.pipeline.result.Document`: JSON files
are read as plain ``dict`` (:func:`robotcal.io._validation.parse_json_text`), CSV files as
:class:`~robotcal.pipeline.result.Table` (cells exactly as written), every other file (PNG figures,
``draws.npz``, ``report.html``) as its :class:`~pathlib.Path`, never opened. Only the names a run writes
(:data:`robotcal.pipeline.plan.OUTPUTS` and ``run.json``) are read: other files the user keeps in the folder
are not the run's.

Safety: a symbolic link anywhere on a file's way from the run folder, or a path that resolves outside it,
is refused (the file becomes a problem, never read); so is a file that cannot be read or parsed. Problems
are ``"relative/path: why"`` strings in :attr:`RunResult.problems`; only a missing folder, or a folder that
holds none of a run's files, raises :class:`~robotcal.errors.InputError`.

The writer (:func:`write_json`, :func:`write_csv`) writes a document atomically and returns it exactly as
:func:`read_run` would read it back, so a run held in memory and the same run read from its folder hold
equal documents.
"""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

from robotcal.errors import InputError
from robotcal.io._validation import parse_json_text, read_text_file
from robotcal.io.atomic import atomic_write_text
from robotcal.pipeline.plan import OUTPUTS, RUN_RECORD
from robotcal.pipeline.result import Document, RunResult, Table

__all__ = [
    "RUN_ENTRIES",
    "json_text",
    "read_document",
    "read_run",
    "refusal",
    "run_documents",
    "table_from_text",
    "write_csv",
    "write_json",
]

#: The top-level names a run writes: ``run.json`` then every stage's outputs, in stage order.
RUN_ENTRIES = (RUN_RECORD, *(name for names in OUTPUTS.values() for name in names))
#: The suffixes read as documents (every other file is a Path).
_PARSED = (".json", ".csv")


def json_text(document: dict, *, default=None) -> str:
    """The text of a JSON document as the run writes it (indented, no NaN, a final newline); ``default`` as
    :func:`json.dumps` (``run.json`` writes ``str`` of what JSON has no type for)."""
    return json.dumps(document, indent=2, allow_nan=False, default=default) + "\n"


def table_from_text(text: str, source: str = "CSV") -> Table:
    """The :class:`Table` of CSV ``text``: the first record is the header; blank records are skipped.

    Raises :class:`InputError` when a row has another number of cells than the header.
    """
    rows = [tuple(row) for row in csv.reader(io.StringIO(text, newline="")) if row]
    if not rows:
        return Table(header=())
    header, body = rows[0], rows[1:]
    for number, row in enumerate(body, start=2):
        if len(row) != len(header):
            raise InputError(f"{source}: row {number} has {len(row)} cells; the header has {len(header)}")
    return Table(header=header, rows=tuple(body))


def write_json(path, document: dict) -> dict:
    """Write ``document`` atomically as JSON (:func:`json_text`); returns it as :func:`read_run` reads it."""
    text = json_text(document)
    atomic_write_text(path, text)
    return json.loads(text)


def write_csv(path, text: str) -> Table:
    """Write CSV ``text`` atomically; returns its :class:`Table` as :func:`read_run` reads it."""
    atomic_write_text(path, text)
    return table_from_text(text, str(path))


def refusal(root, relative) -> str | None:
    """Why ``relative`` may not be read from run folder ``root``: a symbolic link on its way, or a
    target outside the folder; None when it may be read."""
    root = Path(root)
    current = root
    for part in Path(relative).parts:
        current = current / part
        if current.is_symlink():
            return "refused: a symbolic link (only files inside the run folder are read)"
    try:
        inside = (root / relative).resolve().is_relative_to(root.resolve())
    except (OSError, RuntimeError):
        inside = False
    return None if inside else "refused: resolves outside the run folder"


def read_document(root, relative: str) -> Document:
    """The document ``relative`` of run folder ``root`` (JSON -> dict, CSV -> Table, other -> Path).

    Raises :class:`InputError` ``"relative: why"`` when the file is refused (:func:`refusal`), missing or
    cannot be read or parsed.
    """
    root = Path(root)
    why = refusal(root, relative)
    if why is not None:
        raise InputError(f"{relative}: {why}")
    path = root / relative
    if not path.is_file():
        raise InputError(f"{relative}: not a regular file")
    suffix = path.suffix.lower()
    if suffix not in _PARSED:
        return path
    try:
        text = read_text_file(path, kind=f"{suffix[1:].upper()} file")
    except InputError as exc:
        raise InputError(f"{relative}: {str(exc).removeprefix(f'{path}: ')}") from None
    if suffix == ".csv":
        try:
            return table_from_text(text, relative)
        except csv.Error as exc:
            raise InputError(f"{relative}: not a readable CSV file ({exc})") from None
    try:
        data = parse_json_text(text, relative)
    except InputError as exc:
        raise InputError(f"{relative}: not a readable JSON file ({str(exc).removeprefix(relative + ': ')})") from None
    if not isinstance(data, dict):
        raise InputError(f"{relative}: expected a JSON object at the top level")
    return data


def _walk(root: Path, relative: str, documents: dict, problems: list) -> None:
    """Read ``relative`` (a file, or a folder recursively, in sorted order) into ``documents``."""
    path = root / relative
    why = refusal(root, relative)
    if why is not None:
        problems.append(f"{relative}: {why}")
        return
    if path.is_dir():
        try:
            names = sorted(os.listdir(path))
        except OSError as exc:
            problems.append(f"{relative}: cannot list the folder ({exc.strerror or exc})")
            return
        for name in names:
            if not name.startswith("."):  # atomic writes' temporary files and folders
                _walk(root, f"{relative}/{name}", documents, problems)
        return
    try:
        documents[relative] = read_document(root, relative)
    except InputError as exc:
        problems.append(str(exc))


def run_documents(root, entries=RUN_ENTRIES) -> tuple[dict[str, Document], list[str]]:
    """Every document under the top-level ``entries`` of run folder ``root`` and the problems met."""
    root = Path(root)
    documents: dict[str, Document] = {}
    problems: list[str] = []
    for entry in entries:
        if (root / entry).exists() or (root / entry).is_symlink():
            _walk(root, entry, documents, problems)
    return documents, problems


def read_run(folder) -> RunResult:
    """Read a run folder (docs/results.md) into a :class:`RunResult`: the one place that reads one.

    Parameters
    ----------
    folder : path
        A folder written by ``robotcal run`` (or by hand, following docs/results.md); every stage is optional.

    Returns
    -------
    RunResult
        ``record`` is ``run.json`` (empty when missing), ``documents`` every readable file of the run,
        ``summary`` the headline figures, ``problems`` the files that exist but were refused or could not
        be read ("path: why"); ``results`` is empty.

    Raises
    ------
    InputError
        ``folder`` is missing, not a folder, or holds none of a run's files.
    """
    root = Path(folder)
    if not root.exists():
        raise InputError(f"{root}: run folder not found")
    if not root.is_dir():
        raise InputError(f"{root}: not a folder (expected a run folder written by `robotcal run`)")
    if not any((root / entry).exists() or (root / entry).is_symlink() for entry in RUN_ENTRIES):
        raise InputError(
            f"{root}: no results found (expected at least one of {', '.join(RUN_ENTRIES)}; see docs/results.md)"
        )
    documents, problems = run_documents(root)
    record = documents.get(RUN_RECORD)
    record = record if isinstance(record, dict) else {}
    from robotcal.pipeline.summary import summarise

    return RunResult(
        folder=root,
        record=record,
        documents=documents,
        summary=summarise(record, documents),
        problems=tuple(problems),
    )
