# SPDX-License-Identifier: Apache-2.0
"""The URDF is the model: edited files, per-element springs, toleranced robots, rigid motions."""

from __future__ import annotations

import re

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin import H4Params
from h4pin.checks import deformed, statics
from h4pin.description.geometry import geometry_from_params
from h4pin.kinematics import closed_form as geometry
from h4pin.robot import variant_path
from h4pin.stiffness.api import TERMS, compliance, matrices_at
from h4pin.stiffness.matrices import from_points
from h4pin.studies.variants import GENERATORS


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def shifted(text: str, element: str, delta: np.ndarray) -> str:
    """Move the <origin xyz> of a joint (by name) in URDF text by ``delta``."""
    pattern = re.compile(rf'(<joint name="{re.escape(element)}"[^>]*>.*?<origin xyz=")([^"]+)(")', re.S)
    match = pattern.search(text)
    assert match, element
    xyz = np.array([float(v) for v in match.group(2).split()]) + delta
    return text[:match.start(2)] + " ".join(repr(float(v)) for v in xyz) + text[match.end(2):]


def test_geometry_from_params_equals_reading_the_urdf():
    for make in GENERATORS.values():
        params = make()
        read, built = h4pin.load(params).geometry, geometry_from_params(params)
        for field in ("P", "u", "A0", "l", "lat", "C0", "b", "v", "q_lo", "q_hi", "omega_lo", "omega_hi"):
            np.testing.assert_allclose(getattr(read, field), getattr(built, field), atol=1e-15, err_msg=field)
        for name, value in built.springs.items():
            np.testing.assert_array_equal(read.springs[name], value)


def test_hand_edited_urdf_is_the_robot_it_describes(tmp_path, centre):
    """A forearm 2 mm longer on leg 3 and a re-machined plate (lateral bar 1 moved 5 mm along x),
    made by editing joint origins in the text of the shipped URDF: the compliance equals that of
    the robot generated from matching parameters, and the statics route on the edited model."""
    text = variant_path("prototype").read_text()
    a3 = np.array([0.0, 1.0, 0.0])  # forearm 3 direction u_3 x z
    for joint in ("bar_31_u1", "bar_32_u1", "A_31_frame", "A_32_frame", "A_3_frame"):
        text = shifted(text, joint, 0.002 * a3)
    text = shifted(text, "lateral_1", np.array([0.005, 0.0, 0.0]))
    path = tmp_path / "edited.urdf"
    path.write_text(text)
    edited = h4pin.load(path)
    p = H4Params()
    dc, db = p.DC.copy(), p.DB.copy()
    dc[0, 0] += 0.005
    db[0, :2] += 0.005
    matching = h4pin.load(p.replace(r=[0.26, 0.26, 0.262, 0.26], DC=dc, DB=db))
    assert edited.geometry.r[2] == pytest.approx(0.262, abs=1e-15)
    for model in ("paper", "consistent"):
        a, b = compliance(edited, centre, model), compliance(matching, centre, model)
        assert rel(a.matrix, b.matrix) < 1e-12
    ref = statics.compliance_matrix(edited.geometry, centre)
    assert rel(compliance(edited, centre, "consistent").matrix, ref) < 1e-9
    assert rel(compliance(edited, centre).matrix, compliance(h4pin.load("prototype"), centre).matrix) > 1e-3


def test_springs_per_element_and_at_load(centre):
    """Doubling one bar's section halves its tension compliance only: K changes by exactly minus
    half that bar's share, computed independently by the statics route (c g g^T of that bar)."""
    proto = h4pin.load("prototype")
    sb = np.full(8, 28e-6)
    sb[5] *= 2
    stiffer = h4pin.load("prototype", springs={"Sb": sb})
    loads = statics.spring_loads(proto.geometry, centre)["tension"]  # (8 bars, 8)
    c = proto.geometry.compliances()["tension"][5]
    expected = compliance(proto, centre, "consistent").matrix - 0.5 * c * np.outer(loads[5], loads[5])
    assert rel(compliance(stiffer, centre, "consistent").matrix, expected) < 1e-12
    with pytest.raises(h4pin.ParameterError, match="unknown field"):
        h4pin.load("prototype", springs={"kc2": 1.0})
    with pytest.raises(h4pin.ParameterError, match=r"springs\['kc'\].*actuator_2.*not physical"):
        h4pin.load("prototype", springs={"kc": [1.0, -1.0, 1.0, 1.0]})


