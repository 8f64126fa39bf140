"""Kinematics: hybrid DH / Hayati robot model, parameter sets, batched forward kinematics."""

from robotcal.kinematics.forward import (
    check_joint_variables,
    forward_kinematics,
    joint_frames,
    link_transforms,
    target_positions,
)
from robotcal.kinematics.model import (
    LENGTH_KINDS,
    PARAMETER_KINDS,
    ParameterSet,
    ReflectorMount,
    RobotModel,
    check_parameter_array,
)

__all__ = [
    "check_joint_variables",
    "forward_kinematics",
    "joint_frames",
    "link_transforms",
    "target_positions",
    "LENGTH_KINDS",
    "PARAMETER_KINDS",
    "ParameterSet",
    "ReflectorMount",
    "RobotModel",
    "check_parameter_array",
]
