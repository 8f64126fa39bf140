"""Measuring instruments: error model U(L) = A + B*L and the noise policy (thesis 5.2.1.1, 5.2.3).

L is the instrument-to-point distance in metres; the instrument sits at the origin of the tracker
frame. In the core A is in mm and B in mm per metre; presets (in micrometres, as data sheets give
them) live in ``robotcal/data/instruments.toml`` and are loaded by :mod:`robotcal.io`.

Examples
--------
The thesis laser tracker, U(L) = 10 um + 2.5 um/m, at a point 2 m away: U = 15 um, and its
standard uncertainty per coordinate is U / sqrt(3) under the uniform policy, U / k under the normal one:

>>> import numpy as np
>>> from robotcal.instruments import Instrument
>>> tracker = Instrument(name="laser tracker", a_mm=0.010, b_mm_per_m=0.0025)
>>> point = [[0.0, 2000.0, 0.0]]
>>> round(float(tracker.error_bound(point)[0]), 12)
0.015
>>> bool(np.isclose(tracker.standard_uncertainty(point)[0], 0.015 / np.sqrt(3)))
True
>>> normal = Instrument(a_mm=0.010, b_mm_per_m=0.0025, noise="normal", coverage_factor=2.0)
>>> round(float(normal.standard_uncertainty(point)[0]), 12)
0.0075
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError

__all__ = ["Instrument", "NOISE_POLICIES"]

#: ``uniform``: each coordinate uniform in +-U (thesis 5.2.3); ``normal``: sigma = U / k (5.2.1.1 item 6).
NOISE_POLICIES = ("uniform", "normal")


@dataclass(frozen=True, slots=True, kw_only=True)
class Instrument:
    """Coordinate-measuring instrument with a maximum permissible error ``U(L) = A + B L``.

    Attributes
    ----------
    name : str
    a_mm : float
        Constant term A [mm].
    b_mm_per_m : float
        Distance term B [mm per metre of distance].
    noise : {"uniform", "normal"}
        ``uniform``: every coordinate gets an independent error uniform in ``[-U, U]``;
        ``normal``: independent normal errors with ``sigma = U / coverage_factor``.
    coverage_factor : float
        k of the ``normal`` policy (2: U is the 95 % half-width).
    description : str
    orientation_rad : float or None
        A 6-DoF probe's orientation error bound U [rad] (issue 29), under the same noise policy: each component of
        the rotation vector uniform in ``[-U, U]``, or normal with ``sigma = U / coverage_factor``; None: the
        instrument measures positions only.
    """

    name: str = "custom"
    a_mm: float
    b_mm_per_m: float
    noise: str = "uniform"
    coverage_factor: float = 2.0
    description: str = ""
    orientation_rad: float | None = None

    def __post_init__(self) -> None:
        for attr in ("a_mm", "b_mm_per_m", "coverage_factor"):
            value = getattr(self, attr)
            if not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise InputError(f"instrument {self.name!r}: `{attr}` must be a finite number >= 0; got {value!r}")
        if self.coverage_factor == 0:
            raise InputError(f"instrument {self.name!r}: `coverage_factor` must be > 0")
        if self.orientation_rad is not None and (
            not isinstance(self.orientation_rad, (int, float)) or not np.isfinite(self.orientation_rad)
            or self.orientation_rad < 0
        ):  # fmt: skip
            raise InputError(f"instrument {self.name!r}: `orientation_rad` must be a finite number >= 0")
        if self.noise not in NOISE_POLICIES:
            raise InputError(f"instrument {self.name!r}: `noise` must be one of {NOISE_POLICIES}; got {self.noise!r}")

    @property
    def is_noise_free(self) -> bool:
        return self.a_mm == 0.0 and self.b_mm_per_m == 0.0

    def error_bound(self, points: ArrayLike) -> np.ndarray:
        """``U(L) = A + B L`` [mm] for points ``(..., 3)`` in the tracker frame [mm]."""
        distance_m = np.linalg.norm(np.asarray(points, dtype=float), axis=-1) / 1000.0
        return self.a_mm + self.b_mm_per_m * distance_m

    def standard_uncertainty(self, points: ArrayLike) -> np.ndarray:
        """Standard uncertainty per coordinate [mm]: ``U/sqrt(3)`` (uniform) or ``U/k`` (normal)."""
        bound = self.error_bound(points)
        return bound / np.sqrt(3.0) if self.noise == "uniform" else bound / self.coverage_factor

    def sample_noise(self, points: ArrayLike, *, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Random coordinate errors ``(..., 3)`` [mm] for ``points (..., 3)``, drawn from ``rng``."""
        rng = np.random.default_rng(rng)
        points = np.asarray(points, dtype=float)
        bound = self.error_bound(points)[..., None]
        if self.noise == "uniform":
            return rng.uniform(-1.0, 1.0, size=points.shape) * bound
        return rng.standard_normal(size=points.shape) * (bound / self.coverage_factor)

    @property
    def orientation_standard_uncertainty(self) -> float | None:
        """Standard uncertainty of each rotation-vector component of a measured orientation [rad]:
        ``U/sqrt(3)`` (uniform) or ``U/k`` (normal); None for a position-only instrument."""
        if self.orientation_rad is None:
            return None
        return self.orientation_rad / (np.sqrt(3.0) if self.noise == "uniform" else self.coverage_factor)

    def sample_orientation_noise(self, count: int, *, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Random rotation vectors ``(count, 3)`` [rad] of orientation errors, drawn from ``rng``."""
        rng = np.random.default_rng(rng)
        bound = 0.0 if self.orientation_rad is None else self.orientation_rad
        if self.noise == "uniform":
            return rng.uniform(-1.0, 1.0, size=(count, 3)) * bound
        return rng.standard_normal(size=(count, 3)) * (bound / self.coverage_factor)
