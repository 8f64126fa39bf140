"""Before/after evaluation of parameter sets on measured captures (thesis Tables 4.10 and 4.11).

Two views of the error, one per criterion of ch. 4.5.7:

``"points"`` (Table 4.10)
    each parameter set's predicted target positions (base frame) are registered onto the measured
    points (tracker frame) by Horn's method, and the error of a point is its distance after
    registration ``|T p_k - m_k|``.
``"distances"`` (Table 4.11)
    the error of a pair i < j of distinct measurements (different poses or, with per-joint
    reflectors, different targets) is ``| |p_i - p_j| - |m_i - m_j| |``,
    over all such pairs (no registration).

The improvement of a set is ``100 (1 - mean / mean_reference)`` [%], the reference being the
first set given (normally the nominal parameters), per view and capture, as in the tables'
"Mejora promedio" columns (e.g. test 2, CPA: 1 - 0.6498/1.0015 = 35.12 %).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import pdist

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.geometry.registration import register_points
from robotcal.identification.refine import capture_target_index, capture_turning_joints, measurement_pairs
from robotcal.kinematics.forward import target_positions
from robotcal.kinematics.model import ParameterSet, ReflectorMount

__all__ = ["VIEWS", "EvaluationRow", "point_errors", "distance_errors", "evaluate_parameters"]

#: Evaluation views (Tables 4.10, 4.11).
VIEWS = ("points", "distances")


@dataclass(frozen=True, slots=True, kw_only=True)
class EvaluationRow:
    """Errors of one parameter set on one capture under one view [mm]."""

    parameter_set: str
    view: str
    capture: str
    n_errors: int
    mean_error_mm: float
    max_error_mm: float
    rms_error_mm: float
    improvement_pct: float


def _predicted(capture: Capture, parameters: ParameterSet, reflector: ReflectorMount) -> np.ndarray:
    robot = parameters.robot
    if capture.n_joints != robot.n_joints:
        raise InputError(
            f"{capture.source}: {capture.n_joints} joint readings per point; robot {robot.name!r} has {robot.n_joints}"
        )
    turning = capture_turning_joints(capture, reflector)
    return target_positions(parameters.values, robot.model_joint_variables(capture.readings), turning, reflector)


def point_errors(capture: Capture, parameters: ParameterSet, reflector: ReflectorMount) -> np.ndarray:
    """Per-point distance after registering the predicted points onto the measured ones, ``(n_points,)`` [mm]."""
    predicted = _predicted(capture, parameters, reflector)
    return register_points(predicted, capture.points).residuals


def distance_errors(capture: Capture, parameters: ParameterSet, reflector: ReflectorMount) -> np.ndarray:
    """``| |p_i - p_j| - |m_i - m_j| |`` over pairs of distinct measurements, ``(n_pairs,)`` [mm].

    A pair at the same readings on the same target (bidirectional twins) is left out; with per-joint
    reflectors points of different circles are different targets (see
    :func:`robotcal.identification.refine.measurement_pairs`).
    """
    predicted = _predicted(capture, parameters, reflector)
    _, _, keep = measurement_pairs(capture.readings, capture_target_index(capture, reflector))
    return np.abs(pdist(predicted) - pdist(capture.points))[keep]


def evaluate_parameters(
    captures: Mapping[str, Capture],
    parameter_sets: Mapping[str, ParameterSet],
    reflectors: Mapping[str, ReflectorMount] | ReflectorMount,
    *,
    views=VIEWS,
) -> tuple[EvaluationRow, ...]:
    """Mean, max and RMS errors of every parameter set on every capture under each view.

    Parameters
    ----------
    captures : mapping of str to Capture
        E.g. ``{"calibration": ..., "validation": ...}``.
    parameter_sets : mapping of str to ParameterSet
        E.g. ``{"nominal": ..., "cpa": ..., "points": ..., "distances": ...}``; the first is the
        reference of ``improvement_pct``.
    reflectors : ReflectorMount or mapping of str to ReflectorMount
        The target of each capture (one for all, or per capture name).
    views : sequence of {"points", "distances"}

    Returns
    -------
    tuple of EvaluationRow
        Ordered by capture, view, parameter set.
    """
    if not captures or not parameter_sets:
        raise InputError("evaluation needs at least one capture and one parameter set")
    unknown = [view for view in views if view not in VIEWS]
    if unknown:
        raise InputError(f"unknown evaluation view(s) {unknown}; expected {VIEWS}")
    functions = {"points": point_errors, "distances": distance_errors}
    rows = []
    for capture_name, capture in captures.items():
        reflector = reflectors if isinstance(reflectors, ReflectorMount) else reflectors.get(capture_name)
        if reflector is None:
            raise InputError(f"no reflector given for capture {capture_name!r}")
        for view in views:
            reference = None
            for set_name, parameters in parameter_sets.items():
                errors = functions[view](capture, parameters, reflector)
                mean = float(errors.mean())
                reference = mean if reference is None else reference
                improvement = 100.0 * (1.0 - mean / reference) if reference > 0 else 0.0
                rows.append(
                    EvaluationRow(
                        parameter_set=set_name,
                        view=view,
                        capture=capture_name,
                        n_errors=int(errors.size),
                        mean_error_mm=mean,
                        max_error_mm=float(errors.max()),
                        rms_error_mm=float(np.sqrt(np.mean(errors**2))),
                        improvement_pct=float(improvement),
                    )
                )
    return tuple(rows)