def test_rotated_layout_gives_the_rotated_compliance(centre):
    """A URDF whose base and plate layout are turned by 30 deg about z gives T K T^T at the turned
    pose, T = diag(Rz, Rz, 1, 1)."""
    p, angle = H4Params(), np.deg2rad(30.0)
    rz = pin.rpy.rpyToMatrix(0.0, 0.0, angle)
    turned = h4pin.load(p.replace(P=rz @ p.P, U=rz @ p.U, DB=rz @ p.DB, DC=rz @ p.DC))
    proto = h4pin.load(p)
    t = np.eye(8)
    t[:3, :3] = t[3:6, 3:6] = rz
    for x in (centre, centre + [0.04, -0.03, 0.02, 0.2]):
        xr = np.r_[rz @ x[:3], x[3]]
        for model in ("paper", "consistent"):
            assert rel(compliance(turned, xr, model).matrix, t @ compliance(proto, x, model).matrix @ t.T) < 1e-12


@pytest.fixture(scope="module")
def tol():
    return h4pin.load("toleranced")


@pytest.fixture(scope="module")
def tol_poses(tol):
    c = tol.forward_geometry(np.full(4, np.pi / 4))
    return c + np.random.default_rng(5).uniform(-1, 1, (6, 4)) * [0.08, 0.08, 0.05, 0.3]


def test_toleranced_robot_is_not_ideal_and_tilts(tol, tol_poses):
    assert not tol.geometry.ideal
    st = tol.state(tol_poses[0])
    assert 1e-6 < np.linalg.norm(pin.log3(st.R @ geometry.rot_z(-tol_poses[0][3]))) < 1e-2  # a small tilt
    for x in tol_poses:
        assert np.max(np.abs(tol.closure_residuals(tol.configuration(x)))) < 1e-12
        q = tol.inverse_geometry(x)
        np.testing.assert_allclose(tol.forward_geometry(q, guess=x + [0.01, 0.0, 0.01, 0.05]), x, atol=1e-11)


def test_toleranced_robot_every_route_agrees(tol, tol_poses):
    """Pinocchio vs closed forms (1e-12), J from the 24x24 closure Jacobian vs J from M1, M3,
    the consistent K vs the statics route (1e-9) and vs finite differences of the deformed
    robot (1e-6), and the non-linear equilibrium under 10 N vs K F (0.5 %)."""
    g = tol.geometry
    for x in tol_poses[:3]:
        pin_m = matrices_at(tol, x)
        cf = from_points(g, geometry.points(g, tol.state(x)))
        for name in ("M1", "M2", "J", "M3", "M4", "Jb"):
            assert rel(getattr(pin_m, name), getattr(cf, name)) < 1e-12, name
        assert rel(tol.jacobian(x), cf.J) < 1e-10
        for model in ("paper", "consistent"):
            a = compliance(tol, x, model, method="pinocchio")
            b = compliance(tol, x, model, method="closed_form")
            assert rel(a.matrix, b.matrix) < 1e-12
        ours = compliance(tol, x, "consistent").terms
        theirs = statics.compliance_terms(g, x)
        assert max(rel(ours[t], theirs[t]) for t in TERMS) < 1e-9
    x = tol_poses[0]
    fd = sum(deformed.compliance_terms(g, x).values())
    assert rel(compliance(tol, x, "consistent").matrix, fd) < 1e-6
    force = np.array([3.0, -2.0, -9.0])
    d_nl, _ = deformed.loaded_equilibrium(g, x, force)
    d_lin = compliance(tol, x).translational @ force
    assert np.linalg.norm(d_nl - d_lin) / np.linalg.norm(d_lin) < 5e-3


def test_toleranced_batch_equals_single(tol, tol_poses):
    batch = compliance(tol, tol_poses, "consistent")
    for n, x in enumerate(tol_poses):
        assert rel(batch.matrix[n], compliance(tol, x, "consistent", method="pinocchio").matrix) < 1e-12


def test_viewer_draws_the_toleranced_robot(tol, tol_poses):
    from h4pin.stiffness.deflection import deflected_configuration

    x, force = tol_poses[1], np.array([0.0, 0.0, -10.0])
    q = deflected_configuration(tol, x, force, scale=200.0)
    pin.framesForwardKinematics(tol.model, tol.data, q)
    moved = tol.frame_position("D") - x[:3]
    np.testing.assert_allclose(moved, 200.0 * compliance(tol, x, "consistent").translational @ force, rtol=1e-9)
