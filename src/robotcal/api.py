"""The front door for Python users: one call per calibration step, on a scenario (docs/api.md).

Each function wraps the scenario-level operations of :mod:`robotcal.workflow` and the core
(:mod:`robotcal.identification`, :mod:`robotcal.uncertainty`, :mod:`robotcal.planning`) without
repeating their logic; it only turns friendly arguments into core objects:

- a scenario is a :class:`~robotcal.io.scenario.Scenario`, a built-in scenario name or a TOML path;
- a capture is a :class:`~robotcal.capture.Capture` or a capture CSV path;
- parameters are a :class:`~robotcal.kinematics.model.ParameterSet`, a result holding one
  (``CPAResult``, ``RefinementResult``: its ``.parameters``) or a parameter JSON path;
- numbers given here are in millimetres and degrees (names carry the unit: ``poses_deg``,
  ``tool_mm``); the result objects returned are the core's, in mm and radians;
- randomness comes from ``rng``: None, an int seed or a ``numpy.random.Generator``
  (:func:`seed_from`). The core functions take an int seed, so that their blocks of draws are
  reproducible for any batch size or worker count; a Generator gives them ``rng.integers(2**63)``,
  and every result records the seed it used.

These functions never print and never write files (use :func:`robotcal.write_capture`,
:func:`robotcal.write_parameters`, or the pipeline of :func:`robotcal.run_calibration`).
"""

from __future__ import annotations

import dataclasses
import os
import sys
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.io.scenario import Scenario
from robotcal.kinematics.model import ParameterSet, RobotModel

if TYPE_CHECKING:  # the modules of the refinement, the Monte Carlo and the TCP load when a function needs them
    from robotcal.identification.cpa import CPAResult
    from robotcal.identification.evaluation import EvaluationRow
    from robotcal.identification.refine import RefinementResult
    from robotcal.planning.cell import PlanCheck
    from robotcal.uncertainty.montecarlo import MonteCarloResult
    from robotcal.uncertainty.tcp import TCPUncertainty

__all__ = [
    "SEED_BOUND",
    "seed_from",
    "perturb",
    "simulate",
    "identify",
    "refine",
    "evaluate",
    "monte_carlo",
    "tcp_uncertainty",
    "check_plan",
    "change_plan",
]

#: Seeds are integers in ``[0, SEED_BOUND)``; a Generator gives ``rng.integers(SEED_BOUND)``.
SEED_BOUND = 2**63


# ------------------------------------------------------------------------------------------ coercion


def seed_from(rng, default: int | None = None) -> int:
    """The int seed a core function takes, from an ``rng`` argument.

    Parameters
    ----------
    rng : None, int or numpy.random.Generator
        None: ``default`` when given (a seed the scenario records), else fresh entropy; an int: that
        seed; a Generator: ``rng.integers(2**63)`` (the Generator advances, so two calls with one
        Generator give two different, reproducible seeds).
    default : int, optional

    Returns
    -------
    int
        A seed in ``[0, 2**63)``, to record with the result.

    Examples
    --------
    >>> import numpy as np
    >>> from robotcal.api import seed_from
    >>> seed_from(7)
    7
    >>> seed_from(None, default=3)
    3
    >>> a = seed_from(np.random.default_rng(1))
    >>> a == seed_from(np.random.default_rng(1))
    True
    """
    if rng is None:
        if default is not None:
            return seed_from(default)
        return int(np.random.SeedSequence().entropy % SEED_BOUND)
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(SEED_BOUND))
    if isinstance(rng, bool) or not isinstance(rng, int | np.integer):
        raise InputError(f"`rng` must be None, an int seed or a numpy.random.Generator; got {type(rng).__name__}")
    if not 0 <= int(rng) < SEED_BOUND:
        raise InputError(f"`rng` seed must be in [0, 2**63); got {rng}")
    return int(rng)


def _scenario(scenario) -> Scenario:
    """A Scenario from a Scenario, a built-in scenario name or a scenario TOML path."""
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, str | os.PathLike):
        from robotcal.io.scenario import load_scenario

        return load_scenario(scenario)
    raise InputError(
        f"`scenario` must be a Scenario, a built-in scenario name or a path; got {type(scenario).__name__}"
    )


