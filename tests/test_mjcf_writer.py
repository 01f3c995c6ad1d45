# SPDX-License-Identifier: Apache-2.0
"""Any mechanism as an elastic MuJoCo file (``Mechanism.to_mjcf``, h4pin.mechanism.mjcf_writer).

The reference is h4pin's, computed without MuJoCo: the compliance of ``Mechanism.compliance``
(Pinocchio's Jacobians and the closures' null space). MuJoCo integrates the written file: a
static load at an output site, settled with added damping and gravity off; its displacement must
be ``C F`` within 1 %. The file is also read back, as text (its equalities and stiffnesses) and
through ``Mechanism.from_mjcf`` (Pinocchio's MJCF reader and MuJoCo's compiler): the same
springs, closures and compliance.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from h4pin.errors import MechanismWarning, ParameterError, UnsupportedFeatureError
from h4pin.mechanism import Beam, FrameOutput, Mechanism, UnassembledError
from h4pin.mechanism import mjcf_writer as mw

mujoco = pytest.importorskip("mujoco")
if mw.version(mujoco.__version__) < mw.version(mw.MIN_MUJOCO_ELASTIC):
    pytest.skip(f"the elastic export needs MuJoCo >= {mw.MIN_MUJOCO_ELASTIC}, this is {mujoco.__version__}",
                allow_module_level=True)

ROBOTS = Path(__file__).parent / "robots"
#: An aluminium tube, 25 x 2 mm (docs/mechanisms.md).
TUBE = Beam.tube(0.025, 0.002, E=70e9, G=26e9)
#: case -> (robot, output frame, links made beams, MuJoCo time step s). A closure is a spring of
#: about 2.5e3 m / dt^2 N/m (m the mass it moves): the delta's links weigh grams, so its closures
#: need a smaller step to stay far stiffer than its springs (7 % softer at the default 5e-5 s,
#: 0.25 % at 1e-5 s).
CASES = {"5bar_linkage_iso3d": ("5bar_linkage_iso3d", "effector", (), 5e-5),
         "5bar_with_beams": ("5bar_linkage_iso3d", "effector", ("part_2", "part_3", "part_4"), 5e-5),
         "robot_delta": ("robot_delta", "eff", (), 1e-5)}
#: The load's direction (normalised), its size set for a displacement of 1e-4 m.
DIRECTION = np.array([0.3, 0.8, -0.5]) / np.linalg.norm([0.3, 0.8, -0.5])
DISPLACEMENT = 1e-4
STATIC_TOL = 0.01


def _mechanism(robot: str, beams: tuple[str, ...] = ()) -> tuple[Mechanism, np.ndarray, dict[str, float]]:
    """The robot (its ``beams`` links flexible), assembled, with a spring on every joint: motors
    2e3, passive joints 50 N.m/rad."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        mech = Mechanism.from_urdf(ROBOTS / robot / "robot.urdf")
        springs = {n: 2e3 if n in mech.actuated else 50.0 for n in list(mech.model.names)[1:]}
        if beams:
            mech = mech.with_beams(dict.fromkeys(beams, TUBE))
        return mech, mech.assemble(), springs


def _settled(path: Path, frame: str, force: np.ndarray, steps: int = 500) -> np.ndarray:
    """MuJoCo's displacement (3,) of site ``frame`` under ``force`` (N) at it, gravity off: the
    generalised force of the load at the keyframe, every joint damped near critically on its own
    inertia, stepped until the site moves less than 1e-7 of its displacement in ``steps`` steps."""
    m = mujoco.MjModel.from_xml_path(str(path))
    m.opt.gravity[:] = 0.0
    k = m.jnt_stiffness[m.dof_jntid]
    m.dof_damping[:] = 2.0 * np.sqrt(k * (m.dof_M0 + m.dof_armature))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(mw.KEYFRAME).id)
    mujoco.mj_forward(m, d)
    site = m.site(frame).id
    start = d.site_xpos[site].copy()
    mujoco.mj_applyFT(m, d, force, np.zeros(3), start, int(m.site_bodyid[site]), d.qfrc_applied)
    last = start
    for _ in range(400):
        for _ in range(steps):
            mujoco.mj_step(m, d)
        x = d.site_xpos[site].copy()
        assert np.all(np.isfinite(x)), "MuJoCo diverged"
        if np.linalg.norm(x - last) < 1e-7 * np.linalg.norm(x - start):
            return x - start
        last = x
    raise AssertionError("not settled")


