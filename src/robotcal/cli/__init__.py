"""Command-line interface (Typer): thin commands over library calls, one module per command."""

from __future__ import annotations

import typer

app = typer.Typer(
    name="robotcal",
    help="Kinematic calibration of serial robots by Circle Point Analysis, with its uncertainty.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help texts print literally: "[validation]", "[lower, upper]", "[mm]"
)

from robotcal.cli import (  # noqa: E402,F401  (register commands)
    catalog,
    demo,
    evaluate,
    export,
    identify,
    iso9283,
    joints,
    plan,
    predict,
    program,
    refine,
    report,
    run,
    sensitivity,
    simulate,
    tcp,
    uncertainty,
)


def main() -> None:
    """The ``robotcal`` entry point: SIGTERM and SIGINT become clean interrupts (exit 143 / 130)."""
    from robotcal.cli._common import install_signal_handlers

    install_signal_handlers()
    app()
