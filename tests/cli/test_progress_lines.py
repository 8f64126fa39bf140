"""Progress where the output is not a terminal (issue 30): a line every few seconds instead of a Rich bar that
shows nothing until the work ends (``robotcal plan optimise kr5-demo > log`` ran 400 s without a word).

The lines are checked with a simulated clock (no test waits); CliRunner's output is not a terminal, as a file,
a pipe or a CI log is not.
"""

from __future__ import annotations

import io
import re

import pytest
from rich.console import Console
from typer.testing import CliRunner

import robotcal.cli._common as common
from robotcal.cli import app
from robotcal.cli._common import LineProgress, progress_bar

runner = CliRunner()


class FakeClock:
    """A clock that moves only when told to [s]."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def _console() -> tuple[Console, io.StringIO]:
    stream = io.StringIO()
    return Console(file=stream, width=80, markup=False), stream


def test_a_line_at_least_every_interval_of_the_clock():
    console, stream = _console()
    clock = FakeClock()
    printed_at = []
    with LineProgress("plan search", "generations", console=console, interval_s=5.0, clock=clock) as display:
        task = display.add_task("search", total=60)
        for generation in range(1, 61):  # 1.5 s per generation: 90 s in all
            clock.now += 1.5
            before = display.lines
            display.update(task, completed=generation)
            if display.lines > before:
                printed_at.append(clock.now - 1000.0)
    lines = stream.getvalue().splitlines()
    assert len(lines) == len(printed_at) + 1  # and the last line, at the end
    gaps = [later - earlier for earlier, later in zip([0.0, *printed_at], [*printed_at, 90.0], strict=True)]
    assert max(gaps) <= 5.0 + 1.5, gaps  # never longer than the interval and the time between two updates
    assert min(gaps[:-1]) >= 5.0, gaps  # nor more often than every 5 s
    assert lines[0] == "plan search: 4 of 60 generations after 6 s"
    assert lines[-1] == "plan search: 60 of 60 generations after 90 s (done)"


def test_a_short_task_prints_nothing_and_an_unknown_total_its_count():
    console, stream = _console()
    clock = FakeClock()
    with LineProgress("Monte Carlo", "draws", console=console, interval_s=5.0, clock=clock) as display:
        task = display.add_task("draws", total=None)
        clock.now += 1.0
        display.update(task, completed=500)
    assert stream.getvalue() == ""
    with LineProgress("Monte Carlo", "draws", console=console, interval_s=5.0, clock=clock) as display:
        task = display.add_task("draws", total=None)
        clock.now += 6.0
        display.update(task, completed=2500, total=None)
    assert stream.getvalue().splitlines() == ["Monte Carlo: 2,500 draws after 6 s", "Monte Carlo: 2,500 draws after 6 s (done)"]


def test_no_last_line_after_an_error():
    console, stream = _console()
    clock = FakeClock()
    with pytest.raises(KeyboardInterrupt):
        with LineProgress("Monte Carlo", "draws", console=console, interval_s=5.0, clock=clock) as display:
            task = display.add_task("draws", total=100)
            clock.now += 6.0
            display.update(task, completed=10)
            raise KeyboardInterrupt
    assert stream.getvalue().splitlines() == ["Monte Carlo: 10 of 100 draws after 6 s"]


def test_progress_bar_is_lines_off_a_terminal_and_a_bar_on_one(monkeypatch):
    from rich.progress import Progress

    piped, _ = _console()
    monkeypatch.setattr(common, "console", piped, raising=False)
    assert isinstance(progress_bar("Monte Carlo", "draws"), LineProgress)
    terminal = Console(file=io.StringIO(), force_terminal=True)
    monkeypatch.setattr(common, "console", terminal, raising=False)
    assert isinstance(progress_bar("Monte Carlo", "draws"), Progress)


def test_uncertainty_piped_prints_its_progress(tmp_path, monkeypatch):
    """`robotcal uncertainty` with its output in a file: a line per block of draws at interval 0."""
    monkeypatch.setattr(common, "PROGRESS_LINE_INTERVAL_S", 0.0)
    result = runner.invoke(
        app, ["uncertainty", "thesis-laser-tracker", "-n", "200", "--workers", "1", "--out", str(tmp_path / "mc")]
    )
    assert result.exit_code == 0, result.output
    lines = [line for line in result.output.splitlines() if line.startswith("Monte Carlo:")]
    assert lines and all(re.fullmatch(r"Monte Carlo: [\d,]+ of 200 draws after \d+ s( \(done\))?", line) for line in lines)
    assert lines[-1].startswith("Monte Carlo: 200 of 200 draws") and lines[-1].endswith("(done)")


def test_plan_optimise_piped_prints_its_progress(tmp_path, monkeypatch):
    """`robotcal plan optimise` printed nothing at all until the end: a line per generation and per Monte Carlo
    block at interval 0 (every few seconds at the default interval)."""
    monkeypatch.setattr(common, "PROGRESS_LINE_INTERVAL_S", 0.0)
    result = runner.invoke(
        app,
        ["plan", "optimise", "thesis-laser-tracker", "--out", str(tmp_path / "opt"), "--generations", "2",
         "--population", "2", "--confirm-draws", "200", "--workspace-poses", "20", "--no-acceptance"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    search = [line for line in lines if line.startswith("plan search:")]
    assert [line.split(" after ")[0] for line in search] == [
        "plan search: 1 of 2 generations", "plan search: 2 of 2 generations", "plan search: 2 of 2 generations"
    ]  # fmt: skip
    confirm = [line for line in lines if line.startswith("Monte Carlo of baseline and optimised plans:")]
    assert confirm and confirm[-1].startswith("Monte Carlo of baseline and optimised plans: 400 of 400 draws")
