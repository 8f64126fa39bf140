"""Measurement sessions (issue 29): a capture over two tracker stations and two days, a target re-seated between
them; per-session base frames and offsets refined jointly with the robot, and a held-out capture from a station
that is not the recorded one flagged by evaluate."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from robotcal.capture import Capture, join_captures
from robotcal.errors import IdentifiabilityWarning, InputError
from robotcal.geometry.transforms import rot_x, rot_z
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.identification.targets import Target, split_by_session
from robotcal.instruments import Instrument
from robotcal.io.formats.capture_csv import capture_to_csv, read_capture_text
from robotcal.io.schema.robots import load_robot
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses
from robotcal.simulation.sessions import SimulatedSession, simulate_sessions

ROBOT = load_robot("kuka-kr5-sixx-r650")
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.2, angle_sd_deg=0.05, rng=np.random.default_rng(7))
NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)
STATION_1 = np.array([[0.0, 1.0, 0.0, 1800.0], [-1.0, 0.0, 0.0, 50.0], [0.0, 0.0, 1.0, 600.0], [0.0, 0.0, 0.0, 1.0]])
# the tracker moved by about 500 mm and 10 deg
STATION_2 = STATION_1 @ rot_z(np.deg2rad(10.0)) @ rot_x(np.deg2rad(2.0))
STATION_2[:3, 3] += [350.0, -330.0, 120.0]
OFFSETS = np.array([[60.0, 0.0, 30.0], [0.0, 55.0, 40.0], [-45.0, -20.0, 35.0]])
RESEATED = OFFSETS + [[0.8, -0.5, 0.3], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]  # target A moved by about 1 mm
TARGETS = (
    Target(name="A", frame="flange", positions=np.zeros(3), known=False, per_session=True),
    Target(name="B", frame="flange", positions=np.zeros(3), known=False),
    Target(name="C", frame="flange", positions=OFFSETS[2]),
)


def _sessions(station_2=STATION_2):
    readings = random_poses(ROBOT, 60, rng=np.random.default_rng(11))
    return (
        SimulatedSession(name="day1", readings=readings[:30], tracker_from_base=STATION_1, true_offsets=OFFSETS),
        SimulatedSession(name="day2", readings=readings[30:], tracker_from_base=station_2, true_offsets=RESEATED),
    )


def _refine(capture, start, **settings):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        return refine_parameters(capture, start, TARGETS, settings=RefinementSettings(**settings))


def test_session_column_round_trips_and_joins():
    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH, u95_mm=0.02)
    assert capture.session_names == ("day1", "day2") and capture.session_count == 2
    text = capture_to_csv(capture)
    assert text.splitlines()[0].endswith("x,y,z,target,session,u95_mm")
    again = read_capture_text(text, source="again.csv", n_joints=6)
    assert again.point_sessions == capture.point_sessions and again.point_targets == capture.point_targets
    # any column order, as for target and u95_mm
    header, *rows = text.splitlines()
    columns = header.split(",")
    order = [columns.index(c) for c in ("session", *[c for c in columns if c != "session"])]
    swapped = "\n".join(",".join(line.split(",")[k] for k in order) for line in [header, *rows])
    assert read_capture_text(swapped, source="swapped.csv").point_sessions == capture.point_sessions
    # a file without the column is one session, as before
    plain = read_capture_text(capture_to_csv(capture.select(np.arange(6))).replace(",day1", "").replace(",session", ""),
                              source="p")  # fmt: skip
    assert plain.session is None
    joined = join_captures([(capture.select(np.arange(3)), None), (capture.with_session("day3"), None)], source="j")
    assert joined.session_names == ("day1", "day3")
    with pytest.raises(InputError, match="no `session` column"):
        join_captures([(capture, None), (capture.with_points(capture.points), None),
                       (Capture(circle=[0], direction=[1], readings=np.zeros((1, 6)), points=np.zeros((1, 3)),
                                target=[0], target_names=("A",)), None)], source="j")  # fmt: skip


def test_split_by_session_names_one_offset_per_session():
    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    split, targets = split_by_session(capture, TARGETS)
    assert [t.name for t in targets] == ["A@day1", "A@day2", "B", "C"]
    assert set(split.target_names) == {"A@day1", "A@day2", "B", "C"}


def test_two_stations_two_days_recover_the_noise_free_truth():
    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    result = _refine(capture, ParameterSet.nominal(ROBOT))
    assert result.success
    free = result.identifiability.free
    np.testing.assert_allclose(result.parameters.values[free], TRUTH.values[free], rtol=0, atol=1e-8)
    assert result.fit.residual_max < 1e-8
    by_name = {t.name: t.positions for t in result.targets}
    np.testing.assert_allclose(by_name["A@day1"], OFFSETS[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(by_name["A@day2"], RESEATED[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(by_name["B"], OFFSETS[1], rtol=0, atol=1e-8)
    frames = {frame.name: frame for frame in result.sessions}
    assert list(frames) == ["day1", "day2"]
    # d1, theta1 are a gauge of a free base frame: compare each station's frame where the robot is the truth's
    correction = _gauge_correction(result.parameters, TRUTH)
    np.testing.assert_allclose(frames["day1"].tracker_from_base @ correction, STATION_1, rtol=0, atol=1e-8)
    np.testing.assert_allclose(frames["day2"].tracker_from_base @ correction, STATION_2, rtol=0, atol=1e-8)
    np.testing.assert_allclose(result.tracker_from_base, frames["day1"].tracker_from_base)


def test_given_base_holds_the_first_session_and_estimates_the_others():
    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine_parameters(capture, ParameterSet.nominal(ROBOT), TARGETS, tracker_from_base=STATION_1)
    assert not result.identifiability.base_free.any()
    free = result.identifiability.free
    assert free[0, 0] and free[0, 1]  # d1, theta1: a held base frame makes them free
    np.testing.assert_allclose(result.parameters.values[free], TRUTH.values[free], rtol=0, atol=1e-8)
    frames = {frame.name: frame for frame in result.sessions}
    np.testing.assert_allclose(frames["day2"].tracker_from_base, STATION_2, rtol=0, atol=1e-8)
    assert np.all(np.isnan(frames["day1"].standard_uncertainty))


def test_distances_use_pairs_within_a_session_only():
    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    result = _refine(capture, ParameterSet.nominal(ROBOT), criterion="distances")
    n = capture.n_points // 2
    assert result.fit.n_residuals <= 2 * n * (n - 1) // 2
    free = result.identifiability.free
    np.testing.assert_allclose(result.parameters.values[free], TRUTH.values[free], rtol=0, atol=1e-8)
    assert result.sessions == ()


def _gauge_correction(fitted: ParameterSet, truth: ParameterSet) -> np.ndarray:
    """The base-side motion ``G`` with ``T_fit G = T_true`` when the fit's d1, theta1 differ from the truth's:
    ``Rz(theta1) Tz(d1)`` of the fit undone and the truth's applied."""
    def base(values):
        transform = rot_z(values[0, 1])
        transform[2, 3] = values[0, 0]
        return transform

    return base(fitted.values) @ np.linalg.inv(base(truth.values))


