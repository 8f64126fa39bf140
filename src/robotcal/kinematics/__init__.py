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

from robotcal.kinematics import compensation, forward, inverse, jacobian, joint_model, model
from robotcal.kinematics.compensation import *
from robotcal.kinematics.forward import *
from robotcal.kinematics.inverse import *
from robotcal.kinematics.jacobian import *
from robotcal.kinematics.joint_model import *
from robotcal.kinematics.model import *

# every public name of the modules, each listed once, in its module's __all__
__all__ = [
    *compensation.__all__,
    *forward.__all__,
    *inverse.__all__,
    *jacobian.__all__,
    *joint_model.__all__,
    *model.__all__,
]
