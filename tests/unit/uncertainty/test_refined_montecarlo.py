"""Monte Carlo of the refined (deployed) model: the batched refinement against refine_parameters,
the Monte Carlo u against the linearised u, batch-size reproducibility, failed draws, files."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

from robotcal.api import monte_carlo_problem, simulate
from robotcal.errors import IdentifiabilityWarning
from robotcal.identification.cpa import identify_cpa_batch
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.io import load_scenario
from robotcal.io.results.uncertainty_files import read_uncertainty_csv, write_uncertainty_csv, write_uncertainty_json
from robotcal.kinematics.model import ParameterSet
from robotcal.uncertainty.draws import _block_generators, _noise, draw_block
from robotcal.uncertainty.montecarlo import DEFAULT_BLOCK_SIZE, REFINED_BLOCK_SIZE, MonteCarloSettings, run_monte_carlo
from robotcal.uncertainty.refined import refine_batch


@pytest.fixture(scope="module")
def laser():
    scenario = load_scenario("thesis-laser-tracker")
    return scenario, monte_carlo_problem(scenario, model="refined")


@pytest.fixture(scope="module")
def distances(laser):
    return monte_carlo_problem(laser[0], model="refined", criterion="distances")


def _noisy(problem, seed, n_draws):
    rng, _ = _block_generators(seed, 0)
    return problem.exact_points + _noise(problem, n_draws, rng)


def _loop_reference(problem, points, cpa, k, criterion, estimate_base):
    """The plain path a user takes for one capture: refine_parameters from its CPA estimate."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)  # J6 held: recorded in the problem too
        return refine_parameters(
            problem.capture.with_points(points[k]),
            ParameterSet(robot=problem.robot, values=cpa.values[k]),
            problem.structure.reflector,
            tracker_from_base=cpa.tracker_from_base[k] if criterion == "points" else None,
            settings=RefinementSettings(criterion=criterion, estimate_base=estimate_base),
        )


def _assert_same_solution(batch_values, batch_cost, reference):
    # Both solvers stop at the rounding floor of the optimum; along its flattest direction a change of
    # 1e-8 mm moves the cost by ~1e-14 mm^2, below what either can resolve. So: the same parameters to
    # 1e-5 of their own standard uncertainty (1e-8 mm where u ~ 6 um), and a cost no worse.
    u = reference.uncertainty.standard_uncertainty
    free = reference.identifiability.free
    difference = np.abs(batch_values - reference.parameters.values)
    assert np.all(difference[free] <= 1e-5 * u[free]), (difference[free] / u[free]).max()
    assert np.all(difference[~free] == 0.0)  # held parameters keep the start value exactly
    assert batch_cost <= reference.fit.cost_history[-1] * (1.0 + 1e-9)


@pytest.mark.parametrize("base_frame", ["given", "registered"])
def test_batched_refinement_of_a_draw_equals_refine_parameters(laser, base_frame):
    scenario, _ = laser
    options = dataclasses.replace(scenario.identification, base_frame=base_frame)
    problem = monte_carlo_problem(dataclasses.replace(scenario, identification=options), model="refined")
    assert problem.refined.base_free.any() == (base_frame == "registered")
    points = _noisy(problem, seed=5, n_draws=3)
    cpa = identify_cpa_batch(points, problem.structure, problem.tracker_from_base)
    batch = refine_batch(problem.refined, points, cpa.values, cpa.tracker_from_base)
    assert batch.converged.all()
    for k in range(3):
        reference = _loop_reference(problem, points, cpa, k, "points", base_frame == "registered")
        np.testing.assert_array_equal(reference.identifiability.free, problem.refined.free)
        _assert_same_solution(batch.values[k], batch.cost[k], reference)
        # the same base frame: rotation to 1e-10, translation to 1e-7 mm (the flat direction again: the base
        # translation trades against d and a at ~1e-8 mm; its own u is ~1e-2 mm)
        np.testing.assert_allclose(batch.tracker_from_base[k, :3, :3], reference.tracker_from_base[:3, :3], atol=1e-10)
        np.testing.assert_allclose(batch.tracker_from_base[k, :3, 3], reference.tracker_from_base[:3, 3], atol=1e-7)


def test_batched_distances_refinement_equals_refine_parameters(distances):
    problem = distances
    assert problem.refined.criterion == "distances" and not problem.refined.base_free.any()
    points = _noisy(problem, seed=6, n_draws=2)
    cpa = identify_cpa_batch(points, problem.structure, problem.tracker_from_base)
    batch = refine_batch(problem.refined, points, cpa.values)
    assert batch.converged.all() and batch.tracker_from_base is None
    reference = _loop_reference(problem, points, cpa, 1, "distances", False)
    _assert_same_solution(batch.values[1], batch.cost[1], reference)


def test_noise_free_refined_problem_is_centred_on_the_truth(laser):
    _, problem = laser
    # thesis-laser-tracker: nominal truth, no joint errors -> the noise-free refinement is the truth
    free = problem.refined.free
    np.testing.assert_allclose(problem.noise_free_values[free], problem.true_parameters.values[free], atol=1e-9)
    assert problem.identified[free].all()