def _robot(robot) -> RobotModel:
    """A RobotModel from a RobotModel, a Scenario (its robot), a built-in robot name or a robot TOML path."""
    if isinstance(robot, RobotModel):
        return robot
    if isinstance(robot, Scenario):
        return robot.robot
    if isinstance(robot, str | os.PathLike):
        from robotcal.io.robots import load_robot

        return load_robot(robot)
    raise InputError(f"`robot` must be a RobotModel, a Scenario, a robot name or a path; got {type(robot).__name__}")


def _capture(capture, robot: RobotModel, name: str = "capture") -> Capture:
    """A Capture from a Capture or a capture CSV path (read with the robot's joint count)."""
    if isinstance(capture, Capture):
        return capture
    if isinstance(capture, str | os.PathLike):
        from robotcal.io.capture_csv import read_capture

        return read_capture(capture, n_joints=robot.n_joints)
    raise InputError(f"`{name}` must be a Capture or the path of a capture CSV; got {type(capture).__name__}")


def _parameters(parameters, robot: RobotModel, name: str = "parameters") -> ParameterSet:
    """A ParameterSet from a ParameterSet, a result holding one, a parameter JSON path, or None (nominal)."""
    if parameters is None:
        return ParameterSet.nominal(robot)
    if isinstance(getattr(parameters, "parameters", None), ParameterSet):  # CPAResult, RefinementResult
        parameters = parameters.parameters
    elif isinstance(parameters, str | os.PathLike):
        from robotcal.io.parameters_json import read_parameters

        return read_parameters(parameters, robot)
    if not isinstance(parameters, ParameterSet):
        raise InputError(
            f"`{name}` must be a ParameterSet, a CPA or refinement result, or the path of a parameter JSON; "
            f"got {type(parameters).__name__}"
        )
    if parameters.robot.n_joints != robot.n_joints:
        raise InputError(
            f"`{name}` belong to robot {parameters.robot.name!r} ({parameters.robot.n_joints} joints); "
            f"the scenario's robot {robot.name!r} has {robot.n_joints}"
        )
    return parameters


# ---------------------------------------------------------------------------------------- one step each


def perturb(scenario, *, rng=None) -> ParameterSet:
    """A perturbed "true" robot for a synthetic study: nominal + N(0, sd) on the identifiable parameters.

    The standard deviations are the scenario's ``[truth]`` table (``length_sd_mm``, ``angle_sd_deg``,
    ``include_base``; 0.2 mm and 0.05 deg when it has none), as ``robotcal run`` uses them.

    Parameters
    ----------
    scenario : Scenario, str or path
    rng : None, int or numpy.random.Generator
        None: the scenario's ``truth.seed``, else fresh entropy (see :func:`seed_from`).

    Returns
    -------
    ParameterSet
        [mm, rad]; give it to :func:`simulate` as ``true_parameters``.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> scenario = robotcal.load_scenario("kr5-demo")
    >>> truth = robotcal.perturb(scenario, rng=11)
    >>> nominal = robotcal.ParameterSet.nominal(scenario.robot)
    >>> bool(np.any(truth.values != nominal.values))
    True
    >>> truth.values.shape
    (6, 5)
    """
    from robotcal.workflow import scenario_truth

    scenario = _scenario(scenario)
    truth, _ = scenario_truth(scenario, seed=seed_from(rng, None if scenario.truth is None else scenario.truth.seed))
    return truth