@pytest.mark.parametrize("case", list(CASES))
def test_static_displacement_equals_the_compliance(case, tmp_path):
    """MuJoCo's settled displacement of the output site under F is C F (C: the translational block
    of Mechanism.compliance, world axes, the beams' springs included) within 1 %. Measured: 5-bar
    1.2e-4, 5-bar with three aluminium links 1.8e-4, delta 2.5e-3."""
    robot, frame, beams, dt = CASES[case]
    mech, q, springs = _mechanism(robot, beams)
    C = mech.compliance(q, springs, [FrameOutput(frame, reference=pin.LOCAL_WORLD_ALIGNED)])[:3, :3]
    force = DIRECTION * DISPLACEMENT / np.linalg.norm(C @ DIRECTION)
    if case == "robot_delta" and mw.version(mujoco.__version__) < mw.version("3.10"):
        # MuJoCo 3.2.5 to 3.9 step the file once from qpos0 as they compile it; the delta's grams at
        # 1e-5 s pass their limit there (3.2.5 to 3.9.0 checked): refused in one line, nothing written.
        with pytest.raises(UnsupportedFeatureError, match="steps the model once from qpos0.*MuJoCo >= 3.10"):
            mech.to_mjcf(tmp_path / f"{case}.xml", springs, q, sites=[frame], timestep=dt)
        assert not list(tmp_path.iterdir())
        return
    path = mech.to_mjcf(tmp_path / f"{case}.xml", springs, q, sites=[frame], timestep=dt)
    got, want = _settled(path, frame, force), C @ force
    error = np.linalg.norm(got - want) / np.linalg.norm(want)
    assert error < STATIC_TOL, (got, want, error)


def test_the_file_holds_the_springs_closures_and_rest(tmp_path):
    """The 5-bar's file, read as text and by MuJoCo: one equality per closure of its kind, each
    joint's stiffness and springref (its value in q), damping DAMPING x stiffness, the keyframe q;
    read back by Mechanism.from_mjcf: the same springs, motors, closures and compliance."""
    mech, q, springs = _mechanism("5bar_linkage_iso3d")
    path = mech.to_mjcf(tmp_path / "five_bar.xml", springs, q, sites=["effector"])
    root = ET.parse(path).getroot()
    kinds = [e.tag for e in root.find("equality")]
    want = ["connect" if cm.type == pin.ContactType.CONTACT_3D else "weld" for cm in mech.constraint_models]
    assert kinds == want == ["connect"]
    joints = {j.get("name"): j for j in root.iter("joint")}
    assert set(joints) == set(springs)
    for name, k in springs.items():
        jm = mech.model.joints[mech.model.getJointId(name)]
        assert float(joints[name].get("stiffness").split()[0]) == k
        assert float(joints[name].get("springref", "0")) == pytest.approx(q[jm.idx_q], abs=1e-15)
    m = mujoco.MjModel.from_xml_path(str(path))
    assert m.neq == len(mech.constraint_models) and m.nu == len(mech.actuated)
    np.testing.assert_allclose(m.dof_damping, mw.DAMPING * m.jnt_stiffness[m.dof_jntid], rtol=1e-15)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(mw.KEYFRAME).id)
    mujoco.mj_forward(m, d)
    assert np.abs(d.efc_pos).max() < 1e-12  # the keyframe closes the loops
    pd = mech.model.createData()
    pin.framesForwardKinematics(mech.model, pd, q)
    np.testing.assert_allclose(d.site("effector").xpos, pd.oMf[mech.model.getFrameId("effector")].translation,
                               rtol=0, atol=1e-12)
    if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
        pytest.skip(f"needs Pinocchio >= 4 (closures read from MJCF), this is {pin.__version__}")
    back = Mechanism.from_mjcf(path)
    assert back.springs == springs and set(back.actuated) == set(mech.actuated)
    assert len(back.constraint_models) == len(mech.constraint_models)
    out = [FrameOutput("effector", reference=pin.LOCAL_WORLD_ALIGNED)]
    np.testing.assert_allclose(back.compliance(back.reference, back.springs, out), mech.compliance(q, springs, out),
                               rtol=0, atol=1e-9 * np.abs(mech.compliance(q, springs, out)).max())


def test_welds_locked_motors_and_beams_are_written_as_the_mechanism_holds_them(tmp_path):
    """The delta's three 6-D closures are welds; its motors without a spring are left out (welded
    at q); the 5-bar with a beam: its six virtual joints carry the beam's springs at rest 0."""
    mech, q, springs = _mechanism("robot_delta")
    passive = {n: k for n, k in springs.items() if n not in mech.actuated}
    path = mech.to_mjcf(tmp_path / "delta.xml", passive, q)
    m = mujoco.MjModel.from_xml_path(str(path))
    assert list(m.eq_type) == [mujoco.mjtEq.mjEQ_WELD] * 3 and m.nu == 0
    assert {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(m.njnt)} == set(passive)
    beamy, q, springs = _mechanism("5bar_linkage_iso3d", ("part_3",))
    path = beamy.to_mjcf(tmp_path / "beam.xml", springs, q)
    m = mujoco.MjModel.from_xml_path(str(path))
    for name, k in beamy.beam_springs.items():
        assert m.joint(name).stiffness[0] == pytest.approx(k, rel=1e-15)
        assert m.qpos_spring[m.jnt_qposadr[m.joint(name).id]] == 0.0
    assert len(beamy.beam_springs) == 6


