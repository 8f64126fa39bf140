"""Benchmark of the whole demo: ``robotcal demo --out DIR`` (``robotcal run kr5-demo``) into a temp folder.

Plain script: ``python benchmarks/bench_demo.py [--repeat R] [--keep DIR] [-- OPTIONS]`` runs the
command R times as a subprocess (the installed ``robotcal`` next to this interpreter), each into a fresh
temporary folder, and prints per run the wall time of the command, the CPU time of the process and its
children, the load average before and after, and the per-stage seconds read back from ``run.json``;
then the best run. Timings on a shared machine are noisy: compare runs taken under the same load
(the load average is printed for that reason), or compare CPU seconds, which suffer less from it.

Figures of record (2 cores, kr5-demo: 100,000 CPA draws, 20,000 refined-model draws, 1000 workspace
poses; seconds). "Before": the lead's measurement on an idle machine (issue 13, item 5). "After": this
script, one run, load average 1.1 at the start (other helpers' jobs on the same 2 cores), so the
after column is pessimistic; the report stage had meanwhile been changed by the pipeline work (built
from the run in memory, no second build).

==============  ======  ======  =====================================================================
stage           before  after   what changed (helper H3)
==============  ======  ======  =====================================================================
simulate        0.03    0.03
identify        0.04    0.05
refine          0.6     0.71
evaluate        1.1     1.42
joints          4.5     2.10    figures: fixed margins, one legend, one reused figure (same PNG bytes)
uncertainty     15.3    14.04   histograms on reused figures (same bytes); draws unchanged
tcp             10.0    9.54    figures ~2x cheaper; interval order statistics by partition
plan            2.9     1.98    cell-check and sensitivity figures without constrained layout
report          1.2     0.03    (pipeline work: rendered from the run in memory)
total (wall)    38.4    33.0    CPU 45.8 s for the process and its Monte Carlo workers
==============  ======  ======  =====================================================================

Where the rest goes: the two Monte Carlos (~10 s of draws on 2 workers: CPA fits in
identification/cpa.py and geometry/fits.py, the refinement's normal equations), about 20 PNG figures
(~0.15-0.5 s of CPU each with matplotlib), ``tcp.json`` of the 1000-pose workspace (~0.9 s: building
the dict 0.45 s, ``json.dumps(indent=1)``, the pure-Python encoder, 0.46 s), the validation
consistency check (~1.2 s) and the workspace kinematics (10^7 forward kinematics, ~2 s of CPU).

Issue 13, second part (2026-11-26; the code the first part landed with, "old", and this code, "new", run
alternately, 3 pairs, wall seconds and CPU seconds of the command and its children; the machine's speed
varied by about 20 % between the two sittings):

- first sitting: old 21.9-25.5 s (CPU 31.5-35.5 s), new 11.2-12.8 s (CPU 19.6-21.8 s);
- second sitting: old 25.7-28.6 s (CPU 36.6-40.1 s), new 13.7-14.5 s (CPU 23.1-24.0 s);
- new, stages in the second sitting: refine 1.1-1.4 (scipy.optimize is now imported there, not at start-up),
  uncertainty 5.3-5.7, tcp 4.4-4.5, plan 0.4-0.5, report 0.5-0.7 (its wait for the last figures included).

What changed: the Monte Carlo draws (CPA 64 -> 37 us of CPU per draw, refined model 320 -> 200 us), the TCP
chain and angles, one BLAS thread per process, and the figures drawn by a process forked when the command
starts, while the stages compute (the run's own process imports no matplotlib). CPU is now about 20-24 s for
the two cores: figures ~6 s, Monte Carlo draws ~7.5 s, TCP stage ~5 s, the rest (start-up, refinement,
files, report) ~3 s; the 12 s target is met on the faster days of this machine only.

Issue 13, third part (2026-11-27; the code stop 18 landed, c06e526, "old", and this code, "new", alternately,
6 pairs in one sitting): old 10.97-15.08 s (median 13.5, CPU median 22.8 s), new 11.06-14.15 s (median 12.4,
CPU median 21.9 s); this script, new, 3 runs: 11.9-12.4 s, stages joints 0.2, refine 0.8-1.1, uncertainty
4.6-4.9, tcp 4.0-4.4, plan 0.4, report 0.4-0.6. What changed: the joints stage runs before refine, so that
its five figures (~1.2 s of CPU) are drawn while refine imports scipy and computes on one core (median
-0.6 s on its own, 6 pairs); the report's templates are compiled while the last figures are drawn and its
numeric-column test is cheaper (~0.1 s); the process ends without the interpreter's teardown (~0.2 s).
Then the plan stage before tcp (its two figures drawn while tcp computes the workspace, not at the end): against
the code before it, 6 alternated pairs, median 13.2 -> 12.7 s (pair differences -0.84 to +0.23 s), the report
stage's wait for the last figures 0.55-0.89 -> 0.12-0.16 s, the tcp stage 3.9-4.7 vs 4.1-4.9 s.

All of the third part, in one last sitting (2026-11-27 01:20 UTC; c06e526 run as ``python -c "...main()"``, this
code as the installed ``robotcal``; 6 alternated pairs): old 12.03-13.81 s (median 12.8, CPU median 21.7 s),
new 10.90-12.97 s (median 11.9, CPU median 21.2 s), every pair -0.66 to -1.38 s; stages, new: uncertainty
4.4-5.7, tcp 3.8-4.7 (old 3.4-4.6: the plan figures are drawn during it now), plan 0.5-0.8, report 0.10-0.14
(old 0.46-0.67).

Tried and rejected (2026-11-27 01:47-01:49 UTC, the machine on a fast spell; 4 rounds of the three settings in turn):
the figure worker at a lower priority (``os.nice`` 10 or 19 in the worker), so that the TCP stage gets the
cores first. It only moves time: the tcp stage fell from 3.5-3.9 s (nice 0) to 2.6-3.6 s, but the report then
waited 1.1-2.1 s for the figures held back (0.09-0.12 s at nice 0), and the whole demo was no faster (nice 0
10.0-10.7 s, nice 10 10.2-11.6 s, nice 19 9.4-12.4 s). CPU per process in one run (nice 0): the run 8.4 s, the
figure worker 5.1 s, the CPA Monte Carlo's two workers 3.4 s, the refined model's 2.9 s, the histogram helpers
0.65 s; 20.5 s on 2 cores is at least 10.3 s of wall.

Issue 23 (2026-11-27/28; the standard machinery: figures in a ``concurrent.futures`` pool, plain matplotlib, a
normal exit, the stages in the method's order; 6 alternated runs in one sitting): 05de958 (before) 7.96-9.05 s,
median 8.31 s; c0e2034 (issue 23 done) 9.43-10.64 s, median 9.86 s: 1.19x (the issue's bound: 1.3x).

Issue 22 (2026-11-28; the demo's robot sags under gravity, its calibration adds 30 calibration poses, chooses
the joint model by 5-fold cross-validation and deploys the compliance model; 5,000 refined draws of that model,
``montecarlo.refined_iterations``): 17.80-18.73 s, median 18.1 s, 6 runs; stages refine ~3 s (the geometric,
compliance and harmonic fits with their cross-validation), uncertainty ~8.8 s (CPA 100,000 draws ~1.4 s; the
5,000 extended draws ~7 s, on one core, since they make one block of the 10^4-draw reproducibility unit), tcp ~3 s.
Then the refined draws in blocks of 10^3 (``REFINED_BLOCK_SIZE``: five blocks for the two workers), this script, 4
runs, load average 1.1-2.0: 18.2-18.9 s, CPU 29.4-31.8 s; stages refine 3.1-4.3, uncertainty 7.0-8.8, tcp 3.6-3.9,
report 0.5-2.0 s. No faster: the demo needs ~30 s of CPU and the second core was already drawing figures while the
draws ran on one, so on 2 cores the blocks only move time between stages (the refined Monte Carlo alone, 5,000
geometric draws on 2 workers: 0.57-0.75 s instead of 0.80-1.06 s).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def robotcal_command() -> list[str]:
    """The ``robotcal`` console script of this interpreter's environment (falls back to ``python -m``)."""
    script = Path(sys.executable).with_name("robotcal")
    return [str(script)] if script.exists() else [sys.executable, "-m", "robotcal.cli"]


