"""The self-contained HTML calibration report of a run folder (docs/results.md, docs/report.md).

:func:`build_report` reads only the files of a run folder (``run.json``, ``truth.json``,
``capture.csv``, ``validation.csv``, ``cpa/``, ``refine/``, ``evaluation/``, ``joints/``,
``uncertainty/``, ``tcp/*/``) and writes ``report.html``: a summary with the headline numbers first,
then the parameters, evaluation, joint diagnostics, Monte Carlo, TCP, workspace, the interactive 3-D
view of the capture and the provenance. Nothing is recomputed except the circle fits drawn in the
3-D view. Every stage is optional: a missing folder gives a "stage not run" note, an unreadable
file a visible problem note, never an exception.

The page needs no network: CSS and scripts are inline, figures are PNG ``data:`` URIs, and a
Content-Security-Policy forbids any other source. Its last script checks that every figure decoded
and every canvas drew, then sets ``<body data-status="ok">`` (or ``"error"``, with the messages in
``#rc-errors``); the browser test reads that.
"""

from __future__ import annotations

import base64
import csv
import datetime as _dt
import hashlib
import html
import json
import math
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import robotcal
from robotcal.errors import InputError, RobotcalError
from robotcal.io._validation import parse_json_text
from robotcal.io.atomic import atomic_write_text
from robotcal.kinematics.model import LENGTH_KINDS, PARAMETER_KINDS
from robotcal.report.viewer3d import asset_text, render_viewer, viewer_scene

__all__ = ["REPORT_NAME", "Report", "ReportSection", "render_report", "build_report"]

REPORT_NAME = "report.html"

#: Files or folders whose presence makes a folder a run folder.
_RUN_ENTRIES = (
    "run.json",
    "truth.json",
    "capture.csv",
    "validation.csv",
    "cpa",
    "refine",
    "evaluation",
    "joints",
    "uncertainty",
    "tcp",
)

#: Stages in pipeline order: (name, folder or file under the run folder).
_STAGES = (
    ("simulate", "capture.csv"),
    ("identify", "cpa"),
    ("refine", "refine"),
    ("evaluate", "evaluation"),
    ("joints", "joints"),
    ("uncertainty", "uncertainty"),
    ("uncertainty", "uncertainty-refined"),
    ("tcp", "tcp"),
    ("plan", "plan"),
)

#: Captions of the figures the stages are known to write (others get one from the file name, or from
#: a ``"figures": {file: caption}`` mapping in the stage's JSON).
_CAPTIONS = {
    "convergence.png": "Convergence of the refinement: residual RMS (mm) per iteration, per criterion.",
    "ellipsoid.png": "95 % uncertainty ellipsoid of the TCP position (mm).",
    "trajectory.png": "Standard uncertainty of the TCP position along the trajectory (mm).",
    "workspace.png": "Standard uncertainty of the TCP position over the workspace (mm).",
    "scatter.png": "Monte Carlo draws of the TCP position with the coverage ellipsoid (mm).",
    "histograms.png": "Monte Carlo histograms of the TCP coordinates X, Y, Z (mm) and A, B, C (deg).",
    "backlash_vectors.png": "Backlash vectors (return − forward sweep) along each circle, magnified (mm).",
    "backlash_xyz.png": "Backlash components X, Y, Z per joint (mm).",
    "backlash_magnitude.png": "Backlash magnitude per joint (mm).",
    "eccentricity_axial.png": "Axial eccentricity: distance of each point to its circle's plane (mm).",
    "eccentricity_radial.png": "Radial eccentricity: in-plane distance of each point to its circle (mm).",
}

_UNIT_SUFFIXES = (
    ("_um_per_m", "µm/m"),
    ("_mm2", "mm²"),
    ("_mm", "mm"),
    ("_deg", "deg"),
    ("_um", "µm"),
    ("_rad", "rad"),
    ("_pct", "%"),
    ("_percent", "%"),
    ("_s", "s"),
)

_TABLE_ROWS = 40  # longer CSV files show their first rows and say so


# --------------------------------------------------------------------------------------------------
# results


@dataclass(frozen=True, slots=True, kw_only=True)
class ReportSection:
    """One section of the report: anchor, title and whether its stage had results."""

    id: str
    title: str
    present: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class Report:
    """A rendered report.

    Attributes
    ----------
    html : str
        The whole page.
    path : Path or None
        Where it was written (None from :func:`render_report`).
    sections : tuple of ReportSection
    figures : int
        PNG figures embedded.
    canvases : int
        Interactive 3-D views.
    problems : tuple of str
        Files that exist but could not be read; each is also shown in the page.
    """

    html: str
    path: Path | None = None
    sections: tuple[ReportSection, ...] = ()
    figures: int = 0
    canvases: int = 0
    problems: tuple[str, ...] = ()


# --------------------------------------------------------------------------------------------------
# reading the run folder


