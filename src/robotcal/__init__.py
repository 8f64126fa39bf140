"""robotcal: kinematic calibration of serial robots by Circle Point Analysis, with GUM-S1 uncertainty.

The names below are the front door for Python users (docs/api.md); ``__init__.pyi`` lists them with the
module that defines each, for type checkers and IDEs, and they load on first use from that list
(SPEC 1, ``lazy_loader``): ``import robotcal`` imports neither numpy nor anything else until a name is
used, so the command line and scripts that need one corner of the package start fast.

Units, one rule (docs/api.md): a number or array given to these functions is in millimetres and degrees, and
its name says so (``poses_deg``, ``tool_mm``); a value object (RobotModel, ParameterSet, Capture, CapturePlan,
ReflectorMount, the results) holds the core's units, mm and radians, whichever function takes or returns it.
``rng=`` accepts None, an int seed or a ``numpy.random.Generator``.

==========================  =====================================================================
robots, captures, files     :func:`load_robot`, :func:`read_capture`, :func:`write_capture`,
                            :func:`read_parameters`, :func:`write_parameters`, :func:`load_scenario`
one step at a time          :func:`perturb`, :func:`simulate`, :func:`simulate_poses`,
                            :func:`identify`, :func:`refine`, :func:`evaluate`, :func:`diagnose_joints`
uncertainty                 :func:`monte_carlo`, :func:`tcp_uncertainty`, :func:`workspace_uncertainty`,
                            :func:`validation_consistency`, :func:`measured_monte_carlo`, :func:`coverage_study`
planning                    :func:`check_plan`, :func:`change_plan`, :func:`optimise_plan`,
                            :func:`plan_tcp_p95`, :func:`sensitivity`
the calibrated model        :func:`compensate`, :func:`filter_program`, :func:`predict`, :func:`export_model`,
                            :func:`iso9283`, :func:`import_capture`
the whole calibration run   :func:`plan_run`, :func:`run_calibration`, :func:`read_run`,
                            :func:`render_report`, :class:`RunResult`
values                      :class:`RobotModel`, :class:`ParameterSet`, :class:`Capture`, :class:`Target`,
                            :class:`ReflectorMount`, :class:`Instrument`, :class:`CapturePlan`,
                            :class:`CPAOptions`, :class:`Scenario`
errors                      :class:`RobotcalError`, :class:`InputError`
==========================  =====================================================================

Examples
--------
>>> import robotcal
>>> scenario = robotcal.load_scenario("thesis-laser-tracker")
>>> scenario.robot.name, scenario.robot.n_joints
('kuka-kr5-sixx-r650', 6)
>>> capture = robotcal.simulate(scenario, rng=7)
>>> cpa = robotcal.identify(capture, scenario)
>>> bool(cpa.success), cpa.health.verdict
(True, 'OK')
"""

import lazy_loader

from robotcal._version import installed_version as _installed_version

__version__ = _installed_version()  # the installed distribution's, from pyproject.toml

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
__all__ = ["__version__", *__all__]
