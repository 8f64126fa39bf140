"""The self-contained HTML calibration report of a run (docs/results.md, docs/report.md).

The report renders from the run object, never from the run folder: :func:`render_report` takes a
:class:`~robotcal.pipeline.result.RunResult` (``record``: ``run.json``; ``documents``: every output by
its path in the run folder, JSON objects as dicts, CSV files as :class:`~robotcal.pipeline.result.Table`,
figures as Paths) and reads no file but the PNG bytes of the figures it embeds. :func:`build_report` is
:func:`robotcal.pipeline.folder.read_run` (the one reader of a run folder) + :func:`render_report` + an
atomic write, for ``robotcal report DIR``.

How a page is built: one *builder* per section (``_summary``, ``_parameters``, ...) turns the run into
the section's template context (plain strings, numbers and lists: tables as :class:`_Table`, figures as
dicts); one Jinja2 template per section (``templates/<section>.html.j2``, autoescaped) lays it out, with
the shared macros of ``templates/macros.html.j2``; ``templates/page.html.j2`` holds the page, the CSS
and scripts of ``assets/`` inlined. Nothing is recomputed from the documents except the circle fits of the
3-D view; the headline figures come from :attr:`RunResult.summary <robotcal.pipeline.result.RunResult>`
(or :func:`robotcal.pipeline.summary.summarise` when the run has none).

The page needs no network: CSS and scripts are inline, figures are PNG ``data:`` URIs, and a
Content-Security-Policy forbids any other source. Its last script checks that every figure decoded and
every canvas drew, then sets ``<body data-status="ok">`` (or ``"error"``, with the messages in
``#rc-errors``); the browser test reads that.
"""

from __future__ import annotations

import base64
import datetime as _dt
import math
import re
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path, PurePosixPath

import numpy as np

import robotcal
from robotcal.io.atomic import atomic_write_text
from robotcal.kinematics.model import ANGLE_KINDS, DISPLAY_UNITS, KIND_UNITS, LENGTH_KINDS, PARAMETER_KINDS
from robotcal.pipeline.plan import OUTPUTS
from robotcal.pipeline.result import RunResult, Table
from robotcal.pipeline.summary import Summary, set_label, summarise
from robotcal.report import template_environment
from robotcal.report.viewer3d import asset_text, render_viewer, viewer_scene

__all__ = ["REPORT_NAME", "Report", "ReportSection", "render_report", "build_report"]

REPORT_NAME = "report.html"

#: Captions of the figures the stages write, each naming the unit its figure is drawn in (the plot
#: functions of plots/joints.py, montecarlo.py, tcp.py, refine.py, planning.py); a stage's JSON may
#: give others in a ``"figures": {file: caption}`` object.
_CAPTIONS = {
    "iso9283.png": "ISO 9283 pose accuracy AP (bars) and repeatability RP (tick above each bar) at the five test "
    "poses, per model (µm).",
    "convergence.png": "Convergence of the refinement, per criterion: RMS residual per coordinate "
    "√(2·cost/m) over the m residuals (mm, log scale) after each iteration.",
    "ellipsoid.png": "95 % coverage ellipsoid of the TCP position (mm).",
    "scatter.png": "Monte Carlo draws of the TCP position about their mean, with the coverage ellipsoid (mm).",
    "histograms.png": "Monte Carlo histograms of the TCP coordinates X, Y, Z (mm) and A, B, C (deg), with the "
    "nominal and the mean.",
    "trajectory.png": "Along the trajectory: the nominal TCP path coloured by the range of X, Y, Z over the draws, "
    "the range (max − min) per coordinate, and the standard uncertainty of the position (mm) and of the "
    "orientation A, B, C (deg) per pose.",
    "workspace.png": "Over the workspace: the position standard uncertainty √(trace V) of the TCP per pose (mm), "
    "top view, side view and histogram.",
    "backlash_vectors.png": "Backlash vectors (return − forward sweep at the same reading) drawn magnified on each "
    "circle; circle coordinates in the circle's plane (mm).",
    "backlash_xyz.png": "Backlash components x, y, z (return − forward) per joint against the joint reading (µm); "
    "dashed: ±1 standard deviation of a difference of two noisy points (instrument noise alone).",
    "backlash_magnitude.png": "Backlash magnitude |return − forward| per joint against the joint reading (µm); "
    "dash-dot: the mean; dashed: the noise floor, the mean magnitude instrument noise alone gives (no backlash "
    "in the joint); each panel's title says whether the joint's mean lies above it.",
    "eccentricity_axial.png": "Axial eccentricity: signed distance of each point to its circle's plane, against the "
    "joint reading (µm), with the harmonic fit; dashed: instrument noise ±2σ.",
    "eccentricity_radial.png": "Radial eccentricity: in-plane distance of each point to its circle minus the "
    "radius, against the joint reading (µm), with the harmonic fit; dashed: instrument noise ±2σ.",
    "plan_check.png": "Cell check per capture point against the joint reading (deg): sight-line clearance (mm) "
    "and incidence on the reflector (deg); red points are infeasible.",
}

#: What the noise floor of the backlash is, for the joints table and the backlash figure's caption.
_NOISE_FLOOR = (
    "noise floor: the mean backlash magnitude the instrument noise alone gives at this circle (no backlash in "
    "the joint); a mean / floor ratio near 1 is noise, not backlash the capture can resolve"
)

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

#: Columns that hold identifiers or counts: they never take the unit of a unit-split table.
_COUNT_COLUMNS = frozenset(
    ("pose", "joint", "circle", "case", "points", "pairs", "n_errors", "draws", "direction", "point", "state")
)
#: Friendly headers of the columns of the statistics CSV files (unit added after).
_COLUMN_LABELS = {
    "std_uncertainty": "u",
    "coverage_low": "interval low",
    "coverage_high": "interval high",
    "lpu_std_uncertainty": "u linearised (GUM)",
    "parameter_set": "parameter set",
}

_TABLE_ROWS = 40  # longer CSV files show their first rows and say so
_TABLE_COLUMNS = 8  # wider CSV files are split into several tables, repeating their key columns
_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"


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
        Documents that could not be read (``RunResult.problems``) or used (a figure that is not a PNG);
        each is also shown in the page.
    """

    html: str
    path: Path | None = None
    sections: tuple[ReportSection, ...] = ()
    figures: int = 0
    canvases: int = 0
    problems: tuple[str, ...] = ()


# --------------------------------------------------------------------------------------------------
# formatting


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


def _angle(deg) -> str:
    return "n/a" if deg is None else f"{_fmt(deg, '.3g')}°"


def _cell(text: str) -> str:
    number = _number(text)
    if number is None or re.fullmatch(r"[+-]?\d+", text.strip() or "x"):
        return text
    return _fmt(number)


def _unit_of(name: str) -> str | None:
    """The unit a key's suffix names (``plane_rms_mm`` -> ``mm``), else None."""
    for suffix, unit in _UNIT_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            return unit
    return None


