"""How the pipeline's stages draw their figures: now, or in the background (docs/pipeline.md, "Figures").

A stage draws a figure through ``render(function, *args, **kwargs)``, ``function`` being a plot function of
:mod:`robotcal.plots` named ``"robotcal.plots.module:function"`` (so that naming it imports no
matplotlib here). :func:`draw_now` calls it at once and returns its value (the paths written); a
:class:`~robotcal.plots.background.FigureRenderer`'s ``submit`` returns a job whose result is that value,
drawn by a worker process while the run goes on. :func:`figure_paths` turns either into the paths written,
waiting for a job if need be, so a stage's code is the same both ways.

The figures are written into the stage's final folder, after its data files have appeared there
(:func:`robotcal.io.atomic.atomic_directory`), each atomically (temp file + rename). A run waits for every
figure before its report (which embeds them).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from importlib import import_module
from pathlib import Path
from typing import Any

__all__ = ["FIGURE_MODULES", "Render", "draw_now", "figure_paths"]

#: Plot modules a run's figure worker imports as soon as it starts (matplotlib with them).
FIGURE_MODULES = (
    "robotcal.plots.refine",
    "robotcal.plots.joints",
    "robotcal.plots.montecarlo",
    "robotcal.plots.tcp",
    "robotcal.plots.iso9283",
    "robotcal.plots.planning",
)

#: ``render(function, *args, **kwargs)``: draw now and return the value, or submit and return a Future of it.
Render = Callable[..., Any]


def _function(function: Callable | str) -> Callable:
    if not isinstance(function, str):
        return function
    module, _, name = function.partition(":")
    return getattr(import_module(module), name)


def draw_now(function: Callable | str, /, *args, **kwargs) -> Any:
    """Call the plot function (or ``"package.module:function"``) here and now; returns its value."""
    return _function(function)(*args, **kwargs)


def figure_paths(drawn: Any) -> list[Path]:
    """The paths a plot call wrote: its value (a path or a list of paths), or a Future's, once done."""
    value = drawn.result() if isinstance(drawn, Future) else drawn
    if value is None:
        return []
    if isinstance(value, (str, Path)):
        return [Path(value)]
    return [Path(path) for path in value]
