"""Benchmark of the TCP propagation: 100,000 parameter draws x the built-in 75-pose trajectory.

Plain script: ``python benchmarks/bench_tcp.py [--draws N] [--repeat R] [--stage]`` prints draws, poses, wall
time (best of R) and peak memory (tracemalloc, numpy allocations included, measured in a separate
run because tracing slows numpy down). Draws: nominal KR 5 sixx R650 + Gaussian noise on the
identified parameters (0.05 mm, 2e-4 rad), as a Monte Carlo calibration would give. The figure
reported in docs/tcp.md comes from this script. ``--stage`` times instead what the demo's TCP stage
computes (``robotcal run``'s ``tcp_stage``): the Table 5.8 pose and the 75-pose trajectory with
``--draws`` draws, the 1000-pose workspace with the first 10^4 of them, and the validation check's
position covariance at 100 poses with the first 20,000 (about 2e7 forward kinematics at 10^5 draws).

Before/after, the demo's TCP stage (Table 5.8 pose and 75-pose trajectory with the refined model's
20,000 draws, 1000-pose workspace with 10^4 of them; 2 cores; wall seconds):

- before (lead, idle machine): TCP stage 10.0 s in ``robotcal run kr5-demo``; by parts (helper,
  load ~1.3): computing pose 0.11, trajectory 1.45, workspace 5.24; writing pose 2.09, trajectory
  1.20, workspace 1.94 (``tcp.json`` about 1 s of it, the figures the rest).
- after (load 1.9-2.5, so not comparable to the idle figure; CPU seconds in docs/tcp.md): computing
  pose 0.10, trajectory 1.27, workspace 3.96; writing pose 1.35, trajectory 0.76, workspace 1.51. The
  figures cost about half as much (fixed margins); the order statistics come from partitions (half a
  full sort); the forward kinematics are unchanged (about 0.2 us of CPU per draw-pose).
- issue 13 (complex-product chain, pose chunks in two threads with reused buffers, positions-only
  validation check, tcp.json one pose per line; load average 7-10 from other jobs on the 2 cores, so
  CPU seconds are the comparable figure): the demo's TCP stage on the same draws, old and new code
  alternating, 13.0-13.9 s of CPU before, 7.9-8.1 s after (workspace 6.6-7.0 -> 4.2-4.5, trajectory
  1.4-1.5 -> 0.9-1.1, validation check 1.3-1.8 -> 0.3, tcp.json 1.3 -> 0.35 with its dict), wall
  under that load 39 s -> 18-21 s; the chain alone 400 -> 150-175 ns of CPU per draw-pose. Without
  ``--stage`` (100,000 draws x 75 poses, whole script): 17.1 -> 13.1 s of CPU.
- issue 13, second pass (angles as the nominal plus a series arctan of the turned vector, checked per
  block; pose chunks as large as max_bytes allows with the threads sharing each chunk; X, Y turned by
  the first joint per chunk; covariances by upper-triangle rows; tcp.csv a row per %-format): the
  demo's ``tcp_stage`` alone on a saved run (load average 4-5.6, old and new alternating, 3 pairs of
  2 runs) 4.7-6.4 s of CPU before (median 5.5), 4.8-5.4 after (median 4.9); the 1000-pose workspace
  map on one thread 3.8-4.0 -> 3.3-3.4 s of CPU; the angles 93 -> 61 ns per draw-pose.
- issue 23 (the series arctan replaced by ``np.arctan2`` of the turned vector; 2026-11-28, 2 alternated
  rounds, load below 1; best / median of 3): 05de958 1.47 / 1.56 s and 1.36 / 1.44 s, c0e2034 1.36 / 1.46 s
  and 1.36 / 1.38 s, 385f86a 1.31 / 1.35 s and 1.38 / 1.38 s: no measurable change at this scale.

- issue 31 (the link factors of every draw once per call up to 256 MiB instead of once per pose chunk when they
  exceed ``max_bytes``; ``position_covariance`` likewise, with one thread pool for its chunks; cos/sin of an
  extended model's turned angles only at the joints it turns; 2026-11-29, 2 shared cores, other jobs running):
  ``robotcal run kr5-demo`` with 100,000 refined draws (compliance model), f71863b then fe30c5b one after the
  other: TCP stage 21.7 s (load 2.5-3.5) -> 14.4 s (load 1.3-2.5); trajectory 7.19 -> 5.01 s, workspace
  4.28 -> 3.65 s, pose 0.72 -> 0.80 s (``seconds`` in each ``tcp.json``); every ``tcp.csv`` and
  ``consistency.json`` byte-identical. On the 20,000 refined draws of ``robotcal uncertainty kr5-demo --model
  refined`` tiled to 100,000, with the compliance joint model and random deflection values, 75 random poses and
  100 for ``position_covariance``: every array bit-identical, 7.1-8.9 s of CPU for the script instead of
  8.1-9.6 s (alternating, load ~2). What is left is the chain and the order statistics of every draw at
  every pose (draws x poses), and the validation check's two ``position_covariance`` calls (deployed and
  estimate: the same draws, the same 100 poses, the same covariance).

Figures formerly in the docs, moved here by issue 30 (the docs say what dominates a cost; measured times
live here, with their machine):

Moved from docs/tcp.md:

Measured before these changes (2 shared CPU cores, load average ~2.9 from other jobs, numpy 2.4): 100,000 draws x 75
poses in **8.5 s** (best of 2; about 1.1 µs per draw-pose including statistics and the linearised
result), peak traced memory **149 MiB** (the draws array itself 23 MiB). The time grows linearly
with draws x poses; memory is bounded by `max_bytes` and the block size, not by the pose count.
After the changes above (issue 13; same machine, load average 7-10, so CPU seconds compare): the
demo's TCP stage on the same draws takes 7.9-8.1 s of CPU instead of 13.0-13.9 s, outputs equal to
1e-11 relative (summation order); the 100,000 x 75 benchmark script 13.1 instead of 17.1 s of CPU,
peak traced memory 183 MiB. Then (the angles from the series above, chunks of as many poses as fit with
the threads sharing each chunk, X and Y turned by the first joint once per chunk on contiguous rows,
covariances by rows of the upper triangle, `tcp.csv` formatted a row at a time): the TCP stage alone
(`tcp_stage` on a saved demo run's draws, validation capture and refined model; load average 4-5.6 from
other jobs on the 2 cores, old and new code alternating) 4.8-5.4 s of CPU instead of 4.7-6.4 s (median
4.9 vs 5.5), wall 4.6-7.3 s instead of 5.9-10.3 s; the workspace map alone on one thread 3.3-3.4 instead
of 3.8-4.0 s of CPU, the trajectory 0.52 instead of 0.58-0.61 s.

In the demo (`robotcal demo`, 2 cores), the TCP stage's `seconds` in `run.json` were 3.3-4.6 s at the end of
issue 13's work (7.0-9.8 s for the code of its first part, run alternately with it): the computing alone
(`benchmarks/bench_tcp.py --stage`) takes about 2.6 s of wall and 4.7 s of CPU, and in the demo the stage
shares the two cores with the figure process, which draws the Monte Carlo histograms and the TCP figures
meanwhile. The issue's 3 s for the stage is met by the computing alone, not by the stage inside the demo.

docs/tcp.md, the multilinear expansion tried for the workspace map: in isolation 0.11 vs 0.21 us of CPU per
draw-pose.
"""

