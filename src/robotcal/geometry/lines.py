"""Plücker lines and the adjacent-line analysis of Circle Point Analysis (thesis ch. 4.4.2-4.4.4).

A line is ``(S; S0)`` with unit direction ``S`` and moment ``S0 = r x S`` for any point ``r`` of the
line (eqs 4-6..4-8). Everything is batched over leading axes so that a Monte Carlo batch of captures
is analysed in one call. Lengths in mm, angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotcal.errors import DegenerateGeometryError, InputError
from robotcal.geometry._vectors import cross as _cross
from robotcal.geometry._vectors import dot as _dot
from robotcal.geometry._vectors import unit as _unit

__all__ = [
    "PluckerLine",
    "LinePair",
    "PARALLEL_TOLERANCE_RAD",
    "INTERSECTION_TOLERANCE_MM",
    "analyse_dh_pair",
    "analyse_hayati_pair",
    "signed_angle_about",
]

#: Angle between two lines [rad] below which they are exactly parallel (case 4.4.3.3).
PARALLEL_TOLERANCE_RAD = 1e-9
#: Common-normal length [mm] below which two non-parallel lines intersect (case 4.4.3.2).
INTERSECTION_TOLERANCE_MM = 1e-9


@dataclass(frozen=True, slots=True, kw_only=True)
class PluckerLine:
    """Batched Plücker lines ``(S; S0)``.

    Attributes
    ----------
    direction : ndarray, shape (..., 3)
        Unit direction ``S``.
    moment : ndarray, shape (..., 3)
        Moment ``S0 = r x S`` [mm].
    """

    direction: np.ndarray
    moment: np.ndarray

    def __post_init__(self):
        for field in ("direction", "moment"):
            value = np.array(getattr(self, field), dtype=float)
            value.setflags(write=False)
            object.__setattr__(self, field, value)

    @classmethod
    def from_point_direction(cls, point, direction) -> PluckerLine:
        """Line through ``point (..., 3)`` [mm] along ``direction (..., 3)`` (normalised here), eq. 4-7."""
        direction = np.asarray(direction, dtype=float)
        norm = np.linalg.norm(direction, axis=-1, keepdims=True)
        if np.any(norm == 0.0) or not np.all(np.isfinite(direction)):
            raise InputError("a line direction must be a finite non-zero vector")
        direction = direction / norm
        return cls(direction=direction, moment=_cross(np.asarray(point, dtype=float), direction))

    @property
    def point(self) -> np.ndarray:
        """Point of the line closest to the origin, ``S x S0`` [mm]."""
        return _cross(self.direction, self.moment)

    def transformed(self, transform) -> PluckerLine:
        """The line moved by rigid transforms ``(..., 4, 4)``."""
        transform = np.asarray(transform, dtype=float)
        rotation = transform[..., :3, :3]
        direction = np.einsum("...ij,...j->...i", rotation, self.direction)
        point = np.einsum("...ij,...j->...i", rotation, self.point) + transform[..., :3, 3]
        return PluckerLine(direction=direction, moment=_cross(point, direction))

    def flipped(self, mask) -> PluckerLine:
        """Reverse direction (and moment) where ``mask (...)`` is true."""
        sign = np.where(np.asarray(mask)[..., None], -1.0, 1.0)
        return PluckerLine(direction=self.direction * sign, moment=self.moment * sign)

    def __getitem__(self, index) -> PluckerLine:
        """Index the batch axes (never the coordinate axis): ``lines[..., j]`` is line j of each item."""
        index = (index if isinstance(index, tuple) else (index,)) + (slice(None),)
        return PluckerLine(direction=self.direction[index], moment=self.moment[index])


@dataclass(frozen=True, slots=True, kw_only=True)
class LinePair:
    """Result of the analysis of adjacent axes ``j`` (earlier) and ``k`` (later).

    Attributes
    ----------
    case : ndarray of str, shape (...)
        ``"skew"``, ``"intersecting"``, ``"parallel"`` or ``"nearly-parallel"`` (Hayati, Solution 3).
    normal : ndarray, shape (..., 3)
        Unit vector ``a_jk`` from axis j towards axis k, oriented to agree with the hint (x_j).
    point_j, point_k : ndarray, shape (..., 3)
        Feet of the common normal (Hayati: ``P_j`` and ``P_k`` of Solution 3) [mm].
    length : ndarray, shape (...)
        Signed ``a_jk = (P_k - P_j) . a_jk`` [mm].
    twist : ndarray, shape (...)
        ``alpha_jk`` [rad] (Hayati: ``alpha'``), in (-pi, pi].
    beta : ndarray, shape (...)
        Hayati ``beta_jk`` [rad]; 0 for DH pairs.
    mutual_moment : ndarray, shape (...)
        ``MM = S_j . S0_k + S_k . S0_j`` (eq. 4-22) [mm].
    """

    case: np.ndarray
    normal: np.ndarray
    point_j: np.ndarray
    point_k: np.ndarray
    length: np.ndarray
    twist: np.ndarray
    beta: np.ndarray
    mutual_moment: np.ndarray


def signed_angle_about(from_vector, to_vector, axis) -> np.ndarray:
    """Right-handed angle [rad] from ``from_vector`` to ``to_vector`` about unit ``axis``, (-pi, pi].

    Both vectors are projected on the plane normal to ``axis`` first, so they need not be
    perpendicular to it (eqs 4-92, 4-93 with the dot product, see docs/conventions.md).
    """
    return np.arctan2(
        _dot(_cross(from_vector, to_vector), axis),
        _dot(from_vector, to_vector) - _dot(from_vector, axis) * _dot(to_vector, axis),
    )


def _orient(vector, hint):
    """Flip ``vector`` where it points against ``hint`` (the nominal x axis, "cambia signo ajk")."""
    return np.where((_dot(vector, hint) < 0.0)[..., None], -vector, vector)


def analyse_dh_pair(line_j: PluckerLine, line_k: PluckerLine, *, normal_hint, point_j_if_parallel) -> LinePair:
    """Adjacent-line analysis for a Denavit-Hartenberg joint (thesis 4.4.3, 4.4.5 steps 1, 3, 4).

    - skew lines (``|a_jk| > INTERSECTION_TOLERANCE_MM``): common-normal feet by eqs 4-35 and 4-36
      (4-36 with the corrected term ``(a_jk x S_j) x S0_k``);
    - intersecting lines: the common point of eq. 4-44, ``a_jk = 0``;
    - parallel lines (angle below ``PARALLEL_TOLERANCE_RAD``): ``a'_jk`` by eq. 4-52; the feet are not
      unique, so ``P_j = point_j_if_parallel`` (the caller passes ``P_j^prev + d_j^nom S_j``).

    ``a_jk`` has the direction of ``+-(S_j x S_k)`` that agrees with ``normal_hint`` (the nominal
    x_j axis); the length is signed, ``a = (P_k - P_j) . a_jk``, and
    ``alpha = atan2((S_j x S_k) . a_jk, S_j . S_k)`` (eqs 4-12, 4-13).

    Parameters
    ----------
    line_j, line_k : PluckerLine
        Axes j and k, batched alike, directions oriented as the model's z axes.
    normal_hint : array_like, shape (..., 3)
        Nominal direction of x_j, used only for signs.
    point_j_if_parallel : array_like, shape (..., 3)
        Foot on axis j to use when the lines are parallel [mm].
    """
    s_j, s0_j, s_k, s0_k = line_j.direction, line_j.moment, line_k.direction, line_k.moment
    hint = np.broadcast_to(np.asarray(normal_hint, dtype=float), s_j.shape)
    cross = _cross(s_j, s_k)
    sin_angle = np.linalg.norm(cross, axis=-1)
    cos_angle = _dot(s_j, s_k)
    mutual_moment = _dot(s_j, s0_k) + _dot(s_k, s0_j)
    parallel = sin_angle < PARALLEL_TOLERANCE_RAD
    with np.errstate(divide="ignore", invalid="ignore"):
        common_length = np.abs(mutual_moment) / sin_angle
        intersecting = ~parallel & (common_length < INTERSECTION_TOLERANCE_MM)
        normal_skew = _orient(cross / sin_angle[..., None], hint)
        # skew: eqs 4-35, 4-36 (both invariant to the sign of a_jk)
        n_k = _cross(normal_skew, s_k)
        foot_j = (_cross(n_k, s0_j) - _dot(s0_k, normal_skew)[..., None] * s_j) / _dot(n_k, s_j)[..., None]
        n_j = _cross(normal_skew, s_j)
        foot_k = (_cross(n_j, s0_k) - _dot(s0_j, normal_skew)[..., None] * s_k) / _dot(n_j, s_k)[..., None]
        # intersecting: eq. 4-44
        common = _cross(s0_j, s0_k) / _dot(s0_j, s_k)[..., None]
        # degenerate 4-44 (a line through the origin): fall back on the skew feet, which coincide
        common = np.where(np.isfinite(common), common, 0.5 * (foot_j + foot_k))
    # parallel: eq. 4-52, a'_jk = S_j x (cos(alpha) S0_k - S0_j)
    sign = np.sign(cos_angle)[..., None]
    offset = _cross(s_j, sign * s0_k - s0_j)
    offset_norm = np.linalg.norm(offset, axis=-1, keepdims=True)
    hint_perp = hint - _dot(hint, s_j)[..., None] * s_j
    normal_parallel = _orient(
        np.where(
            offset_norm > INTERSECTION_TOLERANCE_MM,
            offset / np.where(offset_norm > 0, offset_norm, 1.0),
            _unit(hint_perp),
        ),
        hint,
    )
    start_parallel = np.broadcast_to(np.asarray(point_j_if_parallel, dtype=float), s_j.shape)

    normal = np.where(parallel[..., None], normal_parallel, normal_skew)
    point_j = np.where(parallel[..., None], start_parallel, np.where(intersecting[..., None], common, foot_j))
    point_k = np.where(parallel[..., None], start_parallel + offset, np.where(intersecting[..., None], common, foot_k))
    length = _dot(point_k - point_j, normal)
    twist = np.arctan2(_dot(cross, normal), cos_angle)
    case = np.where(parallel, "parallel", np.where(intersecting, "intersecting", "skew"))
    return LinePair(
        case=case,
        normal=normal,
        point_j=point_j,
        point_k=point_k,
        length=length,
        twist=twist,
        beta=np.zeros_like(length),
        mutual_moment=mutual_moment,
    )


def analyse_hayati_pair(line_j: PluckerLine, line_k: PluckerLine, *, normal_hint, point_j) -> LinePair:
    """Nearly parallel axes with the extra Hayati angle beta (thesis 4.4.4.3, Solution 3).

    - ``P_j = point_j``: the caller passes ``P_j^prev + d_j^nom S_j`` (eq. 4-60; d = 0 on a Hayati joint);
    - ``P_k``: intersection of axis k with the plane normal to ``S_j`` through ``P_j`` (eq. 4-64);
    - ``a_jk = (P_k - P_j)/|P_k - P_j|`` oriented to agree with ``normal_hint``; ``a = (P_k - P_j) . a_jk``;
    - ``sin beta = S_k . a_jk``, ``cos beta = sqrt(1 - sin^2 beta)`` (eqs 4-99/4-100 as read in docs/conventions.md);
    - ``alpha'`` from the projection ``S_k^P = S_k - (S_k . a_jk) a_jk`` (eqs 4-76, 4-80, 4-81).

    These are exact for the frame ``Rz(theta) Tx(a) Rx(alpha) Ry(beta)`` of eq. 3-82.
    """
    s_j, s_k, s0_k = line_j.direction, line_k.direction, line_k.moment
    hint = np.broadcast_to(np.asarray(normal_hint, dtype=float), s_j.shape)
    point_j = np.broadcast_to(np.asarray(point_j, dtype=float), s_j.shape)
    denominator = _dot(s_j, s_k)
    if np.any(np.abs(denominator) < 1e-6):
        raise DegenerateGeometryError(
            "Hayati (Solution 3) pair: the later axis is perpendicular to the earlier one; "
            "a Hayati joint needs nearly parallel axes"
        )
    point_k = (_cross(s_j, s0_k) + _dot(point_j, s_j)[..., None] * s_k) / denominator[..., None]
    link = point_k - point_j
    link_norm = np.linalg.norm(link, axis=-1, keepdims=True)
    hint_perp = hint - _dot(hint, s_j)[..., None] * s_j
    normal = _orient(
        np.where(
            link_norm > INTERSECTION_TOLERANCE_MM, link / np.where(link_norm > 0, link_norm, 1.0), _unit(hint_perp)
        ),
        hint,
    )
    sin_beta = np.clip(_dot(s_k, normal), -1.0, 1.0)
    beta = np.arctan2(sin_beta, np.sqrt(1.0 - sin_beta**2))
    projected = s_k - sin_beta[..., None] * normal
    twist = np.arctan2(_dot(_cross(s_j, projected), normal), _dot(s_j, projected))
    mutual_moment = _dot(s_j, s0_k) + _dot(s_k, line_j.moment)
    return LinePair(
        case=np.full(denominator.shape, "nearly-parallel"),
        normal=normal,
        point_j=point_j,
        point_k=point_k,
        length=_dot(link, normal),
        twist=twist,
        beta=beta,
        mutual_moment=mutual_moment,
    )
