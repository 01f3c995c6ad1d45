# SPDX-License-Identifier: Apache-2.0
"""The H4 in MuJoCo (``mujoco`` extra): closures kept, kinematics equal to Pinocchio's, gravity held."""

from __future__ import annotations

import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin.io import mjcf
from h4pin.kinematics.closed_form import centre_pose

mujoco = pytest.importorskip("mujoco")

ROOT = Path(__file__).resolve().parent.parent
#: Off-centre offsets [dx, dy, dz, dtheta] (m, rad); the symmetric variant is singular at its centre.
OFFSETS = np.array([[0.05, -0.03, 0.02, 0.2], [-0.08, 0.06, -0.04, -0.3], [0.02, 0.09, 0.05, 0.1]])


@pytest.fixture(scope="module", params=sorted(h4pin.VARIANTS))
def robot(request):
    h4 = h4pin.load(request.param)
    return h4, mujoco.MjModel.from_xml_string(mjcf.to_mjcf(h4))


def _gaps(m, d) -> np.ndarray:
    return np.array([np.linalg.norm(d.site_xpos[m.eq_obj1id[i]] - d.site_xpos[m.eq_obj2id[i]]) for i in range(m.neq)])


def test_mujoco_loads_closures_motors_and_masses(robot):
    h4, m = robot
    assert (m.nq, m.nv) == (h4.model.nq, h4.model.nv)
    assert m.neq == 8
    assert all(m.eq_type[i] == mujoco.mjtEq.mjEQ_CONNECT for i in range(m.neq))
    assert m.nu == 4
    driven = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, m.actuator_trnid[a, 0]) for a in range(m.nu)]
    assert tuple(driven) == h4.actuated_joint_names
    # MuJoCo's joint velocity addresses of the motors are Pinocchio's v_act.
    assert [m.jnt_dofadr[m.actuator_trnid[a, 0]] for a in range(m.nu)] == list(h4.v_act)
    # Moving masses (Pinocchio's inertias[0] is the fixed base, merged into the world).
    assert sum(m.body_mass) == pytest.approx(sum(i.mass for i in h4.model.inertias[1:]), rel=1e-12)


def test_closures_and_frames_at_the_configuration(robot):
    """MuJoCo's forward kinematics at h4.configuration(pose): loops closed, frames where Pinocchio has them."""
    h4, m = robot
    d = mujoco.MjData(m)
    data = h4.model.createData()
    worst = 0.0
    for pose in centre_pose(h4) + OFFSETS:
        q = h4.configuration(pose)
        d.qpos[:] = mjcf.qpos(h4, q)
        mujoco.mj_forward(m, d)
        gaps = _gaps(m, d)
        worst = max(worst, gaps.max())
        assert gaps.max() <= 1e-12
        pin.framesForwardKinematics(h4.model, data, q)
        for name in ["D", "C_1", "C_2"] + [f"B_{i}{j}" for i in range(1, 5) for j in (1, 2)]:
            np.testing.assert_allclose(d.site(name).xpos, data.oMf[h4.frames[name]].translation, rtol=0, atol=1e-12)
        np.testing.assert_allclose(d.site("D").xpos, pose[:3], rtol=0, atol=1e-12)
    # The keyframe q0 is a closed configuration too.
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    assert _gaps(m, d).max() <= 1e-12


#: Bound on the motion of D over 0.5 s with the actuators at the gravity torques (measured: below 4e-8 m).
HOLD_DRIFT = 1e-6


def test_gravity_torques_hold_the_robot_still(robot):
    h4, m = robot
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
            assert _gaps(m, d).max() < 1e-6  # the loops stay closed while it moves or not
        assert drifts[0] < HOLD_DRIFT, f"D moved {drifts[0]:.2e} m in 0.5 s at the gravity torques"
        if n == 0:
            assert drifts[1] > 1e-2  # without them the robot falls: the torques are what holds it


def test_export_cli_writes_a_loadable_file(tmp_path):
    target = tmp_path / "h4.xml"
    out = subprocess.run([sys.executable, "-m", "h4pin.cli", "export", "--mjcf", str(target), "--variant", "symmetric"],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert stat.S_IMODE(target.stat().st_mode) == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["h4.xml"]  # no temporary file left
    m = mujoco.MjModel.from_xml_path(str(target))
    assert (m.neq, m.nu) == (8, 4)
    assert target.read_text() == mjcf.to_mjcf(h4pin.load("symmetric"), "h4")


@pytest.mark.parametrize("where", ["missing/h4.xml", "."])
def test_export_cli_bad_path_is_one_line(tmp_path, where):
    out = subprocess.run([sys.executable, "-m", "h4pin.cli", "export", "--mjcf", str(tmp_path / where)],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and out.stderr.startswith("error: --mjcf ")
    assert list(tmp_path.iterdir()) == []
