"""What ``robotcal filter`` writes into its output folder (issue 28):

- the filtered program files, under their own names, in the encoding and with the line endings they were read in;
- ``points.csv``: one row per point (label, file, line, kind, motion, tool, base, status, correction, joint change,
  remaining error, the tool position uncertainty from the deployed model's draws when given, a note on the status,
  the nominal controller's readings and the command's), then one row per
  target the reader could not filter (status ``not_filtered``, the note saying why);
- ``filter.html``: the summary and the same table, a page that needs no network;
- ``filter.json``: provenance (versions, the inputs and their SHA-256, the counts).
"""

from __future__ import annotations

import csv
import hashlib
import html
import io
import json
import math
from pathlib import Path

from robotcal.io.results.output import SIGNATURE
from robotcal.io.results.provenance import versions
from robotcal.programs.filter import FilteredProgram

__all__ = ["POINT_COLUMNS", "STATUS_NOTES", "points_table", "write_report"]

#: The columns of ``points.csv`` before the readings (``taught_q1..qN``, ``command_q1..qN`` [deg]).
POINT_COLUMNS = (
    "label", "file", "line", "kind", "motion", "tool", "base", "status", "written", "correction_mm",
    "correction_deg", "largest_change_deg", "position_error_mm", "orientation_error_deg", "tcp_u_mm", "note",
)  # fmt: skip
#: What a point's status means (the ``note`` of points.csv).
STATUS_NOTES = {
    "ok": "",
    "near_singular": "at a singularity: the damped command, with the error it leaves",
    "large_correction": "a correction larger than the calibration explains: the damped command, check it",
    "outside_limits": "reachable only beyond a joint limit: left as written",
    "unreachable": "out of the calibrated robot's reach on its branch: left as written",
    "config_mismatch": "no nominal solution has the point's configuration data: left as written",
}


def _number(value: float, digits: int = 6) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value:.{digits}g}"


def points_table(result: FilteredProgram) -> list[list[str]]:
    """The rows of ``points.csv``, header first."""
    n = max((len(p.taught_deg) for p in result.points), default=6)
    rows = [[*POINT_COLUMNS, *(f"taught_q{i + 1}" for i in range(n)), *(f"command_q{i + 1}" for i in range(n))]]
    for record in result.points:
        point = record.point
        rows.append(
            [
                point.label, point.file, str(point.line), point.kind, point.motion, point.tool or "", point.base or "",
                record.status, "yes" if record.written else "no", _number(record.correction_mm),
                _number(record.correction_deg), _number(record.largest_change_deg), _number(record.position_error_mm),
                _number(record.orientation_error_deg), _number(record.tcp_u_mm), "; ".join(filter(None, (STATUS_NOTES[record.status], record.remark))),
                *(_number(v, 10) for v in record.taught_deg),
                *(_number(v, 10) for v in record.command_deg),
            ]
        )  # fmt: skip
    for file, line, why in result.program.skipped:
        rows.append(["", file, str(line), "", "", "", "", "not_filtered", "no", "", "", "", "", "", "", why] + [""] * (2 * n))
    return rows


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _page(result: FilteredProgram, rows: list[list[str]], title: str) -> str:
    counts = ", ".join(f"{count} {status}" for status, count in result.counts.items()) or "no points"
    head = "".join(f"<th>{html.escape(cell)}</th>" for cell in rows[0][: len(POINT_COLUMNS)])
    body = []
    for row in rows[1:]:
        status = row[7]
        style = "" if status == "ok" else ' class="flag"'
        cells = "".join(f"<td>{html.escape(cell)}</td>" for cell in row[: len(POINT_COLUMNS)])
        body.append(f"<tr{style}>{cells}</tr>")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<title>{html.escape(title)}</title><style>"
        "body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;font-size:90%}"
        "td,th{border:1px solid #bbb;padding:2px 6px;text-align:left}tr.flag{background:#fde8e8}"
        "</style></head><body>"
        f"<h1>{html.escape(title)}</h1><p>{html.escape(counts)}. Only <b>ok</b> points are exact (the calibrated model "
        "at the filtered target reaches the original target to 1e-6 mm and 1e-6 deg on the same branch); the others "
        "are flagged and described in docs/deploy.md. Corrections: how far the filtered target moves the tool on the "
        "nominal model; errors: what remains on the calibrated model; tcp_u_mm: the standard uncertainty of the tool "
        "position at the command from the deployed model's Monte Carlo (with --draws).</p>"
        f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table></body></html>\n"
    )


def write_report(result: FilteredProgram, folder: Path, *, params: Path, program: Path, encoding: str = "utf-8") -> None:
    """Write the filtered files, ``points.csv``, ``filter.html`` and ``filter.json`` into ``folder``."""
    folder = Path(folder)
    for name, text in result.texts.items():
        (folder / name).write_bytes(text.encode(encoding))
    rows = points_table(result)
    stream = io.StringIO()
    stream.write(f"# {SIGNATURE} filter: every point of {program.name} with the calibrated model {Path(params).name}\n")
    csv.writer(stream, lineterminator="\n").writerows(rows)
    (folder / "points.csv").write_text(stream.getvalue(), encoding="utf-8")
    title = f"robotcal filter: {program.name} with {Path(params).name}"
    (folder / "filter.html").write_text(_page(result, rows, title), encoding="utf-8")
    sources = [Path(params), *(Path(program).with_name(name) for name in result.program.texts)]
    provenance = {
        "command": "filter",
        "language": result.program.language,
        "versions": versions(),
        "inputs": {str(path): _sha256(path) for path in sources},
        "counts": result.counts,
        "not_filtered": len(result.program.skipped),
    }
    (folder / "filter.json").write_text(json.dumps(provenance, indent=2) + "\n", encoding="utf-8")
