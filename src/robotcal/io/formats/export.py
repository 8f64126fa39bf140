"""Calibrated model out: URDF, Universal Robots calibration YAML, DH and MDH tables (docs/export.md).

Every format is an exact re-expression of the hybrid DH / Hayati chain of eq. 3-84 (thesis of
reference, sec. 3.4), not an approximation:

``A_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)``  (eqs 3-72, 3-82)

Because ``Rz(q_i)`` commutes with ``Rz(theta_i) Tz(d_i)``, ``A_i = P_i Rz(q_i) S_i`` with
``P_i = Rz(theta_i) Tz(d_i)`` and ``S_i = Tx(a_i) Rx(alpha_i) Ry(beta_i)``, so the chain is

``base_from_flange = P_1 Rz(q_1) (S_1 P_2) Rz(q_2) ... (S_{n-1} P_n) Rz(q_n) S_n``.

A URDF joint ``i`` therefore has origin ``S_{i-1} P_i`` (``S_0 = I``) and rotates about its own z
axis; a fixed joint carries ``S_n`` to the flange. With ``joint_variable="reading"`` (the default)
the reading map ``q_i = s_i r_i + o_i`` is folded in: origin ``S_{i-1} P_i Rz(o_i)`` and axis
``(0, 0, s_i)``, so the URDF joint value is the controller reading ``r_i``. This is also exactly the
layout of the UR drivers' calibration file (``kinematics: {shoulder: {x, y, z, roll, pitch, yaw},
...}``, the ``ur_calibration`` output read by ``ur_description``). Lengths are written in metres in
URDF / UR YAML, in mm in the DH / MDH tables; rpy are URDF's fixed-axis roll-pitch-yaw
``R = Rz(yaw) Ry(pitch) Rx(roll)``.
"""

from __future__ import annotations

import io
import math
from xml.sax.saxutils import quoteattr

import numpy as np

from robotcal.errors import InputError
from robotcal.geometry.euler import kuka_abc_from_matrix
from robotcal.geometry.transforms import rot_x, rot_y, rot_z, translation
from robotcal.io.results.output import SIGNATURE  # the first comment by which robotcal recognises its own files
from robotcal.kinematics.model import ParameterSet

__all__ = [
    "joint_model_note",
    "with_note",
    "BETA_ALTERNATIVES",
    "EXPORT_FORMATS",
    "UR_JOINT_NAMES",
    "coupled_joints",
    "joint_origins",
    "model_variable_limits",
    "require_uncoupled",
    "rpy_from_matrix",
    "parameters_to_urdf",
    "parameters_to_ur_yaml",
    "dh_table",
    "mdh_table",
    "table_to_csv",
    "table_to_markdown",
]

#: Formats of ``robotcal export``.
EXPORT_FORMATS = ("json", "urdf", "ur-yaml", "dh", "mdh")
#: Joint names of the UR calibration file, J1..J6.
UR_JOINT_NAMES = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
_EXACT = 1e-12  # a value is "zero" for a convention check below this [mm, rad]
#: How every refusal of an export points to the exact forms that hold what it cannot (:func:`_instead`).
_EXACT_INSTEAD = "exact equivalent that holds it"
#: Where a Hayati beta (nearly parallel axes, thesis ch. 3.4.5) rules out a DH table: the exact forms that hold it.
BETA_ALTERNATIVES = (
    "exact equivalents that hold it: --format urdf (each joint's origin as x, y, z, roll, pitch, yaw: ROS, MoveIt, "
    "Gazebo and most simulators read it), --format ur-yaml for a UR-type arm (its controller's calibration file), or "
    "--format json (the hybrid DH / Hayati model itself); `robotcal compensate` and `robotcal filter` carry the whole "
    "model to a controller that only knows its nominal DH"
)


def _instead(option: str, what: str) -> str:
    """The pointer a refusal ends with, worded as :data:`BETA_ALTERNATIVES`: ``exact equivalent that holds it:
    OPTION (what it writes)``."""
    return f"{_EXACT_INSTEAD}: {option} ({what})"


#: What the model-variable export writes, for the pointers of a coupled robot's refusals.
_MODEL_VARIABLES = "the model variables as the joint values; convert readings with the robot's reading map"


def _float(value: float) -> str:
    """Shortest text that reads back as the same float (round-trip exact)."""
    value = float(value)
    return "0" if value == 0.0 else repr(value)


