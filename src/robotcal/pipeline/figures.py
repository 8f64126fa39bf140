"""How a run draws its figures: in a process pool while the later stages compute (docs/pipeline.md, "Figures").

A stage asks for a figure with ``figures.draw("robotcal.plots.module:function", *args, **kwargs)``: the
plot function is named by a string, so that naming it imports no matplotlib in the run's process; it is
imported where the figure is drawn. :class:`FigureJobs` submits each call to a
:func:`robotcal.execution.process_pool` (or, without a pool, draws it at once) and :meth:`FigureJobs.paths`
waits for all of them. The plot functions write their files themselves, atomically, into the stage's
final folder (its data files are already there), and return the paths written.

An interrupt or an error of the run leaves the pool's ``with`` block: the figure being drawn is interrupted there
and then, and those not started are not drawn (:func:`robotcal.execution.process_pool`): a run stops at once,
whatever its figures cost.
"""

from __future__ import annotations

from concurrent.futures import Executor, Future
from importlib import import_module
from pathlib import Path
from typing import Any

from robotcal.execution import check_stop

__all__ = ["FigureJobs", "draw_figure"]


def draw_figure(function: str, /, *args, **kwargs) -> Any:
    """Call the plot function named ``"package.module:function"``; returns its value (the paths written)."""
    module, _, name = function.partition(":")
    return getattr(import_module(module), name)(*args, **kwargs)


class FigureJobs:
    """The figures of a run: drawn by ``pool`` (a :class:`concurrent.futures.Executor`) or, without one, at once."""

    def __init__(self, pool: Executor | None = None):
        self.pool = pool
        self.jobs: list[tuple[str, Any]] = []

    def draw(self, function: str, /, *args, **kwargs) -> None:
        """Draw a figure (see the module docstring); an error of a figure drawn at once is raised here."""
        if self.pool is None:
            self.jobs.append((function, draw_figure(function, *args, **kwargs)))
        else:
            self.jobs.append((function, self.pool.submit(draw_figure, function, *args, **kwargs)))

    def paths(self) -> list[Path]:
        """Wait for every figure; the paths written, in the order asked. A figure's error is raised with a
        note naming its plot function."""
        written: list[Path] = []
        for function, job in self.jobs:
            try:
                value = job.result() if isinstance(job, Future) else job
            except Exception as exc:
                exc.add_note(f"(while drawing the figure of {function})")
                raise
            check_stop()  # an interrupt whose exception was dropped while waiting
            if value is None:
                continue
            written.extend([Path(value)] if isinstance(value, str | Path) else [Path(path) for path in value])
        return written
