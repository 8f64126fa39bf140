"""Capture CSV: ``circle,direction,q1..qN,x,y,z[,target][,session][,u95_mm][,qw,qx,qy,qz][,u95_deg]``
(docs/scenario.md).

One row per measured point; ``circle`` = joint turned (1-based; 0 for a free pose on no circle, such
as a validation capture), ``direction`` = +1/-1, joint
readings ``q1..qN`` in degrees, target position ``x, y, z`` in the tracker frame in mm. Optional:
``target``, the name of the target measured (declared in the scenario's ``[[targets]]``; absent =
the scenario's one target), and ``u95_mm``, the point's expanded uncertainty U(95) [mm] (k = 2,
normal), ``session``, the measurement session (tracker station, day) of the point, and a 6-DoF probe's
orientation as a unit quaternion ``qw,qx,qy,qz`` (scalar first, probe to tracker frame) with its expanded
uncertainty ``u95_deg`` [deg]. A file without them loads as before.
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.io.atomic import atomic_write_text
from robotcal.io.formats.orientation import QUATERNION_COLUMNS, quaternions_from_rotations, rotations_from_quaternions
from robotcal.io.schema._validation import csv_rows, parse_finite, read_text_file

__all__ = ["capture_to_csv", "read_capture", "read_capture_text", "write_capture"]


def capture_to_csv(capture: Capture) -> str:
    """The CSV text of a capture (readings in degrees and points in mm, 12 decimals)."""
    stream = io.StringIO()
    writer = csv.writer(stream, lineterminator="\n")
    n = capture.n_joints
    extra = (
        (["target"] if capture.target is not None else [])
        + (["session"] if capture.session is not None else [])
        + (["u95_mm"] if capture.u95 is not None else [])
        + (list(QUATERNION_COLUMNS) if capture.orientation is not None else [])
        + (["u95_deg"] if capture.orientation_u95 is not None else [])
    )
    quaternions = None if capture.orientation is None else quaternions_from_rotations(capture.orientation)
    writer.writerow(["circle", "direction", *[f"q{i + 1}" for i in range(n)], "x", "y", "z", *extra])
    readings_deg = np.rad2deg(capture.readings)
    names, sessions = capture.point_targets, capture.point_sessions
    for k in range(capture.n_points):
        writer.writerow(
            [int(capture.circle[k]), int(capture.direction[k])]
            + [f"{value:.12f}" for value in readings_deg[k]]
            + [f"{value:.12f}" for value in capture.points[k]]
            + ([names[k]] if names is not None else [])
            + ([sessions[k]] if sessions is not None else [])
            + ([f"{capture.u95[k]:.12g}"] if capture.u95 is not None else [])
            + ([f"{value:.12f}" for value in quaternions[k]] if quaternions is not None else [])
            + ([f"{np.rad2deg(capture.orientation_u95[k]):.12g}"] if capture.orientation_u95 is not None else [])
        )
    return stream.getvalue()


def write_capture(path: str | os.PathLike[str], capture: Capture) -> Path:
    """Write a capture CSV atomically."""
    return atomic_write_text(path, capture_to_csv(capture))


def read_capture(path: str | os.PathLike[str], *, n_joints: int | None = None) -> Capture:
    """Read a capture CSV; every problem is an :class:`InputError` naming the file, line and column.

    Parameters
    ----------
    path : path-like
    n_joints : int, optional
        Expected number of joint columns (the robot's joint count).
    """
    path = Path(path)
    return read_capture_text(read_text_file(path, kind="capture CSV"), source=str(path), n_joints=n_joints)


def read_capture_text(text: str, *, source: str, n_joints: int | None = None, seed: int | None = None) -> Capture:
    """The capture of a capture CSV's ``text`` (:func:`read_capture`; ``source`` names it in messages and in
    the capture, ``seed`` is recorded with it)."""
    path = source
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
    target, names = _labels(header, records, lines, "target", path)
    session, session_names = _labels(header, records, lines, "session", path)
    u95 = _positive(header, records, "u95_mm", path)
    orientation, orientation_u95 = _orientation(header, records, path)
    return Capture(
        circle=circle.astype(int),
        direction=direction.astype(int),
        readings=np.deg2rad(data[:, 2 : 2 + count]),
        points=data[:, 2 + count :],
        source=str(path),
        seed=seed,
        target=target,
        target_names=names,
        u95=u95,
        session=session,
        session_names=session_names,
        orientation=orientation,
        orientation_u95=orientation_u95,
    )


def _positive(header: list[str], records: list[tuple[int, list[str]]], column: str, path: str) -> np.ndarray | None:
    """A column of numbers > 0 (``u95_mm``, ``u95_deg``); None when the header has no such column."""
    if column not in header:
        return None
    position = header.index(column)
    values = np.empty(len(records) - 1)
    for k, (line, row) in enumerate(records[1:]):
        values[k] = parse_finite(row[position], f"{path}: line {line}, column `{column}`")
        if values[k] <= 0:
            unit = column.rsplit("_", 1)[1]
            raise InputError(f"{path}: line {line}, column `{column}`: U(95) must be > 0 {unit}; got {values[k]:g}")
    return values


def _orientation(
    header: list[str], records: list[tuple[int, list[str]]], path: str
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The rotations of the ``qw,qx,qy,qz`` columns (all four or none) and their U(95) [rad] (``u95_deg``)."""
    present = [column for column in QUATERNION_COLUMNS if column in header]
    if not present:
        if "u95_deg" in header:
            raise InputError(f"{path}: column `u95_deg` without the orientation columns qw,qx,qy,qz")
        return None, None
    if len(present) != 4:
        missing = ", ".join(c for c in QUATERNION_COLUMNS if c not in present)
        raise InputError(f"{path}: the orientation needs the four columns qw,qx,qy,qz; missing {missing}")
    positions = [header.index(column) for column in QUATERNION_COLUMNS]
    quaternions = np.array(
        [[parse_finite(row[p], f"{path}: line {line}, column `{header[p]}`") for p in positions]
         for line, row in records[1:]]
    )  # fmt: skip
    rotations = rotations_from_quaternions(quaternions, source=str(path))
    u95 = _positive(header, records, "u95_deg", path)
    return rotations, None if u95 is None else np.deg2rad(u95)


def _labels(
    header: list[str], records: list[tuple[int, list[str]]], lines: np.ndarray, column: str, path: str
) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """A column of names (``target``, ``session``): the index of each row's name and the names in order of first
    appearance; ``(None, ())`` when the header has no such column."""
    if column not in header:
        return None, ()
    position = header.index(column)
    labels = [row[position].strip() for _, row in records[1:]]
    empty = [k for k, label in enumerate(labels) if not label]
    if empty:
        raise InputError(f"{path}: line {lines[empty[0]]}, column `{column}`: empty {column} name")
    names = tuple(dict.fromkeys(labels))
    lookup = {name: k for k, name in enumerate(names)}
    return np.array([lookup[label] for label in labels], dtype=int), names
