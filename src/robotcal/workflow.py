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

__all__ = [
    "SimulationRun",
    "resolve_seed",
    "simulate_scenario",
    "identify_scenario",
    "versions",
    "scenario_truth",
    "simulate_validation",
    "refine_scenario",
    "refine_provenance",
    "evaluate_scenario",
]


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


# --- refinement and evaluation (thesis ch. 4.5.7) -------------------------------------------------


def scenario_truth(scenario: Scenario, *, seed: int | None = None) -> tuple[ParameterSet, int]:
    """A perturbed "true" robot from the scenario's ``[truth]`` table (defaults when absent).

    Returns the parameters and the seed used (``seed``, else ``truth.seed``, else fresh entropy).
    """
    from robotcal.simulation.perturb import perturb_parameters

    table = scenario.truth or {"length_sd_mm": 0.2, "angle_sd_deg": 0.05, "include_base": False, "seed": None}
    seed = resolve_seed(seed, table.get("seed"))
    truth = perturb_parameters(
        scenario.robot,
        length_sd_mm=table["length_sd_mm"],
        angle_sd_deg=table["angle_sd_deg"],
        include_base=table["include_base"],
        rng=np.random.default_rng(seed),
    )
    return truth, seed


def validation_reflector(scenario: Scenario):
    """The flange target of validation captures: ``[validation].flange_reflector_mm``, else the
    plan's reflector when it is a flange one."""
    from robotcal.errors import InputError
    from robotcal.kinematics.model import ReflectorMount

    if scenario.validation is not None:
        return ReflectorMount(frame="flange", positions=scenario.validation["flange_reflector_mm"])
    if scenario.plan.reflector.frame == "flange":
        return scenario.plan.reflector
    raise InputError(
        f"{scenario.source}: a capture at free poses (circle = 0) needs a flange target: add a [validation] table "
        "with `flange_reflector_mm`, or use a scenario with `capture.flange_reflector_mm`"
    )


def capture_reflector(scenario: Scenario, capture: Capture):
    """The target of ``capture``: the validation flange target when it has free poses, else the plan's."""
    if np.any(capture.circle == 0):
        return validation_reflector(scenario)
    return scenario.plan.reflector


def simulate_validation(
    scenario: Scenario, *, seed: int | None = None, true_parameters: ParameterSet | None = None
) -> SimulationRun:
    """A validation capture at seeded random reachable poses (``[validation]`` table, defaults when
    absent); one generator seeded by ``seed`` (else ``validation.seed``) draws the poses, then the noise."""
    from robotcal.simulation.poses import random_poses, simulate_poses

    table = scenario.validation or {"poses": 100, "seed": None, "margin_deg": 5.0, "min_height_mm": None}
    seed = resolve_seed(seed, table.get("seed"))
    rng = np.random.default_rng(seed)
    reflector = validation_reflector(scenario)
    readings = random_poses(
        scenario.robot,
        int(table["poses"]),
        margin_deg=table["margin_deg"],
        min_height_mm=table["min_height_mm"],
        reflector=reflector,
        rng=rng,
    )
    true_parameters = ParameterSet.nominal(scenario.robot) if true_parameters is None else true_parameters
    capture, exact = simulate_poses(
        scenario.robot,
        readings,
        reflector,
        scenario.instrument,
        scenario.tracker_from_base,
        true_parameters=true_parameters,
        rng=rng,
    )
    capture = Capture(
        circle=capture.circle,
        direction=capture.direction,
        readings=capture.readings,
        points=capture.points,
        source=f"validation capture simulated from {scenario.name}",
        seed=seed,
    )
    return SimulationRun(capture=capture, exact_points=exact, seed=seed, true_parameters=true_parameters)


def refine_scenario(capture: Capture, scenario: Scenario, start: ParameterSet, *, criterion: str = "points", **options):
    """Refine ``start`` on ``capture`` with the scenario's robot and target (thesis ch. 4.5.7).

    The points criterion starts from the scenario's ``tracker_from_base`` when
    ``[identification].base_frame = "given"``, else from a Horn registration. ``options`` go to
    :func:`robotcal.identification.refine.refine_parameters`.
    """
    from robotcal.identification.refine import refine_parameters

    base = scenario.tracker_from_base if scenario.identification.base_frame == "given" else None
    return refine_parameters(
        capture,
        start,
        capture_reflector(scenario, capture),
        criterion=criterion,
        tracker_from_base=base,
        **options,
    )


def refine_provenance(result, capture: Capture, scenario: Scenario, start_source: str) -> dict:
    """What a parameter JSON records about a refinement (mm, deg), convergence history included."""
    names = scenario.robot.parameter_names
    angles = ("theta", "alpha", "beta")
    sd = {}
    for name, value in zip(names, result.standard_uncertainty.ravel(), strict=True):
        if np.isfinite(value):
            sd[name] = float(np.rad2deg(value)) if name.split(".")[1] in angles else float(value)
    return {
        "method": f"least-squares refinement, {result.criterion} criterion (thesis ch. 4.5.7, "
        + ("eq. 4-101)" if result.criterion == "points" else "eq. 4-102)"),
        "criterion": result.criterion,
        "solver": f"scipy.optimize.least_squares method={result.method!r}",
        "start": start_source,
        "capture": capture.source,
        "capture_seed": capture.seed,
        "points": int(capture.n_points),
        "residuals": result.n_residuals,
        "scenario": {"name": scenario.name, "source": scenario.source},
        "free": list(result.free_names),
        "gauge": list(result.gauge),
        "held": list(result.held),
        "still_joints": list(result.still_joints),
        "success": result.success,
        "message": result.message,
        "nfev": result.nfev,
        "njev": result.njev,
        "wall_time_s": result.wall_time_s,
        "convergence": {
            "criterion": result.criterion,
            "cost_mm2": result.cost_history.tolist(),
            "rms_mm": result.rms_history.tolist(),
        },
        "residual_rms_mm": result.residual_rms,
        "residual_mean_mm": result.residual_mean,
        "residual_max_mm": result.residual_max,
        "sigma_mm": result.sigma,
        "condition_number": result.condition_number,
        "singular_values": result.singular_values.tolist(),
        "standard_uncertainty": sd,
        "tracker_from_base": None if result.tracker_from_base is None else result.tracker_from_base.tolist(),
        "versions": versions(),
    }


def evaluate_scenario(scenario: Scenario, captures: dict, parameter_sets: dict):
    """Evaluation rows (thesis Tables 4.10/4.11) of named parameter sets on named captures."""
    from robotcal.identification.evaluation import evaluate_parameters

    reflectors = {name: capture_reflector(scenario, capture) for name, capture in captures.items()}
    return evaluate_parameters(captures, parameter_sets, reflectors)
