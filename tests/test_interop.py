# SPDX-License-Identifier: Apache-2.0
"""The H4's Extended-URDF sidecars for Gepetto's toolbox-parallel-robots. The toolbox's own
functions: ``tests/test_toolbox.py``; yourdfpy: ``tests/test_yourdfpy.py``; example-robot-data and
robot_descriptions: ``tests/test_erd.py``.
"""

from __future__ import annotations

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
