"""The background figure renderer (robotcal.plots.background): the same files as drawing here, results in
submission order, errors raised here with their job and traceback, the synchronous fallback, and a stop
(cancel, an exception in the ``with`` block, the parent's death) that leaves no worker and no temporary file."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import CancelledError
from pathlib import Path

import numpy as np
import pytest

import robotcal.plots.background as background
from robotcal.errors import InputError
from robotcal.io.atomic import atomic_write_bytes
from robotcal.plots.background import FigureRenderer, FigureWorkerError

LINUX_PROC = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads process states from /proc")
#: Seconds a test waits for something the worker does (a generous bound on a loaded machine, not a timing test).
PATIENCE_S = 60.0


# ------------------------------------------------------------------------------ jobs (module level: picklable)


def square(value):
    return value * value


def process_id() -> int:
    return os.getpid()


def refuse(message: str):
    raise InputError(message)


def raise_unpicklable():
    class Local(Exception):  # a local class does not pickle
        pass

    raise Local("local failure")


def line_figure(path: Path, seed: int) -> Path:
    """A small figure with text, a line and a legend, saved atomically as PNG."""
    from robotcal.plots.figures import new_figure, save_figure

    values = np.random.default_rng(seed).normal(size=50).cumsum()
    figure, axis = new_figure(width_in=3.0, height_in=2.0)
    axis.plot(values, label="walk")
    axis.set_xlabel("step [-]")
    axis.legend()
    return save_figure(figure, path)


def is_daemonic() -> bool:
    return multiprocessing.current_process().daemon


def forked_helper_exit_code() -> int:
    """A job that forks a helper process of its own (the histograms do) and returns its exit status."""
    helper = multiprocessing.get_context("fork").Process(target=square, args=(3,), daemon=True)
    helper.start()
    helper.join()
    return helper.exitcode


def _stalled_fsync(marker: str):
    def fsync(fd):
        Path(marker + ".part").write_text(str(os.getpid()))
        os.replace(marker + ".part", marker)  # the marker appears with its content
        time.sleep(PATIENCE_S)

    return fsync


def write_stalled(path: str, marker: str) -> None:
    """An atomic write that stalls after its temporary file exists (fsync replaced in this process only)."""
    os.fsync = _stalled_fsync(marker)
    atomic_write_bytes(path, b"figure" * 1000)


def write_stalled_in_a_helper(path: str, marker: str) -> None:
    """The same stalled write in a process forked by the job."""
    helper = multiprocessing.get_context("fork").Process(target=write_stalled, args=(path, marker), daemon=True)
    helper.start()
    helper.join()


def describe(values: np.ndarray, scale: float) -> tuple:
    """What the worker received: a digest of the values, whether they are writable, the scale."""
    values *= 1.0  # in place: the arrays arrive writable, as they were
    return values.shape, values.dtype.str, values.flags.f_contiguous, float(values.sum()), values.tobytes()[:64], scale


def die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


class _SlowToDelete:
    def __init__(self, marker: str):
        self.marker = marker

    def __del__(self):
        Path(self.marker + ".part").write_text(str(os.getpid()))
        os.replace(self.marker + ".part", self.marker)
        time.sleep(PATIENCE_S / 4)  # the SIGTERM arrives here: its SystemExit is printed and swallowed by Python


def stopped_inside_a_finaliser(marker: str) -> str:
    """A job in a ``__del__`` when it is stopped (as happens when the signal lands in a weakref callback)."""
    _SlowToDelete(marker)  # deleted at once: __del__ runs here
    return "went on"


def exit_from_the_job() -> None:
    raise SystemExit(3)


def _sleep_then_write(path: str) -> None:
    time.sleep(PATIENCE_S / 4)
    Path(path).write_text("written after the worker died")


def die_leaving_a_helper(path: str, marker: str) -> None:
    """Fork a helper that would write ``path`` much later, record its pid in ``marker``, then die (SIGKILL,
    as the out-of-memory killer would)."""
    helper = multiprocessing.get_context("fork").Process(target=_sleep_then_write, args=(path,), daemon=True)
    helper.start()
    Path(marker + ".part").write_text(str(helper.pid))
    os.replace(marker + ".part", marker)
    os.kill(os.getpid(), signal.SIGKILL)


# ------------------------------------------------------------------------------------------------- helpers


def _wait_for(path: Path) -> None:
    deadline = time.monotonic() + PATIENCE_S
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.02)


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _wait_dead(pid: int) -> bool:
    deadline = time.monotonic() + PATIENCE_S
    while _alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


@pytest.fixture(scope="module")
def small_result():
    from robotcal.io import load_scenario
    from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo
    from robotcal.workflow import scenario_monte_carlo

    problem = scenario_monte_carlo(load_scenario("thesis-laser-tracker"))
    return run_monte_carlo(problem, MonteCarloSettings(iterations=300, block_size=300, batch_size=300), seed=5)


# ----------------------------------------------------------------------------------------- same files, order


def test_jobs_run_in_another_process_and_come_back_in_submission_order():
    with FigureRenderer(preload=()) as renderer:
        assert renderer.kind == "process"
        jobs = [renderer.submit(square, value) for value in range(6)]
        where = renderer.submit(process_id)
        values = renderer.wait()
    assert values == [0, 1, 4, 9, 16, 25, where.result()]
    assert [job.result() for job in jobs] == [0, 1, 4, 9, 16, 25]
    assert where.result() != os.getpid()
    assert renderer.wait() == []  # wait() returns the jobs submitted since the last one


def test_figures_are_the_same_bytes_as_drawn_here(tmp_path):
    for name in ("here", "worker", "synchronous"):
        (tmp_path / name).mkdir()
    expected = [line_figure(tmp_path / "here" / f"walk{seed}.png", seed) for seed in range(3)]
    with FigureRenderer() as renderer:
        in_worker = [renderer.submit(line_figure, tmp_path / "worker" / f"walk{seed}.png", seed) for seed in range(3)]
    with FigureRenderer(workers=0) as renderer:
        synchronous = [renderer.submit(line_figure, tmp_path / "synchronous" / f"walk{seed}.png", seed) for seed in range(3)]
    for here, worker, synchronous_job in zip(expected, in_worker, synchronous, strict=True):
        assert worker.result() == tmp_path / "worker" / here.name
        assert worker.result().read_bytes() == here.read_bytes()
        assert synchronous_job.result().read_bytes() == here.read_bytes()
    assert len({path.read_bytes() for path in expected}) == 3  # three different figures, so the check can fail


def test_histograms_in_the_worker_are_the_files_drawn_here(small_result, tmp_path):
    from robotcal.plots.montecarlo import write_histograms

    (tmp_path / "here").mkdir()
    (tmp_path / "worker").mkdir()
    here = write_histograms(small_result, tmp_path / "here", processes=1)
    with FigureRenderer(preload=("robotcal.plots.montecarlo",)) as renderer:
        job = renderer.submit(write_histograms, small_result, tmp_path / "worker")
    worker = job.result()
    assert [path.name for path in worker] == [path.name for path in here] and len(here) >= 2
    assert {path.name: path.read_bytes() for path in worker} == {path.name: path.read_bytes() for path in here}
    assert sorted(p.name for p in (tmp_path / "worker").iterdir()) == sorted(p.name for p in here)  # no temp file


def test_arrays_arrive_intact_and_a_function_may_be_named_by_a_string():
    values = np.random.default_rng(4).normal(size=(20_000, 6, 5))  # 4.8 MB: sent out of band, not pickled
    fortran = np.asfortranarray(values[:100, :, 0])
    with FigureRenderer(preload=()) as renderer:
        by_name = renderer.submit("test_background:describe", values, scale=2.0)
        by_function = renderer.submit(describe, fortran, 1.0)
        strided = renderer.submit(describe, values[::3], 0.5)
    assert by_name.name == "test_background.describe (job 1)"
    assert by_name.result() == describe(values.copy(), 2.0)
    assert by_function.result() == describe(fortran.copy(order="K"), 1.0)  # same memory order: same sum
    assert strided.result() == describe(values[::3].copy(), 0.5)


@pytest.mark.parametrize("name", ["test_background.describe", "test_background:", ":describe", "a:b c"])
def test_a_badly_named_function_is_refused(name):
    with FigureRenderer(workers=0) as renderer, pytest.raises(InputError, match="package.module:function"):
        renderer.submit(name)


def test_naming_a_plot_function_does_not_import_matplotlib_here():
    code = (
        "import sys\n"
        "from robotcal.plots.background import FigureRenderer\n"
        "with FigureRenderer(preload=('robotcal.plots.figures',)) as renderer:\n"
        "    job = renderer.submit('matplotlib:get_backend')\n"
        "    print(job.result().lower(), 'matplotlib' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=PATIENCE_S)
    assert done.stdout.split() == ["agg", "False"], done.stderr  # the worker's preload chose Agg


def test_a_job_may_fork_helpers_of_its_own():
    with FigureRenderer(preload=()) as renderer:
        daemonic = renderer.submit(is_daemonic)
        helper = renderer.submit(forked_helper_exit_code)
    assert daemonic.result() is False and helper.result() == 0


# ------------------------------------------------------------------------------------------------------ errors


def test_a_jobs_error_comes_back_with_its_type_job_and_traceback():
    renderer = FigureRenderer(preload=())
    good = renderer.submit(square, 4)
    bad = renderer.submit(refuse, "no such robot 'kr6'")
    with pytest.raises(InputError, match="no such robot 'kr6'") as caught:
        bad.result()
    assert good.result() == 16
    renderer.close()
    error = caught.value
    assert any("figure job test_background.refuse (job 2)" in note for note in error.__notes__), error.__notes__
    assert "in refuse" in bad.traceback_text and "raise InputError(message)" in bad.traceback_text
    assert "raise InputError(message)" in str(error.__cause__)  # the worker's traceback, chained


def test_wait_raises_the_first_error_in_submission_order():
    renderer = FigureRenderer(preload=())
    renderer.submit(square, 2)
    renderer.submit(refuse, "first")
    renderer.submit(refuse, "second")
    with pytest.raises(InputError, match="first"):
        renderer.wait()
    renderer.close()


def test_leaving_the_block_normally_raises_a_job_error_nobody_asked_for():
    with pytest.raises(InputError, match="unread"):
        with FigureRenderer(preload=()) as renderer:
            renderer.submit(refuse, "unread")


def test_an_unpicklable_job_is_refused_at_submit_and_an_unpicklable_error_is_reported():
    renderer = FigureRenderer(preload=())
    with pytest.raises(TypeError, match="module-level function"):
        renderer.submit(lambda: 1)
    job = renderer.submit(raise_unpicklable)
    with pytest.raises(FigureWorkerError, match="Local: local failure"):
        job.result()
    assert "local failure" in job.traceback_text
    worker = renderer._worker.process
    renderer.cancel()  # nothing left to stop: the worker stays
    assert renderer.submit(square, 5).result() == 25 and renderer._worker.process is worker
    renderer.close()
    assert not worker.is_alive() and worker.exitcode == 0  # close() lets the worker exit by itself


def test_a_job_the_worker_cannot_load_fails_instead_of_hanging(monkeypatch):
    """A function that exists here but not in the worker (added after the fork) fails its job with the
    worker's error; before, the outcome carried no job number, was dropped, and the job waited for ever."""
    renderer = FigureRenderer(preload=())
    assert renderer.submit(square, 2).result() == 4  # the worker is up (forked before the function exists)

    def added_later(value):
        return value

    added_later.__qualname__ = added_later.__name__ = "added_later"
    monkeypatch.setattr(sys.modules[__name__], "added_later", added_later, raising=False)
    job = renderer.submit(added_later, 1)
    with pytest.raises(AttributeError, match="added_later") as caught:
        job.result(timeout=PATIENCE_S)
    assert any("figure job" in note for note in caught.value.__notes__)
    assert renderer.submit(square, 3).result() == 9  # the same worker goes on
    with pytest.raises(AttributeError):
        renderer.wait()
    renderer.close()


