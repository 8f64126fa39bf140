"""Clean interrupts with a real process tree: SIGINT/SIGTERM stop ``robotcal`` and its Monte Carlo
workers quickly, exit 130/143, leave no orphan, no temporary folder, no lock and no half result, and
mark ``run.json`` "interrupted"."""

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


def _start(tmp_path: Path, *args) -> subprocess.Popen:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "120"}
    return subprocess.Popen(
        [sys.executable, "-c", "from robotcal.cli import main; main()", *map(str, args)],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,  # its own process group: a group signal is a terminal's Ctrl-C
        env=env,
    )


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
