# SPDX-License-Identifier: Apache-2.0
"""The H4 in Gepetto's toolbox-parallel-robots (Extended URDF). example-robot-data and
robot_descriptions: ``tests/test_erd.py``.

Against the real packages (``interop`` extra; skipped without it, CI installs it).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin.description.params import VARIANTS
from h4pin.errors import MalformedURDFError, ParameterError
from h4pin.io import interop
from h4pin.kinematics.closed_form import centre_pose

ROOT = Path(__file__).resolve().parent.parent


# ----------------------------------------------------------------- Extended URDF sidecar
def _loader_constraints(model: pin.Model, sidecar: dict) -> list[pin.RigidConstraintModel]:
    """The closures as Gepetto's loader builds them from a sidecar (example_parallel_robots'
    ``completeRobotLoader``, not on PyPI): each frame pair, with the frames' parent joints and
    placements, becomes a ``CONTACT_3D`` (for type 3D) ``RigidConstraintModel`` in the LOCAL frame."""
    out = []
    for (name1, name2), kind in zip(sidecar["closed_loop"], sidecar["type"], strict=True):
        assert kind in ("3D", "3d")
        f1, f2 = (model.frames[model.getFrameId(n)] for n in (name1, name2))
        out.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, f1.parentJoint, f1.placement,
                                            f2.parentJoint, f2.placement, pin.ReferenceFrame.LOCAL))
    return out


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_sidecar_gives_the_same_closures_and_motors(variant):
    yaml = pytest.importorskip("yaml")
    urdf = ROOT / "urdf" / f"h4_{variant}.urdf"
    sidecar = yaml.safe_load((ROOT / "urdf" / f"h4_{variant}.yaml").read_text())
    assert {"closed_loop", "type", "name_mot", "joint_name", "joint_type"} <= set(sidecar)
    h4 = h4pin.load(variant)
    # The loader's model: Pinocchio's URDF parser on the shipped file (not h4pin's).
    model = pin.buildModelFromUrdf(str(urdf))
    cms = _loader_constraints(model, sidecar)
    assert len(cms) == 8
    for mine, theirs in zip(h4.constraint_models, cms, strict=True):
        assert (model.names[theirs.joint1_id], model.names[theirs.joint2_id]) == \
            (h4.model.names[mine.joint1_id], h4.model.names[mine.joint2_id])
        for a, b in ((mine.joint1_placement, theirs.joint1_placement),
                     (mine.joint2_placement, theirs.joint2_placement)):
            np.testing.assert_allclose(a.homogeneous, b.homogeneous, rtol=0, atol=1e-15)
    assert tuple(sidecar["name_mot"]) == h4.actuated_joint_names
    # The motors are the joints whose velocity indices are h4.v_act, in leg order.
    assert [h4.model.joints[h4.model.getJointId(n)].idx_v for n in sidecar["name_mot"]] == list(h4.v_act)
    # The sidecar's closures are closed where h4pin says the robot is assembled.
    data = model.createData()
    q = h4.configuration(centre_pose(h4))
    pin.forwardKinematics(model, data, q)
    for cm in cms:
        gap = (data.oMi[cm.joint1_id] * cm.joint1_placement).translation \
            - (data.oMi[cm.joint2_id] * cm.joint2_placement).translation
        assert np.linalg.norm(gap) < 1e-14


def test_sidecar_needs_a_frame_at_each_closure_point():
    text = h4pin.load("prototype").urdf
    broken = text.replace('<origin xyz="0 0 -0.48" rpy="0 0 0"/>', '<origin xyz="0 0 -0.47" rpy="0 0 0"/>', 1)
    with pytest.raises(MalformedURDFError, match="closure 'closure_11'.*'bar_11'"):
        interop.closure_frame_pairs(broken)


# ----------------------------------------------------------------- the toolbox
def _toolbox():
    """Import the toolbox's Jacobian and actuation modules.

    Workaround (toolbox-parallel-robots 1.2.0): its ``__init__`` imports ``casadi``, ``qpsolvers``
    and ``pinocchio.casadi`` (undeclared; pip's ``pin`` has no casadi bindings), so a bare
    ``import toolbox_parallel_robots`` fails. These modules need only numpy and Pinocchio, so the
    package is entered without running its ``__init__``.
    """
    if "toolbox_parallel_robots" not in sys.modules:
        spec = importlib.util.find_spec("toolbox_parallel_robots")
        if spec is None:
            pytest.skip("toolbox-parallel-robots is not installed (pip install 'h4pin[interop]')")
        try:
            importlib.import_module("toolbox_parallel_robots")
        except ImportError:
            pkg = types.ModuleType("toolbox_parallel_robots")
            pkg.__path__ = list(spec.submodule_search_locations)
            pkg.__spec__ = spec
            sys.modules["toolbox_parallel_robots"] = pkg
    return (importlib.import_module("toolbox_parallel_robots.jacobian"),
            importlib.import_module("toolbox_parallel_robots.actuation_model"))


def _toolbox_inputs(h4):
    """The toolbox's own ActuationModel, with local workarounds for version 1.2.0, and h4pin's data."""
    _, tam = _toolbox()
    loop = interop.closed_loop(h4)
    am = tam.ActuationModel(h4.model, list(h4.actuated_joint_names))
    # h4pin's ActuationModel has the same indices as the toolbox's.
    for field in ("mot_ids_q", "mot_ids_v", "free_ids_q", "free_ids_v", "mot_joints_ids"):
        assert list(getattr(am, field)) == list(getattr(loop.actuation_model, field)), field
    # Workaround: the toolbox reads nv_mot / nv_free, which its ActuationModel lacks; and reads
    # (computeDerivative_dq_dqmot) or writes (inverseConstraintKinematicsSpeed) dq, dq_no on the
    # *model* where it means the data: alias them to the data's arrays.
    am.nv_mot, am.nv_free = loop.actuation_model.nv_mot, loop.actuation_model.nv_free
    ad = loop.actuation_data  # the toolbox's ActuationData() cannot be built here (see interop)
    am.dq, am.dq_no = ad.dq, ad.dq_no
    return loop, am, ad


def _prime(loop, q):
    """Workaround: the toolbox runs computeJointJacobians but never the closures' calc, so its
    constraint Jacobians use stale contact placements. Run forward kinematics and each calc first."""
    pin.forwardKinematics(loop.model, loop.data, q)
    for cm, cd in zip(loop.constraint_models, loop.constraint_datas, strict=True):
        cm.calc(loop.model, loop.data, cd)


def _local_to_world(loop, fid):
    """6x6 map of a LOCAL twist of frame fid to world-aligned axes (after forward kinematics)."""
    rot = pin.updateFramePlacement(loop.model, loop.data, fid).rotation
    return np.block([[rot, np.zeros((3, 3))], [np.zeros((3, 3)), rot]])


@pytest.mark.parametrize("variant", ["prototype", "symmetric"])
def test_toolbox_closed_loop_jacobian_matches_h4(variant):
    jac, _ = _toolbox()
    h4 = h4pin.load(variant)
    from conftest import sample_poses

    loop, am, ad = _toolbox_inputs(h4)
    fid = h4.frames["D"]
    for pose in sample_poses(h4, 6, seed=3):
        q = h4.configuration(pose)
        ref = h4.jacobian(pose)  # rows vx vy vz wz
        _prime(loop, q)
        j_local = jac.computeClosedLoopFrameJacobian(loop.model, loop.data, loop.constraint_models,
                                                     loop.constraint_datas, am, ad, q, fid)
        j_world = _local_to_world(loop, fid) @ j_local  # workaround: the toolbox's is LOCAL
        np.testing.assert_allclose(j_world[[0, 1, 2, 5]], ref, rtol=0, atol=1e-12)
        # The plate does not tilt: no w_x, w_y.
        np.testing.assert_allclose(j_world[[3, 4]], 0, atol=1e-12)
        # h4pin.io.interop's own, world-aligned, needs no priming.
        mine = interop.closed_loop_frame_jacobian(interop.closed_loop(h4), q, "D")
        np.testing.assert_allclose(mine, j_world, rtol=0, atol=1e-12)


def test_toolbox_jacobian_is_wrong_without_the_workaround(proto, centre):
    """Documents the toolbox bug worked around above: without calc, stale contact placements."""
    jac, _ = _toolbox()
    loop, am, ad = _toolbox_inputs(proto)
    fid = proto.frames["D"]
    _prime(loop, proto.configuration(centre))  # the data are now set at another pose
    pose = centre + np.array([0.05, -0.04, 0.03, 0.3])
    q = proto.configuration(pose)
    j_local = jac.computeClosedLoopFrameJacobian(loop.model, loop.data, loop.constraint_models,
                                                 loop.constraint_datas, am, ad, q, fid)
    stale = (_local_to_world(loop, fid) @ j_local)[[0, 1, 2, 5]]
    assert np.max(np.abs(stale - proto.jacobian(pose))) > 1e-3


def test_toolbox_velocity_ik_recovers_the_actuator_speeds(proto):
    jac, _ = _toolbox()
    from conftest import sample_poses

    loop, am, ad = _toolbox_inputs(proto)
    fid = proto.frames["D"]
    rng = np.random.default_rng(7)
    for pose in sample_poses(proto, 5, seed=11):
        q = proto.configuration(pose)
        qdot = rng.uniform(-1, 1, 4)
        x_dot = proto.jacobian(pose) @ qdot  # vx vy vz wz
        twist_world = np.r_[x_dot[:3], 0.0, 0.0, x_dot[3]]
        _prime(loop, q)
        twist_local = _local_to_world(loop, fid).T @ twist_world  # the toolbox wants LOCAL
        vq = jac.inverseConstraintKinematicsSpeed(loop.model, loop.data, loop.constraint_models,
                                                  loop.constraint_datas, am, ad, q, fid, twist_local)
        np.testing.assert_allclose(vq[proto.v_act], qdot, rtol=0, atol=1e-12)
        # The passive speeds keep every closure: Jc vq = 0.
        jc = pin.getConstraintsJacobian(loop.model, loop.data, loop.constraint_models, loop.constraint_datas)
        assert np.max(np.abs(jc @ vq)) < 1e-12


def test_interop_errors_name_the_argument(proto, centre):
    loop = interop.closed_loop(proto)
    q = proto.configuration(centre)
    with pytest.raises(ParameterError, match="frame"):
        interop.closed_loop_frame_jacobian(loop, q, "nowhere")
    with pytest.raises(ParameterError, match="q"):
        interop.closed_loop_frame_jacobian(loop, q[:5], "D")
    with pytest.raises(ParameterError, match="names"):
        interop.ActuationModel(proto.model, ["actuator_9"])


def test_actuated_joint_names_are_the_actuators(proto):
    names = proto.actuated_joint_names
    assert names == ("actuator_1", "actuator_2", "actuator_3", "actuator_4")
    assert [proto.model.joints[proto.model.getJointId(n)].idx_v for n in names] == list(proto.v_act)
