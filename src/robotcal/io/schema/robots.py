"""Robot TOML files: ``name``, ``joints = [{d, theta, a, alpha, beta, hayati, limits_deg, ...}]``.

Lengths in mm and angles in degrees (docs/results.md). Optional per joint: ``reading_sign`` (+1 or
-1) and ``reading_offset_deg``, mapping controller readings to model joint variables
(``q = reading_sign * reading + reading_offset``); both default to the identity map.

Optional per joint ``reading_coupling = {2 = -1.0}`` (keys: other joints, 1-based): the joint's
reading also depends on those joints' model variables,
``reading_k = reading_sign_k (q_k - o_k) + sum_j c_kj (q_j - o_j)`` with ``o = reading_offset``
(a Fanuc-style J3 reading that is the forearm's angle to the horizontal; see
``fanuc-style-coupled.toml``). The whole map must be invertible. No key: today's uncoupled map.

Optional per joint ``mass_kg`` and ``com_mm = [x, y, z]``: the mass of the link the joint moves and its centre
of mass in the joint's DH frame {i} [kg, mm], for the gravity compliance of the extended model
(:mod:`robotcal.kinematics.joint_model`); given for every joint or for none, with ``mass_source`` saying where
the numbers come from.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from robotcal.errors import InputError
from robotcal.io.schema._validation import XYZ, TomlBool, TomlFloat, TomlInt, validate_model
from robotcal.io.schema.builtins import builtin_names, data_path, read_toml
from robotcal.kinematics.model import ANGLE_COLUMNS, LinkMasses, RobotModel

__all__ = ["robot_to_dict", "RobotFile", "JointEntry", "load_robot", "robot_from_dict", "list_robots"]


class JointEntry(BaseModel):
    model_config = ConfigDict(extra="forbid")

    d: TomlFloat = 0.0
    theta: TomlFloat = 0.0
    a: TomlFloat = 0.0
    alpha: TomlFloat = 0.0
    beta: TomlFloat = 0.0
    hayati: TomlBool = False
    limits_deg: tuple[TomlFloat, TomlFloat] = (-360.0, 360.0)
    reading_sign: TomlInt = 1
    reading_offset_deg: TomlFloat = 0.0
    capsule_radius_mm: TomlFloat | None = Field(default=None, ge=0)  # link i as a capsule F_{i-1}-F_i (planning.cell)
    reading_coupling: dict[int, TomlFloat] = Field(default_factory=dict)  # {other joint (1-based): coefficient}
    mass_kg: TomlFloat | None = Field(default=None, ge=0)  # the link joint i moves (joint_model)
    com_mm: XYZ | None = None  # its centre of mass in DH frame {i}

    @field_validator("reading_sign")
    @classmethod
    def _sign(cls, value: int) -> int:
        if value not in (-1, 1):
            raise ValueError("must be +1 or -1")
        return value

    @model_validator(mode="after")
    def _consistent(self) -> JointEntry:
        """The rules between keys (every number is finite by its type)."""
        if self.hayati and self.d != 0.0:
            raise ValueError("a Hayati joint has d = 0 by definition")
        if not self.hayati and self.beta != 0.0:
            raise ValueError("beta must be 0 on a DH joint (set hayati = true to use beta)")
        if self.limits_deg[0] >= self.limits_deg[1]:
            raise ValueError("limits_deg must be [lower, upper] with lower < upper")
        if (self.mass_kg is None) != (self.com_mm is None):
            raise ValueError("mass_kg and com_mm go together (the link's mass and its centre of mass)")
        return self


def _coupling_matrix(spec: RobotFile, source: str) -> np.ndarray:
    """The ``(n, n)`` off-diagonal coupling of the robot file's ``reading_coupling`` keys (zeros: none)."""
    n = len(spec.joints)
    coupling = np.zeros((n, n))
    for row, joint in enumerate(spec.joints):
        for other, coefficient in joint.reading_coupling.items():
            where = f"{source}: key `joints[{row}].reading_coupling.{other}`"
            if not 1 <= other <= n:
                raise InputError(f"{where}: {other} is not a joint number 1..{n}")
            if other == row + 1:
                raise InputError(f"{where}: a joint is not coupled to itself (its own coefficient is `reading_sign`)")
            coupling[row, other - 1] = coefficient
    return coupling