def _bare(name: str) -> str:
    """``"plane_rms_mm"`` -> ``"plane rms"``: the key without its unit suffix, for a table with a unit column."""
    unit = _unit_of(name)
    suffix = next(suffix for suffix, u in _UNIT_SUFFIXES if u == unit and name.endswith(suffix)) if unit else ""
    return name[: len(name) - len(suffix)].replace("_", " ")


def _label(name: str) -> str:
    """``"plane_rms_mm"`` -> ``"plane rms (mm)"``: units named by the key suffix go in brackets."""
    for suffix, unit in _UNIT_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            return f"{name[: -len(suffix)].replace('_', ' ')} ({unit})"
    return name.replace("_", " ")


def _is_param(name: str) -> bool:
    return bool(re.fullmatch(r"J\d+\.(d|theta|a|alpha|beta)", name))


def _param_unit(name: str) -> str:
    return KIND_UNITS[name.split(".")[1]]


def _param_order(name: str):
    if _is_param(name):
        joint, kind = name.split(".")
        return (int(joint[1:]), PARAMETER_KINDS.index(kind))
    return (10**6, 0)


# --------------------------------------------------------------------------------------------------
# template data


@dataclass(slots=True, kw_only=True)
class _Table:
    """A table for ``macros.table``: plain text cells (the template escapes them)."""

    header: list[str]
    rows: list[list[str]]
    caption: str = ""
    source: str = ""  # a document name, shown as code after the caption
    text_columns: frozenset = frozenset()
    code_columns: frozenset = frozenset()
    dim_rows: frozenset = frozenset()
    tags: dict = field(default_factory=dict)  # row -> small text after the first cell
    note: str = ""  # below the table

    @property
    def kind(self) -> str:
        return "table"


def _block(kind: str, **data) -> dict:
    """A non-table item of a section body for ``macros.blocks``: heading, note, problem, not_run, figures."""
    return {"kind": kind, **data}


def _rows_note(shown: int, total: int) -> str:
    return "" if shown == total else f"First {shown} of {total} rows; the file holds them all."


# --------------------------------------------------------------------------------------------------
# the run as the builders see it


class _Page:
    """The run being rendered: its documents, and what rendering found wrong (figures that are not PNGs)."""

    def __init__(self, result: RunResult):
        self.result = result
        self.record = result.record if isinstance(result.record, dict) else {}
        self.problems: list[str] = list(result.problems)
        self.figures = 0
        self.summary: Summary = (
            result.summary if isinstance(result.summary, Summary) else summarise(self.record, result.documents)
        )

    def json(self, name: str) -> dict | None:
        return self.result.json(name)

    def table(self, name: str) -> Table | None:
        return self.result.table(name)

    def has(self, name: str) -> bool:
        """The run has the document ``name``, or any document under the folder ``name``."""
        return name in self.result.documents or bool(self.result.names(name))

    def children(self, folder: str, suffix: str) -> list[str]:
        """Documents directly in ``folder`` (not in its sub-folders) ending with ``suffix``."""
        depth = folder.count("/") + 1
        return [n for n in self.result.names(folder, suffix) if n.count("/") == depth]

    def problem(self, name: str, what: str) -> dict:
        self.problems.append(f"{name}: {what}")
        return _block("problem", name=name, what=what)

    def figure(self, name: str, caption: str) -> dict | None:
        """A figure document as an embedded PNG (the one file the report reads), or a problem block."""
        path = self.result.file(name)
        if path is None:
            return None
        try:
            data = Path(path).read_bytes()
        except OSError as exc:
            return self.problem(name, f"could not read the figure ({exc.strerror or exc})")
        if not data.startswith(b"\x89PNG\r\n\x1a\n"):
            return self.problem(name, "not a PNG file")
        self.figures += 1
        width, height = struct.unpack(">II", data[16:24]) if len(data) >= 24 else (0, 0)
        return {
            "uri": "data:image/png;base64," + base64.b64encode(data).decode("ascii"),
            "width": width,
            "height": height,
            "wide": width > 900 or bool(height and width / height > 1.9),
            "caption": caption,
            "source": name,
        }


def _captions(page: _Page, folder: str) -> dict:
    """``{file name: caption}`` of the ``"figures"`` objects of a stage folder's JSON documents."""
    captions = {}
    for name in page.children(folder, ".json"):
        figures = (page.json(name) or {}).get("figures")
        if isinstance(figures, dict):
            captions.update({str(k): str(v) for k, v in figures.items()})
    return captions


def _caption(name: str, captions: Mapping) -> str:
    if name in captions:
        return captions[name]
    if name in _CAPTIONS:
        return _CAPTIONS[name]
    stem = name.rsplit(".", 1)[0]
    if re.fullmatch(r"hist_J\d+", stem):
        return (
            f"Monte Carlo histograms of the identified parameters of {stem[5:]} (lengths in mm, angles in deg; "
            "density per unit), with the mean, the coverage interval, the noise-free CPA value and the "
            "linearised (GUM) density."
        )
    if stem.startswith("sensitivity_"):
        return (
            "Sensitivity of the CPA Monte Carlo to the swept setting: Cpk (eq. 5-5) and mean − nominal (µm for "
            "lengths, mdeg for angles) per parameter."
        )
    return stem.replace("_", " ").capitalize() + "."


def _figures(page: _Page, folder: str, *, names=None, first=(), captions=None) -> list[dict]:
    """The figure blocks of the PNG documents directly in ``folder`` (or of ``names``), ``first`` first."""
    names = page.children(folder, ".png") if names is None else names
    captions = _captions(page, folder) if captions is None else captions
    names = sorted(
        names,
        key=lambda n: (
            PurePosixPath(n).name not in first,
            first.index(PurePosixPath(n).name) if PurePosixPath(n).name in first else 0,
            n,
        ),
    )
    figures, problems = [], []
    for name in names:
        shown = page.figure(name, _caption(PurePosixPath(name).name, captions))
        if shown is None:
            continue
        (problems if shown.get("kind") == "problem" else figures).append(shown)
    return problems + ([_block("figures", figures=figures)] if figures else [])


def _numeric(table: Table) -> list[bool]:
    """Per column: it has a non-empty cell and every non-empty cell is a number (:func:`_number`)."""
    return [_all_numbers([row[k] for row in table.rows]) for k in range(len(table.header))]


