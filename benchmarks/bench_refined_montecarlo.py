"""Benchmark of the refined-model Monte Carlo (capture -> CPA -> refinement per draw) on the demo capture.

Plain script: ``python benchmarks/bench_refined_montecarlo.py [--draws 100000] [--workers 2] [--loop 0]``.

Issue 31 (the deployed model's Monte Carlo at full size) prints, side by side in one run, on ``--workers`` workers
and ``--draws`` draws each (``--solvers`` limits which solvers run):

- the yardstick: a plain vectorised CPA Monte Carlo of kr5-demo (``model="cpa"``);
- the refined Monte Carlo, geometric (kr5-demo's circles, points criterion, base frame given) and extended (the demo's
  deployed model: J2/J3 compliance refitted in every draw, circles and calibration poses), each solved per draw
  (Levenberg-Marquardt from every draw's CPA estimate, ``refined_solver="per-draw"``) and by batched Gauss-Newton
  around the noise-free solution (``"gauss-newton"``): wall time, CPU per draw (the pool's workers included), the
  ratio to the yardstick's wall time;
- the two solvers' agreement: the largest difference of u and of both ends of the 95 % interval, in units of u;
- the Gauss-Newton draws' evaluations of their own Jacobian and the draws that fell back to the per-draw solve,
  counted on ``min(--draws, 2000)`` draws in this process.

Targets (issue 31): 100,000 draws on 2 cores, geometric <= 8 s, extended <= 15 s, equal to the per-draw solve to
0.01 u. A check that it runs: ``--draws 5000 --workers 1`` (about half a minute); the measurement:
``--draws 100000 --workers 2`` on an idle machine.

The earlier benchmark (issue 11/13), with ``--loop N`` (N > 0), also prints (scenario ``kr5-demo``'s 270 circle points without its calibration poses, the
geometric model, points criterion, base frame given: the kernel of the earlier records; the demo's deployed
compliance model with its poses is timed by ``bench_extended.py``):

- the per-draw loop: batched CPA, then ``refine_parameters`` (SciPy ``least_squares``, analytic
  Jacobian) draw after draw from each draw's CPA estimate, over ``--loop`` draws: s/draw;
- the batched engine (``run_monte_carlo`` with ``model="refined"``) with 1 worker over ``--loop`` x 10
  draws and with ``--workers`` workers over ``--draws`` draws: draws/s, wall time, failed draws,
  and the Jacobian evaluations per draw; CPU time per draw of both paths (the pool's workers included),
  which is what to compare on a machine shared with other jobs (the load average is printed);
- the speed-up of the batched engine over the loop (same core count: 1 worker vs the loop) and the
  extrapolated loop time for ``--draws`` draws.

With ``--command N`` it also times the whole command ``robotcal uncertainty kr5-demo -n N --model refined``
as a subprocess (wall, draws from its ``parameters.json``, and the difference; see ``bench_montecarlo.py``);
``--command-only`` times just that.

Targets (issue 11, docs/uncertainty.md): 100,000 draws <= 120 s on 2 cores; >= 20x the per-draw loop.

Figures of record (2026-11-23, ``--draws 20000``, 2 cores shared with other jobs, load average 7-9, so
compare the CPU figures), before -> after the column-wise kinematics, per-group point products and centred
group moments of issue 13:

- engine, CPU per draw (capture noise + CPA + refinement): 2 workers 0.489 -> 0.235 ms, 1 worker
  0.50 -> 0.30 ms; 2 workers 1068 -> 2707 draws/s wall under that load;
- ``refine_batch`` alone (500-draw batches, 1 thread, min of 8 alternating runs in one process):
  295-390 -> 141-193 us/draw (2.0-2.25x); over 20 batches user+sys 274+80 -> 151+26 us/draw, the system
  time being page faults of the temporaries (peak 27 MB per evaluation, now 11 MB);
- Jacobian evaluations per draw after the start's (500 draws): 2: 206/206, 3: 278/269, 4: 13/24, 5: 3/1
  (a draw whose last steps sit at the cost's rounding floor may take one more evaluation either way);
- the same fixed points: undamped Gauss-Newton from either result, with either implementation's normal
  equations, lands 2e-10 u apart; each result is at most 1.2e-5 (before) / 1.6e-5 (after) u from that fixed
  point (the stopping rule's tolerance: xtol 1e-10 on |z| ~ 1300), median 1.3e-10 u, over 1000 draws.

Issue 23 (2026-11-28, ``--draws 20000 --loop 30 --workers 2``, 3 alternated rounds, load average 0.2-0.65),
2 workers, draws/s: 05de958 (before) 12,547-15,604 (median 14,665), c0e2034 11,261-13,811 (median 13,070),
385f86a 10,995-13,686 (median 13,410, -8.6 %); CPU per draw 0.123-0.142 / 0.140-0.155 / 0.136-0.156 ms. The
draws themselves are unchanged; ~0.1 s of pool start and shutdown is ~7 % of these 1.5 s (bench_montecarlo.py).

Issue 31, the extended model's corrective steps with the shared matrix (2026-11-29, 2-core machine shared with
other jobs, load average 1.5-4, so CPU figures; f71863b before, this change after):

- ``--draws 5000 --workers 1 --solvers gauss-newton`` (one run each, process CPU per draw): geometric 60 -> 60 us
  (unchanged: the draws are bit-identical), extended 590 -> 180 us (its first batches included; before, their
  per-point Jacobians of ~5 MB each made the first batches about twice as slow as the next);
- ``draw_block`` of the demo's deployed model, 2,000 draws, one process, one thread, min of 3 after a warm-up,
  before and after alternated: 309-317 -> 146-153 us per draw (noise + CPA + refinement; the refinement alone
  ~280 -> ~120 us), geometric 50-59 -> 50-60 us; Gauss-Newton batches of 64 extended draws instead of 32:
  164-165 against 176-178 us per draw (``draws.EXTENDED_GAUSS_NEWTON_BATCH``, the same draws bit for bit);
- every extended draw: one evaluation of its own gradient (before: of its own normal equations), no fallback;
- distance to the per-draw solve over 2,000 draws (seed 3, test_gauss_newton.py's draws): extended 1.6e-6 u before
  and after, geometric 1.3e-5 u (unchanged), thesis 7.7e-6 / 9.0e-6 u (given / registered base, unchanged).
- profile of an extended draw after: the chain of link frames point by point (about a third), the gradient's
  dot and cross products, the shared first step's product, CPA.

Figures formerly in the docs, moved here by issue 30 (the docs say what dominates a cost; measured times
live here, with their machine):

Moved from docs/uncertainty.md:

`benchmarks/bench_refined_montecarlo.py` (demo capture, 270 points, points criterion, base given),
on the 2-core development machine shared with other jobs:

| path | wall time | CPU per draw |
| --- | ---: | ---: |
| loop: batched CPA, then `refine_parameters` draw after draw (60-200 draws) | 0.16-0.55 s/draw (100,000 draws: 4.6-15 h) | 53-124 ms |
| batched engine, 1 worker | 307-1,090 draws/s | 0.47 ms |
| batched engine, 2 workers, 100,000 draws, machine nearly idle (load average 1.4-1.6) | **25.8 s** (3,880 draws/s) | 0.50 ms |
| batched engine, 2 workers, 100,000 draws, shared (load average 3.6-4.9) | 153 s and 168 s | 0.55 ms |
| batched engine, 2 workers, 6,000 draws | 5.2 s (1,150 draws/s) | 0.55 ms |

The machine was shared with four other jobs (load average 3.6-4.9 on 2 cores) during every run,
so wall times are inflated by 2-3x and vary between runs; CPU time per draw is the stable figure.
At 0.55 ms of CPU per draw, 100,000 draws need 55 CPU-seconds: about 28 s on 2 dedicated cores
(target: 120 s), and a run on the nearly idle machine took 25.8 s (the loop over the same 60 draws
was 36x slower per core there); the two 100,000-draw runs on the loaded machine took 153 and 168 s. Against
the per-draw loop the engine is 180-190x faster in wall time on one core and 100-230x in CPU time
(target: 20x). Each draw needs 2-5 evaluations of residuals and normal equations from its CPA
start (2: 41 %, 3: 55 %, 4-5: 3 %), no draw failed. The distances criterion costs about 0.13 s per
draw (kr5-demo, 36,180 pairs; 100 draws in 13 s on the loaded machine).

docs/uncertainty.md, Monte Carlo of a measured capture: for 30 poses x 3 targets (90 points, 29 unknowns)
0.03-0.24 s per draw on one core (measured under load on a shared 2-core machine; `-n 300 --workers 1` took
32 s, 0.11 s per draw), so 300 draws take 10-70 s.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
import warnings

import numpy as np
from bench_montecarlo import whole_command  # sibling script (this folder is on sys.path when run as one)

from robotcal.api import link_masses, monte_carlo_problem, perturb
from robotcal.errors import IdentifiabilityWarning
from robotcal.execution import single_blas_thread
from robotcal.identification.cpa import identify_cpa_batch
from robotcal.identification.model_choice import joint_model_for
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.io import load_scenario
from robotcal.kinematics.model import ParameterSet
from robotcal.uncertainty.draws import _block_generators, _noise
from robotcal.uncertainty.gauss_newton import refine_draws_gauss_newton
from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo
from robotcal.uncertainty.refined import refine_batch

SCENARIO = "kr5-demo"


def _cpu() -> float:
    """CPU seconds of this process and its reaped children (the pool's workers)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def per_draw_loop(problem, n_draws: int, cpu: dict | None = None) -> float:
    """Seconds per draw of CPA (batched) + a loop of ``refine_parameters`` over the draws."""
    cpu_start = _cpu()
    rng, _ = _block_generators(1, 0)
    points = problem.exact_points + _noise(problem, n_draws, rng)
    began = time.perf_counter()
    cpa = identify_cpa_batch(points, problem.structure, problem.tracker_from_base)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        for k in range(n_draws):
            refine_parameters(
                problem.capture.with_points(points[k]),
                ParameterSet(robot=problem.robot, values=cpa.values[k]),
                problem.structure.reflector,
                tracker_from_base=problem.tracker_from_base,
                settings=RefinementSettings(estimate_base=False),
            )
    if cpu is not None:
        cpu["loop_cpu_ms_per_draw"] = round((_cpu() - cpu_start) / n_draws * 1e3, 2)
    return (time.perf_counter() - began) / n_draws


def iterations_per_draw(problem, n_draws: int = 500) -> dict:
    rng, _ = _block_generators(2, 0)
    points = problem.exact_points + _noise(problem, n_draws, rng)
    cpa = identify_cpa_batch(points, problem.structure, problem.tracker_from_base)
    batch = refine_batch(problem.refined, points, cpa.values, cpa.tracker_from_base)
    counts = np.bincount(batch.iterations)
    return {str(k): int(c) for k, c in enumerate(counts) if c}


def engine(problem, n_draws: int, workers: int) -> dict:
    settings = MonteCarloSettings(
        iterations=n_draws, workers=workers, block_size=min(10_000, n_draws), refined_solver="per-draw"
    )
    began, cpu_start = time.perf_counter(), _cpu()
    result = run_monte_carlo(problem, settings, seed=1, linearised=False)
    wall = time.perf_counter() - began
    cpu = _cpu() - cpu_start
    return {
        "cpu_ms_per_draw": round(cpu / n_draws * 1e3, 3),
        "draws": n_draws,
        "workers": workers,
        "wall_s": round(wall, 2),
        "draws_per_s": round(n_draws / wall, 1),
        "failed": result.n_failed,
    }


def problems() -> dict:
    """The yardstick's and the two refined Monte Carlos' problems (kr5-demo)."""
    scenario = load_scenario(SCENARIO)
    circles_only = dataclasses.replace(scenario, calibration_poses=None)
    structure = joint_model_for("compliance", scenario.robot, masses=link_masses(scenario))  # [joint_model] defaults
    truth = perturb(scenario, rng=11).replace(joint_model=structure.with_values([1e-5, 4e-5]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        return {
            "yardstick_cpa": monte_carlo_problem(scenario),
            "geometric": monte_carlo_problem(circles_only, model="refined"),
            "extended": monte_carlo_problem(scenario, model="refined", parameters=truth, joint_model=structure),
        }


def timed_run(problem, n_draws: int, workers: int, solver: str = "gauss-newton"):
    """Wall time, CPU per draw and draws/s of ``run_monte_carlo`` (and the result)."""
    settings = MonteCarloSettings(iterations=n_draws, workers=workers, refined_solver=solver)
    began, cpu_start = time.perf_counter(), _cpu()
    result = run_monte_carlo(problem, settings, seed=1, linearised=False)
    wall, cpu = time.perf_counter() - began, _cpu() - cpu_start
    figures = {
        "wall_s": round(wall, 2),
        "cpu_us_per_draw": round(cpu / n_draws * 1e6, 1),
        "draws_per_s": round(n_draws / wall, 1),
        "failed": result.n_failed,
    }
    return figures, result


def agreement(first, second) -> dict:
    """Largest difference of u and of the interval ends between two results of the same draws, in units of u."""
    u = second.summary.std_uncertainty
    varies = second.identified & (u > 0)
    out = {"u": float(np.max(np.abs(first.summary.std_uncertainty - u)[varies] / u[varies]))}
    for name, a, b in zip(("low", "high"), first.draws_interval(), second.draws_interval(), strict=True):
        out[name] = float(np.max(np.abs(a - b)[varies] / u[varies]))
    return {key: f"{value:.2e}" for key, value in out.items()}


def gauss_newton_record(problem, n_draws: int) -> dict:
    """Evaluations of each draw's own Jacobian and fallbacks of the Gauss-Newton draws, in this process."""
    rng, _ = _block_generators(2, 0)
    points = problem.exact_points + _noise(problem, n_draws, rng)
    cpa = identify_cpa_batch(points[:, : problem.n_circle], problem.structure, problem.tracker_from_base)
    size = 500 if problem.refined.joint_model is None else 32
    iterations, fallback = [], 0
    with single_blas_thread():
        for start in range(0, n_draws, size):
            part = slice(start, start + size)
            batch = refine_draws_gauss_newton(problem.refined, points[part], cpa.values[part], cpa.tracker_from_base[part])
            iterations.append(batch.iterations)
            fallback += int(batch.fallback.sum())
    counts = np.bincount(np.concatenate(iterations))
    return {"draws": n_draws, "evaluations": {str(k): int(c) for k, c in enumerate(counts) if c}, "fallback": fallback}


def side_by_side(n_draws: int, workers: int, solvers: list[str]) -> dict:
    """Issue 31: the yardstick and the refined Monte Carlos, geometric and extended, per solver."""
    chosen = problems()
    yardstick, _ = timed_run(chosen["yardstick_cpa"], n_draws, workers)
    report = {"draws": n_draws, "workers": workers, "yardstick_cpa": yardstick}
    for kind in ("geometric", "extended"):
        problem, results, entry = chosen[kind], {}, {}
        for solver in solvers:
            figures, results[solver] = timed_run(problem, n_draws, workers, solver)
            figures["x_yardstick"] = round(figures["wall_s"] / max(yardstick["wall_s"], 1e-9), 2)
            entry[solver] = figures
        if len(results) == 2:
            entry["agreement_in_u"] = agreement(results["gauss-newton"], results["per-draw"])
        if "gauss-newton" in results:
            entry["gauss_newton"] = gauss_newton_record(problem, min(n_draws, 2000))
        report[f"refined_{kind}"] = entry
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--draws", type=int, default=100_000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--solvers", default="per-draw,gauss-newton", help="comma-separated refined solvers")
    parser.add_argument("--loop", type=int, default=0, help="also the earlier record: the scipy loop over N draws")
    parser.add_argument("--command", type=int, default=0, help="also time the whole command with this many draws")
    parser.add_argument("--command-only", action="store_true", help="only time the whole command (--command N)")
    args = parser.parse_args()
    if args.command_only:
        figures = whole_command(args.command or args.draws, model="refined", scenario=SCENARIO)
        print(json.dumps({"whole_command": figures}, indent=2))
        return
    report = side_by_side(args.draws, args.workers, args.solvers.split(","))
    if args.loop:
        report["earlier"] = earlier_record(args)
    if args.command:
        report["whole_command"] = whole_command(args.command, model="refined", scenario=SCENARIO)
    report["load_average"] = [round(x, 2) for x in os.getloadavg()]
    print(json.dumps(report, indent=2))


def earlier_record(args) -> dict:
    """The issue 11/13 record: the scipy loop against the batched engine (geometric, per-draw solve)."""
    began = time.perf_counter()
    circles_only = dataclasses.replace(load_scenario(SCENARIO), calibration_poses=None)
    problem = monte_carlo_problem(circles_only, model="refined")
    report = {"scenario": SCENARIO, "points": problem.n_points, "prepare_s": round(time.perf_counter() - began, 3)}
    loop = per_draw_loop(problem, args.loop, report)
    report["loop_s_per_draw"] = round(loop, 5)
    report["loop_extrapolated_s"] = round(loop * args.draws, 1)
    report["jacobian_evaluations_per_draw"] = iterations_per_draw(problem)
    single = engine(problem, 10 * args.loop, 1)
    report["engine_1_worker"] = single
    report["speedup_1_core"] = round(single["draws_per_s"] * loop, 1)
    report["cpu_time_speedup"] = round(report["loop_cpu_ms_per_draw"] / single["cpu_ms_per_draw"], 1)
    return report


if __name__ == "__main__":
    main()
