"""Clean interrupts with a real process tree: SIGINT/SIGTERM/SIGHUP (also a terminal that closes) stop
``robotcal`` and its Monte Carlo workers quickly, exit 130/143/129, leave no orphan, no temporary folder, no
lock and no half result, and mark ``run.json`` "interrupted"; what a SIGKILL leaves, the next run removes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process tree from /proc")

#: Seconds allowed from the signal to the exit of the whole tree (the issue asks for 2 s on an idle
#: machine; the test machines are shared, so the check leaves room).
EXIT_WITHIN_S = 5.0


def _children(pid: int) -> set[int]:
    """Every descendant of ``pid`` (from /proc, no psutil needed)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _start(tmp_path: Path, *args, terminal: int | None = None, stderr_on_terminal: bool = False) -> subprocess.Popen:
    """``robotcal ARGS`` in its own session; with ``terminal`` (a pseudo-terminal's follower end), that terminal is
    its controlling terminal, stdin and stdout (and stderr if asked), as in a terminal window or an ssh session."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "120"}
    streams = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "preexec_fn": _foreground_job}
    if terminal is not None:
        streams = {
            "stdin": terminal,
            "stdout": terminal,
            "stderr": terminal if stderr_on_terminal else subprocess.PIPE,
            "preexec_fn": _own_terminal,
        }
    return subprocess.Popen(
        [sys.executable, "-c", "from robotcal.cli import main; main()", *map(str, args)],
        cwd=tmp_path,
        env=env,
        **streams,  # its own process group: a group signal is a terminal's Ctrl-C
    )


def _foreground_job() -> None:
    """In the child: a new session (its own process group, so a group signal is a terminal's Ctrl-C) with Ctrl-C
    at its default, as in a terminal's foreground job. The tests may run with SIGINT ignored (a shell without job
    control ignores it in its background jobs, ``cmd &``), and robotcal, like any program, keeps an inherited
    SIG_IGN (``nohup``): its Ctrl-C tests would then see a run that never stops."""
    os.setsid()
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _own_terminal() -> None:
    """:func:`_foreground_job` whose controlling terminal is stdin's (closing its other end hangs it up)."""
    import fcntl
    import termios

    _foreground_job()
    fcntl.ioctl(0, termios.TIOCSCTTY, 0)


def _wait_for(condition, process: subprocess.Popen, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if process.poll() is not None:
            pytest.fail(f"robotcal exited early: {process.returncode} {process.stderr.read().decode()}")
        if time.monotonic() > deadline:
            os.killpg(process.pid, signal.SIGKILL)
            pytest.fail("robotcal did not reach the point to interrupt")
        time.sleep(0.05)


def _interrupt(process: subprocess.Popen, signum: int, *, group: bool) -> tuple[int, float, str, set[int]]:
    tree = _children(process.pid)
    started = time.monotonic()
    (os.killpg if group else os.kill)(process.pid, signum)
    try:
        _, err = process.communicate(timeout=30)  # hangs if an orphan still holds the pipes
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        pytest.fail("robotcal (or a worker holding its output) did not exit")
    elapsed = time.monotonic() - started
    deadline = time.monotonic() + 2.0
    while any(_alive(pid) for pid in tree) and time.monotonic() < deadline:
        time.sleep(0.05)
    return process.returncode, elapsed, err.decode(), {pid for pid in tree if _alive(pid)}


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if p.name.endswith((".partial", ".old", ".robotcal-lock", ".tmp")))


def _stage_running(out: Path, stage: str):
    def running() -> bool:
        try:
            record = json.loads((out / "run.json").read_text())
        except (OSError, ValueError):
            return False
        return record["stages"][stage]["status"] == "running"

    return running


@pytest.mark.parametrize(
    ("signum", "code", "group"),
    [(signal.SIGTERM, 143, False), pytest.param(signal.SIGINT, 130, True, marks=pytest.mark.slow)],
)
def test_uncertainty_with_workers_stops_cleanly(tmp_path, signum, code, group):
    out = tmp_path / "mc"
    process = _start(tmp_path, "uncertainty", "thesis-noise-free", "-n", 2_000_000, "--workers", 2, "--out", out)
    # the pool's two workers are up
    _wait_for(lambda: len(_children(process.pid)) >= 2, process)
    time.sleep(0.3)
    returncode, elapsed, err, orphans = _interrupt(process, signum, group=group)
    assert returncode == code, err
    assert elapsed < EXIT_WITHIN_S
    assert orphans == set()
    assert "Traceback" not in err and ("terminated" if code == 143 else "interrupted") in err
    assert not out.exists() and _leftovers(tmp_path) == []


