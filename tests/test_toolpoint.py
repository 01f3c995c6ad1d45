# SPDX-License-Identifier: Apache-2.0
"""Compliance at a tool point (Compliance.at) against statics + finite differences of the
deformed robot with the force at an offset point."""

from __future__ import annotations

import numpy as np
import pytest

from h4pin.checks import statics, toolpoint
from h4pin.kinematics.closed_form import rot_z
from h4pin.stiffness.api import compliance

OFFSETS = [  # (measured at p, force at p'), central-bar frame, m
    ([0.1, 0.0, 0.0], None),
    ([0.0, -0.1, 0.05], None),
    ([0.08, -0.05, -0.1], [-0.03, 0.09, 0.05]),
]


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("n_pose", [0, 5, 9])
def test_tool_point_compliance_equals_statics_and_deformed_route(proto, poses, n_pose):
    """C_pp' = T_p K6 T_p'^T vs sum_s c_s (dp/deps_s) g_s(p')^T, g from the plate equilibrium
    with the force at p', dp/deps from the non-linear deformed plate (p moved rigidly)."""
    x = poses[n_pose]
    assert abs(x[3]) > 0.02  # theta != 0: the offset is turned with the central bar
    for offset, load_at in OFFSETS:
        route = toolpoint.point_compliance(proto.geometry, x, offset, load_at)
        for model in ("paper", "consistent"):
            ours = compliance(proto, x, model).at(offset, load_at)
            assert rel(ours, route) < 1e-6, (offset, load_at, model)
        # the offset matters: far from the compliance at D
        assert rel(route, compliance(proto, x).translational) > 0.05


def test_offset_force_equilibrium_equals_force_and_couple_at_d(proto, poses):
    """A force at p' is a force and a couple (p' - D) x F at D: bar tensions agree with the
    statics route's unit loads (solved about the world origin, with joint torques)."""
    x = poses[3]
    o = np.array([0.07, -0.02, 0.09])
    arm = rot_z(x[3]) @ o
    ours = toolpoint.bar_forces_at(proto.geometry, x, o)
    lam = statics.bar_forces(proto.geometry, x)
    skew = np.array([[0, -arm[2], arm[1]], [arm[2], 0, -arm[0]], [-arm[1], arm[0], 0]])
    assert rel(ours, lam[:, :3] + lam[:, 3:6] @ skew) < 1e-12


def test_at_the_centre_point_is_the_translational_block(proto, centre):
    res = compliance(proto, centre)
    np.testing.assert_array_equal(res.at(np.zeros(3)), res.translational)


def test_reciprocity_and_batch(proto, poses):
    """Maxwell-Betti: C_p'p = C_pp'^T (consistent K is symmetric); a batch equals single poses."""
    p, q = np.array([0.1, 0.02, -0.05]), np.array([-0.04, 0.1, 0.03])
    res = compliance(proto, poses[:4], "consistent")
    both = res.at(p, q)
    assert both.shape == (4, 3, 3)
    np.testing.assert_allclose(res.at(q, p), np.swapaxes(both, 1, 2), rtol=1e-12, atol=1e-18)
    single = compliance(proto, poses[2], "consistent").at(p, q)
    assert rel(both[2], single) < 1e-12
    per_pose = res.at(np.tile(p, (4, 1)), np.tile(q, (4, 1)))
    assert rel(per_pose, both) < 1e-14


def test_bad_offset_shape(proto, centre):
    with pytest.raises(ValueError, match="offset"):
        compliance(proto, centre).at([0.1, 0.0])
