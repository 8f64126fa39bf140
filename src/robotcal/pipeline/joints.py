"""Joint diagnostics of a capture (thesis ch. 4.6): the computation and the files of ``joints/``.

:func:`compute_joints` runs the diagnostics and their harmonic model; :func:`joints_files` builds the
CSV texts and ``harmonics.json`` (mm, deg); :func:`write_joints_folder` writes them with the figures (:func:`write_joint_figure_files`).
``robotcal joints`` and the joints stage of a run call the same functions.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from robotcal.capture import Capture
from robotcal.diagnostics import HarmonicModel, JointDiagnostics, analyze_joints, fit_harmonics
from robotcal.pipeline.figures import Render, draw_now, figure_paths
from robotcal.pipeline.folder import write_csv, write_json
from robotcal.pipeline.result import Document
from robotcal.workflow import versions

__all__ = [
    "SUMMARY_COLUMNS",
    "backlash_csv",
    "compute_joints",
    "harmonics_document",
    "joints_files",
    "points_csv",
    "summary_csv",
    "write_joint_figure_files",
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
        "scenario": {"name": scenario.name, "source": scenario.source},
        "backlash": diagnostics.backlash,
        "match_tolerance_deg": float(np.rad2deg(diagnostics.match_tolerance)),
        "ignored_points": diagnostics.ignored_points,
        "notes": list(diagnostics.messages),
        "versions": versions(),
    }
    return document


def compute_joints(
    capture: Capture, scenario, *, order: int = 2, backlash: bool = True, match_tolerance_deg: float = 1e-3
) -> tuple[JointDiagnostics, HarmonicModel]:
    """Diagnostics (:func:`analyze_joints` with the scenario's circle fit) and their harmonic model."""
    diagnostics = analyze_joints(
        capture,
        backlash=backlash,
        match_tolerance=float(np.deg2rad(match_tolerance_deg)),
        method=scenario.identification.circle_fit,
    )
    return diagnostics, fit_harmonics(diagnostics, order=order)


def joints_files(diagnostics: JointDiagnostics, model: HarmonicModel, *, capture, scenario) -> dict:
    """The text files of ``joints/`` by name: CSV texts and the ``harmonics.json`` document (a dict)."""
    files = {"summary.csv": summary_csv(diagnostics), "points.csv": points_csv(diagnostics)}
    if diagnostics.backlash:
        files["backlash.csv"] = backlash_csv(diagnostics)
    files["harmonics.json"] = harmonics_document(model, diagnostics, capture=capture, scenario=scenario)
    return files


def write_joints_folder(
    folder: Path,
    diagnostics: JointDiagnostics,
    model: HarmonicModel,
    *,
    capture,
    scenario,
    scale: float = 500.0,
    figures: bool = True,
) -> dict[str, Document]:
    """Write the CSV files, ``harmonics.json`` and (with ``figures``) the figures into ``folder`` (an
    existing, normally temporary, folder); ``capture`` names the capture in the provenance. A run draws the
    figures later, in the background (:func:`write_joint_figure_files`).

    Returns the documents written by file name, in order (CSV -> Table, JSON -> dict, figure -> Path).
    """
    documents: dict[str, Document] = {}
    for name, content in joints_files(diagnostics, model, capture=capture, scenario=scenario).items():
        if isinstance(content, dict):
            documents[name] = write_json(folder / name, content)
        else:
            documents[name] = write_csv(folder / name, content)
    if figures:
        for path in figure_paths(write_joint_figure_files(folder, diagnostics, model, scale=scale)):
            documents[path.name] = path
    return documents


def write_joint_figure_files(
    folder: Path, diagnostics: JointDiagnostics, model: HarmonicModel, *, scale: float = 500.0, render: Render = draw_now
):
    """The backlash and eccentricity figures of ``joints/`` through ``render`` (:mod:`robotcal.pipeline.figures`);
    returns what ``render`` returned (the paths, or a job of them)."""
    return render("robotcal.plots.joints:write_joint_figures", diagnostics, Path(folder), model=model, scale=scale)