def simulate(scenario, *, rng=None, true_parameters=None, validation: bool = False) -> Capture:
    """Simulate the scenario's Circle Point capture (thesis ch. 5.2.1), or a validation capture.

    Joint errors of the scenario's ``[capture.joint_errors]`` and instrument noise U(L) = A + B L come
    from one generator seeded from ``rng``; the capture records the seed (``capture.seed``).

    Parameters
    ----------
    scenario : Scenario, str or path
    rng : None, int or numpy.random.Generator
        None: the scenario's seed (``capture.seed``, or ``validation.seed`` with ``validation=True``),
        else fresh entropy (see :func:`seed_from`).
    true_parameters : ParameterSet, CPAResult, RefinementResult or path, optional
        The robot that is measured [mm, rad] (e.g. from :func:`perturb`); default nominal.
    validation : bool
        Simulate the scenario's validation capture instead: random reachable poses (``[validation]``
        table), each measured once with the flange target (``circle = 0``).

    Returns
    -------
    Capture
        Joint readings [rad] and target positions in the tracker frame [mm]; write it as a capture
        CSV (deg, mm) with :func:`robotcal.write_capture`.

    Examples
    --------
    >>> import robotcal
    >>> capture = robotcal.simulate("kr5-demo", rng=7)
    >>> capture.n_points, capture.n_joints, capture.seed
    (270, 6, 7)
    >>> validation = robotcal.simulate("kr5-demo", rng=8, validation=True)
    >>> validation.n_points, int(validation.circle.max())
    (100, 0)
    """
    from robotcal.workflow import simulate_scenario, simulate_validation

    scenario = _scenario(scenario)
    truth = _parameters(true_parameters, scenario.robot, "true_parameters")
    if validation:
        seed = seed_from(rng, None if scenario.validation is None else scenario.validation.seed)
        return simulate_validation(scenario, seed=seed, true_parameters=truth).capture
    return simulate_scenario(scenario, seed=seed_from(rng, scenario.seed), true_parameters=truth).capture


def identify(capture, scenario, *, check: bool = True) -> CPAResult:
    """Circle Point Analysis of a capture (thesis ch. 4.4-4.5) with the scenario's robot, targets and options.

    Parameters
    ----------
    capture : Capture or path
        A capture, or a capture CSV (``circle,direction,q1..qN,x,y,z``: deg, mm in the tracker frame).
    scenario : Scenario, str or path
        Gives the robot, the target positions, the base frame and the ``[identification]`` options.
    check : bool
        First run the plausibility checks (units, radians for degrees, another robot, outliers):
        :func:`robotcal.identification.plausibility.check_capture`.

    Returns
    -------
    CPAResult
        ``.parameters`` [mm, rad], the fitted circles, the line-pair cases, ``success`` and ``message``.

    Examples
    --------
    Noise-free data give the true parameters back (thesis Table 5.1 scenario):

    >>> import numpy as np, robotcal
    >>> scenario = robotcal.load_scenario("thesis-noise-free")
    >>> truth = robotcal.perturb(scenario, rng=3)
    >>> capture = robotcal.simulate(scenario, rng=1, true_parameters=truth)
    >>> cpa = robotcal.identify(capture, scenario)
    >>> int(cpa.parameters.identified.sum())  # of the 6 x 5 table, those CPA determines
    20
    >>> error = cpa.parameters.difference(truth)  # mm, rad (angles wrapped)
    >>> bool(np.abs(error).max() < 1e-9)
    True
    """
    from robotcal.workflow import identify_scenario

    scenario = _scenario(scenario)
    return identify_scenario(_capture(capture, scenario.robot), scenario, check=check)


def refine(capture, start, scenario, *, criterion: str = "points", **options) -> RefinementResult:
    """Least-squares refinement of ``start`` over every measured point (thesis ch. 4.5.7).

    Parameters
    ----------
    capture : Capture or path
    start : ParameterSet, CPAResult, RefinementResult, path or None
        Start values (usually :func:`identify`'s result; None: nominal).
    scenario : Scenario, str or path
        Gives the robot, the targets and the base frame: with ``[identification] base_frame = "given"``
        the points criterion holds the scenario's ``tracker_from_base`` (pass ``estimate_base=True`` to
        estimate it); with ``"registered"`` it is estimated.
    criterion : {"points", "distances"}
        Eq. 4-101 (positions in the tracker frame) or eq. 4-102 (all pairwise distances).
    **options
        Passed to :func:`robotcal.identification.refine.refine_parameters` (``free``, ``estimate_base``,
        ``method``, ``max_nfev``, ``tolerance``, ...).

    Returns
    -------
    RefinementResult
        ``.parameters`` [mm, rad], ``success``, residual statistics [mm], convergence history,
        linearised covariance and ``standard_uncertainty`` [mm, rad].

    Examples
    --------
    >>> import robotcal
    >>> scenario = robotcal.load_scenario("kr5-demo")
    >>> truth = robotcal.perturb(scenario, rng=11)
    >>> capture = robotcal.simulate(scenario, rng=1, true_parameters=truth)
    >>> cpa = robotcal.identify(capture, scenario)
    >>> result = robotcal.refine(capture, cpa, scenario, criterion="distances")
    >>> bool(result.success), result.criterion
    (True, 'distances')
    >>> bool(result.residual_rms < 0.05)  # mm: laser-tracker noise and the backlash the model does not hold
    True
    """
    from robotcal.workflow import refine_scenario

    scenario = _scenario(scenario)
    robot = scenario.robot
    return refine_scenario(
        _capture(capture, robot), scenario, _parameters(start, robot, "start"), criterion=criterion, **options
    )


