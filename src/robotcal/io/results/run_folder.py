"""A run folder (docs/results.md): its contract, the one reader of it, and the writer of its documents.

What a calibration run produced is held as *documents*, one per file of the run folder, keyed by the
file's path relative to the folder (POSIX separators):

- a JSON file is a ``dict`` (plain JSON types only: what ``json.loads`` would give back);
- a CSV file is a :class:`Table` (header and rows as written, with each column's numbers parsed once);
- a binary file (a PNG figure, ``draws.npz``) is the :class:`~pathlib.Path` of the file in the run folder:
  figures are embedded as they are, never parsed.

The pipeline (:func:`robotcal.run_calibration`) builds them as it computes and writes them (:func:`write_json`,
:func:`write_csv` return a document exactly as :func:`read_run` reads it back); :func:`read_run` is the one
place that reads a run folder back into the same :class:`RunResult` (for ``robotcal report DIR``), and the
report renders from it without touching the file system but to embed figures.

Safety: a symbolic link anywhere on a file's way from the run folder, or a path that resolves outside it,
is refused (the file becomes a problem, never read); so is a file that cannot be read or parsed. Problems
are ``"relative/path: why"`` strings in :attr:`RunResult.problems`; only a missing folder, or a folder that
holds none of a run's files, raises :class:`~robotcal.errors.InputError`. Only the names a run writes
(:data:`OUTPUTS` and ``run.json``) are read: other files the user keeps in the folder are not the run's.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robotcal.errors import InputError
from robotcal.io.atomic import atomic_write_text
from robotcal.io.results.run_summary import summarise
from robotcal.io.schema._validation import parse_json_text, read_text_file

if TYPE_CHECKING:
    from robotcal.identification.records import RefinementResult

__all__ = [
    "OUTPUTS",
    "REPORT_NAME",
    "RUN_ENTRIES",
    "RUN_RECORD",
    "STAGES",
    "Document",
    "RunResult",
    "Table",
    "json_text",
    "read_document",
    "read_run",
    "refusal",
    "run_documents",
    "table_from_text",
    "write_csv",
    "write_json",
]

#: Stages in order (the names of ``run.json`` ``stages`` and of the report's stage table).
STAGES = ("simulate", "identify", "joints", "refine", "evaluate", "uncertainty", "tcp", "plan", "iso9283", "report")
#: What each stage writes under the run folder (docs/results.md).
OUTPUTS = {
    "simulate": ("truth.json", "capture.csv", "validation.csv", "poses.csv"),
    "identify": ("cpa",),
    "joints": ("joints",),
    "refine": ("refine",),
    "evaluate": ("evaluation",),
    "uncertainty": ("uncertainty", "uncertainty-refined"),
    "tcp": ("tcp",),
    "plan": ("plan",),
    "iso9283": ("iso9283",),
    "report": ("report.html",),
}
#: The run's own record, rewritten after every stage.
RUN_RECORD = "run.json"
#: The run's report, written last.
REPORT_NAME = "report.html"


@dataclass(frozen=True, slots=True)
class Table:
    """The contents of a CSV file: its header, its rows (cells as written, strings) and, per column, whether
    every non-empty cell is a number (parsed once, when the table is made)."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...] = ()
    numeric: tuple[bool, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "numeric", tuple(_numbers([row[k] for row in self.rows]) for k in range(len(self.header)))
        )

    def column(self, name: str) -> tuple[str, ...]:
        """Every cell of column ``name`` (KeyError naming the column when there is none)."""
        try:
            k = self.header.index(name)
        except ValueError:
            raise KeyError(f"no column {name!r} (columns: {', '.join(self.header)})") from None
        return tuple(row[k] for row in self.rows)

    def records(self) -> list[dict[str, str]]:
        """The rows as ``{column: cell}`` dicts."""
        return [dict(zip(self.header, row, strict=True)) for row in self.rows]


def _numbers(cells: list[str]) -> bool:
    """A column has a non-empty cell and every non-empty cell parses as a float."""
    present = [cell.strip() for cell in cells if cell.strip()]
    try:
        for cell in present:
            float(cell)
    except ValueError:
        return False
    return bool(present)


#: One output of a run: a JSON object, a CSV table, or the path of a binary file (PNG, NPZ).
Document = dict | Table | Path


