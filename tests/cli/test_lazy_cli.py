"""The lazy command line: ``robotcal --help`` lists the registry without importing any command module,
the registry and the command modules agree, and every command's own help (nested ones too) works.

Timings are not asserted here (benchmarks/bench_cli_startup.py measures them); what makes the start
fast is: which modules a ``--help`` imports.
"""

from __future__ import annotations

import ast
import importlib
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest
import typer
from typer.core import TyperGroup
from typer.testing import CliRunner

import robotcal
import robotcal.cli as cli
from robotcal.cli import COMMANDS, app, load_command

runner = CliRunner()

#: Imports that ``robotcal --help`` must not pay for.
HEAVY = ("numpy", "scipy", "matplotlib")

CLI_FOLDER = Path(cli.__file__).parent


def _command_modules() -> list[str]:
    """Every public module of ``robotcal.cli`` (``_common`` and other private helpers excluded)."""
    return sorted(info.name for info in pkgutil.iter_modules([str(CLI_FOLDER)]) if not info.name.startswith("_"))


def _defined_commands(module_name: str) -> set[str]:
    """The top-level command names that ``robotcal.cli.<module_name>.app`` defines (none without ``app``)."""
    module = importlib.import_module(f"robotcal.cli.{module_name}")
    if not isinstance(getattr(module, "app", None), typer.Typer):
        return set()
    command = typer.main.get_command(module.app)
    return set(command.commands) if isinstance(command, TyperGroup) else {command.name}


