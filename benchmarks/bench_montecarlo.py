"""Benchmark of the Monte Carlo engine on the thesis laser-tracker scenario (Tables 5.2/5.4).

Plain script: ``python benchmarks/bench_montecarlo.py [--draws 100000] [--loop 300] [--million]``.
Prints, side by side in one run:

- the plain per-draw loop (one noisy capture at a time through the single-capture ``identify_cpa``,
  what a straightforward implementation of the thesis's algorithm 5.2.2 does), in draws/s;
- the batched engine (``run_monte_carlo``) with 1 and 2 worker processes: draws/s and wall time for
  ``--draws`` draws (geometric circle fit, 135 points per draw, uniform noise A + B L);
- the speed-up of the batched engine over the loop;
- the cost at 1/4, 1/2 and 1 x ``--draws`` and the fitted exponent of time vs draws (1 = linear);
- peak memory (max RSS of a fresh process, draws kept) at ``--draws``, and at 10^6 draws with
  ``--million`` (about a minute);
- the whole command ``robotcal uncertainty kr5-demo -n --draws --out DIR`` as a subprocess: wall time,
  the draws' time from its ``parameters.json`` (``timings_s.draws``) and the difference, the cost of
  everything else (start-up, imports, statistics, linearised comparison, files, histograms).
  ``--command-only`` measures just that (plus the load average);
- ``--cpu-per-draw``: only the CPU cost of one draw (``draw_block`` in this process, 2,000-draw batches,
  best of ``--repeat`` (at least 3) blocks of 4,000 draws) on the demo scenario (kr5-demo, 270 points) and on
  thesis-laser-tracker (135 points), with the minor page faults per draw: CPU seconds, so that a
  comparison survives a busy machine better than wall time.

Targets (issue 3, docs/uncertainty.md): >= 30x the per-draw loop; 100,000 draws <= 3 s on 2 cores; linear cost;
< 1 GB at 10^6 draws. Issue 13: the whole command at most 1 s more than its draws; CPA draws >= 1.5x cheaper.

Figures of record, ``--cpu-per-draw``, 3 alternating runs of each version on the 2-core AMD EPYC VM shared
with other jobs (load average 8.5-9.3, which inflates CPU times too; CPU us per draw, runs in order):

============================  ===================  ===================  ==================
scenario                      before [1]           after [2]            speed-up (median)
============================  ===================  ===================  ==================
kr5-demo (the demo, 270 pts)  82.1, 84.7, 70.8     47.2, 47.2, 49.0     1.74x
thesis-laser-tracker (135)    53.0, 47.0, 53.4     30.2, 27.7, 34.4     1.75x
============================  ===================  ===================  ==================

Minor page faults per kr5-demo draw: 2.5 before, 0.63 after. At load ~2.5 the same comparison gave
66-77 us before and 38-44 us after on kr5-demo.

[1] commit 5910eb3. [2] issue 13, CPA draws: the plane fit's centroid from the transposed copy (the strided
``mean`` over the points axis alone cost ~19 ns per point and draw), projections by one-pass einsum, the
in-plane scatter from the 3x3 one, the Kasa moments without scaled copies, the Levenberg-Marquardt passes
into preallocated arrays, the closed-form eigenvector by components, residuals left out of Monte Carlo
draws, the axis transport by Rodrigues' formula, the orientation by two one-pass sums, uniform noise as
``2 u - 1`` into a reused buffer. The draws are those of before up to rounding (<= 3e-11 mm, 1.1e-13 rad;
``tests/unit/uncertainty/test_montecarlo.py::test_demo_draws_are_those_of_the_reference_implementation``).

CPU times on the shared 2-core VM now vary by +-25 % between runs, more than a 10 % change. Instruction counts
do not: ``valgrind --tool=callgrind`` on a script that runs ``draw_block(problem, 7, b, 2000, 2000)`` for 1 and
for 3 blocks, the difference of the two totals over 4,000 draws (imports and set-up cancel; memory stalls and
page faults are not counted). Instructions per draw:

============================  ===========  ===========  =======
scenario                      before [2]   after [3]    change
============================  ===========  ===========  =======
kr5-demo (the demo, 270 pts)  166,400      157,600      -5.3 %
thesis-laser-tracker (135)    127,700      114,700      -10.1 %
============================  ===========  ===========  =======

[3] issue 13, S3: the Levenberg-Marquardt circle fit goes on with a copy of the circles still iterating once
at most half of a batch is left (kr5-demo: circles 5 and 6 then iterate 202 and 2 of 2,000 rows in their last
iteration; -9.5 % of the fit's instructions; bit-identical); resting joints' variables taken exactly rather than
as the mean of equal readings, so no axis transport of -1.7e-16 rad is made (5 rotations of the axes per batch on
kr5-demo; draws move by <= 3.6e-12 mm and 4.4e-15 rad). What is left, per kr5-demo draw: the PCG64 stream
(~26,000 instructions, fixed by the seed contract), the row sums of the fits (~19,000), and ~17,000 in numpy's
buffered copies of the per-circle values broadcast along the points (``u - cu[:, None]``, three per evaluation of
the circle fit, ``centred -= centroid``): such a broadcast subtraction costs ~2.4x a contiguous one on a
(2,000, 40) batch, and neither a materialised copy, a transposed layout nor another buffer size was faster.

Issue 23 (2026-11-28, ``--draws 100000 --loop 100``, 2 alternated rounds, load average below 1): 1 worker
62,277-69,075 draws/s before (05de958), 67,803-71,324 with issue 23 (c0e2034), 71,926-72,974 at 385f86a; 2
workers 0.89-0.97 s / 0.85-0.91 s / 0.85-0.92 s for 100,000 draws. The linear fit of cost vs draws puts the
fixed part at 0.06-0.09 s before and 0.16-0.21 s after, the same 7.1-8.7 us per draw: the pool's start and
public shutdown (waiting for its workers) cost ~0.1 s more than the private teardown did; not isolated further,
since at 100,000 draws the totals are equal.

Issue 31, where ``robotcal uncertainty kr5-demo -n 100000 --model cpa`` spends what is not draws (2026-11-29, 2
shared cores, load 1.5-1.9, timestamps around the command's calls; 4.86 s wall, 1.95 s of draws): imports before
the draws 1.29 s (``import robotcal.api`` 1.0 s, of which ``scipy.stats`` 0.5 s, imported at the top of
``identification/model_choice.py`` for one ``scipy.stats.f.sf``; matplotlib with ``plots.montecarlo`` 0.26 s);
statistics and linearised comparison 0.13 s; parameters.csv/json 0.11 s (no draws.npz unless ``--save-draws``);
the five histograms in the forked pool 1.07 s wall (0.75-1.0 s of matplotlib CPU drawn serially: axes, ticks and
text layout, then Agg and the PNG); the interpreter's shutdown ~0.3 s (0.2 s after the imports alone). With
``scipy.stats`` imported where it is used (an experiment on a copy, not committed: not this helper's file) and
otherwise the same code, at load 3.6: 4.39 and 4.55 s besides the draws -> 3.44 and 3.51 s, 4.7 -> 3.95 s of
CPU. A sort of 100,000 draws is as cheap as two partitions and two tail sorts on this numpy (SIMD sort), so
``summarize_draws`` (0.05 s) was left as it is.

Figures formerly in the docs, moved here by issue 30 (the docs say what dominates a cost; measured times
live here, with their machine):

Moved from docs/uncertainty.md:

`benchmarks/bench_montecarlo.py` (thesis laser-tracker scenario, 135 points per draw, geometric
circle fit), measured on the 2-core development machine:

| path | draws/s | 100,000 draws |
| --- | ---: | ---: |
| per-draw loop over the single-capture `identify_cpa` | 74-89 | (19-23 min) |
| batched engine, 1 worker | 20,600 | 4.8 s |
| batched engine, 2 workers | 41,000-43,000 | 2.3-2.4 s |

The batched engine is 230-280x faster than the per-draw loop on one core. The cost grows linearly
with the draws: 0.89, 1.54 and 2.48 s for 2.5x10^4, 5x10^4 and 10^5 draws with 2 workers, i.e.
about 0.35 s to start the workers plus 21 us per draw (the power-law exponent fitted over that
range is 0.74 only because of the fixed part). Peak memory (max RSS of the process
and its workers, every draw kept): 188 MB at 10^5 draws and 811 MB at 10^6 (`--million`). The draws are
written block by block into one preallocated array (no concatenation copy), the coverage intervals
sort one parameter at a time, and the working memory of a batch is bounded by `--batch-size`.

docs/uncertainty.md, adaptive mode: `robotcal uncertainty thesis-laser-tracker --adaptive` stabilised after 107
blocks (1.07x10^6 draws, 30 s with 2 workers).

docs/uncertainty.md, "Why this interval": the study (K = 1000 captures, 1000 draws each) took about 70 s per
case on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from robotcal.api import monte_carlo_problem
from robotcal.identification.cpa import identify_cpa
from robotcal.io import load_scenario
from robotcal.uncertainty.montecarlo import MonteCarloSettings, draw_block, run_monte_carlo

SCENARIO = "thesis-laser-tracker"


def _problem():
    scenario = load_scenario(SCENARIO)
    problem = monte_carlo_problem(scenario)
    return scenario, problem


def per_draw_loop(n_draws: int) -> float:
    """Draws per second of the plain loop over the single-capture CPA."""
    scenario, problem = _problem()
    rng = np.random.default_rng(1)
    began = time.perf_counter()
    for _ in range(n_draws):
        noise = rng.uniform(-1.0, 1.0, size=problem.exact_points.shape) * problem.error_bound[:, None]
        identify_cpa(
            problem.capture.with_points(problem.exact_points + noise),
            scenario.robot,
            scenario.plan.reflector,
            tracker_from_base=scenario.tracker_from_base,
            options=scenario.identification,
        )
    return n_draws / (time.perf_counter() - began)


def engine(n_draws: int, workers: int) -> float:
    """Wall seconds of the batched engine for ``n_draws`` draws (statistics and LPU excluded)."""
    _, problem = _problem()
    settings = MonteCarloSettings(iterations=n_draws, workers=workers, keep_draws=True)
    result = run_monte_carlo(problem, settings, seed=1, linearised=False)
    return result.timings_s["draws"]


def cpu_per_draw(scenario: str, repeat: int = 3, n_draws: int = 4_000) -> dict:
    """CPU microseconds per draw of ``draw_block`` (2,000-draw batches, best of ``repeat`` blocks) and the
    minor page faults per draw, in this process."""
    import resource

    problem = monte_carlo_problem(load_scenario(scenario))
    draw_block(problem, 1, 0, 2_000, 2_000)  # warm-up
    best = float("inf")
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for block in range(repeat):
        began = time.process_time()
        draw_block(problem, 7, block, n_draws, 2_000)
        best = min(best, time.process_time() - began)
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
    return {"cpu_us_per_draw": best / n_draws * 1e6, "minor_faults_per_draw": faults / (repeat * n_draws)}


def peak_memory_mb(n_draws: int, workers: int) -> float:
    """Max RSS [MB] of a fresh process (and its workers) running ``n_draws`` draws with statistics."""
    here = os.path.dirname(os.path.abspath(__file__))
    code = (
        "import resource, sys\n"
        f"sys.path.insert(0, {here!r})\n"
        "from bench_montecarlo import _problem\n"
        "from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo\n"
        "_, problem = _problem()\n"
        f"run_monte_carlo(problem, MonteCarloSettings(iterations={n_draws}, workers={workers}), seed=1)\n"
        "own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss\n"
        "print(max(own, kids) / 1024)\n"
    )
    output = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(output.stdout.strip().splitlines()[-1])


def whole_command(n_draws: int, *, model: str = "cpa", scenario: str = "kr5-demo", repeat: int = 1) -> dict:
    """``robotcal uncertainty SCENARIO -n N --model MODEL`` as a subprocess (best of ``repeat`` by overhead).

    Returns the wall time, the draws' time the command records in ``parameters.json`` and the
    overhead (wall - draws), in seconds, with the load average at the end.
    """
    robotcal = Path(sys.executable).with_name("robotcal")
    best = None
    for _ in range(repeat):
        with tempfile.TemporaryDirectory(prefix="bench-mc-") as folder:
            out = Path(folder) / "uncertainty"
            command = [str(robotcal), "uncertainty", scenario, "-n", str(n_draws), "--model", model, "--out", str(out)]
            began = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            wall = time.perf_counter() - began
            timings = json.loads((out / "parameters.json").read_text(encoding="utf-8"))["timings_s"]
        figures = {"wall_s": round(wall, 3), "draws_s": round(timings["draws"], 3)}
        figures["overhead_s"] = round(wall - timings["draws"], 3)
        if best is None or figures["overhead_s"] < best["overhead_s"]:
            best = figures
    best.update(command=f"robotcal uncertainty {scenario} -n {n_draws} --model {model}", load_average=os.getloadavg())
    return best


def _print_command(figures: dict) -> None:
    print(
        f"whole command `{figures['command']}`: {figures['wall_s']:.2f} s wall, {figures['draws_s']:.2f} s of draws, "
        f"{figures['overhead_s']:.2f} s besides (target <= 1 s); load average "
        + ", ".join(f"{x:.2f}" for x in figures["load_average"])
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=100_000, help="draws of the timed engine runs")
    parser.add_argument("--loop", type=int, default=300, help="draws of the per-draw reference loop")
    parser.add_argument("--million", action="store_true", help="also measure peak memory at 10^6 draws")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    parser.add_argument("--command-only", action="store_true", help="only time the whole `robotcal uncertainty`")
    parser.add_argument("--repeat", type=int, default=1, help="whole command: best of this many runs")
    parser.add_argument("--cpu-per-draw", action="store_true", help="only the CPU cost per CPA draw (2 scenarios)")
    args = parser.parse_args()
    if args.cpu_per_draw:
        figures = {name: cpu_per_draw(name, repeat=max(args.repeat, 3)) for name in ("kr5-demo", SCENARIO)}
        for name, values in figures.items():
            print(
                f"{name}: {values['cpu_us_per_draw']:.1f} us CPU per draw, "
                f"{values['minor_faults_per_draw']:.2f} minor page faults per draw; load average "
                + ", ".join(f"{x:.2f}" for x in os.getloadavg())
            )
        if args.json:
            Path(args.json).write_text(json.dumps({"cpu_per_draw": figures}, indent=2), encoding="utf-8")
        return
    if args.command_only:
        figures = whole_command(args.draws, repeat=args.repeat)
        _print_command(figures)
        if args.json:
            Path(args.json).write_text(json.dumps({"whole_command": figures}, indent=2), encoding="utf-8")
        return
    _, problem = _problem()
    print(f"scenario {SCENARIO}: {problem.n_points} points per draw; CPU cores visible: {os.cpu_count()}")
    engine(2_000, 1)  # warm-up (imports, caches)
    loop_rate = per_draw_loop(args.loop)
    figures = {"per_draw_loop_draws_per_s": loop_rate}
    print(f"{'path':<28} {'draws':>9} {'time_s':>8} {'draws/s':>10} {'speed-up':>9}")
    print(
        f"{'per-draw loop (identify_cpa)':<28} {args.loop:>9} {args.loop / loop_rate:>8.2f} {loop_rate:>10.0f} {1:>9.1f}"
    )
    for workers in (1, 2):
        seconds = engine(args.draws, workers)
        rate = args.draws / seconds
        figures[f"engine_{workers}_workers_s"] = seconds
        print(
            f"{f'batched engine, {workers} worker(s)':<28} {args.draws:>9} {seconds:>8.2f} {rate:>10.0f} {rate / loop_rate:>9.1f}"
        )
    sizes = [args.draws // 4, args.draws // 2, args.draws]
    times = [engine(size, 2) for size in sizes]
    exponent = float(np.polyfit(np.log(sizes), np.log(times), 1)[0])
    figures["scaling_exponent"] = exponent
    print("cost vs draws (2 workers): " + ", ".join(f"{s}: {t:.2f} s" for s, t in zip(sizes, times, strict=True)))
    slope, intercept = np.polyfit(sizes, times, 1)
    figures["linear_fit"] = {"fixed_s": float(intercept), "per_draw_us": float(slope * 1e6)}
    print(f"fitted exponent of time vs draws: {exponent:.3f} (1 = linear)")
    print(f"linear fit: time = {intercept:.2f} s + {slope * 1e6:.1f} us x draws (the fixed part starts the workers)")
    memory = peak_memory_mb(args.draws, 2)
    figures["peak_rss_mb"] = {str(args.draws): memory}
    print(f"peak memory (max RSS, draws kept): {memory:.0f} MB at {args.draws} draws")
    if args.million:
        big = peak_memory_mb(1_000_000, 2)
        figures["peak_rss_mb"]["1000000"] = big
        print(f"peak memory (max RSS, draws kept): {big:.0f} MB at 1,000,000 draws")
    figures["whole_command"] = whole_command(args.draws, repeat=args.repeat)
    _print_command(figures["whole_command"])
    if args.json:
        with open(args.json, "w", encoding="utf-8") as stream:
            json.dump(figures, stream, indent=2)


if __name__ == "__main__":
    main()
