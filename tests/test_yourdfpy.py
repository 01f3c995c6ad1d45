# SPDX-License-Identifier: Apache-2.0
"""A yourdfpy scene of every shipped variant at any pose (``h4pin.io.yourdfpy_scene``), against
Pinocchio's frame placements; and the example of ``docs/interop.md``."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import sample_poses

import h4pin
from h4pin.description.params import VARIANTS
from h4pin.errors import ParameterError
from h4pin.io.interop import closure_frame_pairs
from h4pin.io.yourdfpy_scene import load_scene, pose_scene, scene_at
from h4pin.kinematics.closed_form import centre_pose

yourdfpy = pytest.importorskip("yourdfpy")
# yourdfpy 0.0.60 builds the collision scene with trimesh's deprecated Scene.dump (not ours).
pytestmark = pytest.mark.filterwarnings("ignore:.*Scene.dump.*:DeprecationWarning")
ROOT = Path(__file__).resolve().parent.parent


def _pinocchio_links(h4, q):
    data = h4.model.createData()
    pin.framesForwardKinematics(h4.model, data, q)
    return {f.name: data.oMf[i].homogeneous for i, f in enumerate(h4.model.frames) if f.type == pin.FrameType.BODY}


def _poses(h4):
    """The centre pose and 3 poses spread over the workspace (x, y within 12 cm, theta 0.5 rad)."""
    return np.vstack([centre_pose(h4), sample_poses(h4, 3, seed=21)])


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_every_link_is_where_pinocchio_puts_it(variant):
    h4 = h4pin.load(variant)
    urdf = load_scene(h4, build_collision_scene_graph=True)
    pairs = closure_frame_pairs(h4.urdf)
    assert len(pairs) == 8
    poses = _poses(h4)
    assert np.ptp(poses[:, 0]) > 0.05 and np.ptp(poses[:, 3]) > 0.2  # across the workspace
    for pose in poses:
        pose_scene(urdf, h4, pose)
        mine = _pinocchio_links(h4, h4.configuration(pose))
        assert set(urdf.link_map) <= set(mine) and len(urdf.link_map) > 60
        for link in urdf.link_map:
            np.testing.assert_allclose(urdf.get_transform(link), mine[link], rtol=0, atol=1e-9, err_msg=link)
            np.testing.assert_allclose(urdf.get_transform(link, collision_geometry=True), mine[link],
                                       rtol=0, atol=1e-9, err_msg=link)
        for a, b in pairs:  # the closures are closed in the scene
            gap = urdf.get_transform(a)[:3, 3] - urdf.get_transform(b)[:3, 3]
            assert np.linalg.norm(gap) < 1e-9, (a, b)
        # The revolute joints' values are yourdfpy's own configuration.
        q = h4.configuration(pose)
        for name in ("actuator_1", "bar_32_u2", "lateral_2"):
            idx = urdf.actuated_dof_indices[urdf.actuated_joint_names.index(name)]
            assert urdf.cfg[idx] == q[h4.model.joints[h4.model.getJointId(name)].idx_q]


def test_without_the_plate_edge_the_robot_is_torn_open(proto, centre):
    """Why pose_scene exists: update_cfg alone leaves the floating joint at its origin."""
    urdf = load_scene(proto)
    q = proto.configuration(centre)
    revolute = {j.name: q[proto.model.joints[proto.model.getJointId(j.name)].idx_q]
                for j in urdf.robot.joints if j.type == "revolute"}
    urdf.update_cfg(revolute)
    gaps = [np.linalg.norm(urdf.get_transform(a)[:3, 3] - urdf.get_transform(b)[:3, 3])
            for a, b in closure_frame_pairs(proto.urdf)]
    assert min(gaps) > 0.5


def test_a_configuration_and_the_default(proto, centre):
    """q as given (an open configuration is shown open, as Pinocchio places it); default h4.q0."""
    q = proto.configuration(centre + [0.02, 0.03, -0.02, -0.3])
    q[proto.v_pas[:3]] += 0.1  # three passive leg joints (q index = v index before the plate): loops open
    urdf = scene_at(proto, q=q)
    mine = _pinocchio_links(proto, q)
    for link in urdf.link_map:
        np.testing.assert_allclose(urdf.get_transform(link), mine[link], rtol=0, atol=1e-9, err_msg=link)
    assert np.max(np.abs(proto.closure_residuals(q))) > 1e-3
    default = scene_at(proto)
    np.testing.assert_allclose(default.get_transform("D")[:3, 3], proto.frame_position("D", proto.q0), atol=1e-15)


def test_errors_name_the_argument(proto, centre):
    urdf = load_scene(proto)
    with pytest.raises(ParameterError, match="not both"):
        pose_scene(urdf, proto, centre, q=proto.q0)
    with pytest.raises(ParameterError, match="q must be"):
        pose_scene(urdf, proto, q=proto.q0[:5])
    bare = yourdfpy.URDF.load(str(h4pin.robot.variant_path("prototype")), build_scene_graph=False,
                              load_meshes=False)
    with pytest.raises(ParameterError, match="scene graph"):
        pose_scene(bare, proto)
    other = yourdfpy.URDF.load(str(ROOT / "urdf" / "h4_prototype.urdf"), build_scene_graph=True, load_meshes=False)
    other.robot.joints[1].name = "renamed"
    with pytest.raises(ParameterError, match="renamed"):
        pose_scene(other, proto)


def test_the_documented_example_runs():
    """The yourdfpy example of docs/interop.md, run as written; then its claim checked."""
    text = (ROOT / "docs" / "interop.md").read_text()
    section = text[text.index("## yourdfpy"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    ns: dict = {}
    exec(compile(code, "docs/interop.md", "exec"), ns)  # noqa: S102 - our own documentation
    urdf, h4 = ns["urdf"], ns["h4"]
    pose = ns["pose"]
    mine = _pinocchio_links(h4, h4.configuration(pose))
    np.testing.assert_allclose(urdf.get_transform("B_11"), mine["B_11"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(urdf.get_transform("bar_11_end")[:3, 3], mine["B_11"][:3, 3], rtol=0, atol=1e-9)
