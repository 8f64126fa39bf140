"""The Monte Carlo's draws: seeded blocks of noisy captures, each identified by CPA (and refined).

Block ``b`` draws from its own generators, seeded by ``SeedSequence(seed, spawn_key=(b,))`` (instrument noise and
joint-error noise from separate children), and is consumed in draw order whatever the batch size, so that the same
seed gives the same draws for any ``batch_size``, number of workers and backend (JCGM 101 §7.9 blocks; the module
notes of :mod:`robotcal.uncertainty.montecarlo`). A refined draw is solved by batched Gauss-Newton around the
noise-free solution (:mod:`robotcal.uncertainty.gauss_newton`) or by the per-draw Levenberg-Marquardt
(:func:`robotcal.uncertainty.refined.refine_batch`).

References
----------
JCGM 101:2008 §6.4 (drawing from the input distributions), §7.9; thesis ch. 5.2.3.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Literal

import numpy as np

from robotcal.errors import RobotcalError
from robotcal.execution import check_stop
from robotcal.geometry.transforms import apply_transform
from robotcal.identification.cpa import identify_cpa_batch
from robotcal.kinematics.forward import target_positions
from robotcal.uncertainty.montecarlo_problem import MonteCarloProblem

if TYPE_CHECKING:
    from robotcal.uncertainty.refined_kernel import RefinedModel

__all__ = ["draw_block"]

#: The refined Monte Carlo's solvers (:attr:`robotcal.uncertainty.montecarlo.MonteCarloSettings.refined_solver`).
RefinedSolver = Literal["gauss-newton", "per-draw"]

#: Draws refined per vectorised call (bounds the refinement's working memory whatever ``batch_size``).
REFINE_BATCH = 500
#: The same for an extended model, refined point by point (:class:`robotcal.uncertainty.refined_kernel._PointBatch`): its
#: working arrays are ``(3, batch, points)``; at 32 draws x 300 points they stay a few hundred kB, which the cache
#: and the allocator reuse (faster per draw than batches of 100: the record in benchmarks/bench_extended.py).
EXTENDED_REFINE_BATCH = 32
#: The same for the extended model's Gauss-Newton draws, whose corrective steps form no per-point Jacobian (arrays of
#: ``(3, batch, points)`` only): 64 draws take about 7 % less CPU per draw than 32 (issue 31's record in
#: benchmarks/bench_refined_montecarlo.py).
EXTENDED_GAUSS_NEWTON_BATCH = 64


def _block_generators(seed: int, block: int) -> tuple[np.random.Generator, np.random.Generator]:
    sequence = np.random.SeedSequence(entropy=seed, spawn_key=(block,))
    instrument_seq, joint_seq = sequence.spawn(2)
    return np.random.default_rng(instrument_seq), np.random.default_rng(joint_seq)


def _noisy_exact_points(problem: MonteCarloProblem, n_draws: int, rng: np.random.Generator) -> np.ndarray:
    """Exact points ``(n_draws, n_points, 3)`` with a fresh draw of the joint errors' random part (on the circles:
    the calibration poses, if any, are simulated without joint errors)."""
    circles = slice(0, problem.n_circle)
    readings = problem.capture.readings[circles]
    q = problem.true_parameters.model_joint_variables(readings)
    commanded = problem.robot.model_joint_variables(readings)  # the joint errors follow the commanded motion
    assert problem.joint_errors is not None  # called only for a problem with joint errors
    errors = np.stack([problem.joint_errors.transforms(commanded, rng=rng) for _ in range(n_draws)])
    base = target_positions(
        problem.true_parameters.values,
        q,
        problem.capture.circle[circles] - 1,
        problem.structure.reflector,
        joint_errors=errors,
    )
    out = np.broadcast_to(problem.exact_points, (n_draws,) + problem.exact_points.shape).copy()
    out[:, circles] = apply_transform(problem.tracker_from_base, base)
    return out


def _noise(
    problem: MonteCarloProblem, n_draws: int, rng: np.random.Generator, out: np.ndarray | None = None
) -> np.ndarray:
    """Instrument errors ``(n_draws, n_points, 3)`` [mm], draw-major from ``rng``; written into ``out`` if given.

    Uniform noise is ``rng.random`` mapped to ``2 u - 1`` in place: the very numbers (and the same
    generator state) as ``rng.uniform(-1, 1)``, which computes ``-1 + 2 u`` element by element (``2 u`` is
    exact), in fewer passes and into a buffer that the caller reuses batch after batch (a fresh array of
    millions of numbers costs its page faults every time).
    """
    shape = (n_draws, problem.n_points, 3)
    noise = np.empty(shape) if out is None else out
    if problem.instrument.is_noise_free:
        noise[...] = 0.0
        return _add_repeatability(problem, noise, rng)
    # The bound of every coordinate as one row of 3 n_points numbers: the in-place product then runs
    # along whole draws rather than 3 numbers at a time (the same products, in long inner loops).
    bound = np.repeat(problem.error_bound, 3)
    if problem.instrument.noise == "uniform":
        rng.random(out=noise)
        noise *= 2.0
        noise -= 1.0
    else:
        rng.standard_normal(out=noise)
        bound = bound / problem.instrument.coverage_factor
    flat = noise.reshape(n_draws, -1)  # a view: the product is made in place (millions of numbers)
    flat *= bound
    return _add_repeatability(problem, noise, rng)


def _add_repeatability(problem: MonteCarloProblem, noise: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The robot's pose scatter (the noise budget), isotropic normal of ``problem.repeatability_sd`` per coordinate,
    added to ``noise`` in place, drawn after the instrument's errors from the same generator (none when 0: the
    draws of a problem without it are unchanged)."""
    if problem.repeatability_sd > 0.0:
        noise += problem.repeatability_sd * rng.standard_normal(noise.shape)
    return noise


