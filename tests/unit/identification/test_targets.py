"""Several targets per pose, unknown flange offsets, per-point U(95) weights, duplicate poses, angle
wrapping, fit health and scenarios without a capture plan (issue 14)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import refine_options
from robotcal.api import capture_targets, refine
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityError, IdentifiabilityWarning, InputError
from robotcal.identification.health import FitHealthError, FitHealthWarning, circle_axis_uncertainty
from robotcal.identification.refine import measurement_pairs, refine_parameters, wrap_angles
from robotcal.identification.settings import RefinementSettings
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.formats.capture_csv import read_capture, write_capture
from robotcal.io.formats.parameters_json import read_parameters, read_targets, refined_targets, write_parameters
from robotcal.io.schema.robots import load_robot
from robotcal.io.schema.scenario import scenario_from_dict
from robotcal.kinematics.forward import forward_kinematics
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.generator import simulate_target_poses
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses

ROBOT = load_robot("kuka-kr5-sixx-r650")
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.2, angle_sd_deg=0.05, rng=np.random.default_rng(7))
TRACKER = np.array([[0.0, 1.0, 0.0, 1800.0], [-1.0, 0.0, 0.0, 50.0], [0.0, 0.0, 1.0, 600.0], [0.0, 0.0, 0.0, 1.0]])
TRUE_OFFSETS = np.array([[60.0, 0.0, 30.0], [0.0, 55.0, 40.0], [-45.0, -20.0, 35.0]])
UNKNOWN = tuple(Target(name=f"T{k + 1}", frame="flange", positions=np.zeros(3), known=False) for k in range(3))
NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)


def _tracker_noise(u95_mm: float) -> Instrument:
    return Instrument(name="tracker", a_mm=u95_mm, b_mm_per_m=0.0, noise="normal", coverage_factor=2.0)


def _capture(instrument=NOISE_FREE, *, poses=30, seed=3, u95_mm=None, targets=UNKNOWN):
    readings = random_poses(ROBOT, poses, rng=np.random.default_rng(11))
    capture, exact = simulate_target_poses(
        ROBOT,
        readings,
        targets,
        instrument,
        TRACKER,
        true_parameters=TRUTH,
        true_offsets=TRUE_OFFSETS[: len(targets)],
        u95_mm=u95_mm,
        rng=seed,
    )
    return capture, exact


def _refine(*args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)  # J6's d, theta, a, alpha held: by design
        return refine_options.refine(*args, **kwargs)


# -- the simulator, against an independent forward kinematics ---------------------------------------


def test_simulated_targets_are_the_flange_frame_applied_to_each_offset():
    capture, exact = _capture()
    assert capture.n_points == 90 and capture.target_names == ("T1", "T2", "T3")
    q = ROBOT.model_joint_variables(capture.readings[::3])
    flange = forward_kinematics(TRUTH.values, q)
    for k, offset in enumerate(TRUE_OFFSETS):
        expected = (TRACKER @ flange @ np.r_[offset, 1.0])[:, :3]
        np.testing.assert_allclose(exact[k::3], expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(capture.points, exact)  # noise-free instrument


# -- capture CSV: optional target and u95_mm columns -------------------------------------------------


def test_capture_csv_round_trip_with_target_and_u95(tmp_path):
    capture, _ = _capture(_tracker_noise(0.02), u95_mm=0.02)
    path = write_capture(tmp_path / "c.csv", capture)
    assert path.read_text().splitlines()[0].endswith(",x,y,z,target,u95_mm")
    back = read_capture(path, n_joints=6)
    assert back.point_targets == capture.point_targets
    np.testing.assert_array_equal(back.u95, capture.u95)
    np.testing.assert_allclose(back.points, capture.points, rtol=0, atol=1e-12)  # 12 decimals written


def test_capture_csv_without_the_new_columns_loads_as_before(tmp_path):
    path = tmp_path / "old.csv"
    path.write_text("circle,direction,q1,q2,x,y,z\n0,1,10,20,1,2,3\n0,1,11,21,4,5,6\n")
    capture = read_capture(path)
    assert capture.target is None and capture.target_names == () and capture.u95 is None


@pytest.mark.parametrize(
    ("row", "message"),
    [("0,1,10,20,1,2,3,,0.02", "line 3, column `target`: empty target name"), ("0,1,10,20,1,2,3,A,0", "U\\(95\\) must be > 0")],
)
def test_capture_csv_new_columns_errors_name_line_and_column(tmp_path, row, message):
    path = tmp_path / "bad.csv"
    path.write_text(f"circle,direction,q1,q2,x,y,z,target,u95_mm\n0,1,10,20,1,2,3,A,0.02\n{row}\n")
    with pytest.raises(InputError, match=message):
        read_capture(path)


# -- refinement: several targets, unknown offsets ---------------------------------------------------


@pytest.mark.parametrize(
    ("criterion", "base"), [("points", "given"), ("points", "estimated"), ("distances", None)]
)
def test_noise_free_parameters_and_unknown_offsets_are_recovered(criterion, base):
    capture, _ = _capture()
    kwargs = {"tracker_from_base": TRACKER} if base == "given" else {}
    with pytest.warns(IdentifiabilityWarning, match="an unknown offset is confounded with J6's d, theta, a, alpha"):
        result = refine_options.refine(capture, ParameterSet.nominal(ROBOT), UNKNOWN, criterion=criterion, **kwargs)
    # the flange frame stays nominal: J6's parameters are held, the offsets are estimated in it
    assert set(result.identifiability.held) == {"J6.d", "J6.theta", "J6.a", "J6.alpha"}
    assert {f"target.T{k}.{axis}" for k in (1, 2, 3) for axis in "xyz"} <= set(result.identifiability.free_names)
    # the truth's joint 6 is nominal (perturb_parameters leaves joint n alone), so everything is recoverable
    free = result.identifiability.free
    np.testing.assert_allclose(result.parameters.values[free], wrap_angles(TRUTH.values)[free], rtol=0, atol=1e-9)
    estimated = np.array([target.positions for target in result.targets])
    np.testing.assert_allclose(estimated, TRUE_OFFSETS, rtol=0, atol=1e-9)
    assert result.success and result.fit.residual_rms < 1e-9


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noisy_offsets_and_parameters_lie_within_their_reported_uncertainty(seed):
    capture, _ = _capture(_tracker_noise(0.02), seed=seed)
    result = _refine(capture, ParameterSet.nominal(ROBOT), UNKNOWN, tracker_from_base=TRACKER)
    estimated = np.array([target.positions for target in result.targets])
    z_offsets = (estimated - TRUE_OFFSETS) / result.uncertainty.target_uncertainty
    free = result.identifiability.free
    z_parameters = (result.parameters.values[free] - wrap_angles(TRUTH.values)[free]) / result.uncertainty.standard_uncertainty[free]
    # 9 + ~24 standard-normal z values per seed: |z| < 4 fails with probability ~2e-3 per seed
    assert np.all(np.abs(z_offsets) < 4.0) and np.all(np.abs(z_parameters) < 4.0)
    np.testing.assert_allclose(result.uncertainty.sigma, 0.01, rtol=0.2)  # U = 0.02 mm, k = 2: sigma = 0.01 mm


def test_one_known_target_fixes_the_flange_frame_for_the_unknown_ones():
    known = Target(name="T1", frame="flange", positions=TRUE_OFFSETS[0])
    targets = (known, *UNKNOWN[1:])
    capture, _ = _capture()
    result = _refine(capture, ParameterSet.nominal(ROBOT), targets, tracker_from_base=TRACKER)
    # the known target fixes J6's d, theta, a; alpha_6 stays held, as with one flange target (module notes)
    assert {"J6.d", "J6.theta", "J6.a"} <= set(result.identifiability.free_names) and "J6.alpha" in result.identifiability.held
    np.testing.assert_allclose(result.targets[1].positions, TRUE_OFFSETS[1], rtol=0, atol=1e-8)
    assert np.all(np.isnan(result.uncertainty.target_uncertainty[0]))  # a known target has no estimate


def test_a_single_unknown_target_is_reported_confounded_with_joint_6():
    capture, _ = _capture(targets=UNKNOWN[:1])
    with pytest.warns(IdentifiabilityWarning, match="confounded with J6's d, theta, a, alpha"):
        result = refine_parameters(capture, ParameterSet.nominal(ROBOT), UNKNOWN[:1], tracker_from_base=TRACKER)
    assert {"target.T1.x", "target.T1.y", "target.T1.z"} <= set(result.identifiability.confounded)
    # freeing J6.d explicitly asks for what the data cannot give: an error
    with pytest.raises(IdentifiabilityError):
        refine_parameters(
            capture,
            ParameterSet.nominal(ROBOT),
            UNKNOWN[:1],
            tracker_from_base=TRACKER,
            settings=RefinementSettings(free=["J2.a", "J6.d"]),
        )


def test_strict_does_not_refuse_the_flange_frame_held_for_unknown_offsets():
    capture, _ = _capture()
    with pytest.warns(IdentifiabilityWarning, match="held at their start values"):
        result = refine_parameters(
            capture,
            ParameterSet.nominal(ROBOT),
            UNKNOWN,
            tracker_from_base=TRACKER,
            settings=RefinementSettings(on_unidentifiable="raise"),
        )
    assert result.success


def _held_warning(*args, **kwargs) -> str:
    with pytest.warns(IdentifiabilityWarning) as caught:
        refine_options.refine(*args, **kwargs)
    (warning,) = [w for w in caught if issubclass(w.category, IdentifiabilityWarning)]
    return str(warning.message)


def test_one_held_parameter_is_an_it():
    """Issue 30: "... cannot determine J6.alpha ...; they are held at their start values"."""
    known = Target(name="T1", frame="flange", positions=TRUE_OFFSETS[0])
    capture, _ = _capture()
    message = _held_warning(capture, ParameterSet.nominal(ROBOT), (known, *UNKNOWN[1:]), tracker_from_base=TRACKER)
    assert "cannot determine J6.alpha from this capture" in message
    assert message.endswith("; it is held at its start value")


def test_the_flange_frame_warning_says_held_once():
    """Issue 30: the flange-frame clause says J6's parameters are held, and "; they are held at their start
    values" followed it again."""
    capture, _ = _capture()
    message = _held_warning(capture, ParameterSet.nominal(ROBOT), UNKNOWN, tracker_from_base=TRACKER)
    assert message.count("held at their start values") == 1, message
    assert message.endswith("J6.d, J6.theta, J6.a, J6.alpha are held at their start values and the offsets of T1, T2, "
                            "T3 are estimated in that flange frame")  # fmt: skip


