"""``robotcal report DIR [--out FILE]``: rebuild the HTML report of a run folder from its files."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import Force, _line, app_command, command_app, console, error_console
from robotcal.errors import InputError

app = command_app()

#: Help of ``--out``: the report's name is :data:`robotcal.io.results.run_folder.REPORT_NAME` (a module that loads numpy,
#: so not imported for the help; tests/cli/test_lazy_cli.py checks the two agree).
OUT_HELP = "HTML file to write [default: DIR/report.html]."


def _run_files(run_dir: Path) -> list[Path]:
    """Every file the report may read (the inputs no ``--out`` may replace): the run folder's files and
    the targets of its links, except the folder's own ``report.html``."""
    from robotcal.io.results.run_folder import REPORT_NAME

    if not run_dir.is_dir():
        return []
    own = run_dir / REPORT_NAME
    return [path for path in run_dir.rglob("*") if path.is_file() and path != own]


@app_command(app)
def report(
    run_dir: Annotated[Path, typer.Argument(help="Run folder written by `robotcal run` (docs/results.md).")],
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help=OUT_HELP)
    ] = None,
    force: Force = False,
) -> None:
    """Build the self-contained HTML calibration report of a run folder, from the saved results only."""
    from robotcal.io.results.output import result_file
    from robotcal.report.html import REPORT_NAME, build_report

    started = time.perf_counter()
    if not run_dir.exists():
        raise InputError(f"{run_dir}: run folder not found")  # before the lock makes the folder
    target = out if out is not None else run_dir / REPORT_NAME
    with result_file(target, inputs=_run_files(run_dir), force=force):
        result = build_report(run_dir, out)
    for problem in result.problems:
        error_console.print(_line("warning:", "yellow", problem), highlight=False)
    missing = [s.title for s in result.sections if not s.present]
    size_kib = len(result.html.encode("utf-8")) / 1024
    console.print(
        f"wrote {result.path}: {len(result.sections) - len(missing)} of {len(result.sections)} sections with "
        f"results, {result.figures} figures, {result.canvases} 3-D view(s), {size_kib:.0f} KiB, "
        f"in {time.perf_counter() - started:.2f} s",
        highlight=False,
        soft_wrap=True,
    )
    if missing:
        console.print(f"not in this run: {', '.join(missing)}", highlight=False, soft_wrap=True)