def _all_numbers(cells: list) -> bool:
    """:func:`_numeric` of one column. Text cells (a CSV's) are stripped and parsed by ``float`` directly,
    without :func:`_number`'s type tests per cell: about half its time (the demo's tables hold ~70,000 cells,
    ~0.05 s of a run's report stage). ``strip`` stays: ``float`` alone keeps the controls U+001C-U+001F."""
    present = [cell for cell in cells if cell != ""]
    if not present:
        return False
    if all(type(cell) is str for cell in present):
        try:
            for cell in present:
                float(cell.strip())
        except ValueError:
            return False
        return True
    return all(_number(cell) is not None for cell in present)


def _column_label(name: str, unit: str | None) -> str:
    if unit and name not in _COUNT_COLUMNS:
        return f"{_COLUMN_LABELS.get(name, name.replace('_', ' '))} ({unit})"
    return _COLUMN_LABELS.get(name, _label(name))


def _split_columns(header: list[str], numeric: list[bool]) -> list[list[int]]:
    """Column groups of at most ``_TABLE_COLUMNS``, each repeating the leading key columns (ids, names)."""
    keys = []
    for k, name in enumerate(header[:2]):
        if name in _COUNT_COLUMNS or not numeric[k]:
            keys.append(k)
        else:
            break
    rest = [k for k in range(len(header)) if k not in keys]
    if len(header) <= _TABLE_COLUMNS or not rest:
        return [list(range(len(header)))]
    width = max(1, _TABLE_COLUMNS - len(keys))
    chunks = [rest[i : i + width] for i in range(0, len(rest), width)]
    return [keys + chunk for chunk in chunks]


def _csv(page: _Page, name: str, *, caption: str = "", columns=None, rows_limit: int = _TABLE_ROWS) -> list:
    """A CSV document as tables: the chosen ``columns`` (all by default), one table per ``unit`` (the unit in
    the headers), columns split so that no table is wider than ``_TABLE_COLUMNS``."""
    table = page.table(name)
    if table is None:
        return []
    header = list(table.header)
    numeric = _numeric(table)
    keep = [k for k in range(len(header)) if columns is None or header[k] in columns]
    if columns is not None:
        keep.sort(key=lambda k: list(columns).index(header[k]))
    groups: list[tuple[str | None, list]] = [(None, list(table.rows))]
    if "unit" in header and table.rows:
        at = header.index("unit")
        keep = [k for k in keep if k != at]
        units = list(dict.fromkeys(row[at] for row in table.rows))
        groups = [(unit, [row for row in table.rows if row[at] == unit]) for unit in units]
    blocks = []
    for unit, rows in groups:
        shown = rows[:rows_limit]
        chunks = _split_columns([header[k] for k in keep], [numeric[k] for k in keep])
        for c, chunk in enumerate(chunks):
            picked = [keep[i] for i in chunk]
            parts = [caption] if caption else []
            if unit is not None:
                parts.append(f"rows in {unit or 'no unit'}")
            if len(chunks) > 1:
                parts.append(f"columns {c + 1} of {len(chunks)}")
            blocks.append(
                _Table(
                    header=[
                        _column_label(header[k], unit) if unit and numeric[k] else _label(header[k]) for k in picked
                    ],
                    rows=[[_cell(row[k]) for k in picked] for row in shown],
                    caption="; ".join(parts),
                    source=name,
                    text_columns=frozenset(i for i, k in enumerate(picked) if not numeric[k]),
                    note=_rows_note(len(shown), len(rows)) if c == len(chunks) - 1 else "",
                )
            )
    return blocks


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


def _fact_unit(key: str, value) -> str:
    """The unit of a provenance fact: named by a key's suffix or a parameter name (``J1.a`` mm, ``J1.alpha``
    deg) on its path; ``—`` for a pure number (a count, a ratio); empty for text."""
    if isinstance(value, bool) or value is None:
        return ""
    parts = key.split(".")
    for k in range(len(parts) - 1, -1, -1):
        unit = "s" if parts[k] == "seconds" else _unit_of(parts[k])
        if unit is not None:
            return unit
        if k + 1 < len(parts) and _is_param(f"{parts[k]}.{parts[k + 1]}"):
            return _param_unit(f"{parts[k]}.{parts[k + 1]}")
    if isinstance(value, str):
        return ""
    return "—"


def _facts(data: dict | None, *, caption: str = "", source: str = "", skip=(), limit: int = 60) -> list:
    """Scalar entries of a JSON object as a table of entry, value and unit."""
    if not data:
        return []
    items = [(k, v) for k, v in _flatten(data) if not any(k == s or k.startswith(s + ".") for s in skip)]
    # parameter names are dotted themselves: "standard_uncertainty.J1.a" is one entry of a parameter
    rows = []
    for key, value in items[:limit]:
        parts = re.sub(r"\.(J\d+)\.(d|theta|a|alpha|beta)$", r".\1·\2", key).split(".")
        label = " › ".join(_bare(part) for part in parts)
        label = label.replace("·", ".")
        shown = value if isinstance(value, str) else _fmt(value)
        rows.append([label, shown, _fact_unit(key, value)])
    if not rows:
        return []
    return [
        _Table(
            header=["entry", "value", "unit"],
            rows=rows,
            caption=caption,
            source=source,
            text_columns=frozenset({0, 1, 2}),
            note=_rows_note(limit, len(items)) if len(items) > limit else "",
        )
    ]


# --------------------------------------------------------------------------------------------------
# sections


def _card(question: str, label: str, value: str, detail: str = "") -> dict:
    return {"question": question, "label": label, "value": value, "detail": detail, "na": value == "n/a"}


def _facts_of_run(page: _Page) -> list[dict]:
    """Robot, scenario, instrument, captures, seed, method: ``[{"label", "text", "code"}]``."""
    record = page.record
    scenario = record.get("scenario") if isinstance(record.get("scenario"), dict) else {}
    facts = []
    if isinstance(record.get("robot"), str):
        facts.append({"label": "robot", "text": record["robot"], "code": None})
    if isinstance(scenario.get("name"), str):
        description = scenario.get("description")
        text = scenario["name"] + (f" — {description}" if isinstance(description, str) and description else "")
        facts.append({"label": "scenario", "text": text, "code": None})
    instrument = scenario.get("instrument") if isinstance(scenario.get("instrument"), dict) else {}
    if isinstance(instrument.get("name"), str):
        a_um, b_um = _number(instrument.get("a_um")), _number(instrument.get("b_um_per_m"))
        text = instrument["name"]
        if a_um is not None and b_um is not None:
            text += f", U(L) = {_fmt(a_um)} µm + {_fmt(b_um)} µm/m · L"
        facts.append({"label": "instrument", "text": text, "code": None})
    for name, what in (("capture.csv", "calibration capture"), ("validation.csv", "validation points")):
        table = page.table(name)
        if table is not None:
            text = f"{len(table.rows)} points"
            if name == "capture.csv" and "circle" in table.header:
                text += f" in {len(set(table.column('circle')))} circles"
            facts.append({"label": what, "text": text, "code": name})
    if record.get("seed") is not None:
        facts.append({"label": "seed", "text": str(record["seed"]), "code": None})
    provenance = (page.json("cpa/parameters.json") or {}).get("provenance")
    if isinstance(provenance, dict) and isinstance(provenance.get("method"), str):
        facts.append({"label": "identification", "text": provenance["method"], "code": None})
    return facts


