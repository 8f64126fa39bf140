"""Clean interrupts with a real process tree: SIGINT/SIGTERM/SIGHUP (also a terminal that closes) stop
``robotcal`` and its Monte Carlo workers quickly, exit 130/143/129, leave no orphan, no temporary folder, no
lock and no half result, and mark ``run.json`` "interrupted"; what a SIGKILL leaves, the next run removes.

The tests wait for what robotcal does (a stage recorded "running" in run.json, a worker that has used the CPU), never
for a fixed time, and measure the stop from the signal: they hold on a machine kept busy by other processes (set
ROBOTCAL_TEST_CPU_BURNERS=N to run them beside N CPU-burning processes, as .ci/run does once; one test always does).
A signal at a chosen moment is sent by the test's own code run in robotcal's process before the command line starts
(``prelude``: a fork handler, an import hook), never by a hook in robotcal."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process tree from /proc")

#: Seconds allowed from the signal to the exit of the whole tree, on a busy machine too (issue 30: "a Ctrl-C stops
#: `run` within 2 s there").
EXIT_WITHIN_S = 2.0
#: Seconds to wait for robotcal to reach the moment a test interrupts (a fresh clone on a busy machine is slow).
REACH_WITHIN_S = 300.0
#: Environment variable: the number of CPU-burning processes to run beside every test of this module.
BURNERS_ENV = "ROBOTCAL_TEST_CPU_BURNERS"
#: The longest a CPU burner lives, whatever happens to the test that started it.
BURNER_LIFETIME_S = 900


@contextlib.contextmanager
def cpu_burners(count: int):
    """``count`` processes that keep a CPU busy for the block (in this process's session, so that the scheduler
    weighs them against robotcal's processes); each also ends when this process dies or after
    :data:`BURNER_LIFETIME_S`."""
    code = (
        "import os, sys, time\n"
        "parent, end = int(sys.argv[1]), time.monotonic() + float(sys.argv[2])\n"
        "while os.getppid() == parent and time.monotonic() < end:\n"
        "    for _ in range(100_000):\n"
        "        pass\n"
    )
    burners = [
        subprocess.Popen([sys.executable, "-c", code, str(os.getpid()), str(BURNER_LIFETIME_S)]) for _ in range(count)
    ]
    try:
        yield burners
    finally:
        for burner in burners:
            burner.kill()
        for burner in burners:
            burner.wait()


@pytest.fixture(autouse=True, scope="module")
def _busy_machine_if_asked():
    """:data:`BURNERS_ENV` CPU burners beside every test of the module (none unless asked)."""
    with cpu_burners(int(os.environ.get(BURNERS_ENV) or 0)):
        yield


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


def _cpu_seconds(pid: int) -> float:
    """The CPU time ``pid`` has used (user + system), 0 if it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _start(
    tmp_path: Path, *args, terminal: int | None = None, stderr_on_terminal: bool = False, prelude: str = ""
) -> subprocess.Popen:
    """``robotcal ARGS`` as a terminal's foreground job (its own process group); with ``terminal`` (a
    pseudo-terminal's follower end), in its own session whose controlling terminal, stdin and stdout (and stderr if
    asked) that terminal is, as in a terminal window or an ssh session. ``prelude``: the test's Python code run in
    robotcal's process before the command line starts (it may send a signal at a chosen moment)."""
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
        [sys.executable, "-c", f"{prelude}\nfrom robotcal.cli import main; main()", *map(str, args)],
        cwd=tmp_path,
        env=env,
        **streams,  # its own process group: a group signal is a terminal's Ctrl-C
    )


def _foreground_job() -> None:
    """In the child: its own process group (a group signal is a terminal's Ctrl-C) with Ctrl-C at its default, as a
    terminal's foreground job. The tests may run with SIGINT ignored (a shell without job control ignores it in its
    background jobs, ``cmd &``), and robotcal, like any program, keeps an inherited SIG_IGN (``nohup``): its Ctrl-C
    tests would then see a run that never stops. It stays in the tests' session: where the scheduler groups
    processes by session (Linux's autogroup), a new session would shield it from the CPU burners."""
    os.setpgid(0, 0)
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _own_terminal() -> None:
    """:func:`_foreground_job` in a new session whose controlling terminal is stdin's (closing its other end hangs
    it up)."""
    import fcntl
    import termios

    os.setsid()
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    fcntl.ioctl(0, termios.TIOCSCTTY, 0)