@dataclass(slots=True)
class _Run:
    """Cached, forgiving reads of a run folder; what cannot be read becomes a problem note."""

    root: Path
    problems: list[str] = field(default_factory=list)
    figures: int = 0
    _json: dict = field(default_factory=dict)
    _csv: dict = field(default_factory=dict)

    def path(self, relative: str) -> Path:
        return self.root / relative

    def _linked(self, relative) -> str | None:
        """Why ``relative`` may not be read: a symbolic link on its way, or a target outside the run folder."""
        current = self.root
        for part in Path(relative).parts:
            current = current / part
            if current.is_symlink():
                return "refused: a symbolic link (the report reads only files inside the run folder)"
        try:
            inside = (self.root / relative).resolve().is_relative_to(self.root.resolve())
        except (OSError, RuntimeError):
            inside = False
        return None if inside else "refused: resolves outside the run folder"

    def readable(self, relative: str) -> Path | None:
        """The path of a regular file inside the run folder, else None (a link or escape is noted)."""
        why = self._linked(relative)
        if why is not None:
            if self.path(relative).exists() or self.path(relative).is_symlink():
                self.problem(relative, why)
            return None
        path = self.path(relative)
        return path if path.is_file() else None

    def exists(self, relative: str) -> bool:
        return self.path(relative).exists()

    def problem(self, relative: str, what: str) -> str:
        message = f"{relative}: {what}"
        self.problems.append(message)
        return f'<p class="rc-problem">Could not read <code>{_e(relative)}</code>: {_e(what)}</p>'

    def json(self, relative: str):
        """Parsed JSON object, or None when the file is missing or unreadable (noted)."""
        if relative not in self._json:
            data = None
            path = self.readable(relative)
            if path is not None:
                try:
                    data = parse_json_text(path.read_text(encoding="utf-8"), relative)
                except InputError as exc:
                    self.problem(relative, f"not a readable JSON file ({str(exc).removeprefix(relative + ': ')})")
                    data = None
                except (OSError, ValueError) as exc:
                    self.problem(relative, f"not a readable JSON file ({exc})")
                else:
                    if not isinstance(data, dict):
                        self.problem(relative, "expected a JSON object at the top level")
                        data = None
            self._json[relative] = data
        return self._json[relative]

    def csv(self, relative: str):
        """``(header, rows)`` of a CSV file, or None when missing or unreadable (noted)."""
        if relative not in self._csv:
            table = None
            path = self.readable(relative)
            if path is not None:
                try:
                    with path.open(newline="", encoding="utf-8") as stream:
                        rows = [row for row in csv.reader(stream) if row]
                except (OSError, UnicodeDecodeError, csv.Error) as exc:
                    self.problem(relative, f"not a readable CSV file ({exc})")
                else:
                    if not rows:
                        self.problem(relative, "empty CSV file")
                    else:
                        header = [name.strip() for name in rows[0]]
                        body = [[cell.strip() for cell in row] for row in rows[1:]]
                        bad = [k + 2 for k, row in enumerate(body) if len(row) != len(header)]
                        if bad:
                            self.problem(relative, f"row {bad[0]} has a different number of columns than the header")
                            body = [row for row in body if len(row) == len(header)]
                        table = (header, body)
            self._csv[relative] = table
        return self._csv[relative]

    def files(self, folder: str, pattern: str) -> list[str]:
        base = self.path(folder)
        if not base.is_dir():
            return []
        return sorted(str(p.relative_to(self.root)) for p in base.glob(pattern) if p.is_file() or p.is_symlink())


# --------------------------------------------------------------------------------------------------
# formatting


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _number(text):
    """Float from a CSV cell or JSON value, else None."""
    if isinstance(text, bool):
        return None
    if isinstance(text, (int, float)):
        return float(text)
    try:
        return float(str(text).strip())
    except ValueError:
        return None


def _fmt(value, spec: str = ".6g", *, exponent: bool = True) -> str:
    """A number for people: ``spec``, switching to exponent notation for tiny/huge ones if ``exponent``."""
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    value = float(value)
    if not math.isfinite(value):
        return str(value)
    if exponent and value != 0.0 and (abs(value) < 1e-4 or abs(value) >= 1e7):
        return f"{value:.3e}"
    text = format(value, spec)
    return text[1:] if re.fullmatch(r"-0\.?0*", text) else text  # no "-0.0000"


def _length(mm) -> str:
    """A length for a headline: µm below 1 mm, else mm, 3 significant digits."""
    if mm is None:
        return "n/a"
    return f"{_fmt(mm * 1e3, '.3g', exponent=False)} µm" if abs(mm) < 1.0 else f"{_fmt(mm, '.3g', exponent=False)} mm"


def _cell(text: str) -> str:
    number = _number(text)
    if number is None or re.fullmatch(r"[+-]?\d+", text.strip() or "x"):
        return _e(text)
    return _e(_fmt(number))


def _label(name: str) -> str:
    """``"plane_rms_mm"`` -> ``"plane rms (mm)"``: units named by the key suffix go in brackets."""
    for suffix, unit in _UNIT_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            return f"{name[: -len(suffix)].replace('_', ' ')} ({unit})"
    return name.replace("_", " ")


def _lookup(data, *paths: str):
    """First value found under one of the dotted ``paths`` of nested dicts, else None."""
    for dotted in paths:
        value = data
        for key in dotted.split("."):
            if isinstance(value, dict) and key in value:
                value = value[key]
            else:
                value = None
                break
        if value is not None:
            return value
    return None


def _note(text: str) -> str:
    return f'<p class="rc-note">{text}</p>'


def _not_run(what: str) -> str:
    return _note(f"Stage not run: this run folder has no <code>{_e(what)}</code>.")


def _table(header: list[str], rows: list[list[str]], *, caption: str = "", text_columns=(), dim_rows=()) -> str:
    """An HTML table; ``header`` and cells are already-escaped HTML."""
    parts = ['<div class="rc-table-wrap"><table>']
    if caption:
        parts.append(f"<caption>{caption}</caption>")
    parts.append(
        "<thead><tr>"
        + "".join(f"<th{' class=rc-text' if k in text_columns else ''}>{h}</th>" for k, h in enumerate(header))
        + "</tr></thead><tbody>"
    )
    for r, row in enumerate(rows):
        parts.append(f"<tr{' class=rc-dim' if r in dim_rows else ''}>")
        parts.extend(f"<td{' class=rc-text' if k in text_columns else ''}>{c}</td>" for k, c in enumerate(row))
        parts.append("</tr>")
    parts.append("</tbody></table></div>")
    return "".join(parts)


def _csv_html(run: _Run, relative: str, *, title: str = "") -> str:
    """A CSV file as HTML table(s): units in the headers; a ``unit`` column splits it per unit."""
    table = run.csv(relative)
    if table is None:
        return ""
    header, rows = table
    numeric = [
        all(_number(row[k]) is not None for row in rows if row[k] != "") and any(row[k] != "" for row in rows)
        for k in range(len(header))
    ]
    source = f"<code>{_e(relative)}</code>"
    heading = f"<h4>{_e(title)}</h4>" if title else ""
    if "unit" in header and rows:
        unit_at = header.index("unit")
        units = list(dict.fromkeys(row[unit_at] for row in rows))
        keep = [k for k in range(len(header)) if k != unit_at]
        parts = [heading]
        for unit in units:
            group = [row for row in rows if row[unit_at] == unit]
            labels = [_e(f"{header[k]} ({unit})" if numeric[k] and unit else _label(header[k])) for k in keep]
            shown = group[:_TABLE_ROWS]
            parts.append(
                _table(
                    labels,
                    [[_cell(row[k]) for k in keep] for row in shown],
                    caption=f"{source}, rows in {_e(unit or 'no unit')}",
                    text_columns={i for i, k in enumerate(keep) if not numeric[k]},
                )
            )
            parts.append(_rows_note(len(shown), len(group)))
        return "".join(parts)
    shown = rows[:_TABLE_ROWS]
    return (
        heading
        + _table(
            [_e(_label(h)) for h in header],
            [[_cell(c) for c in row] for row in shown],
            caption=source,
            text_columns={k for k in range(len(header)) if not numeric[k]},
        )
        + _rows_note(len(shown), len(rows))
    )