def _cards(page: _Page) -> list[dict]:
    summary = page.summary
    cards = []
    if summary.validation_before_mm is not None and summary.validation_after_mm is not None:
        before, after = summary.validation_before_set or "before", summary.validation_after_set or "after"
        detail = (
            f"mean position error at the {summary.validation_capture or 'validation'} points, {before} → {after}"
            + (f" ({set_label(after)})" if set_label(after) != after else "")
        )
        cards.append(
            _card(
                "How good is it?",
                "validation error, before → after",
                f"{_length(summary.validation_before_mm)} → {_length(summary.validation_after_mm)}",
                detail,
            )
        )
    else:
        why = "evaluation stage not run" if not page.has("evaluation") else "no headline in evaluation.json"
        cards.append(_card("How good is it?", "validation error, before → after", "n/a", why))
    if summary.circle_rms_mm is not None:
        circle = f"circle J{summary.circle_rms_circle}; " if summary.circle_rms_circle is not None else ""
        cards.append(
            _card(
                "How good is it?",
                "largest circle-fit RMS",
                f"{_fmt(summary.circle_rms_mm * 1e3, '.2f')} µm",
                f"{circle}{summary.circles} circles fitted by CPA",
            )
        )
    refined, cpa = summary.uncertainty("uncertainty-refined"), summary.uncertainty("uncertainty")
    shown = refined or cpa
    model = "refined model (deployed)" if refined is not None else "CPA model"
    for label, value_of, name_of, fmt in (
        ("largest standard uncertainty, lengths", "length_mm", "length_name", _length),
        ("largest standard uncertainty, angles", "angle_deg", "angle_name", _angle),
    ):
        value = getattr(shown, value_of) if shown is not None else None
        if value is None:
            cards.append(_card("How sure are we?", label, "n/a", "uncertainty stage not run"))
            continue
        detail = f"{getattr(shown, name_of)}, {model}, Monte Carlo (GUM-S1)"
        if refined is not None and cpa is not None and getattr(cpa, value_of) is not None:
            detail += f"; CPA alone: {fmt(getattr(cpa, value_of))} ({getattr(cpa, name_of)})"
        cards.append(_card("How sure are we?", label, fmt(value), detail))
    pose = summary.tcp_pose
    if pose is not None:
        detail = "√(u_X² + u_Y² + u_Z²) at the first pose" + (f" (of {pose.poses})" if pose.poses > 1 else "")
        detail += f"; {pose.model}" if pose.model else ""
        if pose.ellipsoid_mm is not None:
            share = f"{_fmt(pose.coverage * 100, '.3g')} % " if pose.coverage else ""
            detail += f"; largest semi-axis of the {share}ellipsoid {_length(pose.ellipsoid_mm)}"
        cards.append(_card("How sure are we?", "TCP position uncertainty at the pose", _length(pose.first_mm), detail))
    else:
        cards.append(_card("How sure are we?", "TCP position uncertainty at the pose", "n/a", "tcp pose not run"))
    workspace = summary.tcp_workspace
    if workspace is not None:
        cards.append(
            _card(
                "Where can I trust it?",
                "TCP position uncertainty over the workspace",
                f"{_length(workspace.median_mm)} / {_length(workspace.p95_mm)}",
                f"median / 95th percentile of {workspace.poses} poses; worst {_length(workspace.max_mm)}"
                + (f"; {workspace.model}" if workspace.model else ""),
            )
        )
    else:
        cards.append(
            _card("Where can I trust it?", "TCP uncertainty over the workspace", "n/a", "workspace map not run")
        )
    trajectory = summary.tcp_trajectory
    if trajectory is not None:
        cards.append(
            _card(
                "Where can I trust it?",
                "TCP uncertainty along the trajectory",
                f"≤ {_length(trajectory.max_mm)}",
                f"largest of {trajectory.poses} poses; smallest {_length(trajectory.min_mm)}"
                + (f"; {trajectory.model}" if trajectory.model else ""),
            )
        )
    check = summary.consistency
    if check is not None:
        registered = check.base_frame == "registered"
        cards.append(
            _card(
                "Does the uncertainty explain the error?",
                "validation RMS error, expected → observed",
                f"{_length(check.expected_rms_mm)} → {_length(check.observed_rms_mm)}",
                f"expected = √(predicted² + instrument²) = √({_length(check.predicted_rms_mm)}² + "
                f"{_length(check.instrument_rms_mm)}²) at {check.poses} validation poses ({check.model}"
                + (", base frame registered: the registration absorbs part of the error" if registered else "")
                + f"); observed / expected = {_fmt(check.ratio, '.3g')}: {check.verdict}",
            )
        )
    return cards


def _summary(page: _Page) -> dict:
    stages = page.record.get("stages") if isinstance(page.record.get("stages"), dict) else {}
    rows = []
    for stage, outputs in OUTPUTS.items():
        if stage == "report":
            continue
        entry = stages.get(stage) if isinstance(stages.get(stage), dict) else {}
        present = any(page.has(name) for name in outputs)
        status = entry.get("status") if isinstance(entry.get("status"), str) else None
        shown = status or ("done" if present else "not run")
        css = "failed" if shown in ("failed", "error") else ("ok" if present else "missing")
        detail = entry.get("detail") if isinstance(entry.get("detail"), str) else ""
        seconds = _fmt(_number(entry.get("seconds")), ".2f")
        rows.append(
            {"stage": stage, "outputs": outputs, "status": shown, "css": css, "seconds": seconds, "detail": detail}
        )
    return {
        "present": True,
        "facts": _facts_of_run(page),
        "cards": _cards(page),
        "stages": rows,
        "notes": page.summary.notes,
    }


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


def _statistics(data: dict | None) -> dict:
    """``name -> parameter entry`` of a Monte Carlo's ``parameters.json`` (``parameters`` list)."""
    parameters = (data or {}).get("parameters")
    if not isinstance(parameters, list):
        return {}
    return {p["name"]: p for p in parameters if isinstance(p, dict) and isinstance(p.get("name"), str)}


