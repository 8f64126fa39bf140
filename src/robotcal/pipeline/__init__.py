"""The calibration pipeline as a library: plan a run, run it, write and read its folder (docs/pipeline.md).

>>> from robotcal.pipeline import plan_run, run_calibration, read_run  # doctest: +SKIP
>>> plan = plan_run("kr5-demo", "out", draws=2000, workspace=50)      # doctest: +SKIP
>>> result = run_calibration(plan)                                     # doctest: +SKIP
>>> result.summary.console_lines()                                     # doctest: +SKIP

Names are imported lazily (PEP 562): ``import robotcal.pipeline`` imports neither numpy's heavy users nor
matplotlib until a name is used.
"""

from __future__ import annotations

import importlib

__all__ = [
    "STAGES",
    "Document",
    "RunPlan",
    "RunResult",
    "Table",
    "plan_run",
    "read_run",
    "run_calibration",
]

_HOMES = {
    "STAGES": "robotcal.pipeline.plan",
    "RunPlan": "robotcal.pipeline.plan",
    "plan_run": "robotcal.pipeline.plan",
    "run_calibration": "robotcal.pipeline.run",
    "read_run": "robotcal.pipeline.folder",
    "Document": "robotcal.pipeline.result",
    "RunResult": "robotcal.pipeline.result",
    "Table": "robotcal.pipeline.result",
}


def __getattr__(name: str):
    if name in _HOMES:
        value = getattr(importlib.import_module(_HOMES[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'robotcal.pipeline' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
