"""Benchmark of plan evaluation throughput (issue 15, scale-out): plans scored per second.

Plain script: ``python benchmarks/bench_planning.py [--plans 48]``. Scores ``--plans`` mutants of the
thesis plan (Table 5.1, laser tracker of Table 5.4; linearised CPA covariance + workspace p95 TCP
uncertainty at 200 poses) through :mod:`robotcal.execution`: serially, on a local pool of 2
processes, and on a 2-worker Dask ``LocalCluster`` (when Dask is installed). Also times the cell check.
The scores must be identical on every backend (printed as a check).

Figures formerly in the docs, moved here by issue 30 (the docs say what dominates a cost; measured times
live here, with their machine):

docs/planning.md: `robotcal sensitivity thesis-laser-tracker --vary capture.sweep_deg.4=15,40,90,180 -n 10000`
took 14 s.

docs/planning.md: `robotcal plan optimise thesis-laser-tracker --generations 120 --seed 0` scored 961
candidates (651 feasible) in about 3 minutes on the shared 2-core machine.

Moved from docs/planning.md:

### Benchmark (`python benchmarks/bench_planning.py --plans 32`)

Measured on the shared 2-core development machine while other jobs ran (so the parallel figures are
lower bounds): cell check 267 plans/s (135 points, 6 capsules); linearised scoring (CPA Jacobian of
810 perturbed captures + 200-pose workspace propagation) 5.2 plans/s serial, 6.0 plans/s on 2 local
processes, 3.7 plans/s on a 2-worker Dask `LocalCluster` (task shipping of the plan and problem
dominates at ~0.2 s per task); the scores were identical on the three backends.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from robotcal.execution import open_executor
from robotcal.io import load_scenario
from robotcal.kinematics.model import ReflectorMount
from robotcal.planning.cell import check_plan
from robotcal.planning.optimise import PlanProblem, _score
from robotcal.planning.scenario import cell_from_scenario


def _plans(scenario, count: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    plans = []
    for _ in range(count):
        scale = rng.uniform(0.5, 1.0, size=6)
        positions = scenario.plan.reflector.positions * rng.uniform(0.8, 1.5, size=(6, 1))
        plans.append(
            dataclasses.replace(
                scenario.plan,
                sweep=scenario.plan.sweep * scale,
                reflector=ReflectorMount(frame="joint", positions=positions),
            )
        )
    return plans


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plans", type=int, default=48)
    args = parser.parse_args()
    scenario = load_scenario("thesis-laser-tracker")
    cell, _ = cell_from_scenario(scenario, no_acceptance=True)
    problem, _ = PlanProblem.from_scenario(scenario, cell, workspace_poses=200, seed=0)
    plans = _plans(scenario, args.plans)
    started = time.perf_counter()
    for plan in plans:
        check_plan(scenario.robot, plan, cell)
    check_rate = len(plans) / (time.perf_counter() - started)
    print(f"cell check: {check_rate:,.0f} plans/s (135 points, 6 capsules)")
    reference = None
    backends = [("serial", {"workers": 1}), ("2 processes", {"workers": 2})]
    try:
        from distributed import LocalCluster

        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
        backends.append(("Dask LocalCluster, 2 workers", {"scheduler": cluster.scheduler_address}))
    except ImportError:
        cluster = None
    tasks = [(plan, problem) for plan in plans]
    for label, options in backends:
        with open_executor(**options) as executor:
            list(executor.map(_score, tasks[:2]))  # warm-up (imports, data shipping)
            started = time.perf_counter()
            scores = [s["p95-tcp"] for s in executor.map(_score, tasks)]
            elapsed = time.perf_counter() - started
        same = reference is None or scores == reference
        reference = reference or scores
        print(f"{label:32s}: {len(plans) / elapsed:6.1f} plans/s ({elapsed:.2f} s), identical scores: {same}")
    if cluster is not None:
        cluster.close()


if __name__ == "__main__":
    main()
