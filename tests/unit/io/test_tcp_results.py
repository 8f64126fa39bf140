"""tcp.json is strict JSON: undefined ellipsoid figures as null, any other NaN refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robotcal.io import load_robot
from robotcal.io.results.tcp_results import write_tcp_json
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


def _reference_dict_poses(result, interval="symmetric"):
    """The per-pose part of tcp.json converted one number at a time (the definition tcp_to_dict vectorises)."""
    deg = np.array([1.0, 1.0, 1.0, *([180.0 / np.pi] * 3)])
    low, high = result.summary.interval(interval)
    s = result.summary
    poses = []
    for p in range(result.n_poses):
        coordinates = {}
        for k, name in enumerate(("X", "Y", "Z", "A", "B", "C")):
            f = deg[k]
            coordinates[name] = {
                "unit": ("mm", "mm", "mm", "deg", "deg", "deg")[k],
                "nominal": float(result.nominal[p, k] * f),
                "mean": float(s.mean[p, k] * f),
                "std_uncertainty": float(s.std_uncertainty[p, k] * f),
                "coverage_low": float(low[p, k] * f),
                "coverage_high": float(high[p, k] * f),
                "symmetric_low": float(s.symmetric_low[p, k] * f),
                "symmetric_high": float(s.symmetric_high[p, k] * f),
                "shortest_low": float(s.shortest_low[p, k] * f),
                "shortest_high": float(s.shortest_high[p, k] * f),
                "min": float(s.minimum[p, k] * f),
                "max": float(s.maximum[p, k] * f),
                "range": float(result.value_range[p, k] * f),
                "lpu_std_uncertainty": float(result.lpu_std_uncertainty[p, k] * f),
            }
        e = result.ellipsoid
        poses.append(
            {
                "pose": p + 1,
                "readings_deg": [float(np.rad2deg(v)) for v in result.readings[p]],
                "coordinates": coordinates,
                "position_uncertainty_mm": float(result.position_uncertainty[p]),
                "position_covariance_mm2": [[float(v) for v in row] for row in result.covariance[p, :3, :3]],
                "covariance": [
                    [float(result.covariance[p, i, j] * deg[i] * deg[j]) for j in range(6)] for i in range(6)
                ],
                "lpu_covariance": [
                    [float(result.lpu_covariance[p, i, j] * deg[i] * deg[j]) for j in range(6)] for i in range(6)
                ],
                "ellipsoid": {
                    "semi_axes_mm": [float(v) for v in e.semi_axes[p]],
                    "directions": [[float(e.directions[p, r, c]) for r in range(3)] for c in range(3)],
                    "fraction_inside": float(e.fraction_inside[p]),
                    "monte_carlo_semi_axes_mm": [float(v) for v in e.monte_carlo_semi_axes[p]],
                },
            }
        )
    return poses


def test_vectorised_dict_equals_the_number_by_number_conversion():
    from robotcal.io.results.tcp_results import tcp_to_dict

    rng = np.random.default_rng(1)
    draws = ROBOT.nominal[None] + rng.normal(0.0, 1e-3, (50, ROBOT.n_joints, 5)) * ~ROBOT.structurally_fixed
    readings = np.deg2rad([[10.0, -80.0, 100.0, 20.0, 50.0, -30.0], [-40.0, -60.0, 90.0, 170.0, -30.0, 100.0]])
    result = propagate_to_tcp(ROBOT, draws, readings)
    for interval in ("symmetric", "shortest"):
        # exact equality: the same float64 products, converted in bulk instead of one by one
        assert tcp_to_dict(result, interval=interval)["poses"] == _reference_dict_poses(result, interval)


def test_json_text_is_the_document_with_one_pose_per_line(tmp_path):
    from robotcal.io.results.tcp_results import tcp_json_text, tcp_to_dict

    rng = np.random.default_rng(2)
    draws = ROBOT.nominal[None] + rng.normal(0.0, 1e-3, (30, ROBOT.n_joints, 5)) * ~ROBOT.structurally_fixed
    readings = np.deg2rad([[10.0, -80.0, 100.0, 20.0, 50.0, -30.0]] * 3)
    result = propagate_to_tcp(ROBOT, draws, readings)
    data = tcp_to_dict(result, provenance={"mode": "trajectory", "versions": {"numpy": np.__version__}})
    text = tcp_json_text(data)
    assert _strict(text) == data
    assert list(_strict(text)) == list(data)  # key order kept
    pose_lines = [line for line in text.splitlines() if line.lstrip().startswith('{"pose": ')]
    assert len(pose_lines) == result.n_poses
    assert text.endswith("}\n") and '\n  "robot": ' in text
    data["poses"][1]["position_uncertainty_mm"] = float("nan")
    with pytest.raises(ValueError, match="JSON compliant"):
        tcp_json_text(data)


def test_csv_text_is_that_of_the_csv_module():
    """``tcp_to_csv`` formats whole rows with ``%``; the truth is the csv module writing ``f"{v:.12g}"`` cells,
    checked on a result whose numbers include -0.0, NaN, infinities and values needing exponents."""
    import csv
    import dataclasses
    import io

    from robotcal.io.results.tcp_results import TCP_CSV_COLUMNS, _file_units, tcp_to_csv
    from robotcal.uncertainty.tcp import TCP_COORDINATES, TCP_UNITS

    rng = np.random.default_rng(1)
    draws = ROBOT.nominal[None] + rng.normal(0.0, 1e-3, (30, ROBOT.n_joints, 5)) * ~ROBOT.structurally_fixed
    result = propagate_to_tcp(ROBOT, draws, np.deg2rad([[10.0, -80.0, 100.0, 20.0, 50.0, -30.0]] * 3))
    mean = result.summary.mean.copy()
    mean[0, :4] = [-0.0, np.nan, np.inf, -np.inf]
    mean[1, :3] = [1.234567890123456e-300, -9.87654321e22, 123456789012345.0]
    result = dataclasses.replace(result, summary=dataclasses.replace(result.summary, mean=mean))
    for interval in ("symmetric", "shortest"):
        low, high = result.summary.interval(interval)
        columns = [
            _file_units(a)
            for a in (
                result.nominal,
                mean,
                result.summary.std_uncertainty,
                low,
                high,
                result.summary.minimum,
                result.summary.maximum,
                result.lpu_std_uncertainty,
            )
        ]
        stream = io.StringIO()
        writer = csv.writer(stream, lineterminator="\n")
        writer.writerow(TCP_CSV_COLUMNS)
        for pose in range(result.n_poses):
            for k, (name, unit) in enumerate(zip(TCP_COORDINATES, TCP_UNITS, strict=True)):
                writer.writerow([pose + 1, name, unit, *[f"{column[pose, k]:.12g}" for column in columns]])
        assert tcp_to_csv(result, interval=interval) == stream.getvalue()