# -- evaluate: each session registered on its own, a station that is not the recorded one flagged ---------------


def _held_out(station, name="day2", seed=5):
    readings = random_poses(ROBOT, 15, rng=np.random.default_rng(seed))
    session = SimulatedSession(name=name, readings=readings, tracker_from_base=station, true_offsets=RESEATED)
    return simulate_sessions(ROBOT, (session,), TARGETS, NOISE_FREE, true_parameters=TRUTH)[0]


def test_held_out_capture_from_an_unknown_station_is_flagged():
    from robotcal.identification.evaluation import GuessedOffsetWarning, StationMovedWarning, evaluate_parameters

    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    result = _refine(capture, ParameterSet.nominal(ROBOT))
    frames = {frame.name: frame.tracker_from_base for frame in result.sessions}
    offsets = {t.name: tuple(t.positions) for t in result.targets if not t.known}
    elsewhere = STATION_2 @ rot_z(np.deg2rad(8.0))
    elsewhere[:3, 3] += [430.0, 200.0, -50.0]
    captures = {"same": _held_out(STATION_2), "elsewhere": _held_out(elsewhere), "unnamed": _held_out(elsewhere, "x")}
    with pytest.warns(StationMovedWarning, match="another tracker station") as caught, warnings.catch_warnings():
        warnings.simplefilter("ignore", GuessedOffsetWarning)  # session x: target A re-seated, its offset unknown
        rows = evaluate_parameters(
            captures, {"refined": result.parameters}, dict.fromkeys(captures, TARGETS),
            views=("points", "absolute"), bases={"refined": frames}, set_targets={"refined": offsets},
        )  # fmt: skip
    assert {str(w.message).split("'")[1] for w in caught if w.category is StationMovedWarning} == {
        "elsewhere", "unnamed"}  # fmt: skip
    by = {(row.capture, row.view): row for row in rows}
    assert by["same", "absolute"].rms_error_mm < 1e-8 and by["same", "absolute"].station == ""
    assert by["elsewhere", "absolute"].station == "moved" and by["elsewhere", "absolute"].rms_error_mm > 100.0
    assert by["unnamed", "absolute"].station == "moved"
    for name in ("same", "elsewhere"):  # the capture's own registration: the model is exact wherever the tracker stood
        assert by[name, "points"].rms_error_mm < 1e-8


