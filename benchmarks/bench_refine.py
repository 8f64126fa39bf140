"""Benchmark of the least-squares refinement on the thesis's test-2 layout (580 points, Table 4.4).

Plain script: ``python benchmarks/bench_refine.py [--repeat N]`` prints, per criterion and start,
the iterations (Jacobian evaluations), residual evaluations, wall time (best of N) and the mean
validation error before/after. Synthetic data: a perturbed KR 5 sixx R650 (0.3 mm / 0.05 deg),
laser-tracker noise (A = 10 um, B = 2.5 um/m, uniform), 100 random validation poses.
Targets (docs/refinement.md): < 50 Jacobian evaluations; points < 2 s, distances < 10 s on 2 cores.

Figures formerly in the docs, moved here by issue 30 (the docs say what dominates a cost; measured times
live here, with their machine):

Moved from docs/refinement.md (time: best of 3 runs, on 2 shared CPU cores, load average 0.40 at the
start, 0.56 at the end, from `uptime`):

| criterion | start | residuals | Jacobian evaluations | time | validation mean error | improvement |
| --- | --- | --- | --- | --- | --- | --- |
| points | nominal | 1,740 | 4 | 0.04 s | 0.0154 mm | 98.8 % |
| points | CPA | 1,740 | 3 | 0.03 s | 0.0154 mm | 98.8 % |
| distances | nominal | 167,620 | 3 | 1.26 s | 0.0161 mm | 98.8 % |
| distances | CPA | 167,620 | 3 | 1.24 s | 0.0161 mm | 98.8 % |
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np

from robotcal.errors import IdentifiabilityWarning
from robotcal.identification import identify_cpa
from robotcal.identification.evaluation import point_errors
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.instruments import Instrument
from robotcal.io import load_robot
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation import simulate_capture
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses, simulate_poses, thesis_test2_plan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="timed repetitions (best is shown)")
    args = parser.parse_args()
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    plan = thesis_test2_plan()
    tracker = np.array([[0.0, 1.0, 0.0, 1800.0], [-1.0, 0.0, 0.0, 5.0], [0.0, 0.0, 1.0, 600.0], [0, 0, 0, 1.0]])
    instrument = Instrument(name="thesis-laser-tracker", a_mm=0.010, b_mm_per_m=0.0025, noise="uniform")
    truth = perturb_parameters(robot, length_sd_mm=0.3, angle_sd_deg=0.05, rng=3)
    capture, _ = simulate_capture(robot, plan, instrument, tracker, true_parameters=truth, joint_limits="ignore", rng=1)
    readings = random_poses(robot, 100, rng=5)
    validation, _ = simulate_poses(robot, readings, plan.reflector, instrument, tracker, true_parameters=truth, rng=6)
    nominal = ParameterSet.nominal(robot)
    cpa = identify_cpa(capture, robot, plan.reflector, tracker_from_base=tracker).parameters
    nominal_error = point_errors(validation, nominal, plan.reflector).mean()
    print(f"capture: {capture.n_points} points; CPU cores visible: {os.cpu_count()}")
    print(
        f"validation mean error: nominal {nominal_error:.4f} mm, CPA "
        f"{point_errors(validation, cpa, plan.reflector).mean():.4f} mm"
    )
    header = f"{'criterion':<10} {'start':<8} {'residuals':>9} {'njev':>5} {'nfev':>5} {'time_s':>7} {'val_mean_mm':>11} {'improv_%':>8}"
    print(header)
    print("-" * len(header))
    for criterion in ("points", "distances"):
        for label, start in (("nominal", nominal), ("cpa", cpa)):
            times = []
            for _ in range(args.repeat):
                began = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", IdentifiabilityWarning)
                    result = refine_parameters(
                        capture,
                        start,
                        plan.reflector,
                        settings=RefinementSettings(criterion=criterion),
                    )
                times.append(time.perf_counter() - began)
            error = point_errors(validation, result.parameters, plan.reflector).mean()
            print(
                f"{criterion:<10} {label:<8} {result.fit.n_residuals:>9} {result.njev:>5} {result.nfev:>5} "
                f"{min(times):>7.2f} {error:>11.4f} {100 * (1 - error / nominal_error):>8.2f}"
            )


if __name__ == "__main__":
    main()