def test_bad_input_is_refused_with_a_typed_error_and_nothing_written(tmp_path):
    mech, q, springs = _mechanism("5bar_linkage_iso3d")
    target = tmp_path / "five_bar.xml"
    with pytest.raises(ParameterError, match="no joint 'elbow'"):
        mech.to_mjcf(target, {**springs, "elbow": 10.0}, q)
    with pytest.raises(ParameterError, match="finite and > 0"):
        mech.to_mjcf(target, {**springs, "free1": -1.0}, q)
    with pytest.raises(UnassembledError, match="is off by"):
        mech.to_mjcf(target, springs, q + 0.1)
    with pytest.raises(ParameterError, match="both locked and sprung"):
        mech.to_mjcf(target, springs, q, locked=["free1"])
    with pytest.raises(ParameterError, match="no frame"):
        mech.to_mjcf(target, springs, q, sites=["nowhere"])
    with pytest.raises(ParameterError, match=r"\.xml"):
        mech.to_mjcf(tmp_path / "five_bar.urdf", springs, q)
    assert list(tmp_path.iterdir()) == []
    target.write_text("<mujoco/>")  # a user's file
    with pytest.raises(ParameterError, match="h4pin did not write it"):
        mech.to_mjcf(target, springs, q)
    assert target.read_text() == "<mujoco/>"
    mech.to_mjcf(target, springs, q, overwrite=True)
    mech.to_mjcf(target, springs, q)  # h4pin's own, unchanged: replaced
    assert sorted(p.name for p in tmp_path.iterdir()) == ["five_bar.xml"]


def test_joints_mujoco_cannot_hold_are_refused_by_name():
    """A spherical joint with three stiffnesses, a planar joint: refused, never approximated."""
    model = pin.Model()
    ball = model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    model.appendBodyToJoint(ball, pin.Inertia.FromSphere(1.0, 0.1), pin.SE3.Identity())
    plane = model.addJoint(ball, pin.JointModelPlanar(), pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.5])), "plane")
    model.appendBodyToJoint(plane, pin.Inertia.FromSphere(1.0, 0.1), pin.SE3.Identity())
    mech = Mechanism(model)
    with pytest.raises(UnsupportedFeatureError, match="'ball' has 3 stiffnesses"):
        mw.spec(mech, {"ball": [1.0, 2.0, 3.0]}, pin.neutral(model))
    with pytest.raises(UnsupportedFeatureError, match="'plane'.*no MuJoCo counterpart"):
        mw.spec(mech, {"ball": 1.0}, pin.neutral(model))


def test_cli_exports_any_robot(tmp_path, monkeypatch, capsys):
    """``h4pin export --robot URDF --elastic --spring J=K --site FRAME``: the file holds those
    springs (the motors without one locked); a bad spring is one line and exit 2, nothing written."""
    from conftest import run_cli_in_process

    target = tmp_path / "delta.xml"
    args = ["export", "--robot", str(ROBOTS / "robot_delta" / "robot.urdf"), "--elastic", "--out", str(target)]
    code, out, err = run_cli_in_process([*args, "--spring", "mot1_rod1=2000", "--spring", "free1_rod1=50",
                                         "--site", "eff", "--timestep", "1e-5"], monkeypatch, capsys)
    assert code == 0 and out == f"wrote {target}\n", err
    m = mujoco.MjModel.from_xml_path(str(target))
    assert {m.joint(i).name: m.jnt_stiffness[i] for i in range(m.njnt) if m.jnt_stiffness[i]} == {
        "mot1_rod1": 2000.0, "free1_rod1": 50.0}
    assert m.nu == 1 and m.site("eff").id >= 0 and m.opt.timestep == 1e-5
    assert "mot1_rod2" not in {m.joint(i).name for i in range(m.njnt)}  # locked: no spring
    code, _, err = run_cli_in_process([*args[:-1], str(tmp_path / "bad.xml"), "--spring", "elbow=1"],
                                      monkeypatch, capsys)
    assert code == 2 and err.startswith("error: springs: no joint 'elbow'") and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["delta.xml"]
