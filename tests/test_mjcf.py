# SPDX-License-Identifier: Apache-2.0
"""The H4 in MuJoCo (``mujoco`` extra), checked with MuJoCo's own API on the shipped mjcf/ files:
loops closed at the keyframe, bodies where Pinocchio puts the same-named links, the URDF's limits,
efforts and inertias, a floor, light and camera, files current, and Pinocchio's MJCF reader."""

from __future__ import annotations

import stat
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin.errors import ParameterError
from h4pin.extras import MissingExtraError
from h4pin.files import same_generated_text, unmarked
from h4pin.io import mjcf
from h4pin.kinematics.closed_form import centre_pose

mujoco = pytest.importorskip("mujoco")

ROOT = Path(__file__).resolve().parent.parent
#: Off-centre offsets [dx, dy, dz, dtheta] (m, rad); the symmetric variant is singular at its centre.
OFFSETS = np.array([[0.05, -0.03, 0.02, 0.2], [-0.08, 0.06, -0.04, -0.3], [0.02, 0.09, 0.05, 0.1]])
#: The issue's bound on closure residuals and on positions against Pinocchio (m).
TOL = 1e-9


@pytest.fixture(scope="module", params=sorted(h4pin.VARIANTS))
def robot(request):
    """(variant, H4, the shipped MJCF loaded by MuJoCo)."""
    h4 = h4pin.load(request.param)
    return request.param, h4, mujoco.MjModel.from_xml_path(str(mjcf.mjcf_path(request.param)))


def _urdf(h4) -> ET.Element:
    return ET.fromstring(h4.urdf)


def _name(m, kind, i: int) -> str:
    return mujoco.mj_id2name(m, kind, i)


def _closure_gaps(m, d) -> np.ndarray:
    """Distance between the two points of each connect (its two sites), m."""
    return np.array([np.linalg.norm(d.site_xpos[m.eq_obj1id[i]] - d.site_xpos[m.eq_obj2id[i]]) for i in range(m.neq)])


def _check_bodies(h4, m, d, q) -> int:
    """Every MuJoCo body named after a URDF link is where Pinocchio puts that link at q (position
    and orientation); returns how many were compared."""
    data = h4.model.createData()
    pin.framesForwardKinematics(h4.model, data, q)
    compared = 0
    for b in range(1, m.nbody):
        name = _name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        oMf = data.oMf[h4.model.getFrameId(name, pin.FrameType.BODY)]
        np.testing.assert_allclose(d.xpos[b], oMf.translation, rtol=0, atol=TOL, err_msg=name)
        np.testing.assert_allclose(d.xmat[b].reshape(3, 3), oMf.rotation, rtol=0, atol=TOL, err_msg=name)
        compared += 1
    return compared


def test_shipped_files_are_the_variants():
    assert sorted(p.name for p in (ROOT / "mjcf").iterdir()) == sorted(f"h4_{v}.xml" for v in h4pin.VARIANTS)
    # The repository's mjcf/ in a source tree, the package's h4pin/mjcf in an installed wheel.
    assert mjcf.mjcf_dir() in (ROOT / "mjcf", Path(h4pin.__file__).resolve().parent / "mjcf")
    for variant in h4pin.VARIANTS:
        assert mjcf.mjcf_path(variant).read_bytes() == (ROOT / "mjcf" / f"h4_{variant}.xml").read_bytes()
    with pytest.raises(ParameterError, match="unknown H4 variant 'nope'"):
        mjcf.mjcf_path("nope")


def test_shipped_file_is_current(robot):
    """The shipped file is what the generator writes now: the same text when this MuJoCo wrote it,
    else (another MuJoCo's writer lays it out differently) the same compiled model."""
    from h4pin.studies.variants import GENERATORS

    variant, _, shipped = robot
    h4 = h4pin.load(GENERATORS[variant]())  # what scripts/generate_urdf.py loads
    text = mjcf.mjcf_path(variant).read_text()
    if mjcf.writer_version(text) == mujoco.__version__:
        assert same_generated_text(text, mjcf.to_mjcf(h4, f"h4_{variant}"))
        return
    fresh = mjcf.spec(h4, f"h4_{variant}").compile()
    for field in ("nq", "nv", "nbody", "njnt", "ngeom", "nsite", "neq", "nu", "nkey", "nlight", "ncam"):
        assert getattr(fresh, field) == getattr(shipped, field), field
    for field in ("body_parentid", "jnt_type", "eq_type", "eq_obj1id", "eq_obj2id", "actuator_trnid", "geom_type"):
        np.testing.assert_array_equal(getattr(fresh, field), getattr(shipped, field), err_msg=field)
    for field in ("body_pos", "body_quat", "body_mass", "body_ipos", "body_inertia", "jnt_axis", "jnt_range",
                  "actuator_ctrlrange", "geom_size", "geom_pos", "site_pos", "eq_solref", "cam_pos"):
        np.testing.assert_allclose(getattr(fresh, field), getattr(shipped, field), rtol=1e-12, atol=1e-15,
                                   err_msg=field)
    # The keyframe is an assembled configuration: closed to 1e-10 by an iterative solve whose last
    # bits depend on the CPU's and the library's rounding, so its zeros agree to rounding (1e-15 rad
    # of 0.79 rad) rather than exactly.
    np.testing.assert_allclose(fresh.key_qpos, shipped.key_qpos, rtol=0, atol=1e-12, err_msg="key_qpos")


