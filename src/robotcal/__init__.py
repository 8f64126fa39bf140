"""robotcal: kinematic calibration of serial robots by Circle Point Analysis, with GUM-S1 uncertainty.

The names below are the front door for Python users (docs/api.md). They load on first use
(PEP 562): ``import robotcal`` imports neither numpy nor anything else until a name is used, so the
command line and scripts that need one corner of the package start fast.

Lengths are in millimetres and angles in degrees wherever these functions take numbers (``rng=``
accepts None, an int seed or a ``numpy.random.Generator``); the result objects they return hold the
core's units, mm and radians, as their docstrings say.

==========================  =====================================================================
scenarios and robots        :func:`load_scenario`, :func:`load_robot`, :func:`change_plan`
one step at a time          :func:`perturb`, :func:`simulate`, :func:`identify`, :func:`refine`,
                            :func:`evaluate`, :func:`check_plan`
uncertainty                 :func:`monte_carlo`, :func:`tcp_uncertainty`
the whole calibration run   :func:`plan_run`, :func:`run_calibration`, :func:`read_run`,
                            :func:`render_report`, :class:`RunResult`
values                      :class:`Scenario`, :class:`RobotModel`, :class:`ParameterSet`,
                            :class:`Capture`
files                       :func:`read_capture`, :func:`write_capture`, :func:`read_parameters`,
                            :func:`write_parameters`
errors                      :class:`RobotcalError`, :class:`InputError`
==========================  =====================================================================

Examples
--------
>>> import robotcal
>>> scenario = robotcal.load_scenario("thesis-noise-free")
>>> scenario.robot.name, scenario.robot.n_joints
('kuka-kr5-sixx-r650', 6)
>>> capture = robotcal.simulate(scenario, rng=7)
>>> cpa = robotcal.identify(capture, scenario)
>>> bool(cpa.success)
True
"""

__version__ = "0.1.0"

#: Public name -> the module that defines it (imported on first use of the name).
_EXPORTS = {
    "load_scenario": "robotcal.io.scenario",
    "load_robot": "robotcal.io.robots",
    "Scenario": "robotcal.io.scenario",
    "read_capture": "robotcal.io.capture_csv",
    "write_capture": "robotcal.io.capture_csv",
    "read_parameters": "robotcal.io.parameters_json",
    "write_parameters": "robotcal.io.parameters_json",
    "perturb": "robotcal.api",
    "simulate": "robotcal.api",
    "identify": "robotcal.api",
    "refine": "robotcal.api",
    "evaluate": "robotcal.api",
    "monte_carlo": "robotcal.api",
    "tcp_uncertainty": "robotcal.api",
    "check_plan": "robotcal.api",
    "change_plan": "robotcal.api",
    "plan_run": "robotcal.pipeline",
    "run_calibration": "robotcal.pipeline",
    "read_run": "robotcal.pipeline",
    "RunResult": "robotcal.pipeline.result",
    "render_report": "robotcal.report.html",
    "Capture": "robotcal.capture",
    "ParameterSet": "robotcal.kinematics.model",
    "RobotModel": "robotcal.kinematics.model",
    "InputError": "robotcal.errors",
    "RobotcalError": "robotcal.errors",
}

__all__ = ["__version__", *_EXPORTS]


def _lazy_exports(package: str, exports: dict[str, str]):
    """Module ``__getattr__`` and ``__dir__`` (PEP 562) for ``package``, whose public names ``exports``
    (name -> defining module) are imported on first use and then cached in the package namespace.

    Used by this package and by the sub-packages whose modules pull heavier dependencies.
    """
    import sys

    def __getattr__(name: str):
        module_name = exports.get(name)
        if module_name is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        import importlib

        module = importlib.import_module(module_name)
        try:
            value = getattr(module, name)
        except AttributeError:
            raise AttributeError(
                f"module {package!r} has no attribute {name!r}: {module_name} does not define it in this version"
            ) from None
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(exports))

    return __getattr__, __dir__


__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)
