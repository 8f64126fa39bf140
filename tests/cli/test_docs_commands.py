"""Every ``robotcal COMMAND ... --option`` the docs and the README show names an option the command has
(issue 24: docs/cli.md showed ``import --log``; the option is ``--joints``).

Looked up in the CLI itself (the Click commands behind ``robotcal``), in inline code and in the lines of
code blocks that run ``robotcal``.
"""

from __future__ import annotations

import re
from pathlib import Path

import click
import pytest
import typer

from robotcal.cli import app

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]


def _command(words: list[str]):
    """The Click command named by the leading words (``plan check`` -> the ``check`` subcommand)."""
    command = typer.main.get_command(app)
    context = click.Context(command)
    for word in words:
        if not hasattr(command, "list_commands"):
            break
        sub = command.get_command(context, word)
        if sub is None:
            return None
        command = sub
    return None if hasattr(command, "list_commands") else command


def _invocations(text: str):
    """``(line, invocation)`` of every ``robotcal ...`` in inline code and in code-block lines."""
    in_block = False
    for number, line in enumerate(text.splitlines(), start=1):
        if line.lstrip().startswith("```"):
            in_block = not in_block
            continue
        if in_block:
            code = line.split("#", 1)[0]
            for part in re.split(r"&&|\|(?!\|)|;", code):
                part = part.strip().removeprefix("$ ").strip()
                if part.startswith("robotcal "):
                    yield number, part
        else:
            for match in re.finditer(r"`(robotcal [^`]+)`", line):
                yield number, match.group(1).replace("\\|", "|")


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_documented_options_exist(path):
    wrong = []
    for number, invocation in _invocations(path.read_text(encoding="utf-8")):
        words = invocation.split()[1:]
        names = [w for w in words[:2] if re.fullmatch(r"[a-z][a-z0-9-]*", w)]
        command = _command(names)
        if command is None:
            continue
        known = {option for param in command.params for option in (*param.opts, *param.secondary_opts)}
        for option in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", invocation):
            if option not in known and option != "--help":
                wrong.append(f"{path.name}:{number}: `{invocation}`: {option} is no option of `robotcal {command.name}`")
    assert wrong == [], "\n".join(wrong)