def _rows_note(shown: int, total: int) -> str:
    if shown == total:
        return ""
    return f'<p class="rc-table-note">First {shown} of {total} rows; the file holds them all.</p>'


def _flatten(data, prefix: str = "", depth: int = 0):
    """``(dotted key, value)`` for the scalars (and short scalar lists) of nested dicts."""
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            if depth < 2:
                yield from _flatten(value, name + ".", depth + 1)
        elif isinstance(value, list):
            if 0 < len(value) <= 6 and all(isinstance(v, (int, float, str, bool)) or v is None for v in value):
                yield name, ", ".join(_fmt(v) if not isinstance(v, str) else v for v in value)
        elif isinstance(value, (int, float, str, bool)) or value is None:
            yield name, value


def _facts_html(data: dict | None, *, caption: str = "", skip=(), limit: int = 60) -> str:
    """Scalar entries of a JSON object as a two-column table (key with its unit, value)."""
    if not data:
        return ""
    items = [(k, v) for k, v in _flatten(data) if not any(k == s or k.startswith(s + ".") for s in skip)]
    if not items:
        return ""
    rows = [
        [_e(".".join(_label(part) for part in key.split("."))), _e(value if isinstance(value, str) else _fmt(value))]
        for key, value in items[:limit]
    ]
    note = "" if len(items) <= limit else _rows_note(limit, len(items))
    return _table(["entry", "value"], rows, caption=caption, text_columns={0, 1}) + note


def _caption(name: str, captions: dict) -> str:
    if name in captions:
        return captions[name]
    if name in _CAPTIONS:
        return _CAPTIONS[name]
    stem = name.rsplit(".", 1)[0]
    if stem.startswith("hist_"):
        return f"Monte Carlo histogram of {stem[5:]} (mm or deg, as the parameter)."
    return stem.replace("_", " ").capitalize() + "."


def _figures_html(run: _Run, folder: str, *, captions: dict | None = None, pattern: str = "*.png", first=()) -> str:
    """Every PNG of ``folder`` (matching ``pattern``) as an embedded figure with a caption."""
    captions = captions if isinstance(captions, dict) else {}
    names = run.files(folder, pattern)
    names.sort(
        key=lambda rel: (
            Path(rel).name not in first,
            first.index(Path(rel).name) if Path(rel).name in first else 0,
            rel,
        )
    )
    parts = []
    for relative in names:
        path = run.readable(relative)
        if path is None:
            continue
        try:
            data = path.read_bytes()
        except OSError as exc:
            parts.append(run.problem(relative, str(exc)))
            continue
        if not data.startswith(b"\x89PNG\r\n\x1a\n"):
            parts.append(run.problem(relative, "not a PNG file"))
            continue
        name = Path(relative).name
        caption = _caption(name, captions)
        uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
        run.figures += 1
        width, height = struct.unpack(">II", data[16:24]) if len(data) >= 24 else (0, 0)
        wide = ' class="rc-wide"' if width > 900 or (height and width / height > 1.9) else ""
        size = f' width="{width}" height="{height}"' if width and height else ""
        parts.append(
            f'<figure{wide}><img src="{uri}"{size} alt="{_e(caption)}" loading="eager">'
            f"<figcaption>{_e(caption)} <code>{_e(relative)}</code></figcaption></figure>"
        )
    return f'<div class="rc-figures">{"".join(parts)}</div>' if parts else ""


# --------------------------------------------------------------------------------------------------
# numbers taken from several files


def _pose_uncertainties(run: _Run, relative: str) -> list[tuple[str, float]]:
    """Per pose of a ``tcp.csv``: combined standard uncertainty of the position sqrt(uX²+uY²+uZ²) [mm]."""
    table = run.csv(relative)
    if table is None:
        return []
    header, rows = table
    if not {"name", "std_uncertainty"} <= set(header):
        return []
    name_at, u_at = header.index("name"), header.index("std_uncertainty")
    pose_at = header.index("pose") if "pose" in header else None
    sums: dict[str, list[float]] = {}
    for row in rows:
        if row[name_at].upper() in ("X", "Y", "Z"):
            u = _number(row[u_at])
            if u is not None:
                sums.setdefault(row[pose_at] if pose_at is not None else "1", []).append(u * u)
    return [(pose, math.sqrt(sum(values))) for pose, values in sums.items() if len(values) == 3]


def _evaluation_means(run: _Run):
    """(mean validation error with nominal parameters, with the calibrated ones [mm], label), or Nones.

    Tries headline keys of ``evaluation/evaluation.json`` first, then reads
    ``evaluation/evaluation.csv`` (columns ``parameter_set, view, capture, ..., mean_error_mm``):
    among the rows of the validation capture (if one is named so) and of the ``points`` view (if
    any), the row whose parameter set names ``nominal`` and the last other row (the final
    calibrated set, in the order the evaluation lists them), in the first column named ``mean...``.
    """
    data = run.json("evaluation/evaluation.json") or {}
    before = _number(
        _lookup(data, "headline.before_mean_mm", "nominal.mean_mm", "before.mean_mm", "mean_error_before_mm")
    )
    after = _number(_lookup(data, "headline.after_mean_mm", "refined.mean_mm", "after.mean_mm", "mean_error_after_mm"))
    label = _lookup(data, "headline.after_label", "after.label")
    table = run.csv("evaluation/evaluation.csv")
    if (before is None or after is None) and table is not None:
        header, rows = table
        mean_at = next((k for k, h in enumerate(header) if h.lower().startswith("mean")), None)
        for column, preferred in (("capture", "validation"), ("view", "points")):
            if column in header and rows:
                at = header.index(column)
                chosen = [row for row in rows if preferred in row[at].lower()]
                rows = chosen or [row for row in rows if row[at] == rows[0][at]]
        name_at = header.index("parameter_set") if "parameter_set" in header else 0
        nominal = next((row for row in rows if "nominal" in row[name_at].lower()), None)
        others = [row for row in rows if row is not nominal]
        if mean_at is not None and nominal is not None and others:
            before = before if before is not None else _number(nominal[mean_at])
            after = after if after is not None else _number(others[-1][mean_at])
            label = label or others[-1][name_at]
    return before, after, label