def test_undeclared_target_name_is_an_input_error():
    capture, _ = _capture()
    with pytest.raises(InputError, match="names target 'T3', which is not declared"):
        refine_parameters(capture, ParameterSet.nominal(ROBOT), UNKNOWN[:2], tracker_from_base=TRACKER)


# -- weights from U(95) --------------------------------------------------------------------------------


@pytest.mark.parametrize("criterion", ["points", "distances"])
def test_u95_weight_equals_repeating_the_point(criterion):
    # weight 1/u^2: a point whose U(95) is U/sqrt(2) counts as that point measured twice with U
    # (points criterion exactly; distances: a pair's weight 2/(u_i^2 + u_j^2) is not a repetition, so
    # there only the direction of the effect is checked)
    capture, _ = _capture(_tracker_noise(0.02), poses=12, seed=5, u95_mm=0.02, targets=UNKNOWN[:1])
    known = (Target(name="T1", frame="flange", positions=TRUE_OFFSETS[0]),)
    heavy = np.array([0, 4, 7])
    u95 = capture.u95.copy()
    u95[heavy] /= np.sqrt(2.0)
    weighted = Capture(**{**_fields(capture), "u95": u95})
    rows = np.r_[np.arange(capture.n_points), heavy]
    repeated = capture.select(rows)
    start = ParameterSet.nominal(ROBOT)
    a = _refine(weighted, start, known, tracker_from_base=TRACKER, criterion=criterion)
    b = _refine(repeated, start, known, tracker_from_base=TRACKER, criterion=criterion, weights="none")
    c = _refine(capture, start, known, tracker_from_base=TRACKER, criterion=criterion)
    assert a.fit.weighted and not b.fit.weighted
    if criterion == "points":
        np.testing.assert_allclose(a.parameters.values, b.parameters.values, rtol=0, atol=1e-9)
    else:
        assert not np.allclose(a.parameters.values, c.parameters.values, rtol=0, atol=1e-12)


