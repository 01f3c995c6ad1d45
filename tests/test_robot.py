# SPDX-License-Identifier: Apache-2.0
"""Loader, closed-loop geometry and Jacobians, checked against independent routes."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin import ConvergenceError, H4Params, PoseError, SingularPoseError, UnreachablePoseError
from h4pin.kinematics import closed_form as geometry


def test_load_sources(proto, tmp_path):
    from h4pin.robot import variant_path

    assert isinstance(proto.model, pin.Model) and len(proto.constraint_models) == 8
    assert h4pin.load(variant_path("prototype")).params.allclose(proto.params, atol=0)
    assert h4pin.load(H4Params(half_width=0.03)).params.half_width == pytest.approx(np.full(4, 0.03))
    with pytest.raises(ValueError, match="prototype, symmetric"):
        h4pin.load("protoype")
    with pytest.raises(FileNotFoundError):
        h4pin.load(tmp_path / "none.urdf")


def test_named_frames(proto):
    names = ["D"] + [f"{p}_{i}" for p in "PAB" for i in range(1, 5)] + ["C_1", "C_2"]
    names += [f"{p}_{i}{j}" for p in "AB" for i in range(1, 5) for j in (1, 2)]
    assert all(n in proto.frames for n in names)


def test_centre_pose(proto, centre):
    """All actuators at 45 deg: D is on the z axis (mirror symmetry) and theta = 0; its height by
    hand from leg 1 (A_1 = P_1 + r (-x cos 45 - z sin 45), B_1 = D + DB_1, |B_1 - A_1| = l)."""
    np.testing.assert_allclose(centre[[0, 1, 3]], 0.0, atol=1e-12)
    r, l, s = 0.260, 0.480, np.sqrt(0.5)
    dx = (0.200 + r * s) - 0.060  # x gap between A_1 and B_1; their y are both -60 mm
    z = -r * s - 0.050 - np.sqrt(l**2 - dx**2)
    assert centre[2] == pytest.approx(z, abs=1e-12)
    assert centre[2] == pytest.approx(-0.58814, abs=5e-6)  # as printed by h4pin table2


def test_inverse_forward_round_trip(proto, poses):
    for x in poses:
        q = proto.inverse_geometry(x)
        np.testing.assert_allclose(proto.forward_geometry(q, guess=x + [0.01, -0.01, 0.01, 0.05]), x, atol=1e-12)
        np.testing.assert_allclose(proto.inverse_geometry(proto.forward_geometry(q)), q, atol=1e-12)
        np.testing.assert_allclose(geometry.closure_residual(proto.geometry, proto.state(x)), 0.0, atol=1e-15)


def test_inverse_geometry_is_elbow_out_and_vectorised(proto, poses):
    q = proto.inverse_geometry(poses)
    assert q.shape == (len(poses), 4)
    np.testing.assert_array_equal(q[3], proto.inverse_geometry(poses[3]))
    pts = geometry.points(proto.geometry, geometry.rigid_state(poses, q))
    elbow = np.einsum("nia,ia->ni", np.cross(pts.A - pts.P, pts.B - pts.A), proto.geometry.u)
    assert np.all(elbow > 0)


def test_unreachable_pose_names_the_leg(proto, centre, poses):
    far = centre + [0.0, 0.0, -0.3, 0.0]
    with pytest.raises(UnreachablePoseError, match=r"leg \d cannot reach B_\d"):
        proto.inverse_geometry(far)
    batch = np.vstack([poses[:3], far, poses[3:]])
    with pytest.raises(UnreachablePoseError, match="pose #3") as info:
        proto.inverse_geometry(batch)
    assert info.value.index == 3
    q = proto.inverse_geometry(batch, on_error="nan")
    assert np.isnan(q[3]).all() and np.isfinite(np.delete(q, 3, axis=0)).all()


@pytest.mark.parametrize("bad", [[0, 0, -0.5], [0, 0, np.nan, 0], "x", np.zeros((2, 2, 4))])
def test_bad_pose_input(proto, bad):
    with pytest.raises(PoseError):
        proto.inverse_geometry(bad)


def test_forward_geometry_failure_is_clear(proto):
    with pytest.raises(ConvergenceError, match="forward geometry"):
        proto.forward_geometry(np.array([0.0, 0.0, 0.0, 3.0]))


def test_configuration_closes_all_loops(proto, poses):
    for x in poses:
        q = proto.configuration(x)
        assert np.max(np.abs(proto.closure_residuals(q))) < 1e-10
        pin.framesForwardKinematics(proto.model, proto.data, q)
        np.testing.assert_allclose(proto.frame_position("D"), x[:3], atol=1e-15)
        for k in (1, 2):  # lateral bars only translate
            lat = proto.data.oMf[proto.frames[f"C_{k}"]].rotation
            np.testing.assert_allclose(lat, np.eye(3), atol=1e-14)


def test_jacobian_against_finite_differences(proto, poses):
    """J from Pinocchio's closure Jacobians vs central differences of the forward geometry."""
    h = 1e-6
    for x in poses[:6]:
        q = proto.inverse_geometry(x)
        fd = np.column_stack([
            (proto.forward_geometry(q + h * e, guess=x) - proto.forward_geometry(q - h * e, guess=x)) / (2 * h)
            for e in np.eye(4)
        ])
        j = proto.jacobian(x)
        assert np.max(np.abs(j - fd)) < 1e-7 * np.max(np.abs(j))