def _largest_uncertainties(run: _Run, relative: str = "uncertainty/parameters.csv") -> dict:
    """Largest standard uncertainty among the identified lengths and angles of a Monte Carlo's parameters.csv."""
    table = run.csv(relative)
    found = {}
    if table is None:
        return found
    header, rows = table
    if not {"name", "unit", "std_uncertainty"} <= set(header):
        return found
    index = {h: k for k, h in enumerate(header)}
    for row in rows:
        if "identified" in index and row[index["identified"]].lower() in ("false", "0", "no"):
            continue
        u = _number(row[index["std_uncertainty"]])
        unit = row[index["unit"]]
        if u is not None and (unit not in found or u > found[unit][1]):
            found[unit] = (row[index["name"]], u)
    return found


# --------------------------------------------------------------------------------------------------
# sections


def _ellipsoid_note(data) -> str:
    """``"; largest semi-axis of the 95 % ellipsoid ... µm"`` from a tcp.json, or ``""``."""
    poses = data.get("poses") if isinstance(data, dict) else None
    first = poses[0] if isinstance(poses, list) and poses and isinstance(poses[0], dict) else {}
    axes = _lookup(first, "ellipsoid.semi_axes_mm")
    coverage = _number(data.get("coverage")) if isinstance(data, dict) else None
    if not isinstance(axes, list) or not axes or any(_number(a) is None for a in axes):
        return ""
    share = f"{_fmt(coverage * 100, '.3g')} % " if coverage else ""
    return f"; largest semi-axis of the {share}ellipsoid {_length(max(_number(a) for a in axes))}"


#: Observed / expected validation RMS error up to which the consistency card says the stated uncertainty
#: explains the error: with 100 poses the RMS of the observed errors scatters by about 10 % about its
#: expectation when the model holds, so 1.5 is far outside chance and flags an unmodelled error.
CONSISTENT_RATIO = 1.5


def _model_note(data) -> str:
    """``"; refined model ..."``: the model whose draws a tcp.json was computed from, or ``""``."""
    model = _lookup(data, "provenance.model") if isinstance(data, dict) else None
    return f"; {_e(model)}" if isinstance(model, str) and model else ""


def _card(question: str, label: str, value: str, detail: str = "") -> str:
    na = " rc-na" if value == "n/a" else ""
    return (
        f'<div class="rc-card{na}"><div class="rc-q">{_e(question)}</div><div class="rc-label">{_e(label)}</div>'
        f'<div class="rc-value">{_e(value)}</div><div class="rc-detail">{detail}</div></div>'
    )


def _stage_status(run: _Run, stage: str):
    """(status text, seconds) of a stage from run.json, tolerant of a dict or a list of stages."""
    data = run.json("run.json") or {}
    stages = data.get("stages")
    entry = None
    if isinstance(stages, dict):
        entry = stages.get(stage)
    elif isinstance(stages, list):
        entry = next((s for s in stages if isinstance(s, dict) and s.get("name") == stage), None)
    status = seconds = None
    if isinstance(entry, dict):
        status = entry.get("status")
        seconds = _number(_lookup(entry, "seconds", "time_s", "elapsed_s", "wall_s"))
    elif isinstance(entry, str):
        status = entry
    if seconds is None:
        seconds = _number(_lookup(data, f"timings_s.{stage}", f"timings.{stage}"))
    return status, seconds


