"""Uncertainty: GUM Supplement 1 Monte Carlo of the calibration, its linearised comparison, and the
propagation of parameter draws to the TCP (thesis ch. 5.2.3 and 5.3).

Names load on first use (PEP 562): ``import robotcal.uncertainty.tcp`` does not import the Monte
Carlo engine. Scenario-level wrappers: :func:`robotcal.monte_carlo`, :func:`robotcal.tcp_uncertainty`.

Examples
--------
Draws of a planar two-link arm (links 300 and 200 mm) whose J1 offset theta_1 has a standard
uncertainty of 1e-4 rad: stretched along X, the TCP moves along Y by 500 mm times that angle, so
u(Y) = 0.05 mm, and u(X) is of second order:

>>> import numpy as np
>>> from robotcal.kinematics import RobotModel
>>> from robotcal.uncertainty import propagate_to_tcp
>>> arm = RobotModel(name="planar-2r", nominal=[[0, 0, 300, 0, 0], [0, 0, 200, 0, 0]], hayati=[False, False])
>>> rng = np.random.default_rng(1)
>>> draws = np.repeat(arm.nominal[None], 20_000, axis=0)
>>> draws[:, 0, 1] += rng.normal(0.0, 1e-4, size=20_000)   # J1.theta [rad]
>>> tcp = propagate_to_tcp(arm, draws, [[0.0, 0.0]])
>>> u_x, u_y = tcp.std_uncertainty[0, :2]
>>> bool(abs(u_y / 0.05 - 1) < 0.03), bool(u_x < 1e-5)   # 3 % > 5 Monte Carlo standard errors of u
(True, True)
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
