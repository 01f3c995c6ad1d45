# SPDX-License-Identifier: Apache-2.0
"""What Mechanism.from_mjcf takes from an MJCF file where Pinocchio's reader and MuJoCo's compiler
differ, each checked against MuJoCo or against a second file:

* a root body placed on the world (``<body pos quat>``): every body and site where MuJoCo puts it,
  and the compliance of the rotated file the unrotated one's turned by the root's rotation;
* masses: every joint's mass, centre of mass and inertia MuJoCo's compiled ones (a geom mass set
  by a default class, which Pinocchio's reader replaces by density times volume), and the mass
  matrix MuJoCo's;
* file values MuJoCo compiles but h4pin would drop: typed errors naming the element and attribute;
* a second tree on the world: refused by name (Pinocchio's reader reads the first one only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from h4pin.errors import MalformedURDFError, UnsupportedFeatureError
from h4pin.mechanism import Mechanism

mujoco = pytest.importorskip("mujoco")
if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
    pytest.skip(f"needs Pinocchio >= 4 (closures read from MJCF), this is {pin.__version__}", allow_module_level=True)

ROBOTS = Path(__file__).parent / "robots"

#: a spatial four-bar closed by a connect, springs on every joint, a body with two joints (a
#: composite for Pinocchio's reader), geoms whose mass a default class sets and a body welded to
#: the rocker; {place}: the root body's placement on the world, {extra}: more bodies on the world
FOURBAR = """<mujoco model="fourbar">
  <default>
    <default class="pad"><geom type="box" size="0.011 0.004 0.009375" mass="0.0035"/></default>
  </default>
  <worldbody>
    <body name="base" {place}>
      <geom type="sphere" size="0.01" mass="0.1"/>
      <body name="crank">
        <joint name="crank" type="hinge" axis="0 0 1" stiffness="80"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.01" mass="0.4"/>
        <body name="coupler" pos="0.2 0 0">
          <joint name="coupler" type="hinge" axis="0 0 1" stiffness="30"/>
          <joint name="coupler_roll" type="hinge" axis="1 0 0" stiffness="5"/>
          <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.01" mass="0.6"/>
          <geom class="pad" pos="0.25 0.02 0" quat="0.9 0.1 0.3 0"/>
          <body name="rocker" pos="0.5 0 0">
            <joint name="rocker" type="hinge" axis="0 0 1" stiffness="20"/>
            <joint name="rocker_pitch" type="hinge" axis="0 1 0" stiffness="5"/>
            <geom type="capsule" fromto="0 0 0 0.3 0.1 0" size="0.01" mass="0.5"/>
            <site name="tip" pos="0.3 0.1 0"/>
            <body name="pad" pos="0.1 0.05 0" quat="1 1 0 0">
              <geom class="pad" pos="0 0.01 0"/>
              <geom class="pad" pos="0 0.03 0.01"/>
              <site name="pad_site" pos="0.01 0.02 0.03"/>
            </body>
          </body>
        </body>
      </body>
    </body>{extra}
  </worldbody>
  <equality>
    <connect body1="rocker" body2="base" anchor="0.3 0.1 0"/>
  </equality>
  <actuator>
    <motor name="m_crank" joint="crank"/>
  </actuator>
  <keyframe>
    <key name="home" qpos="0.3 -0.2 0.05 0.4 -0.1"/>
  </keyframe>
