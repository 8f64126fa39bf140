"""Plücker lines and the adjacent-line analysis of Circle Point Analysis (thesis ch. 4.4.2-4.4.4).

A line is ``(S; S0)`` with unit direction ``S`` and moment ``S0 = r x S`` for any point ``r`` of the
line (eqs 4-6..4-8). Everything is batched over leading axes so that a Monte Carlo batch of captures
is analysed in one call. Lengths in mm, angles in radians.

Inside the pair analyses the ``(..., 3)`` stacks are handled as three ``(...)`` component arrays
(``_xyz``, ``_cross3``, ``_dot3``), stacked back only for the results, and the branches of the
intersecting and parallel cases are evaluated only when some item of the batch is in them. Every
value is computed by the same floating-point operations in the same order as the plain ``(..., 3)``
formulas (``_vectors.cross``/``dot``, ``np.linalg.norm``), so a result does not depend on the layout
nor on the other items of the batch (the Monte Carlo draws are bit-for-bit those of the plain code,
tests/unit/geometry/test_line_pairs.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import DegenerateGeometryError, InputError
from robotcal.geometry._vectors import cross as _cross
from robotcal.geometry._vectors import dot as _dot

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
    def _adopt(cls, direction: np.ndarray, moment: np.ndarray) -> PluckerLine:
        """A line on float arrays that only this module holds (fresh results, or views of a frozen line's
        arrays): frozen in place, without the constructor's defensive copies (``lines[..., j]`` of a Monte Carlo
        batch of axes is then a view, not two strided copies)."""
        line = object.__new__(cls)
        for field, value in (("direction", direction), ("moment", moment)):
            value.setflags(write=False)
            object.__setattr__(line, field, value)
        return line

    @classmethod
    def from_point_direction(cls, point, direction) -> PluckerLine:
        """Line through ``point (..., 3)`` [mm] along ``direction (..., 3)`` (normalised here), eq. 4-7."""
        direction = np.asarray(direction, dtype=float)
        with np.errstate(over="ignore"):  # an overflowing norm is refused below
            norm = np.sqrt(_dot(direction, direction))  # np.linalg.norm(axis=-1), the same operations
        # a NaN or infinite component makes the norm NaN or infinite; so does a finite vector too long to normalise
        if not np.all((norm > 0.0) & (norm < np.inf)):
            raise InputError("a line direction must be a finite non-zero vector")
        direction = direction / norm[..., None]
        return cls._adopt(direction, _cross(np.asarray(point, dtype=float), direction))

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
        return PluckerLine._adopt(direction, _cross(point, direction))

    def flipped(self, mask) -> PluckerLine:
        """Reverse direction (and moment) where ``mask (...)`` is true."""
        sign = np.where(np.asarray(mask)[..., None], -1.0, 1.0)
        return PluckerLine._adopt(self.direction * sign, self.moment * sign)

    def __getitem__(self, index) -> PluckerLine:
        """Index the batch axes (never the coordinate axis): ``lines[..., j]`` is line j of each item.

        Basic indexing gives read-only views of this line's arrays (no copy), advanced indexing fresh copies."""
        index = (index if isinstance(index, tuple) else (index,)) + (slice(None),)
        return PluckerLine._adopt(self.direction[index], self.moment[index])


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


def _xyz(vectors) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The three components of ``(..., 3)`` vectors, as ``(...)`` views."""
    vectors = np.asarray(vectors, dtype=float)
    return vectors[..., 0], vectors[..., 1], vectors[..., 2]


def _xyz_copied(vectors) -> np.ndarray:
    """The components of ``(..., 3)`` vectors as one C-contiguous ``(3, ...)`` copy: cheaper than operating on
    strided views when each component is read many times (a line of a ``(..., n_joints, 3)`` stack)."""
    vectors = np.asarray(vectors, dtype=float)
    return vectors.transpose((vectors.ndim - 1, *range(vectors.ndim - 1))).copy()


def _cross3(a, b) -> tuple:
    """``a x b`` on component triples: the operations of ``_vectors.cross``, without stacking."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


