"""Row-wise vector helpers over the last axis, shared by the geometry and identification code.

Written out by components: for ``(..., 3)`` stacks this avoids ``np.cross``'s axis handling and the product
array of ``np.sum(a * b, axis=-1)``, in the Monte Carlo loop (one call per draw batch).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def dot(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Dot products of ``(..., 3)`` vectors along the last axis."""
    a, b = np.asarray(a), np.asarray(b)
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def cross(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Cross products of ``(..., 3)`` vectors (broadcast) along the last axis."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def unit(v: ArrayLike) -> np.ndarray:
    """``v`` normalised along the last axis."""
    v = np.asarray(v, dtype=float)
    return v / np.sqrt(dot(v, v))[..., None]