</mujoco>
"""
AXIS = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)  # the root's 45 degree turn about a skew axis
ANGLE = np.pi / 4
OFFSET = np.array([0.1, -0.2, 0.3])
QUAT = [float(np.cos(ANGLE / 2)), *(np.sin(ANGLE / 2) * AXIS).tolist()]
PLACE = 'pos="{}" quat="{}"'.format(" ".join(map(repr, OFFSET.tolist())), " ".join(map(repr, QUAT)))


def _write(tmp_path, name, text):
    path = tmp_path / f"{name}.xml"
    path.write_text(text)
    return path


def _fourbar(tmp_path, place="", extra=""):
    return _write(tmp_path, "fourbar_" + str(len(list(tmp_path.iterdir()))), FOURBAR.format(place=place, extra=extra))


def _rodrigues(axis, angle):
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_a_root_placed_on_the_world_is_where_the_file_puts_it(tmp_path):
    """The rotated and offset root: every body and site at MuJoCo's xpos/xmat and site_xpos at the
    reference (first keyframe), and the compliance at the tip the unrotated file's turned by R
    (force and moment, world axes): C = R6 C0 R6^T."""
    from h4pin.mechanism import mjcf_reader

    path = _fourbar(tmp_path, PLACE)
    mech, mech0 = Mechanism.from_mjcf(path), Mechanism.from_mjcf(_fourbar(tmp_path))
    mj = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(mj)
    d.qpos[:] = mj.key_qpos[0]
    mujoco.mj_kinematics(mj, d)
    model = mech.model
    pd = model.createData()
    np.testing.assert_allclose(mjcf_reader.from_qpos(mj, model, d.qpos), mech.reference, rtol=0, atol=0)
    pin.framesForwardKinematics(model, pd, mech.reference)
    for b in range(1, mj.nbody):
        f = pd.oMf[model.getFrameId(mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b), pin.FrameType.BODY)]
        np.testing.assert_allclose(f.translation, d.xpos[b], rtol=0, atol=1e-15)
        np.testing.assert_allclose(f.rotation, d.xmat[b].reshape(3, 3), rtol=0, atol=1e-15)
    for s in range(mj.nsite):
        f = pd.oMf[model.getFrameId(mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_SITE, s))]
        np.testing.assert_allclose(f.translation, d.site_xpos[s], rtol=0, atol=1e-15)
    rot = _rodrigues(AXIS, ANGLE)
    np.testing.assert_allclose(d.xmat[1].reshape(3, 3), rot, rtol=0, atol=1e-15)  # MuJoCo reads the quat so
    q = mech0.assemble()
    assert max(max(e) for e in mech.closure_errors(q).values()) <= 1e-12  # the same joints close both
    assert mech.springs == mech0.springs and len(mech.springs) == 5
    c0 = mech0.compliance(q, mech0.springs, ["tip"])
    c = mech.compliance(q, mech.springs, ["tip"])
    r6 = np.kron(np.eye(2), rot)
    np.testing.assert_allclose(c, r6 @ c0 @ r6.T, rtol=0, atol=1e-12 * np.abs(c0).max())
    assert np.abs(c - c0).max() > 0.1 * np.abs(c0).max()  # the turn matters: C0 itself is not the answer


WELDED = """<mujoco model="welded">
  <worldbody>
    <body name="base" {place}>
      <geom type="sphere" size="0.01" mass="0.1"/>
      <body name="a">
        <joint name="j1" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.01" mass="0.4"/>
        <body name="b" pos="0.2 0 0">
          <joint name="j2" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.01" mass="0.4"/>
          <body name="c" pos="0.2 0 0">
            <joint name="j3" axis="1 0 0"/>
            <joint name="j4" axis="0 0 1"/>
            <geom type="capsule" fromto="0 0 0 0.2 0.1 0" size="0.01" mass="0.4"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <weld body1="c" body2="{body2}"/>
  </equality>
