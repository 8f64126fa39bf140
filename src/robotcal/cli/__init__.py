"""Command-line interface (Typer): thin commands over library calls, one module per command."""

from __future__ import annotations

import typer

app = typer.Typer(
    name="robotcal",
    help="Kinematic calibration of serial robots by Circle Point Analysis, with its uncertainty.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

from robotcal.cli import catalog, demo, evaluate, identify, joints, refine, report, run, simulate, tcp, uncertainty  # noqa: E402,F401  (register commands)


def main() -> None:
    app()
