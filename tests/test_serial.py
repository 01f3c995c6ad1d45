# SPDX-License-Identifier: Apache-2.0
"""Compliance of a serial arm (UR5 and Panda of example-robot-data) against its forward kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from h4pin.errors import ParameterError
from h4pin.mechanism import scene
from h4pin.studies.serial import UR5_JOINT_STIFFNESS, serial_compliance

erd = pytest.importorskip("example_robot_data")

#: Non-singular configurations (rad): elbow up, tool down; and two others.
UR5_CONFIGS = np.array([[0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0],
                        [0.4, -1.2, 1.9, -2.2, -1.4, 0.7],
                        [-0.8, -1.9, 1.2, -0.6, 1.1, -0.3]])


@pytest.fixture(scope="module")
def ur5():
    return erd.load("ur5")


def _position(model, data, q, fid):
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[fid].translation.copy()


def fd_translational_compliance(model, q, fid, k, step=1e-5):
    """C_tt from forward kinematics only: for a unit force F along each axis, the joint torques are
    tau_i = F . dp/dq_i (virtual work, central differences of the frame position), each joint
    turns by tau_i / k_i, and the frame moves by p(q + dq) - p(q) (scaled to stay linear)."""
    data = model.createData()
    p0 = _position(model, data, q, fid)
    dpdq = np.empty((3, model.nv))
    for i in range(model.nv):
        e = np.zeros(model.nv)
        e[i] = step
        dpdq[:, i] = (_position(model, data, pin.integrate(model, q, e), fid)
                      - _position(model, data, pin.integrate(model, q, -e), fid)) / (2 * step)
    out = np.empty((3, 3))
    for axis in range(3):
        tau = dpdq[axis]  # F = unit force along the axis
        dq = tau / k
        s = step / np.abs(dq).max()  # a small load: joint turns of at most `step` rad
        plus = _position(model, data, pin.integrate(model, q, s * dq), fid)
        minus = _position(model, data, pin.integrate(model, q, -s * dq), fid)
        out[:, axis] = (plus - minus) / (2 * s)
    assert np.linalg.norm(p0) > 0
    return out


def test_ur5_compliance_matches_finite_differences(ur5):
    fid = ur5.model.getFrameId("tool0")
    for q in UR5_CONFIGS:
        res = serial_compliance(ur5.model, ur5.data, q, "tool0", UR5_JOINT_STIFFNESS)
        fd = fd_translational_compliance(ur5.model, q, fid, UR5_JOINT_STIFFNESS)
        np.testing.assert_allclose(res.translational, fd, rtol=0, atol=1e-8 * np.abs(fd).max())
        # Symmetric, positive definite; deflection is C F.
        assert np.all(np.linalg.eigvalsh(res.translational) > 0)
        np.testing.assert_allclose(res.deflection([0, 0, -10])[:3], res.translational @ [0, 0, -10])
        np.testing.assert_allclose(res.position, _position(ur5.model, ur5.model.createData(), q, fid))


def test_panda_compliance_with_a_stiffness_mapping():
    panda = erd.load("panda")
    m = panda.model
    arm = {f"panda_joint{i}": k for i, k in enumerate([2e4, 2e4, 2e4, 2e4, 5e3, 5e3, 5e3], start=1)}
    stiffness = {**arm, "panda_finger_joint1": 1.0, "panda_finger_joint2": 1.0}  # fingers do not move the hand
    q = panda.q0.copy()
    res = serial_compliance(m, panda.data, q, "panda_hand_tcp", stiffness)
    k = np.array([stiffness[m.names[j]] for j in range(1, m.njoints)])
    fd = fd_translational_compliance(m, q, m.getFrameId("panda_hand_tcp"), k)
    np.testing.assert_allclose(res.translational, fd, rtol=0, atol=1e-8 * np.abs(fd).max())
    # Twice the stiffness everywhere halves the compliance (C is linear in 1/k).
    double = serial_compliance(m, panda.data, q, "panda_hand_tcp", {n: 2 * v for n, v in stiffness.items()})
    np.testing.assert_allclose(double.matrix, res.matrix / 2, rtol=1e-12, atol=1e-20)


def test_errors_name_the_argument(ur5):
    q = UR5_CONFIGS[0]
    with pytest.raises(ParameterError, match="frame"):
        serial_compliance(ur5.model, ur5.data, q, "no_such_frame", UR5_JOINT_STIFFNESS)
    with pytest.raises(ParameterError, match="q"):
        serial_compliance(ur5.model, ur5.data, q[:3], "tool0", UR5_JOINT_STIFFNESS)
    with pytest.raises(ParameterError, match="joint_stiffness"):
        serial_compliance(ur5.model, ur5.data, q, "tool0", UR5_JOINT_STIFFNESS[:5])
    with pytest.raises(ParameterError, match="joint_stiffness"):
        serial_compliance(ur5.model, ur5.data, q, "tool0", -UR5_JOINT_STIFFNESS)
    with pytest.raises(ParameterError, match="wrist_3_joint"):
        serial_compliance(ur5.model, ur5.data, q, "tool0", {"shoulder_pan_joint": 1e4})


class _Recorder:
    """Stands in for a meshcat.Visualizer: records what is drawn where."""

    def __init__(self):
        self.objects, self.transforms = {}, {}

    def __getitem__(self, path):
        rec = self

        class Node:
            def set_object(self, geometry, material=None):
                rec.objects[path] = geometry

            def set_transform(self, matrix):
                rec.transforms[path] = matrix

        return Node()


def test_ellipsoid_of_the_arm_is_drawn_at_the_tool(ur5):
    res = serial_compliance(ur5.model, ur5.data, UR5_CONFIGS[1], "tool0", UR5_JOINT_STIFFNESS)
    vis = _Recorder()
    scale = scene.draw_ellipsoid(vis, "ur5/compliance", res.translational, res.position)
    tf = vis.transforms["ur5/compliance"]
    np.testing.assert_allclose(tf[:3, 3], res.position)
    drawn = np.asarray(vis.objects["ur5/compliance"].radii)
    # Along each drawn axis, a unit force deflects the tool by the drawn radius / scale.
    for axis, radius in zip(tf[:3, :3].T, drawn, strict=True):
        np.testing.assert_allclose(res.translational @ axis * 1e6 * scale * 1e-3, radius * axis, rtol=1e-9)
