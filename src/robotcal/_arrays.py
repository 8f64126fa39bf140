"""Array helpers shared by every layer (numpy only)."""

from __future__ import annotations

import numpy as np

__all__ = ["frozen_array"]


def frozen_array(array, dtype=float) -> np.ndarray:
    """A read-only copy of ``array`` as ``dtype``: the arrays of frozen result dataclasses."""
    array = np.array(array, dtype=dtype)
    array.setflags(write=False)
    return array
