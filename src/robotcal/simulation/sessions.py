"""A capture measured over several sessions (tracker stations, days; issue 29): each session its own base frame,
and a target re-seated between sessions its own true offset."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robotcal.capture import Capture, join_captures
from robotcal.errors import InputError
from robotcal.instruments import Instrument
from robotcal.kinematics.model import ParameterSet, RobotModel
from robotcal.simulation.generator import simulate_target_poses

__all__ = ["SimulatedSession", "simulate_sessions"]


@dataclass(frozen=True, slots=True, kw_only=True)
class SimulatedSession:
    """One session of a simulated capture.

    Attributes
    ----------
    name : str
        The session's name (the ``session`` column).
    readings : ndarray, shape (n_poses, n_joints)
        Controller readings of its poses [rad].
    tracker_from_base : ndarray, shape (4, 4)
        Where the tracker stood [mm].
    true_offsets : ndarray, shape (n_targets, 3)
        The targets' true flange offsets in this session [mm] (a re-seated target differs between sessions).
    """

    name: str
    readings: np.ndarray
    tracker_from_base: np.ndarray
    true_offsets: np.ndarray


def simulate_sessions(
    robot: RobotModel,
    sessions: Sequence[SimulatedSession],
    targets: Sequence,
    instrument: Instrument,
    *,
    true_parameters: ParameterSet | None = None,
    u95_mm: float | None = None,
    rng: np.random.Generator | int | None = None,
) -> tuple[Capture, np.ndarray]:
    """Every session's poses measured on every flange target (:func:`simulate_target_poses`), joined in session
    order with a ``session`` column.

    Returns
    -------
    capture : Capture
    exact_points : ndarray, shape (n_points, 3)
        The noise-free points [mm], each in its session's tracker frame.
    """
    if not sessions:
        raise InputError("simulate_sessions needs at least one session")
    rng = np.random.default_rng(rng)
    parts, exact = [], []
    for session in sessions:
        capture, points = simulate_target_poses(
            robot, session.readings, targets, instrument, session.tracker_from_base, true_parameters=true_parameters,
            true_offsets=session.true_offsets, u95_mm=u95_mm, rng=rng,
        )  # fmt: skip
        parts.append((capture.with_session(session.name), None))
        exact.append(points)
    return join_captures(parts, source="simulated sessions"), np.concatenate(exact)
