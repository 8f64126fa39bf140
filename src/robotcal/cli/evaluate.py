"""``robotcal evaluate --scenario S --params P1.json [P2.json ...] --capture VALIDATION.csv --out DIR``."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from robotcal.cli import app
from robotcal.cli._common import FORCE_HELP, check_memory, console, handle_errors, pairs_bytes
from robotcal.errors import InputError
from robotcal.io import load_scenario, read_capture, read_parameters
from robotcal.io.output import check_output_folder, existing_inputs, result_folder
from robotcal.kinematics.model import ParameterSet
from robotcal.workflow import evaluate_scenario, versions

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


def _label(path: Path, used: set[str]) -> str:
    label = path.stem
    while label in used:
        label = f"{path.parent.name}/{label}" if "/" not in label else label + "'"
    used.add(label)
    return label


def _convergence(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    entry = (data.get("provenance") or {}).get("convergence") if isinstance(data, dict) else None
    if isinstance(entry, dict) and "rms_mm" in entry and "criterion" in entry:
        return entry
    return None


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
            "scenario": {"name": scenario.name, "source": scenario.source},
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


def write_evaluation_folder(folder: Path, rows, document: dict) -> list[str]:
    """Write ``evaluation.csv``, ``evaluation.json`` and (with convergence histories) ``convergence.png``
    into ``folder`` (an existing, normally temporary, folder); returns the file names."""
    (folder / "evaluation.csv").write_text(evaluation_csv(rows), encoding="utf-8")
    (folder / "evaluation.json").write_text(json.dumps(document, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    names = ["evaluation.csv", "evaluation.json"]
    histories = document.get("convergence") or {}
    if histories:
        from robotcal.report.refine import plot_convergence  # matplotlib only when writing figures

        plot_convergence(
            {label: {"criterion": h["criterion"], "rms_mm": h["rms_mm"]} for label, h in histories.items()},
            folder / "convergence.png",
        )
        names.append("convergence.png")
    return names


@app.command()
@handle_errors
def evaluate(
    scenario: Annotated[str, typer.Option("--scenario", "-s", help="Scenario name or TOML: robot and targets.")],
    params: Annotated[list[Path], typer.Option("--params", "-p", help="Parameter JSON to evaluate (repeatable).")],
    capture: Annotated[list[Path], typer.Option("--capture", "-c", help="Capture CSV to evaluate on (repeatable).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Result folder to write.")],
    nominal: Annotated[
        bool, typer.Option("--nominal/--no-nominal", help="Include the nominal parameters first, as the reference.")
    ] = True,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
) -> None:
    """Mean/max errors of parameter sets under the points and distances views (thesis Tables 4.10/4.11)."""
    inputs = existing_inputs(scenario, *params, *capture)
    check_output_folder(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    robot = loaded.robot
    used: set[str] = set()
    sets: dict[str, ParameterSet] = {}
    if nominal:
        sets["nominal"] = ParameterSet.nominal(robot)
        used.add("nominal")
    histories = {}
    for path in params:
        label = _label(path, used)
        sets[label] = read_parameters(path, robot)
        history = _convergence(path)
        if history is not None:
            histories[label] = history
    if not sets:
        raise InputError("nothing to evaluate: give --params or keep --nominal")
    captures = {}
    capture_labels: set[str] = set()
    for path in capture:
        captures[_label(path, capture_labels)] = read_capture(path, n_joints=robot.n_joints)
    largest = max((c.n_points for c in captures.values()), default=0)
    check_memory(
        f"the distances view of a capture of {largest} points",
        pairs_bytes(largest),
        "evaluate on a capture with fewer points",
    )
    rows = evaluate_scenario(loaded, captures, sets)
    document = evaluation_document(
        rows,
        loaded,
        parameter_files={label: str(path) for label, path in zip(list(sets)[int(nominal) :], params, strict=True)},
        capture_files={label: str(path) for label, path in zip(captures, capture, strict=True)},
        reference=next(iter(sets)),
        histories=histories,
    )
    with result_folder(out, inputs=inputs, force=force, command="robotcal evaluate") as folder:
        write_evaluation_folder(folder, rows, document)
    for capture_name in captures:
        for view in ("points", "distances"):
            table = Table(title=f"{capture_name}: {view} view", title_justify="left")
            for column in ("parameter set", "mean [mm]", "max [mm]", "RMS [mm]", "improvement [%]"):
                table.add_column(column, justify="right" if column != "parameter set" else "left")
            for row in rows:
                if row.capture == capture_name and row.view == view:
                    table.add_row(
                        row.parameter_set,
                        f"{row.mean_error_mm:.4f}",
                        f"{row.max_error_mm:.4f}",
                        f"{row.rms_error_mm:.4f}",
                        f"{row.improvement_pct:.2f}",
                    )
            console.print(table)
    console.print(
        f"wrote {out}/evaluation.csv, evaluation.json" + (", convergence.png" if histories else ""), highlight=False
    )
