"""Two ``robotcal run`` processes into one folder: the second is refused (exit 2, one line naming the
lock's holder) and the first one's folder is not mixed with another seed's stages.

The waits are for what the processes do (one exits, run.json appears), with room for a busy machine."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest


def _run(tmp_path, out, seed):
    return subprocess.Popen(
        [sys.executable, "-c", "from robotcal.cli import main; main()", "run", "kr5-demo", "--seed", str(seed)]
        + ["--draws", "2000", "--workspace", "20", "--workers", "1", "--out", str(out)],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )


def test_two_runs_into_one_folder_one_is_refused(tmp_path):
    out = tmp_path / "r"
    first, second = _run(tmp_path, out, 1), _run(tmp_path, out, 2)
    processes = {1: first, 2: second}
    try:
        deadline = time.monotonic() + 300
        while all(p.poll() is None for p in processes.values()):
            if time.monotonic() > deadline:
                pytest.fail("neither run was refused")
            time.sleep(0.05)
        refused_seed = next(seed for seed, p in processes.items() if p.poll() is not None)
        refused = processes.pop(refused_seed)
        ((winner_seed, winner),) = processes.items()
        _, err = refused.communicate(timeout=120)
        err = err.decode()
        assert refused.returncode == 2, err
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and "another robotcal process" in lines[0] and f"pid {winner.pid}" in lines[0]
        # the folder belongs to the run that holds the lock: its seed, not a mixture
        while not (out / "run.json").exists() and winner.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        record = json.loads((out / "run.json").read_text())
        assert record["seeds"]["capture"] == winner_seed
    finally:
        for process in (first, second):
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
                process.communicate(timeout=120)
    assert winner.returncode == 143  # stopped by the test, cleanly
    assert not list(tmp_path.glob(".*.robotcal-lock"))