def test_a_job_that_raises_system_exit_fails_with_its_traceback():
    renderer = FigureRenderer(preload=())
    job = renderer.submit(exit_from_the_job)
    with pytest.raises(FigureWorkerError, match=r"raised SystemExit\(3\)"):
        job.result()
    assert "exit_from_the_job" in job.traceback_text
    assert renderer.submit(square, 4).result() == 16  # the worker did not exit
    with pytest.raises(FigureWorkerError):
        renderer.wait()
    renderer.close()


def test_a_single_job_is_not_cancelled_behind_the_renderers_back():
    """Future.cancel() on a job is refused (the worker may be drawing it); FigureRenderer.cancel() stops jobs."""
    with FigureRenderer(preload=()) as renderer:
        job = renderer.submit(square, 6)
        assert job.cancel() is False
        assert job.result() == 36


def test_jobs_cancelled_by_the_renderer_are_not_waited_for(tmp_path):
    marker, target = tmp_path / "writing", tmp_path / "figure.png"
    with FigureRenderer(preload=()) as renderer:
        job = renderer.submit(write_stalled, str(target), str(marker))
        _wait_for(marker)
        renderer.cancel()
        assert job.cancelled()
        assert renderer.submit(square, 5).result() == 25
    # leaving the block normally after a deliberate cancel raised no CancelledError
    assert not target.exists()


