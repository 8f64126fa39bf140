"""The calibration pipeline as a library: plan a run, run it (docs/pipeline.md); a run folder is read back by
:func:`robotcal.io.results.run_folder.read_run`.

>>> from robotcal.pipeline import plan_run, run_calibration                    # doctest: +SKIP
>>> plan = plan_run("kr5-demo", "out", draws=2000, workspace=50)              # doctest: +SKIP
>>> result = run_calibration(plan)                                             # doctest: +SKIP
>>> result.summary.console_lines()                                             # doctest: +SKIP
"""

from robotcal.pipeline.plan import RunPlan, plan_run
from robotcal.pipeline.run import run_calibration

__all__ = ["RunPlan", "plan_run", "run_calibration"]
