"""Benchmark of the TCP propagation: 100,000 parameter draws x the built-in 75-pose trajectory.

Plain script: ``python benchmarks/bench_tcp.py [--draws N] [--repeat R]`` prints draws, poses, wall
time (best of R) and peak memory (tracemalloc, numpy allocations included, measured in a separate
run because tracing slows numpy down). Draws: nominal KR 5 sixx R650 + Gaussian noise on the
identified parameters (0.05 mm, 2e-4 rad), as a Monte Carlo calibration would give. The figure
reported in docs/tcp.md comes from this script.
"""

from __future__ import annotations

import argparse
import os
import time
import tracemalloc

import numpy as np

from robotcal.io import load_robot
from robotcal.io.trajectory_csv import load_trajectory
from robotcal.uncertainty.tcp import propagate_to_tcp


def make_draws(robot, n_draws: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    free = ~robot.structurally_fixed
    free[-1, :4] = False  # joint 6 is not identified by CPA
    scale = np.where(np.isin(np.arange(5), [1, 3, 4]), 2e-4, 0.05)
    return robot.nominal + rng.standard_normal((n_draws, robot.n_joints, 5)) * scale * free


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    readings, _ = load_trajectory("kr5-sweep-75", n_joints=robot.n_joints)
    draws = make_draws(robot, args.draws)
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
