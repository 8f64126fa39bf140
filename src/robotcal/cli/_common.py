"""Shared CLI plumbing: consoles, error, interrupt and warning display, limits, parameter tables.

User text (paths, CSV cells, robot and scenario names, exception messages) reaches the terminal
literally: both consoles are created with ``markup=False``, so square brackets are never read as Rich
markup; styled parts are built as :class:`rich.text.Text` (:func:`styled`).

Importing this module is light (``robotcal --help`` and :func:`robotcal.cli.main` import it): Rich, numpy
and the kinematics are imported where used, and ``console`` / ``error_console`` are created on first use.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any

import typer

from robotcal.cli import _silence_broken_streams, exit_interrupted
from robotcal.errors import InputError, RobotcalError, interrupt_behind, interrupt_received
from robotcal.limits import (  # noqa: F401  (re-exported: the commands import them from here)
    BYTES_PER_POSE,
    FALLBACK_MEMORY,
    SEED_BOUND,
    available_memory,
    check_memory,
    monte_carlo_bytes,
    pairs_bytes,
)

if TYPE_CHECKING:  # imported where used: `robotcal --help` and main() stay light (docs/cli.md)
    from pathlib import Path

    from rich.console import Console
    from rich.text import Text

    from robotcal.cli._tables import FittedTable
    from robotcal.kinematics.model import ParameterSet

    console: Console
    error_console: Console

#: Settings of the two consoles, created on first use (module ``__getattr__``): ``console`` for
#: results on stdout, ``error_console`` for messages on stderr (each message stays on one line).
_CONSOLES: dict[str, dict[str, Any]] = {  # the keyword arguments of each rich Console
    "console": {"markup": False},
    "error_console": {"stderr": True, "soft_wrap": True, "markup": False},
}


def __getattr__(name: str):
    """``console`` and ``error_console``, created on first use (``from robotcal.cli._common import console``)."""
    if name not in _CONSOLES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from rich.console import Console

    return globals().setdefault(name, Console(**_CONSOLES[name]))  # one console even if two threads race


def _error_console() -> Console:
    """``error_console`` (a test may have replaced it), created on first use."""
    replaced = globals().get("error_console")
    return __getattr__("error_console") if replaced is None else replaced

#: Help of every command's ``--force`` (docs/cli.md, "Output safety").
FORCE_HELP = (
    "Replace an existing output that robotcal did not write (never an input of the command, "
    "the home folder, / or the current folder)."
)
#: Help of ``--robot`` / ``--scenario`` of the commands that read a parameter JSON.
ROBOT_HELP = "Robot name or TOML of the parameters (default: the robot named in PARAMS, if built-in)."
SCENARIO_HELP = "Scenario name or TOML whose robot the parameters belong to (instead of --robot)."

# Options several commands share, declared once: a command's parameter reads ``force: Force = False``.
Force = Annotated[bool, typer.Option("--force", help=FORCE_HELP)]
ParamsRobot = Annotated[str | None, typer.Option("--robot", "-r", help=ROBOT_HELP)]
ParamsScenario = Annotated[str | None, typer.Option("--scenario", "-s", help=SCENARIO_HELP)]
# The options of the commands that write a robot program (program, iso9283-plan).
ProgramController = Annotated[
    str | None,
    typer.Option(
        "--controller",
        help="Robot file with the controller's reading signs/offsets and limits (e.g. kuka-kr5-sixx-r650-krc); "
        "default: the scenario's robot.",
    ),
]
ProgramSpeed = Annotated[float, typer.Option("--speed", help="Joint speed [% of maximum].", min=0.1, max=100.0)]
ScenarioArgument = Annotated[str, typer.Argument(help="Built-in scenario name or scenario TOML path.")]
Scheduler = Annotated[
    str | None, typer.Option(help="Dask scheduler address (default: $ROBOTCAL_SCHEDULER, else local).")
]
def command_app(**settings) -> typer.Typer:
    """A command module's Typer application, ``app = command_app()``, on which the module registers its
    command(s) (``@app.command()``); :data:`robotcal.cli.COMMANDS` names the module for each command.

    Settings shared with the ``robotcal`` group: help printed literally (no Rich markup: "[mm]" stays),
    no completion options, plain tracebacks; ``settings`` are further :class:`typer.Typer` arguments.
    """
    return typer.Typer(add_completion=False, pretty_exceptions_enable=False, rich_markup_mode=None, **settings)


def app_command(app: typer.Typer, name: str | None = None) -> Callable[[Callable], Callable]:
    """``@app_command(app)`` above a command's function: registers it on ``app`` under ``name`` (default: the
    function's name) with its errors reported by :func:`handle_errors`, as every command of ``robotcal`` is."""

    def register(function: Callable) -> Callable:
        return app.command(name)(handle_errors(function))

    return register


