"""Monte Carlo result files: ``parameters.csv`` and ``parameters.json`` (docs/results.md
"Uncertainty CSV"). Core results are in mm and rad; these files are in mm and degrees."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np

from robotcal.errors import InputError
from robotcal.io.atomic import atomic_write_text
from robotcal.io.formats.draws_npz import parameter_units
from robotcal.io.formats.parameters_json import joint_model_to_dict
from robotcal.kinematics.model import DISPLAY_UNITS, ParameterSet
from robotcal.uncertainty.montecarlo import MonteCarloResult

__all__ = [
    "FORMAT",
    "CSV_COLUMNS",
    "uncertainty_rows",
    "write_uncertainty_csv",
    "write_uncertainty_json",
    "read_uncertainty_csv",
    "write_uncertainty_folder",
    "MEASURED_TARGET_COLUMNS",
    "measured_target_rows",
    "write_measured_folder",
]

FORMAT = "robotcal-uncertainty/1"
#: The original design's columns first (other tools rely on them), then robotcal's extensions.
CSV_COLUMNS = (
    "name",
    "unit",
    "nominal",
    "mean",
    "std_uncertainty",
    "coverage_low",
    "coverage_high",
    "min",
    "max",
    "identified",
    "symmetric_low",
    "symmetric_high",
    "shortest_low",
    "shortest_high",
    "noise_free",
    "lpu_std_uncertainty",
    "lpu_coverage_low",
    "lpu_coverage_high",
    "lpu_agrees",
    "model",
    "centre",
    "bias",
    "draws_low",
    "draws_high",
    "estimate",
    "deployed",
    "bias_treatment",
    "correction_u",
)
#: ``bias_treatment`` of a deployed model's rows: its value is the estimate corrected for the bias.
BIAS_SUBTRACTED = "subtracted: deployed = estimate - bias"
#: ... and of a Monte Carlo that states no deployed value (the CPA model's, or a stand-alone study).
BIAS_REPORTED = "reported, not corrected"
#: How ``coverage_low/high`` are made from the draws (``parameters.json``'s ``interval_method``).
INTERVAL_METHOD = (
    "coverage_low/high: the draws' coverage interval [draws_low, draws_high] moved by twice the Monte Carlo's bias "
    "(bias = mean - centre, centre = the simulated robot, the estimate in a calibration): [draws_low - 2 bias, "
    "draws_high - 2 bias]. Draws simulated at an estimate are centred on estimate + bias, i.e. on truth + 2 bias; "
    "moved, the interval is centred on the bias-corrected estimate and keeps the draws' shape (docs/uncertainty.md)"
)
#: Text (not numeric) columns of ``parameters.csv``.
_TEXT_COLUMNS = ("name", "unit", "model", "bias_treatment")
_METHODS = {
    "cpa": "GUM Supplement 1 Monte Carlo (JCGM 101:2008) of simulated capture + CPA (thesis ch. 5.2.3)",
    "refined": "GUM Supplement 1 Monte Carlo (JCGM 101:2008) of simulated capture + CPA + least-squares "
    "refinement, {criterion} criterion (thesis ch. 5.2.3, 4.5.7): the deployed model",
}


def _scale(result: MonteCarloResult) -> np.ndarray:
    """Per parameter factor core -> file units (1 for mm, 180/pi for angles), flat joint-major."""
    return np.array([180.0 / math.pi if unit == "deg" else 1.0 for unit in parameter_units(result.robot)])


def uncertainty_rows(result: MonteCarloResult, deployed: ParameterSet | None = None) -> list[dict]:
    """One dict per parameter (``J1.d`` ... ``Jn.beta``) in mm / deg.

    ``estimate`` is the value the Monte Carlo was simulated at (:attr:`MonteCarloResult.centre`); ``deployed``
    (given: the value deployed, ``result.corrected(estimate)``, the centre of ``coverage_low/high``; else empty)
    and ``bias_treatment`` say what was done with the bias; ``correction_u`` is the standard uncertainty of that
    correction (from the measured joint errors', :attr:`MonteCarloResult.correction_u`), which ``coverage_low/high``
    include (the deployed value's u: ``std_uncertainty`` and ``correction_u`` in quadrature)."""
    scale = _scale(result)
    summary = result.summary
    low, high = result.interval()  # for the measurand: the draws' interval moved by twice the bias
    draws_low, draws_high = result.draws_interval()

    def flat(array):
        return np.asarray(array, dtype=float).reshape(-1) * scale

    columns = {
        "nominal": flat(result.robot.nominal),
        "mean": flat(summary.mean),
        "std_uncertainty": flat(summary.std_uncertainty),
        "coverage_low": flat(low),
        "coverage_high": flat(high),
        "min": flat(summary.minimum),
        "max": flat(summary.maximum),
        "symmetric_low": flat(summary.symmetric_low),
        "symmetric_high": flat(summary.symmetric_high),
        "shortest_low": flat(summary.shortest_low),
        "shortest_high": flat(summary.shortest_high),
        "noise_free": flat(result.noise_free_values),
        "true": flat(result.true_values),
        "centre": flat(result.centre),
        "bias": flat(result.bias),
        "draws_low": flat(draws_low),
        "draws_high": flat(draws_high),
        "estimate": flat(result.centre),
        "correction_u": flat(result.correction_u),
    }
    if deployed is not None:
        columns["deployed"] = flat(deployed.values)
    linear = result.linearised
    if linear is not None:
        columns.update(
            lpu_std_uncertainty=flat(linear.std_uncertainty),
            lpu_coverage_low=flat(linear.coverage_low),
            lpu_coverage_high=flat(linear.coverage_high),
        )
    rows = []
    units = parameter_units(result.robot)
    identified = result.identified.reshape(-1)
    for index, name in enumerate(result.robot.parameter_names):
        row = {
            "name": name,
            "unit": units[index],
            "identified": bool(identified[index]),
            "model": result.model,
            "bias_treatment": BIAS_REPORTED if deployed is None else BIAS_SUBTRACTED,
        }
        row.update({key: float(values[index]) for key, values in columns.items()})
        if linear is not None:
            row["lpu_agrees"] = bool(linear.agrees.reshape(-1)[index])
        rows.append(row)
    return rows + _joint_model_rows(result, deployed)


def _joint_model_rows(result: MonteCarloResult, deployed: ParameterSet | None) -> list[dict]:
    """One row per joint-model value of an extended refined model (``J2.k`` [rad/(N m)], ``J4.a1`` [deg]), after
    the parameters: the same columns (no nominal, no linearised comparison)."""
    model, summary = result.joint_model, result.extra_summary
    if model is None:  # not an extended model
        return []
    assert summary is not None  # an extended model's draws carry its joint-model values
    low, high = result.extra_interval()
    draws_low, draws_high = summary.interval(result.settings.interval)
    columns = {
        "nominal": np.zeros(model.size),
        "mean": summary.mean,
        "std_uncertainty": summary.std_uncertainty,
        "coverage_low": low,
        "coverage_high": high,
        "min": summary.minimum,
        "max": summary.maximum,
        "symmetric_low": summary.symmetric_low,
        "symmetric_high": summary.symmetric_high,
        "shortest_low": summary.shortest_low,
        "shortest_high": summary.shortest_high,
        "noise_free": model.values,
        "true": result.extra_true,
        "centre": result.extra_true,
        "bias": np.where(result.extra_identified, summary.mean - result.extra_true, 0.0),
        "draws_low": draws_low,
        "draws_high": draws_high,
        "estimate": result.extra_true,
        "correction_u": result.extra_correction_u,
    }
    if deployed is not None and deployed.joint_model is not None and deployed.joint_model.names == model.names:
        columns["deployed"] = deployed.joint_model.values
    shown = {key: model.to_display(value) for key, value in columns.items()}
    return [
        {
            "name": name,
            "unit": unit,
            "identified": bool(result.extra_identified[k]),
            "model": result.model,
            "bias_treatment": BIAS_REPORTED if deployed is None else BIAS_SUBTRACTED,
            **{key: float(values[k]) for key, values in shown.items()},
        }
        for k, (name, unit) in enumerate(zip(model.names, model.display_units, strict=True))
    ]


def _format(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return format(value, ".12g")
    return str(value)


def write_uncertainty_csv(path, result: MonteCarloResult, deployed: ParameterSet | None = None) -> Path:
    """``parameters.csv``: one row per parameter, columns :data:`CSV_COLUMNS` (mm, deg); ``deployed``: the values
    deployed (:func:`uncertainty_rows`)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for row in uncertainty_rows(result, deployed):
        writer.writerow([_format(row[column]) if column in row else "" for column in CSV_COLUMNS])
    return atomic_write_text(path, buffer.getvalue())


def read_uncertainty_csv(path) -> list[dict]:
    """Rows of a ``parameters.csv`` (floats and booleans parsed; errors name the file and line)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    reader = csv.DictReader(io.StringIO(text))
    missing = [column for column in CSV_COLUMNS[:9] if column not in (reader.fieldnames or [])]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}")
    rows = []
    for line, raw in enumerate(reader, start=2):
        row = {}
        for key, value in raw.items():
            if key in _TEXT_COLUMNS:
                row[key] = value
            elif value in ("true", "false"):
                row[key] = value == "true"
            elif value == "":
                row[key] = None
            else:
                try:
                    row[key] = float(value)
                except ValueError:
                    raise InputError(f"{path}, line {line}: column `{key}` is not a number: {value!r}") from None
        rows.append(row)
    return rows


def _matrix_in_file_units(result: MonteCarloResult, matrix: np.ndarray, *, scaled: bool) -> dict:
    mask = result.identified.reshape(-1)
    names = [name for name, keep in zip(result.robot.parameter_names, mask, strict=True) if keep]
    sub = matrix[np.ix_(mask, mask)]
    if scaled:
        scale = _scale(result)[mask]
        sub = sub * np.outer(scale, scale)
    return {"names": names, "matrix": [[float(format(v, ".12g")) for v in row] for row in sub]}


def write_uncertainty_json(
    path, result: MonteCarloResult, *, scenario: dict | None, versions: dict, deployed: ParameterSet | None = None
) -> Path:
    """``parameters.json``: the CSV's content plus covariance, correlation, seed, draws, adaptive
    record, settings, timings, versions and the scenario echo (mm, deg)."""
    settings = result.settings
    adaptive = None
    if result.adaptive is not None:
        record = result.adaptive
        scale = _scale(result)[result.identified.reshape(-1)]
        model = result.joint_model
        if model is not None:  # extended: the joint-model values follow the parameters in the adaptive record
            scale = np.r_[scale, model.to_display(np.ones(model.size))[result.extra_identified]]
        adaptive = {
            "blocks": record.blocks,
            "block_size": settings.block_size,
            "stable": record.stable,
            "reason": record.reason,
            "ndig": settings.ndig,
            "tolerance": (np.asarray(record.tolerance) * scale).tolist(),
            "stability": {key: (np.asarray(value) * scale).tolist() for key, value in record.stability.items()},
        }
    document = {
        "format": FORMAT,
        "robot": result.robot.name,
        "units": dict(DISPLAY_UNITS),
        "method": _METHODS[result.model].format(criterion=result.criterion),
        "model": result.model,
        "criterion": result.criterion,
        "failed_draws": result.n_failed,
        "seed": result.seed,
        "draws": result.n_draws,
        "coverage": settings.coverage,
        "interval": settings.interval,
        "interval_method": INTERVAL_METHOD,
        "settings": {
            "iterations": settings.iterations,
            "adaptive": settings.adaptive,
            "ndig": settings.ndig,
            "max_draws": settings.max_draws,
            "batch_size": settings.batch_size,
            "block_size": settings.block_size,
            "workers": settings.workers,
        },
        "success": result.success,
        "message": result.message,
        "adaptive": adaptive,
        "joint_model": None if result.joint_model is None else joint_model_to_dict(result.joint_model),
        "parameters": uncertainty_rows(result, deployed),
        "covariance": _matrix_in_file_units(result, result.covariance, scaled=True),
        "correlation": _matrix_in_file_units(result, result.correlation, scaled=False),
        "linearised": None
        if result.linearised is None
        else {
            "method": "GUM law of propagation, Jacobian of CPA by central differences over the measured coordinates"
            if result.model == "cpa"
            else "GUM law of propagation of the least-squares refinement at the noise-free solution, "
            "(J^T J)^-1 J^T G U_x G^T J (J^T J)^-1 (CPA's central differences for identified parameters it holds)",
            "step_mm": result.linearised.step_mm,
            "covariance": _matrix_in_file_units(result, result.linearised.covariance, scaled=True),
            "validation": "JCGM 101 §8.2: both interval ends within the numerical tolerance of ndig digits",
        },
        "timings_s": {key: round(value, 4) for key, value in result.timings_s.items()},
        "versions": versions,
        "scenario": scenario,
    }
    return atomic_write_text(path, json.dumps(document, indent=2, allow_nan=False) + "\n")


def write_uncertainty_folder(
    folder: Path, result: MonteCarloResult, *, scenario=None, save_draws: bool, deployed: ParameterSet | None = None
) -> dict:
    """Write ``parameters.csv``, ``parameters.json`` and (optionally) ``draws.npz`` into ``folder`` (an existing,
    normally temporary, folder), with the ``deployed`` values if given (:func:`uncertainty_rows`); returns the documents by file name as :func:`robotcal.io.results.run_folder.read_run`
    reads them (the histograms: :func:`robotcal.plots.montecarlo.write_histograms`)."""
    from robotcal.io.formats.draws_npz import write_draws
    from robotcal.io.results.provenance import versions
    from robotcal.io.results.run_folder import read_document

    folder = Path(folder)
    echo = (
        None if scenario is None else {"name": scenario.name, "source": scenario.source, "settings": scenario.settings}
    )
    write_uncertainty_csv(folder / "parameters.csv", result, deployed)
    write_uncertainty_json(folder / "parameters.json", result, scenario=echo, versions=versions(), deployed=deployed)
    documents = {name: read_document(folder, name) for name in ("parameters.csv", "parameters.json")}
    if save_draws:
        write_draws(
            folder / "draws.npz", result.robot, result.draws, result.identified, seed=result.seed, model=result.model,
            joint_model=result.joint_model, extras=result.extra_draws,
        )  # fmt: skip
        documents["draws.npz"] = folder / "draws.npz"
    return documents


#: Columns of ``targets.csv`` (estimated flange offsets, mm).
MEASURED_TARGET_COLUMNS = (
    "name", "axis", "unit", "estimate", "mean", "std_uncertainty", "coverage_low", "coverage_high", "min", "max",
    "lpu_std_uncertainty", "bias", "draws_low", "draws_high",
)  # fmt: skip


def measured_target_rows(result) -> list[dict]:
    """One dict per estimated offset component (mm)."""
    rows: list[dict] = []
    summary = result.target_summary
    if summary is None:
        return rows
    low, high = result.target_interval()
    draws_low, draws_high = result.target_draws_interval()
    bias = summary.mean - result.target_estimate
    for t, name in enumerate(result.target_names):
        for a, axis in enumerate("xyz"):
            lpu = result.target_linearised_u[t, a]
            rows.append(
                {
                    "name": name,
                    "axis": axis,
                    "unit": "mm",
                    "estimate": float(result.target_estimate[t, a]),
                    "mean": float(summary.mean[t, a]),
                    "std_uncertainty": float(summary.std_uncertainty[t, a]),
                    "coverage_low": float(low[t, a]),
                    "coverage_high": float(high[t, a]),
                    "min": float(summary.minimum[t, a]),
                    "max": float(summary.maximum[t, a]),
                    "lpu_std_uncertainty": float(lpu) if np.isfinite(lpu) else None,
                    "bias": float(bias[t, a]),
                    "draws_low": float(draws_low[t, a]),
                    "draws_high": float(draws_high[t, a]),
                }
            )
    return rows


def write_measured_folder(
    folder: Path, result, *, scenario=None, capture: str, params: str, n_points: int, save_draws: bool
) -> None:
    """The files of the Monte Carlo of a measured capture (:func:`robotcal.api.measured_monte_carlo`):
    ``parameters.csv``, ``parameters.json`` (``model: "measured capture"``), ``targets.csv`` (estimated flange
    offsets) and (``save_draws``) ``draws.npz`` (mm, deg); the histograms:
    :func:`robotcal.plots.montecarlo.write_histograms` of ``result.parameters``."""
    import csv
    import io

    from robotcal.io.formats.draws_npz import write_draws
    from robotcal.io.results.provenance import versions
    from robotcal.uncertainty.measured import MODEL as MEASURED_MODEL
    from robotcal.uncertainty.measured import with_model

    echo = (
        None if scenario is None else {"name": scenario.name, "source": scenario.source, "settings": scenario.settings}
    )

    parameters = result.parameters
    write_uncertainty_csv(folder / "parameters.csv", parameters)
    # the JSON writer knows the scenario models; written as "refined", then re-labelled
    write_uncertainty_json(
        folder / "parameters.json", with_model(parameters, "refined"), scenario=echo, versions=versions()
    )
    document = json.loads((folder / "parameters.json").read_text(encoding="utf-8"))
    document["model"] = MEASURED_MODEL
    document["method"] = (
        "GUM Supplement 1 Monte Carlo (JCGM 101:2008) of a measured capture: its poses and targets simulated on "
        f"the refined parameters, each point's noise N(0, (U95/2)^2) per coordinate (k = 2, normal), "
        f"{parameters.criterion} refinement repeated per draw (thesis ch. 4.5.7)"
    )
    for row in document["parameters"]:
        row["model"] = MEASURED_MODEL
    if document.get("linearised") is not None:
        document["linearised"]["method"] = (
            "the refinement's linearised covariance (robotcal refine's, sigma_hat estimated from its residuals) "
            "rescaled by (u_stated / sigma_hat)^2 to the noise the draws use, u_stated the RMS of the points' "
            "stated standard uncertainties (U(95) / 2, or the instrument's)"
        )
        document["linearised"]["stated_u_mm"] = float(result.stated_u_mm) if np.isfinite(result.stated_u_mm) else None
        document["linearised"]["residual_sigma_mm"] = (
            float(result.residual_sigma_mm) if np.isfinite(result.residual_sigma_mm) else None
        )
        document["linearised"]["step_mm"] = None
        document["linearised"]["validation"] = (
            "JCGM 101 §8.2: both interval ends within the numerical tolerance of one significant digit of u "
            "(what a few hundred draws resolve)"
        )
    document["capture"] = {"source": capture, "params": params, "points": n_points}
    document["noise"] = result.noise_source
    document["targets"] = measured_target_rows(result)
    document["free"] = list(result.reference.identifiability.free_names)
    atomic_write_text(folder / "parameters.json", json.dumps(document, indent=2, allow_nan=False) + "\n")
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(MEASURED_TARGET_COLUMNS)
    for row in measured_target_rows(result):
        writer.writerow(["" if row[c] is None else (format(row[c], ".12g") if isinstance(row[c], float) else row[c])
                         for c in MEASURED_TARGET_COLUMNS])  # fmt: skip
    atomic_write_text(folder / "targets.csv", buffer.getvalue())
    if save_draws:
        write_draws(
            folder / "draws.npz", parameters.robot, parameters.draws, parameters.identified, seed=parameters.seed,
            model=MEASURED_MODEL,
        )  # fmt: skip