def test_points_view_registers_each_session_on_its_own():
    from robotcal.identification.evaluation import point_errors

    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    offsets = {"A@day1": OFFSETS[0], "A@day2": RESEATED[0], "B": OFFSETS[1]}
    relabelled, split = split_by_session(capture, TARGETS)
    known = tuple(t.with_position(offsets[t.name]) if t.name in offsets else t for t in split)
    assert point_errors(relabelled, TRUTH, known).max() < 1e-8


def test_parameter_json_records_the_session_frames(tmp_path):
    from robotcal.io.formats.parameters_json import (
        read_sessions,
        read_targets,
        refined_sessions,
        refined_targets,
        write_parameters,
    )

    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    result = _refine(capture, ParameterSet.nominal(ROBOT))
    path = write_parameters(
        tmp_path / "p.json", result.parameters, {}, refined_targets(result),
        extensions={"sessions": refined_sessions(result)},
    )  # fmt: skip
    frames = read_sessions(path)
    assert list(frames) == ["day1", "day2"]
    np.testing.assert_allclose(frames["day2"], result.sessions[1].tracker_from_base, rtol=0, atol=1e-12)
    assert {"A@day1", "A@day2", "B"} <= set(read_targets(path))
    import json

    u = json.loads(path.read_text())["sessions"]["day2"]["u"]
    assert set(u) == {"tx_mm", "ty_mm", "tz_mm", "rx_deg", "ry_deg", "rz_deg"}


def test_measured_monte_carlo_runs_over_sessions():
    from robotcal.uncertainty.measured import measured_monte_carlo
    from robotcal.uncertainty.montecarlo import MonteCarloSettings

    tracker = Instrument(name="tracker", a_mm=0.02, b_mm_per_m=0.0, noise="normal", coverage_factor=2.0)
    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, tracker, true_parameters=TRUTH, u95_mm=0.02, rng=4)
    estimate = _refine(capture, ParameterSet.nominal(ROBOT))
    result = measured_monte_carlo(capture, estimate, TARGETS, MonteCarloSettings(iterations=21), seed=1)
    assert result.target_names == ("A@day1", "A@day2", "B")
    # the draws scatter like the linearised u: the same noise model, the same per-session frames
    u_draws = result.target_summary.std_uncertainty[1]
    u_linear = result.target_linearised_u[1]
    assert np.all((u_draws > 0.4 * u_linear) & (u_draws < 2.0 * u_linear)), (u_draws, u_linear)


@pytest.mark.parametrize("criterion", ["points", "distances"])
def test_cross_validation_predicts_each_session_in_its_own_frame(criterion):
    from robotcal.identification.model_choice import refine_model

    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine_model(capture, ParameterSet.nominal(ROBOT), TARGETS,
                              settings=RefinementSettings(criterion=criterion))  # fmt: skip
    assert result.cross_validation.folds == 5 and result.cross_validation.cv_rms_mm < 1e-8


def test_a_set_whose_own_model_is_off_does_not_flag_the_station():
    from robotcal.identification.evaluation import StationMovedWarning, evaluate_parameters

    capture, _ = simulate_sessions(ROBOT, _sessions(), TARGETS, NOISE_FREE, true_parameters=TRUTH)
    result = _refine(capture, ParameterSet.nominal(ROBOT))
    frames = {frame.name: frame.tracker_from_base for frame in result.sessions}
    offsets = {t.name: tuple(t.positions) for t in result.targets if not t.known}
    values = result.parameters.values.copy()
    values[0, 1] += np.deg2rad(0.5)  # J1.theta 0.5 deg off: a rigid turn of every point, ~5 mm at the flange
    off = ParameterSet(robot=ROBOT, values=values)
    sets = {"off": off, "refined": result.parameters}
    with warnings.catch_warnings():
        warnings.simplefilter("error", StationMovedWarning)
        rows = evaluate_parameters(
            {"same": _held_out(STATION_2)}, sets, {"same": TARGETS}, views=("points", "absolute"),
            bases=dict.fromkeys(sets, frames), set_targets=dict.fromkeys(sets, offsets),
        )  # fmt: skip
    absolute = {row.parameter_set: row for row in rows if row.view == "absolute"}
    assert absolute["off"].rms_error_mm > 1.0 and not any(row.station for row in rows)
