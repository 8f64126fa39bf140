"""Pose CSV (a trajectory): one row per pose, joint readings ``q1..qN`` in degrees.

Format::

    # comment lines start with '#'
    pose,q1,q2,q3,q4,q5,q6
    1,-45.0,-80.0,100.0,0.0,70.0,-90.0
    ...

The header must name ``q1`` .. ``qN`` (N = the robot's joint count); other columns (a name, a time
stamp) are allowed and ignored. A ``pose`` column names the rows: messages and the files robotcal
writes from them (``compensate``, ``predict``) use those names, never row counts; without it the rows
are named 1, 2, 3... Readings are controller readings, mapped to model
joint variables by the robot file's ``reading_sign`` and ``reading_offset``. A reading beyond
:data:`MAX_READING_DEG` is refused as no joint's reading (a unit or export error). Built-in
trajectories live in ``robotcal/data/trajectories/<name>.csv``.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from robotcal.errors import InputError
from robotcal.io.atomic import atomic_write_text
from robotcal.io.schema._validation import csv_rows, parse_finite, read_text_file
from robotcal.io.schema.builtins import data_path

__all__ = [
    "MAX_READING_DEG",
    "CARTESIAN_COLUMNS",
    "pose_labels",
    "read_pose_targets",
    "read_trajectory",
    "write_trajectory",
    "trajectory_to_csv",
    "load_trajectory",
    "builtin_trajectories",
]

#: Largest joint reading a pose CSV may hold [deg] (2,778 turns): far beyond any joint's travel, and
#: the largest magnitude whose double still resolves the 1e-9 deg a pose CSV and robotcal's outputs
#: write (its spacing is 1.2e-10 deg at 1e6 deg; at 1e308 deg it is 2e292 deg, so the pose has no meaning).
MAX_READING_DEG = 1e6


def builtin_trajectories() -> list[str]:
    """Names of the built-in trajectories (file stems of ``data/trajectories/*.csv``), sorted."""
    return sorted(p.stem for p in data_path("trajectories").glob("*.csv"))


def trajectory_to_csv(readings_rad, *, comment: str = "", labels=None, columns=None) -> str:
    """CSV text ``pose,q1..qN`` (readings in degrees, 9 decimals) of readings ``(n_poses, n_joints)`` [rad].

    ``labels``: the ``pose`` cells (default 1, 2, 3...). ``columns``: more columns after ``qN``, a mapping of name
    to one value per row (floats written with 9 significant digits, NaN and None as empty cells, text as it is). A
    NaN reading is written as an empty cell: a row without a command.
    """
    readings = np.asarray(readings_rad, dtype=float)
    if readings.ndim != 2:
        raise InputError(f"`readings` must have shape (n_poses, n_joints); got {readings.shape}")
    labels = [str(k) for k in range(1, len(readings) + 1)] if labels is None else [str(label) for label in labels]
    columns = dict(columns or {})
    if len(labels) != len(readings) or any(len(values) != len(readings) for values in columns.values()):
        raise InputError(f"pose CSV: {len(readings)} rows but {len(labels)} labels or a column of another length")
    stream = io.StringIO()
    for line in comment.splitlines():
        stream.write(f"# {line}\n" if line else "#\n")
    writer = csv.writer(stream, lineterminator="\n")
    writer.writerow(["pose", *[f"q{i + 1}" for i in range(readings.shape[1])], *columns])
    for k, row in enumerate(np.rad2deg(readings)):
        extra = [_cell(values[k]) for values in columns.values()]
        writer.writerow([labels[k], *["" if np.isnan(value) else f"{value:.9f}" for value in row], *extra])
    return stream.getvalue()


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, str | np.str_):
        return str(value)
    value = float(value)
    return "" if np.isnan(value) else f"{value:.9g}"


def write_trajectory(path, readings_rad, *, comment: str = "", labels=None, columns=None) -> Path:
    """Write a pose CSV atomically (see :func:`trajectory_to_csv`)."""
    return atomic_write_text(path, trajectory_to_csv(readings_rad, comment=comment, labels=labels, columns=columns))


def _label(header: list[str], row: list[str], k: int) -> str:
    """The user's name of data row ``k`` (0-based): its ``pose`` cell, else its 1-based number."""
    if "pose" in header and header.index("pose") < len(row):
        cell = row[header.index("pose")].strip()
        if cell:
            return cell
    return str(k + 1)


def pose_labels(path) -> list[str]:
    """The names of a pose CSV's rows: the ``pose`` column (an empty cell: the row's number), else 1, 2, 3..."""
    path = Path(path)
    _, header, rows = _rows(path, "pose CSV")
    return [_label(header, row, k) for k, (_, row) in enumerate(rows)]


def _rows(path: Path, kind: str) -> tuple[int, list[str], list[tuple[int, list[str]]]]:
    """The header line number, the lower-cased header and the data rows ``(line, cells)`` of a CSV; comment and
    blank lines skipped, a row with another field count than the header refused."""
    text = read_text_file(path, kind=kind)
    lines = [
        (number, row)
        for number, row in csv_rows(text, path)
        if any(cell.strip() for cell in row) and not row[0].lstrip().startswith("#")
    ]
    if not lines:
        raise InputError(f"{path}: empty file; expected a header with q1..qN (joint readings in deg)")
    header_line, header_row = lines[0]
    header = [cell.strip().lower() for cell in header_row]
    if len(set(header)) != len(header):
        raise InputError(f"{path}: line {header_line}: duplicate column names in the header")
    for k, (number, row) in enumerate(lines[1:]):
        if len(row) != len(header):
            raise InputError(
                f"{path}: line {number} (pose {_label(header, row, k)}) has {len(row)} fields; the header has "
                f"{len(header)}"
            )
    if len(lines) == 1:
        raise InputError(f"{path}: no poses after the header")
    return header_line, header, lines[1:]


def _joint_columns(header: list[str]) -> list[str]:
    return sorted(
        (c for c in header if c.startswith("q") and c[1:].isascii() and c[1:].isdigit() and len(c) < 8),
        key=lambda c: int(c[1:]),
    )


def _readings(path: Path, header_line: int, header: list[str], rows, n_joints: int | None) -> np.ndarray:
    joints = _joint_columns(header)
    count = len(joints)
    expected = [f"q{i + 1}" for i in range(count)]
    if count == 0 or joints != expected:
        missing = [c for c in expected if c not in joints] or ["q1"]
        raise InputError(
            f"{path}: line {header_line}: header needs joint columns q1..qN; missing {', '.join(missing)} "
            f"(got {','.join(header)})"
        )
    if n_joints is not None and count != n_joints:
        raise InputError(f"{path}: {count} joint columns (q1..q{count}) but the robot has {n_joints} joints")
    index = [header.index(c) for c in expected]
    readings = np.empty((len(rows), count))
    for k, (number, row) in enumerate(rows):
        for column, position in enumerate(index):
            where = f"{path}: line {number} (pose {_label(header, row, k)}), column `{expected[column]}`"
            readings[k, column] = parse_finite(row[position], where)
            if abs(readings[k, column]) > MAX_READING_DEG:
                raise InputError(
                    f"{where}: {row[position].strip()} deg is no joint reading (|q| must be <= {MAX_READING_DEG:g} deg, "
                    f"{MAX_READING_DEG / 360.0:,.0f} turns); is the column in another unit?"
                )
    return np.deg2rad(readings)


def read_trajectory(path, *, n_joints: int | None = None) -> np.ndarray:
    """Read a pose CSV; returns controller readings ``(n_poses, n_joints)`` [rad].

    Every problem is an :class:`InputError` naming the file, the line (1-based, as an editor shows
    it) and the column: missing ``q`` columns, a joint count other than ``n_joints``, a row with
    the wrong number of fields, a value that is not a finite number (NaN, empty, text) or beyond
    :data:`MAX_READING_DEG`.
    """
    path = Path(path)
    return _readings(path, *_rows(path, "pose CSV"), n_joints)


#: The columns of a Cartesian target: position [mm] and KUKA angles ``R = Rz(A) Ry(B) Rx(C)`` [deg] (what
#: ``robotcal predict`` writes).
CARTESIAN_COLUMNS = ("x", "y", "z", "a", "b", "c")


def read_pose_targets(path, *, n_joints: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Targets for ``robotcal compensate``: a pose CSV of joint targets (``pose,q1..qN`` [deg]) or of Cartesian
    targets (``pose,x,y,z,A,B,C`` [mm, deg KUKA], as ``robotcal predict`` writes them, optionally with ``q1..qN``
    seeds).

    Returns ``(cartesian (n_poses, 6) [mm, rad] or None, readings (n_poses, n_joints) [rad] or None)``: joint
    targets give only readings; Cartesian targets give both when the file has seeds. Errors name the file, the
    line and the column.
    """
    path = Path(path)
    header_line, header, rows = _rows(path, "pose CSV")
    present = [c for c in CARTESIAN_COLUMNS if c in header]
    has_joints = bool(_joint_columns(header))
    if not present:
        return None, _readings(path, header_line, header, rows, n_joints)
    if len(present) != 6:
        missing = [c.upper() if c in "abc" else c for c in CARTESIAN_COLUMNS if c not in header]
        raise InputError(f"{path}: line {header_line}: a Cartesian target needs x,y,z,A,B,C; missing {','.join(missing)}")
    cartesian = np.empty((len(rows), 6))
    for k, (number, row) in enumerate(rows):
        for column, name in enumerate(CARTESIAN_COLUMNS):
            where = f"{path}: line {number} (pose {_label(header, row, k)}), column `{name if column < 3 else name.upper()}`"
            cartesian[k, column] = parse_finite(row[header.index(name)], where)
    cartesian[:, 3:] = np.deg2rad(cartesian[:, 3:])
    seeds = _readings(path, header_line, header, rows, n_joints) if has_joints else None
    return cartesian, seeds


def load_trajectory(name_or_path, *, n_joints: int | None = None) -> tuple[np.ndarray, str]:
    """Readings [rad] of a built-in trajectory (by name) or a pose CSV (by path), and its source path."""
    text = str(name_or_path)
    if text in builtin_trajectories():
        path = data_path("trajectories", f"{text}.csv")
    else:
        path = Path(text)
        if not path.exists():
            raise InputError(
                f"unknown trajectory {text!r}: not a built-in trajectory "
                f"({', '.join(builtin_trajectories())}) nor an existing file"
            )
    return read_trajectory(path, n_joints=n_joints), str(path)
