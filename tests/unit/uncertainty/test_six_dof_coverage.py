"""Coverage of the Monte Carlo of a measured 6-DoF capture (issue 29): position and orientation noise drawn as the
capture states them, the probe's frame re-identified in every draw; K captures of one truth, each its own noise,
and the truth inside each capture's 95 % interval as often as the exact 99 % binomial band allows.

The symmetric interval of M draws (JCGM 101 §7.7.1) contains an independent value of the same distribution with
probability ``q / (M + 1)``, ``q = round(0.95 M)`` (0.927 at M = 40): the band is that of a binomial with this p.
Three quantities are checked, each on its own (one trial per capture: exactly binomial): J2.a, J5.alpha (which the
orientation determines better) and the probe offset's z.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from robotcal.errors import IdentifiabilityWarning
from robotcal.geometry.transforms import rot_x, rot_z
from robotcal.identification.refine import refine_parameters
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.schema.robots import load_robot
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses
from robotcal.simulation.probe import simulate_probe_poses
from robotcal.uncertainty.coverage import binomial_band
from robotcal.uncertainty.measured import measured_monte_carlo
from robotcal.uncertainty.montecarlo import MonteCarloSettings

ROBOT = load_robot("kuka-kr5-sixx-r650")
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.2, angle_sd_deg=0.05, rng=np.random.default_rng(21))
TRACKER = np.array([[1.0, 0.0, 0.0, 1800.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 400.0], [0.0, 0.0, 0.0, 1.0]])
ROTATION = (rot_z(np.deg2rad(25.0)) @ rot_x(np.deg2rad(-10.0)))[:3, :3]
OFFSET = np.array([35.0, -15.0, 85.0])
PROBE = Target(name="probe", frame="flange", positions=np.zeros(3), known=False)
INSTRUMENT = Instrument(name="6dof", a_mm=0.03, b_mm_per_m=0.0, noise="normal", orientation_rad=np.deg2rad(0.01))
READINGS = random_poses(ROBOT, 12, rng=np.random.default_rng(8))
CHECKED = {"J2.a": (1, 2), "J5.alpha": (4, 3)}


def coverage_hits(captures: int, draws: int) -> dict[str, int]:
    """Per checked quantity, the captures whose 95 % Monte Carlo interval holds the truth."""
    hits = dict.fromkeys([*CHECKED, "probe.z"], 0)
    for k in range(captures):
        capture, _, _ = simulate_probe_poses(
            ROBOT, READINGS, PROBE, ROTATION, INSTRUMENT, TRACKER, true_parameters=TRUTH, true_offset=OFFSET,
            u95_mm=0.03, u95_deg=0.01, rng=1000 + k,
        )  # fmt: skip
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            estimate = refine_parameters(capture, ParameterSet.nominal(ROBOT), PROBE)
            result = measured_monte_carlo(capture, estimate, PROBE, MonteCarloSettings(iterations=draws), seed=k)
        assert result.parameters.n_failed == 0
        low, high = result.parameters.interval()
        for name, (joint, kind) in CHECKED.items():
            true = TRUTH.values[joint, kind]
            hits[name] += int(low[joint, kind] <= true <= high[joint, kind])
        t_low, t_high = result.target_interval()
        hits["probe.z"] += int(t_low[0, 2] <= OFFSET[2] <= t_high[0, 2])
    return hits


def _check(hits: dict[str, int], captures: int, draws: int) -> None:
    q = int(np.floor(0.95 * draws + 0.5))
    low, high = binomial_band(captures, q / (draws + 1))
    for name, count in hits.items():
        assert low <= count / captures <= high, (name, count, captures, low, high)


def test_six_dof_monte_carlo_covers_the_truth_reduced():
    _check(coverage_hits(captures=6, draws=21), captures=6, draws=21)


@pytest.mark.slow
def test_six_dof_monte_carlo_covers_the_truth():
    _check(coverage_hits(captures=200, draws=40), captures=200, draws=40)
