"""Scenario-level glue of the planning commands: the cell of a scenario, raw scenario documents, variants.

This module reads files (robot TOML for capsule radii, instrument presets for range and acceptance);
the numeric planning modules (``cell``, ``program``, ``sensitivity``, ``optimise``) do not.
"""

from __future__ import annotations

import copy
import json
import os
from pathlib import Path

import numpy as np

from robotcal.errors import InputError
from robotcal.io.schema.builtins import builtin_names, data_path, read_toml
from robotcal.io.schema.instruments import instrument_presets
from robotcal.io.schema.scenario import Scenario, scenario_from_dict
from robotcal.planning.cell import CellModel

__all__ = [
    "DEFAULT_CAPSULE_RADIUS_MM",
    "scenario_document",
    "scenario_from_document",
    "robot_capsule_radii",
    "cell_from_scenario",
    "set_key",
]

#: Capsule radius of a link whose robot file gives none [mm].
DEFAULT_CAPSULE_RADIUS_MM = 50.0


def scenario_document(name_or_path: str | os.PathLike[str]) -> tuple[dict, Path, str, str]:
    """The parsed TOML of a built-in scenario or scenario file: ``(document, base_dir, name, source)``."""
    text = str(name_or_path)
    if text in builtin_names("scenarios"):
        path, name = data_path("scenarios", f"{text}.toml"), text
    else:
        path = Path(text)
        if not path.exists():
            raise InputError(f"unknown scenario {text!r}: not a built-in scenario nor an existing file")
        name = path.stem
    return read_toml(path), path.parent, name, str(path)


def scenario_from_document(document: dict, base_dir: Path, name: str, source: str) -> Scenario:
    """Validate a (possibly modified) scenario document, relative paths from ``base_dir``."""
    return scenario_from_dict(copy.deepcopy(document), name=name, source=source, base_dir=base_dir)


def _robot_path(scenario: Scenario) -> Path:
    text = str(scenario.settings["robot"])
    if text in builtin_names("robots"):
        return data_path("robots", f"{text}.toml")
    path = Path(text)
    base = Path(scenario.source).parent
    if not path.is_absolute() and (base / path).exists():
        path = base / path
    return path


def robot_capsule_radii(scenario: Scenario) -> tuple[np.ndarray, list[str]]:
    """Per-link capsule radii [mm] from the scenario's robot file (``capsule_radius_mm``), with notes."""
    notes = []
    try:
        joints = read_toml(_robot_path(scenario)).get("joints", [])
    except (InputError, OSError):
        joints = []
    radii = []
    for index in range(scenario.robot.n_joints):
        value = joints[index].get("capsule_radius_mm") if index < len(joints) else None
        if value is None:
            notes.append(
                f"link {index + 1}: no capsule_radius_mm in the robot file; using {DEFAULT_CAPSULE_RADIUS_MM} mm"
            )
            value = DEFAULT_CAPSULE_RADIUS_MM
        radii.append(float(value))
    return np.array(radii), notes


def cell_from_scenario(
    scenario: Scenario,
    *,
    acceptance_deg: float | None = None,
    no_acceptance: bool = False,
    aim: str = "middle",
    min_distance_m: float | None = None,
    max_distance_m: float | None = None,
) -> tuple[CellModel, list[str]]:
    """The cell of a scenario: its tracker pose, its robot's capsules, its instrument preset's range and
    acceptance (explicit arguments override the preset; ``no_acceptance`` skips that check)."""
    radii, notes = robot_capsule_radii(scenario)
    instrument = scenario.settings["instrument"]  # the validated [instrument] table, None when absent
    preset = None if instrument is None else instrument["preset"]
    entry = instrument_presets().get(preset, {}) if preset else {}
    low = entry.get("min_distance_m", 0.0) if min_distance_m is None else min_distance_m
    high = entry.get("max_distance_m", np.inf) if max_distance_m is None else max_distance_m
    angle = entry.get("reflector_acceptance_deg") if acceptance_deg is None else acceptance_deg
    if no_acceptance:
        angle = None
    if angle is None and not no_acceptance:
        notes.append("no reflector acceptance angle (instrument preset or --acceptance-deg): acceptance unchecked")
    cell = CellModel(
        tracker_from_base=scenario.tracker_from_base,
        capsule_radius=radii,
        min_distance=float(low) * 1000.0,
        max_distance=float(high) * 1000.0,
        acceptance=None if angle is None else float(np.deg2rad(angle)),
        aim=aim,
    )
    return cell, notes


def set_key(document: dict, key: str, value: object) -> dict:
    """A copy of ``document`` with the dotted ``key`` set to ``value``.

    ``capture.sweep_deg.4`` sets the 4th (1-based) element of a list; a scalar given for a key that
    holds a list (``capture.points = 40``) sets every element.
    """
    out = copy.deepcopy(document)
    parts = key.split(".")
    index = None
    if len(parts) > 1 and parts[-1].isdigit():
        index = int(parts[-1])
        parts = parts[:-1]
    node = out
    for part in parts[:-1]:
        if not isinstance(node.get(part, {}), dict):
            raise InputError(f"--vary {key}: `{part}` is not a table")
        node = node.setdefault(part, {})
    leaf = parts[-1]
    current = node.get(leaf)
    if index is not None:
        if not isinstance(current, list) or not 1 <= index <= len(current):
            raise InputError(f"--vary {key}: `{'.'.join(parts)}` is not a list with an element {index}")
        current = list(current)
        current[index - 1] = value
        node[leaf] = current
    elif isinstance(current, list) and not isinstance(value, list):
        node[leaf] = [value] * len(current)
    else:
        node[leaf] = value
    return out


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        return repr(float(value))
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items() if v is not None) + " }"
    raise InputError(f"cannot write {type(value).__name__} to TOML")


def dump_toml(document: dict, header: str = "") -> str:
    """A scenario document as TOML text (scalars, arrays, tables, arrays of tables; None dropped).

    ``tomllib.loads(dump_toml(d))`` gives ``d`` back (without its None values)."""
    lines = [f"# {line}" for line in header.splitlines()]

    def table(prefix: str, node: dict) -> None:
        simple = {k: v for k, v in node.items() if v is not None and not isinstance(v, dict) and not _tables(v)}
        for key, value in simple.items():
            lines.append(f"{key} = {_toml_value(value)}")
        for key, value in node.items():
            name = f"{prefix}.{key}" if prefix else key
            if isinstance(value, dict):
                lines.extend(["", f"[{name}]"])
                table(name, value)
            elif _tables(value):
                for item in value:
                    lines.extend(["", f"[[{name}]]"])
                    for k, v in item.items():
                        if v is not None:
                            lines.append(f"{k} = {_toml_value(v)}")

    table("", document)
    return "\n".join(lines) + "\n"


def _tables(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)
