"""Joint error diagnostics (thesis ch. 4.6): backlash, axial/radial eccentricity, harmonic models, and the
ISO 9283 pose characteristics.

Examples
--------
A radial eccentricity of 0.02 mm that turns once per revolution is a first harmonic; the series
fitted to it over a 300 deg circle gives its amplitude back:

>>> import numpy as np
>>> from robotcal.diagnostics import fit_harmonic_series
>>> theta = np.deg2rad(np.linspace(0.0, 300.0, 30))
>>> radial = 0.02 * np.cos(theta - 0.5)
>>> fit = fit_harmonic_series(theta, radial, order=2)
>>> c0, a1, b1 = fit.coefficients[:3]
>>> round(float(np.hypot(a1, b1)), 9), bool(abs(c0) < 1e-12)
(0.02, True)
"""

from robotcal.diagnostics import harmonics, iso9283, joints
from robotcal.diagnostics.harmonics import *
from robotcal.diagnostics.iso9283 import *
from robotcal.diagnostics.joints import *

# every public name of the modules, each listed once, in its module's __all__
__all__ = [*harmonics.__all__, *iso9283.__all__, *joints.__all__]