def _fields(capture):
    return {
        name: getattr(capture, name)
        for name in ("circle", "direction", "readings", "points", "source", "seed", "target", "target_names", "u95")
    }


# -- duplicate poses and angle wrapping ----------------------------------------------------------------


def test_duplicate_poses_360_degrees_apart_do_not_break_the_distances_criterion():
    capture, _ = _capture(_tracker_noise(0.02), poses=10, targets=UNKNOWN[:1])
    twin = capture.select(np.arange(5))
    readings = twin.readings.copy()
    readings[:, 5] += 2.0 * np.pi  # J6 one turn further: the same pose, a new reading
    noise = np.random.default_rng(0).normal(0.0, 0.01, (5, 3))
    both = Capture(
        **{
            **_fields(capture),
            "readings": np.vstack([capture.readings, readings]),
            "points": np.vstack([capture.points, twin.points + noise]),
            "circle": np.zeros(15, dtype=int),
            "direction": np.ones(15, dtype=int),
            "target": np.zeros(15, dtype=int),
            "u95": None,
        }
    )
    _, _, keep = measurement_pairs(both.readings)
    assert (~keep).sum() == 5  # each twin pair left out: model distance 0 for any parameters
    known = (Target(name="T1", frame="flange", positions=TRUE_OFFSETS[0]),)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy "invalid value" (nor any other) warning
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        with np.errstate(all="raise"):
            result = refine_parameters(
                both,
                ParameterSet.nominal(ROBOT),
                known,
                settings=RefinementSettings(criterion="distances"),
            )
    assert result.fit.n_residuals == 15 * 14 // 2 - 5 and np.isfinite(result.uncertainty.sigma)


