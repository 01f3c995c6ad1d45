# SPDX-License-Identifier: Apache-2.0
"""Mechanism.from_mjcf reads an MJCF file as MuJoCo means it (tests/robots/synthetic): the same
kinematics as MuJoCo's for random configurations (a body's several joints split back from
Pinocchio's composite joint, quaternions reordered), the reference configuration from the first
keyframe, the ranges and springs as MuJoCo compiles them (degrees by default), motors on every
joint of a body, joint couplings as constraints, and motors it cannot represent refused by name."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from h4pin.errors import UnsupportedFeatureError
from h4pin.mechanism import Mechanism

mujoco = pytest.importorskip("mujoco")
if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
    pytest.skip(f"needs Pinocchio >= 4 (closures read from MJCF), this is {pin.__version__}", allow_module_level=True)

HERE = Path(__file__).parent / "robots" / "synthetic"


def _random_qpos(mj, rng):
    qpos = mj.qpos0.copy()
    for i in range(mj.njnt):
        adr, kind = mj.jnt_qposadr[i], int(mj.jnt_type[i])
        if kind == int(mujoco.mjtJoint.mjJNT_FREE):
            qpos[adr:adr + 3] = rng.normal(size=3)
            qpos[adr + 3:adr + 7] = rng.normal(size=4)
            qpos[adr + 3:adr + 7] /= np.linalg.norm(qpos[adr + 3:adr + 7])
        elif kind == int(mujoco.mjtJoint.mjJNT_BALL):
            x = rng.normal(size=4)
            qpos[adr:adr + 4] = x / np.linalg.norm(x)
        else:
            qpos[adr] = rng.uniform(-1, 1)
    return qpos


@pytest.mark.parametrize("name", ["loop", "floating"])
def test_kinematics_agree_with_mujoco(name):
    from h4pin.mechanism import mjcf_reader

    mech = Mechanism.from_mjcf(HERE / f"{name}.xml")
    mj = mujoco.MjModel.from_xml_path(str(HERE / f"{name}.xml"))
    d, pd = mujoco.MjData(mj), mech.model.createData()
    rng = np.random.default_rng(3)
    for _ in range(5):
        d.qpos[:] = _random_qpos(mj, rng)
        mujoco.mj_kinematics(mj, d)
        q = mjcf_reader.from_qpos(mj, mech.model, d.qpos)
        pin.framesForwardKinematics(mech.model, pd, q)
        for b in range(1, mj.nbody):
            bname = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b)
            f = pd.oMf[mech.model.getFrameId(bname, pin.FrameType.BODY)]
            np.testing.assert_allclose(f.translation, d.xpos[b], rtol=0, atol=1e-12, err_msg=bname)
            np.testing.assert_allclose(f.rotation, d.xmat[b].reshape(3, 3), rtol=0, atol=1e-12, err_msg=bname)


def test_reference_ranges_springs_and_motors_are_the_files():
    mech = Mechanism.from_mjcf(HERE / "loop.xml")
    mj = mujoco.MjModel.from_xml_path(str(HERE / "loop.xml"))
    # motors on the second joint of a body (Pinocchio's composite) and on the first of another
    assert set(mech.actuated) == {"crank", "tilt"}
    model = mech.model
    iq = {n: model.joints[model.getJointId(n)].idx_q for n in ("tilt", "crank", "coupler")}
    # Pinocchio's coordinate of a hinge: MuJoCo's qpos minus the joint's ref (tilt: ref 5 degrees)
    ref = np.radians(5)
    want = mj.key_qpos[0][:2] - [ref, 0.0]
    np.testing.assert_allclose(mech.reference[[iq["tilt"], iq["crank"]]], want, rtol=0, atol=1e-15)
    lo, hi = mech.ranges
    assert lo[iq["tilt"]] == pytest.approx(np.radians(-40) - ref) and hi[iq["crank"]] == pytest.approx(np.radians(170))
    assert np.isnan(lo[iq["coupler"]])
    assert mech.springs == {"tilt": 40.0} and mech.spring_rest["tilt"] == pytest.approx(np.radians(3) - ref)
    # assembled from the keyframe with the motors held there, inside the ranges
    q = mech.assemble()
    assert max(max(e) for e in mech.closure_errors(q).values()) <= 1e-10
    np.testing.assert_allclose(q[[iq["tilt"], iq["crank"]]], want, rtol=0, atol=1e-15)
    # the file's springs and the motors give a compliance at the tip
    C = mech.compliance(q, {**mech.springs, "crank": 80.0, "coupler_roll": 5.0, "rocker_pitch": 5.0}, ["tip"])
    assert C.shape == (6, 6) and np.all(np.isfinite(C)) and np.allclose(C, C.T, atol=1e-12 * np.abs(C).max())


def test_what_cannot_be_represented_is_refused_by_name():
    with pytest.raises(UnsupportedFeatureError, match=r"'m_tendon' drive no joint"):
        Mechanism.from_mjcf(HERE / "ghost_motor.xml")


def test_a_joint_coupling_is_a_constraint_that_holds_as_mujoco_holds_it():
    """coupled.xml: rocker_pitch = coupler_roll (polycoef 0 1): a JointCoupling, kept by the
    assembly, and MuJoCo's own equality residual (efc_pos) is 0 at the assembled state."""
    from h4pin.mechanism import mjcf_reader

    mech = Mechanism.from_mjcf(HERE / "coupled.xml")
    assert [(c.joint1, c.joint2, c.poly[:2]) for c in mech.couplings] == [("rocker_pitch", "coupler_roll", (0.0, 1.0))]
    start = np.array(mech.reference)
    start[mech.model.joints[mech.model.getJointId("coupler_roll")].idx_q] += 0.2
    q = mech.assemble(start)
    mj = mujoco.MjModel.from_xml_path(str(HERE / "coupled.xml"))
    d = mujoco.MjData(mj)
    for i in range(mj.njnt):
        jm = mech.model.joints[mech.model.getJointId(mjcf_reader._joint_name(mj, i))]
        d.qpos[mj.jnt_qposadr[i]] = q[jm.idx_q] + mjcf_reader._ref(mj, i)
    mujoco.mj_forward(mj, d)
    eq = [r for r in range(d.nefc) if int(d.efc_type[r]) == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)]
    assert len(eq) == 4 and np.abs(d.efc_pos[eq]).max() < 1e-9  # the connect's 3 rows and the coupling's


def test_a_tendon_motor_is_fine_when_the_motors_are_given():
    mech = Mechanism.from_mjcf(HERE / "ghost_motor.xml", actuated=["crank", "tilt"])
    assert mech.actuated == ("crank", "tilt")


def test_files_the_readers_cannot_read_are_typed_errors(tmp_path):
    from h4pin.errors import InputFileError, MalformedURDFError

    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><joint type='nonsense'/></body></worldbody></mujoco>")
    with pytest.raises(MalformedURDFError, match="bad.xml"):
        Mechanism.from_mjcf(bad)
    with pytest.raises(InputFileError, match="nothing.xml: no such file"):
        Mechanism.from_mjcf(tmp_path / "nothing.xml")
