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
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
from numpy.typing import ArrayLike
from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from robotcal.errors import InputError, RobotcalWarning
from robotcal.io.atomic import atomic_write_text
from robotcal.io.schema._validation import XYZ, Matrix4, TomlBool, TomlFloat, as_toml, read_json_file, validate_model
from robotcal.kinematics.joint_model import MAX_DEFLECTION_DEG, JointModel, largest_deflection, parse_parameter_name
from robotcal.kinematics.model import ANGLE_KINDS, DISPLAY_UNITS, PARAMETER_KINDS, LinkMasses, ParameterSet, RobotModel

if TYPE_CHECKING:
    from robotcal.identification.records import RefinementResult, SessionFrame
    from robotcal.identification.targets import Target

__all__ = [
    "ParameterFile",
    "JointValues",
    "JointModelEntry",
    "joint_model_to_dict",
    "parameters_to_dict",
    "read_joint_model",
    "read_parameters",
    "read_sessions",
    "read_targets",
    "read_tracker_from_base",
    "probe_to_dict",
    "read_probe",
    "refined_sessions",
    "refined_targets",
    "sessions_to_dict",
    "targets_to_dict",
    "write_parameters",
]


def _wrap_deg(value: float, centre: float = 0.0) -> float:
    """An angle in degrees in (centre - 180, centre + 180] (a turn of 360 deg changes no transform)."""
    offset = value - centre
    return value if -180.0 < offset <= 180.0 else centre + 180.0 - (180.0 - offset) % 360.0


def targets_to_dict(targets: Sequence[Target], uncertainty: ArrayLike | None = None) -> dict:
    """``{"name": {"frame": "flange", "flange_mm": [x, y, z], "known": bool, "u_mm": [ux, uy, uz] | null}}``
    for flange targets (per-joint ones: ``reflector_mm``); ``u_mm``: standard uncertainties of an estimated
    offset, null where unknown or not estimated."""
    out: dict[str, dict] = {}
    uncertainties = None if uncertainty is None else np.asarray(uncertainty, dtype=float)
    for k, target in enumerate(targets):
        entry: dict = {"frame": target.frame, "known": bool(target.known)}
        if target.frame == "flange":
            entry["flange_mm"] = [float(v) for v in target.positions]
        else:
            entry["reflector_mm"] = [[float(v) for v in row] for row in target.positions]
        u = None
        if uncertainties is not None and not target.known:
            row = uncertainties[k]
            u = [float(v) if np.isfinite(v) else None for v in row]
        entry["u_mm"] = u
        out[target.name] = entry
    return out


def joint_model_to_dict(joint_model: JointModel, uncertainty: ArrayLike | None = None) -> dict:
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


class _JsonObject(BaseModel):
    """An object of the parameter JSON: strict types, unknown keys ignored (the format's extensions, docs/scenario.md)."""

    model_config = ConfigDict(extra="ignore", frozen=True)


class JointValues(_JsonObject):
    """One entry of ``joints`` [mm, deg]: ``theta``, ``a`` and ``alpha`` required, ``d`` and ``beta`` 0 if absent."""

    d: TomlFloat = 0.0
    theta: TomlFloat
    a: TomlFloat
    alpha: TomlFloat
    beta: TomlFloat = 0.0
    hayati: TomlBool | None = None


class MassesEntry(_JsonObject):
    """``joint_model.masses``: the link masses and the payload [kg, mm]."""

    mass_kg: list[TomlFloat] = []
    com_mm: list[XYZ] = []
    payload_kg: TomlFloat = 0.0
    payload_com_mm: XYZ = (0.0, 0.0, 0.0)
    source: str = ""


class JointModelParameter(_JsonObject):
    """One entry of ``joint_model.parameters`` (``group`` and ``u`` are written for people, not read)."""

    name: str
    value: TomlFloat
    unit: str | None = None
    identified: TomlBool = False


class JointModelEntry(_JsonObject):
    """The ``joint_model`` key (module notes)."""

    parameters: list[JointModelParameter]
    gravity_mps2: XYZ = (0.0, 0.0, -9.81)
    masses: MassesEntry | None = None
    lumped: dict[str, list[TomlFloat]] = {}
    backlash_deg: list[TomlFloat] | None = None
    backlash_source: str = ""


class TargetEntry(_JsonObject):
    """One entry of ``targets``: a flange target's ``flange_mm`` is read, a per-joint one is skipped."""

    frame: str = "flange"
    flange_mm: XYZ | None = None


