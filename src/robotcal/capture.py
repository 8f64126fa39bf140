"""The Capture: measured (or simulated) target positions with the joint readings of every point.

This is the in-memory form of the capture CSV (``circle,direction,q1..qN,x,y,z[,target][,session][,u95_mm]``,
docs/scenario.md); it is what the generator produces and what identification consumes. Readings in
radians, points in mm in the tracker frame.

Two optional columns (issue 14): ``target`` names the target each point was measured on (several
targets per pose; the names are declared in the scenario's ``[[targets]]``), and ``u95_mm`` is the
point's expanded uncertainty U(95) [mm] as the tracker reports it (k = 2, normal: the standard
uncertainty of each coordinate is U / 2).

Issue 29 adds ``session``, which names the measurement session of each point (a tracker station, a day): every
session has its own base registration, and a target declared ``per_session`` its own offset in each session; and
a 6-DoF probe's ``orientation`` (a rotation per point, probe to tracker frame) with its ``orientation_u95``.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from robotcal._arrays import frozen_array as _frozen
from robotcal.errors import InputError, RobotcalWarning

__all__ = ["Capture", "join_captures"]


@dataclass(frozen=True, slots=True, kw_only=True)
class Capture:
    """A Circle Point capture.

    Attributes
    ----------
    circle : ndarray of int, shape (n_points,)
        1-based joint turned for the point's circle (the CSV's ``circle``); 0 for a point on no
        circle (a free pose, e.g. of a validation capture; then ``direction`` is +1).
    direction : ndarray of int, shape (n_points,)
        +1 for the forward sweep, -1 for the return sweep.
    readings : ndarray, shape (n_points, n_joints)
        Controller joint readings [rad].
    points : ndarray, shape (n_points, 3)
        Target positions in the tracker frame [mm].
    source : str
        Where the capture came from (file name or ``"simulated"``), used in error messages.
    seed : int or None
        Seed of the generator that simulated it, if any.
    target : ndarray of int, shape (n_points,), or None
        Index into ``target_names`` of the target each point was measured on; None: no ``target``
        column (one target, the scenario's, for every point: the historical meaning).
    target_names : tuple of str
        Names of the targets ``target`` indexes (empty when ``target`` is None).
    u95 : ndarray, shape (n_points,), or None
        Expanded uncertainty U(95) of each point [mm] (k = 2, normal); None: not given.
    session : ndarray of int, shape (n_points,), or None
        Index into ``session_names`` of the measurement session (tracker station, day) of each point; None: no
        ``session`` column (one session: the historical meaning).
    session_names : tuple of str
        Names of the sessions ``session`` indexes, in order of first appearance (empty when ``session`` is None).
    orientation : ndarray, shape (n_points, 3, 3), or None
        A 6-DoF probe's measured orientation at each point: the rotation from the probe frame to the tracker
        frame; None: position only (the historical capture).
    orientation_u95 : ndarray, shape (n_points,), or None
        Expanded uncertainty U(95) of each orientation [rad] (k = 2, normal, per component of the rotation
        vector); None: not given (an instrument may state it).
    """

    circle: np.ndarray
    direction: np.ndarray
    readings: np.ndarray
    points: np.ndarray
    source: str = "capture"
    seed: int | None = field(default=None)
    target: np.ndarray | None = None
    target_names: tuple[str, ...] = ()
    u95: np.ndarray | None = None
    session: np.ndarray | None = None
    session_names: tuple[str, ...] = ()
    orientation: np.ndarray | None = None
    orientation_u95: np.ndarray | None = None

    def __post_init__(self) -> None:
        circle = np.asarray(self.circle)
        readings = np.asarray(self.readings, dtype=float)
        points = np.asarray(self.points, dtype=float)
        direction = np.asarray(self.direction)
        n = circle.shape[0] if circle.ndim == 1 else -1
        if (
            circle.ndim != 1
            or readings.ndim != 2
            or readings.shape[0] != n
            or points.shape != (n, 3)
            or direction.shape != (n,)
        ):
            raise InputError(
                f"{self.source}: inconsistent capture shapes: circle {circle.shape}, direction {direction.shape}, "
                f"readings {readings.shape}, points {points.shape} (expected (n,), (n,), (n, n_joints), (n, 3))"
            )
        if not np.all(circle == np.round(circle)) or np.any(circle < 0) or np.any(circle > readings.shape[1]):
            raise InputError(
                f"{self.source}: `circle` values must be joint numbers 1..{readings.shape[1]} (0: a point on no circle)"
            )
        if not np.all(np.isin(direction, (-1, 1))):
            raise InputError(f"{self.source}: `direction` values must be +1 or -1")
        for name, array in (("readings", readings), ("points", points)):
            bad = np.flatnonzero(~np.all(np.isfinite(array.reshape(n, -1)), axis=1))
            if bad.size:
                raise InputError(f"{self.source}: point {bad[0] + 1} has NaN or infinite {name}")
        for column in ("target", "session"):
            self._check_labels(column, n)
        if self.u95 is not None:
            u95 = np.asarray(self.u95, dtype=float)
            bad = np.flatnonzero(~np.isfinite(u95) | (u95 <= 0)) if u95.shape == (n,) else np.array([0])
            if u95.shape != (n,) or bad.size:
                where = f"point {bad[0] + 1}" if u95.shape == (n,) else f"shape {u95.shape}"
                raise InputError(f"{self.source}: `u95_mm` must be one finite U(95) > 0 [mm] per point ({where})")
            object.__setattr__(self, "u95", _frozen(u95))
        self._check_orientation(n)
        object.__setattr__(self, "circle", _frozen(circle, int))
        object.__setattr__(self, "direction", _frozen(direction, int))
        object.__setattr__(self, "readings", _frozen(readings))
        object.__setattr__(self, "points", _frozen(points))

    def _check_orientation(self, n: int) -> None:
        """The 6-DoF columns: one rotation matrix per point (orthonormal within 1e-6, right-handed), U(95) > 0."""
        if self.orientation is not None:
            rotations = np.asarray(self.orientation, dtype=float)
            if rotations.shape != (n, 3, 3) or not np.all(np.isfinite(rotations)):
                raise InputError(f"{self.source}: `orientation` must be one finite 3x3 rotation per point")
            gram = np.einsum("pji,pjk->pik", rotations, rotations) - np.eye(3)
            bad = np.flatnonzero((np.abs(gram).max(axis=(1, 2)) > 1e-6) | (np.linalg.det(rotations) <= 0))
            if bad.size:
                raise InputError(f"{self.source}: point {bad[0] + 1}: the orientation is not a rotation")
            object.__setattr__(self, "orientation", _frozen(rotations))
        if self.orientation_u95 is not None:
            u95 = np.asarray(self.orientation_u95, dtype=float)
            if self.orientation is None or u95.shape != (n,) or not np.all(np.isfinite(u95) & (u95 > 0)):
                raise InputError(f"{self.source}: `orientation_u95` must be one U(95) > 0 per oriented point [rad]")
            object.__setattr__(self, "orientation_u95", _frozen(u95))

    def _check_labels(self, column: str, n: int) -> None:
        """The ``target`` or ``session`` column: one whole index per point into distinct, non-empty names."""
        labels, names = getattr(self, column), tuple(str(name) for name in getattr(self, f"{column}_names"))
        if labels is None:
            if names:
                raise InputError(f"{self.source}: `{column}_names` given without `{column}`")
            return
        index = np.asarray(labels)
        if index.shape != (n,) or not np.all(index == np.round(index)):
            raise InputError(f"{self.source}: `{column}` must hold one whole {column} index per point; got {index.shape}")
        if index.size and (index.min() < 0 or index.max() >= len(names)):
            raise InputError(f"{self.source}: `{column}` indexes {len(names)} {column} names; got {index.max()}")
        if len(set(names)) != len(names) or any(not name.strip() for name in names):
            raise InputError(f"{self.source}: {column} names must be distinct and not empty; got {names}")
        object.__setattr__(self, column, _frozen(index, int))
        object.__setattr__(self, f"{column}_names", names)

    @property
    def n_points(self) -> int:
        return self.points.shape[0]

    def __repr__(self) -> str:
        circles = sorted({int(c) for c in self.circle if c > 0})
        free = int(np.sum(self.circle == 0))
        parts = [f"{self.n_points} points", f"{self.n_joints} joints"]
        if circles:
            parts.append(f"circles {','.join(map(str, circles))}")
        if free:
            parts.append(f"{free} at free poses")
        if self.target_names:
            parts.append(f"targets {', '.join(self.target_names)}")
        if self.session_names:
            parts.append(f"sessions {', '.join(self.session_names)}")
        if self.u95 is not None:
            parts.append("u95_mm")
        if self.orientation is not None:
            parts.append("orientation")
        return f"Capture({self.source!r}: {', '.join(parts)})"

    @property
    def n_joints(self) -> int:
        return self.readings.shape[1]

    @property
    def point_targets(self) -> tuple[str, ...] | None:
        """The target name of every point, or None without a ``target`` column."""
        if self.target is None:
            return None
        return tuple(self.target_names[k] for k in self.target)

    @property
    def point_sessions(self) -> tuple[str, ...] | None:
        """The session name of every point, or None without a ``session`` column."""
        if self.session is None:
            return None
        return tuple(self.session_names[k] for k in self.session)

    @property
    def session_count(self) -> int:
        """Number of measurement sessions (1 without a ``session`` column)."""
        return max(len(self.session_names), 1)

    def with_points(self, points: ArrayLike) -> Capture:
        """The same capture with other target positions (e.g. noisy copies)."""
        return replace(self, points=np.asarray(points, dtype=float))

    def with_orientation(self, orientation: ArrayLike) -> Capture:
        """The same capture with other measured orientations (e.g. noisy copies)."""
        return replace(self, orientation=np.asarray(orientation, dtype=float))

    def with_session(self, name: str) -> Capture:
        """The same capture with every point in session ``name`` (e.g. ``robotcal import --session``)."""
        return replace(self, session=np.zeros(self.n_points, dtype=int), session_names=(str(name),))

    def select(self, rows: ArrayLike) -> Capture:
        """The capture restricted to ``rows`` (indices or a bool mask), every column kept."""
        rows = np.asarray(rows)
        return Capture(
            circle=self.circle[rows],
            direction=self.direction[rows],
            readings=self.readings[rows],
            points=self.points[rows],
            source=self.source,
            seed=self.seed,
            target=None if self.target is None else self.target[rows],
            target_names=self.target_names,
            u95=None if self.u95 is None else self.u95[rows],
            session=None if self.session is None else self.session[rows],
            session_names=self.session_names,
            orientation=None if self.orientation is None else self.orientation[rows],
            orientation_u95=None if self.orientation_u95 is None else self.orientation_u95[rows],
        )


def join_captures(parts: Iterable[tuple[Capture, str | None]], *, source: str) -> Capture:
    """Captures one after the other as one capture with a ``target`` column.

    ``parts``: ``(capture, name)`` pairs; a capture with a ``target`` column keeps its own names (``name`` None),
    one without takes ``name`` for every point. ``u95_mm`` is kept only when every part has it; seeds are dropped
    (a joined capture is no one simulation's). Orientations (with their U(95)) are kept only when every part has
    them; when only some parts have them they are dropped with a :class:`~robotcal.errors.RobotcalWarning` naming
    those parts. Sessions are kept: when any part has a ``session`` column, every part must have one (a part
    without one would fall in no session).
    """
    parts = list(parts)
    if not parts:
        raise InputError("no capture to join")
    names: list[str] = []
    index = []
    for capture, name in parts:
        own = capture.point_targets if capture.target is not None else None
        if own is None:
            if not name:
                raise InputError(f"{capture.source}: no `target` column: name the target its points were measured on")
            own = (name,) * capture.n_points
        for target in own:
            if target not in names:
                names.append(target)
        index.append(np.array([names.index(target) for target in own], dtype=int))
    joints = {capture.n_joints for capture, _ in parts}
    if len(joints) != 1:
        raise InputError(f"captures of different joint counts cannot be joined: {sorted(joints)}")
    every_u95 = all(capture.u95 is not None for capture, _ in parts)
    session, session_names = _joined_sessions([capture for capture, _ in parts])
    oriented = all(capture.orientation is not None for capture, _ in parts)
    every_u = oriented and all(capture.orientation_u95 is not None for capture, _ in parts)
    dropped = [capture.source for capture, _ in parts if capture.orientation is not None]
    if dropped and not oriented:
        warnings.warn(
            f"{', '.join(dropped)}: orientations dropped: the captures joined with them measured positions only (the "
            "joined capture is positions only)",
            RobotcalWarning,
            stacklevel=2,
        )
    return Capture(
        circle=np.concatenate([capture.circle for capture, _ in parts]),
        direction=np.concatenate([capture.direction for capture, _ in parts]),
        readings=np.concatenate([capture.readings for capture, _ in parts]),
        points=np.concatenate([capture.points for capture, _ in parts]),
        source=source,
        target=np.concatenate(index),
        target_names=tuple(names),
        u95=np.concatenate([capture.u95 for capture, _ in parts]) if every_u95 else None,
        session=session,
        session_names=session_names,
        orientation=np.concatenate([capture.orientation for capture, _ in parts]) if oriented else None,
        orientation_u95=np.concatenate([capture.orientation_u95 for capture, _ in parts]) if every_u else None,
    )


def _joined_sessions(captures: Sequence[Capture]) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """The ``session`` column of captures joined one after the other (None when none has one)."""
    if all(capture.session is None for capture in captures):
        return None, ()
    without = [capture.source for capture in captures if capture.session is None]
    if without:
        raise InputError(
            f"{without[0]}: no `session` column, while other captures joined with it have one: give every capture "
            "its session (a `session` column, or `robotcal import --session NAME`)"
        )
    labels: list[str] = []
    for capture in captures:
        point_sessions = capture.point_sessions
        assert point_sessions is not None  # every capture has a session column (checked above)
        labels.extend(point_sessions)
    names = tuple(dict.fromkeys(labels))
    return np.array([names.index(name) for name in labels], dtype=int), names