def _refinement_rms(page: _Page, label: str, data: dict) -> list:
    """Which RMS is which, for one refinement: the criterion's, the points', and the validation's."""
    provenance = data.get("provenance") if isinstance(data.get("provenance"), dict) else {}
    convergence = provenance.get("convergence") if isinstance(provenance.get("convergence"), dict) else {}
    history = convergence.get("rms_mm") if isinstance(convergence.get("rms_mm"), list) else []
    final = _number(history[-1]) if history else None
    residuals, points = provenance.get("residuals"), provenance.get("points")
    distance = "point distance |T p − m|" if label == "points" else "distance error |D model − D measured|"
    rows = []
    if final is not None:
        rows.append(
            [
                "criterion RMS (convergence figure)",
                _length(final),
                f"√(2·cost/m): RMS of the {residuals} residuals, per coordinate"
                if label == "points"
                else f"√(2·cost/m): RMS of the {residuals} distance residuals",
            ]
        )
    rms = _number(provenance.get("residual_rms_mm"))
    if rms is not None:
        what = (
            f"at the {points} capture points: a distance in 3-D, so about √3 × the per-coordinate RMS"
            if label == "points"
            else "over the capture's point pairs: the same residuals as the criterion's"
        )
        rows.append([f"RMS {distance}", _length(rms), what])
    evaluation = page.json("evaluation/evaluation.json") or {}
    for row in evaluation.get("rows") or []:
        if isinstance(row, dict) and row.get("parameter_set") == label and row.get("capture") == "validation":
            if row.get("view") == "points" and _number(row.get("rms_error_mm")) is not None:
                rows.append(
                    [
                        "validation RMS error",
                        _length(_number(row["rms_error_mm"])),
                        f"RMS of the {row.get('n_errors')} validation point errors after registration "
                        "(evaluation, points view): not fitted, so the honest figure",
                    ]
                )
    if not rows:
        return []
    return [
        _Table(
            header=["RMS", "value", "what it is"],
            rows=rows,
            caption=f"The RMS figures of the {label} refinement",
            text_columns=frozenset({0, 2}),
        )
    ]


def _parameters(page: _Page) -> dict:
    cpa = page.json("cpa/parameters.json")
    truth = page.json("truth.json")
    refined = {label: page.json(f"refine/{label}.json") for label in ("points", "distances")}
    mc = {
        folder: _statistics(page.json(f"{folder}/parameters.json")) for folder in ("uncertainty-refined", "uncertainty")
    }
    if cpa is None and not any(mc.values()) and not any(refined.values()):
        return {"present": False, "blocks_": [_block("not_run", what="cpa/parameters.json")]}
    cpa_values, identified, fixed = _parameter_values(cpa)
    truth_values = _parameter_values(truth)[0]
    nominal = {}
    for stats in mc.values():
        nominal.update(
            {n: _number(p.get("nominal")) for n, p in stats.items() if _number(p.get("nominal")) is not None}
        )
    values: list[tuple[str, dict, str]] = [("nominal", nominal, ".4f")] if nominal else []
    if truth_values:
        values.append(("truth", truth_values, ".4f"))
    if cpa_values:
        values.append(("CPA", cpa_values, ".4f"))
        if truth_values:
            values.append(
                ("CPA − truth", {k: _difference(k, v, truth_values[k]) for k, v in cpa_values.items() if k in truth_values}, ".3e")
            )
    for label, data in refined.items():
        found, more, more_fixed = _parameter_values(data)
        if found:
            values.append((f"refined ({label})", found, ".4f"))
            identified |= more
            fixed |= more_fixed
    uncertainty: list[tuple[str, dict, str]] = []
    for folder, model in (("uncertainty-refined", "refined"), ("uncertainty", "CPA")):
        stats = mc[folder]
        if not stats:
            continue
        coverage = _number((page.json(f"{folder}/parameters.json") or {}).get("coverage"))
        share = f"{_fmt(coverage * 100, '.3g')} % " if coverage else ""
        uncertainty += [
            (f"{model} MC mean", {n: _number(p.get("mean")) for n, p in stats.items()}, ".4f"),
            (f"{model} u", {n: _number(p.get("std_uncertainty")) for n, p in stats.items()}, ".3g"),
            (
                f"{model} {share}interval",
                {n: (_number(p.get("coverage_low")), _number(p.get("coverage_high"))) for n, p in stats.items()},
                ".4f",
            ),
        ]
        if not identified:
            identified = {n for n, p in stats.items() if p.get("identified") is True}
    names = sorted({n for _, found, _ in values + uncertainty for n in found if _is_param(n)} - fixed, key=_param_order)
    blocks = []
    for unit, kinds, title in (
        (DISPLAY_UNITS["length"], LENGTH_KINDS, "Lengths"),
        (DISPLAY_UNITS["angle"], ANGLE_KINDS, "Angles"),
    ):
        group = [n for n in names if n.split(".")[1] in kinds]
        if not group:
            continue
        dim = frozenset(r for r, n in enumerate(group) if identified and n not in identified)
        tags = {r: "(not identified)" for r in dim}
        blocks.append(_block("heading", text=f"{title} ({unit})"))
        for columns, what in ((values, "values"), (uncertainty, "Monte Carlo uncertainty")):
            if not columns:
                continue
            rows = []
            for name in group:
                row = [name]
                for _, found, spec in columns:
                    value = found.get(name)
                    if isinstance(value, tuple):
                        row.append(
                            f"{_fmt(value[0], spec, exponent=False)} … {_fmt(value[1], spec, exponent=False)}"
                            if None not in value
                            else ""
                        )
                    else:
                        row.append(_fmt(value, spec, exponent=spec != ".4f") if value is not None else "")
                rows.append(row)
            blocks.append(
                _Table(
                    header=["parameter"] + [f"{label} ({unit})" for label, _, _ in columns],
                    rows=rows,
                    caption=f"{what}, every one in {unit}; grey rows are not identified and stay nominal",
                    text_columns=frozenset({0}),
                    dim_rows=dim,
                    tags=tags,
                )
            )
    provenance = (cpa or {}).get("provenance") if isinstance((cpa or {}).get("provenance"), dict) else None
    if provenance is not None:
        circles = [c for c in provenance.get("circles") or [] if isinstance(c, dict)]
        if circles:
            blocks.append(_block("heading", text="CPA circle fits"))
            blocks.append(
                _Table(
                    header=["circle", "points", "radius (mm)", "plane RMS (µm)", "circle RMS (µm)"],
                    rows=[
                        [
                            str(c.get("circle", "")),
                            str(c.get("points", "")),
                            _fmt(_number(c.get("radius_mm")), ".4f"),
                            _fmt(
                                None if _number(c.get("plane_rms_mm")) is None else _number(c["plane_rms_mm"]) * 1e3,
                                ".3g",
                            ),
                            _fmt(
                                None if _number(c.get("circle_rms_mm")) is None else _number(c["circle_rms_mm"]) * 1e3,
                                ".3g",
                            ),
                        ]
                        for c in circles
                    ],
                    caption="plane RMS: distance of the points to the fitted plane; circle RMS: in-plane distance to "
                    "the fitted circle",
                    source="cpa/parameters.json",
                )
            )
        pairs = provenance.get("line_pairs")
        if isinstance(pairs, list) and pairs:
            blocks.append(_block("note", text="Adjacent joint axes: " + "; ".join(str(p) for p in pairs) + "."))
        blocks += _facts(
            provenance,
            caption="CPA provenance",
            source="cpa/parameters.json",
            skip=("circles", "line_pairs", "versions", "tracker_from_base"),
        )
    for label, data in refined.items():
        if data and isinstance(data.get("provenance"), dict):
            blocks.append(_block("heading", text=f"Refinement ({label} criterion)"))
            blocks += _refinement_rms(page, label, data)
            blocks += _facts(
                data["provenance"],
                caption="provenance",
                source=f"refine/{label}.json",
                skip=("versions", "convergence", "correlation", "tracker_from_base"),
            )
    return {"present": True, "blocks_": blocks}