def _units(value: dict) -> dict:
    if value != dict(DISPLAY_UNITS):
        raise ValueError(f"must be {dict(DISPLAY_UNITS)}")
    return value


class ParameterFile(_JsonObject):
    """The parameter JSON (docs/scenario.md): what robotcal reads of it."""

    robot: str | None = None
    units: Annotated[dict, AfterValidator(_units)] = dict(DISPLAY_UNITS)
    joints: list[JointValues]
    identified: list[str] = []
    joint_model: JointModelEntry | None = None


class _TargetsPart(_JsonObject):
    targets: dict[str, TargetEntry] | None = None


class SessionEntry(_JsonObject):
    """One entry of ``sessions``: a session's base frame (what robotcal reads of it)."""

    tracker_from_base: Matrix4


class _SessionsPart(_JsonObject):
    sessions: dict[str, SessionEntry] | None = None


class ProbeEntry(_JsonObject):
    """The ``probe`` key: what robotcal reads of it (the rotation as a quaternion, scalar first)."""

    quaternion: Annotated[list[TomlFloat], Field(min_length=4, max_length=4)]


class _ProbePart(_JsonObject):
    probe: ProbeEntry | None = None


class _ProvenanceEntry(_JsonObject):
    """What robotcal reads of ``provenance``: the base frame a fit recorded (null: none)."""

    tracker_from_base: Matrix4 | None = None


class _ProvenancePart(_JsonObject):
    provenance: _ProvenanceEntry | None = None


class _JointModelPart(_JsonObject):
    joint_model: JointModelEntry


def read_joint_model(data: Any, robot: RobotModel, path: str | os.PathLike[str]) -> JointModel:
    """A ``joint_model`` document (the parameter JSON's key) back as a :class:`JointModel` (errors name ``path`` and
    the key)."""
    part: _JointModelPart = validate_model(_JointModelPart, {"joint_model": data}, str(path))
    return _joint_model(part.joint_model, robot, path)


def _joint_model(entry: JointModelEntry, robot: RobotModel, path: str | os.PathLike[str]) -> JointModel:
    """The validated ``joint_model`` key as a :class:`JointModel`: what the schema cannot say (names, units,
    sizes that depend on the robot, the deflection bound) checked here."""
    where = f"{path}: key `joint_model"
    masses = None
    if entry.masses is not None:
        try:
            masses = LinkMasses(
                mass_kg=np.array(entry.masses.mass_kg, dtype=float),
                com_mm=np.asarray(entry.masses.com_mm, dtype=float),
                payload_kg=entry.masses.payload_kg,
                payload_com_mm=np.asarray(entry.masses.payload_com_mm, dtype=float),
                source=entry.masses.source,
            )
        except (TypeError, ValueError, InputError) as exc:
            raise InputError(f"{where}.masses`: {exc}") from None
    for k, parameter in enumerate(entry.parameters):
        try:
            parse_parameter_name(parameter.name, robot.n_joints)
        except InputError as exc:
            raise InputError(f"{where}.parameters[{k}].name`: {exc}") from None
    names = [parameter.name for parameter in entry.parameters]
    values = [parameter.value for parameter in entry.parameters]
    try:
        model = JointModel.assemble(
            robot, names, np.zeros(len(names)), identified=[parameter.identified for parameter in entry.parameters],
            masses=masses, lumped={name: np.asarray(vector, dtype=float) for name, vector in entry.lumped.items()},
            gravity=list(entry.gravity_mps2),
        )  # fmt: skip
    except (TypeError, ValueError, InputError) as exc:
        raise InputError(f"{where}`: {exc}") from None
    for k, (parameter, unit) in enumerate(zip(entry.parameters, model.display_units, strict=True)):
        if parameter.unit not in (None, unit):
            raise InputError(
                f"{where}.parameters[{k}].unit` of {parameter.name} must be {unit!r}; got {as_toml(parameter.unit)}"
            )
    lash = [0.0] * robot.n_joints if entry.backlash_deg is None else entry.backlash_deg
    if len(lash) != robot.n_joints:
        raise InputError(f"{where}.backlash_deg` must be {robot.n_joints} angles [deg]; got {len(lash)}")
    model = model.with_values(model.from_display(values))
    _check_deflection(model, robot, values, where)
    return model.with_backlash(np.radians(lash), entry.backlash_source)


