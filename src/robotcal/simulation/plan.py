"""Capture plans: which joint readings the robot visits, circle after circle (thesis 5.2.1, 4.5.3).

Two ways to say where circles start, both in controller readings:

- ``start`` of shape ``(n_joints,)`` (the thesis generator, Table 5.1): circle i turns joint i from
  ``start_i`` to ``start_i + sweep_i`` inclusive in ``points_i`` equal steps; afterwards joint i rests
  where its circle ended while the later joints turn (docs/conventions.md).
- ``start`` of shape ``(n_joints, n_joints)`` (real tests, Table 4.2): row i is the full configuration
  from which circle i starts; joint i then turns from ``start[i, i]`` by ``sweep_i``.

A bidirectional plan goes back over the same angles after each forward sweep.

Coupled readings (a Fanuc-style J3 reading that follows J2, ``RobotModel.reading_coupling``): the plan's
``start`` and ``sweep`` stay in controller readings, the language of the robot program, and a circle of
joint i turns **model joint i alone**, as CPA needs (docs/conventions.md). Reading i then sweeps from
its start by ``sweep_i``, and the readings of the joints coupled to joint i follow, so that their model
variables rest: these are the readings the robot program must command. :meth:`CapturePlan.readings`
does this when given the robot; for an uncoupled robot (or without a robot) reading i changes alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotcal.errors import InputError
from robotcal.kinematics.model import ReflectorMount, RobotModel

__all__ = ["CapturePlan"]


@dataclass(frozen=True, slots=True, kw_only=True)
class CapturePlan:
    """A Circle Point capture plan.

    Attributes
    ----------
    start : ndarray, shape (n_joints,) or (n_joints, n_joints)
        Readings where the circles start [rad] (see module docstring).
    sweep : ndarray, shape (n_joints,)
        Signed angle each joint turns in its circle [rad], non-zero.
    points : ndarray of int, shape (n_joints,)
        Points per circle and direction, >= 3.
    reflector : ReflectorMount
    bidirectional : bool
    """

    start: np.ndarray
    sweep: np.ndarray
    points: np.ndarray
    reflector: ReflectorMount
    bidirectional: bool = False

    def __post_init__(self) -> None:
        start = np.asarray(self.start, dtype=float)
        sweep = np.asarray(self.sweep, dtype=float)
        points = np.asarray(self.points)
        n = sweep.shape[0] if sweep.ndim == 1 else -1
        if sweep.ndim != 1 or n < 1:
            raise InputError(f"capture plan: `sweep` must be one angle per joint; got shape {sweep.shape}")
        if start.shape not in ((n,), (n, n)):
            raise InputError(f"capture plan: `start` must have shape ({n},) or ({n}, {n}); got {start.shape}")
        if points.shape != (n,) or not np.all(points == np.round(points)):
            raise InputError(f"capture plan: `points` must be {n} whole numbers; got {points.tolist()}")
        for name, value in (("start", start), ("sweep", sweep)):
            if not np.all(np.isfinite(value)):
                raise InputError(f"capture plan: `{name}` contains NaN or infinite values")
        small = np.flatnonzero(points < 3)
        if small.size:
            raise InputError(
                f"capture plan: circle {small[0] + 1} has {int(points[small[0]])} points; a circle needs at least 3"
            )
        zero = np.flatnonzero(sweep == 0.0)
        if zero.size:
            raise InputError(f"capture plan: circle {zero[0] + 1} has a zero sweep; joint J{zero[0] + 1} must turn")
        if self.reflector.frame == "joint" and self.reflector.positions.shape[0] != n:
            raise InputError(f"capture plan: {self.reflector.positions.shape[0]} reflector positions for {n} circles")
        for name, value in (("start", start), ("sweep", sweep), ("points", points.astype(int))):
            value = np.array(value)
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def n_joints(self) -> int:
        return self.sweep.shape[0]

    def readings(self, robot: RobotModel | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The visited readings, point by point.

        Parameters
        ----------
        robot : RobotModel, optional
            The robot the readings are for. Needed when its readings are coupled
            (:attr:`RobotModel.is_coupled`): circle i then turns model joint i alone, reading i
            sweeping from its start by ``sweep_i`` and every reading k coupled to joint i following
            by ``M[k, i] / M[i, i]`` times reading i's step (``M`` = :attr:`RobotModel.reading_matrix`),
            i.e. ``readings_from_model`` of the swept model variables. Without a robot, or for an
            uncoupled one, reading i changes alone (the same numbers bit for bit).

        Returns
        -------
        circle : ndarray of int, shape (n_points,)
            1-based joint turned.
        direction : ndarray of int, shape (n_points,)
            +1 forward, -1 on the return sweep.
        readings : ndarray, shape (n_points, n_joints)
            Controller readings [rad].
        """
        n = self.n_joints
        follow = None  # column i: how every reading moves per unit of reading i when model joint i turns alone
        if robot is not None:
            if robot.n_joints != n:
                raise InputError(f"capture plan has {n} circles but robot {robot.name!r} has {robot.n_joints} joints")
            if robot.is_coupled:
                matrix = robot.reading_matrix
                follow = matrix / np.diag(matrix)[None, :]
        current = self.start.copy() if self.start.ndim == 1 else None
        circles, directions, rows = [], [], []
        for i in range(n):
            base = current.copy() if current is not None else self.start[i].copy()
            steps = np.linspace(0.0, self.sweep[i], int(self.points[i]))
            sweeps = [(steps, 1)] + ([(steps[::-1], -1)] if self.bidirectional else [])
            for offsets, direction in sweeps:
                if follow is None:
                    block = np.tile(base, (offsets.size, 1))
                    block[:, i] = base[i] + offsets
                else:  # follow[i, i] == 1: reading i is exactly base[i] + offset, as uncoupled
                    block = base + offsets[:, None] * follow[:, i]
                rows.append(block)
                circles.append(np.full(offsets.size, i + 1))
                directions.append(np.full(offsets.size, direction))
            if current is not None:  # the next circles start where this one ended (coupled readings included)
                current = rows[-1][-1].copy()
        return np.concatenate(circles), np.concatenate(directions), np.concatenate(rows)
