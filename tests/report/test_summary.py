"""robotcal.io.results.run_summary: the headline figures from a hand-made documents mapping.

The expected figures are worked out by hand from the documents below (independent of numpy):
the median and 95th percentile of (1, 2, 3, 4, 5) um by linear interpolation between order statistics
are 3 and 4 + 0.8 * (5 - 4) = 4.8 um; the largest identified u skips a larger unidentified one.
"""

from __future__ import annotations

import math

import pytest

from robotcal.io.results.run_folder import Table
from robotcal.io.results.run_summary import CONSISTENT_RATIO, Summary, summarise

WORKSPACE_UM = (4.0, 1.0, 5.0, 2.0, 3.0)


def _tcp(values_mm, *, model="refined (CPA + points refinement), Monte Carlo"):
    poses = [{"pose": k + 1, "position_uncertainty_mm": value} for k, value in enumerate(values_mm)]
    poses[0]["ellipsoid"] = {"semi_axes_mm": [0.01, 0.03, 0.02]}
    return {"coverage": 0.95, "poses": poses, "provenance": {"model": model}}


def _parameters(entries, draws):
    return {
        "draws": draws,
        "parameters": [
            {"name": name, "unit": unit, "identified": identified, "std_uncertainty": u}
            for name, unit, identified, u in entries
        ],
    }


def documents() -> dict:
    return {
        "evaluation/evaluation.json": {
            "headline": {
                "capture": "validation",
                "view": "points",
                "before_label": "nominal",
                "after_label": "points",
                "before_mean_mm": 0.59,
                "after_mean_mm": 0.077,
            }
        },
        "evaluation/evaluation.csv": Table(header=("parameter_set", "mean_error_mm"), rows=(("nominal", "9"),)),
        "cpa/parameters.json": {
            "provenance": {
                "circles": [
                    {"circle": 1, "circle_rms_mm": 0.004},
                    {"circle": 2, "circle_rms_mm": 0.011},
                    {"circle": 3, "circle_rms_mm": 0.007},
                ]
            }
        },
        "uncertainty-refined/parameters.json": _parameters(
            [
                ("J1.d", "mm", True, 0.002),
                ("J3.a", "mm", True, 0.005),
                ("J6.d", "mm", False, 9.0),  # not identified: never the largest
                ("J2.theta", "deg", True, 0.0039),
                ("J1.alpha", "deg", True, 0.001),
            ],
            2000,
        ),
        "uncertainty/parameters.json": _parameters([("J1.a", "mm", True, 0.70), ("J2.beta", "deg", True, 0.136)], 500),
        "tcp/pose/tcp.json": _tcp([0.0158]),
        "tcp/workspace/tcp.json": _tcp([u / 1000 for u in WORKSPACE_UM]),
        "tcp/trajectory/tcp.json": _tcp([0.02, 0.03, 0.025]),
        "tcp/consistency.json": {
            "model": "refined (CPA + points refinement)",
            "poses": 100,
            "base_frame": "given",
            "predicted_rms_mm": 0.03,
            "instrument_rms_mm": 0.016,
            "expected_rms_mm": 0.034,
            "observed_rms_mm": 0.091,
            "ratio": 0.091 / 0.034,
        },
    }


RECORD = {
    "stages": {"refine": {"status": "done", "warnings": ["b warning", "a warning"]}, "tcp": {"status": "done"}},
    "notes": ["a note", "a warning"],
}


def test_every_figure_from_its_key():
    summary = summarise(RECORD, documents())
    assert (summary.validation_before_mm, summary.validation_after_mm) == (0.59, 0.077)
    assert (summary.validation_before_set, summary.validation_after_set) == ("nominal", "points")
    assert (summary.validation_capture, summary.validation_view) == ("validation", "points")
    assert (summary.circle_rms_mm, summary.circle_rms_circle, summary.circles) == (0.011, 2, 3)
    refined, cpa = summary.uncertainties
    assert refined.folder == "uncertainty-refined" and summary.uncertainty("uncertainty") is cpa
    assert (refined.length_mm, refined.length_name, refined.angle_deg, refined.angle_name) == (
        0.005,
        "J3.a",
        0.0039,
        "J2.theta",
    )
    assert (refined.draws, cpa.draws, cpa.length_mm, cpa.angle_name) == (2000, 500, 0.70, "J2.beta")
    assert summary.tcp_pose.first_mm == 0.0158 and summary.tcp_pose.poses == 1
    assert summary.tcp_pose.ellipsoid_mm == 0.03 and summary.tcp_pose.coverage == 0.95
    workspace = summary.tcp_workspace
    assert workspace.poses == 5 and workspace.first_mm == pytest.approx(0.004, abs=1e-15)
    assert workspace.median_mm == pytest.approx(0.003, abs=1e-15)
    assert workspace.p95_mm == pytest.approx(0.0048, abs=1e-15)
    assert (workspace.min_mm, workspace.max_mm) == pytest.approx((0.001, 0.005), abs=1e-15)
    assert (summary.tcp_trajectory.min_mm, summary.tcp_trajectory.max_mm) == (0.02, 0.03)
    check = summary.consistency
    assert check.ratio == pytest.approx(0.091 / 0.034) and not check.consistent and "exceeds" in check.verdict
    assert summary.notes == ("a warning", "b warning", "a note")