def test_run_interrupted_is_recorded(tmp_path):
    out = tmp_path / "r"

    def refining() -> bool:
        try:
            record = json.loads((out / "run.json").read_text())
        except (OSError, ValueError):
            return False
        return record["stages"]["refine"]["status"] == "running"

    process = _start(tmp_path, "run", "kr5-demo", "--draws", 2000, "--workspace", 20, "--workers", 1, "--out", out)
    _wait_for(refining, process)
    returncode, elapsed, err, orphans = _interrupt(process, signal.SIGINT, group=True)  # Ctrl-C
    assert returncode == 130, err
    assert elapsed < EXIT_WITHIN_S and orphans == set()
    # the figure pool is drawing the joints' figures meanwhile: its workers leave the signal to the run (issue 24:
    # the former figure worker printed "SystemExit: 143" or "ValueError: Invalid bounding box" in 2 of 5 trials)
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("interrupted"), err
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["failed_stage"] == "refine"
    assert record["stages"]["refine"]["status"] == "interrupted"
    assert "SIGINT" in record["error"]
    assert not (out / "refine").exists() and (out / "cpa" / "parameters.json").is_file()  # no half stage
    assert _leftovers(tmp_path) == []


@pytest.mark.slow
def test_run_interrupted_in_the_monte_carlo_leaves_no_worker(tmp_path):
    out = tmp_path / "r"
    process = _start(tmp_path, "run", "kr5-demo", "--draws", 1_000_000, "--workspace", 20, "--workers", 2, "--out", out)
    _wait_for(lambda: len(_children(process.pid)) >= 3, process, timeout=300)  # figure pool + 2 Monte Carlo workers
    time.sleep(0.3)
    returncode, elapsed, err, orphans = _interrupt(process, signal.SIGTERM, group=False)
    assert returncode == 143, err
    assert elapsed < EXIT_WITHIN_S and orphans == set()
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["failed_stage"] == "uncertainty"
    assert not (out / "uncertainty").exists() and _leftovers(tmp_path) == []


@pytest.mark.parametrize(
    "how",
    [
        "signal",  # kill -HUP to the process group
        "terminal",  # the terminal window / ssh session closes: SIGHUP, then writes to it fail (EIO)
        "terminal-stderr-too",  # the same, the error stream on the terminal too: nothing may turn the status into 1
    ],
)
def test_a_hang_up_stops_run_and_demo_cleanly(tmp_path, how):
    # issue 24: SIGHUP killed run/demo with run.json left "running" and the lock left; then the closed terminal's
    # EIO replaced the interrupt (exit 2 "error: Input/output error", or 1 with a traceback)
    out = tmp_path / "r"
    if how == "signal":
        arguments = ["run", "kr5-demo", "--draws", 2000, "--workspace", 20, "--workers", 1, "--out", out]
        process = _start(tmp_path, *arguments)
        _wait_for(_stage_running(out, "refine"), process)
        returncode, elapsed, err, orphans = _interrupt(process, signal.SIGHUP, group=True)
    else:
        leader, follower = os.openpty()
        process = _start(
            tmp_path, "demo", "--draws", 2000, "--out", out, terminal=follower, stderr_on_terminal=how.endswith("too")
        )
        os.close(follower)

        def refining() -> bool:
            while True:  # keep the terminal's buffer drained, as a terminal window does
                try:
                    if not os.read(leader, 65536) or not os.get_blocking(leader):
                        break
                except BlockingIOError:
                    break
            return _stage_running(out, "refine")()

        os.set_blocking(leader, False)
        _wait_for(refining, process)
        tree = _children(process.pid)
        started = time.monotonic()
        os.close(leader)  # the window closes: the kernel hangs the terminal up
        try:
            process.wait(timeout=30)
            err = process.stderr.read().decode() if process.stderr else ""
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            pytest.fail("robotcal did not exit when its terminal closed")
        elapsed = time.monotonic() - started
        deadline = time.monotonic() + 2.0
        while any(_alive(pid) for pid in tree) and time.monotonic() < deadline:
            time.sleep(0.05)
        returncode, orphans = process.returncode, {pid for pid in tree if _alive(pid)}
    assert returncode == 129, err
    assert elapsed < EXIT_WITHIN_S and orphans == set()
    if how != "terminal-stderr-too":
        assert "Traceback" not in err and "terminated (SIGHUP)" in err and "error" not in err, err
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["failed_stage"] == "refine"
    assert "SIGHUP" in record["error"] and record["stages"]["refine"]["status"] == "interrupted"
    assert not (out / "refine").exists() and _leftovers(tmp_path) == []


def _kill_while(process: subprocess.Popen, present, timeout: float = 60.0) -> None:
    """SIGKILL ``process`` at a moment when ``present()`` holds (checked again with the process stopped)."""
    deadline = time.monotonic() + timeout
    while True:
        if present():
            os.kill(process.pid, signal.SIGSTOP)
            if present():
                os.kill(process.pid, signal.SIGKILL)
                return
            os.kill(process.pid, signal.SIGCONT)
        if process.poll() is not None:
            pytest.fail(f"robotcal exited early: {process.returncode} {process.stderr.read().decode()}")
        if time.monotonic() > deadline:
            os.killpg(process.pid, signal.SIGKILL)
            pytest.fail("robotcal did not reach the point to kill")
        time.sleep(0.002)


