"""The execution backend: order, backends give bit-identical Monte Carlo statistics, clean interrupts."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from robotcal.api import monte_carlo_problem
from robotcal.errors import InputError
from robotcal.execution import SCHEDULER_ENV, check_stop, open_executor
from robotcal.io import load_scenario
from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo


def _square(x):
    return x * x


def _pid(_):
    return os.getpid()


def _slow(x):
    """A 30 s task that checks for a stop between its steps, as the Monte Carlo blocks do."""
    for _ in range(3000):
        check_stop()
        time.sleep(0.01)
    return x


def _fail(x):
    if x == 0:
        raise ValueError("task failed")
    return x


def test_results_come_back_in_order_serial_and_in_processes(monkeypatch):
    monkeypatch.delenv(SCHEDULER_ENV, raising=False)
    with open_executor() as serial:
        assert serial.kind == "serial"
        assert list(serial.map(_square, range(10))) == [x * x for x in range(10)]
    with open_executor(workers=2) as pool:
        assert pool.kind == "processes"
        assert list(pool.map(_square, range(10))) == [x * x for x in range(10)]


def _wait_dead(pids, seconds=5.0):
    deadline = time.monotonic() + seconds
    alive = set(pids)
    while alive and time.monotonic() < deadline:
        for pid in list(alive):
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                alive.discard(pid)
        time.sleep(0.05)
    return alive


@pytest.mark.parametrize("error", [ValueError, KeyboardInterrupt, SystemExit])
def test_an_exception_terminates_the_workers_promptly(monkeypatch, error):
    monkeypatch.delenv(SCHEDULER_ENV, raising=False)
    began = time.monotonic()
    with pytest.raises(error):  # noqa: PT012 - the pool must be torn down by the exception
        with open_executor(workers=2) as pool:
            pids = set(pool.map(_pid, range(4)))
            if error is ValueError:
                list(pool.map(_fail, range(2)))  # a task's exception reaches the parent
            pool.map(_slow, range(4))  # workers busy for 30 s: the parent is interrupted meanwhile
            time.sleep(0.2)
            raise error
    assert pids and not _wait_dead(pids), "a worker outlived the pool"
    assert time.monotonic() - began < 10.0  # no wait for the 30 s tasks: they stop at their next check


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_workers_leave_signals_to_the_parent(monkeypatch, signum):
    monkeypatch.delenv(SCHEDULER_ENV, raising=False)
    with open_executor(workers=2) as pool:
        pid = next(iter(pool.map(_pid, [0])))
        os.kill(pid, signum)
        assert list(pool.map(_square, range(4))) == [0, 1, 4, 9]


def test_check_stop_does_nothing_outside_a_stopping_pool():
    check_stop()  # in this (parent) process: no pool, no stop


def test_bad_arguments_are_refused(monkeypatch):
    monkeypatch.delenv(SCHEDULER_ENV, raising=False)
    with pytest.raises(InputError, match="workers"):
        with open_executor(workers=0):
            pass
    with pytest.raises(InputError, match="scheduler"):
        with open_executor(scheduler="   "):
            pass


def test_same_seed_bit_identical_statistics_serial_processes_and_dask(monkeypatch):
    distributed = pytest.importorskip("distributed")
    monkeypatch.delenv(SCHEDULER_ENV, raising=False)
    problem = monte_carlo_problem(load_scenario("thesis-laser-tracker"))

    def run(workers, scheduler=None):
        settings = MonteCarloSettings(
            iterations=600, block_size=200, batch_size=150, workers=workers, scheduler=scheduler
        )
        return run_monte_carlo(problem, settings, seed=11, linearised=False)

    serial = run(1)
    local = run(2)
    with distributed.LocalCluster(
        processes=False, n_workers=2, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        dask = run(1, cluster.scheduler_address)
        monkeypatch.setenv(SCHEDULER_ENV, cluster.scheduler_address)  # the environment variable is read too
        with open_executor() as executor:
            assert executor.kind == "dask"
            assert list(executor.map(_square, range(5))) == [0, 1, 4, 9, 16]
    for other in (local, dask):
        np.testing.assert_array_equal(other.draws, serial.draws)
        np.testing.assert_array_equal(other.summary.std_uncertainty, serial.summary.std_uncertainty)
        np.testing.assert_array_equal(other.summary.symmetric_low, serial.summary.symmetric_low)
        np.testing.assert_array_equal(other.covariance, serial.covariance)


@pytest.mark.parametrize("address", ["not an address", "http://host:8786", "myhost", "tcp://host"])
def test_a_malformed_scheduler_address_is_an_input_error(address):
    # review finding: ValueError tracebacks from distributed.Client for these
    with pytest.raises(InputError, match="not a Dask scheduler address"):
        with open_executor(scheduler=address):
            pass