def test_jacobian_against_closed_form(proto, poses):
    """Pinocchio's J equals the paper's Jx^-1 Jq (eq. 8)."""
    for x in poses:
        jx, jq = proto.jx_jq(x)
        np.testing.assert_allclose(proto.jacobian(x), np.linalg.solve(jx, jq), atol=1e-12)


def test_singular_pose_of_the_symmetric_variant(sym):
    centre = sym.forward_geometry(np.full(4, np.pi / 4))
    with pytest.raises(SingularPoseError, match="cond = "):
        sym.jacobian(centre)


def test_gravity_torques_against_potential_energy(proto, poses):
    """Holding torques from Pinocchio's dynamics and closures = gradient of the potential energy."""
    h = 1e-6
    for x in poses[:4]:
        q = proto.inverse_geometry(x)

        def energy(qa, guess=x):
            return proto.potential_energy(proto.forward_geometry(qa, guess=guess))

        fd = np.array([(energy(q + h * e) - energy(q - h * e)) / (2 * h) for e in np.eye(4)])
        tau = proto.gravity_torques(x)
        np.testing.assert_allclose(tau, fd, rtol=1e-6, atol=1e-6 * np.max(np.abs(fd)))
        assert np.max(np.abs(tau)) > 0.1  # the robot weighs a few kg: torques are not trivially zero


def test_gravity_torques_change_sign_with_gravity(proto, centre):
    tau = proto.gravity_torques(centre)
    np.testing.assert_allclose(proto.gravity_torques(centre, gravity=[0, 0, 9.81]), -tau, rtol=1e-12)


@pytest.mark.parametrize("variant", h4pin.VARIANTS)
def test_q0_is_the_assembled_reference_configuration(variant):
    """h4.q0 and model.referenceConfigurations["q0"] (Pinocchio's convention) are the configuration
    with every actuator at 45 deg, all loops closed; the shipped SRDF's q0 agrees to its rounding
    (1 um, 1 urad on the pose)."""
    from h4pin.robot import urdf_dir

    h4 = h4pin.load(variant)
    assert h4.q0 is not None and not h4.q0.flags.writeable
    np.testing.assert_array_equal(h4.model.referenceConfigurations["q0"], h4.q0)
    assert np.abs(h4.closure_residuals(h4.q0)).max() < 1e-12
    np.testing.assert_allclose(h4.q0[h4.index.q_act], np.pi / 4, atol=1e-9)
    model = pin.buildModelFromUrdf(str(urdf_dir() / f"h4_{variant}.urdf"))
    pin.loadReferenceConfigurations(model, str(urdf_dir().parent / "srdf" / f"h4_{variant}.srdf"))
    np.testing.assert_allclose(model.referenceConfigurations["q0"], h4.q0, atol=1e-5)