from __future__ import annotations

import argparse
import os
import time
import tracemalloc
import warnings

import numpy as np

from robotcal.api import TABLE_5_8_READINGS_DEG
from robotcal.errors import JointLimitWarning
from robotcal.io import load_robot
from robotcal.io.formats.trajectory_csv import load_trajectory
from robotcal.uncertainty.tcp import position_covariance, propagate_to_tcp
from robotcal.uncertainty.workspace import sample_workspace, workspace_uncertainty


def make_draws(robot, n_draws: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    free = ~robot.structurally_fixed
    free[-1, :4] = False  # joint 6 is not identified by CPA
    scale = np.where(np.isin(np.arange(5), [1, 3, 4]), 2e-4, 0.05)
    return robot.nominal + rng.standard_normal((n_draws, robot.n_joints, 5)) * scale * free


def demo_stage(robot, draws, readings, repeat: int) -> None:
    """Best-of-``repeat`` seconds of the three parts of the demo's TCP stage."""
    pose = np.deg2rad(TABLE_5_8_READINGS_DEG)
    parts = {
        "pose (keep draws)": lambda: propagate_to_tcp(robot, draws, pose, keep_draws=True),
        "trajectory": lambda: propagate_to_tcp(robot, draws, readings),
        "workspace 1000 poses x 10^4 draws": lambda: workspace_uncertainty(robot, draws[:10_000], 1000, rng=1),
        "validation check, 100 poses (positions only)": lambda: position_covariance(
            robot, draws[:20_000], sample_workspace(robot, 100, rng=2)
        ),
    }
    total = total_cpu = 0.0
    for name, task in parts.items():
        times, cpu = [], []
        for _ in range(repeat):
            started, started_cpu = time.perf_counter(), time.process_time()
            task()
            times.append(time.perf_counter() - started)
            cpu.append(time.process_time() - started_cpu)  # all threads of the process
        total += min(times)
        total_cpu += min(cpu)
        print(f"{name}: best {min(times):.2f} s of {repeat} (CPU {min(cpu):.2f} s)")
    print(f"TCP stage total (sum of bests): {total:.2f} s, CPU {total_cpu:.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--stage", action="store_true", help="time the demo's TCP stage instead")
    args = parser.parse_args()
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    readings, _ = load_trajectory("kr5-sweep-75", n_joints=robot.n_joints)
    draws = make_draws(robot, args.draws)
    if args.stage:
        warnings.simplefilter("ignore", JointLimitWarning)  # the Table 5.8 pose is outside the file's limits
        print(f"cpu cores: {os.cpu_count()}, draws: {args.draws}, load average {os.getloadavg()[0]:.1f}")
        demo_stage(robot, draws, readings, args.repeat)
        return
    times = []
    for _ in range(args.repeat):
        started = time.perf_counter()
        result = propagate_to_tcp(robot, draws, readings)
        times.append(time.perf_counter() - started)
    tracemalloc.start()
    propagate_to_tcp(robot, draws, readings)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"cpu cores: {os.cpu_count()}")
    print(f"draws: {args.draws}, poses: {result.n_poses}")
    print(f"wall time: best {min(times):.2f} s, median {np.median(times):.2f} s of {args.repeat}")
    print(
        f"peak traced memory during propagation: {peak / 2**20:.0f} MiB (draws array itself: {draws.nbytes / 2**20:.0f} MiB)"
    )
    print(f"largest u(X, Y, Z) along the path: {result.std_uncertainty[:, :3].max(axis=0).round(4)} mm")


if __name__ == "__main__":
    main()
