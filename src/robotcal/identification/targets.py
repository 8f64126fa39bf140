"""Measurement targets: where each measured point sits on the robot (issue 14: several targets per pose).

A :class:`Target` is a named :class:`~robotcal.kinematics.model.ReflectorMount` whose position may
be unknown:

* ``frame="joint"``: per-joint reflectors (the thesis generator's layout, eq. 5-1), always known;
* ``frame="flange"``: a target fixed in the flange frame {n}, ``base_p = F_n r``; with
  ``known=False`` its offset ``r`` [mm] is estimated by the refinement, starting from ``position``
  (the guess, the flange origin by default).

A capture with a ``target`` column names, per point, one of the scenario's targets;
:func:`resolve_targets` maps those names to :class:`Target` objects (an :class:`InputError` names the
unknown ones).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.kinematics.model import ReflectorMount

__all__ = ["SESSION_SEPARATOR", "Target", "resolve_targets", "point_target_index", "split_by_session"]


@dataclass(frozen=True, slots=True, kw_only=True)
class Target:
    """A named target.

    Attributes
    ----------
    name : str
    frame : {"joint", "flange"}
    positions : ndarray
        ``(n_joints, 3)`` for per-joint reflectors (row i in frame {i-1}, turned by q_i), ``(3,)`` for a
        flange target (frame {n}) [mm]; for an unknown flange offset, the start of its estimate.
    known : bool
        False: a flange offset the refinement estimates.
    per_session : bool
        An unknown flange offset that is re-seated between measurement sessions (issue 29): each session of a
        capture with a ``session`` column has its own offset, named ``NAME@SESSION`` (:func:`split_by_session`).
    """

    name: str
    frame: str
    positions: np.ndarray
    known: bool = True
    per_session: bool = False

    def __post_init__(self) -> None:
        if self.frame not in ("joint", "flange"):
            raise InputError(f"target {self.name!r}: frame must be 'joint' or 'flange'; got {self.frame!r}")
        positions = np.asarray(self.positions, dtype=float)
        if self.frame == "flange":
            positions = positions.reshape(-1)
            if positions.shape != (3,):
                raise InputError(f"target {self.name!r}: a flange offset is [x, y, z] mm; got shape {positions.shape}")
        elif positions.ndim != 2 or positions.shape[1] != 3:
            raise InputError(f"target {self.name!r}: per-joint reflectors are rows of [x, y, z] mm")
        if not np.all(np.isfinite(positions)):
            raise InputError(f"target {self.name!r}: positions must be finite")
        if self.frame == "joint" and not self.known:
            raise InputError(f"target {self.name!r}: only a flange target's offset can be unknown")
        if self.per_session and self.known:
            raise InputError(f"target {self.name!r}: only an unknown flange offset can differ per session")
        object.__setattr__(self, "positions", _frozen(positions))

    @property
    def mount(self) -> ReflectorMount:
        """The reflector mount at the target's (known or guessed) position."""
        return ReflectorMount(frame=self.frame, positions=self.positions)

    @classmethod
    def from_mount(cls, mount: ReflectorMount, name: str = "target") -> Target:
        positions = mount.positions[0] if mount.frame == "flange" else mount.positions
        return cls(name=name, frame=mount.frame, positions=positions)

    def with_position(self, position: ArrayLike) -> Target:
        """The same target at another flange offset (e.g. the refined estimate), still marked unknown."""
        return Target(
            name=self.name, frame=self.frame, positions=np.asarray(position), known=self.known, per_session=self.per_session
        )


#: Separates a re-seated target's name from its session's in the name of its per-session offset.
SESSION_SEPARATOR = "@"


def split_by_session(capture: Capture, targets: Sequence[Target]) -> tuple[Capture, tuple[Target, ...]]:
    """The capture and targets with every ``per_session`` target split into one target per session.

    A point of session ``S`` on a re-seated target ``A`` is then on target ``A@S`` (an unknown offset of its own,
    starting at ``A``'s guess); the other targets and a capture without ``session`` column come back unchanged.
    """
    split = [target for target in targets if target.per_session]
    if capture.session is None or capture.target is None or not split:
        return capture, tuple(targets)
    labels = list(capture.point_targets or ())
    sessions = capture.point_sessions or ()
    names = {target.name for target in split}
    labels = [f"{label}{SESSION_SEPARATOR}{session}" if label in names else label for label, session in
              zip(labels, sessions, strict=True)]  # fmt: skip
    used = tuple(dict.fromkeys(labels))
    lookup = {name: k for k, name in enumerate(used)}
    relabelled = replace(capture, target=np.array([lookup[label] for label in labels], dtype=int), target_names=used)
    expanded: list[Target] = []
    for target in targets:
        if target.per_session:
            for session in capture.session_names:
                expanded.append(replace(target, name=f"{target.name}{SESSION_SEPARATOR}{session}", per_session=False))
        else:
            expanded.append(target)
    return relabelled, tuple(expanded)


def point_target_index(capture: Capture, targets: Sequence[Target]) -> np.ndarray:
    """0-based index into ``targets`` of the target of every point.

    Without a ``target`` column every point is on ``targets[0]`` (only one target may be given then);
    with one, each name must be one of the targets' names.
    """
    if capture.target is None:
        if len(targets) != 1:
            raise InputError(
                f"{capture.source}: the capture has no `target` column, but {len(targets)} targets are given "
                f"({', '.join(t.name for t in targets)}): add a `target` column naming each point's target"
            )
        return np.zeros(capture.n_points, dtype=int)
    lookup = {target.name: k for k, target in enumerate(targets)}
    missing = [name for name in capture.target_names if name not in lookup]
    if missing:
        rows = np.flatnonzero(np.isin(capture.target, [capture.target_names.index(m) for m in missing]))
        raise InputError(
            f"{capture.source}: point {rows[0] + 1} names target {missing[0]!r}, which is not declared "
            f"(declared: {', '.join(lookup) or 'none'}); declare it in the scenario's [[targets]]"
        )
    mapping = np.array([lookup[name] for name in capture.target_names], dtype=int)
    return mapping[capture.target]


def resolve_targets(capture: Capture, targets: Sequence[Target]) -> tuple[tuple[Target, ...], np.ndarray]:
    """The targets the capture uses (in ``targets`` order) and each point's index into them."""
    index = point_target_index(capture, targets)
    used = np.unique(index)
    remap = np.full(len(targets), -1)
    remap[used] = np.arange(used.size)
    return tuple(targets[k] for k in used), remap[index]
