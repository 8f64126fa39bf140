"""Capture CSV: ``circle,direction,q1..qN,x,y,z`` (docs/results.md).

One row per measured point; ``circle`` = joint turned (1-based; 0 for a free pose on no circle, such
as a validation capture), ``direction`` = +1/-1, joint
readings ``q1..qN`` in degrees, target position ``x, y, z`` in the tracker frame in mm.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.io._validation import csv_rows, parse_finite, read_text_file
from robotcal.io.atomic import atomic_write_text

__all__ = ["read_capture", "write_capture", "capture_to_csv"]


def capture_to_csv(capture: Capture) -> str:
    """The CSV text of a capture (readings in degrees and points in mm, 12 decimals)."""
    stream = io.StringIO()
    writer = csv.writer(stream, lineterminator="\n")
    n = capture.n_joints
    writer.writerow(["circle", "direction", *[f"q{i + 1}" for i in range(n)], "x", "y", "z"])
    readings_deg = np.rad2deg(capture.readings)
    for k in range(capture.n_points):
        writer.writerow(
            [int(capture.circle[k]), int(capture.direction[k])]
            + [f"{value:.12f}" for value in readings_deg[k]]
            + [f"{value:.12f}" for value in capture.points[k]]
        )
    return stream.getvalue()


def write_capture(path, capture: Capture) -> Path:
    """Write a capture CSV atomically."""
    return atomic_write_text(path, capture_to_csv(capture))


def read_capture(path, *, n_joints: int | None = None) -> Capture:
    """Read a capture CSV; every problem is an :class:`InputError` naming the file, line and column.

    Parameters
    ----------
    path : path-like
    n_joints : int, optional
        Expected number of joint columns (the robot's joint count).
    """
    path = Path(path)
    text = read_text_file(path, kind="capture CSV")
    records = [(number, row) for number, row in csv_rows(text, path) if any(cell.strip() for cell in row)]
    rows = [row for _, row in records]
    if not rows:
        raise InputError(f"{path}: empty file; expected a header `circle,direction,q1..qN,x,y,z`")
    header = [cell.strip().lower() for cell in rows[0]]
    joint_columns = sorted(
        (c for c in header if c.startswith("q") and c[1:].isascii() and c[1:].isdigit() and len(c) < 8),
        key=lambda c: int(c[1:]),
    )
    count = len(joint_columns)
    expected = ["circle", "direction", *[f"q{i + 1}" for i in range(count)], "x", "y", "z"]
    missing = [c for c in expected if c not in header]
    if count == 0:
        missing.insert(2, "q1..qN")
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}; expected header {','.join(expected)}")
    if n_joints is not None and count != n_joints:
        raise InputError(f"{path}: {count} joint columns (q1..q{count}) but the robot has {n_joints} joints")
    index = [header.index(c) for c in expected]
    data = np.empty((len(rows) - 1, len(expected)))
    lines = np.array([number for number, _ in records[1:]], dtype=int)
    for k, (line, row) in enumerate(records[1:]):
        if len(row) != len(header):
            raise InputError(f"{path}: line {line} has {len(row)} fields; the header has {len(header)}")
        for column, position in enumerate(index):
            data[k, column] = parse_finite(row[position], f"{path}: line {line}, column `{expected[column]}`")
    if data.shape[0] == 0:
        raise InputError(f"{path}: no data rows")
    circle, direction = data[:, 0], data[:, 1]
    for name, values in (("circle", circle), ("direction", direction)):
        bad = np.flatnonzero(values != np.round(values))
        if bad.size:
            raise InputError(f"{path}: line {lines[bad[0]]}, column `{name}`: must be a whole number")
    bad = np.flatnonzero((circle < 0) | (circle > count))
    if bad.size:
        raise InputError(
            f"{path}: line {lines[bad[0]]}, column `circle`: {circle[bad[0]]:g} is not a joint number 1..{count} "
            "(or 0 for a point on no circle)"
        )
    bad = np.flatnonzero(~np.isin(direction, (-1.0, 1.0)))
    if bad.size:
        raise InputError(f"{path}: line {lines[bad[0]]}, column `direction`: must be +1 or -1")
    return Capture(
        circle=circle.astype(int),
        direction=direction.astype(int),
        readings=np.deg2rad(data[:, 2 : 2 + count]),
        points=data[:, 2 + count :],
        source=str(path),
    )