def test_angles_are_wrapped_in_every_output(tmp_path):
    values = TRUTH.values.copy()
    values[1, 1] = np.deg2rad(-451.3)  # J2.theta one turn and a quarter too far: the same robot
    start = TRUTH.replace(values=values)
    capture, _ = _capture(targets=UNKNOWN[:1])
    known = (Target(name="T1", frame="flange", positions=TRUE_OFFSETS[0]),)
    result = _refine(capture, start, known, tracker_from_base=TRACKER, free=["J2.a"])
    # the fit stays continuous with its start; the outputs wrap
    path = write_parameters(tmp_path / "p.json", result.parameters)
    joints = json.loads(path.read_text())["joints"]
    assert joints[1]["theta"] == pytest.approx(-91.3, abs=1e-9)
    nominal_deg = np.rad2deg(ROBOT.nominal)
    for i, joint in enumerate(joints):  # within 180 deg of the nominal: the nominal's branch
        for k, kind in ((1, "theta"), (3, "alpha"), (4, "beta")):
            assert -180.0 < joint[kind] - nominal_deg[i, k] <= 180.0, (i, kind)
    np.testing.assert_allclose(  # the wrapped file is the same robot
        forward_kinematics(read_parameters(path, ROBOT).values, ROBOT.model_joint_variables(capture.readings)),
        forward_kinematics(result.parameters.values, ROBOT.model_joint_variables(capture.readings)),
        rtol=0,
        atol=1e-9,
    )
    expected = np.deg2rad([[0.0, 180.0, 0.0, 180.0, 179.0]])
    np.testing.assert_array_equal(wrap_angles(np.deg2rad([[0.0, 180.0, 0.0, -180.0, 179.0]])), expected)
    np.testing.assert_allclose(wrap_angles(np.deg2rad([[0.0, 540.5, 0.0, -190.0, 0.0]])), np.deg2rad([[0, 180.5 - 360, 0, 170, 0]]), atol=1e-12)