def read_scenario_capture(capture: Path, scenario: str, out: Path, *, force: bool, folder: bool = False):
    """What a command on one capture reads, once it has checked that ``out`` may be written (a file, or with
    ``folder`` a result folder): ``(scenario, capture, inputs)``, ``inputs`` the files read (never overwritten)."""
    from robotcal.io.formats.capture_csv import read_capture
    from robotcal.io.results.output import check_output_file, check_output_folder, existing_inputs
    from robotcal.io.schema.scenario import load_scenario

    inputs = existing_inputs(capture, scenario)
    (check_output_folder if folder else check_output_file)(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    return loaded, read_capture(capture, n_joints=loaded.robot.n_joints), inputs


def styled(text: str, style: str) -> Text:
    """``text`` (printed literally) in ``style``."""
    from rich.text import Text

    return Text(str(text), style=style)


def _line(label: str, style: str, message) -> Text:
    from rich.text import Text

    line = Text(label, style=style)
    line.append(f" {message}")
    return line


def _show_warning(message, category, filename, lineno, file=None, line=None):
    _error_console().print(_line("warning:", "yellow", message), highlight=False)


def _say(message) -> None:
    """Print ``message`` on stderr; a terminal that is gone (closed window or ssh session: EIO, a closed pipe:
    EPIPE) is not an error of the command."""
    try:
        _error_console().print(message, highlight=False)
    except (OSError, ValueError):  # ValueError: a closed stream
        pass


def _message(exc: BaseException) -> str:
    """The one-line message of an error ``handle_errors`` reports."""
    if isinstance(exc, MemoryError):
        return "out of memory; use fewer draws, poses or points (or --batch-size)"
    if isinstance(exc, OSError):  # a full disk, a folder that cannot be written: the file named, no traceback
        from robotcal.io.atomic import describe_os_error, final_path

        where = f"{final_path(exc.filename)}: " if exc.filename else ""
        return f"{where}{describe_os_error(exc)}"
    return str(exc)


def handle_errors(function):
    """Run a command: robotcal errors, an out-of-memory and an :class:`OSError` (a full disk: the path named, with
    what to do) become a one-line message and exit status 2, never a traceback; an interrupt exits 130 (Ctrl-C),
    129 (SIGHUP) or 143 (SIGTERM) after the cleanup has run (:func:`robotcal.cli.exit_interrupted`), also when the
    cleanup itself failed (a terminal closed by the SIGHUP), the interrupt surfaced as another error
    (:func:`robotcal.errors.interrupt_behind`) or an error followed a signal whose exception Python dropped
    (:func:`robotcal.errors.interrupt_received`)."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        previous = warnings.showwarning
        warnings.showwarning = _show_warning
        try:
            return function(*args, **kwargs)
        except (SystemExit, typer.Exit, typer.Abort):
            raise
        except BaseException as exc:
            interrupt = interrupt_behind(exc) or interrupt_received()
            if interrupt is not None:
                exit_interrupted(interrupt, say=lambda line: _say(styled(line, "red")))
            if not isinstance(exc, (RobotcalError, MemoryError, OSError)):
                raise  # a bug: its traceback is wanted
            _say(_line("error:", "red", _message(exc)))
            _silence_broken_streams()
            raise typer.Exit(code=2) from None
        finally:
            warnings.showwarning = previous

    return wrapper


def seed_option_check(seed: int | None, option: str = "--seed", *, headroom: int = 0) -> None:
    """Seeds are integers in ``[0, SEED_BOUND - headroom)``."""
    if seed is not None and not 0 <= seed < SEED_BOUND - headroom:
        raise InputError(f"{option} must be an integer in [0, {SEED_BOUND - headroom}); got {seed}")


def _display(kind: str, value: float) -> float:
    from robotcal.kinematics.model import ANGLE_KINDS

    return math.degrees(float(value)) if kind in ANGLE_KINDS else float(value)


def parameter_table(
    nominal: ParameterSet, identified: ParameterSet, title: str, *, reference: str = "nominal"
) -> FittedTable:
    """Reference / identified / difference per parameter, in mm and degrees (a :class:`FittedTable`: numbers and
    parameter names are never broken, whatever the console's width). ``nominal`` is the reference set, headed
    ``reference``: the nominal model for ``identify``, the start (e.g. the CPA result) for ``refine``."""
    from robotcal.cli._tables import Column, FittedTable
    from robotcal.kinematics.model import KIND_UNITS, PARAMETER_KINDS

    table = FittedTable(
        title,
        [
            Column("parameter", "name"),
            Column("unit", "name"),
            Column(reference, narrow=1),
            Column("identified"),
            Column("difference"),
        ],
    )
    difference = identified.difference(nominal)
    robot = nominal.robot
    for i in range(robot.n_joints):
        for k, kind in enumerate(PARAMETER_KINDS):
            if robot.structurally_fixed[i, k]:
                continue
            unit = KIND_UNITS[kind]
            shown: str | Text
            if identified.identified[i, k]:
                shown, diff = (
                    f"{_display(kind, identified.values[i, k]):.6f}",
                    f"{_display(kind, difference[i, k]):+.3e}",
                )
            else:
                shown, diff = styled("nominal", "dim"), ""
            table.add_row(f"J{i + 1}.{kind}", unit, f"{_display(kind, nominal.values[i, k]):.6f}", shown, diff)
    return table


def joint_model_table(joint_model, uncertainty=None) -> FittedTable:
    """The extended model's parameters with their unit and standard uncertainty (``rad/(N m)``, ``deg``)."""
    from robotcal.cli._tables import Column, FittedTable

    table = FittedTable(
        "Joint model (gravity compliance, harmonic errors)",
        [Column("parameter", "name"), Column("group", "name", narrow=1), Column("unit", "name"), Column("value"), Column("u")],
    )
    values = joint_model.to_display(joint_model.values)
    u = joint_model.to_display(uncertainty) if uncertainty is not None else [float("nan")] * joint_model.size
    for name, group, unit, value, sd, flag in zip(
        joint_model.names, joint_model.groups, joint_model.display_units, values, u, joint_model.identified, strict=True
    ):
        shown = f"{value:.4e}" if flag else styled("held at 0", "dim")
        table.add_row(name, group, unit, shown, f"{sd:.2e}" if sd == sd else "-")
    return table


def model_table(result) -> FittedTable:
    """Calibration and cross-validation RMS of the fitted model (of every candidate with ``--model auto``)."""
    from robotcal.cli._tables import Column, FittedTable

    choice = result.model_choice
    candidates = choice.candidates if choice is not None else (result.cross_validation,)
    folds = candidates[0].folds
    title = f"Model choice ({folds}-fold cross-validation by pose)" if choice else f"{folds}-fold cross-validation by pose"
    table = FittedTable(
        title,
        [Column("model", "name"), Column("unknowns"), Column("calibration RMS [mm]"), Column("CV RMS [mm]")]
        + ([Column("chosen", "name")] if choice is not None else []),  # one model, nothing chosen: no column
    )
    for candidate in candidates:
        cells = [
            candidate.model,
            str(candidate.unknowns),
            f"{candidate.calibration_rms_mm:.4f}",
            f"{candidate.cv_rms_mm:.4f}",
        ]
        if choice is not None:
            cells.append("yes" if candidate.model == choice.chosen else "")
        table.add_row(*cells)
    return table


def circle_table(result) -> FittedTable:
    """Per-circle fit residuals of a CPA result."""
    from robotcal.cli._tables import Column, FittedTable

    headers = ("circle", "points", "radius (mm)", "plane RMS (mm)", "circle RMS (mm)")
    table = FittedTable("Circle fits", [Column(header) for header in headers])
    for joint, fit in enumerate(result.circle_fits):
        table.add_row(
            str(joint + 1),
            str(fit.plane_residuals.shape[-1]),
            f"{float(fit.radius):.4f}",
            f"{float(fit.plane_rms):.2e}",
            f"{float(fit.circle_rms):.2e}",
        )
    return table


#: Style of each fit-health verdict on the console.
_VERDICT_STYLE = {"OK": "green", "NOT CHECKED": "yellow", "MODEL ERROR": "yellow", "FAILED": "bold red"}


def print_health(health) -> None:
    """The fit-health verdict (:class:`robotcal.identification.health.FitHealth`): one line, then why and what to
    do; a FAILED fit ends the command with exit status 1 (its result file was written, marked failed)."""
    from rich.text import Text

    verdict, _, rest = health.line().partition(": ")
    line = Text("fit health: ")
    line.append(verdict, style=_VERDICT_STYLE.get(verdict, ""))
    line.append(f": {rest}")
    console = __getattr__("console")
    console.print(line, highlight=False, soft_wrap=True)
    for label, items in (("why", health.problems), ("advice", health.advice), ("poorly determined", health.poorly_determined)):
        for item in items:
            console.print(f"  {label}: {item}", highlight=False, markup=False, soft_wrap=True)
    if health.failed:
        raise typer.Exit(code=1)


#: Where the output is not a terminal (a file, a pipe, a CI log): the least time between two progress lines [s].
PROGRESS_LINE_INTERVAL_S = 5.0


class LineProgress:
    """Progress as plain lines, for an output that is not a terminal (a file, a pipe, a CI log), where a Rich
    bar shows nothing until the work ends: ``title: done of total unit after N s``, at most one line per
    ``interval_s`` seconds of ``clock`` (at the updates: long work updates every few seconds), and a last
    line at the end when a line was printed (a short task prints none).

    The part of :class:`rich.progress.Progress` the commands use: a context manager with ``add_task`` and
    ``update(task, completed=..., total=...)``.
    """

    def __init__(
        self, title: str, unit: str, *, console: Console, interval_s: float = PROGRESS_LINE_INTERVAL_S,
        clock: Callable[[], float] | None = None,
    ):
        import time

        self.title, self.unit, self.console, self.interval_s = title, unit, console, interval_s
        self.clock = time.monotonic if clock is None else clock
        self.tasks: list[dict] = []
        self.lines = 0
        self._started = self._last = 0.0  # the clock's time, from __enter__

    def __enter__(self) -> LineProgress:
        self._started = self._last = self.clock()
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None and self.lines:
            for task in self.tasks:
                self._print(task, " (done)")

    def add_task(self, description: str, total: float | None = None, **fields) -> int:
        self.tasks.append({"completed": 0, "total": total})
        return len(self.tasks) - 1

    def update(self, task: int, *, completed: float | None = None, total: float | None = None, advance=None, **fields):
        entry = self.tasks[task]
        if total is not None:
            entry["total"] = total
        if completed is not None:
            entry["completed"] = completed
        if advance is not None:
            entry["completed"] += advance
        now = self.clock()
        if now - self._last >= self.interval_s:
            self._last = now
            self._print(entry)

    def _print(self, entry: dict, end: str = "") -> None:
        done, total = entry["completed"], entry["total"]
        count = f"{done:,.0f} of {total:,.0f}" if total else f"{done:,.0f}"
        elapsed = self.clock() - self._started
        self.console.print(f"{self.title}: {count} {self.unit} after {elapsed:.0f} s{end}", highlight=False, soft_wrap=True)
        self.lines += 1


def progress_bar(title: str, unit: str):
    """A transient Rich progress bar ``title [bar] done/total unit elapsed remaining``; in a narrow console
    only the bar shrinks (the title and the counts are never cut). Where the output is not a terminal (a
    file, a pipe, a CI log: a bar would show nothing), a :class:`LineProgress`: a line every few seconds."""
    console = __getattr__("console")
    if not console.is_terminal:
        return LineProgress(title, unit, console=console, interval_s=PROGRESS_LINE_INTERVAL_S)
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.table import Column

    def whole() -> Column:
        return Column(no_wrap=True)

    return Progress(
        TextColumn(title, markup=False, table_column=whole()),
        BarColumn(),
        MofNCompleteColumn(table_column=whole()),
        TextColumn(unit, markup=False, table_column=whole()),
        TimeElapsedColumn(table_column=whole()),
        TimeRemainingColumn(table_column=whole()),
        console=console,
        transient=True,
    )
