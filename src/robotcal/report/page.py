"""What every section of the report shares: number formatting, table and figure blocks, and :class:`_Page`,
the run as the section builders see it (:mod:`robotcal.report.sections`).

The names here are the report package's own (underscored: not part of robotcal's API).
"""

from __future__ import annotations

import base64
import math
import re
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from robotcal.io.results.run_folder import RunResult, Table
from robotcal.io.results.run_summary import Summary, summarise
from robotcal.io.results.uncertainty_files import CSV_COLUMNS
from robotcal.kinematics.model import ANGLE_KINDS, KIND_UNITS, PARAMETER_KINDS

_CAPTIONS = {
    "iso9283.png": "ISO 9283 pose accuracy AP (bars) and repeatability RP (tick above each bar) at the five test "
    "poses, per model (µm).",
    "convergence.png": "Convergence of the refinement, per criterion: RMS residual per coordinate "
    "√(2·cost/m) over the m residuals (mm, log scale) after each iteration; the y axis labels where each "
    "refinement ended, in the colour of its curve.",
    "ellipsoid.png": "95 % coverage ellipsoid of the TCP position (mm).",
    "scatter.png": "Monte Carlo draws of the TCP position about their mean, with the coverage ellipsoid (mm).",
    "histograms.png": "Monte Carlo histograms of the TCP coordinates X, Y, Z (mm) and A, B, C (deg) about their "
    "mean, with the coverage interval; the nominal is drawn where it lies among the draws, else its distance "
    "from the mean is in the panel's title.",
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
#: Columns of a table split by its ``unit`` column whose values are in each row's unit (the statistics of a
#: parameter or TCP coordinate); every other column (a varied setting such as ``capture.sweep_deg.4``, Cpk,
#: counts) keeps its own label and the unit its name gives, if any. These are the statistics of ``parameters.csv``
#: from ``nominal`` to ``lpu_coverage_high`` but ``identified`` (``tcp.csv``'s are among them).
_ROW_UNIT_COLUMNS = frozenset(CSV_COLUMNS[CSV_COLUMNS.index("nominal") : CSV_COLUMNS.index("lpu_agrees")]) - {"identified"}
#: Friendly headers of the columns of the statistics CSV files (unit added after).
_COLUMN_LABELS = {
    "cpk": "Cpk",
    "std_uncertainty": "u",
    "coverage_low": "interval low",
    "coverage_high": "interval high",
    "lpu_std_uncertainty": "u linearised (GUM)",
    "parameter_set": "parameter set",
}

_TABLE_ROWS = 40  # longer CSV files show their first rows and say so
_TABLE_COLUMNS = 8  # wider CSV files are split into several tables, repeating their key columns


def _number(text: object) -> float | None:
    """Float from a CSV cell or JSON value, else None."""
    if isinstance(text, bool):
        return None
    if isinstance(text, (int, float)):
        return float(text)
    try:
        return float(str(text).strip())
    except ValueError:
        return None


def _scaled(text: object, factor: float) -> float | None:
    """``_number(text) * factor`` (a unit change), else None."""
    number = _number(text)
    return None if number is None else number * factor


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


def _cell(text: str, spec: str = ".6g") -> str:
    """A CSV cell: integers and text as written, other numbers in ``spec`` (:func:`_fmt`)."""
    number = _number(text)
    if number is None or re.fullmatch(r"[+-]?\d+", text.strip() or "x"):
        return text
    return _fmt(number, spec, exponent=spec == ".6g")


#: The format of the numbers of a CSV column by its unit (a percentage: one decimal, 52.4 %).
_UNIT_FORMATS: dict[str | None, str] = {"%": ".1f"}  # by _unit_of: a unit, or None


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


def _setting_label(key: str) -> str:
    """``"capture.sweep_deg.4"`` -> ``"J4 sweep (deg)"``: a scenario setting a sensitivity study varies
    (``--vary KEY=...``: section, field and an optional 1-based element; the elements of a capture list are
    the circles, circle i turning joint i), its unit from the field's suffix."""
    parts = key.split(".")
    index = parts.pop() if len(parts) > 1 and parts[-1].isdigit() else None
    field = parts.pop()
    unit = _unit_of(field)
    name = _bare(field)
    if index is not None and parts == ["capture"]:
        text = f"J{index} {name}"
    else:
        text = " ".join([*parts, name, *([index] if index is not None else [])])
    return f"{text} ({unit})" if unit else text


def _label(name: str) -> str:
    """``"plane_rms_mm"`` -> ``"plane rms (mm)"``: units named by the key suffix go in brackets; a dotted
    scenario key (``"capture.sweep_deg.4"``) reads as the setting it names (:func:`_setting_label`)."""
    if "." in name and not _is_param(name):
        return _setting_label(name)
    for suffix, unit in _UNIT_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            return f"{name[: -len(suffix)].replace('_', ' ')} ({unit})"
    return name.replace("_", " ")


def _is_param(name: str) -> bool:
    return bool(re.fullmatch(r"J\d+\.(d|theta|a|alpha|beta)", name))


def _param_unit(name: str) -> str:
    return KIND_UNITS[name.split(".")[1]]


#: Units of the joint-model parameters by kind (robotcal.kinematics.joint_model): the compliance ``Jn.k`` and the
#: harmonic coefficients ``Jn.a1``, ``Jn.b1``, ...; a document's own joint model (``joint_model.parameters``, name
#: and unit) is asked first (:func:`_joint_model_units`).
_JOINT_MODEL_KINDS = ((re.compile(r"k"), "rad/(N m)"), (re.compile(r"[ab]\d+"), "deg"))


def _joint_model_units(document) -> dict[str, str]:
    """``{parameter name: unit}`` of a parameter document's ``joint_model.parameters`` (``refine/points.json``)."""
    model = document.get("joint_model") if isinstance(document, dict) else None
    parameters = model.get("parameters") if isinstance(model, dict) else None
    if not isinstance(parameters, list):
        return {}
    return {
        p["name"]: p["unit"]
        for p in parameters
        if isinstance(p, dict) and isinstance(p.get("name"), str) and isinstance(p.get("unit"), str)
    }


def _name_unit(name: str, units: Mapping | None = None) -> str | None:
    """The unit of a parameter name: a DH parameter (``J1.a``: mm) or a joint-model one (``J2.k``), else None."""
    if _is_param(name):
        return _param_unit(name)
    if units and name in units:
        return units[name]
    match = re.fullmatch(r"J\d+\.(\w+)", name)
    if match is not None:
        for pattern, unit in _JOINT_MODEL_KINDS:
            if pattern.fullmatch(match.group(1)):
                return unit
    return None


def _param_order(name: str):
    if _is_param(name):
        joint, kind = name.split(".")
        return (int(joint[1:]), PARAMETER_KINDS.index(kind))
    return (10**6, 0)


# --------------------------------------------------------------------------------------------------
# template data


#: Characters of a token (a path, a long name) above which a table cell may break it anywhere.
_LONG_TOKEN = 32


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
    fold: str = ""  # not empty: the table is folded under this summary line (a long table)

    @property
    def kind(self) -> str:
        return "table"

    @property
    def long_cells(self) -> frozenset:
        """``(row, column)`` of the text cells holding a token too long to fit a column (a path): those, and
        only those, may break anywhere; a word never breaks (issue 30: "uncertaint y")."""
        return frozenset(
            (r, c)
            for r, row in enumerate(self.rows)
            for c, cell in enumerate(row)
            if c in self.text_columns and max(map(len, str(cell).split()), default=0) > _LONG_TOKEN
        )


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


def _histogram_caption(joint: str, *, model: str | None = None, linearised: bool | None = None, refinement=None) -> str:
    """The caption of ``hist_J<n>.png`` (:func:`robotcal.plots.montecarlo.write_histograms`): what it draws depends
    on the Monte Carlo: the noise-free value is CPA's or the refinement's (``model``), and the linearised (GUM)
    density is drawn only when the Monte Carlo computed the linearised comparison (``linearised``; None: not
    known). ``refinement``: the document holding the refinement's own linearised u, named where there is no
    density."""
    noise_free = {
        "cpa": "the noise-free CPA value (dotted)",
        "refined": "the noise-free refined value (dotted: the refinement of the noise-free capture)",
    }.get(model or "", "the model's noise-free value (dotted)")
    text = (
        f"Monte Carlo histograms of the identified parameters of {joint} (lengths in mm, angles in deg; density per "
        f"unit), with the mean (solid), the coverage interval for the measurand (dashed), the draws' own interval "
        f"(dash-dot), {noise_free}"
    )
    if linearised is None:
        return text + " and, where the Monte Carlo computed the linearised comparison, the linearised (GUM) density."
    if linearised:
        return text + " and the linearised (GUM) density."
    where = f"; the refinement's own linearised standard uncertainties are in {refinement}" if refinement else ""
    return f"{text}. This Monte Carlo computed no linearised comparison, so no linearised (GUM) density is drawn{where}."


def _caption(name: str, captions: Mapping) -> str:
    if name in captions:
        return captions[name]
    if name in _CAPTIONS:
        return _CAPTIONS[name]
    stem = name.rsplit(".", 1)[0]
    if re.fullmatch(r"hist_J\d+", stem):
        return _histogram_caption(stem[5:])
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
    figures: list[dict] = []
    problems: list[dict] = []
    for name in names:
        shown = page.figure(name, _caption(PurePosixPath(name).name, captions))
        if shown is None:
            continue
        (problems if shown.get("kind") == "problem" else figures).append(shown)
    return problems + ([_block("figures", figures=figures)] if figures else [])


def _column_label(name: str, unit: str | None) -> str:
    """The header of a column of a table whose rows are in ``unit``: the statistics take it, other columns keep
    their own (``_ROW_UNIT_COLUMNS``)."""
    if unit and name in _ROW_UNIT_COLUMNS:
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
    numeric = list(table.numeric)
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
                    rows=[[_cell(row[k], _UNIT_FORMATS.get(_unit_of(header[k]), ".6g")) for k in picked] for row in shown],
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


def _fact_unit(key: str, value, units: Mapping | None = None) -> str:
    """The unit of a provenance fact: named by a key's suffix or a parameter name (``J1.a`` mm, ``J1.alpha``
    deg, ``J2.k`` rad/(N m); ``units``: more names) on its path; ``—`` for a pure number (a count, a ratio);
    empty for text."""
    if isinstance(value, bool) or value is None:
        return ""
    parts = key.split(".")
    for k in range(len(parts) - 1, -1, -1):
        unit = "s" if parts[k] == "seconds" else _unit_of(parts[k])
        if unit is not None:
            return unit
        if k + 1 < len(parts) and (unit := _name_unit(f"{parts[k]}.{parts[k + 1]}", units)) is not None:
            return unit
    if isinstance(value, str):
        return ""
    return "—"


#: A unit written "um" in a stage's one-line result (console text): the page writes µm.
_UM = re.compile(r"(?<![\w.])(\d+(?:\.\d+)?(?:e[+-]?\d+)?) ?um\b")


def _micrometres(text: str) -> str:
    """``"points RMS 11.5 um"`` -> ``"points RMS 11.5 µm"``: the page writes micrometres one way."""
    return _UM.sub(r"\1 µm", text)


#: Tables longer than this are folded under a summary line (every row is in the page).
_FOLD_ROWS = 40


def _facts(data: dict | None, *, caption: str = "", source: str = "", skip=(), units: Mapping | None = None) -> list:
    """Scalar entries of a JSON object as a table of entry, value and unit; every entry, folded when long.

    ``units``: units of parameter names beyond the DH and joint-model kinds (``{"J2.k": "rad/(N m)"}``)."""
    if not data:
        return []
    items = [(k, v) for k, v in _flatten(data) if not any(k == s or k.startswith(s + ".") for s in skip)]
    # parameter names are dotted themselves: "standard_uncertainty.J1.a" is one entry of a parameter
    rows = []
    for key, value in items:
        parts = key.split(".")
        if len(parts) > 2 and _name_unit(".".join(parts[-2:]), units) is not None:
            parts = [*parts[:-2], ".".join(parts[-2:])]
        label = " › ".join(part if _name_unit(part, units) else _bare(part) for part in parts)
        shown = _micrometres(value) if isinstance(value, str) else _fmt(value)
        rows.append([label, shown, _fact_unit(key, value, units)])
    if not rows:
        return []
    what = " of ".join(part for part in (caption, source) if part) or "entries"
    return [
        _Table(
            header=["entry", "value", "unit"],
            rows=rows,
            caption=caption,
            source=source,
            text_columns=frozenset({0, 1, 2}),
            fold=f"{what}: {len(rows)} entries (show)" if len(rows) > _FOLD_ROWS else "",
        )
    ]


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


def _difference(name: str, value: float, reference: float) -> float:
    """``value - reference``; for an angle (``Jn.theta``, ``alpha``, ``beta``, deg) the difference within
    (-180, 180], so that two values a turn apart (180.08 and -179.92) differ by 0.16, not 360."""
    difference = value - reference
    if name.rsplit(".", 1)[-1] in ANGLE_KINDS:
        difference = 180.0 - (180.0 - difference) % 360.0
    return difference