def _check_deflection(model: JointModel, robot: RobotModel, display_values: Sequence[float], where: str) -> None:
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
    parameters: ParameterSet,
    provenance: dict | None = None,
    targets: dict | None = None,
    joint_model_u: ArrayLike | None = None,
    extensions: dict | None = None,
) -> dict:
    """The parameter JSON document; angles in degrees within 180 deg of their nominal value (the branch of the
    nominal: see :func:`robotcal.identification.refine.wrap_angles`). ``targets`` (from
    :func:`targets_to_dict`) adds the key ``targets``: the refined (estimated) target offsets. An extended set
    adds ``joint_model`` (module notes), ``joint_model_u`` its standard uncertainties (core units).
    ``extensions`` adds its keys that have a value: ``sessions`` (:func:`sessions_to_dict`, the base frame of every
    measurement session) and ``probe`` (:func:`probe_to_dict`, a 6-DoF probe's rotation on the flange)."""
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
    document.update({key: value for key, value in (extensions or {}).items() if value})
    if parameters.joint_model is not None:
        document["joint_model"] = joint_model_to_dict(parameters.joint_model, joint_model_u)
    document["provenance"] = provenance or {}
    return document


def write_parameters(
    path: str | os.PathLike[str],
    parameters: ParameterSet,
    provenance: dict | None = None,
    targets: dict | None = None,
    joint_model_u: ArrayLike | None = None,
    extensions: dict | None = None,
) -> Path:
    """Write a parameter JSON atomically (``targets``, ``joint_model_u``, ``extensions``: see
    :func:`parameters_to_dict`)."""
    document = parameters_to_dict(parameters, provenance, targets, joint_model_u, extensions)
    text = json.dumps(document, indent=2, allow_nan=False)
    return atomic_write_text(path, text + "\n")


def read_targets(path: str | os.PathLike[str]) -> dict:
    """The ``targets`` key of a parameter JSON: ``{name: (x, y, z) flange offset [mm]}`` of its flange
    targets (empty when the key is absent)."""
    path = Path(path)
    data = read_json_file(path, kind="parameter JSON")
    part: _TargetsPart = validate_model(_TargetsPart, data if isinstance(data, dict) else {}, str(path))
    entries = part.targets or {}
    return {
        name: entry.flange_mm
        for name, entry in entries.items()
        if entry.frame == "flange" and entry.flange_mm is not None
    }


def sessions_to_dict(frames: Sequence[SessionFrame]) -> dict:
    """The ``sessions`` key: per session (in the refinement's order, the first its reference) its
    ``tracker_from_base`` [mm] and the standard uncertainties ``u`` of its corrections (``T = T_start [Rz Ry Rx |
    t]``: ``tx_mm, ty_mm, tz_mm, rx_deg, ry_deg, rz_deg``; null where held)."""
    keys = ("tx_mm", "ty_mm", "tz_mm", "rx_deg", "ry_deg", "rz_deg")
    out = {}
    for frame in frames:
        u = np.asarray(frame.standard_uncertainty, dtype=float).copy()
        u[3:] = np.rad2deg(u[3:])
        out[frame.name] = {
            "tracker_from_base": np.asarray(frame.tracker_from_base, dtype=float).tolist(),
            "u": {key: None if not np.isfinite(value) else float(value) for key, value in zip(keys, u, strict=True)},
        }
    return out


def probe_to_dict(result: RefinementResult) -> dict | None:
    """The ``probe`` key of a 6-DoF refinement: the probe's target (its position is that target's offset in
    ``targets``), its rotation in the flange frame as a quaternion ``qw, qx, qy, qz`` and a matrix, the standard
    uncertainties of the rotation's corrections ``u_deg`` (rx, ry, rz; null where not estimated) and the RMS of the
    orientation residuals [deg]; None without orientations."""
    from robotcal.io.formats.orientation import quaternions_from_rotations

    probe = result.probe
    if probe is None:
        return None
    target = next((t.name for t in result.targets if t.frame == "flange"), None)
    u = np.rad2deg(np.asarray(probe.standard_uncertainty, dtype=float))
    return {
        "target": target,
        "quaternion": quaternions_from_rotations(probe.rotation[None])[0].tolist(),
        "rotation": np.asarray(probe.rotation, dtype=float).tolist(),
        "u_deg": [None if not np.isfinite(value) else float(value) for value in u],
        "orientation_rms_deg": probe.orientation_rms_deg,
    }


