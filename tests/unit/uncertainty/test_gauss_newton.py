"""The refined Monte Carlo's batched Gauss-Newton draws against the per-draw Levenberg-Marquardt (issue 31).

The same draws (same seed, same noise) are solved both ways. The per-draw solve stops at ``|dz| <= xtol (1 + |z|)``
(xtol 1e-10 on |z| ~ 1e3, ~1e-7 u), the Gauss-Newton draws when every component of the step is below 1e-3 of its
linearised u, after which the next step, i.e. the distance left to the solution, is ~1e-3 of it again (the linear
rate measured on these problems): ~1e-6 u. Measured largest differences: 7e-8 u (demo), 3e-6 u (thesis, points),
5e-6 u (thesis, distances). Draw for draw they must therefore agree to 1e-4 u (a margin of 20 over the largest seen),
and then the Monte Carlo's u and both ends of every 95 % interval agree to far better than the 0.01 u the issue
asks (each differs from the other's by at most the largest per-draw difference).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robotcal.api import link_masses, monte_carlo_problem, perturb
from robotcal.execution import single_blas_thread
from robotcal.identification.cpa import identify_cpa_batch
from robotcal.identification.model_choice import joint_model_for
from robotcal.io import load_scenario
from robotcal.uncertainty.draws import _block_generators, _noise, draw_block
from robotcal.uncertainty.gauss_newton import MAX_CONTRACTION, refine_draws_gauss_newton
from robotcal.uncertainty.montecarlo import MonteCarloSettings
from robotcal.uncertainty.refined import refine_batch
from robotcal.uncertainty.refined_kernel import _PointBatch, reference_unknowns
from robotcal.uncertainty.statistics import summarize_draws

#: Draw-for-draw agreement, in units of each output's standard uncertainty (see the module notes).
PER_DRAW = 1e-4
#: The issue's bound on u and on the interval ends, in units of u.
SUMMARY = 0.01


def _demo_deployed():
    """kr5-demo's deployed model: compliance refitted in every draw, circles and calibration poses."""
    scenario = load_scenario("kr5-demo")
    structure = joint_model_for("compliance", scenario.robot, masses=link_masses(scenario))  # [joint_model] defaults
    truth = perturb(scenario, rng=11).replace(joint_model=structure.with_values([1e-5, 4e-5]))
    return monte_carlo_problem(scenario, model="refined", parameters=truth, joint_model=structure)


def _both_ways(problem, n_draws: int, batch_size: int):
    with single_blas_thread():  # as run_monte_carlo draws them
        draws = {
            solver: draw_block(problem, 3, 0, n_draws, batch_size, refined_solver=solver)
            for solver in ("gauss-newton", "per-draw")
        }
    return draws["gauss-newton"], draws["per-draw"]


def _assert_equal_draws(problem, gauss_newton, per_draw):
    assert np.isfinite(gauss_newton).all() and np.isfinite(per_draw).all()
    summary_gn = summarize_draws(gauss_newton, 0.95)
    summary_lm = summarize_draws(per_draw, 0.95)
    u = summary_lm.std_uncertainty
    varies = u > 0  # parameters not estimated keep one value in every draw, the same both ways
    np.testing.assert_array_equal(gauss_newton[:, ~varies], per_draw[:, ~varies])
    difference = np.abs(gauss_newton - per_draw)[:, varies] / u[varies]
    assert difference.max() <= PER_DRAW, difference.max()
    assert np.all(np.abs(summary_gn.std_uncertainty - u)[varies] <= SUMMARY * u[varies])
    for kind in ("symmetric", "shortest"):
        for end_gn, end_lm in zip(summary_gn.interval(kind), summary_lm.interval(kind), strict=True):
            assert np.all(np.abs(end_gn - end_lm)[varies] <= SUMMARY * u[varies])


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")
def test_demo_deployed_model_gauss_newton_equals_the_per_draw_solve():
    problem = _demo_deployed()
    assert problem.n_extra == 2  # the compliance of J2 and J3, refitted in every draw
    gauss_newton, per_draw = _both_ways(problem, 2_000, 500)
    _assert_equal_draws(problem, gauss_newton, per_draw)


@pytest.mark.parametrize("base_frame", ["given", "registered"])
def test_thesis_gauss_newton_equals_the_per_draw_solve(base_frame):
    scenario = load_scenario("thesis-laser-tracker")
    options = dataclasses.replace(scenario.identification, base_frame=base_frame)
    problem = monte_carlo_problem(dataclasses.replace(scenario, identification=options), model="refined")
    assert problem.refined.base_free.all() == (base_frame == "registered")
    gauss_newton, per_draw = _both_ways(problem, 2_000, 500)
    _assert_equal_draws(problem, gauss_newton, per_draw)


def test_distances_criterion_gauss_newton_equals_the_per_draw_solve():
    problem = monte_carlo_problem(load_scenario("thesis-laser-tracker"), model="refined", criterion="distances")
    gauss_newton, per_draw = _both_ways(problem, 12, 6)
    u = np.std(per_draw, axis=0)
    varies = u > 0
    assert np.all(np.abs(gauss_newton - per_draw)[:, varies] <= PER_DRAW * u[varies])