def test_tree_joints_closures_and_motors(robot):
    _, h4, m = robot
    model = h4.model
    assert (m.nq, m.nv) == (model.nq, model.nv) == (29, 28)
    # One joint per URDF joint, in Pinocchio's order; the floating one as 3 slides and a ball.
    names = []
    for jid in range(1, model.njoints):
        n = model.names[jid]
        names += [n + s for s in mjcf.SLIDES] + [n] if model.joints[jid].nq == 7 else [n]
    assert [_name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)] == names
    # Bodies: the URDF's links, by name, with the URDF's parents.
    links = {link.get("name") for link in _urdf(h4).findall("link")}
    assert {_name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, m.nbody)} == links
    parents = {j.find("child").get("link"): j.find("parent").get("link") for j in _urdf(h4).findall("joint")}
    for b in range(2, m.nbody):
        assert _name(m, mujoco.mjtObj.mjOBJ_BODY, m.body_parentid[b]) == parents[_name(m, mujoco.mjtObj.mjOBJ_BODY, b)]
    # Closures: the URDF's <constraint>s, each a connect between a site on its parent link and
    # one on its child link.
    assert m.neq == 8
    for i, c in enumerate(_urdf(h4).findall("constraint")):
        assert m.eq_type[i] == mujoco.mjtEq.mjEQ_CONNECT and m.eq_objtype[i] == mujoco.mjtObj.mjOBJ_SITE
        assert _name(m, mujoco.mjtObj.mjOBJ_EQUALITY, i) == c.get("name")
        for obj, end in ((m.eq_obj1id[i], "parent"), (m.eq_obj2id[i], "child")):
            assert _name(m, mujoco.mjtObj.mjOBJ_BODY, m.site_bodyid[obj]) == c.find(end).get("link")
            xyz = [float(v) for v in c.find(f"{end}_origin").get("xyz").split()]
            np.testing.assert_allclose(m.site_pos[obj], xyz, rtol=0, atol=1e-15)
    assert m.nu == 4
    driven = [_name(m, mujoco.mjtObj.mjOBJ_JOINT, m.actuator_trnid[a, 0]) for a in range(m.nu)]
    assert tuple(driven) == h4.actuated_joint_names
    assert [m.jnt_dofadr[m.actuator_trnid[a, 0]] for a in range(m.nu)] == list(h4.v_act)


def test_joint_ranges_are_the_urdf_limits(robot):
    """Every revolute joint is a limited hinge with the URDF's <limit lower upper>; the plate's
    slides and ball stay unlimited."""
    _, h4, m = robot
    urdf = {j.get("name"): j for j in _urdf(h4).findall("joint")}
    hinges = 0
    for j in range(m.njnt):
        name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        if name in urdf and urdf[name].get("type") == "revolute":
            limit = urdf[name].find("limit")
            assert m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and m.jnt_limited[j]
            np.testing.assert_array_equal(m.jnt_range[j], [float(limit.get("lower")), float(limit.get("upper"))])
            hinges += 1
        else:
            assert not m.jnt_limited[j], name
    assert hinges == 4 + 16 + 2


def test_motors_ctrlrange_is_the_urdf_effort(robot):
    _, h4, m = robot
    urdf = {j.get("name"): j for j in _urdf(h4).findall("joint")}
    for a in range(m.nu):
        effort = float(urdf[_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a)].find("limit").get("effort"))
        assert m.actuator_ctrllimited[a]
        np.testing.assert_array_equal(m.actuator_ctrlrange[a], [-effort, effort])
        assert m.actuator_gear[a, 0] == 1.0 and m.actuator_gainprm[a, 0] == 1.0 and not m.actuator_biasprm[a].any()


