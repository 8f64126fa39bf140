"""Interactive 3-D view of a Circle Point capture for the HTML report (thesis Figs 4.21 and 5.8).

The scene holds, in the tracker frame [mm]: the measured points of every circle, the circle fitted to
them (plane, centre, radius, as CPA fits it, ch. 4.4.1) and the joint axis that CPA takes from that
fit (the line through the centre along the plane normal, the Plücker line of eq. 4-8), plus the
robot base frame when ``tracker_from_base`` is known. It is drawn by ``assets/viewer3d.js``, a
small hand-written canvas renderer inlined into the page: no library, no WebGL, no network.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any, Literal

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import RobotcalError
from robotcal.geometry.fits import fit_circle_3d

__all__ = ["CIRCLE_COLOURS", "viewer_scene", "render_viewer", "asset_text"]

CircleFit = Literal["geometric", "algebraic"]  # [identification] circle_fit

#: One colour per circle (colour-blind-safe qualitative palette), cycled beyond ten circles.
CIRCLE_COLOURS = (
    "#0072b2",
    "#e69f00",
    "#009e73",
    "#cc79a7",
    "#d55e00",
    "#56b4e9",
    "#7a5c00",
    "#5e3c99",
    "#999999",
    "#000000",
)

_DECIMALS = 4  # coordinates are sent rounded to 0.1 µm; far below any instrument resolution


@cache
def asset_text(name: str) -> str:
    """Text of a file in ``robotcal/report/assets`` (CSS and scripts inlined into the report), read once."""
    return resources.files("robotcal.report").joinpath("assets", name).read_text(encoding="utf-8")


def _rounded(vector) -> list[float]:
    return [round(float(x), _DECIMALS) for x in np.asarray(vector, dtype=float).reshape(-1)]


def _in_plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``u, v`` with ``(u, v, normal)`` orthonormal."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(normal, u)


def viewer_scene(
    capture: Capture, *, tracker_from_base: np.ndarray | None = None, circle_fit: CircleFit = "geometric"
) -> dict:
    """The scene of the 3-D view: points, fitted circles and axes per circle, base frame, bounds.

    Parameters
    ----------
    capture : Capture
        The measured points ``(n_points, 3)`` [mm, tracker frame] with their circle numbers.
    tracker_from_base : array_like, shape (4, 4), optional
        Pose of the robot base in the tracker frame [mm]; drawn as a frame when given.
    circle_fit : {"geometric", "algebraic"}
        Circle fit, as in the scenario's ``[identification] circle_fit``.

    Returns
    -------
    dict
        JSON-ready: ``circles`` (label, colour, points, and where at least 3 non-collinear points
        exist centre, normal, radius, in-plane unit vectors ``u, v``, plane and circle RMS [mm]),
        ``axes`` (circle index, label, point, unit direction, half length [mm]), ``frames``,
        ``bounds`` (``min``, ``max`` [mm]) and ``notes`` (circles that could not be fitted).
    """
    circles: list[dict[str, Any]] = []
    axes: list[dict[str, Any]] = []
    notes, extremes = [], [capture.points]
    for index, number in enumerate(np.unique(capture.circle)):
        points = capture.points[capture.circle == number]
        entry = {
            "label": f"J{int(number)}",
            "colour": CIRCLE_COLOURS[index % len(CIRCLE_COLOURS)],
            "points": [_rounded(p) for p in points],
            "radius": 0.0,
        }
        try:
            fit = fit_circle_3d(points, method=circle_fit)
        except RobotcalError as exc:
            notes.append(f"circle J{int(number)}: no circle fitted ({exc})")
        else:
            normal = np.asarray(fit.normal, dtype=float)
            u, v = _in_plane_basis(normal)
            centre = np.asarray(fit.centre, dtype=float)
            radius = float(fit.radius)
            entry.update(
                centre=_rounded(centre),
                normal=_rounded(normal),
                radius=round(radius, _DECIMALS),
                u=_rounded(u),
                v=_rounded(v),
                plane_rms_mm=float(fit.plane_rms),  # type: ignore[arg-type]  # fitted with residuals
                circle_rms_mm=float(fit.circle_rms),  # type: ignore[arg-type]
            )
            angles = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)[:, None]
            extremes.append(centre + radius * (np.cos(angles) * u + np.sin(angles) * v))
            axes.append(
                {
                    "circle": index,
                    "label": f"J{int(number)} axis",
                    "point": _rounded(centre),
                    "direction": _rounded(normal),
                    "half_length": 0.0,
                }
            )
        circles.append(entry)
    frames = []
    if tracker_from_base is not None:
        pose = np.asarray(tracker_from_base, dtype=float)
        frames.append(
            {
                "label": "base",
                "origin": _rounded(pose[:3, 3]),
                "x": _rounded(pose[:3, 0]),
                "y": _rounded(pose[:3, 1]),
                "z": _rounded(pose[:3, 2]),
                "length": 0.0,
            }
        )
        extremes.append(pose[None, :3, 3])
    everything = np.concatenate(extremes, axis=0)
    low, high = everything.min(axis=0), everything.max(axis=0)
    extent = float(np.max(high - low)) or 1.0
    for axis in axes:
        centre, direction = np.array(axis["point"]), np.array(axis["direction"])
        radius = circles[axis["circle"]]["radius"]
        axis["half_length"] = round(max(1.2 * radius, 0.25 * extent), _DECIMALS)
        ends = centre + np.outer([-1.0, 1.0], direction) * axis["half_length"]
        low, high = np.minimum(low, ends.min(axis=0)), np.maximum(high, ends.max(axis=0))
    for frame in frames:
        frame["length"] = round(0.15 * extent, _DECIMALS)
    pad = 0.03 * float(np.max(high - low) or 1.0)
    return {
        "units": "mm",
        "frame": "tracker",
        "circles": circles,
        "axes": axes,
        "frames": frames,
        "bounds": {"min": _rounded(low - pad), "max": _rounded(high + pad)},
        "notes": notes,
    }


def _script_json(data: dict) -> str:
    """JSON safe inside ``<script type="application/json">`` (no ``</script>`` or ``<!--`` can appear)."""
    return json.dumps(data, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")


def render_viewer(scene: dict, *, element_id: str = "rc-view3d") -> str:
    """HTML of one viewer (``templates/viewer.html.j2``: canvas, embedded scene, legend, controls); needs
    ``viewer3d.js`` on the page."""
    from markupsafe import Markup

    from robotcal.report import template_environment

    template = template_environment().get_template("viewer.html.j2")
    return template.render(element_id=element_id, scene_json=Markup(_script_json(scene)))
