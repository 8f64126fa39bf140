"""tcp.json is strict JSON: undefined ellipsoid figures as null, any other NaN refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robotcal.io import load_robot
from robotcal.io.tcp_results import write_tcp_json
from robotcal.uncertainty.tcp import propagate_to_tcp

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")
READINGS = np.deg2rad([[10.0, -80.0, 100.0, 20.0, 50.0, -30.0]])


def _strict(text):
    def refuse(constant):
        raise AssertionError(f"non-standard JSON constant {constant}")

    return json.loads(text, parse_constant=refuse)


def test_singular_position_covariance_is_written_as_null(tmp_path):
    # every draw the nominal robot: zero covariance, the ellipsoid's coverage figures are undefined
    draws = np.repeat(ROBOT.nominal[None], 20, axis=0)
    result = propagate_to_tcp(ROBOT, draws, READINGS)
    assert np.isnan(result.ellipsoid.fraction_inside[0])
    data = _strict(write_tcp_json(tmp_path / "tcp.json", result).read_text())
    assert data["poses"][0]["ellipsoid"]["fraction_inside"] is None


def test_nan_elsewhere_is_refused_not_written(tmp_path):
    rng = np.random.default_rng(0)
    draws = ROBOT.nominal[None] + rng.normal(0.0, 1e-3, (20, ROBOT.n_joints, 5)) * ~ROBOT.structurally_fixed
    result = propagate_to_tcp(ROBOT, draws, READINGS)
    _strict(write_tcp_json(tmp_path / "ok.json", result).read_text())
    with pytest.raises(ValueError, match="JSON compliant"):
        write_tcp_json(tmp_path / "bad.json", result, provenance={"sigma_mm": float("nan")})
    assert not (tmp_path / "bad.json").exists()
