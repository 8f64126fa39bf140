"""Thesis data and test helpers shared by the test modules (one place for each typed-in table).

Imported as ``thesis_data`` (``tests`` is on ``pythonpath``, see pyproject.toml).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from robotcal.kinematics import RobotModel

#: Published Tables 5.6-5.8 as printed, kept in the repository (source cited in tests/data/README.md).
THESIS_TABLES = Path(__file__).parent / "data" / "thesis_tables.json"


def thesis_tables() -> dict:
    """The published tables (``tests/data/thesis_tables.json``) as a dict; see tests/data/README.md."""
    return json.loads(THESIS_TABLES.read_text(encoding="utf-8"))


#: Thesis Table 3.1, typed in [mm, deg]: columns d, theta (offset), a, alpha; J2 is Hayati (beta2 = 0).
KR5_D_MM = [335.0, 0.0, 0.0, 295.0, 0.0, 80.0]
KR5_THETA_DEG = [0.0, 0.0, 90.0, 0.0, 180.0, 0.0]
KR5_A_MM = [75.0, 270.0, 90.0, 0.0, 0.0, 0.0]
KR5_ALPHA_DEG = [90.0, 0.0, 90.0, 90.0, 90.0, 0.0]
KR5_HAYATI = [False, True, False, False, False, False]
#: KUKA controller angles (thesis Table 5.8, docs/conventions.md) -> model joint variables.
KUKA_SIGN = [-1, -1, -1, -1, 1, -1]

#: Thesis Table 5.1 capture plan [deg, points per circle].
TABLE_5_1_START_DEG = np.array([15.0, 0.0, 0.0, 0.0, 0.0, 0.0])
TABLE_5_1_SWEEP_DEG = np.array([45.0, 80.0, 100.0, 50.0, 200.0, 300.0])
TABLE_5_1_POINTS = np.array([15, 20, 30, 15, 25, 30])
#: Thesis Table 5.1 targets, one per circle, in DH frame {i-1} turned by joint i (eq. 5-1) [mm].
TABLE_5_1_REFLECTORS_MM = np.array(
    [[100.0, 0.0, 0.0], [200.0, 0.0, 0.0], [0.0, 50.0, 0.0], [20.0, 0.0, 0.0], [0.0, 80.0, 0.0], [0.0, 60.0, 0.0]]
)

#: Thesis Table 4.2: row i is the configuration where circle i starts [deg].
TABLE_4_2_DEG = np.array(
    [
        [0.0, -90.0, 90.0, 0.0, -90.0, 0.0],
        [0.0, -90.0, 45.0, -90.0, -90.0, 0.0],
        [0.0, -90.0, 90.0, -90.0, -90.0, 0.0],
        [0.0, -90.0, 90.0, 0.0, -90.0, 0.0],
        [0.0, -90.0, 90.0, 0.0, 0.0, 0.0],
        [0.0, -90.0, 90.0, 0.0, 0.0, 0.0],
    ]
)

#: Per-circle targets off every axis and out of the circle planes [mm] (test choice, not thesis).
OFF_AXIS_REFLECTORS_MM = np.array(
    [
        [250.0, 0.0, 120.0],
        [180.0, 60.0, 40.0],
        [150.0, -50.0, -30.0],
        [0.0, 120.0, 90.0],
        [0.0, 80.0, 0.0],
        [60.0, 40.0, 30.0],
    ]
)


def kr5_nominal() -> np.ndarray:
    """Table 3.1 as a ``(6, 5)`` array [mm, rad] (d, theta, a, alpha, beta)."""
    nominal = np.zeros((6, 5))
    nominal[:, 0] = KR5_D_MM
    nominal[:, 1] = np.deg2rad(KR5_THETA_DEG)
    nominal[:, 2] = KR5_A_MM
    nominal[:, 3] = np.deg2rad(KR5_ALPHA_DEG)
    return nominal


def kr5_robot(**changes) -> RobotModel:
    """The KR5 of Table 3.1 as a :class:`RobotModel`; keyword arguments replace fields."""
    arguments = {"name": "kr5", "nominal": kr5_nominal(), "hayati": KR5_HAYATI} | changes
    return RobotModel(**arguments)


def random_rigid(rng, max_shift: float = 3000.0) -> np.ndarray:
    """A random rigid transform (uniform rotation, translation within +-max_shift mm) as 4x4."""
    matrix = np.eye(4)
    matrix[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    matrix[:3, 3] = rng.uniform(-max_shift, max_shift, 3)
    return matrix