</mujoco>
"""


@pytest.mark.parametrize("body2", ["base", "a"])
def test_a_weld_to_a_placed_root_holds_where_mujocos_holds(tmp_path, body2):
    """A weld without relpose holds at qpos0 (MuJoCo's definition); with the root placed on the
    world, its end on the root is moved with it (Pinocchio's reader gives it in the root's axes)."""
    from h4pin.mechanism import mjcf_reader

    path = _write(tmp_path, "welded", WELDED.format(place=PLACE, body2=body2))
    mech = Mechanism.from_mjcf(path)
    mj = mujoco.MjModel.from_xml_path(str(path))
    q = mjcf_reader.from_qpos(mj, mech.model, mj.qpos0)
    errors = mech.closure_errors(q)
    assert len(errors) == 1 and max(errors.popitem()[1]) <= 1e-15
    d, pd = mujoco.MjData(mj), mech.model.createData()
    mujoco.mj_kinematics(mj, d)
    pin.framesForwardKinematics(mech.model, pd, q)  # and the welded body is where MuJoCo puts it
    c = pd.oMf[mech.model.getFrameId("c", pin.FrameType.BODY)]
    np.testing.assert_allclose(c.translation, d.xpos[mj.nbody - 1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(c.rotation, d.xmat[mj.nbody - 1].reshape(3, 3), rtol=0, atol=1e-15)


def _owner(mj, b):
    """The name of the Pinocchio joint that carries MuJoCo body b: the last joint of its nearest
    ancestor with joints (h4pin splits a body's joints, the body on the last), else the universe."""
    from h4pin.mechanism import mjcf_reader

    while b and mj.body_jntnum[b] == 0:
        b = mj.body_parentid[b]
    return mjcf_reader._joint_name(mj, mj.body_jntadr[b] + mj.body_jntnum[b] - 1) if b else "universe"


def _assert_inertias_are_mujocos(mj, model):
    """Every joint's mass, centre of mass and rotational inertia (world axes, at qpos0) equal to
    MuJoCo's bodies carried by it, summed here with the parallel-axis theorem from MuJoCo's own
    xipos/ximat; the total mass MuJoCo's."""
    from h4pin.mechanism import mjcf_reader

    d = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, d)
    pd = model.createData()
    pin.forwardKinematics(model, pd, mjcf_reader.from_qpos(mj, model, mj.qpos0))
    groups: dict[str, list[int]] = {}
    for b in range(mj.nbody):
        groups.setdefault(_owner(mj, b), []).append(b)
    assert set(groups) <= set(model.names)
    for j in range(model.njoints):
        bodies = groups.get(model.names[j], [])
        mass = float(mj.body_mass[bodies].sum())
        got = pd.oMi[j].act(model.inertias[j])
        assert got.mass == pytest.approx(mass, rel=1e-14, abs=1e-18), model.names[j]
        if mass == 0:
            continue
        com = (mj.body_mass[bodies, None] * d.xipos[bodies]).sum(axis=0) / mass
        tensor = np.zeros((3, 3))
        for b in bodies:
            rot, r = d.ximat[b].reshape(3, 3), d.xipos[b] - com
            tensor += rot @ np.diag(mj.body_inertia[b]) @ rot.T + mj.body_mass[b] * (r @ r * np.eye(3) - np.outer(r, r))
        np.testing.assert_allclose(got.lever, com, rtol=0, atol=1e-14, err_msg=model.names[j])
        np.testing.assert_allclose(got.inertia, tensor, rtol=0, atol=1e-12 * np.abs(tensor).max(),
                                   err_msg=model.names[j])
    assert sum(model.inertias[j].mass for j in range(model.njoints)) == pytest.approx(mj.body_mass.sum(), rel=1e-14)


@pytest.mark.parametrize("place", ["", PLACE])
def test_masses_are_mujocos_where_a_default_class_sets_a_geom_mass(tmp_path, place):
    """The four-bar's pads: a geom mass of 0.0035 kg set by a default class (Pinocchio's reader:
    density x volume = 0.0033 kg); every joint's inertia MuJoCo's, and so is the mass matrix
    (MuJoCo's mj_fullM at a random configuration against Pinocchio's CRBA)."""
    from h4pin.mechanism import mjcf_reader

    path = _fourbar(tmp_path, place)
    mech = Mechanism.from_mjcf(path)
    mj = mujoco.MjModel.from_xml_path(str(path))
    assert mj.body_mass[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, "pad")] == pytest.approx(0.007, rel=1e-15)
    _assert_inertias_are_mujocos(mj, mech.model)
    d, model = mujoco.MjData(mj), mech.model
    d.qpos[:] = np.random.default_rng(5).uniform(-1, 1, mj.nq)
    mujoco.mj_forward(mj, d)
    full = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, d, full)
    cols = [model.joints[model.getJointId(mjcf_reader._joint_name(mj, i))].idx_v for i in range(mj.njnt)]
    crba = pin.crba(model, model.createData(), mjcf_reader.from_qpos(mj, model, d.qpos))
    crba = np.triu(crba) + np.triu(crba, 1).T
    np.testing.assert_allclose(crba[np.ix_(cols, cols)], full, rtol=0, atol=1e-13 * np.abs(full).max())