@LINUX_PROC
def test_a_helper_of_a_killed_worker_dies_with_it(tmp_path):
    """A worker killed outright (SIGKILL) takes the processes its job forked with it: the job fails at once
    instead of waiting for the helper, and the helper never writes its file."""
    marker, target = tmp_path / "helper", tmp_path / "figure.png"
    renderer = FigureRenderer(preload=())
    job = renderer.submit(die_leaving_a_helper, str(target), str(marker))
    started = time.monotonic()
    with pytest.raises(FigureWorkerError, match="killed by SIGKILL"):
        job.result()
    assert time.monotonic() - started < PATIENCE_S / 8  # not after the helper's PATIENCE_S / 4 of sleep
    _wait_for(marker)
    assert _wait_dead(int(marker.read_text()))
    assert not target.exists()
    with pytest.raises(FigureWorkerError):
        renderer.wait()
    renderer.close()


def test_a_dead_worker_fails_its_jobs_instead_of_hanging():
    renderer = FigureRenderer(preload=())
    lost = renderer.submit(die)
    after = renderer.submit(square, 2)
    with pytest.raises(FigureWorkerError, match="killed by SIGKILL before figure job test_background.die"):
        lost.result()
    with pytest.raises(FigureWorkerError, match="square"):
        after.result()
    assert renderer.submit(square, 3).result() == 9  # a new worker
    with pytest.raises(FigureWorkerError, match="die"):
        renderer.wait()  # the first failure, in submission order
    renderer.close()


