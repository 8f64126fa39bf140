"""The headline figures of a run, computed once from its documents: how good, how sure, where.

:func:`summarise` reads the documents a run produced (:class:`robotcal.io.results.run_folder.RunResult`
``documents``: parsed JSON objects and CSV tables keyed by their path in the run folder, docs/results.md)
and returns a :class:`Summary`: the figures the report's summary cards and the console lines at the end
of ``robotcal run`` show. Every figure is taken from ONE key of ONE document, named in the field's
comment; a figure whose document the run did not produce (a stage not run), or whose key is missing or
not a number, is None. Nothing here reads a file or raises on a malformed document.

Units: lengths in mm, angles in degrees, as in the documents.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["CONSISTENT_RATIO", "Consistency", "ModelUncertainty", "Spread", "Summary", "set_label", "summarise"]

#: Observed / expected validation RMS error up to which the stated uncertainty is taken to explain the error:
#: with 100 validation poses the RMS of the observed errors scatters by about 10 % about its expectation
#: when the model holds (chi distribution with 300 degrees of freedom: relative sd ~ 1/sqrt(2*300) = 4 %,
#: widened for the correlation between poses), so a ratio of 1.5 is far outside chance and flags an error
#: the model does not hold.
CONSISTENT_RATIO = 1.5

#: Monte Carlo folders, deployed (refined) model first: (folder, model label in the console).
_MONTE_CARLOS = (("uncertainty-refined", "refined (deployed) model"), ("uncertainty", "CPA model"))


def _number(value) -> float | None:
    """A finite float from a JSON number, else None (bools, strings, NaN and missing values are not numbers)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _count(value) -> int | None:
    """A JSON integer, else None (a boolean is not a count)."""
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _text(value) -> str | None:
    return value if isinstance(value, str) and value else None


def _json(documents: Mapping, name: str) -> dict:
    document = documents.get(name)
    return document if isinstance(document, dict) else {}


def set_label(name: str | None) -> str | None:
    """People's name of an evaluation parameter set: ``"points"`` -> ``"refined, points criterion"``."""
    if name in ("points", "distances"):
        return f"refined, {name} criterion"
    if name == "cpa":
        return "CPA"
    return name


@dataclass(frozen=True, slots=True, kw_only=True)
class ModelUncertainty:
    """The largest standard uncertainty of the identified parameters of one Monte Carlo (``<folder>/parameters.json``).

    Attributes
    ----------
    folder : str
        ``"uncertainty-refined"`` (the deployed, refined model) or ``"uncertainty"`` (the CPA model).
    label : str
        How the console and the report name the model.
    draws : int or None
        ``draws``: Monte Carlo draws.
    length_mm, length_name : float or None, str or None
        Largest ``std_uncertainty`` among the identified parameters of ``unit`` ``"mm"``, and its name; of the
        refined model, among those its refinement determines (not held, not confounded with a held one).
    angle_deg, angle_name : float or None, str or None
        The same for ``unit`` ``"deg"``.
    set_aside : dict of str to (float, str, str)
        Per unit, a larger u of a parameter the refinement does not determine on its own: ``(u, name, why)``.
    bias : dict of str to (float, str, float)
        Per unit, the largest Monte Carlo bias in units of its u among the same parameters: ``(bias, name, bias / u)``
        (the headline states it beside the largest u, so that the u never hides it).
    bias_treatment : str or None
        What was done with the bias (``parameters.csv``'s ``bias_treatment``: subtracted from the deployed values,
        or reported); None in a folder written before issue 29.
    """

    folder: str
    label: str
    draws: int | None = None
    length_mm: float | None = None
    length_name: str | None = None
    angle_deg: float | None = None
    angle_name: str | None = None
    set_aside: dict = field(default_factory=dict)
    bias: dict = field(default_factory=dict)
    bias_treatment: str | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class Spread:
    """Combined standard uncertainty of the TCP position sqrt(u_X² + u_Y² + u_Z²) [mm] over the poses of a tcp.json.

    Per pose it is ``poses[].position_uncertainty_mm``; the median and 95th percentile are linear
    interpolations between order statistics (``numpy.percentile``'s default).
    """

    poses: int
    first_mm: float
    median_mm: float
    p95_mm: float
    min_mm: float
    max_mm: float
    model: str | None = None  # provenance.model
    coverage: float | None = None  # coverage (of the ellipsoid)
    ellipsoid_mm: float | None = None  # largest of poses[0].ellipsoid.semi_axes_mm