def test_console_lines():
    lines = summarise(RECORD, documents()).console_lines()
    assert lines == [
        "how good: mean validation error 0.5900 mm (nominal) -> 0.0770 mm (refined, points criterion)",
        "how sure, refined (deployed) model: largest standard uncertainty of the parameters its refinement determines "
        "0.0050 mm (lengths), 0.0039 deg (angles); 2,000 draws",
        "how sure, CPA model: largest standard uncertainty 0.7000 mm (lengths), 0.1360 deg (angles); 500 draws",
        "consistency at the 100 validation poses: predicted RMS position uncertainty 0.0300 mm, with the instrument "
        "0.0340 mm; observed RMS error 0.0910 mm (ratio 2.68: not explained by the stated uncertainty)",
        "TCP position uncertainty at the pose: 0.0158 mm (refined (CPA + points refinement), Monte Carlo)",
        "where: over 5 workspace poses the TCP position uncertainty is 0.0030 mm (median), 0.0048 mm "
        "(95th percentile), 0.0050 mm (worst)",
    ]


def test_consistent_at_the_ratio_limit():
    docs = documents()
    docs["tcp/consistency.json"]["ratio"] = CONSISTENT_RATIO
    assert summarise({}, docs).consistency.consistent
    docs["tcp/consistency.json"]["ratio"] = math.nextafter(CONSISTENT_RATIO, 2.0)
    assert not summarise({}, docs).consistency.consistent


def test_nothing_run_gives_nones():
    summary = summarise({}, {})
    assert summary == Summary()
    assert summary.console_lines() == []


@pytest.mark.parametrize(
    ("name", "broken"),
    [
        ("evaluation/evaluation.json", {"headline": {"before_mean_mm": "0.59", "after_mean_mm": None}}),
        ("cpa/parameters.json", {"provenance": {"circles": "none"}}),
        ("uncertainty-refined/parameters.json", {"parameters": [{"unit": "mm", "identified": "true"}]}),
        ("tcp/workspace/tcp.json", {"poses": [{"position_uncertainty_mm": 0.01}, {}]}),
        ("tcp/consistency.json", {"expected_rms_mm": 0.03, "observed_rms_mm": float("nan"), "ratio": 1.0}),
    ],
)
def test_malformed_document_gives_none_not_an_error(name, broken):
    docs = documents()
    docs[name] = broken
    summary = summarise(RECORD, docs)
    figure = {
        "evaluation/evaluation.json": summary.validation_before_mm,
        "cpa/parameters.json": summary.circle_rms_mm,
        "uncertainty-refined/parameters.json": getattr(summary.uncertainty("uncertainty-refined"), "length_mm", None),
        "tcp/workspace/tcp.json": summary.tcp_workspace,
        "tcp/consistency.json": summary.consistency,
    }[name]
    assert figure is None
    assert summary.tcp_pose is not None  # the others are still there


def test_a_csv_where_a_json_is_expected_is_ignored():
    docs = documents()
    docs["tcp/pose/tcp.json"] = Table(header=("pose",), rows=(("1",),))
    assert summarise({}, docs).tcp_pose is None


def test_the_refined_models_largest_u_leaves_out_what_its_refinement_does_not_determine():
    """Issue 30: a parameter the refinement holds, or one confounded with a held one, is not the headline's largest u
    (on the console and in the report); it is set aside with why."""
    docs = dict(documents())
    docs["refine/points.json"] = {"provenance": {"held": ["J6.alpha"], "confounded": ["J3.a"]}}
    refined = summarise(RECORD, docs).uncertainty("uncertainty-refined")
    assert refined.length_name != "J3.a" and refined.length_mm < 0.005
    u, name, why = refined.set_aside["mm"]
    assert (u, name) == (0.005, "J3.a") and "confounded with the held J6.alpha" in why
    assert "deg" not in refined.set_aside  # J2.theta is determined
