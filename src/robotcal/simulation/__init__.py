"""Simulation: capture plans and the synthetic Circle Point generator (thesis ch. 5.2.1), validation poses,
perturbed "true" robots.

Examples
--------
A noise-free capture of a planar two-link arm: circle 1 turns J1 with its target 100 mm from the J1
axis, so its points lie 100 mm from the base origin:

>>> import numpy as np
>>> from robotcal.instruments import Instrument
>>> from robotcal.kinematics import ReflectorMount, RobotModel
>>> from robotcal.simulation import CapturePlan, simulate_capture
>>> arm = RobotModel(name="planar-2r", nominal=[[0, 0, 300, 0, 0], [0, 0, 200, 0, 0]], hayati=[False, False])
>>> plan = CapturePlan(start=[0.0, 0.0], sweep=np.deg2rad([90.0, 60.0]), points=[5, 4],
...                    reflector=ReflectorMount(frame="joint", positions=[[100, 0, 0], [50, 0, 0]]))
>>> capture, exact = simulate_capture(arm, plan, Instrument(a_mm=0.0, b_mm_per_m=0.0), np.eye(4), rng=1)
>>> capture.n_points, capture.circle.tolist()
(9, [1, 1, 1, 1, 1, 2, 2, 2, 2])
>>> np.round(np.linalg.norm(capture.points[capture.circle == 1], axis=1), 9).tolist()
[100.0, 100.0, 100.0, 100.0, 100.0]
"""

from robotcal.simulation import generator, perturb, plan, poses, probe, sessions
from robotcal.simulation.generator import *
from robotcal.simulation.perturb import *
from robotcal.simulation.plan import *
from robotcal.simulation.poses import *
from robotcal.simulation.probe import *
from robotcal.simulation.sessions import *

# every public name of the modules, each listed once, in its module's __all__
__all__ = [*generator.__all__, *perturb.__all__, *plan.__all__, *poses.__all__, *probe.__all__, *sessions.__all__]
