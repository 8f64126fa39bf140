"""Sensitivity of the calibration uncertainty to the capture conditions (thesis 5.2.4, Figs 5.14-5.16).

One Monte Carlo per combination of the varied scenario keys; per parameter the mean, the standard
uncertainty u and the process capability index of eq. 5-5,

    Cpk = min(USL - mean, mean - LSL) / (3 u),

with the limits centred on the nominal (generating) value, ``nominal -+ 0.1 mm`` for lengths as in
the thesis, and ``nominal -+ angle_limit`` for angles. The thesis gives no angular limit; robotcal's
default is 0.01 deg, the angle that moves a point 0.1 mm at a lever of 573 mm (about the reach of
the KR 5 sixx R650's forearm and wrist), configurable.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.kinematics.model import ANGLE_COLUMNS, KIND_UNITS, PARAMETER_KINDS

__all__ = [
    "DEFAULT_LENGTH_LIMIT_MM",
    "DEFAULT_ANGLE_LIMIT_DEG",
    "process_capability",
    "capability_limits",
    "SensitivityCase",
    "SensitivityStudy",
    "parse_vary",
    "run_sensitivity",
]

DEFAULT_LENGTH_LIMIT_MM = 0.1
DEFAULT_ANGLE_LIMIT_DEG = 0.01


def process_capability(mean: ArrayLike, std: ArrayLike, lower: ArrayLike, upper: ArrayLike) -> np.ndarray:
    """Cpk of eq. 5-5: ``min(upper - mean, mean - lower) / (3 std)`` (elementwise; inf when std = 0)."""
    mean, std, lower, upper = (np.asarray(v, dtype=float) for v in (mean, std, lower, upper))
    margin = np.minimum(upper - mean, mean - lower)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(std > 0, margin / (3.0 * std), np.where(margin >= 0, np.inf, -np.inf))


def capability_limits(
    nominal: ArrayLike, *, length_mm: float = DEFAULT_LENGTH_LIMIT_MM, angle_deg: float = DEFAULT_ANGLE_LIMIT_DEG
) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper)`` of shape (n_joints, 5) around ``nominal`` [mm, rad]."""
    if not (length_mm > 0 and angle_deg > 0):
        raise InputError(f"Cpk limits must be positive; got {length_mm} mm and {angle_deg} deg")
    nominal = np.asarray(nominal, dtype=float)
    half = np.full(nominal.shape, float(length_mm))
    half[:, list(ANGLE_COLUMNS)] = np.deg2rad(angle_deg)
    return nominal - half, nominal + half


@dataclass(frozen=True, slots=True, kw_only=True)
class SensitivityCase:
    """One combination: the values of the varied keys and the Monte Carlo figures [mm, rad]."""

    values: dict
    n_draws: int
    seed: int
    mean: np.ndarray
    std_uncertainty: np.ndarray
    cpk: np.ndarray
    identified: np.ndarray


@dataclass(frozen=True, slots=True, kw_only=True)
class SensitivityStudy:
    keys: tuple[str, ...]
    cases: tuple[SensitivityCase, ...]
    names: tuple[str, ...]
    nominal: np.ndarray
    length_limit_mm: float
    angle_limit_deg: float
    executor: str


def _value(text: str):
    text = text.strip()
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    return text


def parse_vary(options: list[str]) -> list[tuple[str, list]]:
    """``["capture.points=10,40"]`` -> ``[("capture.points", [10, 40])]``."""
    out = []
    for option in options:
        key, sep, values = option.partition("=")
        if not sep or not key.strip() or not values.strip():
            raise InputError(f"--vary {option!r}: expected KEY=V1,V2,... (e.g. capture.sweep_deg.4=15,40,90,180)")
        out.append((key.strip(), [_value(v) for v in values.split(",") if v.strip()]))
    keys = [key for key, _ in out]
    if len(set(keys)) != len(keys):
        raise InputError(f"--vary: a key is given twice ({', '.join(keys)})")
    return out


