"""The library bounds BLAS threads in its hot loops itself (issue 24): refinement, CPA and the Monte Carlo run with
one BLAS thread whatever the caller's setting, and the caller's setting is restored afterwards."""

from __future__ import annotations

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import robotcal
from robotcal.identification import refine as refine_module
from robotcal.uncertainty import draws


def _blas_threads() -> set[int]:
    return {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}


@pytest.fixture
def four_threads():
    if not _blas_threads():
        pytest.skip("no BLAS library found by threadpoolctl")
    with threadpool_limits(limits=4, user_api="blas"):
        if max(_blas_threads()) < 2:
            pytest.skip("the BLAS library keeps one thread: nothing to bound")
        yield


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")  # J6 behind its own reflector
def test_refinement_and_monte_carlo_run_on_one_blas_thread(four_threads, monkeypatch):
    seen = []
    solve = refine_module.least_squares
    monkeypatch.setattr(refine_module, "least_squares", lambda *a, **k: (seen.append(_blas_threads()), solve(*a, **k))[1])
    draw = draws.draw_block
    monkeypatch.setattr(draws, "draw_block", lambda *a, **k: (seen.append(_blas_threads()), draw(*a, **k))[1])
    outside_by_library = {pool["filepath"]: pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}
    scenario = robotcal.load_scenario("thesis-laser-tracker")
    capture = robotcal.simulate(scenario, rng=1)
    robotcal.refine(capture, scenario, robotcal.identify(capture, scenario), folds=0)
    robotcal.monte_carlo(scenario, draws=100, rng=1, linearised=False)
    assert len(seen) >= 2 and all(threads == {1} for threads in seen), seen
    # the caller's limit is back once the calls return, on every BLAS library loaded before them (a library the
    # calls load first, e.g. SciPy's own OpenBLAS with scipy.optimize, starts at its default)
    after = {pool["filepath"]: pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}
    assert {path: after[path] for path in outside_by_library} == outside_by_library
