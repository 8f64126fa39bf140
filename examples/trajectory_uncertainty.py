"""Propagate the uncertainty of a calibrated robot to its TCP along a trajectory, and plot it.

What it shows
    The uncertainty of the *deployed* model (thesis ch. 5.2.3 and 5.3, docs/tcp.md):

    1. a calibration: a simulated kr5-demo capture of a perturbed robot, identified by CPA and refined
       (points criterion);
    2. :func:`robotcal.monte_carlo` with ``model="refined"``: every draw is a noisy capture made on the
       refined estimate, identified and refined again, so the draws spread as the deployed parameters do;
    3. :func:`robotcal.tcp_uncertainty` along the built-in 75-pose trajectory ``kr5-sweep-75`` (KUKA
       controller readings, hence the robot ``kuka-kr5-sixx-r650-krc``: the same model, read as the
       controller counts its axes), with a 100 mm tool;
    4. a plot of u(X), u(Y), u(Z) and of the position uncertainty sqrt(u_X^2 + u_Y^2 + u_Z^2) along
       the trajectory, Monte Carlo beside the linearised propagation of the same draws.

Run
    python examples/trajectory_uncertainty.py --out trajectory-example   # 2000 draws, each a refinement: the cost
    python examples/trajectory_uncertainty.py --quick                    # 200 draws (the test suite)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import robotcal

TOOL_MM = [0.0, 0.0, 100.0]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("trajectory-example"), help="output folder")
    parser.add_argument("--draws", type=int, default=2000, help="Monte Carlo draws of the refined model")
    parser.add_argument("--quick", action="store_true", help="200 draws")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    draws = 200 if args.quick else args.draws
    args.out.mkdir(parents=True, exist_ok=True)

    # 1. the calibration whose uncertainty is stated
    scenario = robotcal.load_scenario("kr5-demo")
    truth = robotcal.perturb(scenario, rng=args.seed)
    capture = robotcal.simulate(scenario, rng=args.seed + 1, true_parameters=truth)
    refined = robotcal.refine(capture, scenario, robotcal.identify(capture, scenario))

    # 2. the Monte Carlo of the deployed model, centred on the estimate
    result = robotcal.monte_carlo(scenario, draws=draws, model="refined", parameters=refined, rng=args.seed)
    print(f"Monte Carlo of the refined model: {result.message} (seed {result.seed})")

    # 3. the TCP along the trajectory (load_trajectory gives radians, the core's unit; the API takes degrees)
    from robotcal.io import load_trajectory

    readings_rad, source = load_trajectory("kr5-sweep-75", n_joints=scenario.robot.n_joints)
    tcp = robotcal.tcp_uncertainty(robotcal.load_robot("kuka-kr5-sixx-r650-krc"), result, np.rad2deg(readings_rad), tool_mm=TOOL_MM)
    position_um = tcp.position_uncertainty * 1000.0
    worst = int(np.argmax(position_um))
    print(
        f"TCP position uncertainty along {tcp.n_poses} poses of {Path(source).name}: "
        f"{position_um.min():.1f} to {position_um.max():.1f} um (worst at pose {worst + 1})"
    )
    lpu_um = np.sqrt(np.sum(tcp.lpu_std_uncertainty[:, :3] ** 2, axis=1)) * 1000.0
    print(f"linearised propagation of the same draws: {lpu_um.min():.1f} to {lpu_um.max():.1f} um")

    # 4. the plot (matplotlib, no display needed)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pose = np.arange(1, tcp.n_poses + 1)
    figure, axis = plt.subplots(figsize=(9, 4.5), layout="constrained")
    for k, name in enumerate("XYZ"):
        axis.plot(pose, tcp.std_uncertainty[:, k] * 1000.0, label=f"u({name})")
    axis.plot(pose, position_um, color="black", linewidth=2, label="position, Monte Carlo")
    axis.plot(pose, lpu_um, color="tab:red", linestyle="--", linewidth=1.2, label="position, linearised")
    axis.set_xlabel("trajectory pose")
    axis.set_ylabel("standard uncertainty (um)")
    axis.set_title(
        f"TCP of the refined kr5-demo model ({result.n_draws} draws, tool 100 mm along z)", fontsize="medium"
    )
    axis.set_ylim(bottom=0)
    figure.legend(loc="outside right upper", fontsize="small")
    path = args.out / "tcp_along_trajectory.png"
    figure.savefig(path, dpi=120)
    plt.close(figure)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
