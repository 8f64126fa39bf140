"""I/O at the edge: TOML robots and scenarios, capture CSV, parameter JSON, result files, atomic writes.

Files hold millimetres and degrees (micrometres where a name says ``_um``); the objects read hold the
core's mm and radians.

The names below load on first use (SPEC 1, ``lazy_loader``, as the ``robotcal`` package does):
``__init__.pyi`` lists each with the module that defines it, so ``import robotcal.io`` imports neither
numpy nor any of its modules, and a command's ``--help`` that names one of them stays fast.
``joints_files`` is not among them: it is also the name of its module, which the import system binds
on the package (import it from :mod:`robotcal.io.results.joints_files`).

Examples
--------
A capture written to CSV (readings in degrees, 12 decimals) reads back the same:

>>> import os, tempfile
>>> import numpy as np
>>> import robotcal
>>> from robotcal.io import read_capture, write_capture
>>> capture = robotcal.simulate(robotcal.load_scenario("thesis-laser-tracker"), rng=5)
>>> with tempfile.TemporaryDirectory() as folder:
...     path = write_capture(os.path.join(folder, "capture.csv"), capture)
...     back = read_capture(path, n_joints=6)
>>> back.n_points == capture.n_points, bool(np.array_equal(back.circle, capture.circle))
(True, True)
>>> bool(np.allclose(back.readings, capture.readings, rtol=0, atol=1e-12))  # rad, from 12-decimal degrees
True
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