@pytest.mark.parametrize("command", ["run", "uncertainty"])
def test_what_a_sigkill_leaves_the_next_run_removes(tmp_path, command):
    # issue 24: SIGKILL left a .partial folder (and the lock) that the next run did not remove
    out = tmp_path / "out"
    if command == "run":  # a stage's folder being built inside the run folder
        arguments = ["run", "kr5-demo", "--draws", 200, "--workspace", 5, "--workers", 1, "--out", out]
        where = out
    else:  # the result folder being built beside its place
        arguments = ["uncertainty", "thesis-noise-free", "-n", 200, "--out", out]
        where = tmp_path
    process = _start(tmp_path, *arguments)
    _kill_while(process, lambda: any(where.glob(".*.robotcal-*.partial")))
    tree = _children(process.pid)
    process.communicate(timeout=30)
    assert process.returncode == -signal.SIGKILL
    deadline = time.monotonic() + 5.0
    while any(_alive(pid) for pid in tree) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert {pid for pid in tree if _alive(pid)} == set()  # the workers die with their parent
    left = _leftovers(tmp_path)
    assert any(name.endswith(".partial") for name in left) and any(name.endswith(".robotcal-lock") for name in left)
    again = _start(tmp_path, *arguments)
    _, err = again.communicate(timeout=120)
    assert again.returncode == 0, err.decode()
    assert _leftovers(tmp_path) == []
    if command == "run":
        assert json.loads((out / "run.json").read_text())["status"] == "done"
    else:
        assert (out / "parameters.csv").is_file()


def test_an_interrupt_that_surfaces_as_another_error_is_that_interrupt(tmp_path, monkeypatch):
    # a signal landing while a C extension initialises (scipy.optimize's, imported as refine starts) breaks the import:
    # "ImportError: initialization failed" from the KeyboardInterrupt/Terminated; it was a traceback, exit 1, and
    # run.json "failed" (about 1 Ctrl-C in 15 at the start of refine)
    from typer.testing import CliRunner

    from robotcal.cli import app
    from robotcal.errors import Terminated
    from robotcal.pipeline import stages

    def refine_stage(*args, **kwargs):
        try:
            raise Terminated("SIGHUP")
        except Terminated as exc:
            raise ImportError("initialization failed") from exc

    monkeypatch.setattr(stages, "refine_stage", refine_stage)
    out = tmp_path / "r"
    arguments = ["run", "kr5-demo", "--draws", "200", "--workspace", "5", "--workers", "1", "--out", str(out)]
    result = CliRunner().invoke(app, arguments)
    assert result.exit_code == 129, result.output
    assert "terminated (SIGHUP)" in result.output and "Traceback" not in result.output
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["failed_stage"] == "refine"
    assert record["error"] == "terminated (SIGHUP)" and record["stages"]["refine"]["status"] == "interrupted"
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize(
    ("interrupt", "status"), [("SIGHUP", 129), ("SIGTERM", 143), (None, 130)], ids=["SIGHUP", "SIGTERM", "Ctrl-C"]
)
def test_an_error_while_cleaning_up_after_an_interrupt_keeps_the_interrupts_status(capsys, interrupt, status):
    # the terminal a SIGHUP closed: the progress display's last write fails with EIO during the cleanup
    import errno

    import typer

    from robotcal.cli._common import handle_errors
    from robotcal.errors import Terminated

    @handle_errors
    def command():
        try:
            raise Terminated(interrupt) if interrupt else KeyboardInterrupt
        finally:
            raise OSError(errno.EIO, "Input/output error")

    with pytest.raises(SystemExit) as info:
        command()
    assert info.value.code == status
    err = capsys.readouterr().err
    assert ("interrupted" if interrupt is None else f"terminated ({interrupt})") in err and "error" not in err

    @handle_errors
    def bug():
        raise ZeroDivisionError  # not an interrupt, not robotcal's: its traceback is kept

    with pytest.raises(ZeroDivisionError):
        bug()
    with pytest.raises(typer.Exit):
        handle_errors(lambda: (_ for _ in ()).throw(typer.Exit(code=1)))()


@pytest.mark.parametrize("stage", ["refine", pytest.param("report", marks=pytest.mark.slow)])  # report: a whole run
def test_an_interrupt_right_after_run_json_says_running_is_that_stages(tmp_path, stage):
    # the moment the signal tests send their signal: run.json has just said "running"; the stage was left "running"
    # and the record had no failed_stage when the interrupt came before the stage's own error handling began
    from robotcal.errors import Terminated
    from robotcal.pipeline import plan_run, run_calibration

    def progress(name, done, total, detail=""):
        if name == stage and done == 0 and detail == "running":
            raise Terminated("SIGHUP")

    out = tmp_path / "r"
    plan = plan_run("kr5-demo", out, draws=200, workspace=5, workers=1, refined_draws=100)
    with pytest.raises(Terminated):
        run_calibration(plan, progress=progress, figure_workers=0)
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["failed_stage"] == stage
    assert record["stages"][stage]["status"] == "interrupted" and record["error"] == "terminated (SIGHUP)"
    assert _leftovers(tmp_path) == []