def read_probe(path: str | os.PathLike[str]) -> np.ndarray | None:
    """The probe's rotation in the flange frame (``probe.quaternion`` of a parameter JSON), None when absent."""
    from robotcal.io.formats.orientation import rotations_from_quaternions

    path = Path(path)
    data = read_json_file(path, kind="parameter JSON")
    part: _ProbePart = validate_model(_ProbePart, data if isinstance(data, dict) else {}, str(path))
    if part.probe is None:
        return None
    return rotations_from_quaternions([part.probe.quaternion], source=f"{path}: probe.quaternion")[0]


def refined_sessions(result: RefinementResult) -> dict | None:
    """The parameter JSON's ``sessions`` key of a refinement over several sessions, None otherwise."""
    return sessions_to_dict(result.sessions) if result.sessions else None


def read_sessions(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """The ``sessions`` key of a parameter JSON: ``{session: tracker_from_base (4, 4) [mm]}`` in the file's order
    (empty when absent); a frame that is not a rigid 4x4 transform is an :class:`InputError` naming the key."""
    from robotcal.geometry.transforms import check_rigid_transform

    path = Path(path)
    data = read_json_file(path, kind="parameter JSON")
    part: _SessionsPart = validate_model(_SessionsPart, data if isinstance(data, dict) else {}, str(path))
    frames = {}
    for name, entry in (part.sessions or {}).items():
        key = f"sessions.{name}.tracker_from_base"
        try:
            frames[name] = check_rigid_transform(np.asarray(entry.tracker_from_base, dtype=float), f"{path}: {key}")
        except InputError as exc:
            raise InputError(f"{path}: key `{key}` must be a 4x4 rigid transform ({exc})") from None
    return frames


def read_tracker_from_base(path: str | os.PathLike[str]) -> np.ndarray | None:
    """The base frame a fit recorded, ``provenance.tracker_from_base`` of a parameter JSON, as a (4, 4)
    rigid transform [mm]; None when the key is absent or null (a nominal set, a distances-criterion
    refinement). A value that is not a rigid 4x4 transform is an :class:`InputError` naming the key."""
    from robotcal.geometry.transforms import check_rigid_transform

    path = Path(path)
    data = read_json_file(path, kind="parameter JSON")
    part: _ProvenancePart = validate_model(_ProvenancePart, data if isinstance(data, dict) else {}, str(path))
    matrix = None if part.provenance is None else part.provenance.tracker_from_base
    if matrix is None:
        return None
    try:  # a 4x4 matrix of numbers by its type: the rigidity is the core's check
        return check_rigid_transform(np.asarray(matrix, dtype=float), f"{path}: provenance.tracker_from_base")
    except InputError as exc:
        raise InputError(f"{path}: key `provenance.tracker_from_base` must be a 4x4 rigid transform ({exc})") from None


def read_parameters(path: str | os.PathLike[str], robot: RobotModel) -> ParameterSet:
    """Read a parameter JSON for ``robot`` (schema :class:`ParameterFile`); joint count and types must match."""
    path = Path(path)
    data = read_json_file(path, kind="parameter JSON")
    document: ParameterFile = validate_model(ParameterFile, data, str(path))
    if document.robot not in (None, robot.name):
        warnings.warn(
            f"{path}: parameters written for robot {document.robot!r} are read for robot {robot.name!r}",
            RobotcalWarning,
            stacklevel=2,
        )
    if len(document.joints) != robot.n_joints:
        raise InputError(f"{path}: {len(document.joints)} joints but robot {robot.name!r} has {robot.n_joints}")
    values = np.zeros((robot.n_joints, 5))
    for i, entry in enumerate(document.joints):
        if entry.hayati is not None and entry.hayati != bool(robot.hayati[i]):
            raise InputError(
                f"{path}: key `joints[{i}].hayati` is {as_toml(entry.hayati)} but J{i + 1} of robot {robot.name!r} "
                "is not"
            )
        for k, kind in enumerate(PARAMETER_KINDS):
            value = getattr(entry, kind)
            values[i, k] = math.radians(value) if kind in ANGLE_KINDS else value
    names = set(document.identified)
    identified = np.array([n in names for n in robot.parameter_names]).reshape(robot.n_joints, 5)
    joint_model = None if document.joint_model is None else _joint_model(document.joint_model, robot, path)
    try:
        return ParameterSet(robot=robot, values=values, identified=identified, joint_model=joint_model)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def refined_targets(result: RefinementResult) -> dict | None:
    """The parameter JSON's ``targets`` key of a refinement (estimated offsets with their standard
    uncertainty), None when it used the historical single mount."""
    if not result.targets:
        return None
    return targets_to_dict(result.targets, result.uncertainty.target_uncertainty)
