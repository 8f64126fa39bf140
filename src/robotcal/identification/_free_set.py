"""Which quantities a refinement estimates: the rank test on the column-scaled Jacobian of every candidate, and the
names of what it holds (gauge, held, confounded), with the warning or error that reports them.

The module notes of :mod:`robotcal.identification.refine` give the documented order of the test and the cases.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from robotcal.errors import IdentifiabilityError, IdentifiabilityWarning, InputError
from robotcal.identification._problem import BASE_NAMES, Problem, Setup
from robotcal.identification.observability import select_identifiable, triangular_factor
from robotcal.kinematics.model import PARAMETER_KINDS

__all__ = ["Selection", "HeldNames", "check_free", "select_free", "selection_key", "describe_held", "report_held"]

_SAMPLE_ROWS = 8192  # residuals sampled for the null space at the generic point
_SUPPORT = 1e-8  # a null vector's entry (unit columns) above this ties a free quantity to a held one


def check_free(free, robot) -> np.ndarray | None:
    if free is None:
        return None
    if isinstance(free, (list, tuple)) and all(isinstance(name, str) for name in free):
        names = robot.parameter_names
        unknown = [name for name in free if name not in names]
        if unknown:
            raise InputError(f"`free` names unknown parameters {unknown}; expected names like 'J2.beta'")
        mask = np.array([name in free for name in names]).reshape(robot.n_joints, 5)
    else:
        mask = np.asarray(free)
        if mask.shape != (robot.n_joints, 5) or mask.dtype != bool:
            raise InputError(
                f"`free` must be None, parameter names, or a bool array of shape ({robot.n_joints}, 5); got {mask.shape}"
            )
    fixed = mask & robot.structurally_fixed
    if np.any(fixed):
        names = [n for n, flag in zip(robot.parameter_names, fixed.ravel(), strict=True) if flag]
        raise InputError(f"`free` frees parameters the model fixes at 0: {', '.join(names)}")
    return mask


def _rigid_motion_fields(points: np.ndarray, angle_scale: float) -> np.ndarray:
    """Orthonormal basis ``(3 n_points, <= 6)`` of the velocity fields of the rigid motions of ``points``.

    Translations ``e_k`` and rotations ``e_k x (p - centroid)`` (scaled by ``angle_scale``); a
    parameter whose effect on the points lies in this span moves the whole cloud rigidly.
    """
    centred = points - points.mean(axis=0)
    fields = np.zeros((points.shape[0], 3, 6))
    for k in range(3):
        axis = np.zeros(3)
        axis[k] = 1.0
        fields[:, k, k] = 1.0
        fields[:, :, 3 + k] = np.cross(axis, centred) * angle_scale
    matrix = fields.reshape(-1, 6)
    u, s, _ = np.linalg.svd(matrix, full_matrices=False)
    return u[:, s > s[0] * 1e-12]


@dataclass(frozen=True, slots=True, kw_only=True)
class Selection:
    """Outcome of the rank test on the full candidate set (module notes)."""

    free: np.ndarray  # (n, 5) bool: parameters estimated
    extra_free: np.ndarray  # (m,) bool: joint-model values estimated
    offset_free: np.ndarray  # (3 k,) bool: unknown offset components estimated
    base_free: np.ndarray  # (6,) bool: base corrections estimated
    held: np.ndarray  # (n, 5) bool: candidate parameters held, gauge ones included
    extra_held: np.ndarray  # (m,) bool
    offset_held: np.ndarray  # (3 k,) bool
    base_held: np.ndarray  # (6,) bool: candidate base corrections held
    gauge: np.ndarray  # (n, 5) bool: held because they move the whole point cloud rigidly
    confounded: np.ndarray  # (5 n + m + 3 k + 6,) bool: free quantities tied to a held one


def _null_support(matrix: np.ndarray, dimension: int) -> np.ndarray:
    """Columns of ``matrix`` (scaled to unit norm) that enter its ``dimension`` smallest right singular vectors."""
    if dimension <= 0:
        return np.zeros(matrix.shape[1], dtype=bool)
    _, _, vt = np.linalg.svd(matrix / np.linalg.norm(matrix, axis=0), full_matrices=True)
    return np.abs(vt[-dimension:]).max(axis=0) > _SUPPORT


def selection_key(selection: Selection) -> bytes:
    """What a selection estimates, comparable across rank tests."""
    return np.r_[selection.free.ravel(), selection.extra_free, selection.offset_free, selection.base_free].tobytes()


def select_free(
    probe: Problem,
    candidates: np.ndarray,
    all_scale: np.ndarray,
    tolerance: float,
    jacobian: np.ndarray | None = None,
    preferred: Selection | None = None,
) -> Selection:
    """Rank test at ``probe.x0()`` (the start, or a solution) on every candidate column (parameters, joint-model
    values, unknown offsets, base corrections); ``jacobian``: ``probe``'s Jacobian there when already evaluated.

    Columns are taken base corrections first, then the unknown flange offsets, then the parameters of
    joints 1..n in the order d, theta, a, alpha, beta (:func:`select_identifiable`), then the joint-model values:
    of a dependent group the earlier ones stay free, so a parameter equivalent to a base motion is held and the
    base correction kept, a joint-model term that only repeats a geometric parameter's effect is held, and joint
    n's d, theta, a, alpha, which only move the flange frame that unknown offsets are expressed in, are held in
    favour of the offsets (the flange frame stays nominal; the offsets are estimated in it); so is a parameter of
    joints 1..n-1 that only an offset's rough guess would otherwise absorb (a target on axis n). ``preferred``
    (at a solution: the free set in use) puts its columns first, each part in that order, so that a free quantity
    is dropped only when it is not determined and a held one freed only when it adds to the rank.

    ``candidates`` ``(5 n + m,)``: the parameters and joint-model values that may be free; ``all_scale``
    ``(5 n + m + 6,)``: the column scale of the parameters, the joint-model values and the base corrections.
    """
    n = probe.free.shape[0]
    m = probe.extra_free.size
    n_off = probe.offset_free.size
    n_base = int(probe.base_free.sum())
    own = 5 * n + m  # parameter and joint-model columns
    first = None  # the columns of ``preferred``, in the column order below
    if preferred is not None:
        first = np.r_[
            preferred.free.ravel(), preferred.extra_free, preferred.offset_free, preferred.base_free[probe.base_free]
        ]
    # columns: 5 n parameters, m joint-model values, 3 k offsets, then the candidate base ones
    jac_all = probe.evaluate(probe.x0())[1] if jacobian is None else jacobian
    scale = np.concatenate([all_scale[:own], np.ones(n_off), all_scale[own:][probe.base_free]])
    scaled = triangular_factor(jac_all * scale)
    chosen = np.r_[candidates, np.ones(n_off + n_base, dtype=bool)]
    order = np.r_[
        np.arange(own + n_off, own + n_off + n_base),
        np.arange(own, own + n_off),
        np.arange(5 * n),
        np.arange(5 * n, own),
    ]
    if first is not None:  # the free set being checked first, each part in the documented order
        order = np.r_[order[first[order]], order[~first[order]]]
    keep = np.zeros(chosen.size, dtype=bool)
    keep[order] = select_identifiable(scaled[:, order], chosen[order], tolerance=tolerance)
    held_all = chosen & ~keep

    confounded = _confounded(probe, scaled, scale, chosen, keep, tolerance)
    held = held_all[: 5 * n].reshape(n, 5)
    rigid_blind = n_base or probe.criterion == "distances"  # a free base frame or distances: a rigid motion is unseen
    gauge = _gauge(probe, held, all_scale, tolerance) if rigid_blind else np.zeros((n, 5), dtype=bool)
    base_keep = np.zeros(6, dtype=bool)
    base_keep[probe.base_free] = keep[own + n_off :]
    base_held = probe.base_free & ~base_keep
    base_confounded = np.zeros(6, dtype=bool)
    base_confounded[probe.base_free] = confounded[own + n_off :]
    return Selection(
        free=keep[: 5 * n].reshape(n, 5),
        extra_free=keep[5 * n : own],
        offset_free=keep[own : own + n_off],
        base_free=base_keep,
        held=held,
        extra_held=held_all[5 * n : own],
        offset_held=held_all[own : own + n_off],
        base_held=base_held,
        gauge=gauge,
        confounded=np.r_[confounded[: own + n_off], base_confounded],
    )


def _confounded(probe: Problem, scaled, scale, chosen, keep, tolerance: float) -> np.ndarray:
    """Free quantities whose estimate depends on a held one: the support of the null space of the scaled candidate
    columns ``scaled``, taken at the probe's point and at a generic point near it (every candidate moved by up to
    one scale unit, a fixed seed): at the point itself special values (alpha = 0, a target on an axis) can hide a
    coupling that is of second order there but still moves the free parameter once the held one is off its truth."""
    norms = np.linalg.norm(scaled, axis=0)
    live = chosen & (norms > tolerance * max(float(norms[chosen].max(initial=0.0)), 1e-300))  # as the selection
    confounded = np.zeros(chosen.size, dtype=bool)
    n_null = int(live.sum() - keep.sum())
    if n_null <= 0:
        return confounded
    generic = probe.x0() + np.where(chosen, np.random.default_rng(0).uniform(-1.0, 1.0, chosen.size), 0.0) * scale
    # (a strided sample of the pairs: the null space of a few thousand generic rows is that of all)
    moved = triangular_factor(probe.jacobian_sample(generic, _SAMPLE_ROWS) * scale)[:, live]
    # the generic point keeps the structural dependencies but can lose those of the probe's own geometry
    # (a fitted target on axis n): its null space is at most n_null wide, as wide as its rank says, and the
    # null space at the probe point itself is taken too
    n_generic = min(
        n_null,
        int(live.sum()) - int(select_identifiable(moved, np.ones(moved.shape[1], bool), tolerance=tolerance).sum()),
    )
    support = _null_support(moved, n_generic) | _null_support(scaled[:, live], n_null)
    confounded[np.flatnonzero(live)[support]] = True
    return confounded & keep


def _gauge(probe: Problem, held: np.ndarray, all_scale: np.ndarray, tolerance: float) -> np.ndarray:
    """Held parameters ``(n, 5)`` whose effect is a (non-zero) rigid motion of the whole point cloud, which a free
    base frame absorbs and pairwise distances do not see."""
    n = held.shape[0]
    if not np.any(held):
        return np.zeros((n, 5), dtype=bool)
    points, point_jac = probe.base_jacobian(probe.unpack_all(probe.x0()))
    columns = point_jac[:, :, : 5 * n].reshape(-1, 5 * n) * all_scale[: 5 * n]
    basis = _rigid_motion_fields(points, float(all_scale[1]))
    size = np.linalg.norm(columns, axis=0)
    outside = np.linalg.norm(columns - basis @ (basis.T @ columns), axis=0)
    rigid = (size > 1e-12 * max(float(size.max()), 1e-300)) & (outside <= tolerance * size)
    return held & rigid.reshape(n, 5)


@dataclass(frozen=True, slots=True)
class HeldNames:
    """The gauge, held and confounded quantities of a selection (names), and those the layout holds anyway
    (``accepted``: ``strict`` only reports them)."""

    gauge: tuple[str, ...]
    held: tuple[str, ...]
    confounded: tuple[str, ...]
    flange_frame: str
    accepted: tuple[str, ...]


def describe_held(setup: Setup, chosen: Selection) -> HeldNames:
    robot = setup.start.robot
    names, n = robot.parameter_names, robot.n_joints
    gauge = tuple(name for name, flag in zip(names, chosen.gauge.ravel(), strict=True) if flag)
    held_mask = chosen.held & ~chosen.gauge
    held = (
        tuple(name for name, flag in zip(names, held_mask.ravel(), strict=True) if flag)
        + tuple(name for name, flag in zip(setup.extra_names, chosen.extra_held, strict=True) if flag)
        + tuple(name for name, flag in zip(setup.offset_names, chosen.offset_held, strict=True) if flag)
        + tuple(BASE_NAMES[k] for k in np.flatnonzero(chosen.base_held))
    )
    every = names + setup.extra_names + setup.offset_names + BASE_NAMES
    confounded = tuple(name for name, flag in zip(every, chosen.confounded, strict=True) if flag)
    flange_frame = _flange_frame_note(setup.probe.targets, setup.probe.unknown, held_mask, n)
    # what any capture of the layout holds: a gauge (a free base frame or distances cannot see a rigid motion),
    # and joint n's parameters, never all determined (behind its own reflector, none of d, theta, a, alpha; behind
    # flange targets, alpha_n, or all four when every offset is unknown): --strict reports them, refusing only
    # what this capture fails to determine (an explicit free set is refused whatever it holds)
    accepted = () if setup.explicit else gauge + tuple(f"J{n}.{kind}" for kind in PARAMETER_KINDS)
    return HeldNames(gauge, held, confounded, flange_frame, accepted)


def _flange_frame_note(targets, unknown, held_mask, n) -> str:
    """Why joint n's parameters are held when every flange target's offset is unknown (empty otherwise:
    with a known flange target, joint n's alpha is held as with the historical single flange target)."""
    known = [t.name for t in targets if t.frame == "flange" and t.known]
    if not unknown or known or not held_mask[n - 1].any():
        return ""
    names = ", ".join(f"J{n}.{kind}" for kind, flag in zip(PARAMETER_KINDS, held_mask[n - 1], strict=True) if flag)
    unknown_names = ", ".join(targets[t].name for t in unknown)
    return (
        f"every flange target's offset is unknown, so the flange frame {{{n}}} is not determined by the data: an "
        f"unknown offset is confounded with J{n}'s d, theta, a, alpha (a change of those moves the flange frame, "
        f"which the offsets absorb); {names} are held at their start values and the offsets of {unknown_names} "
        "are estimated in that flange frame"
    )


def report_held(
    setup: Setup,
    verdict: HeldNames,
    *,
    strict: bool,
    where: str = "the solution",
    refits: int = 0,
    unsettled: str = "",
) -> None:
    """Warn about (or, ``strict``, raise for) the quantities the rank test holds.

    ``verdict.accepted``: what the layout holds whatever the capture (a gauge; joint n's parameters): with
    ``strict`` they alone only warn. ``where``: the point
    of the deciding rank test ("the start", "the solution"); ``refits``: how many times the free set changed
    at a solution and the capture was refitted; ``unsettled``: why the free set did not settle, if so.
    """
    gauge, held, still = verdict.gauge, verdict.held, setup.still
    parts = []
    if gauge:
        why = (
            "a free base frame absorbs them (tracker_from_base is estimated)"
            if setup.use_base
            else "pairwise distances do not see them"
        )
        parts.append(f"{', '.join(gauge)} move the whole point cloud rigidly, a rigid motion of the base: {why}")
    if held:
        detail = f"; joints that never move in the capture: {', '.join(still)}" if still else ""
        parts.append(
            f"the {setup.criterion} criterion cannot determine {', '.join(held)} from this capture "
            f"(rank-deficient column-scaled Jacobian at {where}){detail}"
        )
    if refits:
        parts.append(
            f"the rank test at the solution changed the free set, so the capture was refitted ({refits} refit"
            f"{'s' if refits > 1 else ''}) with the quantities it holds back at their start values"
        )
    if verdict.flange_frame:
        parts.append(verdict.flange_frame)
    if unsettled:
        parts.append(unsettled)
    text = f"{setup.capture.source}: " + "; ".join(parts)
    if strict and set(gauge + held) - set(verdict.accepted):
        raise IdentifiabilityError(text, parameters=gauge + held)
    warnings.warn(text + _held_clause(setup, verdict), IdentifiabilityWarning, stacklevel=3)


def _held_clause(setup: Setup, verdict: HeldNames) -> str:
    """The warning's last clause: what is held at its start value, in the number its names need, and not again
    what the flange-frame note already says it holds (joint n's parameters)."""
    n = setup.start.robot.n_joints
    said = {name for name in verdict.held if name.startswith(f"J{n}.")} if verdict.flange_frame else set()
    rest = [name for name in verdict.gauge + verdict.held if name not in said]
    if not rest:
        return ""
    if said:  # the note named joint n's: name the others, so that "they" means no more than these
        return f"; {', '.join(rest)} {'is' if len(rest) == 1 else 'are'} held at {'its start value' if len(rest) == 1 else 'their start values'}"
    return "; it is held at its start value" if len(rest) == 1 else "; they are held at their start values"
