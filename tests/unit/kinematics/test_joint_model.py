"""The extended model's joint model (issue 22): gravity torques against the potential energy, the lumped form
against the known-mass form, the parameter JSON round trip, and the geometric model left exactly as it was."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io import load_robot
from robotcal.io.formats.parameters_json import read_parameters, write_parameters
from robotcal.kinematics.forward import joint_frames
from robotcal.kinematics.joint_model import GRAVITY_MPS2, JointModel, gravity_torques
from robotcal.kinematics.model import LinkMasses, ParameterSet


@pytest.fixture(scope="module")
def kr5():
    return load_robot("kuka-kr5-sixx-r650")


def _potential(values, q, masses: LinkMasses) -> np.ndarray:
    """V = -sum_j m_j g . c_j (base frame, J), the independent truth of tau = -dV/dq."""
    frames = joint_frames(values, q)[:, 1:]  # base_from_link_j, j = 1..n
    com = np.einsum("pjab,jb->pja", frames[..., :3, :3], masses.com_mm) + frames[..., :3, 3]
    com[:, -1] = (com[:, -1] * masses.mass_kg[-1] + masses.payload_kg * (
        np.einsum("pab,b->pa", frames[:, -1, :3, :3], masses.payload_com_mm) + frames[:, -1, :3, 3]
    )) / (masses.mass_kg[-1] + masses.payload_kg)
    total = masses.mass_kg.copy()
    total[-1] += masses.payload_kg
    return -np.einsum("j,pja,a->p", total, com * 1e-3, np.asarray(GRAVITY_MPS2))


def test_gravity_torque_is_minus_the_gradient_of_the_potential(kr5):
    masses = kr5.masses.with_payload(3.0, [10.0, -20.0, 60.0])
    rng = np.random.default_rng(4)
    q = rng.uniform(-np.pi, np.pi, (5, 6))
    torque = gravity_torques(kr5.nominal, q, masses)
    step = 1e-6
    for j in range(6):
        up, down = q.copy(), q.copy()
        up[:, j] += step
        down[:, j] -= step
        gradient = (_potential(kr5.nominal, up, masses) - _potential(kr5.nominal, down, masses)) / (2 * step)
        # central differences of V ~ 100 J: truncation ~1e-11, rounding ~1e-14 * 100 / 1e-6 = 1e-6 N m
        np.testing.assert_allclose(torque[:, j], -gradient, rtol=0, atol=1e-5)
    # the KR 5 at q = 0 (upper arm level, forearm forward): J1 carries nothing, J2 and J3 the arm
    horizontal = gravity_torques(kr5.nominal, np.zeros((1, 6)), kr5.masses)[0]
    assert horizontal[0] == pytest.approx(0.0, abs=1e-12) and horizontal[1] < -20.0 and horizontal[2] < -3.0


def test_lumped_terms_span_every_known_mass_deflection(kr5):
    """Any compliance times any masses is a combination of the lumped terms (fitted on other poses)."""
    lumped = JointModel.build(kr5, compliance_joints=[1, 2])
    known = JointModel.build(kr5, compliance_joints=[1, 2], masses=kr5.masses.with_payload(2.0, [0, 0, 50]))
    known = known.with_values([6.7e-5, 2.5e-4])
    rng = np.random.default_rng(9)
    limits = kr5.limits
    fit_q = kr5.model_joint_variables(rng.uniform(limits[:, 0], limits[:, 1], (300, 6)))
    test_q = kr5.model_joint_variables(rng.uniform(limits[:, 0], limits[:, 1], (50, 6)))
    columns = lumped.columns(fit_q).reshape(-1, lumped.size)
    values, *_ = np.linalg.lstsq(columns, known.deflection(fit_q).ravel(), rcond=None)
    predicted = lumped.deflection(test_q, values)
    # deflections ~1e-3 rad; the span is exact: rounding only
    np.testing.assert_allclose(predicted, known.deflection(test_q), rtol=0, atol=1e-14)
    assert lumped.names[0] == "J2.g1" and all(name.startswith(("J2.g", "J3.g")) for name in lumped.names)


def test_harmonic_terms_and_names(kr5):
    model = JointModel.build(kr5, harmonic_joints=[3], harmonic_order=2).with_values([1e-4, 2e-4, 3e-4, 4e-4])
    assert model.names == ("J4.a1", "J4.b1", "J4.a2", "J4.b2") and model.groups == ("harmonic",) * 4
    q = np.random.default_rng(1).uniform(-3, 3, (7, 6))
    expected = 1e-4 * np.sin(q[:, 3]) + 2e-4 * np.cos(q[:, 3]) + 3e-4 * np.sin(2 * q[:, 3]) + 4e-4 * np.cos(2 * q[:, 3])
    deflection = model.deflection(q)
    np.testing.assert_allclose(deflection[:, 3], expected, rtol=1e-14, atol=0)
    assert np.all(deflection[:, [0, 1, 2, 4, 5]] == 0.0)
    assert model.display_units == ("deg",) * 4
    with pytest.raises(InputError, match="harmonic order"):
        JointModel.build(kr5, harmonic_joints=[0], harmonic_order=5)
    with pytest.raises(InputError, match="unknown parameter"):
        JointModel.assemble(kr5, ["J9.k"], [0.0], masses=kr5.masses)


def test_geometric_sets_are_unchanged(kr5):
    readings = np.random.default_rng(2).uniform(-1, 1, (4, 6))
    geometric = ParameterSet.nominal(kr5)
    assert not geometric.is_extended
    np.testing.assert_array_equal(geometric.model_joint_variables(readings), kr5.model_joint_variables(readings))
    empty = geometric.replace(joint_model=JointModel.build(kr5))
    np.testing.assert_array_equal(empty.model_joint_variables(readings), kr5.model_joint_variables(readings))


@pytest.mark.parametrize("form", ["known masses", "lumped"])
def test_parameter_json_round_trip(kr5, tmp_path, form):
    masses = kr5.masses.with_payload(2.5, [0.0, 10.0, 45.0]) if form == "known masses" else None
    model = JointModel.build(kr5, compliance_joints=[1, 2], masses=masses, harmonic_joints=[0, 4])
    values = np.random.default_rng(3).normal(0.0, 1e-4, model.size)
    flags = np.arange(model.size) % 3 != 0
    model = model.with_values(values, identified=flags)
    parameters = ParameterSet(robot=kr5, values=kr5.nominal, joint_model=model)
    u = np.abs(values) / 10
    write_parameters(tmp_path / "p.json", parameters, joint_model_u=u)
    back = read_parameters(tmp_path / "p.json", kr5).joint_model
    assert back.names == model.names and np.array_equal(back.identified, flags)
    # degrees and back: a relative rounding of a few ulp
    np.testing.assert_allclose(back.values, values, rtol=1e-14, atol=0)
    np.testing.assert_array_equal(back.compliance_map, model.compliance_map)
    q = np.random.default_rng(4).uniform(-2, 2, (5, 6))
    np.testing.assert_allclose(back.deflection(q), model.deflection(q), rtol=1e-13, atol=1e-20)


def test_parameter_json_refuses_a_wrong_unit(kr5, tmp_path):
    import json

    model = JointModel.build(kr5, compliance_joints=[1], masses=kr5.masses).with_values([1e-5])
    write_parameters(tmp_path / "p.json", ParameterSet(robot=kr5, values=kr5.nominal, joint_model=model))
    document = json.loads((tmp_path / "p.json").read_text())
    document["joint_model"]["parameters"][0]["unit"] = "deg/(N m)"
    (tmp_path / "p.json").write_text(json.dumps(document))
    with pytest.raises(InputError, match=r"joint_model.parameters\[0\].unit"):
        read_parameters(tmp_path / "p.json", kr5)
