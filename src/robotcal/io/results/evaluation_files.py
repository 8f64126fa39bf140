"""The files of ``evaluation/``: parameter sets evaluated on captures (thesis Tables 4.10/4.11), errors in mm.

``robotcal evaluate`` and the evaluate stage of a run build ``evaluation.csv`` (:func:`evaluation_csv`) and
``evaluation.json`` (:func:`evaluation_document`, with the headline of :func:`evaluation_headline`) with the
same functions (:func:`write_evaluation_folder`; the convergence figure:
:func:`robotcal.plots.refine.plot_convergence`).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from robotcal.io.results.provenance import scenario_echo, versions
from robotcal.io.results.run_folder import Document, write_csv, write_json

__all__ = [
    "COLUMNS",
    "evaluation_csv",
    "evaluation_document",
    "convergence_of",
    "evaluation_headline",
    "write_evaluation_folder",
]

#: Columns of ``evaluation.csv`` (and of each row of ``evaluation.json``).
COLUMNS = (
    "parameter_set",
    "view",
    "capture",
    "n_errors",
    "mean_error_mm",
    "max_error_mm",
    "rms_error_mm",
    "improvement_pct",
)


def evaluation_csv(rows) -> str:
    """``evaluation.csv``: one row per parameter set, view and capture (:data:`COLUMNS`)."""
    stream = io.StringIO()
    writer = csv.writer(stream, lineterminator="\n")
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow([getattr(row, column) for column in COLUMNS])
    return stream.getvalue()


def evaluation_headline(rows, *, reference: str, after: str | None = None) -> dict | None:
    """Headline numbers of the report: mean error of ``reference`` (before) and ``after`` (default: the
    last parameter set) on the first capture, points view; ``None`` when either row is missing."""
    if not rows:
        return None
    labels = list(dict.fromkeys(row.parameter_set for row in rows))
    after = labels[-1] if after is None else after
    capture = rows[0].capture
    chosen = {row.parameter_set: row for row in rows if row.capture == capture and row.view == "points"}
    if reference not in chosen or after not in chosen:
        return None
    return {
        "capture": capture,
        "view": "points",
        "before_label": reference,
        "after_label": after,
        "before_mean_mm": chosen[reference].mean_error_mm,
        "after_mean_mm": chosen[after].mean_error_mm,
    }


def evaluation_document(
    rows,
    scenario,
    *,
    parameter_files: dict,
    capture_files: dict,
    reference: str,
    histories: dict,
    headline_after: str | None = None,
) -> dict:
    """``evaluation.json``: the rows, the reference set, the headline, settings, convergence, versions."""
    return {
        "rows": [{column: getattr(row, column) for column in COLUMNS} for row in rows],
        "reference": reference,
        "headline": evaluation_headline(rows, reference=reference, after=headline_after),
        "settings": {
            "scenario": scenario_echo(scenario),
            "parameter_files": parameter_files,
            "capture_files": capture_files,
            "views": {
                "points": "distance per point after Horn registration of the predicted onto the measured points",
                "distances": "absolute error of every pairwise distance between points at different poses",
            },
            "improvement": "100 * (1 - mean / mean of the reference set), per capture and view",
        },
        "convergence": histories,
        "versions": versions(),
    }


def write_evaluation_folder(folder: Path, rows, document: dict) -> dict[str, Document]:
    """Write ``evaluation.csv`` and ``evaluation.json`` into ``folder`` (an existing, normally temporary,
    folder); returns the documents by file name."""
    return {
        "evaluation.csv": write_csv(folder / "evaluation.csv", evaluation_csv(rows)),
        "evaluation.json": write_json(folder / "evaluation.json", document),
    }


def convergence_of(document: dict) -> dict:
    """The refinement histories of ``evaluation.json`` as :func:`robotcal.plots.refine.plot_convergence` takes
    them (label -> criterion and RMS per iteration [mm]); empty without them."""
    histories = document.get("convergence") or {}
    return {label: {"criterion": h["criterion"], "rms_mm": h["rms_mm"]} for label, h in histories.items()}