def evaluate(
    captures, parameter_sets: Mapping, scenario, *, views=("points", "distances")
) -> tuple[EvaluationRow, ...]:
    """Mean, max and RMS errors of named parameter sets on captures (thesis Tables 4.10/4.11).

    Parameters
    ----------
    captures : Capture, path, or mapping of str to Capture or path
        E.g. ``{"validation": ...}``; a single capture is named ``"capture"``. A capture at free
        poses (``circle = 0``) is measured with the scenario's validation flange target.
    parameter_sets : mapping of str to ParameterSet, CPAResult, RefinementResult or path
        E.g. ``{"nominal": None, "cpa": cpa, "refined": refined}`` (None: nominal); the first is the
        reference of ``improvement_pct``.
    scenario : Scenario, str or path
    views : sequence of {"points", "distances"}
        Points after a best-fit registration of the prediction on the measurement, or all pairwise
        distances.

    Returns
    -------
    tuple of EvaluationRow
        ``parameter_set, view, capture, n_errors, mean_error_mm, max_error_mm, rms_error_mm,
        improvement_pct``, ordered by capture, view, parameter set.

    Examples
    --------
    >>> import robotcal
    >>> scenario = robotcal.load_scenario("kr5-demo")
    >>> truth = robotcal.perturb(scenario, rng=11)
    >>> capture = robotcal.simulate(scenario, rng=1, true_parameters=truth)
    >>> validation = robotcal.simulate(scenario, rng=2, true_parameters=truth, validation=True)
    >>> refined = robotcal.refine(capture, robotcal.identify(capture, scenario), scenario)
    >>> rows = robotcal.evaluate({"validation": validation}, {"nominal": None, "refined": refined}, scenario,
    ...                          views=["points"])
    >>> [(row.parameter_set, row.view) for row in rows]
    [('nominal', 'points'), ('refined', 'points')]
    >>> bool(rows[1].mean_error_mm < 0.25 * rows[0].mean_error_mm)  # calibration removes most of the error
    True
    """
    from robotcal.workflow import evaluate_scenario

    scenario = _scenario(scenario)
    robot = scenario.robot
    if isinstance(captures, Mapping):
        named = {str(name): _capture(value, robot, f"captures[{name!r}]") for name, value in captures.items()}
    else:
        named = {"capture": _capture(captures, robot, "captures")}
    if not isinstance(parameter_sets, Mapping):
        raise InputError(
            f"`parameter_sets` must be a mapping of names to parameters; got {type(parameter_sets).__name__}"
        )
    sets = {str(name): _parameters(value, robot, f"parameter_sets[{name!r}]") for name, value in parameter_sets.items()}
    return evaluate_scenario(scenario, named, sets, views=tuple(views))


# ------------------------------------------------------------------------------------------ uncertainty