def _imported_in_subprocess(code: str) -> tuple[str, set[str]]:
    """Run ``code`` in a fresh interpreter; returns its stdout and the modules it had imported at exit."""
    script = (
        "import atexit, sys\n"
        "atexit.register(lambda: print('\\nMODULES', *sorted(sys.modules), file=sys.stderr))\n" + code
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    marker = done.stderr.rsplit("MODULES", 1)
    assert len(marker) == 2, done.stderr
    return done.stdout, set(marker[1].split())


def _heavy_or_commands(modules: set[str]) -> list[str]:
    command_modules = {f"robotcal.cli.{name}" for name in _command_modules()}
    return sorted(m for m in modules if m.split(".")[0] in HEAVY or m in command_modules)


def test_top_level_help_lists_every_registered_command_with_its_line():
    result = runner.invoke(app, ["--help"])
    assert result.exit_code == 0, result.output
    listed = result.output.split("Commands:", 1)[1]
    for name, entry in COMMANDS.items():
        assert f"  {name} " in listed, name
        # the registry's line, as write_dl may wrap it: compare without the layout's whitespace
        assert " ".join(entry.help.split()) in " ".join(listed.split()), name


def test_registry_lines_are_single_sentences_that_fit_the_listing():
    for name, entry in COMMANDS.items():
        assert entry.help.strip() and "\n" not in entry.help, name
        # 80 columns minus the indent, the longest name and the gap: one line, not wrapped
        assert len(entry.help) <= 62, (name, len(entry.help))


def test_help_imports_no_command_module_nor_numpy_scipy_matplotlib():
    stdout, modules = _imported_in_subprocess(
        "import sys\nfrom robotcal.cli import main\nsys.argv = ['robotcal', '--help']\n"
        "try:\n    main()\nexcept SystemExit as exit:\n    assert not exit.code, exit.code\n"
    )
    assert "Commands:" in stdout and "uncertainty" in stdout
    assert _heavy_or_commands(modules) == []


def test_importing_the_cli_package_is_light():
    _, modules = _imported_in_subprocess("import robotcal.cli\nimport robotcal.cli._common")
    assert _heavy_or_commands(modules) == []


def test_a_command_loads_only_its_own_module():
    stdout, modules = _imported_in_subprocess(
        "import sys\nfrom robotcal.cli import main\nsys.argv = ['robotcal', 'robots', '--help']\n"
        "try:\n    main()\nexcept SystemExit as exit:\n    assert not exit.code, exit.code\n"
    )
    assert "Usage: robotcal robots" in stdout
    loaded = {m for m in modules if m.startswith("robotcal.cli.") and not m.startswith("robotcal.cli._")}
    assert loaded == {"robotcal.cli.catalog"}


@pytest.mark.parametrize("command", ["run", "demo"])
def test_run_and_demo_help_load_neither_the_pipeline_nor_numpy(command):
    """Their options name the run's constants (seed offsets, refined draws): those live in robotcal.limits, so
    the help does not import the pipeline and the whole domain with it (0.2 s instead of 0.9 s)."""
    stdout, modules = _imported_in_subprocess(
        f"import sys\nfrom robotcal.cli import main\nsys.argv = ['robotcal', '{command}', '--help']\n"
        "try:\n    main()\nexcept SystemExit as exit:\n    assert not exit.code, exit.code\n"
    )
    assert f"Usage: robotcal {command}" in stdout
    assert not {m for m in modules if m.split(".")[0] in HEAVY or m.startswith("robotcal.pipeline")}


def _help_paths_of_registry() -> list[list[str]]:
    """Every command of the registry and the sub-commands of ``plan`` (the one command with sub-commands)."""
    return [[name] for name in COMMANDS] + [["plan", "check"], ["plan", "optimise"]]


@pytest.mark.parametrize("path", _help_paths_of_registry(), ids=" ".join)
def test_every_command_help_imports_neither_numpy_nor_the_api(path):
    """Issue 30: ``refine --help`` took 1.1-1.2 s, importing the API and all of ``robotcal.io`` to print its help.
    What a help needs (option names, defaults, help texts) loads without numpy; the command's work imports the
    rest when it runs (benchmarks/bench_cli_startup.py times the helps)."""
    stdout, modules = _imported_in_subprocess(
        f"import sys\nfrom robotcal.cli import main\nsys.argv = ['robotcal', *{path!r}, '--help']\n"
        "try:\n    main()\nexcept SystemExit as exit:\n    assert not exit.code, exit.code\n"
    )
    assert f"Usage: robotcal {' '.join(path)}" in stdout
    heavy = sorted(m for m in modules if m.split(".")[0] in HEAVY or m == "robotcal.api")
    assert heavy == [], heavy


def test_report_help_names_the_report_file():
    from robotcal.cli.report import OUT_HELP
    from robotcal.io.results.run_folder import REPORT_NAME

    assert f"DIR/{REPORT_NAME}]" in OUT_HELP


def test_version():
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0, result.output
    assert result.output.strip() == f"robotcal {robotcal.__version__}"


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_registry_entry_loads_a_command_of_its_name(name):
    command = load_command(name)
    assert command.name == name
    assert command is load_command(name)  # loaded once per process


def test_every_command_a_module_defines_is_registered_under_its_module():
    defined = {}
    for module_name in _command_modules():
        for name in _defined_commands(module_name):
            assert name not in defined, f"{name} defined by {defined.get(name)} and {module_name}"
            defined[name] = module_name
    registered = {name: entry.module for name, entry in COMMANDS.items()}
    assert defined == registered


def test_no_command_module_imports_the_top_level_app():
    for module_name in _command_modules():
        tree = ast.parse((CLI_FOLDER / f"{module_name}.py").read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module == "robotcal.cli":
                assert "app" not in {alias.name for alias in node.names}, module_name


def _help_paths(name: str, command) -> list[list[str]]:
    paths = [[name]]
    if isinstance(command, TyperGroup):
        for sub_name, sub_command in command.commands.items():
            paths += [[name, *rest] for rest in _help_paths(sub_name, sub_command)]
    return paths


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_command_and_sub_command_has_a_working_help(name):
    paths = _help_paths(name, load_command(name))
    for path in paths:
        result = runner.invoke(app, [*path, "--help"])
        assert result.exit_code == 0, (path, result.output)
        assert f"Usage: robotcal {' '.join(path)}" in result.output, (path, result.output)
    if name == "plan":
        assert ["plan", "check"] in paths and ["plan", "optimise"] in paths


def test_unknown_command_is_refused_with_a_suggestion():
    result = runner.invoke(app, ["rnu"])
    assert result.exit_code == 2
    assert "No such command 'rnu'" in result.output and "Did you mean 'run'?" in result.output


def test_a_registry_entry_naming_no_command_of_its_module_is_an_error(monkeypatch):
    monkeypatch.setitem(COMMANDS, "no-such-command", cli.CommandEntry("catalog", "Nothing."))
    load_command.cache_clear()
    try:
        with pytest.raises(LookupError, match="no command 'no-such-command'"):
            load_command("no-such-command")
    finally:
        load_command.cache_clear()
