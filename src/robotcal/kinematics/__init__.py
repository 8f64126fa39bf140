"""Kinematics: hybrid DH / Hayati robot model, parameter sets, batched forward kinematics, Jacobians.

Parameters per joint ``d, theta, a, alpha, beta`` [mm, rad] (thesis Table 3.1); a DH joint is
``Rz(theta + q) Tz(d) Tx(a) Rx(alpha)``, a Hayati joint ``Rz(theta + q) Tx(a) Rx(alpha) Ry(beta)``
(eqs 3-72, 3-82).

Examples
--------
A planar two-link arm (links of 300 and 200 mm): at q = (90, -90) deg the flange is at (200, 300, 0):

>>> import numpy as np
>>> from robotcal.kinematics import RobotModel, forward_kinematics
>>> arm = RobotModel(name="planar-2r", nominal=[[0, 0, 300, 0, 0], [0, 0, 200, 0, 0]], hayati=[False, False])
>>> pose = forward_kinematics(arm.nominal, np.deg2rad([[90.0, -90.0]]))
>>> pose.shape
(1, 4, 4)
>>> np.round(pose[0, :3, 3], 9).tolist()
[200.0, 300.0, 0.0]
"""

from robotcal.kinematics.compensation import STATUSES, Compensation, CompensationSettings, compensate_commands
from robotcal.kinematics.forward import (
    check_joint_variables,
    forward_kinematics,
    joint_frames,
    link_transforms,
    target_positions,
)
from robotcal.kinematics.inverse import (
    BRANCH_NAMES,
    FAMILIES,
    InverseSolutions,
    Solved,
    arm_family,
    as_tool_frame,
    branch_of,
    check_targets,
    inverse_kinematics,
    nominal_solutions,
    robot_size,
    rotation_vector,
    solve_pose,
    tool_frames,
    within_limits,
    wrap_readings,
    wrist_centre_in_flange,
)
from robotcal.kinematics.jacobian import target_jacobian
from robotcal.kinematics.joint_model import (
    GRAVITY_MPS2,
    JOINT_MODEL_GROUPS,
    MAX_DEFLECTION_DEG,
    MAX_HARMONIC_ORDER,
    Deflection,
    JointModel,
    gravity_regressor,
    gravity_torques,
    largest_deflection,
    lash_turns,
    lumped_terms,
    motion_direction,
    parse_parameter_name,
)
from robotcal.kinematics.model import (
    ANGLE_COLUMNS,
    ANGLE_KINDS,
    DISPLAY_UNITS,
    KIND_UNITS,
    LENGTH_COLUMNS,
    LENGTH_KINDS,
    PARAMETER_KINDS,
    LinkMasses,
    ParameterSet,
    ReflectorMount,
    RobotModel,
    check_parameter_array,
)

__all__ = [
    "STATUSES",
    "Compensation",
    "CompensationSettings",
    "compensate_commands",
    "BRANCH_NAMES",
    "FAMILIES",
    "InverseSolutions",
    "Solved",
    "as_tool_frame",
    "within_limits",
    "wrap_readings",
    "wrist_centre_in_flange",
    "robot_size",
    "check_targets",
    "arm_family",
    "branch_of",
    "inverse_kinematics",
    "nominal_solutions",
    "rotation_vector",
    "solve_pose",
    "tool_frames",
    "link_transforms",
    "joint_frames",
    "forward_kinematics",
    "target_positions",
    "check_joint_variables",
    "target_jacobian",
    "GRAVITY_MPS2",
    "JOINT_MODEL_GROUPS",
    "MAX_DEFLECTION_DEG",
    "MAX_HARMONIC_ORDER",
    "Deflection",
    "JointModel",
    "gravity_regressor",
    "gravity_torques",
    "largest_deflection",
    "lumped_terms",
    "lash_turns",
    "motion_direction",
    "parse_parameter_name",
    "PARAMETER_KINDS",
    "LENGTH_KINDS",
    "ANGLE_KINDS",
    "LENGTH_COLUMNS",
    "ANGLE_COLUMNS",
    "KIND_UNITS",
    "DISPLAY_UNITS",
    "LinkMasses",
    "RobotModel",
    "ParameterSet",
    "ReflectorMount",
    "check_parameter_array",
]
