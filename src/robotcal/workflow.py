"""Scenario-level operations shared by the CLI and by scripts: simulate, identify, provenance.

Each function is one library call over core objects; nothing here prints or exits.
"""

from __future__ import annotations

import platform
from dataclasses import dataclass

import numpy as np

import robotcal
from robotcal.capture import Capture
from robotcal.identification.cpa import CPAResult, identify_cpa
from robotcal.io.scenario import Scenario
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.generator import simulate_capture

__all__ = ["SimulationRun", "resolve_seed", "simulate_scenario", "identify_scenario", "versions"]


@dataclass(frozen=True, slots=True, kw_only=True)
class SimulationRun:
    """A simulated capture with what produced it."""

    capture: Capture
    exact_points: np.ndarray
    seed: int
    true_parameters: ParameterSet


def resolve_seed(*candidates: int | None) -> int:
    """The first seed given, else fresh entropy (returned so that it can be recorded)."""
    for seed in candidates:
        if seed is not None:
            return int(seed)
    return int(np.random.SeedSequence().entropy % (2**63))


def simulate_scenario(
    scenario: Scenario, *, seed: int | None = None, true_parameters: ParameterSet | None = None
) -> SimulationRun:
    """Simulate the scenario's capture (noise and joint errors from one generator seeded by ``seed``,
    else the scenario's ``capture.seed``, else fresh entropy)."""
    seed = resolve_seed(seed, scenario.seed)
    true_parameters = ParameterSet.nominal(scenario.robot) if true_parameters is None else true_parameters
    capture, exact = simulate_capture(
        scenario.robot,
        scenario.plan,
        scenario.instrument,
        scenario.tracker_from_base,
        true_parameters=true_parameters,
        joint_errors=scenario.joint_errors,
        joint_limits=scenario.joint_limits,
        rng=np.random.default_rng(seed),
    )
    capture = Capture(
        circle=capture.circle,
        direction=capture.direction,
        readings=capture.readings,
        points=capture.points,
        source=f"capture simulated from {scenario.name}",
        seed=seed,
    )
    return SimulationRun(capture=capture, exact_points=exact, seed=seed, true_parameters=true_parameters)


def identify_scenario(capture: Capture, scenario: Scenario) -> CPAResult:
    """CPA of ``capture`` with the scenario's robot, reflector, base frame and options."""
    return identify_cpa(
        capture,
        scenario.robot,
        scenario.plan.reflector,
        tracker_from_base=scenario.tracker_from_base,
        options=scenario.identification,
    )


def versions() -> dict[str, str]:
    """Versions of robotcal and of the numeric stack, for provenance records."""
    import scipy

    return {
        "robotcal": robotcal.__version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "python": platform.python_version(),
    }


def cpa_provenance(result: CPAResult, capture: Capture, scenario: Scenario) -> dict:
    """What a parameter JSON records about a CPA identification (mm, deg)."""
    return {
        "method": "circle point analysis (thesis ch. 4.4-4.5)",
        "capture": capture.source,
        "capture_seed": capture.seed,
        "points": int(capture.n_points),
        "scenario": {"name": scenario.name, "source": scenario.source},
        "options": {
            "circle_fit": result.options.circle_fit,
            "base_frame": result.options.base_frame,
            "base_axis": result.options.base_axis,
            "near_parallel_deg": result.options.near_parallel_deg,
            "still_tolerance_deg": result.options.still_tolerance_deg,
        },
        "reference_readings_deg": np.rad2deg(result.reference_readings).tolist(),
        "circles": [
            {
                "circle": joint + 1,
                "points": int(fit.plane_residuals.shape[-1]),
                "radius_mm": float(fit.radius),
                "plane_rms_mm": float(fit.plane_rms),
                "circle_rms_mm": float(fit.circle_rms),
            }
            for joint, fit in enumerate(result.circle_fits)
        ],
        "line_pairs": [f"J{j + 1}-J{j + 2}: {case}" for j, case in enumerate(result.pair_cases)],
        "tracker_from_base": result.tracker_from_base.tolist(),
        "registration_rms_mm": result.registration_rms,
        "success": result.success,
        "message": result.message,
        "versions": versions(),
    }