def _stage(page: _Page, folder: str, *, first_csv=(), first_png=(), csv_options=None, skip_csv=()) -> list:
    """Every CSV (as tables), PNG (figures) and JSON (scalar entries) directly in a stage folder."""
    csv_options = csv_options or {}
    blocks = []
    names = [n for n in page.children(folder, ".csv") if PurePosixPath(n).name not in skip_csv]
    names.sort(key=lambda n: (PurePosixPath(n).name not in first_csv, n))
    for name in names:
        blocks += _csv(page, name, **csv_options.get(PurePosixPath(name).name, {}))
    blocks += _figures(page, folder, first=tuple(first_png))
    for name in page.children(folder, ".json"):
        blocks += _facts(page.json(name), source=name, skip=("figures", "versions", "rows", "convergence", "poses"))
    return blocks


def _evaluation(page: _Page) -> dict:
    if not page.has("evaluation"):
        return {"present": False, "blocks_": [_block("not_run", what="evaluation/")]}
    return {
        "present": True,
        "blocks_": _stage(page, "evaluation", first_csv=("evaluation.csv",), first_png=("convergence.png",)),
    }


def _difference(name: str, value: float, reference: float) -> float:
    """``value - reference``; for an angle (``Jn.theta``, ``alpha``, ``beta``, deg) the difference within
    (-180, 180], so that two values a turn apart (180.08 and -179.92) differ by 0.16, not 360."""
    difference = value - reference
    if name.rsplit(".", 1)[-1] in ANGLE_KINDS:
        difference = 180.0 - (180.0 - difference) % 360.0
    return difference


def _noise_floors(page: _Page) -> tuple[dict, str]:
    """``(joint -> noise floor [µm], document)``: the ``noise_floor_um`` column of ``joints/summary.csv`` (one
    row per joint; older runs have none)."""
    for name, key in (("joints/summary.csv", "joint"),):
        table = page.table(name)
        if table is not None and {key, "noise_floor_um"} <= set(table.header):
            floors = {}
            for joint, value in zip(table.column(key), table.column("noise_floor_um"), strict=True):
                if _number(value) is not None:
                    floors.setdefault(joint, _number(value))
            return floors, name
    return {}, ""


def _joints(page: _Page) -> dict:
    if not page.has("joints"):
        return {"present": False, "blocks_": [_block("not_run", what="joints/")]}
    blocks = []
    summary = page.table("joints/summary.csv")
    floors, floor_source = _noise_floors(page)
    if summary is not None:
        records = summary.records()
        fits = [
            "joint",
            "points",
            "radius_mm",
            "plane_rms_mm",
            "circle_rms_mm",
            "axial_min_mm",
            "axial_max_mm",
            "radial_min_mm",
            "radial_max_mm",
        ]
        um = {name for name in fits if name.endswith("_mm") and name != "radius_mm"}
        present = [c for c in fits if c in summary.header]
        blocks.append(_block("heading", text="Circle fits and eccentricity"))
        blocks.append(
            _Table(
                header=[_label(c[:-3] + "_um") if c in um else _label(c) for c in present],
                rows=[
                    [
                        _fmt(_number(r[c]) * 1e3, ".3g") if c in um and _number(r[c]) is not None else _cell(r[c])
                        for c in present
                    ]
                    for r in records
                ],
                caption="per joint; small lengths in µm",
                source="joints/summary.csv",
            )
        )
        lash = [
            c
            for c in ("backlash_mean_mm", "backlash_min_mm", "backlash_max_mm", "backlash_std_mm")
            if c in summary.header
        ]
        if lash:
            header = ["joint", "pairs"] + [_label(c[:-3] + "_um") for c in lash]
            rows = []
            for r in records:
                row = [r.get("joint", ""), r.get("pairs", "")]
                row += [_fmt(_number(r[c]) * 1e3, ".3g") if _number(r[c]) is not None else r[c] for c in lash]
                if "backlash_angle_mean_deg" in summary.header:
                    row.append(_cell(r["backlash_angle_mean_deg"]))
                if floors:
                    floor, mean = floors.get(r.get("joint")), _number(r.get("backlash_mean_mm"))
                    row.append(_fmt(floor, ".3g") if floor is not None else "n/a")
                    ratio = mean * 1e3 / floor if floor and mean is not None else None
                    row.append(_fmt(ratio, ".2f", exponent=False))
                rows.append(row)
            if "backlash_angle_mean_deg" in summary.header:
                header.append("backlash angle mean (deg)")
            if floors:
                header += ["noise floor (µm)", "mean / floor"]
            blocks.append(_block("heading", text="Backlash"))
            blocks.append(
                _Table(
                    header=header,
                    rows=rows,
                    caption="per joint: magnitude of return − forward at the same reading; "
                    + (f"{_NOISE_FLOOR} (from {floor_source})" if floors else "no noise floor in this run"),
                    source="joints/summary.csv",
                )
            )
    captions = _captions(page, "joints")
    per_point = [n for n in page.children("joints", ".csv") if n != "joints/summary.csv"]
    if per_point:
        blocks.append(
            _block("note", text="Per point and per pair of forward and return points: " + ", ".join(per_point) + ".")
        )
    blocks += _figures(page, "joints", captions=captions, first=("backlash_magnitude.png", "backlash_xyz.png"))
    for name in page.children("joints", ".json"):
        blocks += _facts(page.json(name), source=name, skip=("figures", "versions", "joints"))
    return {"present": True, "blocks_": blocks, "noise_floor": bool(floors)}