def test_angles_are_wrapped_into_the_branch_of_their_nominal(tmp_path):
    """A J5.theta of nominal 180 deg estimated at 180.08 deg is written 180.08, never -179.92: estimate, truth
    and their difference stay in one branch (the report's "CPA - truth" column subtracts them)."""
    nominal = np.zeros((1, 5))
    nominal[0, 1] = np.pi  # theta nominal 180 deg
    estimate = np.deg2rad([[0.0, -179.92, 0.0, 0.0, 0.0]])
    np.testing.assert_allclose(np.rad2deg(wrap_angles(estimate, nominal))[0, 1], 180.08, atol=1e-12)
    np.testing.assert_allclose(np.rad2deg(wrap_angles(np.deg2rad([[0, -451.3, 0, 0, 0]]), nominal))[0, 1], 268.7, atol=1e-9)
    inside = np.deg2rad([[0.0, 200.0, 10.0, -30.0, 0.5]])
    np.testing.assert_array_equal(wrap_angles(inside, nominal), inside)  # already in the branch: every bit kept
    # the parameter JSON of the KR 5 (J5.theta nominal 180 deg) keeps the nominal's branch
    kr5 = load_robot("kuka-kr5-sixx-r650")
    j5 = int(np.flatnonzero(np.isclose(np.abs(kr5.nominal[:, 1]), np.pi))[0])
    values = kr5.nominal.copy()
    values[j5, 1] = np.deg2rad(-179.92) * np.sign(kr5.nominal[j5, 1])
    path = write_parameters(tmp_path / "kr5.json", ParameterSet(robot=kr5, values=values))
    written = json.loads(path.read_text())["joints"][j5]["theta"]
    assert abs(written - np.rad2deg(kr5.nominal[j5, 1])) == pytest.approx(0.08, abs=1e-9)


# -- fit health -----------------------------------------------------------------------------------------


def test_circle_axis_uncertainty_matches_the_full_circle_formula():
    # N points on a full circle of radius r: in-plane scatter N r^2 / 2, so u_axis = u / (r sqrt(N / 2))
    angles = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    points = np.column_stack([5.0 * np.cos(angles), 5.0 * np.sin(angles), np.zeros(24)]) + [100.0, 0.0, 0.0]
    u_axis, radius = circle_axis_uncertainty(points, 0.01)
    assert u_axis == pytest.approx(0.01 / (5.0 * np.sqrt(12.0)), rel=1e-12) and radius == pytest.approx(5.0)


PLANLESS = """
robot = "kuka-kr5-sixx-r650"
tracker_from_base = [[0.0, 1.0, 0.0, 1800.0], [-1.0, 0.0, 0.0, 50.0], [0.0, 0.0, 1.0, 600.0], [0.0, 0.0, 0.0, 1.0]]
[instrument]
a_um = 20.0
b_um_per_m = 0.0
noise = "normal"
[[targets]]
name = "T1"
flange_mm = "unknown"
guess_mm = [50.0, 0.0, 20.0]
[[targets]]
name = "T2"
flange_mm = "unknown"
[[targets]]
name = "T3"
flange_mm = "unknown"
"""


