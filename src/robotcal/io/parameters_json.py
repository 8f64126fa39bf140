"""Parameter JSON (docs/results.md): robot name, units, per-joint values in mm/deg, provenance.

``{"robot": ..., "units": {"length": "mm", "angle": "deg"}, "joints": [{"d", "theta", "a", "alpha",
"beta", "hayati"}, ...], "identified": ["J1.d", ...], "provenance": {...}}``. ``identified`` and
``provenance`` are extensions: readers that do not know them ignore them.

An extended model (:mod:`robotcal.kinematics.joint_model`) adds the key ``joint_model``: ``{"gravity_mps2": [gx,
gy, gz], "masses": {"mass_kg": [...], "com_mm": [[x, y, z], ...], "payload_kg", "payload_com_mm", "source"} |
null, "lumped": {"J2.g1": [4 n numbers], ...}, "parameters": [{"name": "J2.k", "group": "compliance", "value",
"unit": "rad/(N m)", "u": number | null, "identified": bool}, ...]}``: every parameter with its unit (``rad/(N m)``
for a compliance, ``deg`` for a lumped deflection or a harmonic amplitude). A file without the key is the
geometric model, read exactly as before.
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
from robotcal.kinematics.joint_model import MAX_DEFLECTION_DEG, JointModel, largest_deflection, parse_parameter_name
from robotcal.kinematics.model import ANGLE_KINDS, DISPLAY_UNITS, PARAMETER_KINDS, LinkMasses, ParameterSet, RobotModel

__all__ = [
    "joint_model_to_dict",
    "parameters_to_dict",
    "read_joint_model",
    "read_parameters",
    "read_targets",
    "read_tracker_from_base",
    "refined_targets",
    "targets_to_dict",
    "write_parameters",
]


def _wrap_deg(value: float, centre: float = 0.0) -> float:
    """An angle in degrees in (centre - 180, centre + 180] (a turn of 360 deg changes no transform)."""
    offset = value - centre
    return value if -180.0 < offset <= 180.0 else centre + 180.0 - (180.0 - offset) % 360.0


def targets_to_dict(targets, uncertainty=None) -> dict:
    """``{"name": {"frame": "flange", "flange_mm": [x, y, z], "known": bool, "u_mm": [ux, uy, uz] | null}}``
    for flange targets (per-joint ones: ``reflector_mm``); ``u_mm``: standard uncertainties of an estimated
    offset, null where unknown or not estimated."""
    out = {}
    for k, target in enumerate(targets):
        entry: dict = {"frame": target.frame, "known": bool(target.known)}
        if target.frame == "flange":
            entry["flange_mm"] = [float(v) for v in target.positions]
        else:
            entry["reflector_mm"] = [[float(v) for v in row] for row in target.positions]
        u = None
        if uncertainty is not None and not target.known:
            row = np.asarray(uncertainty[k], dtype=float)
            u = [float(v) if np.isfinite(v) else None for v in row]
        entry["u_mm"] = u
        out[target.name] = entry
    return out


def joint_model_to_dict(joint_model: JointModel, uncertainty=None) -> dict:
    """The ``joint_model`` key (module notes); ``uncertainty (m,)``: standard uncertainties in core units (NaN:
    none)."""
    values = joint_model.to_display(joint_model.values)
    u = np.full(joint_model.size, np.nan) if uncertainty is None else joint_model.to_display(uncertainty)
    masses = joint_model.masses
    return {
        "gravity_mps2": [float(v) for v in joint_model.gravity],
        "masses": None
        if masses is None
        else {
            "mass_kg": [float(v) for v in masses.mass_kg],
            "com_mm": [[float(v) for v in row] for row in masses.com_mm],
            "payload_kg": float(masses.payload_kg),
            "payload_com_mm": [float(v) for v in masses.payload_com_mm],
            "source": masses.source,
        },
        "lumped": {name: [float(v) for v in vector] for name, vector in joint_model.lumped.items()},
        "backlash_deg": [float(v) for v in np.degrees(joint_model.backlash)],
        "backlash_source": joint_model.backlash_source,
        "parameters": [
            {
                "name": name,
                "group": group,
                "value": float(value),
                "unit": unit,
                "u": float(sd) if np.isfinite(sd) else None,
                "identified": bool(flag),
            }
            for name, group, value, unit, sd, flag in zip(
                joint_model.names,
                joint_model.groups,
                values,
                joint_model.display_units,
                u,
                joint_model.identified,
                strict=True,
            )
        ],
    }


def read_joint_model(data, robot: RobotModel, path) -> JointModel:
    """A ``joint_model`` document (the parameter JSON's key) back as a :class:`JointModel` (errors name ``path`` and
    the key)."""
    where = f"{path}: key `joint_model"
    if not isinstance(data, dict) or not isinstance(data.get("parameters"), list):
        raise InputError(f"{where}` must be an object with a list `parameters`")
    gravity = data.get("gravity_mps2", [0.0, 0.0, -9.81])
    if not isinstance(gravity, list) or len(gravity) != 3:
        raise InputError(f"{where}.gravity_mps2` must be [gx, gy, gz]")
    gravity = [as_finite_float(v, f"{where}.gravity_mps2`") for v in gravity]
    masses = None
    if data.get("masses") is not None:
        entry = data["masses"]
        if not isinstance(entry, dict):
            raise InputError(f"{where}.masses` must be an object or null")
        try:
            masses = LinkMasses(
                mass_kg=[as_finite_float(v, f"{where}.masses.mass_kg`") for v in entry.get("mass_kg", [])],
                com_mm=np.asarray(entry.get("com_mm", []), dtype=float),
                payload_kg=as_finite_float(entry.get("payload_kg", 0.0), f"{where}.masses.payload_kg`"),
                payload_com_mm=np.asarray(entry.get("payload_com_mm", [0.0, 0.0, 0.0]), dtype=float),
                source=str(entry.get("source", "")),
            )
        except (TypeError, ValueError, InputError) as exc:
            raise InputError(f"{where}.masses`: {exc}") from None
    lumped = data.get("lumped", {})
    if not isinstance(lumped, dict):
        raise InputError(f"{where}.lumped` must be an object of term names")
    names, values, flags = [], [], []
    for k, entry in enumerate(data["parameters"]):
        if not isinstance(entry, dict) or not isinstance(entry.get("name"), str):
            raise InputError(f"{where}.parameters[{k}]` must be an object with a `name`")
        try:
            parse_parameter_name(entry["name"], robot.n_joints)
        except InputError as exc:
            raise InputError(f"{where}.parameters[{k}].name`: {exc}") from None
        names.append(entry["name"])
        values.append(as_finite_float(entry.get("value"), f"{where}.parameters[{k}].value`"))
        flags.append(bool(entry.get("identified", False)))
    try:
        model = JointModel.assemble(
            robot, names, np.zeros(len(names)), identified=flags, masses=masses,
            lumped={name: np.asarray(vector, dtype=float) for name, vector in lumped.items()}, gravity=gravity,
        )  # fmt: skip
    except (TypeError, ValueError) as exc:
        raise InputError(f"{where}`: {exc}") from None
    except InputError as exc:
        raise InputError(f"{where}`: {exc}") from None
    for k, (entry, unit) in enumerate(zip(data["parameters"], model.display_units, strict=True)):
        if entry.get("unit", unit) != unit:
            raise InputError(
                f"{where}.parameters[{k}].unit` of {entry['name']} must be {unit!r}; got {_short(entry['unit'])}"
            )
    lash = data.get("backlash_deg", [0.0] * robot.n_joints)
    if not isinstance(lash, list) or len(lash) != robot.n_joints:
        raise InputError(f"{where}.backlash_deg` must be {robot.n_joints} angles [deg]")
    lash = np.radians([as_finite_float(v, f"{where}.backlash_deg`") for v in lash])
    model = model.with_values(model.from_display(values))
    _check_deflection(model, robot, values, where)
    return model.with_backlash(lash, str(data.get("backlash_source", "")))


def _check_deflection(model: JointModel, robot: RobotModel, display_values, where: str) -> None:
    """Refuse a joint model that deflects a joint by more than :data:`MAX_DEFLECTION_DEG` at a pose within the
    limits (a compliance of 1 rad/(N m) moved ``predict``'s flange by a metre, issue 30): no robot's joint does,
    so the value is a typing error or a unit slip, and every prediction from it would be wrong."""
    if model.is_empty:
        return
    worst = largest_deflection(model, robot)
    if np.degrees(worst.angle) <= MAX_DEFLECTION_DEG:
        return
    k = worst.parameter
    angle = np.degrees(worst.angle)
    pose = ", ".join(f"{v:.4g}" for v in np.degrees(worst.readings))
    shift = f" and moves the flange by {worst.flange_shift_mm:,.1f} mm" if angle < 90.0 else ""  # else it wraps
    raise InputError(
        f"{where}.parameters[{k}].value`: {model.names[k]} = {display_values[k]:g} {model.display_units[k]} deflects "
        f"J{worst.joint + 1} by {angle:.3g} deg at the readings [{pose}] deg{shift}: more than the "
        f"{MAX_DEFLECTION_DEG:g} deg of any robot's joint (a "
        "compliance of 1e-6..1e-4 rad/(N m) sags a joint by under 0.2 deg, gear harmonics are arc-minutes); check the "
        "value and its unit"
    )


def parameters_to_dict(
    parameters: ParameterSet, provenance: dict | None = None, targets: dict | None = None, joint_model_u=None
) -> dict:
    """The parameter JSON document; angles in degrees within 180 deg of their nominal value (the branch of the
    nominal: see :func:`robotcal.identification.refine.wrap_angles`). ``targets`` (from
    :func:`targets_to_dict`) adds the key ``targets``: the refined (estimated) target offsets. An extended set
    adds ``joint_model`` (module notes), ``joint_model_u`` its standard uncertainties (core units)."""
    robot = parameters.robot
    joints = []
    for i in range(robot.n_joints):
        entry = {}
        for k, kind in enumerate(PARAMETER_KINDS):
            value = float(parameters.values[i, k])
            if kind in ANGLE_KINDS:
                value = _wrap_deg(math.degrees(value), math.degrees(float(robot.nominal[i, k])))
            entry[kind] = value
        entry["hayati"] = bool(robot.hayati[i])
        joints.append(entry)
    names = [n for n, flag in zip(robot.parameter_names, parameters.identified.ravel(), strict=True) if flag]
    document = {
        "robot": robot.name,
        "units": dict(DISPLAY_UNITS),
        "joints": joints,
        "identified": names,
    }
    if targets:
        document["targets"] = targets
    if parameters.joint_model is not None:
        document["joint_model"] = joint_model_to_dict(parameters.joint_model, joint_model_u)
    document["provenance"] = provenance or {}
    return document


def write_parameters(
    path, parameters: ParameterSet, provenance: dict | None = None, targets: dict | None = None, joint_model_u=None
) -> Path:
    """Write a parameter JSON atomically (``targets``, ``joint_model_u``: see :func:`parameters_to_dict`)."""
    text = json.dumps(parameters_to_dict(parameters, provenance, targets, joint_model_u), indent=2, allow_nan=False)
    return atomic_write_text(path, text + "\n")


def read_targets(path) -> dict:
    """The ``targets`` key of a parameter JSON: ``{name: (x, y, z) flange offset [mm]}`` of its flange
    targets (empty when the key is absent)."""
    path = Path(path)
    data = read_json_file(path, kind="parameter JSON")
    entries = data.get("targets") if isinstance(data, dict) else None
    if entries is None:
        return {}
    if not isinstance(entries, dict):
        raise InputError(f"{path}: key `targets` must be an object of target names")
    out = {}
    for name, entry in entries.items():
        if not isinstance(entry, dict):
            raise InputError(f"{path}: key `targets.{name}` must be an object")
        if entry.get("frame", "flange") != "flange" or "flange_mm" not in entry:
            continue
        position = entry["flange_mm"]
        if not isinstance(position, list) or len(position) != 3:
            raise InputError(f"{path}: key `targets.{name}.flange_mm` must be [x, y, z]")
        out[name] = tuple(as_finite_float(v, f"{path}: key `targets.{name}.flange_mm`") for v in position)
    return out


def read_tracker_from_base(path) -> np.ndarray | None:
    """The base frame a fit recorded, ``provenance.tracker_from_base`` of a parameter JSON, as a (4, 4)
    rigid transform [mm]; None when the key is absent or null (a nominal set, a distances-criterion
    refinement). A value that is not a rigid 4x4 transform is an :class:`InputError` naming the key."""
    from robotcal.geometry.transforms import check_rigid_transform

    path = Path(path)
    data = read_json_file(path, kind="parameter JSON")
    provenance = data.get("provenance") if isinstance(data, dict) else None
    matrix = provenance.get("tracker_from_base") if isinstance(provenance, dict) else None
    if matrix is None:
        return None
    try:
        return check_rigid_transform(np.asarray(matrix, dtype=float), f"{path}: provenance.tracker_from_base")
    except (TypeError, ValueError) as exc:
        raise InputError(f"{path}: key `provenance.tracker_from_base` must be a 4x4 rigid transform ({exc})") from None


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
    units = data.get("units", dict(DISPLAY_UNITS))  # optional: robotcal's units when absent
    if units != dict(DISPLAY_UNITS):
        raise InputError(f"{path}: key `units` must be {dict(DISPLAY_UNITS)}; got {_short(units)}")
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
            values[i, k] = math.radians(value) if kind in ANGLE_KINDS else value
    listed = data.get("identified", [])
    if not isinstance(listed, list) or not all(isinstance(n, str) for n in listed):
        raise InputError(f'{path}: key `identified` must be a list of parameter names such as "J1.d"')
    names = set(listed)
    identified = np.array([n in names for n in robot.parameter_names]).reshape(robot.n_joints, 5)
    joint_model = None if data.get("joint_model") is None else read_joint_model(data["joint_model"], robot, path)
    try:
        return ParameterSet(robot=robot, values=values, identified=identified, joint_model=joint_model)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def refined_targets(result) -> dict | None:
    """The parameter JSON's ``targets`` key of a refinement (estimated offsets with their standard
    uncertainty), None when it used the historical single mount."""
    if not result.targets:
        return None
    return targets_to_dict(result.targets, result.uncertainty.target_uncertainty)
