"""The ``robotcal`` entry point ends the process without the interpreter's teardown, after every exit handler.

Each test runs :func:`robotcal.cli.main` in a fresh interpreter. An object whose ``__del__`` writes
``teardown`` to the standard output stands for the teardown: Python deletes it when it frees the
``__main__`` module, after the exit handlers, so it writes only when the teardown runs (checked by the
test where the teardown must run).
"""

from __future__ import annotations

import subprocess
import sys

import pytest

SCRIPT = """\
import atexit, os, sys

class Marker:
    def __del__(self, write=os.write):  # bound now: the teardown may have cleared the modules already
        write(1, b"teardown\\n")

marker = Marker()
{before}
import robotcal.cli as cli

command = cli.app

def app():  # the command registers a handler of its own while it runs
    atexit.register(print, "handler registered by the command", flush=True)
    command()

cli.app = app
sys.argv = ["robotcal", *{arguments!r}]
cli.main()
"""


def _main(arguments: list[str], before: str = "") -> subprocess.CompletedProcess:
    script = SCRIPT.format(before=before, arguments=arguments)
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize(
    ("arguments", "status", "output"),
    [
        (["--version"], 0, "robotcal "),  # stdout, through a pipe: flushed before the process ends
        (["no-such-command"], 2, "No such command"),  # Typer's usage error, on stderr
        (["run", "no-such-scenario", "--out", "unused"], 2, "unknown scenario"),  # robotcal's error: status 2
    ],
)
def test_the_status_and_output_are_kept_and_the_teardown_skipped(arguments, status, output):
    done = _main(arguments)
    assert done.returncode == status, done.stderr
    assert output in done.stdout + done.stderr
    assert "handler registered by the command" in done.stdout  # every exit handler ran...
    assert "teardown" not in done.stdout  # ...and then the process ended


def test_an_exit_handler_registered_before_main_keeps_the_normal_exit():
    """A handler registered before ``main`` would run after the early exit, so none is installed: that
    handler and the teardown run, with the same status."""
    done = _main(["no-such-command"], before='atexit.register(print, "early handler", flush=True)')
    assert done.returncode == 2
    assert "handler registered by the command" in done.stdout
    assert "early handler" in done.stdout and "teardown" in done.stdout


def test_a_forked_child_ends_as_before():
    """The handler acts in the process that registered it only: a child forked by the command and ending
    through the exit handlers (``sys.exit``) keeps its own status and teardown."""
    code = (
        "import os, sys\n"
        "import robotcal.cli._common as common\n"
        "assert common.end_without_teardown()\n"
        "common.record_exit_status(0)\n"
        "pid = os.fork()\n"
        "if pid == 0:\n"
        "    sys.exit(3)\n"
        "_, status = os.waitpid(pid, 0)\n"
        "print('child', os.waitstatus_to_exitcode(status), flush=True)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "child 3" in done.stdout
