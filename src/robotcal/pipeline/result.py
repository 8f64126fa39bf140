"""What a calibration run produced, in memory: the contract between the pipeline, the run folder and the report.

A run's outputs are held as *documents*, one per file of the run folder (docs/results.md), keyed by the
file's path relative to the folder (POSIX separators):

- a JSON file is a ``dict`` (plain JSON types only: what ``json.loads`` would give back);
- a CSV file is a :class:`Table` (header and rows as the strings written to the file);
- a binary file (a PNG figure, ``draws.npz``) is the :class:`~pathlib.Path` of the file in the run folder:
  figures are embedded as they are, never parsed.

The pipeline (:func:`robotcal.pipeline.run_calibration`) builds them as it computes and writes them;
:func:`robotcal.pipeline.read_run` is the one place that reads a run folder back into the same object
(for ``robotcal report DIR``), and the report renders from it without touching the file system but to
embed figures.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["Document", "RunResult", "Table"]


@dataclass(frozen=True, slots=True)
class Table:
    """The contents of a CSV file: its header and its rows, cells as written (strings)."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...] = ()

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
    summary : robotcal.pipeline.summary.Summary or None
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
