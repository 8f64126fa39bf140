"""Generate ``docs/validation.md``: robotcal's Monte Carlo against the thesis's Tables 5.6 and 5.7.

Usage: ``python scripts/make_validation_page.py [--draws 100000] [--tables PATH] [--out docs/validation.md]``.
The published tables are read from ``../shared/data/thesis_tables.json`` (transcribed as printed).
Nothing is tuned to the tables: each scenario is the built-in one, run with the thesis's 10^5 draws.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

import robotcal
from robotcal.io import load_scenario
from robotcal.io.atomic import atomic_write_text
from robotcal.uncertainty.montecarlo import MonteCarloSettings, prepare_monte_carlo, run_monte_carlo

ROOT = Path(__file__).resolve().parents[1]
ANGLES = (1, 3, 4)


def run(scenario, draws: int, seed: int, instrument=None):
    problem = prepare_monte_carlo(
        scenario.robot,
        scenario.plan,
        scenario.instrument if instrument is None else instrument,
        scenario.tracker_from_base,
        options=scenario.identification,
        joint_errors=scenario.joint_errors,
        joint_limits=scenario.joint_limits,
    )
    return run_monte_carlo(problem, MonteCarloSettings(iterations=draws, workers=2), seed=seed, linearised=False)


def to_file_units(array: np.ndarray) -> np.ndarray:
    out = np.array(array, dtype=float)
    out[..., ANGLES] = np.rad2deg(out[..., ANGLES])
    return out


def table(scenario, published: dict, result, extra=None) -> list[str]:
    names = np.array(scenario.robot.parameter_names).reshape(scenario.robot.n_joints, 5)
    mean, std = to_file_units(result.summary.mean), to_file_units(result.summary.std_uncertainty)
    low, high = (to_file_units(v) for v in result.summary.interval("symmetric"))
    header = "| parameter | unit | thesis mean | robotcal mean | thesis u | robotcal u | u ratio | thesis 95 % interval | robotcal 95 % interval |"
    rule = "| --- | --- | ---: | ---: | ---: | ---: | ---: | --- | --- |"
    if extra is not None:
        header += f" {extra[0]} u | ratio |"
        rule += " ---: | ---: |"
        extra_std = to_file_units(extra[1].summary.std_uncertainty)
    lines = [header, rule]
    ratios, extra_ratios, listed = [], [], []
    for joint, column in zip(*np.nonzero(result.identified), strict=True):
        name = names[joint, column]
        unit = "deg" if column in ANGLES else "mm"
        ratio = std[joint, column] / published["std"][name]
        ratios.append(ratio)
        listed.append(name)
        row = (
            f"| {name} | {unit} | {published['mean'][name]:.4f} | {mean[joint, column]:.4f} | "
            f"{published['std'][name]:.4f} | {std[joint, column]:.4f} | {ratio:.3f} | "
            f"[{published['lo'][name]:.4f}, {published['hi'][name]:.4f}] | "
            f"[{low[joint, column]:.4f}, {high[joint, column]:.4f}] |"
        )
        if extra is not None:
            extra_ratios.append(extra_std[joint, column] / published["std"][name])
            row += f" {extra_std[joint, column]:.4f} | {extra_ratios[-1]:.3f} |"
        lines.append(row)
    ratios = np.array(ratios)
    lines.append("")
    lines.append(
        f"Standard-uncertainty ratio robotcal / thesis over the {ratios.size} identified parameters: "
        f"min {ratios.min():.3f}, median {np.median(ratios):.3f}, max {ratios.max():.3f}."
    )
    if extra_ratios:
        extra_ratios = np.array(extra_ratios)
        lines.append(
            f"With {extra[0]}: min {extra_ratios.min():.3f}, median {np.median(extra_ratios):.3f}, "
            f"max {extra_ratios.max():.3f}; within 5 % of 1: {int(np.sum(np.abs(extra_ratios - 1) <= 0.05))} of "
            f"{extra_ratios.size}; further off: "
            + ", ".join(f"{n} ({r:.2f})" for n, r in zip(listed, extra_ratios, strict=True) if abs(r - 1) > 0.05)
            + "."
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--tables", default=str(ROOT.parent / "shared" / "data" / "thesis_tables.json"))
    parser.add_argument("--out", default=str(ROOT / "docs" / "validation.md"))
    args = parser.parse_args()
    tables = json.loads(Path(args.tables).read_text())
    began = time.perf_counter()
    igps = load_scenario("thesis-igps")
    laser = load_scenario("thesis-laser-tracker")
    igps_result = run(igps, args.draws, args.seed)
    laser_result = run(laser, args.draws, args.seed)
    # ch. 5.2.1.1 item 6's reading (normal, 2 sigma = A + B L) with the B L term dropped: sigma = 5 um
    five_um = dataclasses.replace(
        laser.instrument, name="normal, sigma 5 um", noise="normal", a_mm=0.010, b_mm_per_m=0.0, coverage_factor=2.0
    )
    laser_5um = run(laser, args.draws, args.seed, instrument=five_um)
    elapsed = time.perf_counter() - began
    page = [
        "# Validation against the thesis's Monte Carlo tables",
        "",
        "<!-- generated by scripts/make_validation_page.py; do not edit by hand -->",
        "",
        f"Generated with robotcal {robotcal.__version__}: {args.draws:,} draws per scenario (the thesis's 10^5,",
        f"ch. 5.2.3), seed {args.seed}, workers 2, {elapsed:.0f} s for the three runs. Published values from",
        "`shared/data/thesis_tables.json` (Tables 5.6 and 5.7 as printed). Mean, standard uncertainty u and",
        "the probabilistically symmetric 95 % interval per identified parameter; lengths in mm, angles in",
        "degrees. J6's d, theta, a, alpha cannot be identified by CPA and are not listed (THESIS_NOTES).",
        "",
        "Settings common to both scenarios (the built-in scenario files): the Table 5.1 capture plan",
        "(135 points, per-circle reflectors of eq. 5-1), `tracker_from_base` of Table 5.4 (nearest",
        "rotation), geometric circle fit, base frame given, theta1 measured from the circle-1 data",
        '(`base_axis = "circle1"`), uniform noise in +-(A + B L) on every coordinate (ch. 5.2.3).',
        "",
        "## Table 5.7: iGPS (A = 200 um, B = 0)",
        "",
        "Scenario `thesis-igps`. Every standard uncertainty agrees with the published one within a few",
        "per cent, which is the Monte Carlo scatter of both studies (the relative standard error of a",
        "standard deviation from 10^5 draws is 0.2 %; the test suite checks +-3 % at 2x10^4 draws). The",
        "non-linear biases the table shows (J4.d, J3.a and J4.theta means away from nominal) come out",
        "with the same sign and size. Known misprint: the published J1.d maximum is below its own upper",
        "95 % limit.",
        "",
        *table(igps, tables["table_5_7_igps"], igps_result),
        "",
        "## Table 5.6: laser tracker (A = 10 um, B = 2.5 um/m)",
        "",
        "Scenario `thesis-laser-tracker`. robotcal's standard uncertainties are about twice the",
        "published ones, for every parameter alike. This difference is not removed, because it is in the",
        "table, not in the method: the same pipeline reproduces Table 5.7 above, and the published",
        "laser-tracker spread is consistent with a standard deviation of about 5 um per coordinate:",
        "the thesis's other noise reading (ch. 5.2.1.1 item 6: normal with 2 sigma = A + B L) with the",
        "distance term B L (about 5 um at the 2 m of Table 5.4) dropped, i.e. sigma = A/2 (THESIS_NOTES.md).",
        "The last two columns show this openly: the same scenario run with normal noise of sigma = 5 um",
        "(A = 10 um, B = 0, k = 2) instead of the stated instrument. They are a diagnosis, not a",
        "calibration of robotcal to the table; robotcal's result for the stated instrument (uniform",
        "+-(A + B L), as ch. 5.2.3 describes) is the robotcal u column. The parameters that stay",
        "above the table under the diagnostic reading (listed under the table) are also the highest",
        "ratios under the stated instrument; the thesis text gives nothing that explains them, and this",
        "page reports them rather than fits them.",
        "",
        *table(laser, tables["table_5_6_laser_tracker"], laser_result, extra=("sigma 5 um", laser_5um)),
        "",
        "## Reproduce",
        "",
        "```bash",
        f".venv/bin/python scripts/make_validation_page.py --draws {args.draws} --seed {args.seed}",
        "```",
        "",
    ]
    atomic_write_text(args.out, "\n".join(page))
    print(f"wrote {args.out} in {elapsed:.1f} s")


if __name__ == "__main__":
    main()