def rpy_from_matrix(matrix) -> np.ndarray:
    """URDF ``roll, pitch, yaw`` [rad] of ``(..., 3, 3)`` / ``(..., 4, 4)``: ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    The same factorisation as KUKA's A, B, C (A = yaw, B = pitch, C = roll), see
    :func:`robotcal.geometry.euler.kuka_abc_from_matrix`.
    """
    return kuka_abc_from_matrix(matrix)[..., ::-1]


def _pre(values) -> np.ndarray:
    d, theta = values[0], values[1]
    return rot_z(theta) @ translation([0.0, 0.0, d])


def _post(values) -> np.ndarray:
    a, alpha, beta = values[2], values[3], values[4]
    return translation([a, 0.0, 0.0]) @ rot_x(alpha) @ rot_y(beta)


def joint_origins(
    parameters: ParameterSet, *, joint_variable: str = "reading"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint origins of the chain re-expressed with every joint turning about its own z axis.

    Parameters
    ----------
    parameters : ParameterSet
    joint_variable : {"reading", "model"}
        ``"reading"``: the exported joint value is the controller reading ``r`` (origin
        ``S_{i-1} P_i Rz(o_i)``, axis ``(0, 0, s_i)``); ``"model"``: it is the model variable ``q``
        (origin ``S_{i-1} P_i``, axis ``(0, 0, 1)``). See the module docstring.

    Returns
    -------
    origins : ndarray, shape (n_joints, 4, 4)
        ``link_{i-1}_from_joint_i`` frames [mm] (link 0 = base = DH frame {0}).
    axis_sign : ndarray, shape (n_joints,)
        +1 or -1: joint i turns about ``(0, 0, axis_sign_i)`` of its origin frame.
    flange : ndarray, shape (4, 4)
        ``link_n_from_flange = S_n`` [mm]; the flange is DH frame {n}.
    """
    _check_joint_variable(joint_variable)
    robot = parameters.robot
    if joint_variable == "reading":
        require_uncoupled(robot, "a URDF or UR YAML joint whose value is the controller reading")
    values = parameters.values
    n = robot.n_joints
    origins = np.empty((n, 4, 4))
    previous = np.eye(4)
    for i in range(n):
        origin = previous @ _pre(values[i])
        if joint_variable == "reading":
            origin = origin @ rot_z(robot.reading_offset[i])
        origins[i] = origin
        previous = _post(values[i])
    sign = robot.reading_sign.copy() if joint_variable == "reading" else np.ones(n)
    return origins, sign, previous


def coupled_joints(robot) -> list[str]:
    """Joints ``Jk`` whose controller reading depends on another joint's model variable (``reading_coupling``)."""
    if not robot.is_coupled:
        return []
    return [f"J{k + 1}" for k in np.flatnonzero(np.any(robot.reading_coupling != 0.0, axis=1))]


def require_uncoupled(robot, what: str) -> None:
    """InputError naming the coupled joints: ``what`` turns each joint by its own reading alone."""
    joints = coupled_joints(robot)
    if joints:
        raise InputError(
            f"robot {robot.name!r}: the readings of {', '.join(joints)} are coupled to other joints "
            f"(`reading_coupling`), which {what} cannot express; {_instead('--joint-variable model', _MODEL_VARIABLES)}"
        )


def model_variable_limits(robot) -> np.ndarray:
    """``(n, 2)`` limits of the model variables ``q = M^-1 r + o`` [rad] implied by the reading limits.

    A box only where ``q_i`` follows one reading alone (row ``i`` of ``M^-1`` has one non-zero entry);
    elsewhere ``(-inf, inf)``: the controller's limits bound a combination of joints, which a per-joint
    limit cannot hold (the URDF joint becomes ``continuous``).
    """
    inverse = np.linalg.inv(robot.reading_matrix)
    limits = np.full((robot.n_joints, 2), [-np.inf, np.inf])
    for i, row in enumerate(inverse):
        used = np.flatnonzero(np.abs(row) > 1e-12)
        if used.size == 1:
            j = int(used[0])
            limits[i] = np.sort(row[j] * robot.limits[j] + robot.reading_offset[i])
    return limits


def _origin_xml(matrix, indent: str) -> str:
    xyz = " ".join(_float(v / 1000.0) for v in matrix[:3, 3])
    rpy = " ".join(_float(v) for v in rpy_from_matrix(matrix[:3, :3]))
    return f'{indent}<origin xyz="{xyz}" rpy="{rpy}"/>\n'


def parameters_to_urdf(
    parameters: ParameterSet,
    *,
    tool=None,
    name: str | None = None,
    joint_variable: str = "reading",
    prefix: str = "",
) -> str:
    """URDF text of the calibrated chain: links ``base_link, link_1..link_n, flange[, tool0]``.

    Parameters
    ----------
    parameters : ParameterSet
    tool : array_like, shape (3,), optional
        Tool point in the flange frame [mm]; adds a fixed joint ``flange -> tool0`` (same orientation).
    name : str, optional
        Robot name (default: the robot model's name).
    joint_variable : {"reading", "model"}
        What the URDF joint value is (see :func:`joint_origins`).
    prefix : str
        Prefix of every link and joint name.

    Returns
    -------
    str
        URDF XML. Lengths in metres, angles in radians; joints ``joint_1..joint_n`` are
        ``revolute`` with the robot's software limits, or ``continuous`` where unlimited.
    """
    robot = parameters.robot
    origins, sign, flange = joint_origins(parameters, joint_variable=joint_variable)
    limits = robot.limits
    if joint_variable == "model":  # limits of q = M^-1 r + o (q = s r + o without coupling)
        limits = model_variable_limits(robot)
    out = io.StringIO()
    out.write('<?xml version="1.0"?>\n')
    out.write(f"<!-- {SIGNATURE}: calibrated model of {robot.name}; joint value = controller ")
    out.write(f"{'reading' if joint_variable == 'reading' else 'model variable q'} [rad]; lengths in m -->\n")
    out.write(f"<robot name={quoteattr(name or robot.name)}>\n")
    links = [f"{prefix}base_link"] + [f"{prefix}link_{i + 1}" for i in range(robot.n_joints)] + [f"{prefix}flange"]
    if tool is not None:
        links.append(f"{prefix}tool0")
    for link in links:
        out.write(f"  <link name={quoteattr(link)}/>\n")
    for i in range(robot.n_joints):
        lower, upper = limits[i]
        kind = "revolute" if np.isfinite(lower) and np.isfinite(upper) else "continuous"
        out.write(f'  <joint name="{prefix}joint_{i + 1}" type="{kind}">\n')
        out.write(f'    <parent link="{links[i]}"/>\n    <child link="{links[i + 1]}"/>\n')
        out.write(_origin_xml(origins[i], "    "))
        out.write(f'    <axis xyz="0 0 {_float(sign[i])}"/>\n')
        if kind == "revolute":
            out.write(f'    <limit lower="{_float(lower)}" upper="{_float(upper)}" effort="0" velocity="0"/>\n')
        out.write("  </joint>\n")
    n = robot.n_joints
    out.write(f'  <joint name="{prefix}flange_joint" type="fixed">\n')
    out.write(f'    <parent link="{links[n]}"/>\n    <child link="{links[n + 1]}"/>\n')
    out.write(_origin_xml(flange, "    "))
    out.write("  </joint>\n")
    if tool is not None:
        tool = _check_tool(tool)
        out.write(f'  <joint name="{prefix}tool0_joint" type="fixed">\n')
        out.write(f'    <parent link="{links[n + 1]}"/>\n    <child link="{links[n + 2]}"/>\n')
        out.write(_origin_xml(translation(tool), "    "))
        out.write("  </joint>\n")
    out.write("</robot>\n")
    return out.getvalue()


def _check_tool(tool) -> np.ndarray:
    try:
        tool = np.asarray(tool, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError("`tool` must be three numbers x,y,z [mm]") from exc
    if tool.shape != (3,) or not np.all(np.isfinite(tool)):
        raise InputError(f"`tool` must be three finite numbers x,y,z [mm]; got shape {tool.shape}")
    return tool


def parameters_to_ur_yaml(parameters: ParameterSet) -> str:
    """The UR drivers' calibration YAML (``kinematics: {shoulder: {x, y, z, roll, pitch, yaw}, ...}``).

    Entry ``i`` is ``link_{i-1}_from_joint_i`` of :func:`joint_origins` with the joint value = the
    controller reading, lengths in metres, rpy in radians (the ``ur_calibration`` output layout,
    whose ``wrist_3`` link frame is the flange). Exact only where the format can hold the model,
    else :class:`InputError` naming the joint: six joints; every reading sign +1 (UR axes are +z);
    J6's ``a``, ``alpha`` and ``beta`` zero (the format has no flange offset after ``wrist_3``).
    """
    robot = parameters.robot
    joints = coupled_joints(robot)
    if joints:
        raise InputError(
            f"robot {robot.name!r}: the readings of {', '.join(joints)} are coupled to other joints "
            "(`reading_coupling`); the UR calibration YAML turns each joint by its own reading and cannot hold a "
            f"coupled robot; {_instead('--format urdf --joint-variable model', _MODEL_VARIABLES)}"
        )
    if robot.n_joints != 6:
        raise InputError(f"the UR calibration YAML needs 6 joints; robot {robot.name!r} has {robot.n_joints}")
    bad = [f"J{i + 1}" for i in np.flatnonzero(robot.reading_sign < 0)]
    if bad:
        raise InputError(
            f"the UR calibration YAML turns every joint about +z; {', '.join(bad)} of robot {robot.name!r} "
            f"{'has' if len(bad) == 1 else 'have'} reading_sign = -1; "
            f"{_instead('--format urdf', 'each joint turning about its own axis, -z included')}"
        )
    tail = parameters.values[5, 2:]
    if np.any(np.abs(tail) > _EXACT):
        names = [f"J6.{k}" for k, v in zip(("a", "alpha", "beta"), tail, strict=True) if abs(v) > _EXACT]
        raise InputError(
            f"the UR calibration YAML has no flange offset after wrist_3; {', '.join(names)} != 0; "
            f"{_instead('--format urdf', 'the flange offset as its fixed flange joint')}"
        )
    origins, _, _ = joint_origins(parameters, joint_variable="reading")
    lines = [
        f"# {SIGNATURE}: calibrated model of {robot.name}; lengths in m, angles in rad",
        "kinematics:",
    ]
    for joint, origin in zip(UR_JOINT_NAMES, origins, strict=True):
        roll, pitch, yaw = rpy_from_matrix(origin[:3, :3])
        x, y, z = origin[:3, 3] / 1000.0
        lines.append(f"  {joint}:")
        for key, value in zip(("x", "y", "z", "roll", "pitch", "yaw"), (x, y, z, roll, pitch, yaw), strict=True):
            lines.append(f"    {key}: {_float(value)}")
    return "\n".join(lines) + "\n"


def _check_joint_variable(joint_variable: str) -> None:
    if joint_variable not in ("reading", "model"):
        raise InputError(f"`joint_variable` must be 'reading' or 'model'; got {joint_variable!r}")


def _dh_values(parameters: ParameterSet, joint_variable: str, convention: str) -> np.ndarray:
    """``parameters.values``, checked for a DH table: ``joint_variable`` known, every beta 0 (else InputError
    naming the joints: ``convention`` cannot express a rotation about y)."""
    _check_joint_variable(joint_variable)
    values = parameters.values
    bad = [
        f"J{i + 1}.beta = {math.degrees(values[i, 4]):.6g} deg" for i in np.flatnonzero(np.abs(values[:, 4]) > _EXACT)
    ]
    if bad:
        raise InputError(f"{convention} cannot express a rotation about y: {', '.join(bad)}; {BETA_ALTERNATIVES}")
    return values


def _reading_columns(parameters: ParameterSet, i: int, joint_variable: str) -> dict:
    """``reading_sign``, ``reading_offset_deg`` of row ``i``: the robot's (``q = s r + o``), or 1 and 0 where the
    table's joint value is the model variable q itself (``joint_variable = "model"``, any coupling)."""
    if joint_variable == "model":
        return {"reading_sign": 1, "reading_offset_deg": 0.0}
    robot = parameters.robot
    require_uncoupled(robot, "the table's `reading_sign`/`reading_offset_deg` columns")
    return {
        "reading_sign": int(robot.reading_sign[i]),
        "reading_offset_deg": math.degrees(robot.reading_offset[i]),
    }


def dh_table(parameters: ParameterSet, *, joint_variable: str = "reading") -> list[dict]:
    """Standard DH rows ``A_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` (eq. 3-72) [mm, deg].

    Exact: a Hayati joint is a DH joint with d = 0 when its beta is 0; a non-zero beta cannot be
    written and raises :class:`InputError` naming the joint. ``q`` is the model variable,
    ``q = reading_sign * reading + reading_offset`` (columns of every row). ``joint_variable =
    "model"``: the joint value is q itself (``reading_sign`` 1, ``reading_offset_deg`` 0 in every row), the
    only exact table of a coupled robot (convert readings with the robot's reading map).
    """
    values = _dh_values(parameters, joint_variable, "standard DH")
    rows = []
    for i in range(parameters.robot.n_joints):
        d, theta, a, alpha, _ = values[i]
        row = {"joint": f"J{i + 1}", "theta_deg": math.degrees(theta), "d_mm": d, "a_mm": a}
        row["alpha_deg"] = math.degrees(alpha)
        row.update(_reading_columns(parameters, i, joint_variable))
        rows.append(row)
    return rows


def mdh_table(parameters: ParameterSet, *, joint_variable: str = "reading") -> list[dict]:
    """Modified (Craig) DH rows ``T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i + q_i) Tz(d_i)`` [mm, deg].

    The model's chain regroups exactly (``Tx(a) Rx(alpha) = Rx(alpha) Tx(a)``): row i takes
    ``alpha_{i-1}, a_{i-1}`` from joint i-1 (0 for J1) and ``theta_i, d_i`` from joint i; a last
    fixed row ``flange`` (no joint variable) carries ``alpha_n, a_n``. A non-zero beta raises
    :class:`InputError` naming the joint. ``joint_variable``: as :func:`dh_table`.
    """
    values = _dh_values(parameters, joint_variable, "modified DH")
    rows = []
    previous_a, previous_alpha = 0.0, 0.0
    for i in range(parameters.robot.n_joints):
        d, theta, a, alpha, _ = values[i]
        row = {"joint": f"J{i + 1}", "alpha_prev_deg": math.degrees(previous_alpha), "a_prev_mm": previous_a}
        row.update({"theta_deg": math.degrees(theta), "d_mm": d})
        row.update(_reading_columns(parameters, i, joint_variable))
        rows.append(row)
        previous_a, previous_alpha = a, alpha
    rows.append(
        {
            "joint": "flange",
            "alpha_prev_deg": math.degrees(previous_alpha),
            "a_prev_mm": previous_a,
            "theta_deg": 0.0,
            "d_mm": 0.0,
            "reading_sign": 0,
            "reading_offset_deg": 0.0,
        }
    )
    return rows


def joint_model_note(parameters: ParameterSet) -> str | None:
    """What a geometric-only export leaves out of an extended model (issue 22), or None for a geometric one."""
    model = parameters.joint_model
    if model is None or model.is_empty:
        return None
    return (
        f"the calibrated model also has a joint model ({', '.join(sorted(set(model.groups)))}: {', '.join(model.names)}) "
        "that this format cannot carry: only its geometric part is written here. `robotcal compensate` applies the "
        "whole model (joint commands that reach the taught poses); `robotcal predict` evaluates it"
    )


def with_note(text: str, note: str, format: str) -> str:
    """``text`` of an export format with ``note`` added as a comment after its first line (URDF, UR YAML: after
    the signature comment; Markdown: after the title) or, for a CSV table, as a first comment line that carries
    :data:`SIGNATURE` (so that the file is still recognised as robotcal's)."""
    head, _, rest = text.partition("\n")
    if format == "urdf":
        return f"{head}\n<!-- {note.replace('--', '-')} -->\n{rest}"
    if format == "ur-yaml":
        return f"{head}\n# {note}\n{rest}"
    if format == "markdown":
        return f"{head}\n\n> Note: {note}.\n{rest}"
    return f"# {SIGNATURE}: {note}\n{text}"


def table_to_csv(rows: list[dict]) -> str:
    """CSV text of DH / MDH rows (numbers written round-trip exact)."""
    columns = list(rows[0])
    lines = [",".join(columns)]
    for row in rows:
        lines.append(",".join(str(row[c]) if isinstance(row[c], str | int) else _float(row[c]) for c in columns))
    return "\n".join(lines) + "\n"


def table_to_markdown(rows: list[dict], *, title: str = "") -> str:
    """Markdown table of DH / MDH rows (numbers with 9 decimals)."""
    columns = list(rows[0])
    lines = [f"# {title}", ""] if title else []
    lines.append("| " + " | ".join(columns) + " |")
    lines.append("|" + "---|" * len(columns))
    for row in rows:
        cells = [str(row[c]) if isinstance(row[c], str | int) else f"{row[c]:.9f}" for c in columns]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