def draw_block(
    problem: MonteCarloProblem,
    seed: int,
    block: int,
    n_draws: int,
    batch_size: int,
    *,
    refined_solver: RefinedSolver = "gauss-newton",
) -> np.ndarray:
    """The outputs of the ``n_draws`` draws of block ``block``, one row per draw, shape ``(n_draws, 5 n + m)``:
    the parameters ``d, theta, a, alpha, beta`` joint by joint [mm, rad], then the joint model's ``m`` values of
    an extended refined model (``m = 0`` otherwise; ``.reshape(-1, n, 5)`` gives the parameters).

    A draw whose refinement did not converge (``model="refined"``) is a row of NaN: the driver
    counts and drops it. The noise is drawn draw by draw from the block's generators, and every
    computation on a batch is per draw, so a draw's value does not depend on ``batch_size``; a lone
    draw is computed as a batch of two (itself twice), because numpy reduces a stack of one with
    other loops than a larger stack (last-bit differences). ``refined_solver``: see :class:`MonteCarloSettings`.
    """
    instrument_rng, joint_rng = _block_generators(seed, block)
    values = np.empty((n_draws, 5 * problem.robot.n_joints + problem.n_extra))
    chunks = _chunks(n_draws, batch_size)
    buffer = np.empty((max((count for _, count in chunks), default=0), problem.n_points, 3))  # every batch's points
    for start, count in chunks:
        check_stop()  # a pool worker: end the block when the pool stops; this process: an interrupt Python dropped
        if problem.joint_errors is not None:
            exact = _noisy_exact_points(problem, count, joint_rng)
        else:
            exact = problem.exact_points
        points = _noise(problem, count, instrument_rng, out=buffer[:count])
        points += exact  # noise + exact, in place (the same numbers as exact + noise)
        try:
            result = solve_points(problem, points, refined_solver)
        except RobotcalError as exc:
            raise type(exc)(f"Monte Carlo block {block}, draws {start}..{start + count - 1}: {exc}") from None
        values[start : start + count] = result[:count]
    return values