def test_masses_of_the_2f85_are_mujocos():
    """The Robotiq 2F-85 (refused by from_mjcf for its follower joints' class pos, so read here
    before that check): every joint's inertia and the total mass MuJoCo's."""
    from h4pin.mechanism import mjcf_reader

    mj, model, _, _ = mjcf_reader._load(ROBOTS / "mjcf" / "robotiq_2f85" / "2f85.xml")
    _assert_inertias_are_mujocos(mj, model)
    follower = model.inertias[model.getJointId("right_follower_joint")].mass  # follower, pad, silicone pad
    assert follower == pytest.approx(0.0125222 + 0.0035 + 0.001302811839479651, rel=1e-14)


#: file edit of tests/robots/synthetic/loop.xml -> what the message must name
BAD_VALUES = {"negative stiffness": (('stiffness="40"', 'stiffness="-40"'), r"joint 'tilt': stiffness -40"),
              "nan stiffness": (('stiffness="40"', 'stiffness="nan"'), r"joint 'tilt': stiffness nan"),
              "nan springref": (('springref="3"', 'springref="nan"'), r"joint 'tilt': springref nan"),
              "reversed range": (('range="-170 170"', 'range="170 -170"'), r"joint 'crank': range '170 -170'"),
              "nan range": (('range="-170 170"', 'range="nan nan"'), r"joint 'crank': range 'nan nan'"),
              "short keyframe": (('<key qpos="0.1 0.3 -0.2 0.05 0.4 -0.1"/>', '<key name="home" qpos="0.1"/>'),
                                 r"keyframe 'home': qpos has 1 values, the model has 6")}


@pytest.mark.parametrize("case", sorted(BAD_VALUES))
def test_file_values_that_would_be_dropped_are_typed_errors(tmp_path, case):
    (old, new), match = BAD_VALUES[case]
    text = (ROBOTS / "synthetic" / "loop.xml").read_text()
    assert text.count(old) == 1
    path = _write(tmp_path, case.replace(" ", "_"), text.replace(old, new))
    mujoco.MjModel.from_xml_path(str(path))  # MuJoCo compiles it: the value would be dropped without a word
    with pytest.raises(MalformedURDFError, match=match):
        Mechanism.from_mjcf(path)


ARM = """
    <body name="{name}" pos="0 {y} 0">
      <joint name="{name}/waist" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.01" mass="0.4"/>
      <body name="{name}/arm" pos="0.2 0 0">
        <joint name="{name}/elbow" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.01" mass="0.4"/>
      </body>
    </body>"""


def test_a_second_tree_on_the_world_is_refused_by_name(tmp_path):
    """Two arms on the world (Pinocchio's reader reads the first): refused, the second named; a
    second body without joints (a table) is part of the world and changes nothing."""
    two = ARM.format(name="left", y=0.5) + ARM.format(name="right", y=-0.5)
    path = _write(tmp_path, "two", f'<mujoco model="two"><worldbody>{two}</worldbody>'
                  '<keyframe><key qpos="0.1 0.2 0.3 0.4"/></keyframe></mujoco>')
    assert mujoco.MjModel.from_xml_path(str(path)).njnt == 4
    with pytest.raises(UnsupportedFeatureError, match=r"second root body on the world, 'right' \(2 joints\)"):
        Mechanism.from_mjcf(path)
    table = '\n    <body name="table" pos="1 0 -0.5"><geom type="box" size="0.5 0.5 0.02" mass="20"/></body>'
    mech = Mechanism.from_mjcf(_fourbar(tmp_path, PLACE, table))
    mech0 = Mechanism.from_mjcf(_fourbar(tmp_path, PLACE))
    q = mech0.assemble()
    np.testing.assert_array_equal(mech.compliance(q, mech.springs, ["tip"]),
                                  mech0.compliance(q, mech0.springs, ["tip"]))
    assert [i.mass for i in mech.model.inertias] == [i.mass for i in mech0.model.inertias]