def test_gauss_newton_steps_and_the_fallback():
    problem = monte_carlo_problem(load_scenario("thesis-laser-tracker"), model="refined")
    rng, _ = _block_generators(5, 0)
    points = problem.exact_points + _noise(problem, 40, rng)
    cpa = identify_cpa_batch(points, problem.structure, problem.tracker_from_base)
    args = (problem.refined, points, cpa.values, cpa.tracker_from_base)
    batched = refine_draws_gauss_newton(*args)
    assert batched.converged.all() and not batched.fallback.any()
    assert set(batched.iterations) <= {1, 2}  # the first step shared, then one or two evaluations of each draw's own
    # without corrective iterations no draw has met the stopping rule: every draw falls back to the per-draw solve,
    # whose results it then returns exactly
    impatient = refine_draws_gauss_newton(*args, max_corrections=0)
    assert impatient.fallback.all() and impatient.converged.all()
    reference = refine_batch(*args)
    np.testing.assert_array_equal(impatient.values, reference.values)
    np.testing.assert_array_equal(impatient.iterations, reference.iterations + 1)
    # held parameters that differ from the noise-free solution's (J6.d held at each draw's own value): no shared
    # first step, the corrective iterations start at x0 and still reach the per-draw solution
    assert "J6.d" in problem.refined.held
    moved = cpa.values.copy()
    moved[:, 5, 0] += np.linspace(-0.01, 0.01, moved.shape[0])
    args = (problem.refined, points, moved, cpa.tracker_from_base)
    alone, reference = refine_draws_gauss_newton(*args), refine_batch(*args)
    assert alone.converged.all() and not alone.fallback.any()
    u = np.std(reference.values, axis=0)
    varies = u > 0
    assert np.all(np.abs(alone.values - reference.values)[:, varies] <= PER_DRAW * u[varies])


def test_refined_solver_is_checked():
    with pytest.raises(ValueError, match="refined_solver"):
        MonteCarloSettings(refined_solver="newton")


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")
def test_extended_gauss_newton_draws_do_not_depend_on_the_batch():
    problem = _demo_deployed()
    with single_blas_thread():
        reference = draw_block(problem, 9, 1, 7, 7)
        for batch_size in (1, 3):
            np.testing.assert_array_equal(draw_block(problem, 9, 1, 7, batch_size), reference)


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")
@pytest.mark.parametrize("base_free", [False, True])
def test_extended_gradient_in_reverse_form_equals_the_normal_equations(base_free):
    problem = _demo_deployed()
    model = problem.refined
    if base_free:
        model = dataclasses.replace(model, base_free=np.ones(6, bool), x_scale=np.r_[model.x_scale, np.ones(6)])
    rng, _ = _block_generators(4, 0)
    points = problem.exact_points + _noise(problem, 5, rng)
    cpa = identify_cpa_batch(points[:, : problem.n_circle], problem.structure, problem.tracker_from_base)
    batch = _PointBatch(model, points, cpa.values, cpa.tracker_from_base)
    x = reference_unknowns(model) + 1e-3 * rng.standard_normal((5, model.n_free)) * model.x_scale
    cost, _, gradient = batch.normal_equations(x, np.arange(5))
    reverse_cost, reverse_gradient = batch.gradient(x, np.arange(5))
    np.testing.assert_allclose(reverse_cost, cost, rtol=1e-12)
    np.testing.assert_allclose(reverse_gradient, gradient, rtol=1e-10, atol=1e-12 * np.abs(gradient).max())


@pytest.mark.filterwarnings("ignore::robotcal.errors.IdentifiabilityWarning")
def test_shared_matrix_only_where_its_contraction_is_bounded():
    # the demo's deployed model: the corrective steps use the shared (J0^T J0)^-1 (the draws equal to the per-draw
    # solve: test_demo_deployed_model_gauss_newton_equals_the_per_draw_solve)
    assert _demo_deployed().refined.shared_step.contraction <= MAX_CONTRACTION
    # its base frame registered: the rotations about x and y against the first joint make the chord iteration slow;
    # the draws' own normal equations are solved instead, and still equal the per-draw solve
    scenario = load_scenario("kr5-demo")
    options = dataclasses.replace(scenario.identification, base_frame="registered")
    structure = joint_model_for("compliance", scenario.robot, masses=link_masses(scenario))
    truth = perturb(scenario, rng=11).replace(joint_model=structure.with_values([1e-5, 4e-5]))
    problem = monte_carlo_problem(
        dataclasses.replace(scenario, identification=options), model="refined", parameters=truth, joint_model=structure
    )
    assert problem.refined.base_free.all() and problem.refined.shared_step.contraction > MAX_CONTRACTION
    gauss_newton, per_draw = _both_ways(problem, 12, 6)
    u = np.std(per_draw, axis=0)
    varies = u > 0
    assert np.all(np.abs(gauss_newton - per_draw)[:, varies] <= PER_DRAW * u[varies])
