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


CLI_DOC = ROOT / "docs" / "cli.md"


def _command_sections() -> dict[str, str]:
    """``{command: its section}`` of docs/cli.md, for the sections headed ``## `robotcal COMMAND```."""
    text = CLI_DOC.read_text(encoding="utf-8")
    found = re.finditer(r"^## `robotcal ([a-z0-9 -]+)`\n(.*?)(?=^## )", text, re.S | re.M)
    return {match.group(1): match.group(2) for match in found}


@pytest.mark.parametrize("name", sorted(_command_sections()))
def test_every_option_is_in_its_commands_table(name):
    """Issue 30: `--weights none` was missing from refine's table. Where a command's section has an options
    table, every option of the command is in it (``--force`` is in "Output safety", for every command)."""
    rows = "\n".join(line for line in _command_sections()[name].splitlines() if line.startswith("| `"))
    command = _command(name.split())
    options = [p.opts[0] for p in command.params if p.param_type_name == "option" and p.opts[0] != "--force"]
    if not rows:
        pytest.skip(f"{name}: no options table (the options are described in its text)")
    listed = {match for match in re.findall(r"^\| `([^`]+)`", rows, re.M)}
    named = {word for cell in listed for word in re.split(r"[\s,/=\\|]+", cell) if word.startswith("-")}
    missing = [option for option in options if option not in named]
    assert missing == [], f"docs/cli.md, robotcal {name}: options not in the table: {', '.join(missing)}"


def test_joint_model_doc_quotes_the_demos_draws():
    """Issue 30: docs/joint-model.md gave the consistency check of a 1,000-draw run; the demo's refined Monte
    Carlo (whose draws tcp/consistency.json uses) has the scenario's refined_iterations."""
    from robotcal.io import load_scenario

    draws = load_scenario("kr5-demo").montecarlo.refined_iterations
    text = " ".join((ROOT / "docs" / "joint-model.md").read_text(encoding="utf-8").split())
    consistency = text.split("The demo's consistency check", 1)[1].split(". ", 1)[0]
    assert f"{draws:,} draws" in consistency, consistency
