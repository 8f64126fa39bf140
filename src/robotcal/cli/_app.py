"""The ``robotcal`` Typer application: the group that lists :data:`robotcal.cli.COMMANDS` and loads the one invoked.

Imported by :func:`robotcal.cli.main` after the interrupt handlers are installed (Typer and Click take a good part
of the command line's start), and by ``robotcal.cli.app`` on first use.
"""

from __future__ import annotations

from typing import Annotated

import typer
from typer.core import TyperGroup

from robotcal.cli._commands import COMMANDS, load_command

__all__ = ["LazyCommandGroup", "app"]


class LazyCommandGroup(TyperGroup):
    """The ``robotcal`` group: lists :data:`COMMANDS` without importing them; loads the one invoked."""

    def list_commands(self, ctx) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx, cmd_name: str):
        return load_command(cmd_name) if cmd_name in COMMANDS else None

    def format_commands(self, ctx, formatter) -> None:
        with formatter.section("Commands"):
            formatter.write_dl([(name, entry.help) for name, entry in COMMANDS.items()])

    def resolve_command(self, ctx, args):
        if args and args[0] not in COMMANDS and not args[0].startswith("-"):
            # "Did you mean": Typer's own suggestions look at self.commands, empty here
            from difflib import get_close_matches

            matches = get_close_matches(args[0], list(COMMANDS))
            hint = f" Did you mean {', '.join(map(repr, matches))}?" if matches else ""
            ctx.fail(f"No such command {args[0]!r}.{hint}")
        return super().resolve_command(ctx, args)


app = typer.Typer(
    name="robotcal",
    cls=LazyCommandGroup,
    help="Kinematic calibration of serial robots by Circle Point Analysis, with its uncertainty.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help texts print literally: "[validation]", "[lower, upper]", "[mm]"
)


def _print_version(asked: bool) -> None:
    if asked:
        from robotcal._version import installed_version

        typer.echo(f"robotcal {installed_version()}")
        raise typer.Exit()


@app.callback()
def _robotcal(
    version: Annotated[
        bool, typer.Option("--version", callback=_print_version, is_eager=True, help="Print the version and exit.")
    ] = False,
) -> None:
    # The options of `robotcal` itself. A callback also makes Typer build a group (LazyCommandGroup)
    # although no command is registered on this application.
    pass
