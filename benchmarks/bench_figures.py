"""Benchmark of the report figures: Monte Carlo histograms and the TCP figures.

Plain script: ``python benchmarks/bench_figures.py [--draws N] [--repeat R]`` runs the Monte Carlo
of the built-in KR 5 scenario with ``N`` draws (default 100,000, as ``robotcal uncertainty -n
100000``) once, then times (best of R) writing the per-joint histogram PNGs
(:func:`robotcal.plots.montecarlo.write_histograms`), the TCP pose figures (scatter, histograms)
for 100,000 synthetic draws, the trajectory figure, the workspace map, and the five joint-diagnostic
figures of the kr5-demo capture, and the convergence figure. Each line gives the best wall time and the best CPU time (the CPU
time suffers less from other jobs on a shared machine). The figures quoted in the issue notes come
from this script.

Before/after (CPU seconds of one figure set, measured under load on the shared 2-core machine, the
old code run from a copy of the tree in the same minutes; noisy to +-30 %; this script with
``--draws 20000 --repeat 2`` at load average 2.1-2.2, before -> after):

- joint figures (5 figures x 6 panels): 5.0 -> 2.5 s by fixed margins instead of constrained layout,
  one legend per figure instead of six ``loc="best"`` searches, titles at a fixed height and 5 ticks
  an axis; then -> ~2.0 s by drawing all five on one reused figure (same PNG bytes as new figures);
- TCP scatter 0.35 -> 0.23, TCP histograms 0.86 -> 0.40, trajectory 0.90 -> 0.51, workspace map
  0.63 -> 0.34 (fixed margins; the workspace histogram one step artist);
- Monte Carlo histograms (they already had fixed margins and ``stairs``): joints with the same panel
  grid drawn on one reused figure, 1.7-2.2 -> 1.1-1.6 s for a set (same PNG bytes; measured with
  3000 draws, thesis-laser-tracker and kr5-demo).

Issue 13 (the demo's 23 figures, replayed from the arguments the demo passed, best of 2, measured under
heavy load, load average 8-10 on the 2 shared cores, old code and new code run in the same minutes):
9.3 -> 7.0 s of CPU in all, with the same pixels in 21 of the 23 files:

- PNG encoding by :func:`robotcal.plots.figures.encode_png` (rows unfiltered, zlib level 3) instead of
  Pillow (adaptive row filters, level 6): ~0.95 -> ~0.2 s for the 23 files, 2.63 -> 2.55 MB;
- text laid out once per process (:class:`robotcal.plots.figures.TextCacheRenderer`: 1240 strings
  drawn, 448 distinct), figures off pyplot's registry;
- convergence 0.67 -> 0.27 s: fixed margins instead of constrained layout, titles at a fixed height,
  log labels as plain text (10⁻²) instead of mathtext; ISO 9283 0.33 -> 0.15 s (fixed margins).

Figures formerly in the docs, moved here by issue 30 (the docs say what dominates a cost; measured times
live here, with their machine):

docs/tcp.md: the four TCP figures cost 2.7 s of CPU before fixed margins, 1.5 s after, under load.

docs/joints.md: the five joint-diagnostic figures cost about 2 s of CPU instead of about 6 s with fixed
margins and one legend below the panels (measured under load, same machine, same run).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from robotcal.api import monte_carlo_problem, simulate
from robotcal.diagnostics import analyze_joints, fit_harmonics
from robotcal.io import load_robot, load_scenario
from robotcal.io.formats.trajectory_csv import load_trajectory
from robotcal.plots.joints import write_joint_figures
from robotcal.plots.montecarlo import write_histograms
from robotcal.plots.refine import plot_convergence
from robotcal.plots.tcp import plot_tcp_histograms, plot_tcp_scatter, plot_trajectory, plot_workspace
from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo
from robotcal.uncertainty.tcp import propagate_to_tcp
from robotcal.uncertainty.workspace import workspace_uncertainty

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_tcp import make_draws  # noqa: E402

SCENARIO = "thesis-laser-tracker"
#: RMS residuals per iteration [mm] of the demo's two refinements (the convergence figure's input).
CONVERGENCE = {
    "points": {"criterion": "points", "rms_mm": np.array([0.131, 0.0109, 0.01088, 0.01088])},
    "distances": {
        "criterion": "distances",
        "rms_mm": np.array([0.0497, 0.0145, 0.0145, 0.0145, 0.0145, 0.0145, 0.0145]),
    },
}


def best_of(repeat: int, task) -> tuple[float, float]:
    """Best wall and best CPU seconds of ``repeat`` calls of ``task``."""
    walls, cpus = [], []
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        task()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    problem = monte_carlo_problem(load_scenario(SCENARIO))
    started = time.perf_counter()
    result = run_monte_carlo(problem, MonteCarloSettings(iterations=args.draws, keep_draws=True), seed=1)
    print(f"cpu cores: {os.cpu_count()}")
    print(f"Monte Carlo: {args.draws} draws in {time.perf_counter() - started:.2f} s (not part of the figures)")
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    readings, _ = load_trajectory("kr5-sweep-75", n_joints=robot.n_joints)
    draws = make_draws(robot, args.draws)
    pose = propagate_to_tcp(robot, draws, readings[10], keep_draws=True)
    path = propagate_to_tcp(robot, draws[:2000], readings)
    workspace = workspace_uncertainty(robot, draws[:2000], 1000, rng=1)
    demo = load_scenario("kr5-demo")
    diagnostics = analyze_joints(simulate(demo, rng=0).capture, method=demo.identification.circle_fit)
    model = fit_harmonics(diagnostics, order=2)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        timings = {
            "uncertainty histograms (all joints)": best_of(args.repeat, lambda: write_histograms(result, folder)),
            "TCP scatter": best_of(args.repeat, lambda: plot_tcp_scatter(pose, folder / "scatter.png")),
            "TCP histograms": best_of(args.repeat, lambda: plot_tcp_histograms(pose, folder / "hist.png")),
            "TCP trajectory": best_of(args.repeat, lambda: plot_trajectory(path, folder / "trajectory.png")),
            "TCP workspace map": best_of(args.repeat, lambda: plot_workspace(workspace, folder / "workspace.png")),
            "joint figures (5)": best_of(args.repeat, lambda: write_joint_figures(diagnostics, folder, model=model)),
            "convergence": best_of(args.repeat, lambda: plot_convergence(CONVERGENCE, folder / "convergence.png")),
        }
    print(f"load average {os.getloadavg()[0]:.1f}")
    for name, (wall, cpu) in timings.items():
        print(f"{name}: best {wall:.2f} s wall, {cpu:.2f} s cpu of {args.repeat}")


if __name__ == "__main__":
    main()
