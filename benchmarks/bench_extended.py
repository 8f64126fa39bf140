"""Benchmark of the extended model (issue 22): an extended refinement of 100 poses x 3 flange targets, the
compensation of 1,000 poses, and the extended refined Monte Carlo per draw.

Plain script: ``python benchmarks/bench_extended.py [--repeat N]`` prints the best of N wall times. Synthetic
data: a perturbed KR 5 sixx R650 (0.3 mm / 0.1 deg) with J2/J3 compliance (5e-5, 2e-4 rad/(N m)), a 3 kg
payload and first-order harmonic errors on every joint (0.01 deg), laser-tracker noise (10 um + 2.5 um/m,
normal). Targets (issue 22): compensation of 1,000 poses in under 1 s.

Figures of record (2026-11-28, 2 cores, load below 1, ``--repeat 3``): extended refine (38 unknowns, 300 points)
from nominal 0.032 s, 4 Jacobian evaluations; ``refine --model auto`` (4 models x (1 + 5 folds) fits) 0.97 s;
compensation of 1,000 poses 0.137 s, 5 Newton steps, largest remaining error 1.0e-8 mm; the demo's refined
Monte Carlo, 1,000 draws with its set-up, geometric 0.82 s, compliance 2.08 s. The extended draws alone (600
draws on one core after a first run, 3 alternated rounds): 1.56-1.57 ms per draw in vectorised calls of 32 draws
(``EXTENDED_REFINE_BATCH``), 2.12-2.14 ms in calls of 100: the point-by-point working arrays then outgrow the cache.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
import warnings

import numpy as np

import robotcal
from robotcal.errors import IdentifiabilityWarning
from robotcal.identification.refine import refine_parameters
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io import load_robot
from robotcal.kinematics.inverse import tool_frames
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.generator import simulate_target_poses

TRACKER = np.array([[1.0, 0, 0, 1800.0], [0, 1.0, 0, 0], [0, 0, 1.0, 600.0], [0, 0, 0, 1.0]])
TARGETS = (
    Target(name="A", frame="flange", positions=[60.0, 40.0, 30.0]),
    Target(name="B", frame="flange", positions=[-50.0, 60.0, 20.0]),
    Target(name="C", frame="flange", positions=[0.0, -70.0, 40.0]),
)


def _best(function, repeat: int) -> tuple[float, object]:
    best, value = float("inf"), None
    for _ in range(repeat):
        started = time.perf_counter()
        value = function()
        best = min(best, time.perf_counter() - started)
    return best, value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="timed repetitions (best is shown)")
    args = parser.parse_args()
    robot = load_robot("kuka-kr5-sixx-r650")
    robot = dataclasses.replace(robot, masses=robot.masses.with_payload(3.0, [0.0, 0.0, 60.0]))
    rng = np.random.default_rng(3)
    truth = robotcal.perturb(robot, length_sd_mm=0.3, angle_sd_deg=0.1, rng=3)
    model = JointModel.build(robot, compliance_joints=[1, 2], masses=robot.masses, harmonic_joints=range(6))
    truth = truth.replace(joint_model=model.with_values(np.r_[5e-5, 2e-4, rng.normal(0, np.deg2rad(0.01), 12)]))
    readings = rng.uniform(robot.limits[:, 0] * 0.9, robot.limits[:, 1] * 0.9, (100, 6))
    tracker = Instrument(name="laser tracker", a_mm=0.010, b_mm_per_m=0.0025, noise="normal")
    capture, _ = simulate_target_poses(robot, readings, TARGETS, tracker, TRACKER, true_parameters=truth, rng=rng)
    start = ParameterSet(robot=robot, values=robot.nominal, joint_model=model)
    print(f"CPU cores visible: {os.cpu_count()}; capture {capture.n_points} points (100 poses x 3 targets)")

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        seconds, result = _best(lambda: refine_parameters(capture, start, TARGETS, tracker_from_base=TRACKER), args.repeat)
    print(
        f"extended refine (compliance+harmonic, {len(result.identifiability.free_names)} unknowns) from nominal: "
        f"{seconds:.3f} s, "
        f"{result.njev} Jacobian evaluations, residual RMS {result.fit.residual_rms * 1e3:.1f} um"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        seconds, choice = _best(
            lambda: robotcal.refine(capture, robot, targets=TARGETS, tracker_from_base=TRACKER, model="auto", health="off"),
            1,
        )
    print(f"refine --model auto (4 models x (1 + 5 folds) fits): {seconds:.2f} s, chose {choice.model}")

    calibrated = result.parameters
    limits = np.rad2deg(robot.limits)
    poses = np.random.default_rng(0).uniform(limits[:, 0] * 0.8, limits[:, 1] * 0.8, (4000, 6))
    _, jacobian = tool_frames(ParameterSet.nominal(robot), np.deg2rad(poses), np.eye(4))
    regular = poses[np.linalg.cond(jacobian * np.r_[1, 1, 1, 700, 700, 700][:, None]) < 100][:1000]
    seconds, compensated = _best(lambda: robotcal.compensate(calibrated, poses_deg=regular), args.repeat)
    print(
        f"compensate 1,000 poses: {seconds:.3f} s ({compensated.iterations} Newton steps, largest remaining error "
        f"{np.nanmax(compensated.position_error_mm):.1e} mm); target < 1 s: {'met' if seconds < 1.0 else 'NOT met'}"
    )

    scenario = robotcal.load_scenario("kr5-demo")
    demo_truth = robotcal.perturb(scenario, rng=11)
    estimate = robotcal.refine(
        robotcal.calibration_capture(
            scenario,
            robotcal.simulate(scenario, rng=1, true_parameters=demo_truth),
            robotcal.simulate_poses(scenario, kind="calibration", rng=3, true_parameters=demo_truth),
        ),
        scenario,
        model="compliance",
        folds=0,
        health="off",
    )
    for label, parameters in (("geometric", estimate.parameters.geometric()), ("compliance", estimate.parameters)):
        seconds, mc = _best(
            lambda parameters=parameters: robotcal.monte_carlo(
                scenario, parameters=parameters, model="refined", draws=1000, rng=1, keep_draws=False
            ),
            1,
        )
        print(f"kr5-demo refined Monte Carlo, {label} model, 1,000 draws (circles + 30 poses): {seconds:.2f} s "
              f"({seconds * 1e3 / mc.n_draws:.2f} ms per draw)")  # fmt: skip


if __name__ == "__main__":
    main()