#: Columns of a Monte Carlo's parameters.csv shown in the report (the file holds more).
_MC_COLUMNS = (
    "name",
    "nominal",
    "mean",
    "std_uncertainty",
    "coverage_low",
    "coverage_high",
    "lpu_std_uncertainty",
    "identified",
)
_TCP_COLUMNS = (
    "pose",
    "name",
    "nominal",
    "mean",
    "std_uncertainty",
    "coverage_low",
    "coverage_high",
    "lpu_std_uncertainty",
)


def _montecarlo(page: _Page) -> dict:
    if not page.has("uncertainty") and not page.has("uncertainty-refined"):
        return {"present": False, "blocks_": [_block("not_run", what="uncertainty/")]}
    models = []
    for folder, title in (
        ("uncertainty-refined", "Refined model (deployed)"),
        ("uncertainty", "CPA model (thesis ch. 5.2.3)"),
    ):
        if not page.has(folder):
            models.append({"title": title, "folder": folder, "blocks_": [_block("not_run", what=folder + "/")]})
            continue
        blocks = _facts(
            page.json(f"{folder}/parameters.json"),
            caption="settings and outcome",
            source=f"{folder}/parameters.json",
            skip=("figures", "versions", "scenario", "parameters", "covariance", "correlation", "linearised"),
        )
        pngs = page.children(folder, ".png")
        blocks += _figures(page, folder, names=[n for n in pngs if PurePosixPath(n).name.startswith("hist_")])
        blocks += _figures(page, folder, names=[n for n in pngs if not PurePosixPath(n).name.startswith("hist_")])
        blocks += _csv(
            page,
            f"{folder}/parameters.csv",
            caption="parameter statistics of the draws (the file has more columns: min, max, shortest interval, "
            "linearised interval)",
            columns=_MC_COLUMNS,
            rows_limit=200,
        )
        for name in page.children(folder, ".csv"):
            if name != f"{folder}/parameters.csv":
                blocks += _csv(page, name)
        models.append({"title": title, "folder": folder, "blocks_": blocks})
    return {"present": True, "models": models}


def _tcp_stage(page: _Page, folder: str) -> list:
    return _stage(
        page,
        folder,
        first_csv=("tcp.csv",),
        csv_options={"tcp.csv": {"columns": _TCP_COLUMNS, "caption": "the file has more columns: min, max"}},
    )


def _tcp(page: _Page) -> dict:
    parts = []
    for sub, title in (("pose", "At the pose"), ("trajectory", "Along the trajectory")):
        folder = f"tcp/{sub}"
        present = page.has(folder)
        blocks = _tcp_stage(page, folder) if present else [_block("not_run", what=folder + "/")]
        parts.append({"title": title, "blocks_": blocks, "present": present})
    consistency = _facts(
        page.json("tcp/consistency.json"), caption="validation consistency", source="tcp/consistency.json"
    )
    return {"present": any(p["present"] for p in parts), "parts": parts, "consistency": consistency}


def _workspace(page: _Page) -> dict:
    if not page.has("tcp/workspace"):
        return {"present": False, "blocks_": [_block("not_run", what="tcp/workspace/")]}
    return {"present": True, "blocks_": _tcp_stage(page, "tcp/workspace")}


def _iso9283(page: _Page) -> dict:
    if not page.has("iso9283"):
        return {"present": False, "blocks_": [_block("not_run", what="iso9283/")]}
    units = "units: APx, APy, APz, AP, l_bar, S_l, RP, AD, RD in mm; APa, APb, APc, RPa, RPb, RPc in deg"
    blocks = _stage(
        page,
        "iso9283",
        first_csv=("iso9283.csv",),
        first_png=("iso9283.png",),
        csv_options={"iso9283.csv": {"caption": units}},
    )
    return {"present": True, "blocks_": blocks}


def _planning(page: _Page) -> dict:
    if not page.has("plan"):
        return {"present": False, "blocks_": [_block("not_run", what="plan/")]}
    check = _stage(page, "plan", first_csv=("plan_check.csv",), first_png=("plan_check.png",))
    if page.has("plan/sensitivity"):
        sensitivity = _stage(page, "plan/sensitivity")
    else:
        sensitivity = [_block("not_run", what="plan/sensitivity/")]
    return {"present": True, "check": check, "sensitivity": sensitivity}


def _capture(table: Table):
    """The Capture of a ``capture.csv`` document (circle, direction, q1..qN in deg, x, y, z in mm)."""
    from robotcal.capture import Capture

    header = [h.strip().lower() for h in table.header]
    joints = sorted((h for h in header if re.fullmatch(r"q\d+", h)), key=lambda h: int(h[1:]))
    missing = [c for c in ("circle", "direction", "x", "y", "z") if c not in header] + ([] if joints else ["q1..qN"])
    if missing:
        raise ValueError(f"missing column(s) {', '.join(missing)}")
    columns = ["circle", "direction", *joints, "x", "y", "z"]
    data = np.array([[float(row[header.index(c)]) for c in columns] for row in table.rows], dtype=float)
    if data.size == 0 or not np.all(np.isfinite(data)):
        raise ValueError("no rows, or a value that is not a finite number")
    return Capture(
        circle=data[:, 0].astype(int),
        direction=data[:, 1].astype(int),
        readings=np.deg2rad(data[:, 2 : 2 + len(joints)]),
        points=data[:, -3:],
    )


def _view3d(page: _Page) -> dict:
    table = page.table("capture.csv")
    if table is None:
        return {"present": False, "blocks_": [_block("not_run", what="capture.csv")]}
    from robotcal.errors import RobotcalError

    try:
        capture = _capture(table)
    except (ValueError, IndexError, RobotcalError) as exc:
        return {"present": False, "blocks_": [page.problem("capture.csv", f"not a capture ({exc})")]}
    provenance = (page.json("cpa/parameters.json") or {}).get("provenance")
    provenance = provenance if isinstance(provenance, dict) else {}
    pose = provenance.get("tracker_from_base")
    try:
        pose = np.asarray(pose, dtype=float) if pose is not None else None
        if pose is not None and pose.shape != (4, 4):
            pose = None
    except (TypeError, ValueError):
        pose = None
    options = provenance.get("options") if isinstance(provenance.get("options"), dict) else {}
    circle_fit = options.get("circle_fit")
    scene = viewer_scene(
        capture,
        tracker_from_base=pose,
        circle_fit=circle_fit if circle_fit in ("geometric", "algebraic") else "geometric",
    )
    return {"present": True, "notes": scene["notes"], "frame": pose is not None, "viewer": render_viewer(scene)}


