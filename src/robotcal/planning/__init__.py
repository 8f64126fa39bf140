"""Capture planning (thesis 4.5.2, 5.2.4, 6.2): cell check, robot programs, sensitivity, optimisation.

Names load on first use (PEP 562); :mod:`.scenario` is the glue that reads scenario and robot files
for the cell. Scenario-level wrappers: :func:`robotcal.check_plan`, :func:`robotcal.change_plan`.

Examples
--------
The process capability index of eq. 5-5, ``Cpk = min(USL - mean, mean - LSL) / (3 u)``:

>>> from robotcal.planning import process_capability
>>> round(float(process_capability(0.01, 0.02, -0.1, 0.1)), 12)
1.5
"""

from robotcal.planning import cell, files, optimise, program, scenario, sensitivity
from robotcal.planning.cell import *
from robotcal.planning.files import *
from robotcal.planning.optimise import *
from robotcal.planning.program import *
from robotcal.planning.scenario import *
from robotcal.planning.sensitivity import *

# every public name of the modules, each listed once, in its module's __all__
__all__ = [*cell.__all__, *files.__all__, *optimise.__all__, *program.__all__, *scenario.__all__, *sensitivity.__all__]