def _summary(run: _Run) -> tuple[str, bool]:
    data = run.json("run.json") or {}
    cpa = run.json("cpa/parameters.json") or {}
    provenance = cpa.get("provenance") if isinstance(cpa.get("provenance"), dict) else {}
    robot = _lookup(data, "robot", "scenario.robot") or cpa.get("robot")
    scenario_name = _lookup(data, "scenario.name", "scenario_name") or _lookup(provenance, "scenario.name")
    if isinstance(_lookup(data, "scenario"), str):
        scenario_name = data["scenario"]
    description = _lookup(data, "scenario.description", "description")
    instrument = _lookup(
        data, "scenario.instrument.name", "scenario.instrument.preset", "instrument.name", "instrument"
    )
    a_um = _number(_lookup(data, "scenario.instrument.a_um", "instrument.a_um"))
    b_um = _number(_lookup(data, "scenario.instrument.b_um_per_m", "instrument.b_um_per_m"))
    seed = _lookup(data, "seed", "scenario.seed")
    if seed is None:
        seed = provenance.get("capture_seed")

    facts = []
    if robot:
        facts.append(("robot", _e(robot if isinstance(robot, str) else json.dumps(robot))))
    if scenario_name:
        facts.append(("scenario", _e(scenario_name) + (f" — {_e(description)}" if description else "")))
    if instrument:
        text = _e(instrument if isinstance(instrument, str) else json.dumps(instrument))
        if a_um is not None and b_um is not None:
            text += f", U(L) = {_fmt(a_um)} µm + {_fmt(b_um)} µm/m · L"
        facts.append(("instrument", text))
    for relative, what in (("capture.csv", "calibration capture"), ("validation.csv", "validation points")):
        table = run.csv(relative)
        if table is not None:
            header, rows = table
            circles = {row[0] for row in rows} if header and header[0] == "circle" else set()
            detail = f"{len(rows)} points" + (
                f" in {len(circles)} circles" if circles and relative == "capture.csv" else ""
            )
            facts.append((what, f"{detail} (<code>{_e(relative)}</code>)"))
    if seed is not None:
        facts.append(("seed", _e(seed)))
    method = provenance.get("method")
    if method:
        facts.append(("identification", _e(method)))

    cards = []
    before, after, after_label = _evaluation_means(run)
    if before is not None or after is not None:
        value = f"{_length(before)} → {_length(after)}"
        detail = "mean position error at the validation points, nominal → " + _e(after_label or "calibrated")
    else:
        value, detail = "n/a", "evaluation stage not run" if not run.exists("evaluation") else "no mean error found"
    cards.append(_card("How good is it?", "validation error, before → after", value, detail))
    circles = provenance.get("circles") if isinstance(provenance.get("circles"), list) else []
    rms = [_number(c.get("circle_rms_mm")) for c in circles if isinstance(c, dict)]
    rms = [r for r in rms if r is not None]
    if rms:
        worst = int(np.argmax(rms))
        cards.append(
            _card(
                "How good is it?",
                "largest circle-fit RMS",
                f"{_fmt(rms[worst] * 1e3, '.2f')} µm",
                f"circle J{worst + 1}; {len(rms)} circles fitted by CPA",
            )
        )
    # the deployed model's uncertainty first (refined, uncertainty-refined/), CPA's beside it
    refined_largest = _largest_uncertainties(run, "uncertainty-refined/parameters.csv")
    cpa_largest = _largest_uncertainties(run)
    largest = refined_largest or cpa_largest
    model = "refined model (deployed)" if refined_largest else "CPA model"
    for unit, label in (
        ("mm", "largest standard uncertainty, lengths"),
        ("deg", "largest standard uncertainty, angles"),
    ):
        if unit in largest:
            name, u = largest[unit]
            shown = _length(u) if unit == "mm" else f"{_fmt(u, '.3g')}°"
            detail = f"{_e(name)}, {model}, Monte Carlo (GUM-S1)"
            if refined_largest and unit in cpa_largest:
                cpa_name, cpa_u = cpa_largest[unit]
                cpa_shown = _length(cpa_u) if unit == "mm" else f"{_fmt(cpa_u, '.3g')}°"
                detail += f"; CPA alone: {cpa_shown} ({_e(cpa_name)})"
            cards.append(_card("How sure are we?", label, shown, detail))
        else:
            cards.append(_card("How sure are we?", label, "n/a", "uncertainty stage not run"))
    pose = _pose_uncertainties(run, "tcp/pose/tcp.csv")
    if pose:
        name, u = pose[0]
        cards.append(
            _card(
                "How sure are we?",
                "TCP position uncertainty at the pose",
                _length(u),
                f"√(u_X² + u_Y² + u_Z²), pose {_e(name)}"
                + _model_note(run.json("tcp/pose/tcp.json"))
                + (f" (of {len(pose)})" if len(pose) > 1 else "")
                + _ellipsoid_note(run.json("tcp/pose/tcp.json")),
            )
        )
    else:
        cards.append(_card("How sure are we?", "TCP position uncertainty at the pose", "n/a", "tcp pose not run"))
    workspace = _pose_uncertainties(run, "tcp/workspace/tcp.csv")
    if workspace:
        values = np.array([u for _, u in workspace])
        p50, p95 = np.percentile(values, [50, 95])
        cards.append(
            _card(
                "Where can I trust it?",
                "TCP position uncertainty over the workspace",
                f"{_length(p50)} / {_length(p95)}",
                f"median / 95th percentile of {len(values)} poses; worst {_length(values.max())}"
                + _model_note(run.json("tcp/workspace/tcp.json")),
            )
        )
    else:
        cards.append(
            _card("Where can I trust it?", "TCP uncertainty over the workspace", "n/a", "workspace map not run")
        )
    trajectory = _pose_uncertainties(run, "tcp/trajectory/tcp.csv")
    if trajectory:
        values = np.array([u for _, u in trajectory])
        cards.append(
            _card(
                "Where can I trust it?",
                "TCP uncertainty along the trajectory",
                f"≤ {_length(values.max())}",
                f"largest of {len(values)} poses; smallest {_length(values.min())}"
                + _model_note(run.json("tcp/trajectory/tcp.json")),
            )
        )
    check = run.json("tcp/consistency.json")
    expected, observed = (_number(_lookup(check or {}, key)) for key in ("expected_rms_mm", "observed_rms_mm"))
    if expected is not None and observed is not None:
        predicted = _number(_lookup(check, "predicted_rms_mm"))
        instrument = _number(_lookup(check, "instrument_rms_mm"))
        ratio = _number(_lookup(check, "ratio"))
        if ratio is None:
            ratio = observed / expected if expected > 0 else float("inf")
        verdict = (
            "the stated uncertainty explains the error"
            if ratio <= CONSISTENT_RATIO
            else "the error exceeds what the parameter uncertainty and the instrument explain: the rest is what "
            "the kinematic model does not hold (joint errors such as backlash and eccentricity, see Joints)"
        )
        cards.append(
            _card(
                "Does the uncertainty explain the error?",
                "validation RMS error, expected → observed",
                f"{_length(expected)} → {_length(observed)}",
                f"expected = √(predicted² + instrument²) = √({_length(predicted)}² + {_length(instrument)}²) at "
                f"{_e(_lookup(check, 'poses'))} validation poses ({_e(_lookup(check, 'model'))}"
                + (
                    ", base frame registered: the registration absorbs part of the error"
                    if _lookup(check, "base_frame") == "registered"
                    else ""
                )
                + f"); {verdict}",
            )
        )

    stage_rows = []
    for stage, where in _STAGES:
        present = run.exists(where)
        status, seconds = _stage_status(run, stage)
        shown = status or ("done" if present else "not run")
        css = (
            "rc-status-failed"
            if str(shown).lower() in ("failed", "error")
            else ("rc-status-ok" if present else "rc-status-missing")
        )
        stage_rows.append(
            [
                _e(stage),
                f"<code>{_e(where)}</code>",
                f'<span class="{css}">{_e(shown)}</span>',
                _e(_fmt(seconds, ".2f")),
            ]
        )
    body = (
        ('<dl class="rc-facts">' + "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in facts) + "</dl>" if facts else "")
        + f'<div class="rc-cards">{"".join(cards)}</div>'
        + _table(
            ["stage", "results", "status", "time (s)"], stage_rows, caption="Stages of this run", text_columns={0, 1, 2}
        )
    )
    return body, True


def _parameter_values(data: dict | None) -> tuple[dict, set, set]:
    """``name -> value`` [mm, deg], identified names and structurally fixed names of a parameter JSON."""
    values, fixed = {}, set()
    if not data or not isinstance(data.get("joints"), list):
        return values, set(), fixed
    for i, joint in enumerate(data["joints"]):
        if not isinstance(joint, dict):
            continue
        for kind in PARAMETER_KINDS:
            number = _number(joint.get(kind))
            if number is not None:
                values[f"J{i + 1}.{kind}"] = number
        if "hayati" in joint:
            fixed.add(f"J{i + 1}.d" if joint["hayati"] else f"J{i + 1}.beta")
    identified = data.get("identified")
    return values, set(identified) if isinstance(identified, list) else set(), fixed


def _nominal_values(run: _Run, robot_name) -> dict:
    """Nominal values [mm, deg] from uncertainty/parameters.csv, else from the built-in robot file."""
    table = run.csv("uncertainty/parameters.csv")
    if table is not None and {"name", "nominal"} <= set(table[0]):
        header, rows = table
        at_name, at_nominal = header.index("name"), header.index("nominal")
        values = {row[at_name]: _number(row[at_nominal]) for row in rows}
        return {k: v for k, v in values.items() if v is not None}
    if not isinstance(robot_name, str):
        return {}
    try:
        from robotcal.io.robots import load_robot

        robot = load_robot(robot_name)
    except RobotcalError:
        return {}
    return {
        name: (math.degrees(value) if name.split(".")[1] not in LENGTH_KINDS else float(value))
        for name, value in zip(robot.parameter_names, robot.nominal.reshape(-1), strict=True)
    }


def _parameters(run: _Run) -> tuple[str, bool]:
    cpa = run.json("cpa/parameters.json")
    truth = run.json("truth.json")
    refined = {label: run.json(f"refine/{label}.json") for label in ("points", "distances")}
    mc = run.csv("uncertainty/parameters.csv")
    if cpa is None and mc is None and not any(refined.values()):
        return _not_run("cpa/parameters.json") + _note("No identified parameters to show."), False
    cpa_values, identified, fixed = _parameter_values(cpa)
    robot_name = (cpa or {}).get("robot") or (truth or {}).get("robot")
    columns: list[tuple[str, dict]] = [("nominal", _nominal_values(run, robot_name))]
    truth_values = _parameter_values(truth)[0]
    if truth_values:
        columns.append(("truth", truth_values))
    if cpa_values:
        columns.append(("CPA", cpa_values))
        if truth_values:
            columns.append(
                ("CPA − truth", {k: v - truth_values[k] for k, v in cpa_values.items() if k in truth_values})
            )
    for label, data in refined.items():
        values, more, more_fixed = _parameter_values(data)
        if values:
            columns.append((f"refined ({label})", values))
            identified |= more
            fixed |= more_fixed
    mc_data = run.json("uncertainty/parameters.json") or {}
    coverage = _number(_lookup(mc_data, "coverage", "coverage_probability", "scenario.montecarlo.coverage"))
    if mc is not None:
        header, rows = mc
        index = {h: k for k, h in enumerate(header)}
        interval = f"{_fmt(coverage * 100, '.3g')} % interval" if coverage else "interval"
        for column, label in (
            ("mean", "MC mean"),
            ("std_uncertainty", "u"),
            ("coverage_low", f"{interval} low"),
            ("coverage_high", f"{interval} high"),
        ):
            if column in index and "name" in index:
                values = {row[index["name"]]: _number(row[index[column]]) for row in rows}
                columns.append((label, {k: v for k, v in values.items() if v is not None}))
        if "identified" in index and "name" in index and not identified:
            identified = {
                row[index["name"]] for row in rows if row[index["identified"]].lower() in ("true", "1", "yes")
            }
    names = []
    for _, values in columns:
        names.extend(n for n in values if n not in names)
    names.sort(
        key=lambda n: (int(n.split(".")[0][1:]), PARAMETER_KINDS.index(n.split(".")[1])) if _is_param(n) else (10**6, 0)
    )
    names = [n for n in names if n not in fixed]
    parts = []
    for unit, kinds in (("mm", LENGTH_KINDS), ("deg", ("theta", "alpha", "beta"))):
        group = [n for n in names if _is_param(n) and n.split(".")[1] in kinds]
        if not group:
            continue
        rows_html, dim = [], set()
        for r, name in enumerate(group):
            row = [_e(name)]
            for label, values in columns:
                value = values.get(name)
                spec = ".3g" if label == "u" else (".3e" if "−" in label else ".4f")
                row.append(_e(_fmt(value, spec, exponent=spec != ".4f")) if value is not None else "")
            if identified and name not in identified:
                dim.add(r)
                row[0] += " <small>(not identified)</small>"
            rows_html.append(row)
        title = "Lengths" if unit == "mm" else "Angles"
        parts.append(f"<h3>{title} ({unit})</h3>")
        parts.append(
            _table(
                ["parameter"] + [_e(f"{label} ({unit})") for label, _ in columns],
                rows_html,
                caption=f"every value in {unit}; grey rows are not identified by CPA and stay nominal",
                text_columns={0},
                dim_rows=dim,
            )
        )
    provenance = (cpa or {}).get("provenance")
    if isinstance(provenance, dict):
        circles = provenance.get("circles")
        if isinstance(circles, list) and circles:
            rows_html = [
                [
                    _e(c.get("circle", "")),
                    _e(c.get("points", "")),
                    _e(_fmt(_number(c.get("radius_mm")), ".4f")),
                    _e(
                        _fmt(
                            _number(c.get("plane_rms_mm")) * 1e3
                            if _number(c.get("plane_rms_mm")) is not None
                            else None,
                            ".3g",
                        )
                    ),
                    _e(
                        _fmt(
                            _number(c.get("circle_rms_mm")) * 1e3
                            if _number(c.get("circle_rms_mm")) is not None
                            else None,
                            ".3g",
                        )
                    ),
                ]
                for c in circles
                if isinstance(c, dict)
            ]
            parts.append("<h3>CPA circle fits</h3>")
            parts.append(
                _table(
                    ["circle", "points", "radius (mm)", "plane RMS (µm)", "circle RMS (µm)"],
                    rows_html,
                    caption="<code>cpa/parameters.json</code> provenance",
                )
            )
        pairs = provenance.get("line_pairs")
        if isinstance(pairs, list) and pairs:
            parts.append("<p>Adjacent joint axes: " + "; ".join(_e(p) for p in pairs) + ".</p>")
        parts.append(
            _facts_html(
                provenance,
                caption="CPA provenance (<code>cpa/parameters.json</code>)",
                skip=("circles", "line_pairs", "versions", "tracker_from_base"),
            )
        )
    for label, data in refined.items():
        if data and isinstance(data.get("provenance"), dict):
            parts.append(f"<h3>Refinement ({_e(label)})</h3>")
            parts.append(
                _facts_html(
                    data["provenance"], caption=f"<code>refine/{label}.json</code> provenance", skip=("versions",)
                )
            )
    return "".join(parts), True


def _is_param(name: str) -> bool:
    return bool(re.fullmatch(r"J\d+\.(d|theta|a|alpha|beta)", name))


def _stage_generic(run: _Run, folder: str, *, first_csv=(), first_png=(), csv_titles=None) -> str:
    """Every CSV (as tables), JSON (scalar entries) and PNG (figures) of a stage folder."""
    parts = []
    csv_titles = csv_titles or {}
    json_files = run.files(folder, "*.json")
    captions = {}
    for relative in json_files:
        data = run.json(relative)
        if isinstance(data, dict) and isinstance(data.get("figures"), dict):
            captions.update({str(k): str(v) for k, v in data["figures"].items()})
    csv_files = run.files(folder, "*.csv")
    csv_files.sort(key=lambda rel: (Path(rel).name not in first_csv, rel))
    for relative in csv_files:
        parts.append(_csv_html(run, relative, title=csv_titles.get(Path(relative).name, "")))
    parts.append(_figures_html(run, folder, captions=captions, first=tuple(first_png)))
    for relative in json_files:
        parts.append(
            _facts_html(run.json(relative), caption=f"<code>{_e(relative)}</code>", skip=("figures", "versions"))
        )
    return "".join(parts)


def _evaluation(run: _Run) -> tuple[str, bool]:
    if not run.exists("evaluation"):
        return _not_run("evaluation/"), False
    note = _note(
        "The points criterion (eq. 4-101) fits the measured positions themselves (with the base frame given or "
        "estimated) and is the deployed result. The distances criterion (eq. 4-102) is registration-free: it uses "
        "only the distances between points and so no absolute position; from the same capture it can determine "
        "the parameters markedly less precisely (compare the standard uncertainties in refine/*.json) and end "
        "worse than CPA on the validation poses. Use it when the base frame cannot be known."
    )
    return note + _stage_generic(run, "evaluation", first_csv=("evaluation.csv",), first_png=("convergence.png",)), True


def _joints(run: _Run) -> tuple[str, bool]:
    if not run.exists("joints"):
        return _not_run("joints/"), False
    return _stage_generic(run, "joints", first_csv=("summary.csv",)), True


def _montecarlo(run: _Run) -> tuple[str, bool]:
    if not run.exists("uncertainty") and not run.exists("uncertainty-refined"):
        return _not_run("uncertainty/"), False
    parts = [
        _note(
            "Two Monte Carlos of the same capture. The refined model is the one a user deploys: every draw runs "
            "CPA and then the points-criterion refinement, simulated around the refined estimate; the TCP "
            "figures use its draws. The CPA model is the thesis's (ch. 5.2.3): every draw runs CPA alone, "
            "simulated around the CPA estimate. Both use the same seed, so they see the same instrument noise."
        )
    ]
    for folder, title in (
        ("uncertainty-refined", "Refined model (deployed)"),
        ("uncertainty", "CPA model (thesis ch. 5.2.3)"),
    ):
        parts.append(f"<h3>{_e(title)}: <code>{_e(folder)}/</code></h3>")
        if not run.exists(folder):
            parts.append(_not_run(folder + "/"))
            continue
        data = run.json(f"{folder}/parameters.json")
        parts += [
            _facts_html(
                data, caption=f"<code>{folder}/parameters.json</code>", skip=("figures", "versions", "scenario")
            ),
            _figures_html(run, folder, pattern="hist_*.png"),
            _figures_html(run, folder, pattern="[!h]*.png"),
            _csv_html(run, f"{folder}/parameters.csv", title="Parameter statistics of the Monte Carlo draws"),
        ]
        others = [r for r in run.files(folder, "*.csv") if r != f"{folder}/parameters.csv"]
        parts.extend(_csv_html(run, r) for r in others)
    return "".join(parts), True


def _tcp(run: _Run) -> tuple[str, bool]:
    parts, present = [], False
    for sub, title in (("pose", "At the pose"), ("trajectory", "Along the trajectory")):
        folder = f"tcp/{sub}"
        parts.append(f"<h3>{title}</h3>")
        if run.exists(folder):
            present = True
            parts.append(_stage_generic(run, folder, first_csv=("tcp.csv",)))
        else:
            parts.append(_not_run(folder + "/"))
    return "".join(parts), present


def _workspace(run: _Run) -> tuple[str, bool]:
    if not run.exists("tcp/workspace"):
        return _not_run("tcp/workspace/"), False
    return _stage_generic(run, "tcp/workspace", first_csv=("tcp.csv",)), True


def _planning(run: _Run) -> tuple[str, bool]:
    if not run.exists("plan"):
        return _not_run("plan/"), False
    parts = [
        "<h3>The capture plan in the cell (thesis 4.5.2)</h3>",
        _note(
            "Every capture point checked against the joint limits of the robot file, the instrument's range, "
            "the reflector's acceptance angle and the line of sight from the tracker, past the robot's links "
            "modelled as capsules (docs/planning.md). A synthetic plan may fail these checks and still be a "
            "valid study; a plan for a real cell must pass them."
        ),
        _stage_generic(run, "plan", first_csv=("plan_check.csv",), first_png=("plan_check.png",)),
        "<h3>Sensitivity to the angle joint 4 covers (thesis 5.2.4, Fig. 5.15)</h3>",
        _note(
            "One CPA Monte Carlo per J4 sweep, all with the same seed; Cpk is eq. 5-5 with the limits in "
            "<code>plan/sensitivity/</code>'s JSON. The thesis plan turns J4's 20 mm target through 50 deg."
        ),
    ]
    if run.exists("plan/sensitivity"):
        parts.append(_stage_generic(run, "plan/sensitivity"))
    else:
        parts.append(_not_run("plan/sensitivity/"))
    return "".join(parts), True


def _view3d(run: _Run) -> tuple[str, bool]:
    if not run.exists("capture.csv"):
        return _not_run("capture.csv"), False
    from robotcal.io.capture_csv import read_capture

    try:
        capture = read_capture(run.path("capture.csv"))
    except RobotcalError as exc:
        return run.problem("capture.csv", str(exc)), False
    provenance = (run.json("cpa/parameters.json") or {}).get("provenance") or {}
    pose = provenance.get("tracker_from_base") if isinstance(provenance, dict) else None
    try:
        pose = np.asarray(pose, dtype=float) if pose is not None else None
        if pose is not None and pose.shape != (4, 4):
            pose = None
    except (TypeError, ValueError):
        pose = None
    circle_fit = _lookup(provenance, "options.circle_fit") if isinstance(provenance, dict) else None
    scene = viewer_scene(
        capture,
        tracker_from_base=pose,
        circle_fit=circle_fit if circle_fit in ("geometric", "algebraic") else "geometric",
    )
    notes = "".join(f'<p class="rc-problem">{_e(n)}</p>' for n in scene["notes"])
    intro = (
        "<p>The measured points of every circle (tracker frame, mm), the circle fitted to each "
        "(plane, then circle in the plane, as CPA fits it) and the joint axis taken from it: the line "
        "through the circle centre along the plane normal"
        + (", with the robot base frame <code>tracker_from_base</code> of the CPA result." if pose is not None else ".")
        + "</p>"
    )
    return intro + notes + render_viewer(scene), True


def _provenance(run: _Run) -> tuple[str, bool]:
    data = run.json("run.json")
    parts = []
    if data is not None:
        parts.append(_facts_html(data, caption="<code>run.json</code>", skip=("versions",), limit=80))
    else:
        parts.append(_note("No <code>run.json</code>: this folder was not written by <code>robotcal run</code>."))
    versions = {}
    for relative in ("cpa/parameters.json", "uncertainty/parameters.json", "run.json"):
        found = _lookup(run.json(relative) or {}, "versions", "provenance.versions")
        if isinstance(found, dict):
            versions.update({str(k): str(v) for k, v in found.items()})
    versions.setdefault("robotcal (this report)", robotcal.__version__)
    parts.append(
        _table(
            ["software", "version"],
            [[_e(k), _e(v)] for k, v in versions.items()],
            caption="Versions",
            text_columns={0, 1},
        )
    )
    rows = []
    for path in sorted(p for p in run.root.rglob("*") if p.is_file() or p.is_symlink()):
        relative = path.relative_to(run.root)
        if relative.name == REPORT_NAME or any(part.startswith(".") for part in relative.parts):
            continue
        if run._linked(relative) is not None:
            rows.append([f"<code>{_e(relative)}</code>", "", _e(run._linked(relative))])
            continue
        try:
            digest = hashlib.sha256(path.read_bytes()).hexdigest()
        except OSError:
            continue
        rows.append(
            [f"<code>{_e(relative)}</code>", _e(f"{path.stat().st_size / 1024:.1f}"), f"<code>{digest[:16]}</code>"]
        )
    parts.append(
        _table(
            ["file", "size (KiB)", "SHA-256 (first 16 hex digits)"],
            rows[:300],
            caption="Files this report was built from",
            text_columns={0, 2},
        )
    )
    generated = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    parts.append(
        f"<p>Report generated {generated} by robotcal {_e(robotcal.__version__)} from <code>{_e(run.root)}</code>, "
        "from the saved files only (no recomputation except the circle fits of the 3-D view).</p>"
    )
    return "".join(parts), True


_SECTIONS = (
    ("summary", "Summary", _summary),
    ("parameters", "Parameters", _parameters),
    ("evaluation", "Evaluation and convergence", _evaluation),
    ("joints", "Joint diagnostics", _joints),
    ("montecarlo", "Monte Carlo uncertainty", _montecarlo),
    ("tcp", "TCP uncertainty", _tcp),
    ("workspace", "Workspace map", _workspace),
    ("planning", "Capture planning", _planning),
    ("view3d", "3-D view of the capture", _view3d),
    ("provenance", "Provenance", _provenance),
)

_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"


def _check_run_dir(run_dir) -> Path:
    root = Path(run_dir)
    if not root.exists():
        raise InputError(f"{root}: run folder not found")
    if not root.is_dir():
        raise InputError(f"{root}: not a folder (expected a run folder written by `robotcal run`)")
    if not any((root / entry).exists() for entry in _RUN_ENTRIES):
        raise InputError(
            f"{root}: no results found (expected at least one of {', '.join(_RUN_ENTRIES)}; see docs/results.md)"
        )
    return root


def render_report(run_dir) -> Report:
    """Render the report of ``run_dir`` as one HTML string, without writing anything.

    Parameters
    ----------
    run_dir : path
        A run folder (docs/results.md). Every stage is optional.

    Returns
    -------
    Report

    Raises
    ------
    InputError
        ``run_dir`` is missing, not a folder, or holds none of the result files.
    """
    run = _Run(root=_check_run_dir(run_dir))
    sections, bodies = [], []
    for anchor, title, render in _SECTIONS:
        body, present = render(run)
        sections.append(ReportSection(id=anchor, title=title, present=present))
        bodies.append(f'<section id="{anchor}"><h2>{_e(title)}</h2>{body}</section>')
    toc = "".join(
        f'<li{"" if s.present else " class=rc-missing"}><a href="#{s.id}">{_e(s.title)}</a></li>' for s in sections
    )
    cpa = run.json("cpa/parameters.json") or {}
    data = run.json("run.json") or {}
    robot = cpa.get("robot") or _lookup(data, "robot", "scenario.robot") or "robot"
    scenario = _lookup(data, "scenario.name") or _lookup(cpa, "provenance.scenario.name")
    if isinstance(data.get("scenario"), str):
        scenario = data["scenario"]
    title = f"Calibration report: {robot}"
    subtitle = f"scenario {scenario} · " if scenario else ""
    problems = "".join(f"<li>{_e(p)}</li>" for p in run.problems)
    problems_html = (
        f'<div class="rc-problem"><strong>Some result files could not be read:</strong><ul>{problems}</ul></div>'
        if problems
        else ""
    )
    canvases = sum(body.count("<canvas") for body in bodies)
    page = "".join(
        [
            '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">',
            f'<meta http-equiv="Content-Security-Policy" content="{_CSP}">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f'<meta name="generator" content="robotcal {_e(robotcal.__version__)}">',
            f"<title>{_e(title)}</title>",
            f"<style>{asset_text('report.css')}</style>",
            f"<script>{asset_text('errors.js')}</script>",
            '</head><body data-status="loading"><div class="rc-layout">',
            f'<nav class="rc-toc" aria-label="Contents"><div class="rc-brand">robotcal report</div><ol>{toc}</ol></nav>',
            f'<main><header class="rc-title"><h1>{_e(title)}</h1>',
            f"<p>{_e(subtitle)}run folder <code>{_e(run.root.resolve().name)}</code> · lengths in mm, angles in degrees</p></header>",
            '<pre id="rc-errors" hidden></pre>',
            problems_html,
            "".join(bodies),
            "</main></div>",
            f"<script>{asset_text('viewer3d.js')}</script>" if canvases else "",
            f"<script>{asset_text('check.js')}</script>",
            "</body></html>\n",
        ]
    )
    return Report(
        html=page,
        sections=tuple(sections),
        figures=run.figures,
        canvases=canvases,
        problems=tuple(run.problems),
    )


def build_report(run_dir, out=None) -> Report:
    """Render the report of ``run_dir`` and write it atomically to ``out`` (default ``run_dir/report.html``).

    Returns the :class:`Report` with ``path`` set. See :func:`render_report`.
    """
    report = render_report(run_dir)
    path = Path(out) if out is not None else Path(run_dir) / REPORT_NAME
    atomic_write_text(path, report.html)
    return Report(
        html=report.html,
        path=path,
        sections=report.sections,
        figures=report.figures,
        canvases=report.canvases,
        problems=report.problems,
    )
