"""The 3-D view of the measured circles and the identified axes."""

from __future__ import annotations

import re

import numpy as np

from robotcal.io.results.run_folder import Table
from robotcal.report.page import _block, _Page
from robotcal.report.viewer3d import render_viewer, viewer_scene


def _capture(table: Table):
    """The Capture of a ``capture.csv`` document (circle, direction, q1..qN in deg, x, y, z in mm)."""
    from robotcal.capture import Capture

    header = [h.strip().lower() for h in table.header]
    joints = sorted((h for h in header if re.fullmatch(r"q\d+", h)), key=lambda h: int(h[1:]))
    missing = [c for c in ("circle", "direction", "x", "y", "z") if c not in header] + ([] if joints else ["q1..qN"])
    if missing:
        raise ValueError(f"missing column(s) {', '.join(missing)}")
    columns = ["circle", "direction", *joints, "x", "y", "z"]
    data = np.array([[float(row[header.index(c)]) for c in columns] for row in table.rows], dtype=float)
    if data.size == 0 or not np.all(np.isfinite(data)):
        raise ValueError("no rows, or a value that is not a finite number")
    return Capture(
        circle=data[:, 0].astype(int),
        direction=data[:, 1].astype(int),
        readings=np.deg2rad(data[:, 2 : 2 + len(joints)]),
        points=data[:, -3:],
    )


def _view3d(page: _Page) -> dict:
    table = page.table("capture.csv")
    if table is None:
        return {"present": False, "blocks_": [_block("not_run", what="capture.csv")]}
    from robotcal.errors import RobotcalError

    try:
        capture = _capture(table)
    except (ValueError, IndexError, RobotcalError) as exc:
        return {"present": False, "blocks_": [page.problem("capture.csv", f"not a capture ({exc})")]}
    provenance = (page.json("cpa/parameters.json") or {}).get("provenance")
    provenance = provenance if isinstance(provenance, dict) else {}
    pose = provenance.get("tracker_from_base")
    try:
        pose = np.asarray(pose, dtype=float) if pose is not None else None
        if pose is not None and pose.shape != (4, 4):
            pose = None
    except (TypeError, ValueError):
        pose = None
    options = found if isinstance(found := provenance.get("options"), dict) else {}
    circle_fit = options.get("circle_fit")
    scene = viewer_scene(
        capture,
        tracker_from_base=pose,
        circle_fit=circle_fit if circle_fit in ("geometric", "algebraic") else "geometric",
    )
    return {"present": True, "notes": scene["notes"], "frame": pose is not None, "viewer": render_viewer(scene)}