@pytest.mark.parametrize(
    "options, message",
    [({"workers": 2}, "must be 0 .* or 1"), ({"workers": True}, "must be 0"), ({"preload": "matplotlib"}, "sequence")],
)
def test_bad_settings_are_refused(options, message):
    with pytest.raises(InputError, match=message):
        FigureRenderer(**options)


def test_a_closed_renderer_refuses_jobs():
    renderer = FigureRenderer(workers=0)
    renderer.close()
    with pytest.raises(RuntimeError, match="closed"):
        renderer.submit(square, 1)


# -------------------------------------------------------------------------------------------------- fallback


def test_synchronous_mode_runs_here_with_the_same_outcomes():
    with FigureRenderer(workers=0) as renderer:
        assert renderer.kind == "synchronous"
        where = renderer.submit(process_id)
        assert where.done()  # ran in submit
        bad = renderer.submit(refuse, "here too")
        good = renderer.submit(square, 7)
        with pytest.raises(InputError, match="here too") as caught:
            renderer.wait()
    assert where.result() == os.getpid() and good.result() == 49
    assert any("refuse (job 2)" in note for note in caught.value.__notes__)
    assert "raise InputError(message)" in bad.traceback_text


def test_without_fork_the_jobs_run_synchronously(monkeypatch):
    monkeypatch.setattr(background.multiprocessing, "get_all_start_methods", lambda: ["spawn"])
    with FigureRenderer() as renderer:
        assert renderer.kind == "synchronous"
        assert renderer.submit(process_id).result() == os.getpid()


def test_when_no_process_can_start_the_jobs_run_synchronously(monkeypatch):
    import multiprocessing.context

    def refuse_start(self):
        raise AssertionError("daemonic processes are not allowed to have children")

    monkeypatch.setattr(multiprocessing.context.ForkProcess, "start", refuse_start)
    with FigureRenderer() as renderer:
        assert renderer.kind == "synchronous"
        assert renderer.submit(square, 6).result() == 36


# ---------------------------------------------------------------------------------------------------- stopping


@LINUX_PROC
@pytest.mark.parametrize("in_helper", [False, True], ids=["in the worker", "in a helper the job forked"])
def test_cancel_stops_a_write_in_progress_and_leaves_no_temporary_file(tmp_path, in_helper):
    marker, target = tmp_path / "writing", tmp_path / "out" / "figure.png"
    renderer = FigureRenderer(preload=())
    job = renderer.submit(write_stalled_in_a_helper if in_helper else write_stalled, str(target), str(marker))
    _wait_for(marker)
    writer = int(marker.read_text())
    assert [p.name.endswith(".tmp") for p in target.parent.iterdir()] == [True]  # the write is under way
    worker = renderer._worker.process
    renderer.cancel()
    assert not worker.is_alive() and worker.exitcode == 128 + signal.SIGTERM  # unwound, not killed
    assert _wait_dead(writer)
    assert list(target.parent.iterdir()) == []  # the temporary file was removed, the target never written
    assert job.cancelled()
    with pytest.raises(CancelledError):
        job.result()
    assert renderer.submit(square, 8).result() == 64  # the next job starts a new worker
    renderer.close()