def test_inertias_are_the_urdfs(robot):
    """Each body's mass is its link's URDF <mass>; the bodies that move with one Pinocchio joint
    sum to Pinocchio's inertia of that joint (mass, centre of mass, rotational inertia, world
    frame at q0), so the centres of mass and tensors are the URDF's too."""
    _, h4, m = robot
    model = h4.model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(mjcf.KEYFRAME).id)
    mujoco.mj_forward(m, d)
    masses = {link.get("name"): float(link.find("inertial/mass").get("value"))
              for link in _urdf(h4).findall("link") if link.find("inertial") is not None}
    sums = {j: pin.Inertia.Zero() for j in range(model.njoints)}
    for b in range(1, m.nbody):
        name = _name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        assert m.body_mass[b] == masses.get(name, 0.0), name
        rot = d.ximat[b].reshape(3, 3)
        world = pin.Inertia(m.body_mass[b], d.xipos[b], rot @ np.diag(m.body_inertia[b]) @ rot.T)
        sums[model.frames[model.getFrameId(name, pin.FrameType.BODY)].parentJoint] += world
    data = model.createData()
    pin.forwardKinematics(model, data, h4.q0)
    for j in range(model.njoints):
        mine = data.oMi[j].act(model.inertias[j])
        assert sums[j].mass == pytest.approx(mine.mass, rel=1e-13)
        if mine.mass > 0:
            np.testing.assert_allclose(sums[j].lever, mine.lever, rtol=0, atol=1e-12)
            np.testing.assert_allclose(sums[j].inertia, mine.inertia, rtol=1e-9, atol=1e-15)


def test_keyframe_closes_the_loops_where_pinocchio_does(robot):
    """At the keyframe q0 (and at off-centre configurations through mjcf.qpos), after mj_forward:
    the equality rows' residuals and the distances between connected points are ~0, and every body
    is where Pinocchio puts the same-named link."""
    _, h4, m = robot
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(mjcf.KEYFRAME).id)
    mujoco.mj_forward(m, d)
    rows = d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    assert rows.sum() == 3 * 8
    assert np.abs(d.efc_pos[rows]).max() < TOL
    assert _closure_gaps(m, d).max() < TOL
    assert _check_bodies(h4, m, d, h4.q0) == m.nbody - 1 == 63
    np.testing.assert_allclose(d.body("D").xpos, centre_pose(h4)[:3], rtol=0, atol=TOL)
    for pose in centre_pose(h4) + OFFSETS:
        q = h4.configuration(pose)
        d.qpos[:] = mjcf.qpos(h4, q)
        mujoco.mj_forward(m, d)
        assert _closure_gaps(m, d).max() < TOL
        _check_bodies(h4, m, d, q)
        np.testing.assert_allclose(d.site("D").xpos, pose[:3], rtol=0, atol=TOL)


def test_floor_light_and_camera(robot):
    """A floor plane below the robot at every pose tried, a light, and a camera looking at the robot."""
    _, h4, m = robot
    floor = m.geom("floor")
    assert floor.type == mujoco.mjtGeom.mjGEOM_PLANE and m.geom_bodyid[floor.id] == 0
    assert m.nlight >= 1 and m.ncam == 1
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(mjcf.KEYFRAME).id)
    mujoco.mj_forward(m, d)
    centre = d.xpos[1:].mean(axis=0)
    camera = d.cam(mjcf.CAMERA)
    forward = -camera.xmat.reshape(3, 3)[:, 2]  # a MuJoCo camera looks along its -z
    towards = (centre - camera.xpos) / np.linalg.norm(centre - camera.xpos)
    assert forward @ towards > np.cos(np.radians(10))
    assert m.light_pos[0, 2] > d.xpos[1:, 2].max()
    for pose in centre_pose(h4) + np.vstack([OFFSETS, [[0, 0, -0.1, 0]]]):
        d.qpos[:] = mjcf.qpos(h4, h4.configuration(pose))
        mujoco.mj_forward(m, d)
        assert d.xpos[1:, 2].min() > m.geom_pos[floor.id, 2]


