"""The 3-D view's scene: circle fits against a known circle, axes, frame, bounds, safe embedding."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robotcal.capture import Capture
from robotcal.report.viewer3d import asset_text, render_viewer, viewer_scene

ROUNDING_MM = 0.5e-4  # the scene rounds coordinates to 4 decimals


def _circle_capture(centre, normal, radius, n=12, *, extra=None) -> Capture:
    """Exact points on a known circle (circle 1), optionally a second point set (circle 2)."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    t = np.linspace(0.1, 2.0, n)[:, None]
    points = np.asarray(centre) + radius * (np.cos(t) * u + np.sin(t) * v)
    circle = np.ones(n, int)
    if extra is not None:
        points = np.vstack([points, extra])
        circle = np.concatenate([circle, np.full(len(extra), 2)])
    return Capture(
        circle=circle, direction=np.ones(len(points), int), readings=np.zeros((len(points), 2)), points=points
    )


def test_fitted_circle_and_axis_match_the_known_circle():
    centre, normal, radius = np.array([1200.0, -300.0, 850.0]), np.array([0.3, -0.2, 0.93]), 150.0
    scene = viewer_scene(_circle_capture(centre, normal, radius))
    (circle,) = scene["circles"]
    unit = normal / np.linalg.norm(normal)
    np.testing.assert_allclose(circle["centre"], centre, atol=ROUNDING_MM)
    np.testing.assert_allclose(circle["radius"], radius, atol=ROUNDING_MM)
    assert abs(np.dot(circle["normal"], unit)) == pytest.approx(1.0, abs=1e-4)  # the normal's sign is arbitrary
    basis = np.array([circle["u"], circle["v"], circle["normal"]])
    np.testing.assert_allclose(basis @ basis.T, np.eye(3), atol=2e-4)  # rounded orthonormal basis
    assert circle["circle_rms_mm"] < 1e-9 and circle["plane_rms_mm"] < 1e-9  # exact points
    (axis,) = scene["axes"]
    assert axis["circle"] == 0 and axis["point"] == circle["centre"] and axis["direction"] == circle["normal"]
    # the bounds hold every point, the whole circle and both ends of the axis
    low, high = np.array(scene["bounds"]["min"]), np.array(scene["bounds"]["max"])
    ends = centre + np.outer([-1, 1], unit) * axis["half_length"]
    ring = centre + radius * np.array([circle["u"], circle["v"]])
    for point in np.vstack([circle["points"], ends, ring, centre - (ring - centre)]):
        assert np.all(point >= low - ROUNDING_MM) and np.all(point <= high + ROUNDING_MM)


def test_collinear_circle_keeps_its_points_without_a_fit():
    line = np.column_stack([np.linspace(0, 100, 5), np.zeros(5), np.zeros(5)])
    scene = viewer_scene(_circle_capture([0, 0, 0], [0, 0, 1], 50.0, extra=line))
    assert [c["label"] for c in scene["circles"]] == ["J1", "J2"]
    assert len(scene["circles"][1]["points"]) == 5 and "centre" not in scene["circles"][1]
    assert len(scene["axes"]) == 1
    assert scene["notes"] and scene["notes"][0].startswith("circle J2: no circle fitted")


def test_base_frame_is_drawn_from_tracker_from_base():
    pose = np.eye(4)
    pose[:3, 3] = [2000.0, 100.0, -50.0]
    scene = viewer_scene(_circle_capture([0, 0, 0], [0, 0, 1], 50.0), tracker_from_base=pose)
    (frame,) = scene["frames"]
    assert frame["origin"] == [2000.0, 100.0, -50.0] and frame["z"] == [0.0, 0.0, 1.0]
    assert scene["bounds"]["max"][0] >= 2000.0


def test_embedded_scene_cannot_close_its_script_tag():
    scene = viewer_scene(_circle_capture([0, 0, 0], [0, 0, 1], 50.0))
    scene["circles"][0]["label"] = "</script><script>alert(1)</script>"
    snippet = render_viewer(scene)
    assert snippet.count("</script>") == 1
    payload = snippet.split('<script type="application/json">')[1].split("</script>")[0]
    assert json.loads(payload)["circles"][0]["label"] == "</script><script>alert(1)</script>"


def test_assets_are_plain_scripts_without_network_access():
    for name in ("viewer3d.js", "check.js", "errors.js", "report.css"):
        text = asset_text(name)
        assert "</script" not in text.lower()
        code = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith(("/*", "*", "//")))
        for forbidden in ("http:", "https:", "import(", "fetch(", "XMLHttpRequest", "webgl", "url("):
            assert forbidden not in code, (name, forbidden)