class RobotFile(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str
    description: str = ""
    source: str = ""
    mass_source: str = ""
    #: x, y, z [mm], A, B, C [deg KUKA]
    flange_frame: tuple[TomlFloat, TomlFloat, TomlFloat, TomlFloat, TomlFloat, TomlFloat] | None = None
    joints: list[JointEntry] = Field(min_length=1)


def _masses(spec: RobotFile, source: str) -> LinkMasses | None:
    given = [j.mass_kg is not None for j in spec.joints]
    if not any(given):
        return None
    if not all(given):
        missing = ", ".join(f"J{k + 1}" for k, flag in enumerate(given) if not flag)
        raise InputError(f"{source}: `mass_kg` and `com_mm` are given for some joints but not for {missing}")
    return LinkMasses(
        mass_kg=np.array([j.mass_kg for j in spec.joints], dtype=float),
        com_mm=np.array([j.com_mm for j in spec.joints], dtype=float),
        source=spec.mass_source,
    )


def robot_from_dict(data: dict, source: str = "robot") -> RobotModel:
    """Build a :class:`RobotModel` from a parsed robot TOML (degrees -> radians)."""
    spec: RobotFile = validate_model(RobotFile, data, source)
    nominal = np.array([[j.d, np.deg2rad(j.theta), j.a, np.deg2rad(j.alpha), np.deg2rad(j.beta)] for j in spec.joints])
    return RobotModel(
        name=spec.name,
        nominal=nominal,
        hayati=np.array([j.hayati for j in spec.joints], dtype=bool),
        reading_sign=np.array([j.reading_sign for j in spec.joints], dtype=float),
        reading_offset=np.deg2rad([j.reading_offset_deg for j in spec.joints]),
        limits=np.deg2rad([j.limits_deg for j in spec.joints]),
        description=spec.description,
        reading_coupling=_coupling_matrix(spec, source),
        masses=_masses(spec, source),
        flange_frame=None if spec.flange_frame is None else _frame(spec.flange_frame),
    )


def _frame(values: Sequence[float]) -> np.ndarray:
    """A frame from ``x, y, z`` [mm] and KUKA ``A, B, C`` [deg] (``R = Rz(A) Ry(B) Rx(C)``)."""
    from robotcal.geometry.euler import matrix_from_kuka_abc

    frame = np.eye(4)
    frame[:3, :3] = matrix_from_kuka_abc(np.deg2rad(values[3:]))
    frame[:3, 3] = values[:3]
    return frame


def robot_to_dict(robot: RobotModel, *, source: str = "") -> dict:
    """The robot TOML content of ``robot`` (radians -> degrees); ``robot_from_dict`` inverts it."""
    nominal_deg = robot.nominal.copy()
    angles = list(ANGLE_COLUMNS)  # theta, alpha, beta; d and a stay mm
    nominal_deg[:, angles] = np.rad2deg(nominal_deg[:, angles])
    joints = []
    for index in range(robot.n_joints):
        d, theta, a, alpha, beta = (float(value) for value in nominal_deg[index])
        joints.append(
            {
                "d": d,
                "theta": theta,
                "a": a,
                "alpha": alpha,
                "beta": beta,
                "hayati": bool(robot.hayati[index]),
                "limits_deg": [float(v) for v in np.rad2deg(robot.limits[index])],
                "reading_sign": int(robot.reading_sign[index]),
                "reading_offset_deg": float(np.rad2deg(robot.reading_offset[index])),
            }
        )
        coupled = np.flatnonzero(robot.reading_coupling[index])
        if coupled.size:  # written only when present, so that uncoupled robots keep their exact layout
            joints[-1]["reading_coupling"] = {str(j + 1): float(robot.reading_coupling[index, j]) for j in coupled}
        if robot.masses is not None:
            joints[-1]["mass_kg"] = float(robot.masses.mass_kg[index])
            joints[-1]["com_mm"] = [float(v) for v in robot.masses.com_mm[index]]
    document: dict[str, Any] = {"name": robot.name, "description": robot.description, "source": source, "joints": joints}
    if robot.masses is not None:
        document["mass_source"] = robot.masses.source
    if robot.flange_frame is not None:
        from robotcal.geometry.euler import kuka_abc_from_matrix

        abc = np.rad2deg(kuka_abc_from_matrix(robot.flange_frame[:3, :3]))
        document["flange_frame"] = [float(v) for v in np.r_[robot.flange_frame[:3, 3], abc]]
    return document


def load_robot(name_or_path: str | os.PathLike[str], *, relative_to: Path | None = None) -> RobotModel:
    """A built-in robot by name, or a robot TOML file by path (relative paths from ``relative_to``)."""
    text = str(name_or_path)
    if text in builtin_names("robots"):
        path = data_path("robots", f"{text}.toml")
    else:
        path = Path(text)
        if not path.is_absolute() and relative_to is not None and (relative_to / path).exists():
            path = relative_to / path  # a scenario's relative robot path is relative to the scenario
        if not path.exists():
            raise InputError(
                f"unknown robot {text!r}: not a built-in robot ({', '.join(builtin_names('robots'))}) nor an existing file"
            )
    return robot_from_dict(read_toml(path), str(path))


def list_robots() -> list[RobotModel]:
    """Every built-in robot."""
    return [load_robot(name) for name in builtin_names("robots")]