@dataclass(frozen=True, slots=True, kw_only=True)
class Consistency:
    """Does the stated uncertainty explain the validation error? (``tcp/consistency.json``).

    ``expected_rms_mm`` = sqrt(predicted² + instrument² + uncompensated²): the RMS validation error the parameter
    uncertainty, the instrument and the measured joint errors the deployed model does not represent
    (``uncompensated_rms_mm``, None when none were given) would give; ``observed_rms_mm`` is the RMS of the
    validation errors.
    """

    poses: int | None
    model: str | None
    base_frame: str | None
    predicted_rms_mm: float | None
    instrument_rms_mm: float | None
    expected_rms_mm: float
    observed_rms_mm: float
    ratio: float
    uncompensated_rms_mm: float | None = None

    @property
    def consistent(self) -> bool:
        """The observed error is within :data:`CONSISTENT_RATIO` times the expected one."""
        return self.ratio <= CONSISTENT_RATIO

    @property
    def verdict(self) -> str:
        if self.consistent:
            return "the stated uncertainty explains the error"
        return (
            "the error exceeds what the parameter uncertainty and the instrument explain: the rest is what the "
            "kinematic model does not hold (joint errors such as backlash and eccentricity, see the joint diagnostics)"
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class Summary:
    """The headline figures of a run; each None when the run did not produce it.

    Attributes
    ----------
    validation_before_mm, validation_after_mm : float or None
        Mean position error at the validation points with the ``before`` and ``after`` parameter sets
        (``evaluation/evaluation.json`` ``headline.before_mean_mm`` / ``headline.after_mean_mm``).
    validation_before_set, validation_after_set : str or None
        Their parameter sets (``headline.before_label`` / ``headline.after_label``: ``"nominal"``, ``"points"``).
    validation_capture, validation_view : str or None
        ``headline.capture`` / ``headline.view``: the capture and the error view the means are of.
    circle_rms_mm, circle_rms_circle, circles : float, int, int or None
        Largest ``circle_rms_mm`` of ``cpa/parameters.json`` ``provenance.circles``, its ``circle`` number,
        and how many circles CPA fitted.
    uncertainties : tuple of ModelUncertainty
        One per Monte Carlo run, the refined (deployed) model first.
    tcp_pose, tcp_workspace, tcp_trajectory : Spread or None
        ``tcp/pose/tcp.json``, ``tcp/workspace/tcp.json``, ``tcp/trajectory/tcp.json``.
    consistency : Consistency or None
        ``tcp/consistency.json``.
    notes : tuple of str
        Warnings of the stages and notes of ``run.json`` (``stages.*.warnings``, ``notes``), sorted, once each.
    """

    validation_before_mm: float | None = None
    validation_after_mm: float | None = None
    validation_before_set: str | None = None
    validation_after_set: str | None = None
    validation_capture: str | None = None
    validation_view: str | None = None
    circle_rms_mm: float | None = None
    circle_rms_circle: int | None = None
    circles: int | None = None
    uncertainties: tuple[ModelUncertainty, ...] = ()
    tcp_pose: Spread | None = None
    tcp_workspace: Spread | None = None
    tcp_trajectory: Spread | None = None
    consistency: Consistency | None = None
    notes: tuple[str, ...] = ()

    def uncertainty(self, folder: str) -> ModelUncertainty | None:
        """The Monte Carlo of ``folder`` (``"uncertainty-refined"`` or ``"uncertainty"``), or None."""
        return next((u for u in self.uncertainties if u.folder == folder), None)

    def console_lines(self) -> list[str]:
        """The headline lines ``robotcal run`` prints at its end (the stage table and notes are printed apart)."""
        lines = []
        if self.validation_before_mm is not None and self.validation_after_mm is not None:
            lines.append(
                f"how good: mean validation error {self.validation_before_mm:.4f} mm "
                f"({set_label(self.validation_before_set) or 'before'}) -> {self.validation_after_mm:.4f} mm "
                f"({set_label(self.validation_after_set) or 'after'})"
            )
        for model in self.uncertainties:
            parts = []
            if model.length_mm is not None:
                parts.append(f"{model.length_mm:.4f} mm (lengths)")
            if model.angle_deg is not None:
                parts.append(f"{model.angle_deg:.4f} deg (angles)")
            if not parts:
                continue
            draws = f"; {model.draws:,} draws" if model.draws is not None else ""
            over = " of the parameters its refinement determines" if model.folder == "uncertainty-refined" else ""
            lines.append(
                f"how sure, {model.label}: largest standard uncertainty{over} {', '.join(parts)}{draws}"
                + bias_text(model)
            )
        check = self.consistency
        if check is not None:
            predicted = f"{check.predicted_rms_mm:.4f} mm" if check.predicted_rms_mm is not None else "n/a"
            joint = ""
            if check.uncompensated_rms_mm is not None:
                joint = f" and the measured joint errors it cannot compensate ({check.uncompensated_rms_mm:.4f} mm)"
            lines.append(
                f"consistency at the {check.poses} validation poses: predicted RMS position uncertainty {predicted}, "
                f"with the instrument{joint} {check.expected_rms_mm:.4f} mm; observed RMS error "
                f"{check.observed_rms_mm:.4f} mm (ratio {check.ratio:.2f}: "
                f"{'consistent' if check.consistent else 'not explained by the stated uncertainty'})"
            )
        if self.tcp_pose is not None:
            which = f" ({self.tcp_pose.model})" if self.tcp_pose.model else ""
            lines.append(f"TCP position uncertainty at the pose: {self.tcp_pose.first_mm:.4f} mm{which}")
        if self.tcp_workspace is not None:
            spread = self.tcp_workspace
            lines.append(
                f"where: over {spread.poses} workspace poses the TCP position uncertainty is {spread.median_mm:.4f} mm "
                f"(median), {spread.p95_mm:.4f} mm (95th percentile), {spread.max_mm:.4f} mm (worst)"
            )
        return lines


def _validation(documents: Mapping) -> dict:
    headline = _json(documents, "evaluation/evaluation.json").get("headline")
    headline = headline if isinstance(headline, dict) else {}
    return {
        "validation_before_mm": _number(headline.get("before_mean_mm")),
        "validation_after_mm": _number(headline.get("after_mean_mm")),
        "validation_before_set": _text(headline.get("before_label")),
        "validation_after_set": _text(headline.get("after_label")),
        "validation_capture": _text(headline.get("capture")),
        "validation_view": _text(headline.get("view")),
    }


def _circles(documents: Mapping) -> dict:
    provenance = _json(documents, "cpa/parameters.json").get("provenance")
    circles = provenance.get("circles") if isinstance(provenance, dict) else None
    if not isinstance(circles, list):
        return {}
    every = [(c.get("circle"), _number(c.get("circle_rms_mm"))) for c in circles if isinstance(c, dict)]
    fits = [(circle, rms) for circle, rms in every if rms is not None]
    if not fits:
        return {"circles": len(circles)}
    circle, rms = max(fits, key=lambda fit: fit[1])
    return {
        "circle_rms_mm": rms,
        "circle_rms_circle": _count(circle),
        "circles": len(circles),
    }


def _not_determined(documents: Mapping, data: Mapping) -> dict[str, str]:
    """The refined model's parameters its refinement does not determine on their own, with why: those it holds
    (``held``, ``gauge``) and the free ones that take up their effect (``confounded``: only their combination is
    determined), from ``refine/<criterion>.json``'s provenance (identification/refine.py)."""
    criterion = found if isinstance(found := data.get("criterion"), str) else "points"
    provenance = _json(documents, f"refine/{criterion}.json").get("provenance")
    provenance = provenance if isinstance(provenance, Mapping) else {}

    def names(key: str) -> list[str]:
        listed = provenance.get(key)
        return [n for n in listed if isinstance(n, str)] if isinstance(listed, list) else []

    held = names("held") + names("gauge")
    reasons = {name: "held at its start value by the refinement" for name in held}
    with_held = f" with the held {', '.join(held)}" if held else ""
    reasons.update({n: f"confounded{with_held}: only their combination is determined" for n in names("confounded")})
    return reasons


def bias_text(model: ModelUncertainty) -> str:
    """``; largest bias 0.0078 mm (J1.a, 7.2 u), subtracted: deployed = estimate - bias`` ('' without a bias)."""
    if not model.bias:
        return ""
    bias, name, ratio = max(model.bias.values(), key=lambda entry: abs(entry[2]))
    unit = next(unit for unit, entry in model.bias.items() if entry[1] == name)
    done = f", {model.bias_treatment}" if model.bias_treatment else ""
    return f"; largest bias {bias:.4g} {unit} ({name}, {abs(ratio):.1f} u){done}"


def _model_uncertainty(documents: Mapping, folder: str, label: str) -> ModelUncertainty | None:
    data = _json(documents, f"{folder}/parameters.json")
    parameters = data.get("parameters")
    if not isinstance(parameters, list):
        return None
    reasons = _not_determined(documents, data) if folder == "uncertainty-refined" else {}
    largest: dict[str, tuple[float, str | None]] = {}
    aside: dict[str, tuple[float, str | None, str]] = {}
    biases: dict[str, tuple[float, str | None, float]] = {}
    treatment = None
    for entry in parameters:
        if not isinstance(entry, dict) or entry.get("identified") is not True:
            continue
        u, unit, name = _number(entry.get("std_uncertainty")), entry.get("unit"), _text(entry.get("name"))
        if u is None or unit not in ("mm", "deg"):
            continue
        treatment = _text(entry.get("bias_treatment")) or treatment
        bias = _number(entry.get("bias"))
        if bias is not None and u > 0 and name not in reasons and abs(bias) / u > abs(biases.get(unit, (0, "", 0.0))[2]):
            biases[unit] = (bias, name, bias / u)
        if name in reasons:
            if unit not in aside or u > aside[unit][0]:
                aside[unit] = (u, name, reasons[name])
        elif unit not in largest or u > largest[unit][0]:
            largest[unit] = (u, name)
    length, angle = largest.get("mm", (None, None)), largest.get("deg", (None, None))
    return ModelUncertainty(
        folder=folder,
        label=label,
        draws=_count(data.get("draws")),
        length_mm=length[0],
        length_name=length[1],
        angle_deg=angle[0],
        angle_name=angle[1],
        set_aside={unit: entry for unit, entry in aside.items() if entry[0] > largest.get(unit, (-1.0,))[0]},
        bias=biases,
        bias_treatment=treatment,
    )


def _spread(documents: Mapping, name: str) -> Spread | None:
    data = _json(documents, name)
    poses = data.get("poses")
    if not isinstance(poses, list):
        return None
    values = [_number(p.get("position_uncertainty_mm")) if isinstance(p, dict) else None for p in poses]
    if not values or any(v is None for v in values):
        return None
    array = np.asarray(values, dtype=float)
    p50, p95 = np.percentile(array, [50, 95])
    provenance = data.get("provenance")
    ellipsoid = poses[0].get("ellipsoid")
    axes = ellipsoid.get("semi_axes_mm") if isinstance(ellipsoid, dict) else None
    axes = [_number(a) for a in axes] if isinstance(axes, list) and axes else None
    return Spread(
        poses=array.size,
        first_mm=float(array[0]),
        median_mm=float(p50),
        p95_mm=float(p95),
        min_mm=float(array.min()),
        max_mm=float(array.max()),
        model=_text(provenance.get("model")) if isinstance(provenance, dict) else None,
        coverage=_number(data.get("coverage")),
        ellipsoid_mm=max(axes) if axes and None not in axes else None,
    )


def _consistency(documents: Mapping) -> Consistency | None:
    data = _json(documents, "tcp/consistency.json")
    expected, observed, ratio = (_number(data.get(key)) for key in ("expected_rms_mm", "observed_rms_mm", "ratio"))
    if expected is None or observed is None or ratio is None:
        return None
    return Consistency(
        poses=_count(data.get("poses")),
        model=_text(data.get("model")),
        base_frame=_text(data.get("base_frame")),
        predicted_rms_mm=_number(data.get("predicted_rms_mm")),
        instrument_rms_mm=_number(data.get("instrument_rms_mm")),
        expected_rms_mm=expected,
        observed_rms_mm=observed,
        ratio=ratio,
        uncompensated_rms_mm=_number(data.get("uncompensated_rms_mm")),
    )


def _notes(record: Mapping) -> tuple[str, ...]:
    stages = record.get("stages")
    warned: set[str] = set()
    if isinstance(stages, dict):
        for entry in stages.values():
            warnings = entry.get("warnings") if isinstance(entry, dict) else None
            if isinstance(warnings, list):
                warned.update(w for w in warnings if isinstance(w, str))
    notes = record.get("notes")
    extra = [n for n in notes if isinstance(n, str) and n not in warned] if isinstance(notes, list) else []
    return (*sorted(warned), *dict.fromkeys(extra))


def summarise(record: Mapping, documents: Mapping) -> Summary:
    """The headline figures of a run from its record (``run.json``) and documents.

    Parameters
    ----------
    record : mapping
        ``run.json`` (only its ``stages.*.warnings`` and ``notes`` are used, for :attr:`Summary.notes`).
    documents : mapping of str to Document
        The run's documents by path relative to the run folder (:class:`robotcal.io.results.run_folder.RunResult`).

    Returns
    -------
    Summary
        Every figure the documents hold; None for the others. Never raises on a missing or malformed document.

    Examples
    --------
    >>> headline = {"before_label": "nominal", "after_label": "points", "before_mean_mm": 0.59, "after_mean_mm": 0.077}
    >>> summary = summarise({}, {"evaluation/evaluation.json": {"headline": headline}})
    >>> summary.validation_after_mm, summary.tcp_pose is None
    (0.077, True)
    >>> summary.console_lines()
    ['how good: mean validation error 0.5900 mm (nominal) -> 0.0770 mm (refined, points criterion)']
    """
    uncertainties = tuple(
        model for folder, label in _MONTE_CARLOS if (model := _model_uncertainty(documents, folder, label)) is not None
    )
    return Summary(
        **_validation(documents),
        **_circles(documents),
        uncertainties=uncertainties,
        tcp_pose=_spread(documents, "tcp/pose/tcp.json"),
        tcp_workspace=_spread(documents, "tcp/workspace/tcp.json"),
        tcp_trajectory=_spread(documents, "tcp/trajectory/tcp.json"),
        consistency=_consistency(documents),
        notes=_notes(record if isinstance(record, Mapping) else {}),
    )