def monte_carlo(
    scenario,
    *,
    draws: int | None = None,
    model: str = "cpa",
    criterion: str = "points",
    parameters=None,
    rng=None,
    workers: int = 1,
    coverage: float | None = None,
    interval: str = "symmetric",
    adaptive: bool = False,
    keep_draws: bool = True,
    linearised: bool | None = None,
    progress=None,
) -> MonteCarloResult:
    """GUM Supplement 1 Monte Carlo of the calibration of a scenario (thesis ch. 5.2.3).

    Every draw adds the instrument noise (and the random part of the joint errors) to the capture the
    scenario's plan gives on the robot ``parameters``, identifies it by CPA and, with
    ``model="refined"``, refines it (the deployed model); the spread of the draws is the uncertainty
    of the parameters.

    Parameters
    ----------
    scenario : Scenario, str or path
    draws : int, optional
        Number of draws M (default the scenario's ``montecarlo.iterations``; JCGM 101 recommends 10^4
        or more, the examples here use a few hundred to stay fast).
    model : {"cpa", "refined"}
        The parameters of CPA, or of CPA followed by the refinement with ``criterion``.
    criterion : {"points", "distances"}
        Refinement objective, ``model="refined"`` only.
    parameters : ParameterSet, CPAResult, RefinementResult, path or None
        The robot the capture is simulated from: the estimate, when stating the uncertainty of a
        calibration (``robotcal run`` uses the CPA estimate for ``"cpa"`` and the refined one for
        ``"refined"``); default nominal.
    rng : None, int or numpy.random.Generator
        None: the scenario's ``montecarlo.seed``, else fresh entropy. The draws are seeded per block
        from one int seed (``rng.integers(2**63)`` for a Generator), so the result does not depend on
        ``workers``; ``result.seed`` records it.
    workers : int
        Processes computing blocks of draws in parallel.
    coverage : float, optional
        Coverage probability of the intervals (default the scenario's ``montecarlo.coverage``).
    interval : {"symmetric", "shortest"}
    adaptive : bool
        JCGM 101 §7.9 adaptive procedure instead of a fixed ``draws``.
    keep_draws : bool
        Keep every draw (``result.draws``, needed by :func:`tcp_uncertainty`).
    linearised : bool, optional
        Also compute the GUM law-of-propagation comparison (JCGM 101 §8); default True for
        ``model="cpa"``, False for ``"refined"`` (where it costs as much as many draws).
    progress : callable, optional
        ``progress(draws_done, draws_total)`` after every block.

    Returns
    -------
    MonteCarloResult
        ``summary`` (mean, ``std_uncertainty``, intervals, min, max per parameter, shape
        (n_joints, 5) [mm, rad]), covariance, ``draws`` (n_draws, n_joints, 5), ``seed``.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> result = robotcal.monte_carlo("thesis-laser-tracker", draws=200, rng=1)
    >>> result.n_draws, result.seed, result.model
    (200, 1, 'cpa')
    >>> u = result.summary.std_uncertainty  # (6, 5): d, theta, a, alpha, beta per joint [mm, rad]
    >>> bool(np.all(u[result.identified] > 0)), bool(np.all(u[~result.identified] == 0))
    (True, True)
    """
    from robotcal.uncertainty.montecarlo import MonteCarloSettings, run_monte_carlo
    from robotcal.workflow import scenario_monte_carlo

    scenario = _scenario(scenario)
    table = scenario.montecarlo
    seed = seed_from(rng, table.seed)
    settings = MonteCarloSettings(
        iterations=int(table.iterations if draws is None else draws),
        coverage=float(table.coverage if coverage is None else coverage),
        interval=interval,
        adaptive=adaptive,
        workers=workers,
        keep_draws=keep_draws,
    )
    truth = _parameters(parameters, scenario.robot, "parameters")
    problem = scenario_monte_carlo(scenario, true_parameters=truth, model=model, criterion=criterion)
    if linearised is None:
        linearised = model == "cpa"
    return run_monte_carlo(problem, settings, seed=seed, linearised=linearised, progress=progress)