def test_refined_monte_carlo_u_agrees_with_the_linearised_u(laser):
    scenario, problem = laser
    result = run_monte_carlo(problem, MonteCarloSettings(iterations=1000, batch_size=500), seed=3)
    assert result.model == "refined" and result.criterion == "points" and result.n_failed == 0
    mask = problem.refined.free
    ratio = result.summary.std_uncertainty[mask] / result.linearised.std_uncertainty[mask]
    # relative standard error of a standard deviation from M = 1000 draws: 1/sqrt(2M) = 2.2 %; 4 sigma
    assert np.all(np.abs(ratio - 1.0) < 0.09), ratio
    assert abs(np.mean(ratio) - 1.0) < 0.02  # the 20 ratios' mean: ~0.5 % standard error
    # refine_parameters' own linearised u from one noisy capture (sigma estimated from its residuals)
    capture = simulate(scenario, rng=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        single = refine_parameters(
            capture,
            ParameterSet(robot=problem.robot, values=problem.noise_free_values),
            scenario.plan.reflector,
            tracker_from_base=scenario.tracker_from_base,
            settings=RefinementSettings(estimate_base=False),
        )
    ratio = result.summary.std_uncertainty[mask] / single.uncertainty.standard_uncertainty[mask]
    # sigma from 405 - 20 residual dof (+-3.6 %) and U(L) varying a few % over the points; 2.2 % MC error
    assert np.all(np.abs(ratio - 1.0) < 0.15), ratio


@pytest.mark.parametrize("model", ["cpa", "refined", "distances"])
def test_draws_are_bit_identical_for_any_batch_size(laser, distances, model):
    scenario, refined = laser
    if model == "distances":
        problem, sizes = distances, (1, 3)
    else:
        problem = refined if model == "refined" else monte_carlo_problem(scenario)
        sizes = (1, 2, 3)
    reference = draw_block(problem, seed=9, block=2, n_draws=7, batch_size=7)
    for batch_size in sizes:
        np.testing.assert_array_equal(draw_block(problem, seed=9, block=2, n_draws=7, batch_size=batch_size), reference)


def test_draws_that_do_not_converge_are_counted_and_left_out(laser):
    _, problem = laser
    impatient = dataclasses.replace(problem, refined=dataclasses.replace(problem.refined, max_iterations=3))
    # the per-draw solve's evaluation limit (the Gauss-Newton draws converge in 2 evaluations here)
    settings = MonteCarloSettings(iterations=200, batch_size=100, refined_solver="per-draw")
    result = run_monte_carlo(impatient, settings, seed=1, linearised=False)
    assert 0 < result.n_failed < 200
    assert result.n_draws + result.n_failed == 200
    assert np.isfinite(result.draws).all()
    assert "did not converge" in result.message and not result.success
    # the kept draws are exactly the ones the patient engine computes for those draws
    full = run_monte_carlo(problem, settings, seed=1, linearised=False)
    kept = np.isin(full.draws[:, 2, 2], result.draws[:, 2, 2])
    assert kept.sum() == result.n_draws


def test_files_name_the_model(laser, tmp_path):
    _, problem = laser
    result = run_monte_carlo(problem, MonteCarloSettings(iterations=100, batch_size=100), seed=2, linearised=False)
    write_uncertainty_json(tmp_path / "p.json", result, scenario={}, versions={})
    document = json.loads((tmp_path / "p.json").read_text())
    assert document["model"] == "refined" and document["criterion"] == "points"
    assert "refinement" in document["method"] and document["failed_draws"] == 0
    write_uncertainty_csv(tmp_path / "p.csv", result)
    assert {row["model"] for row in read_uncertainty_csv(tmp_path / "p.csv")} == {"refined"}


def test_adaptive_mode_runs_the_refined_model_in_seeded_blocks(laser):
    _, problem = laser
    settings = MonteCarloSettings(adaptive=True, block_size=100, max_draws=300, ndig=1, batch_size=100)
    result = run_monte_carlo(problem, settings, seed=4, linearised=False)
    assert result.adaptive is not None and result.n_draws % 100 == 0 and result.n_draws >= 200
    # the kept draws are the fixed-mode draws of the same seed and blocks
    fixed = run_monte_carlo(
        problem, MonteCarloSettings(iterations=result.n_draws, block_size=100), seed=4, linearised=False
    )
    np.testing.assert_array_equal(result.draws, fixed.draws)


def test_refined_draws_come_in_blocks_of_a_thousand_that_any_number_of_workers_shares(laser):
    """A refined draw costs tens of CPA draws: by default a fixed number of them is cut into blocks of
    REFINED_BLOCK_SIZE (so that the demo's 5,000 draws keep every worker busy), the CPA model's and the adaptive
    procedure's into JCGM 101's 10^4; the size used is recorded, and the draws do not depend on the workers."""
    scenario, problem = laser
    one = run_monte_carlo(problem, MonteCarloSettings(iterations=1_500, workers=1), seed=6, linearised=False)
    assert one.settings.block_size == REFINED_BLOCK_SIZE == 1_000
    two = run_monte_carlo(problem, MonteCarloSettings(iterations=1_500, workers=2), seed=6, linearised=False)
    np.testing.assert_array_equal(two.draws, one.draws)
    # blocks 0 and 1 of 1,000 and 500 draws: the second block's draws are its own seeded stream
    assert one.n_failed == 0
    np.testing.assert_array_equal(
        one.draws[1_000:1_007].reshape(7, -1), draw_block(problem, seed=6, block=1, n_draws=7, batch_size=7)
    )
    cpa = run_monte_carlo(monte_carlo_problem(scenario), MonteCarloSettings(iterations=100), seed=6, linearised=False)
    assert cpa.settings.block_size == DEFAULT_BLOCK_SIZE == 10_000
    adaptive = MonteCarloSettings(adaptive=True)
    assert adaptive.block_size is None and adaptive.max_draws >= 2 * DEFAULT_BLOCK_SIZE