def _dot3(a, b):
    """``a . b`` on component triples: the operations of ``_vectors.dot``."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _stacked(components) -> np.ndarray:
    """Component triple -> ``(..., 3)`` array (what ``np.stack(..., axis=-1)`` gives, broadcast)."""
    out = np.empty(np.broadcast_shapes(*(np.shape(c) for c in components)) + (3,))
    out[..., 0], out[..., 1], out[..., 2] = components
    return out


def _orient3(vector, hint) -> tuple:
    """Flip ``vector`` where it points against ``hint`` (the nominal x axis, "cambia signo ajk").

    A product by -1 is exact, so this is ``where(v . hint < 0, -v, v)`` to the bit; a batch flipped as a
    whole or not at all (the usual Monte Carlo batch) costs no per-item selection."""
    against = _dot3(vector, hint) < 0.0
    if not against.any():
        return tuple(vector)
    if against.all():
        return tuple(-component for component in vector)
    sign = np.where(against, -1.0, 1.0)
    return tuple(component * sign for component in vector)


def _where3(condition, if_true, if_false) -> tuple:
    """``np.where`` on component triples."""
    return tuple(np.where(condition, t, f) for t, f in zip(if_true, if_false, strict=True))


def signed_angle_about(from_vector: ArrayLike, to_vector: ArrayLike, axis: ArrayLike) -> np.ndarray:
    """Right-handed angle [rad] from ``from_vector`` to ``to_vector`` about unit ``axis``, (-pi, pi].

    Both vectors are projected on the plane normal to ``axis`` first, so they need not be
    perpendicular to it (eqs 4-92, 4-93 with the dot product, see docs/conventions.md).
    """
    f, t, n = _xyz(from_vector), _xyz(to_vector), _xyz(axis)
    return np.arctan2(_dot3(_cross3(f, t), n), _dot3(f, t) - _dot3(f, n) * _dot3(t, n))


def analyse_dh_pair(
    line_j: PluckerLine, line_k: PluckerLine, *, normal_hint: ArrayLike, point_j_if_parallel: ArrayLike
) -> LinePair:
    """Adjacent-line analysis for a Denavit-Hartenberg joint (thesis 4.4.3, 4.4.5 steps 1, 3, 4).

    - skew lines (``|a_jk| > INTERSECTION_TOLERANCE_MM``): common-normal feet by eqs 4-35 and 4-36
      (4-36 with the corrected term ``(a_jk x S_j) x S0_k``);
    - intersecting lines: the common point of eq. 4-44, ``a_jk = 0``;
    - parallel lines (angle below ``PARALLEL_TOLERANCE_RAD``): ``a'_jk`` by eq. 4-52; the feet are not
      unique, so ``P_j = point_j_if_parallel`` (the caller passes ``P_j^prev + d_j^nom S_j``).

    ``a_jk`` has the direction of ``+-(S_j x S_k)`` that agrees with ``normal_hint`` (the nominal
    x_j axis); the length is signed, ``a = (P_k - P_j) . a_jk``, and
    ``alpha = atan2((S_j x S_k) . a_jk, S_j . S_k)`` (eqs 4-12, 4-13).

    The intersecting and parallel formulas are evaluated only when some item of the batch is in that
    case (a Monte Carlo batch of measured axes is all skew); each item's values do not depend on that.

    Parameters
    ----------
    line_j, line_k : PluckerLine
        Axes j and k, batched alike, directions oriented as the model's z axes.
    normal_hint : array_like, shape (..., 3)
        Nominal direction of x_j, used only for signs.
    point_j_if_parallel : array_like, shape (..., 3)
        Foot on axis j to use when the lines are parallel [mm].
    """
    s_j, s0_j, s_k, s0_k = (_xyz_copied(v) for v in (line_j.direction, line_j.moment, line_k.direction, line_k.moment))
    hint = _xyz(np.broadcast_to(np.asarray(normal_hint, dtype=float), line_j.direction.shape))
    cross = _cross3(s_j, s_k)
    sin_angle = np.sqrt(_dot3(cross, cross))  # np.linalg.norm: the same operations
    cos_angle = _dot3(s_j, s_k)
    mutual_moment = _dot3(s_j, s0_k) + _dot3(s_k, s0_j)
    parallel = sin_angle < PARALLEL_TOLERANCE_RAD
    any_parallel = bool(parallel.any())
    with np.errstate(divide="ignore", invalid="ignore"):
        common_length = np.abs(mutual_moment) / sin_angle
        intersecting = common_length < INTERSECTION_TOLERANCE_MM
        if any_parallel:
            intersecting &= ~parallel
        any_intersecting = bool(intersecting.any())
        normal = _orient3(tuple(component / sin_angle for component in cross), hint)
        # skew: eqs 4-35, 4-36 (both invariant to the sign of a_jk)
        n_k = _cross3(normal, s_k)
        along_j = _dot3(s0_k, normal)
        across_j = _dot3(n_k, s_j)
        point_j = tuple((c - along_j * s) / across_j for c, s in zip(_cross3(n_k, s0_j), s_j, strict=True))
        n_j = _cross3(normal, s_j)
        along_k = _dot3(s0_j, normal)
        across_k = _dot3(n_j, s_k)
        point_k = tuple((c - along_k * s) / across_k for c, s in zip(_cross3(n_j, s0_k), s_k, strict=True))
        if any_intersecting:
            # intersecting: eq. 4-44
            denominator = _dot3(s0_j, s_k)
            common = tuple(c / denominator for c in _cross3(s0_j, s0_k))
            # degenerate 4-44 (a line through the origin): fall back on the skew feet, which coincide
            common = tuple(
                np.where(np.isfinite(c), c, 0.5 * (fj + fk)) for c, fj, fk in zip(common, point_j, point_k, strict=True)
            )
            point_j = _where3(intersecting, common, point_j)
            point_k = _where3(intersecting, common, point_k)
    if any_parallel:
        # parallel: eq. 4-52, a'_jk = S_j x (cos(alpha) S0_k - S0_j)
        sign = np.sign(cos_angle)
        offset = _cross3(s_j, tuple(sign * ck - cj for ck, cj in zip(s0_k, s0_j, strict=True)))
        offset_norm = np.sqrt(_dot3(offset, offset))
        along_hint = _dot3(hint, s_j)
        hint_perp = tuple(h - along_hint * s for h, s in zip(hint, s_j, strict=True))
        hint_perp_norm = np.sqrt(_dot3(hint_perp, hint_perp))
        divisor = np.where(offset_norm > 0, offset_norm, 1.0)
        normal_parallel = _orient3(
            _where3(
                offset_norm > INTERSECTION_TOLERANCE_MM,
                tuple(o / divisor for o in offset),
                tuple(h / hint_perp_norm for h in hint_perp),
            ),
            hint,
        )
        start = _xyz(np.broadcast_to(np.asarray(point_j_if_parallel, dtype=float), line_j.direction.shape))
        normal = _where3(parallel, normal_parallel, normal)
        point_j = _where3(parallel, start, point_j)
        point_k = _where3(parallel, tuple(p + o for p, o in zip(start, offset, strict=True)), point_k)
    length = _dot3(tuple(pk - pj for pk, pj in zip(point_k, point_j, strict=True)), normal)
    twist = np.arctan2(_dot3(cross, normal), cos_angle)
    if any_parallel or any_intersecting:
        case = np.where(parallel, "parallel", np.where(intersecting, "intersecting", "skew"))
    else:  # what the line above gives, without comparing strings per item
        case = np.full(np.shape(parallel), "skew", dtype="<U12")
    return LinePair(
        case=case,
        normal=_stacked(normal),
        point_j=_stacked(point_j),
        point_k=_stacked(point_k),
        length=length,
        twist=twist,
        beta=np.zeros_like(length),
        mutual_moment=mutual_moment,
    )


def analyse_hayati_pair(
    line_j: PluckerLine, line_k: PluckerLine, *, normal_hint: ArrayLike, point_j: ArrayLike
) -> LinePair:
    """Nearly parallel axes with the extra Hayati angle beta (thesis 4.4.4.3, Solution 3).

    - ``P_j = point_j``: the caller passes ``P_j^prev + d_j^nom S_j`` (eq. 4-60; d = 0 on a Hayati joint);
    - ``P_k``: intersection of axis k with the plane normal to ``S_j`` through ``P_j`` (eq. 4-64);
    - ``a_jk = (P_k - P_j)/|P_k - P_j|`` oriented to agree with ``normal_hint``; ``a = (P_k - P_j) . a_jk``;
    - ``sin beta = S_k . a_jk``, ``cos beta = sqrt(1 - sin^2 beta)`` (eqs 4-99/4-100 as read in docs/conventions.md);
    - ``alpha'`` from the projection ``S_k^P = S_k - (S_k . a_jk) a_jk`` (eqs 4-76, 4-80, 4-81).

    These are exact for the frame ``Rz(theta) Tx(a) Rx(alpha) Ry(beta)`` of eq. 3-82.
    """
    shape = line_j.direction.shape
    s_j, s_k, s0_k = (_xyz_copied(v) for v in (line_j.direction, line_k.direction, line_k.moment))
    hint = _xyz(np.broadcast_to(np.asarray(normal_hint, dtype=float), shape))
    point_j = np.broadcast_to(np.asarray(point_j, dtype=float), shape)
    p_j = _xyz(point_j)
    denominator = _dot3(s_j, s_k)
    if np.any(np.abs(denominator) < 1e-6):
        raise DegenerateGeometryError(
            "Hayati (Solution 3) pair: the later axis is perpendicular to the earlier one; "
            "a Hayati joint needs nearly parallel axes"
        )
    height = _dot3(p_j, s_j)
    point_k = tuple((c + height * s) / denominator for c, s in zip(_cross3(s_j, s0_k), s_k, strict=True))
    link = tuple(pk - pj for pk, pj in zip(point_k, p_j, strict=True))
    link_norm = np.sqrt(_dot3(link, link))  # np.linalg.norm: the same operations
    long_link = link_norm > INTERSECTION_TOLERANCE_MM
    if np.all(long_link):
        normal = tuple(c / link_norm for c in link)
    else:
        along_hint = _dot3(hint, s_j)
        hint_perp = tuple(h - along_hint * s for h, s in zip(hint, s_j, strict=True))
        hint_perp_norm = np.sqrt(_dot3(hint_perp, hint_perp))
        divisor = np.where(link_norm > 0, link_norm, 1.0)
        normal = _where3(long_link, tuple(c / divisor for c in link), tuple(h / hint_perp_norm for h in hint_perp))
    normal = _orient3(normal, hint)
    sin_beta = np.clip(_dot3(s_k, normal), -1.0, 1.0)
    beta = np.arctan2(sin_beta, np.sqrt(1.0 - sin_beta**2))
    projected = tuple(s - sin_beta * n for s, n in zip(s_k, normal, strict=True))
    twist = np.arctan2(_dot3(_cross3(s_j, projected), normal), _dot3(s_j, projected))
    mutual_moment = _dot3(s_j, s0_k) + _dot3(s_k, _xyz(line_j.moment))
    return LinePair(
        case=np.full(denominator.shape, "nearly-parallel"),
        normal=_stacked(normal),
        point_j=point_j,
        point_k=_stacked(point_k),
        length=_dot3(link, normal),
        twist=twist,
        beta=beta,
        mutual_moment=mutual_moment,
    )
