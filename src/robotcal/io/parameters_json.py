"""Parameter JSON (docs/results.md): robot name, units, per-joint values in mm/deg, provenance.

``{"robot": ..., "units": {"length": "mm", "angle": "deg"}, "joints": [{"d", "theta", "a", "alpha",
"beta", "hayati"}, ...], "identified": ["J1.d", ...], "provenance": {...}}``. ``identified`` and
``provenance`` are extensions: readers that do not know them ignore them.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np

from robotcal.errors import InputError, RobotcalWarning
from robotcal.io._validation import _short, as_finite_float, read_json_file
from robotcal.io.atomic import atomic_write_text
from robotcal.kinematics.model import PARAMETER_KINDS, ParameterSet, RobotModel

__all__ = ["parameters_to_dict", "write_parameters", "read_parameters"]

_ANGLES = ("theta", "alpha", "beta")


def parameters_to_dict(parameters: ParameterSet, provenance: dict | None = None) -> dict:
    robot = parameters.robot
    joints = []
    for i in range(robot.n_joints):
        entry = {}
        for k, kind in enumerate(PARAMETER_KINDS):
            value = float(parameters.values[i, k])
            entry[kind] = math.degrees(value) if kind in _ANGLES else value
        entry["hayati"] = bool(robot.hayati[i])
        joints.append(entry)
    names = [n for n, flag in zip(robot.parameter_names, parameters.identified.ravel(), strict=True) if flag]
    return {
        "robot": robot.name,
        "units": {"length": "mm", "angle": "deg"},
        "joints": joints,
        "identified": names,
        "provenance": provenance or {},
    }


def write_parameters(path, parameters: ParameterSet, provenance: dict | None = None) -> Path:
    """Write a parameter JSON atomically."""
    text = json.dumps(parameters_to_dict(parameters, provenance), indent=2, allow_nan=False)
    return atomic_write_text(path, text + "\n")


def read_parameters(path, robot: RobotModel) -> ParameterSet:
    """Read a parameter JSON for ``robot``; joint count, joint types and units must match."""
    path = Path(path)
    data = read_json_file(path, kind="parameter JSON")
    if not isinstance(data, dict) or not isinstance(data.get("joints"), list):
        raise InputError(f"{path}: missing key `joints` (a list with one object per joint)")
    if data.get("robot") is not None and not isinstance(data["robot"], str):
        raise InputError(f"{path}: key `robot` must be a text; got {_short(data['robot'])}")
    if data.get("robot") not in (None, robot.name):
        warnings.warn(
            f"{path}: parameters written for robot {data['robot']!r} are read for robot {robot.name!r}",
            RobotcalWarning,
            stacklevel=2,
        )
    units = data.get("units", {"length": "mm", "angle": "deg"})
    if units != {"length": "mm", "angle": "deg"}:
        raise InputError(f"{path}: key `units` must be {{'length': 'mm', 'angle': 'deg'}}; got {_short(units)}")
    joints = data["joints"]
    if len(joints) != robot.n_joints:
        raise InputError(f"{path}: {len(joints)} joints but robot {robot.name!r} has {robot.n_joints}")
    values = np.zeros((robot.n_joints, 5))
    for i, entry in enumerate(joints):
        if not isinstance(entry, dict):
            raise InputError(f"{path}: key `joints[{i}]` must be an object")
        if "hayati" in entry and bool(entry["hayati"]) != bool(robot.hayati[i]):
            raise InputError(
                f"{path}: key `joints[{i}].hayati` is {_short(entry['hayati'])} but J{i + 1} of robot {robot.name!r} is not"
            )
        for k, kind in enumerate(PARAMETER_KINDS):
            raw = entry.get(kind, 0.0 if kind in ("beta", "d") else None)
            value = as_finite_float(raw, f"{path}: key `joints[{i}].{kind}`")
            values[i, k] = math.radians(value) if kind in _ANGLES else value
    listed = data.get("identified", [])
    if not isinstance(listed, list) or not all(isinstance(n, str) for n in listed):
        raise InputError(f'{path}: key `identified` must be a list of parameter names such as "J1.d"')
    names = set(listed)
    identified = np.array([n in names for n in robot.parameter_names]).reshape(robot.n_joints, 5)
    try:
        return ParameterSet(robot=robot, values=values, identified=identified)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