@dataclass(frozen=True, slots=True, kw_only=True)
class RunResult:
    """Everything a run produced, in memory.

    Attributes
    ----------
    folder : Path or None
        The run folder the documents were written to (or read from); None for a run kept in memory.
    record : dict
        ``run.json``: command, scenario echo, seeds, versions, per-stage status, times and warnings.
    documents : mapping of str to Document
        Every output file of the run by its path relative to the run folder (see the module docstring).
    summary : robotcal.io.results.run_summary.Summary or None
        The headline figures (how good, how sure, where), computed once from the documents.
    problems : tuple of str
        Files of a run folder that exist but could not be read (``read_run``), each "path: why".
    results : mapping of str to object
        The typed results of a run computed in this process, for Python users (empty when read from a
        folder): ``"truth"``, ``"nominal"``, ``"cpa"`` (ParameterSet), ``"refined"`` (criterion -> RefineResult),
        ``"capture"``, ``"validation"`` (Capture), ``"evaluation"`` (rows), ``"joints"``, ``"montecarlo"``
        (``"cpa"``/``"refined"`` -> MonteCarloResult), ``"tcp"`` (mode -> TCPUncertainty), ``"plan"``.
    """

    folder: Path | None = None
    record: dict = field(default_factory=dict)
    documents: Mapping[str, Document] = field(default_factory=dict)
    summary: Any = None
    problems: tuple[str, ...] = ()
    results: Mapping[str, Any] = field(default_factory=dict)

    def json(self, name: str) -> dict | None:
        """The JSON document ``name`` (a path relative to the run folder), or None when the run has none."""
        document = self.documents.get(name)
        return document if isinstance(document, dict) else None

    def table(self, name: str) -> Table | None:
        """The CSV document ``name``, or None when the run has none."""
        document = self.documents.get(name)
        return document if isinstance(document, Table) else None

    def file(self, name: str) -> Path | None:
        """The binary file ``name`` (a figure, draws), or None when the run has none."""
        document = self.documents.get(name)
        return document if isinstance(document, Path) else None

    def names(self, folder: str = "", suffix: str = "") -> list[str]:
        """Sorted document names under ``folder`` (relative, no trailing slash) ending with ``suffix``."""
        prefix = f"{folder.rstrip('/')}/" if folder else ""
        return sorted(name for name in self.documents if name.startswith(prefix) and name.endswith(suffix))

    @property
    def status(self) -> str:
        """``run.json``'s status: ``done``, ``failed``, ``interrupted``, ``running`` (``unknown`` without a record)."""
        return str(self.record.get("status", "unknown"))

    @property
    def deployed(self) -> RefinementResult | None:
        """The deployed refinement (points criterion) of a run computed in this process, a ``RefinementResult``
        (``.parameters``, ``.model``, ``.health``...); None otherwise."""
        return (self.results.get("refined") or {}).get("points")

    @property
    def montecarlo(self) -> Mapping[str, Any]:
        """``{"cpa": MonteCarloResult, "refined": MonteCarloResult}`` of a run computed in this process ({})."""
        return self.results.get("montecarlo") or {}

    def __repr__(self) -> str:
        """One line for notebooks: where, how it ended, what was deployed and how good it is."""
        stages = found if isinstance(found := self.record.get("stages"), dict) else {}
        done = sum(1 for entry in stages.values() if isinstance(entry, dict) and entry.get("status") == "done")
        parts = [f"folder={str(self.folder)!r}" if self.folder is not None else "in memory", f"status={self.status!r}"]
        if stages:
            parts.append(f"stages {done}/{len(stages)} done")
        if self.deployed is not None:
            parts.append(f"deployed model {self.deployed.model!r}")
        headline = (self.json("evaluation/evaluation.json") or {}).get("headline") or {}
        if "before_mean_mm" in headline and "after_mean_mm" in headline:
            parts.append(f"validation mean {headline['before_mean_mm']:.3g} -> {headline['after_mean_mm']:.3g} mm")
        parts.append(f"{len(self.documents)} files")
        return f"RunResult({', '.join(parts)})"


#: The top-level names a run writes: ``run.json`` then every stage's outputs, in stage order.
RUN_ENTRIES = (RUN_RECORD, *(name for names in OUTPUTS.values() for name in names))
#: The suffixes read as documents (every other file is a Path).
_PARSED = (".json", ".csv")


def json_text(document: dict, *, default: Callable[[Any], Any] | None = None) -> str:
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


def write_json(path: str | os.PathLike[str], document: dict) -> dict:
    """Write ``document`` atomically as JSON (:func:`json_text`); returns it as :func:`read_run` reads it."""
    text = json_text(document)
    atomic_write_text(path, text)
    return json.loads(text)


def write_csv(path: str | os.PathLike[str], text: str) -> Table:
    """Write CSV ``text`` atomically; returns its :class:`Table` as :func:`read_run` reads it."""
    atomic_write_text(path, text)
    return table_from_text(text, str(path))


def refusal(root: str | os.PathLike[str], relative: str | os.PathLike[str]) -> str | None:
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


def read_document(root: str | os.PathLike[str], relative: str) -> Document:
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


def run_documents(root: str | os.PathLike[str], entries: Iterable[str] = RUN_ENTRIES) -> tuple[dict[str, Document], list[str]]:
    """Every document under the top-level ``entries`` of run folder ``root`` and the problems met."""
    root = Path(root)
    documents: dict[str, Document] = {}
    problems: list[str] = []
    for entry in entries:
        if (root / entry).exists() or (root / entry).is_symlink():
            _walk(root, entry, documents, problems)
    return documents, problems


def read_run(folder: str | os.PathLike[str]) -> RunResult:
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
    return RunResult(
        folder=root,
        record=record,
        documents=documents,
        summary=summarise(record, documents),
        problems=tuple(problems),
    )
