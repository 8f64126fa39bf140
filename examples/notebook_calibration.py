"""Calibrate from a capture CSV and a robot in a notebook, without writing any TOML (cells for Jupyter or VS Code).

What it shows
    The core API on explicit objects (docs/api.md): a robot (``robotcal.load_robot``), a capture CSV read
    with ``robotcal.read_capture``, the target the points were measured on (a ``ReflectorMount``), the
    instrument and the base frame; no scenario file anywhere. Circle Point Analysis (thesis ch. 4.4-4.5),
    the least-squares refinement (ch. 4.5.7) with its fit health and cross-validation, the Monte Carlo
    uncertainty of the parameters (ch. 5.2.3) and the TCP uncertainty at a pose (ch. 5.3), then the
    parameter JSON. Each ``# %%`` line starts a cell; every result prints a compact summary.

    The capture CSV is first made here (a simulated KR 5 sixx R650 on the thesis's Table 5.1 plan) so that the
    example runs anywhere; with a real capture, start at the second cell.

Run
    python examples/notebook_calibration.py --out notebook-example [--quick]

    ``--quick`` uses 500 Monte Carlo draws instead of 5,000.
"""

# %% Set-up: what a cell has (no TOML): the robot, the instrument, where the robot base sits, the target
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import robotcal

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", type=Path, default=Path("notebook-example"))
parser.add_argument("--quick", action="store_true", help="500 Monte Carlo draws instead of 5,000")
args, _ = parser.parse_known_args()  # (a notebook passes its own arguments)
args.out.mkdir(parents=True, exist_ok=True)

robot = robotcal.load_robot("kuka-kr5-sixx-r650")
instrument = robotcal.Instrument(name="laser tracker", a_mm=0.010, b_mm_per_m=0.0025, noise="uniform")
tracker_from_base = np.array(  # where the robot base sits in the tracker frame [mm]
    [[0.0, 1.0, 0.0, 1867.0], [-1.0, 0.0, 0.0, 5.0], [0.0, 0.0, 1.0, 625.5], [0.0, 0.0, 0.0, 1.0]]
)
# one reflector per circle, in the frame of the joint before it (thesis eq. 5-1) [mm]
reflector = robotcal.ReflectorMount(
    frame="joint",
    positions=[[100, 0, 0], [200, 0, 0], [0, 50, 0], [20, 0, 0], [0, 80, 0], [0, 60, 0]],
)
plan = robotcal.CapturePlan(
    start=np.deg2rad([15.0, 0, 0, 0, 0, 0]),
    sweep=np.deg2rad([45.0, 80, 100, 50, 100, 300]),
    points=np.array([15, 20, 30, 15, 25, 30]),
    reflector=reflector,
)
# the stand-in for the tracker's export: a perturbed robot measured along the plan, written as a capture CSV
truth = robotcal.perturb(robot, rng=11)
simulated = robotcal.simulate(robot, plan, instrument=instrument, tracker_from_base=tracker_from_base,
                              true_parameters=truth, rng=1)  # fmt: skip
csv_path = robotcal.write_capture(args.out / "capture.csv", simulated)

# %% Read the capture: readings in degrees and points in mm, every problem named by file, line and column
capture = robotcal.read_capture(csv_path, n_joints=robot.n_joints)
print(capture)  # Capture(...: 135 points, 6 joints, circles 1,...,6)

# %% Circle Point Analysis: each circle gives a joint axis, adjacent axes give the parameters
cpa = robotcal.identify(capture, robot, target=reflector, tracker_from_base=tracker_from_base, instrument=instrument)
print(cpa)
print(cpa.health.line())

# %% Refinement over every point (points criterion, the base frame held), cross-validated by pose
refined = robotcal.refine(
    capture, robot, cpa, targets=reflector, tracker_from_base=tracker_from_base, instrument=instrument, folds=5
)
print(refined.health.line())
print(f"calibration RMS {refined.cross_validation.calibration_rms_mm * 1e3:.1f} um, "
      f"cross-validated {refined.cross_validation.cv_rms_mm * 1e3:.1f} um")  # fmt: skip
# the columns of a parameter table are d, theta, a, alpha, beta: lengths [mm] in 0 and 2, angles [rad] in 1, 3, 4
LENGTHS = np.zeros(refined.identifiability.free.shape, dtype=bool)
LENGTHS[:, [0, 2]] = True
error = np.abs(refined.parameters.difference(truth))
print(f"largest error against the truth: {error[refined.identifiability.free & LENGTHS].max():.4f} mm (lengths), "
      f"{np.degrees(error[refined.identifiability.free & ~LENGTHS]).max():.5f} deg (angles)")  # fmt: skip

# %% Monte Carlo (GUM Supplement 1) of the deployed model, simulated at its estimate, and the TCP at a pose
draws = 500 if args.quick else 5000
uncertainty = robotcal.monte_carlo(
    robot, plan=plan, instrument=instrument, tracker_from_base=tracker_from_base, parameters=refined,
    model="refined", draws=draws, rng=7,
)  # fmt: skip
u = uncertainty.summary.std_uncertainty
print(f"{uncertainty.n_draws} draws: largest u {u[uncertainty.identified & LENGTHS].max():.4f} mm (lengths), "
      f"{np.degrees(u[uncertainty.identified & ~LENGTHS]).max():.5f} deg (angles)")  # fmt: skip
tcp = robotcal.tcp_uncertainty(robot, uncertainty, [[10.0, 40.0, 30.0, 5.0, 45.0, 0.0]], tool_mm=[0, 0, 100])
print(f"TCP position uncertainty at the pose: {tcp.position_uncertainty[0] * 1e3:.2f} um")

# %% The calibrated parameters, as a parameter JSON (mm, deg) that robotcal export and predict read
path = robotcal.write_parameters(args.out / "refined.json", refined.parameters)
print(f"wrote {path}")
