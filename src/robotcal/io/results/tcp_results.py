"""TCP uncertainty result files: ``tcp.csv`` and ``tcp.json`` (docs/results.md).

``tcp.csv``: one row per pose and coordinate, columns ``pose, name, unit, nominal, mean,
std_uncertainty, coverage_low, coverage_high, min, max, lpu_std_uncertainty``; ``name`` is X, Y, Z
[mm] or the KUKA angles A (about Z), B (about Y), C (about X) [deg]. ``pose`` counts from 1 in the
order of the input poses.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from robotcal.io.atomic import atomic_write_text
from robotcal.io.results.uncertainty_files import CSV_COLUMNS
from robotcal.kinematics.model import DISPLAY_UNITS
from robotcal.uncertainty.statistics import IntervalKind
from robotcal.uncertainty.tcp import ORIENTATION_CONVENTION, TCP_COORDINATES, TCP_UNITS, TCPUncertainty
from robotcal.uncertainty.workspace import WorkspaceUncertainty

__all__ = [
    "TCP_CSV_COLUMNS",
    "tcp_json_text",
    "tcp_to_csv",
    "tcp_to_dict",
    "write_tcp_csv",
    "write_tcp_folder",
    "write_tcp_json",
]

#: ``tcp.csv``: the pose, the original design's columns of ``parameters.csv``, the linearised u.
TCP_CSV_COLUMNS = ("pose", *CSV_COLUMNS[:9], "lpu_std_uncertainty")
_DEG = np.array([1.0, 1.0, 1.0, *([180.0 / np.pi] * 3)])


def _file_units(values: np.ndarray) -> np.ndarray:
    """Scale the last axis (X, Y, Z, A, B, C) from mm/rad to mm/deg."""
    return np.asarray(values, dtype=float) * _DEG


def _covariance_file_units(covariance: np.ndarray) -> np.ndarray:
    return np.asarray(covariance, dtype=float) * _DEG[:, None] * _DEG[None, :]


def tcp_to_csv(result: TCPUncertainty, *, interval: IntervalKind = "symmetric") -> str:
    """The ``tcp.csv`` text (12 significant digits) of a result; ``interval`` picks the coverage interval."""
    low, high = result.summary.interval(interval)
    columns = [
        _file_units(array)
        for array in (
            result.nominal,
            result.summary.mean,
            result.summary.std_uncertainty,
            low,
            high,
            result.summary.minimum,
            result.summary.maximum,
            result.lpu_std_uncertainty,
        )
    ]
    # one %-format per row over Python floats (tolist): the text csv.writer gave for f"{value:.12g}" cells (no
    # cell needs quoting: numbers, coordinate names and units), about 5x quicker for the 6000-row workspace map
    row = "%d,%s,%s," + ",".join(["%.12g"] * len(columns)) + "\n"
    values = np.stack(columns, axis=-1).tolist()  # [pose][coordinate][column]
    lines = [",".join(TCP_CSV_COLUMNS) + "\n"]
    for pose, per_pose in enumerate(values, start=1):
        for (name, unit), cells in zip(zip(TCP_COORDINATES, TCP_UNITS, strict=True), per_pose, strict=True):
            lines.append(row % (pose, name, unit, *cells))
    return "".join(lines)


def write_tcp_csv(path, result: TCPUncertainty, *, interval: IntervalKind = "symmetric") -> Path:
    """Write ``tcp.csv`` atomically."""
    return atomic_write_text(path, tcp_to_csv(result, interval=interval))


def tcp_to_dict(
    result: TCPUncertainty,
    *,
    interval: IntervalKind = "symmetric",
    workspace: WorkspaceUncertainty | None = None,
    provenance: dict | None = None,
) -> dict:
    """Everything of a result as JSON-ready data in mm and degrees (``tcp.json``)."""
    k_squared = result.ellipsoid.gaussian_scale**2
    data = {
        "robot": result.robot_name,
        "draws": result.n_draws,
        "coverage": result.coverage,
        "interval": interval,
        "tool_mm": result.tool.tolist(),
        "units": dict(DISPLAY_UNITS),
        "coordinates": list(TCP_COORDINATES),
        "orientation": ORIENTATION_CONVENTION,
        "covariance_order": "X, Y, Z [mm], A, B, C [deg]",
        "ellipsoid": (
            f"{result.coverage:g} coverage region (x - mean)^T V^-1 (x - mean) <= k^2 of the position, "
            f"k^2 = chi2.ppf({result.coverage:g}, 3) = {k_squared:.6g} (JCGM 102 6.5.3); "
            "directions: one unit vector per semi-axis, base frame; monte_carlo_semi_axes: k_p from the "
            "draws (JCGM 102 7.7.2)"
        ),
        "poses": _pose_entries(result, interval),
    }
    if workspace is not None:
        data["workspace"] = {
            "seed": workspace.seed,
            "poses": result.n_poses,
            "percentiles": list(workspace.percentiles),
            "position_uncertainty_mm": workspace.position_uncertainty_percentiles.tolist(),
            "max_semi_axis_mm": workspace.max_semi_axis_percentiles.tolist(),
            "std_uncertainty": {
                name: (workspace.std_uncertainty_percentiles[:, k] * _DEG[k]).tolist()
                for k, name in enumerate(TCP_COORDINATES)
            },
        }
    if provenance:
        data["provenance"] = provenance
    return data


def _pose_entries(result: TCPUncertainty, interval: IntervalKind) -> list[dict]:
    """The ``poses`` of ``tcp.json``: per pose its readings, coordinates, covariances and ellipsoid."""
    low, high = result.summary.interval(interval)
    ellipsoid = result.ellipsoid
    summary = result.summary
    # every per-pose number converted to Python floats in one call per quantity (tolist), the same float64
    # products as a pose-by-pose loop: (n_poses, 6) -> nested lists indexed [pose][coordinate]
    fields = {
        "nominal": result.nominal,
        "mean": summary.mean,
        "std_uncertainty": summary.std_uncertainty,
        "coverage_low": low,
        "coverage_high": high,
        "symmetric_low": summary.symmetric_low,
        "symmetric_high": summary.symmetric_high,
        "shortest_low": summary.shortest_low,
        "shortest_high": summary.shortest_high,
        "min": summary.minimum,
        "max": summary.maximum,
        "range": result.value_range,
        "lpu_std_uncertainty": result.lpu_std_uncertainty,
    }
    columns = {name: _file_units(values).tolist() for name, values in fields.items()}
    readings_deg = np.rad2deg(result.readings).tolist()
    position_uncertainty = result.position_uncertainty.tolist()
    position_covariance = result.position_covariance.tolist()
    covariance = _covariance_file_units(result.covariance).tolist()
    lpu_covariance = _covariance_file_units(result.lpu_covariance).tolist()
    semi_axes = ellipsoid.semi_axes.tolist()
    directions = np.swapaxes(ellipsoid.directions, -1, -2).tolist()
    monte_carlo_semi_axes = ellipsoid.monte_carlo_semi_axes.tolist()
    fraction_inside = ellipsoid.fraction_inside.tolist()
    poses = []
    for p in range(result.n_poses):
        coordinates = {}
        for k, name in enumerate(TCP_COORDINATES):
            entry = {"unit": TCP_UNITS[k]}
            for field_name, column in columns.items():
                entry[field_name] = column[p][k]
            coordinates[name] = entry
        poses.append(
            {
                "pose": p + 1,
                "readings_deg": readings_deg[p],
                "coordinates": coordinates,
                "position_uncertainty_mm": position_uncertainty[p],
                "position_covariance_mm2": position_covariance[p],
                "covariance": covariance[p],
                "lpu_covariance": lpu_covariance[p],
                "ellipsoid": {
                    "semi_axes_mm": semi_axes[p],
                    "directions": directions[p],
                    "fraction_inside": _finite_or_none(fraction_inside[p]),
                    "monte_carlo_semi_axes_mm": [_finite_or_none(v) for v in monte_carlo_semi_axes[p]],
                },
            }
        )
    return poses


def _finite_or_none(value) -> float | None:
    value = float(value)
    return value if np.isfinite(value) else None


def tcp_json_text(data: dict) -> str:
    """The text of ``tcp.json`` for the dict of :func:`tcp_to_dict`: indented, one pose per line.

    The top-level keys are indented (``indent=2``) and every entry of ``poses`` is written compactly on
    its own line: the same document, and JSON's C encoder (the indenting encoder is pure Python) writes
    the 1000-pose workspace map about ten times faster. Strict JSON: a non-finite number raises
    ``ValueError``.
    """
    encoder = json.JSONEncoder(allow_nan=False)
    items = []
    for key, value in data.items():
        if key == "poses" and value:
            rendered = "[\n" + ",\n".join("    " + encoder.encode(pose) for pose in value) + "\n  ]"
        else:
            rendered = json.dumps(value, indent=2, allow_nan=False).replace("\n", "\n  ")
        items.append(f"  {json.dumps(key)}: {rendered}")
    return "{\n" + ",\n".join(items) + "\n}\n"


def write_tcp_json(path, result: TCPUncertainty, **kwargs) -> Path:
    """Write ``tcp.json`` atomically (arguments as :func:`tcp_to_dict`, text as :func:`tcp_json_text`).

    Strict JSON, like the other writers: the ellipsoid figures that can be undefined (a singular
    covariance) are written as ``null`` on purpose; any other non-finite number (e.g. in
    ``provenance``) raises ``ValueError`` rather than being written as ``NaN``.
    """
    return atomic_write_text(path, tcp_json_text(tcp_to_dict(result, **kwargs)))


def write_tcp_folder(
    folder: Path,
    result: TCPUncertainty,
    *,
    interval: IntervalKind = "symmetric",
    workspace: WorkspaceUncertainty | None = None,
    provenance: dict | None = None,
) -> dict:
    """Write ``tcp.csv`` and ``tcp.json`` into ``folder`` (an existing, normally temporary, folder); returns the
    documents by file name as :func:`robotcal.io.results.run_folder.read_run` reads them (the figures:
    :func:`robotcal.plots.tcp.write_tcp_figures`)."""
    from robotcal.io.results.run_folder import write_csv

    data = tcp_to_dict(result, interval=interval, workspace=workspace, provenance=provenance or {})
    atomic_write_text(Path(folder) / "tcp.json", tcp_json_text(data))
    return {
        "tcp.csv": write_csv(Path(folder) / "tcp.csv", tcp_to_csv(result, interval=interval)),
        # the poses of tcp_to_dict are plain JSON values already (lists of floats, str keys, None): they read
        # back equal, so only the rest goes through the round trip
        "tcp.json": {key: value if key == "poses" else json.loads(json.dumps(value)) for key, value in data.items()},
    }
