"""Shared matplotlib plumbing: a headless backend, one look for every figure, atomic PNG writes."""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # never open a window; figures are files

import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from robotcal.io.atomic import atomic_write_bytes  # noqa: E402

__all__ = ["new_figure", "save_figure", "plt"]

DPI = 110


def new_figure(n_rows: int = 1, n_cols: int = 1, *, width_in: float = 6.4, height_in: float = 4.0, **kwargs):
    """A figure with an ``n_rows x n_cols`` grid of axes (``plt.subplots`` semantics, constrained layout)."""
    kwargs.setdefault("layout", "constrained")
    return plt.subplots(n_rows, n_cols, figsize=(width_in, height_in), dpi=DPI, **kwargs)


def save_figure(figure: Figure, path: str | Path) -> Path:
    """Write ``figure`` as PNG atomically (temp file + rename) and close it; returns the path."""
    path = Path(path)
    buffer = io.BytesIO()
    try:
        figure.savefig(buffer, format="png", dpi=DPI)
    finally:
        plt.close(figure)
    atomic_write_bytes(path, buffer.getvalue())
    return path
