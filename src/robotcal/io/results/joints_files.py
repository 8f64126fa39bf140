"""The files of ``joints/``: joint diagnostics of a capture (thesis ch. 4.6) and their harmonic model, mm and deg.

:func:`joints_files` builds the CSV texts and ``harmonics.json``; :func:`write_joints_folder` writes them.
``robotcal joints`` and the joints stage of a run call the same functions (the figures:
:func:`robotcal.plots.joints.write_joint_figures`).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from robotcal.diagnostics import HarmonicModel, JointDiagnostics
from robotcal.errors import InputError
from robotcal.io.results.provenance import scenario_echo, versions
from robotcal.io.results.run_folder import Document, write_csv, write_json

__all__ = [
    "SUMMARY_COLUMNS",
    "backlash_csv",
    "harmonics_document",
    "joints_files",
    "points_csv",
    "read_backlash",
    "summary_csv",
    "write_joints_folder",
]

SUMMARY_COLUMNS = (
    "joint", "points", "pairs", "radius_mm", "plane_rms_mm", "circle_rms_mm", "axial_min_mm", "axial_max_mm",
    "radial_min_mm", "radial_max_mm", "backlash_max_mm", "backlash_min_mm", "backlash_mean_mm", "backlash_std_mm",
    "backlash_angle_mean_deg", "noise_sigma_um", "noise_floor_um", "backlash_exceeds_noise",
)  # fmt: skip


def _number(value: float, digits: int = 9) -> str:
    return "" if not math.isfinite(value) else f"{value:.{digits}f}"


def _csv(header, rows) -> str:
    stream = io.StringIO()
    writer = csv.writer(stream, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return stream.getvalue()


def summary_csv(diagnostics: JointDiagnostics) -> str:
    """``summary.csv``: one row per joint (Tables 4.12-4.17 plus eccentricity and fit RMS), mm/deg."""
    rows = []
    for s in diagnostics.summary():
        rows.append(
            [s.joint, s.points, s.pairs]
            + [
                _number(v)
                for v in (
                    s.radius,
                    s.plane_rms,
                    s.circle_rms,
                    s.axial_min,
                    s.axial_max,
                    s.radial_min,
                    s.radial_max,
                    s.backlash_max,
                    s.backlash_min,
                    s.backlash_mean,
                    s.backlash_std,
                )
            ]  # fmt: skip
            + [_number(float(np.rad2deg(s.backlash_angle_mean)))]
            # the instrument noise and the backlash it alone would show (docs/joints.md "Noise floor"), um
            + [_number(s.noise_sigma * 1e3, 4), _number(s.backlash_noise_floor * 1e3, 4)]
            + ["" if not math.isfinite(s.backlash_noise_floor) else int(s.backlash_exceeds_noise)]
        )
    return _csv(SUMMARY_COLUMNS, rows)


def points_csv(diagnostics: JointDiagnostics) -> str:
    """``points.csv``: per point its circle, sweep, lash state, reading and signed eccentricities."""
    rows = []
    for c in diagnostics.circles:
        for k in range(c.n_points):
            rows.append(
                [int(c.rows[k]) + 1, c.joint, int(c.direction[k]), int(c.state[k])]
                + [_number(float(np.rad2deg(c.reading[k]))), _number(float(c.axial[k])), _number(float(c.radial[k]))]
            )
    return _csv(("point", "circle", "direction", "state", "reading_deg", "axial_mm", "radial_mm"), rows)


def backlash_csv(diagnostics: JointDiagnostics) -> str:
    """``backlash.csv``: per circle and matched reading, the vector return - forward and its parts."""
    rows = []
    for c in diagnostics.circles:
        magnitude = c.backlash_magnitude
        for k in range(c.n_pairs):
            rows.append(
                [c.joint, _number(float(np.rad2deg(c.pair_reading[k]))), int(c.pair_forward[k]) + 1]
                + [int(c.pair_return[k]) + 1, int(bool(c.turnaround[k]))]
                + [_number(float(v)) for v in (*c.backlash[k], magnitude[k], *c.backlash_local[k])]
                + [_number(float(np.rad2deg(c.backlash_angle[k])))]
            )
    header = (
        "circle", "reading_deg", "forward_point", "return_point", "turnaround", "dx_mm", "dy_mm", "dz_mm",
        "magnitude_mm", "axial_mm", "radial_mm", "tangential_mm", "angle_deg",
    )  # fmt: skip
    return _csv(header, rows)


def harmonics_document(model: HarmonicModel, diagnostics: JointDiagnostics, *, capture: Path, scenario) -> dict:
    """``harmonics.json``: the model (:meth:`HarmonicModel.to_dict`) plus provenance."""
    document = model.to_dict()
    document["provenance"] = {
        "capture": str(capture),
        "scenario": scenario_echo(scenario),
        "backlash": diagnostics.backlash,
        "match_tolerance_deg": float(np.rad2deg(diagnostics.match_tolerance)),
        "ignored_points": diagnostics.ignored_points,
        "notes": list(diagnostics.messages),
        "versions": versions(),
    }
    return document


def joints_files(diagnostics: JointDiagnostics, model: HarmonicModel, *, capture, scenario) -> dict[str, Any]:
    """The text files of ``joints/`` by name: CSV texts and the ``harmonics.json`` document (a dict)."""
    files: dict[str, Any] = {"summary.csv": summary_csv(diagnostics), "points.csv": points_csv(diagnostics)}
    if diagnostics.backlash:
        files["backlash.csv"] = backlash_csv(diagnostics)
    files["harmonics.json"] = harmonics_document(model, diagnostics, capture=capture, scenario=scenario)
    return files


def write_joints_folder(
    folder: Path, diagnostics: JointDiagnostics, model: HarmonicModel, *, capture, scenario
) -> dict[str, Document]:
    """Write the CSV files and ``harmonics.json`` into ``folder`` (an existing, normally temporary, folder);
    ``capture`` names the capture in the provenance. Returns the documents by file name, in order."""
    documents: dict[str, Document] = {}
    for name, content in joints_files(diagnostics, model, capture=capture, scenario=scenario).items():
        if isinstance(content, dict):
            documents[name] = write_json(folder / name, content)
        else:
            documents[name] = write_csv(folder / name, content)
    return documents


def read_backlash(path, n_joints: int) -> np.ndarray:
    """The angular backlash [deg] per joint from a joints stage's ``summary.csv``: ``backlash_angle_mean_deg`` of the
    joints whose backlash exceeds the noise (``backlash_exceeds_noise`` 1), 0 for the others and for joints the
    capture has no circle of. Errors name the file, the line and the column."""
    from robotcal.io.schema._validation import csv_rows, parse_finite, parse_whole, read_text_file

    path = Path(path)
    rows = [row for _, row in csv_rows(read_text_file(path, kind="joints summary CSV"), path) if any(row)]
    if not rows:
        raise InputError(f"{path}: empty file; expected the joints stage's summary.csv")
    header = [cell.strip() for cell in rows[0]]
    needed = ("joint", "backlash_angle_mean_deg", "backlash_exceeds_noise")
    missing = [name for name in needed if name not in header]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}; is this a joints stage's summary.csv?")
    out = np.zeros(n_joints)
    for line, row in enumerate(rows[1:], start=2):
        cells = dict(zip(header, row, strict=False))
        joint = parse_whole(cells["joint"], f"{path}: line {line}, column `joint`")
        if not 1 <= joint <= n_joints:
            raise InputError(f"{path}: line {line}: joint {joint} of a {n_joints}-joint robot")
        if cells["backlash_exceeds_noise"].strip() in ("1", "true", "True"):
            out[joint - 1] = parse_finite(cells["backlash_angle_mean_deg"], f"{path}: line {line}, column `backlash_angle_mean_deg`")
    return out