def solve_points(problem: MonteCarloProblem, points: np.ndarray, solver: str = "gauss-newton") -> np.ndarray:
    """The outputs (rows as :func:`draw_block`'s) of captures whose measured points are ``points (k, n_points, 3)``
    [mm]: what a draw computes (CPA of the circles, then the refinement by ``solver``), for drawn or given points
    (a noise-free capture of other joint errors, say). A lone capture is solved as a batch of two (itself twice):
    numpy reduces a stack of one with other loops than a larger stack."""
    points = np.asarray(points, dtype=float)
    count = points.shape[0]
    if count == 1:
        points = np.concatenate([points, points])
    batch = identify_cpa_batch(points[:, : problem.n_circle], problem.structure, problem.tracker_from_base, residuals=False)
    result = batch.values.reshape(batch.values.shape[0], -1)
    if problem.refined is not None:
        result = _refine_draws(problem.refined, points, batch, solver)
    return result[:count]


def _refine_draws(model: RefinedModel, points: np.ndarray, batch, solver: str = "gauss-newton") -> np.ndarray:
    """Refine every CPA draw of ``batch``, ``REFINE_BATCH`` draws at a time (fewer for an extended model, whose
    per-point Jacobian takes ~30 times the memory): the rows of :func:`draw_block`. ``solver``: batched
    Gauss-Newton around the noise-free solution, or Levenberg-Marquardt from every draw's CPA estimate."""
    from robotcal.uncertainty.gauss_newton import refine_draws_gauss_newton
    from robotcal.uncertainty.refined import refine_batch

    solve = refine_draws_gauss_newton if solver == "gauss-newton" else refine_batch

    n_draws = batch.values.shape[0]
    m = 0 if model.joint_model is None else model.joint_model.size
    out = np.empty((n_draws, batch.values[0].size + m))
    if model.joint_model is None:
        size = REFINE_BATCH
    else:
        size = EXTENDED_GAUSS_NEWTON_BATCH if solver == "gauss-newton" else EXTENDED_REFINE_BATCH
    for start, count in _chunks(points.shape[0], size):
        part = slice(start, start + count)
        refined = solve(model, points[part], batch.values[part], batch.tracker_from_base[part])
        out[part] = np.concatenate([refined.values.reshape(count, -1), refined.extras], axis=1)
    return out


def _chunks(n_draws: int, batch_size: int) -> list[tuple[int, int]]:
    """``(start, count)`` of the vectorised calls over a block, never a lone draw after a full batch.

    numpy reduces a batch of one with other loops than a larger batch (last-bit differences), so a
    trailing single draw joins the previous batch: every draw is then computed identically for any
    ``batch_size`` and the same seed gives bit-identical results.
    """
    chunks = [(start, min(batch_size, n_draws - start)) for start in range(0, n_draws, batch_size)]
    if len(chunks) > 1 and chunks[-1][1] == 1:
        start, count = chunks[-2]
        chunks[-2:] = [(start, count + 1)]
    return chunks


def _block_sizes(total: int, block_size: int) -> list[int]:
    full, rest = divmod(total, block_size)
    return [block_size] * full + ([rest] if rest else [])


def _draw_task(
    problem: MonteCarloProblem, seed: int, batch_size: int, solver: RefinedSolver, item: tuple[int, int]
) -> np.ndarray:
    """One block ``item = (block, size)``: a top-level function, so that any backend can run it."""
    block, size = item
    return draw_block(problem, seed, block, size, batch_size, refined_solver=solver)


class _BlockRunner:
    """Computes blocks on an :class:`robotcal.execution.Executor` (serial, local processes or Dask)."""

    def __init__(self, problem: MonteCarloProblem, seed: int, settings, executor):
        self.task = functools.partial(_draw_task, problem, seed, settings.batch_size, settings.refined_solver)
        self.executor = executor

    def map(self, blocks: list[tuple[int, int]]):
        """Yield ``(block, values)`` in block order."""
        for (block, _), values in zip(blocks, self.executor.map(self.task, blocks), strict=True):
            yield block, values
