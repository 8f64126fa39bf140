"""Limits checked before work starts: the seed bound, the seeds and draws of a run, and memory estimates of
the large computations.

Only the standard library and :mod:`robotcal.errors` are imported, so the command line can check its options
(and show its help) before it imports numpy.
"""

from __future__ import annotations

from robotcal.errors import InputError

__all__ = [
    "BYTES_PER_POSE",
    "FALLBACK_MEMORY",
    "ISO_CYCLES",
    "REFINED_DRAWS",
    "SEED_BOUND",
    "SEED_OFFSETS",
    "available_memory",
    "check_memory",
    "monte_carlo_bytes",
    "pairs_bytes",
]

#: Seeds are integers in ``[0, SEED_BOUND)``: numpy's ``SeedSequence`` takes any non-negative integer,
#: but seeds are recorded in files as signed 64-bit integers (``draws.npz``), so 2^63 is the bound.
SEED_BOUND = 2**63
#: Offsets of the seeds a run derives from ``seed=N`` (:func:`robotcal.pipeline.plan_run`): every random
#: part of the run gets its own, so a run's seed is at most ``SEED_BOUND - 1 - max(SEED_OFFSETS.values())``.
SEED_OFFSETS = {"capture": 0, "truth": 1, "validation": 2, "montecarlo": 3, "workspace": 4, "iso9283": 5, "poses": 6}
#: Refined-model Monte Carlo draws of a run unless the option or the scenario says otherwise (at most the CPA
#: Monte Carlo's): each refined draw costs about 20 CPA draws (docs/uncertainty.md).
REFINED_DRAWS = 20_000
#: Cycles of ISO 9283's pose test (the run's iso9283 stage, ``robotcal iso9283-plan``), here so that the
#: command's help names the default without importing numpy (:mod:`robotcal.diagnostics.iso9283` re-exports it).
ISO_CYCLES = 30
#: Memory assumed available when ``/proc/meminfo`` cannot be read [bytes].
FALLBACK_MEMORY = 4 * 2**30
#: Memory per workspace or trajectory pose (readings, nominal and summary arrays) [bytes], generous.
BYTES_PER_POSE = 4096


def available_memory() -> int:
    """Bytes available to a new allocation: ``MemAvailable`` of ``/proc/meminfo``, else
    :data:`FALLBACK_MEMORY`."""
    try:
        with open("/proc/meminfo", encoding="ascii") as stream:
            for line in stream:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return FALLBACK_MEMORY


def _gib(value: float) -> str:
    return f"{value / 2**30:.1f} GiB"


def check_memory(what: str, estimate: float, way_out: str) -> None:
    """Refuse, before any work, a problem whose estimated memory exceeds 80 % of the available memory.

    Raises :class:`InputError` with the estimate, the memory available and ``way_out``.
    """
    available = available_memory()
    if estimate > 0.8 * available:
        raise InputError(f"{what} needs about {_gib(estimate)} of memory but {_gib(available)} is available; {way_out}")


def monte_carlo_bytes(n_draws: int, n_joints: int, n_points: int, *, batch_size: int, workers: int) -> float:
    """Memory estimate of a Monte Carlo [bytes]: the kept draws (n_draws, n_joints, 5) float64 twice
    (draws and the sorted copy of the statistics) plus each worker's block of simulated points
    (batch_size, n_points, 3) with ~20 arrays of intermediates."""
    kept = 2.0 * n_draws * n_joints * 5 * 8
    block = 20.0 * min(batch_size, n_draws) * max(n_points, 1) * 3 * 8
    return kept + max(workers, 1) * block


def pairs_bytes(n_points: int, n_free: int = 0) -> float:
    """Memory estimate of a pairwise-distances problem over ``n_points`` points [bytes]: pair indices,
    two ``pdist`` vectors and the mask (~50 B per pair), plus a Jacobian column per free parameter
    (three copies in the solver)."""
    pairs = n_points * (n_points - 1) / 2
    return pairs * (50.0 + 3 * 8.0 * n_free)
