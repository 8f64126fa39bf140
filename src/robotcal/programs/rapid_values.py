"""ABB RAPID values: a robtarget's pose as a frame and back, and the new text of a point's numbers (issue 28).

The layouts are those of the ABB "Technical reference manual - RAPID Instructions, Functions and Data types"
(RobotWare 6/7): a pose is ``[[x, y, z], [q1, q2, q3, q4]]``, position [mm] and a unit quaternion ``q1 + q2 i + q3 j
+ q4 k`` (``q1`` the scalar part); a robtarget's configuration is ``[cf1, cf4, cf6, cfx]``; a jointtarget's axes are
degrees. :mod:`robotcal.programs.rapid` reads modules and re-exports :func:`render`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.geometry.transforms import check_rigid_transform
from robotcal.programs.base import NumberSpan, ProgramPoint, format_number, joint_values

__all__ = ["CONFIG_KEYS", "frame_from_pose", "quaternion_from_frame", "render"]

#: Decimals written for positions [mm], quaternion components and joint values [deg].
POSITION_DECIMALS = 6
QUATERNION_DECIMALS = 9
JOINT_DECIMALS = 8  # 5e-9 deg per axis: under 1e-7 mm at the tool of a 1 m arm
#: Configuration components of a robtarget, in the order written.
CONFIG_KEYS = ("cf1", "cf4", "cf6", "cfx")


def frame_from_pose(position_mm: ArrayLike, quaternion_wxyz: ArrayLike) -> np.ndarray:
    """4x4 frame [mm] of a RAPID ``pose``: ``position_mm = [x, y, z]``, ``quaternion_wxyz = [q1, q2, q3, q4]``.

    The quaternion is normalised (RAPID's ``q1`` is the scalar part; scipy's ``Rotation.from_quat`` takes
    ``[x, y, z, w]``). A zero quaternion raises :class:`InputError`.
    """
    from scipy.spatial.transform import Rotation

    quaternion = np.asarray(quaternion_wxyz, dtype=float)
    norm = float(np.linalg.norm(quaternion))
    if not np.isfinite(norm) or norm < 1e-12:
        raise InputError(f"quaternion {quaternion.tolist()} has zero length; it is no orientation")
    quaternion = quaternion / norm
    frame = np.eye(4)
    frame[:3, :3] = Rotation.from_quat([quaternion[1], quaternion[2], quaternion[3], quaternion[0]]).as_matrix()
    frame[:3, 3] = np.asarray(position_mm, dtype=float)
    return frame


def quaternion_from_frame(frame_mm: ArrayLike, near_wxyz: ArrayLike | None = None) -> np.ndarray:
    """Unit quaternion ``[q1, q2, q3, q4]`` (scalar first, RAPID's order) of a 4x4 frame's rotation.

    ``q`` and ``-q`` are the same rotation; the one returned lies in the hemisphere of ``near_wxyz`` (the
    quaternion as written, so a rewritten target keeps its signs), else has ``q1 >= 0``.
    """
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(np.asarray(frame_mm, dtype=float)[:3, :3]).as_quat()
    quaternion = np.array([w, x, y, z])
    quaternion /= np.linalg.norm(quaternion)
    reference = np.array([1.0, 0.0, 0.0, 0.0]) if near_wxyz is None else np.asarray(near_wxyz, dtype=float)
    if float(quaternion @ reference) < 0.0:
        quaternion = -quaternion
    return quaternion


def render(
    point: ProgramPoint, *, frame_mm: ArrayLike | None = None, joints_deg: ArrayLike | None = None,
    config: Mapping[str, int] | None = None,
) -> dict[NumberSpan, str]:
    """RAPID's :class:`~robotcal.programs.base.Render`: the replacement text of every number of ``point``.

    Robtargets (Cartesian points): ``frame_mm``, the new TCP frame in the point's work-object frame, is written as
    ``x, y, z`` with 6 decimals [mm] and ``q1..q4`` normalised with 9 decimals, in the hemisphere of the quaternion as
    written (``q`` and ``-q`` are the same rotation; the signs stay as the user wrote them). Each quaternion component
    is rounded up or down so that the written quaternion, normalised, is nearest the rotation: the rotation comes
    back to about 1e-9 (below 1e-7 deg), and a quaternion as written with at most 9 decimals is rewritten digit for
    digit for the same frame. ``config``: new ``cf1``, ``cf4``, ``cf6``, ``cfx``; only those that differ from the
    point's are rewritten (an unknown or non-integer entry is an error). Jointtargets: ``joints_deg``, the robot axis
    values, 6 decimals (RAPID has no joint form of a Cartesian target). External axis values are never included.
    """
    where = f"{point.file}: line {point.line}: {point.label}"
    if point.kind == "cartesian":
        if joints_deg is not None:
            raise InputError(
                f"{where} is a robtarget (a Cartesian pose); RAPID cannot write it from joint values: give frame_mm"
            )
        if frame_mm is None:
            raise InputError(f"{where} is a robtarget; give its new frame_mm")
        frame = check_rigid_transform(frame_mm, "frame_mm")
        quaternion = quaternion_from_frame(frame, near_wxyz=point.values[3:7])
        texts = [format_number(v, POSITION_DECIMALS) for v in frame[:3, 3]]
        texts += [format_number(v, QUATERNION_DECIMALS) for v in _rounded_quaternion(quaternion, QUATERNION_DECIMALS)]
        replacements = dict(zip(point.spans, texts, strict=True))
        if config is not None:
            replacements.update(_render_config(point, config, where))
        return replacements
    if frame_mm is not None:
        raise InputError(f"{where} is a jointtarget (axis values); give joints_deg, not frame_mm")
    if joints_deg is None:
        raise InputError(f"{where} is a jointtarget; give its new joints_deg")
    if config:
        raise InputError(f"{where} is a jointtarget; it has no configuration data to write")
    joints = joint_values(point, joints_deg)
    return {span: format_number(value, JOINT_DECIMALS) for span, value in zip(point.spans, joints, strict=True)}


def _rounded_quaternion(quaternion: np.ndarray, decimals: int) -> np.ndarray:
    """``quaternion`` rounded to ``decimals``, choosing each component's rounding up or down so that the written
    quaternion, once normalised (as the controller and :func:`read_program` do), is nearest the rotation.

    Plain rounding errs by up to ``0.5e-decimals`` per component; of the 16 neighbours on the grid the best also
    lets the normalisation absorb the error along the quaternion, which roughly halves the rotation error.
    """
    import itertools

    scale = 10.0**decimals
    low = np.floor(quaternion * scale)
    best, best_error = np.round(quaternion * scale) / scale, np.inf
    for steps in itertools.product((0.0, 1.0), repeat=4):
        candidate = (low + np.array(steps)) / scale
        error = float(np.linalg.norm(candidate / np.linalg.norm(candidate) - quaternion))
        if error < best_error:
            best, best_error = candidate, error
    return best


def _render_config(point: ProgramPoint, config: Mapping[str, int], where: str) -> dict[NumberSpan, str]:
    out = {}
    for key, value in config.items():
        if key not in point.config_spans:
            raise InputError(f"{where}: unknown configuration entry {key!r}; RAPID writes {', '.join(CONFIG_KEYS)}")
        try:
            whole = int(value)
            exact = float(value) == whole
        except (TypeError, ValueError, OverflowError):
            exact = False
        if not exact:
            raise InputError(f"{where}: configuration {key} must be a whole number; got {value!r}")
        if whole != point.config[key]:
            out[point.config_spans[key]] = str(whole)
    return out