def _parameter_draws(draws, robot: RobotModel) -> np.ndarray:
    """Parameter draws (n_draws, n_joints, 5) [mm, rad] from a result, a draws file or an array.

    Draws that name their robot (a Monte Carlo result, a draws file) must be of ``robot``'s model (same
    joint types and nominal parameters; its reading map may differ, e.g. controller readings).
    """
    source = None
    montecarlo = sys.modules.get("robotcal.uncertainty.montecarlo")  # not loaded: not a MonteCarloResult
    if montecarlo is not None and isinstance(draws, montecarlo.MonteCarloResult):
        if draws.draws is None:
            raise InputError("`draws`: this Monte Carlo result kept no draws; run monte_carlo(..., keep_draws=True)")
        values, source = draws.draws, draws.robot
    elif isinstance(draws, str | os.PathLike):
        from robotcal.io.draws_npz import read_draws

        read = read_draws(draws)
        values, source = read.values, read.robot
    else:
        values, source = getattr(draws, "values", draws), getattr(draws, "robot", None)  # a ParameterDraws
    values = np.asarray(values, dtype=float)
    if values.ndim != 3 or values.shape[1:] != (robot.n_joints, 5):
        raise InputError(
            f"`draws` must be a MonteCarloResult, a draws.npz path or an array of shape (n_draws, "
            f"{robot.n_joints}, 5) [mm, rad]; got shape {values.shape}"
        )
    if isinstance(source, RobotModel) and not (
        np.array_equal(source.hayati, robot.hayati) and np.allclose(source.nominal, robot.nominal, rtol=0, atol=1e-9)
    ):
        raise InputError(
            f"`draws` are parameters of robot {source.name!r}, whose model differs from robot {robot.name!r}'s"
        )
    return values


def tcp_uncertainty(
    robot, draws, poses_deg, *, tool_mm=None, coverage: float = 0.95, keep_draws: bool = False
) -> TCPUncertainty:
    """TCP position and orientation uncertainty at poses from Monte Carlo parameter draws (thesis ch. 5.3).

    Parameters
    ----------
    robot : RobotModel, Scenario, str or path
        The robot whose readings ``poses_deg`` are (a scenario's robot, a built-in name, a TOML path).
    draws : MonteCarloResult, path, or array_like of shape (n_draws, n_joints, 5)
        :func:`monte_carlo`'s result (run with ``keep_draws=True``), a ``draws.npz`` written by
        ``robotcal uncertainty --save-draws``, or draws in core units [mm, rad].
    poses_deg : array_like, shape (n_poses, n_joints) or (n_joints,)
        Controller joint readings [deg] (e.g. a trajectory).
    tool_mm : array_like, shape (3,), optional
        TCP in flange coordinates [mm]; default the flange origin.
    coverage : float
        Coverage probability of the intervals and of the 95 % ellipsoid.
    keep_draws : bool
        Keep the TCP coordinates of every draw (``result.draws``; for scatter plots of a few poses).

    Returns
    -------
    TCPUncertainty
        Per pose X, Y, Z [mm] and KUKA A, B, C [rad]: ``std_uncertainty`` (n_poses, 6),
        ``position_uncertainty`` (n_poses,) [mm], covariance, coverage ellipsoid, and the linearised
        (LPU) result beside.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> scenario = robotcal.load_scenario("thesis-laser-tracker")
    >>> result = robotcal.monte_carlo(scenario, draws=200, rng=1)
    >>> poses_deg = [[0, 10, 90, 0, 30, 0], [20, 30, 60, 10, 40, 0]]  # readings J1..J6 [deg]
    >>> tcp = robotcal.tcp_uncertainty(scenario, result, poses_deg, tool_mm=[0, 0, 100])
    >>> tcp.n_poses, tcp.std_uncertainty.shape
    (2, (2, 6))
    >>> # the Monte Carlo and the linearised propagation of the same draws agree to a few percent
    >>> bool(np.allclose(tcp.std_uncertainty[:, :3], tcp.lpu_std_uncertainty[:, :3], rtol=0.1))
    True
    """
    from robotcal.uncertainty.tcp import propagate_to_tcp

    robot = _robot(robot)
    values = _parameter_draws(draws, robot)
    poses = np.asarray(poses_deg, dtype=float)
    tool = None if tool_mm is None else np.asarray(tool_mm, dtype=float)
    return propagate_to_tcp(robot, values, np.deg2rad(poses), tool=tool, coverage=coverage, keep_draws=keep_draws)


# ----------------------------------------------------------------------------------------------- planning