@LINUX_PROC
def test_a_stop_swallowed_by_a_finaliser_still_stops_the_worker_at_once(tmp_path):
    """The SystemExit of a SIGTERM raised inside a ``__del__`` (or weakref callback) is swallowed by Python; the
    worker then exits when the job returns, instead of waiting for its SIGKILL (STOP_TIMEOUT_S later)."""
    marker = tmp_path / "in-del"
    renderer = FigureRenderer(preload=())
    job = renderer.submit(stopped_inside_a_finaliser, str(marker))
    _wait_for(marker)
    worker = renderer._worker.process
    started = time.monotonic()
    renderer.cancel()
    assert worker.exitcode == 128 + signal.SIGTERM  # not -SIGKILL
    assert time.monotonic() - started < background.STOP_TIMEOUT_S / 2
    assert job.cancelled()
    renderer.close()


@LINUX_PROC
def test_an_idle_worker_exits_at_once_on_sigterm():
    renderer = FigureRenderer(preload=())
    assert renderer.submit(square, 2).result() == 4
    worker = renderer._worker.process
    started = time.monotonic()
    os.kill(worker.pid, signal.SIGTERM)
    worker.join(PATIENCE_S)
    assert worker.exitcode == 128 + signal.SIGTERM and time.monotonic() - started < background.STOP_TIMEOUT_S / 2
    renderer.cancel()
    renderer.close()


@LINUX_PROC
def test_an_exception_in_the_block_stops_the_worker(tmp_path):
    marker, target = tmp_path / "writing", tmp_path / "figure.png"
    with pytest.raises(KeyboardInterrupt):
        with FigureRenderer(preload=()) as renderer:
            renderer.submit(write_stalled, str(target), str(marker))
            _wait_for(marker)
            worker = renderer._worker.process
            raise KeyboardInterrupt
    assert not worker.is_alive() and worker.exitcode == 128 + signal.SIGTERM
    assert sorted(p.name for p in tmp_path.iterdir()) == ["writing"]


@LINUX_PROC
def test_sigint_to_the_worker_is_ignored():
    with FigureRenderer(preload=()) as renderer:
        pid = renderer.submit(process_id).result()
        os.kill(pid, signal.SIGINT)  # Ctrl-C reaches the whole process group: the parent decides
        assert renderer.submit(square, 9).result() == 81


_PARENT_SCRIPT = textwrap.dedent(
    """
    import sys, time
    sys.path.insert(0, {tests!r})
    from robotcal.plots.background import FigureRenderer
    import test_background as jobs
    renderer = FigureRenderer(preload=())
    print(renderer.submit(jobs.process_id).result(), flush=True)
    renderer.submit(jobs.write_stalled, {target!r}, {marker!r})
    {ending}
    """
)


def _parent(tmp_path: Path, ending: str) -> subprocess.Popen:
    script = _PARENT_SCRIPT.format(
        tests=str(Path(__file__).parent), target=str(tmp_path / "figure.png"), marker=str(tmp_path / "writing"), ending=ending
    )
    return subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@LINUX_PROC
def test_the_worker_dies_with_its_killed_parent(tmp_path):
    parent = _parent(tmp_path, "time.sleep(600)")
    try:
        worker = int(parent.stdout.readline())
        _wait_for(tmp_path / "writing")
        parent.kill()
        parent.wait(timeout=PATIENCE_S)
        assert _wait_dead(worker)
    finally:
        if parent.poll() is None:
            parent.kill()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["writing"]  # SIGTERM unwound the write


@LINUX_PROC
def test_a_parent_that_exits_without_closing_does_not_hang_and_leaves_no_worker(tmp_path):
    parent = _parent(tmp_path, "import pathlib\nwhile not pathlib.Path({marker!r}).exists(): time.sleep(0.02)".format(
        marker=str(tmp_path / "writing")))
    try:
        worker = int(parent.stdout.readline())
        _, err = parent.communicate(timeout=PATIENCE_S)  # multiprocessing would join a worker left running
        assert parent.returncode == 0, err
        assert _wait_dead(worker)
    finally:
        if parent.poll() is None:
            parent.kill()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["writing"]
