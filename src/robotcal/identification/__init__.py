"""Identification: Circle Point Analysis (:mod:`.cpa`), least-squares refinement (:mod:`.refine`, with its
problem and rank test in private modules, records :mod:`.records` and settings :mod:`.settings`), the
model choice (:mod:`.model_choice`), evaluation on validation captures (:mod:`.evaluation`), observability,
capture plausibility, targets, fit health.

The names below load on first use (``lazy_loader``, as :mod:`robotcal.io` does): ``__init__.pyi`` lists each
with the module that defines it, so ``import robotcal.identification`` imports none of its modules (the
refinement pulls ``scipy.optimize``). Scenario-level wrappers: :func:`robotcal.identify`, :func:`robotcal.refine`,
:func:`robotcal.evaluate`.

Examples
--------
CPA of a noise-free simulated capture returns the parameters it was simulated with:

>>> import numpy as np
>>> import robotcal
>>> from robotcal.identification import identify_cpa
>>> scenario = robotcal.load_scenario("thesis-noise-free")
>>> capture = robotcal.simulate(scenario, rng=0)
>>> result = identify_cpa(capture, scenario.robot, scenario.plan.reflector,
...                       tracker_from_base=scenario.tracker_from_base, options=scenario.identification)
>>> result.pair_cases[:2]
('skew', 'nearly-parallel')
>>> error = result.parameters.difference(robotcal.ParameterSet.nominal(scenario.robot))  # mm, rad
>>> bool(np.abs(error).max() < 1e-9)
True
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
