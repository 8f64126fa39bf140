"""Property: several flange targets of unknown offset at free poses are refined exactly (issue 14).

Hypothesis draws the robot (joints 1-5 moved by up to 0.5 mm / 0.2 deg; joint 6 nominal, since with every
offset unknown the flange frame is held at its start by design, docs/refinement.md), the tracker (anywhere
within 3 m, any orientation), 1-3 targets 30-150 mm from the flange origin with unknown offsets (guess: the
flange origin), 12-30 random poses, the criterion and the base-frame mode. Every parameter the data
determine and every offset must be recovered to <= 1e-9 mm / 1e-9 deg, the capture fitted exactly.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

import refine_options
from robotcal.errors import IdentifiabilityWarning, InputError
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.schema.robots import load_robot
from robotcal.kinematics import ParameterSet
from robotcal.simulation.generator import simulate_target_poses
from robotcal.simulation.poses import random_poses

ROBOT = load_robot("kuka-kr5-sixx-r650")  # finite limits: random poses
TOLERANCE = np.array([1e-9, np.deg2rad(1e-9), 1e-9, np.deg2rad(1e-9), np.deg2rad(1e-9)])


def _floats(low, high):
    return st.floats(low, high, allow_nan=False, allow_infinity=False)


@st.composite
def cases(draw):
    n_targets = draw(st.integers(1, 3))
    directions = draw(arrays(np.float64, (n_targets, 3), elements=_floats(-1.0, 1.0)))
    lengths = draw(arrays(np.float64, (n_targets, 1), elements=_floats(30.0, 150.0)))
    norms = np.linalg.norm(directions, axis=1, keepdims=True)
    offsets = np.where(norms > 0.1, directions / np.maximum(norms, 1e-300), [[0.6, 0.0, 0.8]]) * lengths
    # distinct targets, as on a real adapter plate (centimetres apart): two at one place are one target, which
    # the distances criterion refuses with a clear error (tests/unit/identification/test_targets.py)
    gaps = np.linalg.norm(offsets[:, None] - offsets[None], axis=-1)[np.triu_indices(n_targets, 1)]
    assume(np.all(gaps >= 10.0))
    # off the flange's z axis (joint 6): a lone target on it does not see joint 6 turn (see _ON_AXIS6)
    assume(np.all(np.linalg.norm(offsets[:, :2], axis=1) >= 10.0))
    return {
        "length_moves": draw(arrays(np.float64, (6, 5), elements=_floats(-0.5, 0.5))),
        "angle_moves": np.deg2rad(draw(arrays(np.float64, (6, 5), elements=_floats(-0.2, 0.2)))),
        "rotation_vector": draw(arrays(np.float64, 3, elements=_floats(-np.pi, np.pi))),
        "translation": draw(arrays(np.float64, 3, elements=_floats(-3000.0, 3000.0))),
        "offsets": offsets,
        "poses": draw(st.integers(12, 30)),
        "seed": draw(st.integers(0, 2**31)),
        "criterion": draw(st.sampled_from(["points", "distances"])),
        "base": draw(st.sampled_from(["given", "estimated"])),
    }


#: Found by hypothesis: one unknown target on the flange's z axis. Joint 6 turning moves it nowhere, so the
#: target is a fixed point of frame 5 and J5's d, theta, a, alpha and the offset are not all determined; the rank
#: test at the guess moved 50 mm off (refine.py) frees them all and they came back 46 mm off with a zero residual.
#: The rank test at the solution holds J5.a and J5.alpha (the offsets come first in its order: their guess is
#: rough, the nominal parameters are not) and the refit with them at their start values is exact.
_ON_AXIS6 = {
    "length_moves": np.zeros((6, 5)), "angle_moves": np.zeros((6, 5)), "rotation_vector": np.zeros(3),
    "translation": np.zeros(3), "offsets": np.array([[0.0, 0.0, 30.0]]), "poses": 12, "seed": 0,
    "criterion": "points", "base": "given",
}  # fmt: skip


@settings(max_examples=8, deadline=None, derandomize=True)  # the same examples in every CI run
@given(cases())
@example(_ON_AXIS6)
def test_unknown_offsets_and_parameters_are_recovered_exactly(case):
    moves = np.where(np.isin(np.arange(5), [0, 2]), case["length_moves"], case["angle_moves"])
    moves[5] = 0.0  # joint 6 nominal: the flange frame the offsets are estimated in
    values = ROBOT.nominal + np.where(ROBOT.structurally_fixed, 0.0, moves)
    truth = ParameterSet(robot=ROBOT, values=values)
    tracker = np.eye(4)
    tracker[:3, :3] = Rotation.from_rotvec(case["rotation_vector"]).as_matrix()
    tracker[:3, 3] = case["translation"]
    targets = [
        Target(name=f"T{k}", frame="flange", positions=np.zeros(3), known=False) for k in range(len(case["offsets"]))
    ]
    readings = random_poses(ROBOT, case["poses"], rng=np.random.default_rng(case["seed"]))
    capture, _ = simulate_target_poses(
        ROBOT,
        readings,
        targets,
        Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0),
        tracker,
        true_parameters=truth,
        true_offsets=case["offsets"],
    )
    base = {"tracker_from_base": tracker} if case["base"] == "given" and case["criterion"] == "points" else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine_options.refine(capture, ParameterSet.nominal(ROBOT), targets, criterion=case["criterion"], **base)
    free = result.identifiability.free
    error = np.abs(result.parameters.values - truth.values)
    assert np.all(error[free] <= np.broadcast_to(TOLERANCE, error.shape)[free]), error[free].max()
    estimated = np.array([target.positions for target in result.targets])
    np.testing.assert_allclose(estimated, case["offsets"], rtol=0, atol=1e-9)
    assert result.fit.residual_max < 1e-9 and result.fit.cost_history[-1] <= result.fit.start_cost


def test_two_targets_at_one_place_are_refused_by_the_distances_criterion():
    """The case the strategy leaves out: coincident targets give zero distances (no derivative), a clear error."""
    targets = [Target(name=f"T{k}", frame="flange", positions=np.zeros(3), known=False) for k in range(2)]
    readings = random_poses(ROBOT, 12, rng=np.random.default_rng(0))
    capture, _ = simulate_target_poses(
        ROBOT,
        readings,
        targets,
        Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0),
        np.eye(4),
        true_offsets=np.array([[18.0, 0.0, 24.0], [18.0, 0.0, 24.0]]),
    )
    with warnings.catch_warnings(), pytest.raises(InputError, match="coincide at different poses or targets"):
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        refine_parameters(
            capture,
            ParameterSet.nominal(ROBOT),
            targets,
            settings=RefinementSettings(criterion="distances"),
        )