def _provenance(page: _Page) -> dict:
    record = page.record
    blocks = (
        _facts(record, caption="run record", source="run.json", skip=("versions", "scenario.settings"), limit=80)
        if record
        else [_block("note", text="No run.json: this run was not recorded by robotcal run.")]
    )
    versions = {}
    for name in ("cpa/parameters.json", "uncertainty/parameters.json"):
        found = (page.json(name) or {}).get("provenance", {})
        if isinstance(found, dict) and isinstance(found.get("versions"), dict):
            versions.update({str(k): str(v) for k, v in found["versions"].items()})
    if isinstance(record.get("versions"), dict):
        versions.update({str(k): str(v) for k, v in record["versions"].items()})
    versions.setdefault("robotcal (this report)", robotcal.__version__)
    blocks.append(
        _Table(
            header=["software", "version"],
            rows=[[k, v] for k, v in versions.items()],
            caption="Versions",
            text_columns=frozenset({0, 1}),
        )
    )
    rows = []
    for name in sorted(n for n in page.result.documents if n != REPORT_NAME):
        document = page.result.documents[name]
        if isinstance(document, Table):
            rows.append([name, "CSV", f"{len(document.rows)} rows of {len(document.header)} columns"])
        elif isinstance(document, dict):
            rows.append([name, "JSON", f"{len(document)} top-level entries"])
        else:
            rows.append([name, "figure" if name.endswith(".png") else "binary file", ""])
    blocks.append(
        _Table(
            header=["document", "kind", "contents"],
            rows=rows[:300],
            caption="The documents of the run this report was built from",
            text_columns=frozenset({0, 1, 2}),
            code_columns=frozenset({0}),
            note=_rows_note(min(len(rows), 300), len(rows)),
        )
    )
    folder = page.result.folder
    return {
        "present": True,
        "blocks_": blocks,
        "generated": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
        "version": robotcal.__version__,
        "folder": str(folder) if folder is not None else None,
    }


_SECTIONS = (
    ("summary", "Summary", _summary),
    ("parameters", "Parameters", _parameters),
    ("evaluation", "Evaluation and convergence", _evaluation),
    ("joints", "Joint diagnostics", _joints),
    ("montecarlo", "Monte Carlo uncertainty", _montecarlo),
    ("tcp", "TCP uncertainty", _tcp),
    ("workspace", "Workspace map", _workspace),
    ("iso9283", "ISO 9283 accuracy and repeatability", _iso9283),
    ("planning", "Capture planning", _planning),
    ("view3d", "3-D view of the capture", _view3d),
    ("provenance", "Provenance", _provenance),
)


def load_templates() -> None:
    """Compile every template of the report now (the environment keeps them): a run calls this while its last
    figures are drawn, so that :func:`render_report` only renders afterwards (~0.1 s less at a run's end)."""
    environment = template_environment()
    try:
        for name in environment.list_templates(extensions=["j2"]):
            environment.get_template(name)
    except Exception:  # noqa: BLE001 - a template that does not compile fails render_report, which names it
        pass


def render_report(result: RunResult) -> Report:
    """Render the report of a run as one HTML string, without writing anything.

    Parameters
    ----------
    result : RunResult
        The run (from :func:`robotcal.pipeline.run_calibration` or :func:`robotcal.pipeline.folder.read_run`).
        Every stage is optional. No file is read but the PNG figures among its documents.

    Returns
    -------
    Report

    Examples
    --------
    A run held in memory, here built by hand: a workspace map and nothing else.

    >>> from robotcal.pipeline.result import RunResult
    >>> workspace = {"poses": [{"position_uncertainty_mm": u} for u in (0.002, 0.004)]}
    >>> report = render_report(RunResult(documents={"tcp/workspace/tcp.json": workspace}))
    >>> [section.id for section in report.sections if section.present]
    ['summary', 'workspace', 'provenance']
    >>> "3 µm / 3.9 µm" in report.html  # median / 95th percentile of the two poses
    True
    """
    from markupsafe import Markup

    page = _Page(result)
    environment = template_environment()
    sections, bodies = [], []
    for anchor, title, build in _SECTIONS:
        context = build(page)
        sections.append(ReportSection(id=anchor, title=title, present=bool(context["present"])))
        if "viewer" in context:
            context["viewer"] = Markup(context["viewer"])  # render_viewer escapes what it embeds (tested)
        body = environment.get_template(f"{anchor}.html.j2").render(**context)
        bodies.append({"id": anchor, "title": title, "body": Markup(body)})
    robot = page.record.get("robot") or (page.json("cpa/parameters.json") or {}).get("robot") or "robot"
    scenario = page.record.get("scenario") if isinstance(page.record.get("scenario"), dict) else {}
    canvases = sum(str(b["body"]).count("<canvas") for b in bodies)
    html = environment.get_template("page.html.j2").render(
        title=f"Calibration report: {robot}",
        scenario=scenario.get("name") if isinstance(scenario.get("name"), str) else None,
        folder=result.folder.name if result.folder is not None else None,
        version=robotcal.__version__,
        csp=_CSP,
        sections=sections,
        bodies=bodies,
        problems=page.problems,
        css=Markup(asset_text("report.css")),
        errors_js=Markup(asset_text("errors.js")),
        viewer_js=Markup(asset_text("viewer3d.js")) if canvases else None,
        check_js=Markup(asset_text("check.js")),
    )
    return Report(
        html=html,
        sections=tuple(sections),
        figures=page.figures,
        canvases=canvases,
        problems=tuple(page.problems),
    )


def build_report(run_dir, out=None) -> Report:
    """Read the run folder ``run_dir``, render its report and write it atomically to ``out``.

    Parameters
    ----------
    run_dir : path
        A run folder (docs/results.md), read by :func:`robotcal.pipeline.folder.read_run`.
    out : path, optional
        The HTML file to write (default ``run_dir/report.html``).

    Returns
    -------
    Report
        With ``path`` set. See :func:`render_report`.

    Raises
    ------
    InputError
        ``run_dir`` is missing, not a folder, or holds none of the result files.
    """
    from robotcal.pipeline.folder import read_run

    report = render_report(read_run(run_dir))
    path = Path(out) if out is not None else Path(run_dir) / REPORT_NAME
    atomic_write_text(path, report.html)
    return replace(report, path=path)