def _wait_for(condition, process: subprocess.Popen, timeout: float = REACH_WITHIN_S) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if process.poll() is not None:
            pytest.fail(f"robotcal exited early: {process.returncode} {process.stderr.read().decode()}")
        if time.monotonic() > deadline:
            os.killpg(process.pid, signal.SIGKILL)
            pytest.fail("robotcal did not reach the point to interrupt")
        time.sleep(0.02)


def _workers_computing(process: subprocess.Popen, count: int):
    """Whether ``count`` worker processes of ``process`` have each used some CPU (they are computing)."""

    def computing() -> bool:
        return sum(_cpu_seconds(pid) >= 0.05 for pid in _children(process.pid)) >= count

    return computing


def _wait_gone(pids, timeout: float = 30.0) -> set[int]:
    """The processes among ``pids`` still alive after waiting up to ``timeout`` seconds for them to end."""
    deadline = time.monotonic() + timeout
    while any(_alive(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.02)
    return {pid for pid in pids if _alive(pid)}


def _interrupt(process: subprocess.Popen, signum: int, *, group: bool) -> tuple[int, float, str, set[int]]:
    """Send ``signum`` (to the process group: a terminal's Ctrl-C); the exit status, the seconds from the signal to
    the exit of the whole process tree, stderr, and the processes of the tree left alive."""
    tree = _children(process.pid)
    started = time.monotonic()
    (os.killpg if group else os.kill)(process.pid, signum)
    try:
        _, err = process.communicate(timeout=120)  # hangs if an orphan still holds the pipes
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        pytest.fail("robotcal (or a worker holding its output) did not exit")
    orphans = _wait_gone(tree)
    return process.returncode, time.monotonic() - started, err.decode(), orphans


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
    _wait_for(_workers_computing(process, 2), process)  # the pool's two workers are drawing
    returncode, elapsed, err, orphans = _interrupt(process, signum, group=group)
    assert returncode == code, err
    assert elapsed < EXIT_WITHIN_S
    assert orphans == set()
    assert "Traceback" not in err and ("terminated" if code == 143 else "interrupted") in err
    assert not out.exists() and _leftovers(tmp_path) == []


def test_run_interrupted_is_recorded(tmp_path):
    out = tmp_path / "r"
    process = _start(tmp_path, "run", "kr5-demo", "--draws", 2000, "--workspace", 20, "--workers", 1, "--out", out)
    _wait_for(_stage_running(out, "refine"), process)
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
    _wait_for(_stage_running(out, "uncertainty"), process)
    _wait_for(_workers_computing(process, 2), process)  # the Monte Carlo's workers are drawing
    returncode, elapsed, err, orphans = _interrupt(process, signal.SIGTERM, group=False)
    assert returncode == 143, err
    assert elapsed < EXIT_WITHIN_S and orphans == set()
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["failed_stage"] == "uncertainty"
    assert not (out / "uncertainty").exists() and _leftovers(tmp_path) == []


#: Prelude: the signal ``signal`` to robotcal's process group from the parent's side of its ``fork``-th fork, i.e.
#: as a pool's worker has just been started; it lands in a fork handler, where Python prints an exception and goes
#: on ("Exception ignored in: <function _releaseLock ...> KeyboardInterrupt").
_SIGNAL_AT_FORK = """
import os, signal
_forks = [0]
def _signal_at_fork():
    _forks[0] += 1
    if _forks[0] == {fork}:
        os.killpg(0, signal.{signal})
os.register_at_fork(after_in_parent=_signal_at_fork)
"""

#: Prelude: the signal ``signal`` to robotcal's process as the module ``module`` is about to be imported.
_SIGNAL_AT_IMPORT = """
import os, signal, sys
class _SignalAtImport:
    def find_spec(self, name, path=None, target=None):
        if name == {module!r}:
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.{signal})
        return None
sys.meta_path.insert(0, _SignalAtImport())
"""

#: The exit status and the one line on stderr after each signal.
_INTERRUPTED = {
    "SIGINT": (130, "interrupted"),
    "SIGTERM": (143, "terminated (SIGTERM)"),
    "SIGHUP": (129, "terminated (SIGHUP)"),
}


@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_an_interrupt_as_the_monte_carlos_workers_start_stops_it(tmp_path, signame):
    # issue 30: a Ctrl-C as the workers started was lost in 3 of 12 trials ("Exception ignored in ... _releaseLock
    # ... KeyboardInterrupt"): the command went on, exited 0 and wrote its result; or a worker that got it before it
    # ignored signals printed a traceback and the parent ended in a BrokenProcessPool traceback
    out = tmp_path / "mc"
    arguments = ["uncertainty", "thesis-laser-tracker", "--iterations", 60_000, "--workers", 2, "--out", out]
    process = _start(tmp_path, *arguments, prelude=_SIGNAL_AT_FORK.format(fork=1, signal=signame))
    _, err = process.communicate(timeout=REACH_WITHIN_S)
    assert (process.returncode, err.decode().strip()) == _INTERRUPTED[signame]
    assert not out.exists() and _leftovers(tmp_path) == []


def test_a_ctrl_c_as_the_runs_monte_carlo_workers_start_stops_the_run(tmp_path):
    # issue 30: the same lost Ctrl-C inside `run` left its lock behind; fork 1 starts the figure worker, fork 2 the
    # first of the Monte Carlo's two workers
    out = tmp_path / "r"
    arguments = ["run", "kr5-demo", "--draws", 2000, "--workspace", 20, "--workers", 2, "--out", out]
    process = _start(tmp_path, *arguments, prelude=_SIGNAL_AT_FORK.format(fork=2, signal="SIGINT"))
    _, err = process.communicate(timeout=REACH_WITHIN_S)
    assert process.returncode == 130, err.decode()
    assert "Traceback" not in err.decode() and err.decode().strip().splitlines()[-1] == "interrupted", err.decode()
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["failed_stage"] == "uncertainty"
    assert not (out / "uncertainty").exists() and _leftovers(tmp_path) == []


@pytest.mark.parametrize("module", ["typer", "robotcal.cli.uncertainty"], ids=["framework", "command"])
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_as_the_command_starts_is_a_clean_interrupt(tmp_path, module, signame):
    # issue 30: a Ctrl-C in the first 0.3-0.5 s printed an import traceback (exit -2: the command line framework was
    # imported before the handlers were installed); SIGTERM or SIGHUP in the first second ended with exit 130 and no
    # message (while the framework loaded the command's module, it turned the interrupt into its own silent exit 130)
    out = tmp_path / "mc"
    arguments = ["uncertainty", "thesis-laser-tracker", "--iterations", 60_000, "--out", out]
    process = _start(tmp_path, *arguments, prelude=_SIGNAL_AT_IMPORT.format(module=module, signal=signame))
    _, err = process.communicate(timeout=REACH_WITHIN_S)
    assert (process.returncode, err.decode().strip()) == _INTERRUPTED[signame]
    assert not out.exists() and _leftovers(tmp_path) == []


def test_a_ctrl_c_stops_run_within_2_s_on_a_busy_machine(tmp_path):
    # issue 30: with the load at 8-17 on 2 cores, run and demo took 18-28 s to stop after Ctrl-C: the figure worker
    # finished the figure it was drawing, and the next, first
    out = tmp_path / "r"
    with cpu_burners(4 * len(os.sched_getaffinity(0))):
        process = _start(tmp_path, "run", "kr5-demo", "--draws", 2000, "--workspace", 20, "--workers", 1, "--out", out)
        _wait_for(_stage_running(out, "refine"), process)
        _wait_for(_workers_computing(process, 1), process)  # the figure worker draws the joints' figures
        returncode, elapsed, err, orphans = _interrupt(process, signal.SIGINT, group=True)
    assert returncode == 130, err
    assert elapsed < EXIT_WITHIN_S and orphans == set()
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "interrupted", err
    assert json.loads((out / "run.json").read_text())["status"] == "interrupted"
    assert _leftovers(tmp_path) == []


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
            process.wait(timeout=120)
            err = process.stderr.read().decode() if process.stderr else ""
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            pytest.fail("robotcal did not exit when its terminal closed")
        orphans = _wait_gone(tree)
        returncode, elapsed = process.returncode, time.monotonic() - started
    assert returncode == 129, err
    assert elapsed < EXIT_WITHIN_S and orphans == set()
    if how != "terminal-stderr-too":
        assert "Traceback" not in err and "terminated (SIGHUP)" in err and "error" not in err, err
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["failed_stage"] == "refine"
    assert "SIGHUP" in record["error"] and record["stages"]["refine"]["status"] == "interrupted"
    assert not (out / "refine").exists() and _leftovers(tmp_path) == []


def _kill_while(process: subprocess.Popen, present, timeout: float = REACH_WITHIN_S) -> None:
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
    process.communicate(timeout=120)
    assert process.returncode == -signal.SIGKILL
    assert _wait_gone(tree) == set()  # the workers die with their parent
    left = _leftovers(tmp_path)
    assert any(name.endswith(".partial") for name in left) and any(name.endswith(".robotcal-lock") for name in left)
    again = _start(tmp_path, *arguments)
    _, err = again.communicate(timeout=REACH_WITHIN_S)
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


def _busy_until_stopped(folder: str) -> None:
    """A pool task that never calls check_stop (a figure being drawn): it marks that it runs, computes for up to a
    minute, and removes its mark in ``finally`` (as a figure's writer removes its temporary file)."""
    mark = Path(folder) / f"running-{os.getpid()}"
    mark.touch()
    try:
        end = time.monotonic() + 60.0
        while time.monotonic() < end:
            sum(range(10_000))
    finally:
        mark.unlink()


def test_the_task_a_pool_worker_runs_is_interrupted_when_the_pool_stops(tmp_path):
    # issue 30: the pool waited for the figure being drawn (and the next), 18-28 s on a busy machine
    from robotcal.execution import StopRequested, process_pool

    with pytest.raises(KeyboardInterrupt):  # noqa: PT012 - the pool must be torn down by the exception
        with process_pool(2) as pool:
            futures = [pool.submit(_busy_until_stopped, str(tmp_path)) for _ in range(4)]
            deadline = time.monotonic() + REACH_WITHIN_S
            while len(list(tmp_path.glob("running-*"))) < 2 and time.monotonic() < deadline:
                time.sleep(0.01)
            workers = {int(path.name.split("-")[1]) for path in tmp_path.glob("running-*")}
            raise KeyboardInterrupt
    assert len(workers) == 2 and _wait_gone(workers) == set()
    # no task ran to its end: the two running were interrupted (their finally ran), the others never ran
    assert all(future.cancelled() or isinstance(future.exception(), StopRequested) for future in futures)
    assert sum(not future.cancelled() for future in futures) >= 2 and list(tmp_path.iterdir()) == []


def test_an_interrupt_whose_exception_python_dropped_still_stops_the_work(tmp_path, monkeypatch, capsys):
    # issue 30: Python drops an exception raised in a fork handler or a __del__ ("Exception ignored in ..."): the
    # command went on and wrote its result; the signal's record makes the next check raise it again
    from robotcal import errors
    from robotcal.cli._common import handle_errors
    from robotcal.execution import check_stop, open_executor
    from robotcal.io.results.output import result_folder

    monkeypatch.setattr(errors, "_RECEIVED", [])
    with contextlib.suppress(KeyboardInterrupt):  # the handler's exception, dropped
        errors._on_signal(signal.SIGTERM, None)
    with pytest.raises(errors.Terminated, match="SIGTERM"):
        check_stop()
    with open_executor() as executor, pytest.raises(errors.Terminated):
        next(executor.map(str, range(3)))
    out = tmp_path / "result"
    with pytest.raises(errors.Terminated), result_folder(out, command="test") as folder:
        (folder / "values.csv").write_text("1\n")
    assert list(tmp_path.iterdir()) == []  # no result, no lock, no temporary folder

    @handle_errors
    def command():
        raise RuntimeError("a pool broken by the signal")  # an error after the signal is the signal's

    with pytest.raises(SystemExit) as ending:
        command()
    assert ending.value.code == 143 and capsys.readouterr().err.strip() == "terminated (SIGTERM)"


def test_an_interrupt_as_the_lock_is_taken_leaves_no_lock(tmp_path, monkeypatch):
    # issue 30: an interrupt after the lock file was made and before the block that removes it left the lock behind
    from robotcal.io.results import output

    create = output._create_lock

    def create_then_interrupted(*args):
        create(*args)
        raise KeyboardInterrupt

    monkeypatch.setattr(output, "_create_lock", create_then_interrupted)
    with pytest.raises(KeyboardInterrupt), output.output_lock(tmp_path / "out"):
        pass
    assert list(tmp_path.iterdir()) == []