def _run_case(task) -> dict:
    """One combination (top level, picklable): build the scenario and run its Monte Carlo."""
    from robotcal.planning.scenario import scenario_from_document, set_key
    from robotcal.uncertainty.montecarlo import MonteCarloSettings, prepare_monte_carlo, run_monte_carlo

    document, base_dir, name, source, values, iterations, seed = task
    for key, value in values.items():
        document = set_key(document, key, value)
    scenario = scenario_from_document(document, Path(base_dir), name, source)
    n = scenario.montecarlo.iterations if iterations is None else int(iterations)
    settings = MonteCarloSettings(iterations=n, coverage=scenario.montecarlo.coverage, keep_draws=False)
    problem = prepare_monte_carlo(
        scenario.robot,
        scenario.plan,
        scenario.instrument,
        scenario.tracker_from_base,
        options=scenario.identification,
        joint_errors=scenario.joint_errors,
        joint_limits=scenario.joint_limits,
    )
    result = run_monte_carlo(problem, settings, seed=seed, linearised=False)
    return {
        "n_draws": result.n_draws,
        "mean": result.summary.mean,
        "std": result.summary.std_uncertainty,
        "identified": result.identified,
        "nominal": result.true_values,
    }


def run_sensitivity(
    document: dict,
    base_dir: str | Path,
    name: str,
    source: str,
    vary: list[tuple[str, list]],
    *,
    seed: int,
    iterations: int | None = None,
    length_limit_mm: float = DEFAULT_LENGTH_LIMIT_MM,
    angle_limit_deg: float = DEFAULT_ANGLE_LIMIT_DEG,
    workers: int = 1,
    scheduler: str | None = None,
) -> SensitivityStudy:
    """One Monte Carlo per combination of ``vary`` (the Cartesian product), all with the same ``seed``
    (common random numbers: differences between cases are the plan's, not the draws')."""
    from robotcal.execution import open_executor

    if not vary:
        raise InputError("give at least one --vary KEY=V1,V2,...")
    keys = tuple(key for key, _ in vary)
    combos = [dict(zip(keys, values, strict=True)) for values in itertools.product(*(v for _, v in vary))]
    tasks = [(document, str(base_dir), name, source, combo, iterations, seed) for combo in combos]
    with open_executor(workers=workers, scheduler=scheduler) as executor:
        results = list(executor.map(_run_case, tasks))
        kind = executor.kind
    nominal = results[0]["nominal"]
    lower, upper = capability_limits(nominal, length_mm=length_limit_mm, angle_deg=angle_limit_deg)
    cases = []
    for combo, result in zip(combos, results, strict=True):
        low, high = capability_limits(result["nominal"], length_mm=length_limit_mm, angle_deg=angle_limit_deg)
        cases.append(
            SensitivityCase(
                values=combo,
                n_draws=int(result["n_draws"]),
                seed=seed,
                mean=result["mean"],
                std_uncertainty=result["std"],
                cpk=process_capability(result["mean"], result["std"], low, high),
                identified=result["identified"],
            )
        )
    del lower, upper
    n_joints = nominal.shape[0]
    names = tuple(f"J{i + 1}.{k}" for i in range(n_joints) for k in PARAMETER_KINDS)
    return SensitivityStudy(
        keys=keys,
        cases=tuple(cases),
        names=names,
        nominal=nominal,
        length_limit_mm=length_limit_mm,
        angle_limit_deg=angle_limit_deg,
        executor=kind,
    )


def study_rows(study: SensitivityStudy) -> list[dict]:
    """One row per case and identified parameter (mm and deg): the CSV/JSON content."""
    rows = []
    for number, case in enumerate(study.cases, start=1):
        for flat, name in enumerate(study.names):
            joint, kind = divmod(flat, len(PARAMETER_KINDS))  # kind: the column
            if not case.identified[joint, kind]:
                continue
            angle = kind in ANGLE_COLUMNS
            scale = np.rad2deg(1.0) if angle else 1.0
            row: dict[str, object] = {"case": number}
            row.update({key: case.values[key] for key in study.keys})
            row.update(
                {
                    "name": name,
                    "unit": KIND_UNITS[PARAMETER_KINDS[kind]],
                    "nominal": float(study.nominal[joint, kind] * scale),
                    "mean": float(case.mean[joint, kind] * scale),
                    "std_uncertainty": float(case.std_uncertainty[joint, kind] * scale),
                    "cpk": float(case.cpk[joint, kind]),
                    "draws": case.n_draws,
                }
            )
            rows.append(row)
    return rows
