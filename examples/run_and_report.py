"""The whole calibration run from Python: plan it, run it, read its summary and results, render its report.

What it shows
    The pipeline behind ``robotcal run`` as a library (docs/pipeline.md, docs/api.md):

    1. :func:`robotcal.plan_run` loads and checks everything the run needs before any computation
       (scenario, seeds, Monte Carlo settings, TCP targets, memory, the output folder);
    2. :func:`robotcal.run_calibration` runs every stage (simulate, identify, joints, refine, evaluate,
       uncertainty, plan, tcp, iso9283, report) into the run folder and returns a :class:`robotcal.RunResult`:
       ``record`` (run.json), ``documents`` (every file, in memory), ``summary`` (the headline figures)
       and ``results`` (the typed results: parameter sets, Monte Carlo results, TCP uncertainties...);
    3. :func:`robotcal.read_run` reads a run folder back into the same object, and
       :func:`robotcal.render_report` renders its HTML report again from it.

Run
    python examples/run_and_report.py --out run-example            # the demo's sizes: the refinement's model
                                                                    # choice, the refined Monte Carlo and the
                                                                    # TCP stage are most of the cost
    python examples/run_and_report.py --quick --out run-example    # small Monte Carlos (the test suite)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import robotcal


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="kr5-demo", help="built-in scenario name or scenario TOML")
    parser.add_argument("--out", type=Path, default=Path("run-example"), help="run folder")
    parser.add_argument("--quick", action="store_true", help="200 + 50 Monte Carlo draws, 20 workspace poses")
    args = parser.parse_args(argv)

    sizes = {"draws": 200, "refined_draws": 50, "workspace": 20, "workers": 1} if args.quick else {}
    plan = robotcal.plan_run(args.scenario, args.out, command="examples/run_and_report.py", **sizes)
    result = robotcal.run_calibration(plan)
    print(f"run folder {result.folder}: {len(result.documents)} documents")
    for line in result.summary.console_lines():
        print(line)

    # the typed results, for further work in Python (core units: mm, rad)
    refined = result.results["refined"]["points"]
    montecarlo = result.results["montecarlo"]["refined"]
    u = montecarlo.summary.std_uncertainty
    largest = np.unravel_index(np.argmax(u[:, [0, 2]]), (u.shape[0], 2))
    name = refined.parameters.robot.parameter_names[largest[0] * 5 + (0, 2)[largest[1]]]
    print(
        f"refined parameters: residual RMS {refined.fit.residual_rms * 1000:.1f} um; "
        f"largest length u of the deployed model {name} = {u[:, [0, 2]].max() * 1000:.2f} um "
        f"({montecarlo.n_draws} draws)"
    )

    # the same run read back from its folder, and its report rendered again from the object
    again = robotcal.read_run(args.out)
    same = again.summary.console_lines() == result.summary.console_lines()
    print(f"read back from {args.out}: the same headline figures: {same}")
    report = robotcal.render_report(again)
    copy = args.out.with_name(f"{args.out.name}-report.html")
    from robotcal.io import atomic_write_text

    atomic_write_text(copy, report.html)
    print(f"report of {len(report.sections)} sections and {report.figures} figures rendered again into {copy}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
