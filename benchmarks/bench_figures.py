"""Benchmark of the report figures: Monte Carlo histograms and the TCP figures.

Plain script: ``python benchmarks/bench_figures.py [--draws N] [--repeat R]`` runs the Monte Carlo
of the built-in KR 5 scenario with ``N`` draws (default 100,000, as ``robotcal uncertainty -n
100000``) once, then times (best of R) writing the per-joint histogram PNGs
(:func:`robotcal.report.montecarlo.write_histograms`), the TCP pose figures (scatter, histograms)
for 100,000 synthetic draws and the trajectory figure. The figures quoted in the issue notes come
from this script.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from robotcal.io import load_robot, load_scenario
from robotcal.io.trajectory_csv import load_trajectory
from robotcal.report.montecarlo import write_histograms
from robotcal.report.tcp import plot_tcp_histograms, plot_tcp_scatter, plot_trajectory
from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo
from robotcal.uncertainty.tcp import propagate_to_tcp
from robotcal.workflow import scenario_monte_carlo

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_tcp import make_draws  # noqa: E402

SCENARIO = "thesis-laser-tracker"


def best_of(repeat: int, task) -> float:
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        task()
        times.append(time.perf_counter() - started)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    problem = scenario_monte_carlo(load_scenario(SCENARIO))
    started = time.perf_counter()
    result = run_monte_carlo(problem, MonteCarloSettings(iterations=args.draws, keep_draws=True), seed=1)
    print(f"cpu cores: {os.cpu_count()}")
    print(f"Monte Carlo: {args.draws} draws in {time.perf_counter() - started:.2f} s (not part of the figures)")
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    readings, _ = load_trajectory("kr5-sweep-75", n_joints=robot.n_joints)
    draws = make_draws(robot, args.draws)
    pose = propagate_to_tcp(robot, draws, readings[10], keep_draws=True)
    path = propagate_to_tcp(robot, draws[:2000], readings)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        timings = {
            "uncertainty histograms (all joints)": best_of(args.repeat, lambda: write_histograms(result, folder)),
            "TCP scatter": best_of(args.repeat, lambda: plot_tcp_scatter(pose, folder / "scatter.png")),
            "TCP histograms": best_of(args.repeat, lambda: plot_tcp_histograms(pose, folder / "hist.png")),
            "TCP trajectory": best_of(args.repeat, lambda: plot_trajectory(path, folder / "trajectory.png")),
        }
    for name, seconds in timings.items():
        print(f"{name}: best {seconds:.2f} s of {args.repeat}")


if __name__ == "__main__":
    main()
