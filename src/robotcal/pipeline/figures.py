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

from collections.abc import Callable
from concurrent.futures import Executor, Future
from importlib import import_module
from pathlib import Path
from typing import Any

from robotcal.execution import check_stop, process_pool

__all__ = ["FigureJobs", "draw_figure", "draw_histograms"]


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


def draw_histograms(
    result, folder: Path, *, workers: int, plot: Callable, write_files: Callable[[], Any] | None = None
) -> list[Path]:
    """A Monte Carlo's histograms, ``plot(result, folder, joints=...)`` (:func:`robotcal.plots.montecarlo.write_histograms`),
    drawn by ``workers`` processes at once, a share of the joints each, while this process runs ``write_files()``
    (the folder's data files); with one worker, here after ``write_files()``. The figures are those of one call.

    The pool is forked after the draws, so its workers inherit the modules the caller imported (matplotlib, with
    the plot module); each receives the result once. Returns the paths written, in joint order.
    """
    joints = [joint for joint in range(result.robot.n_joints) if result.identified[joint].any()]
    count = max(1, min(workers, len(joints)))
    if count == 1:
        if write_files is not None:
            write_files()
        return [Path(path) for path in plot(result, folder)]
    with process_pool(count) as pool:
        jobs = [pool.submit(plot, result, folder, joints=joints[share::count]) for share in range(count)]
        if write_files is not None:
            write_files()
        written = [Path(path) for job in jobs for path in job.result()]
        check_stop()
    return sorted(written, key=lambda path: int(path.stem.rpartition("J")[2]))
