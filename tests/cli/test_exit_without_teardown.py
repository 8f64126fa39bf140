"""The ``robotcal`` console script (:func:`robotcal.cli.entry`) ends the process without the interpreter's
teardown, after every exit handler; a Python caller of :func:`robotcal.cli.main` keeps its normal exit.

Each test runs a script in a fresh interpreter, with ``PYTHONUNBUFFERED`` unset so that what is not flushed
stays in the buffer. An object whose ``__del__`` writes ``teardown`` to the standard output stands for the
teardown: Python deletes it when it frees the ``__main__`` module, after the exit handlers, so it writes
only when the teardown runs (checked by the tests where the teardown must run).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

PREAMBLE = """\
import atexit, os, sys
if atexit._ncallbacks():  # a sitecustomize or .pth file registered one: the early end switches itself off
    print("handlers at start", flush=True)
    raise SystemExit(0)

class Marker:
    def __del__(self, write=os.write):  # bound now: the teardown may have cleared the modules already
        write(1, b"teardown\\n")

marker = Marker()
"""

SCRIPT = (
    PREAMBLE
    + """{before}
import robotcal.cli as cli

command = cli.app

def app():  # the command registers handlers of its own while it runs: one leaves output in the buffer
    atexit.register(sys.stdout.write, "unflushed output of an exit handler\\n")
    atexit.register(print, "handler registered by the command", flush=True)
    command()

cli.app = app
sys.argv = ["robotcal", *{arguments!r}]
cli.entry()
"""
)


def _python(script: str) -> subprocess.CompletedProcess:
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONUNBUFFERED"}
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, env=environment
    )
    if "handlers at start" in done.stdout:
        pytest.skip("this interpreter registers an exit handler at start-up (coverage, sitecustomize)")
    return done


def _entry(arguments: list[str], before: str = "") -> subprocess.CompletedProcess:
    return _python(SCRIPT.format(before=before, arguments=arguments))


@pytest.mark.parametrize(
    ("arguments", "status", "output"),
    [
        (["--version"], 0, "robotcal "),
        (["no-such-command"], 2, "No such command"),  # Typer's usage error, on stderr
        (["run", "no-such-scenario", "--out", "unused"], 2, "unknown scenario"),  # robotcal's error: status 2
    ],
)
def test_the_status_and_output_are_kept_and_the_teardown_skipped(arguments, status, output):
    done = _entry(arguments)
    assert done.returncode == status, done.stderr
    assert output in done.stdout + done.stderr
    assert "unflushed output of an exit handler" in done.stdout  # flushed before the process ends
    assert "handler registered by the command" in done.stdout  # every exit handler ran...
    assert "teardown" not in done.stdout  # ...and then the process ended


def test_an_exit_handler_registered_before_the_script_keeps_the_normal_exit():
    """A handler registered before ``entry`` would run after the early end, so none is installed: that
    handler and the teardown run, with the same status."""
    done = _entry(["no-such-command"], before='atexit.register(print, "early handler", flush=True)')
    assert done.returncode == 2
    assert "handler registered by the command" in done.stdout
    assert "early handler" in done.stdout and "teardown" in done.stdout


def test_a_python_caller_of_main_keeps_its_own_status_and_teardown():
    """``main`` ends with ``SystemExit``; a caller that catches it and fails afterwards exits with its own
    status (1 for the uncaught error), and the teardown runs."""
    script = PREAMBLE + (
        "import robotcal.cli as cli\n"
        "sys.argv = ['robotcal', 'no-such-command']\n"
        "try:\n"
        "    cli.main()\n"
        "except SystemExit as exc:\n"
        "    print('main ended with', exc.code, flush=True)\n"
        "raise RuntimeError('the caller fails afterwards')\n"
    )
    done = _python(script)
    assert "main ended with 2" in done.stdout
    assert done.returncode == 1 and "the caller fails afterwards" in done.stderr
    assert "teardown" in done.stdout


@pytest.mark.parametrize("code", [2**31, -(2**31) - 1, True, "a message"])
def test_a_status_os_exit_cannot_take_is_left_to_python(code):
    """Beyond a C int (``os._exit`` would raise OverflowError), a bool or a message: Python's own exit."""
    script = PREAMBLE + (
        "import robotcal.cli as cli\n"
        f"def app():\n    raise SystemExit({code!r})\n"
        "cli.app = app\n"
        "cli.entry()\n"
    )
    done = _python(script)
    reference = subprocess.run([sys.executable, "-c", f"raise SystemExit({code!r})"], capture_output=True, text=True)
    assert done.returncode == reference.returncode
    assert "teardown" in done.stdout and "Exception ignored" not in done.stderr


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
    done = _python(code)
    assert done.returncode == 0, done.stderr
    assert "child 3" in done.stdout