def children_cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_once(folder: Path, extra: list[str]) -> dict:
    """Run the demo into ``folder``; returns wall and CPU seconds, loads and the stages of ``run.json``."""
    load_before = os.getloadavg()[0]
    cpu_before = children_cpu_seconds()
    started = time.perf_counter()
    completed = subprocess.run(
        [*robotcal_command(), "demo", "--out", str(folder), *extra],
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - started
    cpu = children_cpu_seconds() - cpu_before
    if completed.returncode != 0:
        raise SystemExit(f"robotcal run failed ({completed.returncode}):\n{completed.stderr[-4000:]}")
    record = json.loads((folder / "run.json").read_text(encoding="utf-8"))
    stages = record.get("stages", {})
    if isinstance(stages, list):  # tolerate a list of {"name", "seconds"} entries
        stages = {entry["name"]: entry for entry in stages}
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "load_before": load_before,
        "load_after": os.getloadavg()[0],
        "run_seconds": record.get("seconds"),
        "stages": {name: entry.get("seconds") for name, entry in stages.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--keep", type=Path, help="also keep the last run's folder here (replaced)")
    parser.add_argument("extra", nargs="*", help="further options of `robotcal demo` (after --), e.g. --draws")
    args = parser.parse_args()
    print(f"cpu cores: {os.cpu_count()}, command: {' '.join(robotcal_command())} demo")
    runs = []
    for k in range(args.repeat):
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp) / "run"
            if args.keep is not None and k == args.repeat - 1:
                folder = args.keep
            outcome = run_once(folder, args.extra)
        runs.append(outcome)
        stages = ", ".join(
            f"{name} {seconds:.2f}" for name, seconds in outcome["stages"].items() if seconds is not None
        )
        print(
            f"run {k + 1}: wall {outcome['wall_s']:.1f} s, cpu {outcome['cpu_s']:.1f} s, "
            f"load {outcome['load_before']:.1f} -> {outcome['load_after']:.1f}; stages (s): {stages}"
        )
    best = min(runs, key=lambda run: run["wall_s"])
    print(f"best wall {best['wall_s']:.1f} s of {len(runs)} (cpu {best['cpu_s']:.1f} s)")


if __name__ == "__main__":
    main()
