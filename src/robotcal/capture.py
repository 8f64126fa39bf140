"""The Capture: measured (or simulated) target positions with the joint readings of every point.

This is the in-memory form of the capture CSV (``circle,direction,q1..qN,x,y,z``, docs/results.md); it is
what the generator produces and what identification consumes. Readings in radians, points in mm in
the tracker frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.errors import InputError

__all__ = ["Capture"]


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
    """

    circle: np.ndarray
    direction: np.ndarray
    readings: np.ndarray
    points: np.ndarray
    source: str = "capture"
    seed: int | None = field(default=None)

    def __post_init__(self):
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
        object.__setattr__(self, "circle", _frozen(circle, int))
        object.__setattr__(self, "direction", _frozen(direction, int))
        object.__setattr__(self, "readings", _frozen(readings))
        object.__setattr__(self, "points", _frozen(points))

    @property
    def n_points(self) -> int:
        return self.points.shape[0]

    @property
    def n_joints(self) -> int:
        return self.readings.shape[1]

    def with_points(self, points) -> Capture:
        """The same capture with other target positions (e.g. noisy copies)."""
        return Capture(
            circle=self.circle,
            direction=self.direction,
            readings=self.readings,
            points=points,
            source=self.source,
            seed=self.seed,
        )