def test_refine_scenario_without_a_plan_warns_on_a_wrong_known_offset():
    scenario = scenario_from_dict(_toml(PLANLESS), source="cell.toml")
    assert not scenario.has_plan and [t.name for t in scenario.targets] == ["T1", "T2", "T3"]
    capture, _ = _capture(_tracker_noise(0.02))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine(capture, scenario, ParameterSet.nominal(ROBOT))  # healthy: no FitHealthWarning
    saved = refined_targets(result)
    assert saved["T2"]["known"] is False and all(u > 0 for u in saved["T2"]["u_mm"])
    np.testing.assert_allclose(saved["T2"]["flange_mm"], TRUE_OFFSETS[1], atol=0.05)
    # two known targets 10 mm closer together than they are: no parameter set explains that
    wrong_text = PLANLESS.replace('flange_mm = "unknown"\nguess_mm = [50.0, 0.0, 20.0]', "flange_mm = [60.0, 0.0, 30.0]")
    wrong_text = wrong_text.replace('name = "T2"\nflange_mm = "unknown"', 'name = "T2"\nflange_mm = [0.0, 45.0, 40.0]')
    wrong = scenario_from_dict(_toml(wrong_text), source="cell.toml")
    assert [t.known for t in wrong.targets] == [True, True, False]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        # a known offset 10 mm wrong leaves millimetres no robot has: an input error, FAILED
        with pytest.warns(FitHealthWarning, match="fit health FAILED: the residual .* beyond what a calibrated robot"):
            result = refine(capture, wrong, ParameterSet.nominal(ROBOT))
        assert result.health.verdict == "FAILED" and "target or target offset" in result.health.problems[0]
        with pytest.raises(FitHealthError, match="fit health FAILED"):
            refine(capture, wrong, ParameterSet.nominal(ROBOT), health="strict")


def test_missing_plan_and_instrument_name_the_key_and_the_commands():
    text = "\n".join(line for line in PLANLESS.splitlines() if not line.startswith(("a_um", "b_um", "noise", "[instrument]")))
    scenario = scenario_from_dict(_toml(text), source="cell.toml")
    with pytest.raises(InputError, match=r"cell.toml: key `capture.start_deg` .* needed by simulate"):
        scenario.plan.reflector  # noqa: B018
    with pytest.raises(InputError, match=r"cell.toml: key `instrument` is missing"):
        scenario.instrument.standard_uncertainty  # noqa: B018
    capture, _ = _capture()
    assert capture_targets(scenario, capture) == scenario.targets


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('[[targets]]\nname = "A"\nguess_mm = [1.0, 2.0, 3.0]\nflange_mm = [0.0, 0.0, 1.0]', "`guess_mm` is the start"),
        ('[[targets]]\nname = "A"\nflange_mm = [1.0, 2.0]', "targets\\[0\\].flange_mm` must be \\[x, y, z\\]"),
        ('[[targets]]\nname = "A"\nflange_mm = [1.0, 2.0, 3.0]\n[[targets]]\nname = "A"\nflange_mm = "unknown"', "declared twice"),
        ("[capture]\nsweep_deg = [1, 1, 1, 1, 1, 1]", "`capture.start_deg`, `capture.points` missing"),
    ],
)
def test_target_and_plan_errors_name_the_key(table, message):
    text = 'robot = "kuka-kr5-sixx-r650"\n' + table
    with pytest.raises(InputError, match=message):
        scenario_from_dict(_toml(text), source="s.toml")


def test_parameter_json_carries_the_estimated_offsets(tmp_path):
    capture, _ = _capture()
    result = _refine(capture, ParameterSet.nominal(ROBOT), UNKNOWN, tracker_from_base=TRACKER)
    path = write_parameters(tmp_path / "p.json", result.parameters, {}, refined_targets(result))
    offsets = read_targets(path)
    np.testing.assert_allclose([offsets[name] for name in ("T1", "T2", "T3")], TRUE_OFFSETS, rtol=0, atol=1e-9)


def _toml(text: str) -> dict:
    import tomllib

    return tomllib.loads(text)


def test_cpa_on_a_capture_with_a_target_column_uses_its_first_target():
    from robotcal.api import identify, simulate
    from robotcal.io.schema.scenario import load_scenario

    scenario = load_scenario("thesis-noise-free")
    capture = simulate(scenario, rng=1)
    named = Capture(**{**_fields(capture), "target": np.zeros(capture.n_points, dtype=int), "target_names": ("capture",)})
    plain = identify(capture, scenario)
    tagged = identify(named, scenario)  # `capture`: the scenario's [capture] reflector, by name
    np.testing.assert_array_equal(tagged.parameters.values, plain.parameters.values)
    unknown = Capture(**{**_fields(capture), "target": np.zeros(capture.n_points, dtype=int), "target_names": ("X",)})
    with pytest.raises(InputError, match="no target named 'X'"):
        identify(unknown, scenario)
