"""Row-wise vector helpers over the last axis, shared by the geometry and identification code."""

from __future__ import annotations

import numpy as np


def dot(a, b) -> np.ndarray:
    """Dot products of ``(..., 3)`` vectors along the last axis."""
    return np.sum(a * b, axis=-1)


def unit(v) -> np.ndarray:
    """``v`` normalised along the last axis."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)