def test_pinocchio_reads_the_mjcf(robot):
    """pin.buildModelFromMJCF on the shipped file gives the URDF's model: nq, nv, the keyframe as
    reference configuration q0, and every link at q0."""
    if int(pin.__version__.split(".")[0]) < 4:
        pytest.skip(f"Pinocchio {pin.__version__}'s MJCF reader needs connect between bodies (these use sites)")
    variant, h4, _ = robot
    model = pin.buildModelFromMJCF(str(mjcf.mjcf_path(variant)))
    assert (model.nq, model.nv) == (h4.model.nq, h4.model.nv)
    refs = {e.key(): np.asarray(e.data()) for e in model.referenceConfigurations}
    # The keyframe was computed where the file was generated: its last bits follow that CPU
    # (h4pin.files.same_generated_text, the generator's own tolerance).
    np.testing.assert_allclose(refs[mjcf.KEYFRAME], h4.q0, rtol=0, atol=1e-12)
    data, mine = model.createData(), h4.model.createData()
    pin.framesForwardKinematics(model, data, h4.q0)
    pin.framesForwardKinematics(h4.model, mine, h4.q0)
    for i, f in enumerate(h4.model.frames):
        if f.type == pin.FrameType.BODY:
            theirs = data.oMf[model.getFrameId(f.name, pin.FrameType.BODY)]
            np.testing.assert_allclose(theirs.homogeneous, mine.oMf[i].homogeneous, rtol=0, atol=TOL, err_msg=f.name)


#: Bound on the motion of D over 0.5 s with the actuators at the gravity torques. Measured: up to
#: 4.2e-7 m with MuJoCo 3.3.0 and 4.0.0 (symmetric variant, off-centre; below 4e-8 m for the
#: others), 1.1e-6 m with MuJoCo 3.2.4.
HOLD_DRIFT = 5e-6


def test_gravity_torques_hold_the_robot_still(robot):
    _, h4, m = robot
    d = mujoco.MjData(m)
    steps = int(round(0.5 / m.opt.timestep))
    for n, pose in enumerate(centre_pose(h4) + OFFSETS[:2]):
        start = mjcf.qpos(h4, h4.configuration(pose))
        drifts = []
        for torques in (h4.gravity_torques(pose), np.zeros(4))[:2 if n == 0 else 1]:
            mujoco.mj_resetData(m, d)
            d.qpos[:] = start
            d.ctrl[:] = torques
            mujoco.mj_forward(m, d)
            d0 = d.site("D").xpos.copy()
            for _ in range(steps):
                mujoco.mj_step(m, d)
            drifts.append(np.linalg.norm(d.site("D").xpos - d0))
            # The loops stay closed, held (measured: below 3.1e-7 m) or fallen onto the URDF's joint
            # limits, whose impacts stretch the soft closures more (measured: below 4e-5 m).
            assert _closure_gaps(m, d).max() < (1e-6 if len(drifts) == 1 else 1e-4)
        assert drifts[0] < HOLD_DRIFT, f"D moved {drifts[0]:.2e} m in 0.5 s at the gravity torques"
        if n == 0:
            assert drifts[1] > 1e-2  # without them the robot falls: the torques are what holds it


def test_refuses_an_open_configuration_and_a_missing_or_old_mujoco(monkeypatch):
    h4 = h4pin.load("prototype")
    with pytest.raises(ParameterError, match="does not close the loops"):
        mjcf.spec(h4, q=pin.neutral(h4.model))
    with pytest.raises(ParameterError, match="expected shape"):
        mjcf.qpos(h4, np.zeros(3))
    monkeypatch.setattr(mujoco, "__version__", "3.2.3")
    with pytest.raises(MissingExtraError, match=r"MuJoCo >= 3\.2\.4, this is 3\.2\.3"):
        mjcf.to_mjcf(h4)
    monkeypatch.setitem(sys.modules, "mujoco", None)
    with pytest.raises(MissingExtraError, match=r"h4pin\[mujoco\]"):
        mjcf.to_mjcf(h4)


def test_export_cli_writes_a_loadable_file(tmp_path):
    target = tmp_path / "h4.xml"
    out = subprocess.run([sys.executable, "-m", "h4pin.cli", "export", "--out", str(target), "--variant", "symmetric"],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert stat.S_IMODE(target.stat().st_mode) == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["h4.xml"]  # no temporary file left
    m = mujoco.MjModel.from_xml_path(str(target))
    assert (m.neq, m.nu) == (8, 4)
    assert unmarked(target.read_text()) == mjcf.to_mjcf(h4pin.load("symmetric"), "h4")


@pytest.mark.parametrize("where", ["missing/h4.xml", "."])
def test_export_cli_bad_path_is_one_line(tmp_path, where):
    out = subprocess.run([sys.executable, "-m", "h4pin.cli", "export", "--out", str(tmp_path / where)],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and out.stderr.startswith("error: --out ")
    assert list(tmp_path.iterdir()) == []
