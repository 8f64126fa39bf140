"""Geometry: batched fits, Plücker lines, line-pair analysis, rigid transforms, registration, KUKA A, B, C.

Everything in mm and radians; batched over leading axes, last axis the coordinates.

Examples
--------
A circle fitted to points of a known circle gives its centre, radius and axis back:

>>> import numpy as np
>>> from robotcal.geometry import fit_circle_3d
>>> angle = np.linspace(0.0, 1.5, 12)
>>> points = np.stack([10 + 50 * np.cos(angle), -5 + 50 * np.sin(angle), np.full(12, 3.0)], axis=-1)
>>> fit = fit_circle_3d(points)
>>> np.round(fit.centre, 9).tolist(), round(float(fit.radius), 9), np.round(np.abs(fit.normal), 9).tolist()
([10.0, -5.0, 3.0], 50.0, [0.0, 0.0, 1.0])
"""

from robotcal.geometry import euler, fits, lines, registration, rotations, transforms
from robotcal.geometry.euler import *
from robotcal.geometry.fits import *
from robotcal.geometry.lines import *
from robotcal.geometry.registration import *
from robotcal.geometry.rotations import *
from robotcal.geometry.transforms import *

# every public name of the modules, each listed once, in its module's __all__
__all__ = [*euler.__all__, *fits.__all__, *lines.__all__, *registration.__all__, *rotations.__all__, *transforms.__all__]