def change_plan(
    scenario, *, start_deg=None, sweep_deg=None, points=None, reflector_mm=None, bidirectional: bool | None = None
) -> Scenario:
    """The scenario with another capture plan: the keys given replace those of ``[capture]``.

    Parameters
    ----------
    scenario : Scenario, str or path
    start_deg : array_like, shape (n_joints,) or (n_joints, n_joints), optional
        Readings where the circles start [deg] (one start for all, or one full start per circle).
    sweep_deg : array_like, shape (n_joints,), optional
        Signed angle each joint turns in its circle [deg].
    points : array_like of int, shape (n_joints,), optional
        Points per circle and direction.
    reflector_mm : array_like, shape (n_joints, 3) or (3,), optional
        Target positions [mm] in the frames of the scenario's reflector mount (per joint, or flange).
    bidirectional : bool, optional

    Returns
    -------
    Scenario
        A new scenario (the one given is unchanged); the plan is checked as a scenario file's would be.

    Examples
    --------
    >>> import numpy as np, robotcal
    >>> scenario = robotcal.load_scenario("thesis-laser-tracker")
    >>> longer = robotcal.change_plan(scenario, reflector_mm=[[100, 0, 0], [200, 0, 0], [0, 50, 0],
    ...                                                       [120, 0, 0], [0, 80, 0], [0, 60, 0]])
    >>> float(longer.plan.reflector.positions[3, 0]), float(scenario.plan.reflector.positions[3, 0])
    (120.0, 20.0)
    >>> np.rad2deg(longer.plan.sweep).tolist() == np.rad2deg(scenario.plan.sweep).tolist()
    True
    """
    scenario = _scenario(scenario)
    plan = scenario.plan  # a scenario without a capture plan raises its InputError (naming the key) on first use
    if plan.n_joints != scenario.robot.n_joints:
        raise InputError(
            f"{scenario.source}: the plan has {plan.n_joints} circles for {scenario.robot.n_joints} joints"
        )
    changes = {}
    if start_deg is not None:
        changes["start"] = np.deg2rad(np.asarray(start_deg, dtype=float))
    if sweep_deg is not None:
        changes["sweep"] = np.deg2rad(np.asarray(sweep_deg, dtype=float))
    if points is not None:
        changes["points"] = np.asarray(points)
    if bidirectional is not None:
        changes["bidirectional"] = bool(bidirectional)
    if reflector_mm is not None:
        changes["reflector"] = dataclasses.replace(plan.reflector, positions=np.asarray(reflector_mm, dtype=float))
    try:
        new_plan = dataclasses.replace(plan, **changes)
    except InputError as exc:
        raise InputError(f"{scenario.source}: changed plan: {exc}") from None
    return dataclasses.replace(scenario, plan=new_plan)


def check_plan(scenario, *, acceptance_deg: float | None = None, aim: str = "middle") -> PlanCheck:
    """Check every point of the scenario's capture plan in its cell (thesis ch. 4.5.2).

    Joint limits, the instrument's measuring range, the reflector's acceptance angle and the line of
    sight past the robot's links (capsules), as ``robotcal plan check`` does.

    Parameters
    ----------
    scenario : Scenario, str or path
        Its plan (see :func:`change_plan`), tracker pose, robot and instrument preset (range, acceptance).
    acceptance_deg : float, optional
        Reflector acceptance half-angle [deg] (default the instrument preset's; unchecked when it has none).
    aim : {"middle", ...}
        How the reflector is aimed (:class:`robotcal.planning.cell.CellModel`).

    Returns
    -------
    PlanCheck
        ``feasible``, per point ``ok`` and ``reasons(i)``, per circle ``circles`` (usable range [deg]).

    Examples
    --------
    The thesis plan (Table 5.1) in the cell of Table 5.4: the circles of J5 and J6 lose points to
    the reflector's acceptance angle and to the line of sight past the links:

    >>> import robotcal
    >>> check = robotcal.check_plan("kr5-demo")
    >>> check.feasible
    False
    >>> [(c.circle, c.feasible_points, c.points) for c in check.circles if c.feasible_points < c.points]
    [(5, 8, 25), (6, 7, 30)]
    >>> check.circles[4].first_reasons
    ('acceptance (60 deg)',)
    """
    from robotcal.planning.cell import check_plan as check_points
    from robotcal.planning.scenario import cell_from_scenario

    scenario = _scenario(scenario)
    cell, _ = cell_from_scenario(scenario, acceptance_deg=acceptance_deg, aim=aim)
    return check_points(scenario.robot, scenario.plan, cell)
