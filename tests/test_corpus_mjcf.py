# SPDX-License-Identifier: Apache-2.0
"""The closed-loop MJCF robots of the corpus (tests/robots/mjcf: MuJoCo Menagerie's Cassie, IIT
SoftFoot, xArm7 gripper and arm, Robotiq 2F-85, TidyBot; ToddlerBot) through
Mechanism.from_mjcf: each loads as MuJoCo means it or is refused by name, assembles from the
file's keyframe (or qpos0) inside the file's ranges, and its compliance agrees with a KKT route
built by the test: the closures' rows from Pinocchio's frame Jacobians at the closures' own
anchors, the joint couplings' rows from MuJoCo's own constraint Jacobian (``efc_J`` of the
``<equality><joint>`` rows, mapped by joint name), the free-flyer root held."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from h4pin.errors import H4Error, UnsupportedFeatureError
from h4pin.mechanism import Mechanism

mujoco = pytest.importorskip("mujoco")
if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
    pytest.skip(f"needs Pinocchio >= 4 (closures read from MJCF), this is {pin.__version__}", allow_module_level=True)
from kkt import closure_rows  # noqa: E402
from test_corpus import _assembled_in_range  # noqa: E402

HERE = Path(__file__).parent / "robots" / "mjcf"
#: robot file -> (motors to give, or None for the file's actuators; output site or body frame)
LOADED = {"agility_cassie/cassie.xml": (None, "left-foot"),
          "iit_softfoot/softfoot.xml": (None, "heel"),
          "ufactory_xarm7/hand.xml": (["left_driver_joint"], "left_finger"),
          "ufactory_xarm7/xarm7.xml": (["joint1", "joint2", "joint3", "joint4", "joint5", "joint6", "joint7",
                                        "left_driver_joint"], "link7")}
#: robot file -> what the refusal names (Pinocchio 4.1's reader, measured)
REFUSED = {"robotiq_2f85/2f85.xml": (UnsupportedFeatureError, "places body 'right_follower'"),
           "stanford_tidybot/tidybot.xml": (UnsupportedFeatureError, "places body 'right_follower'"),
           "toddlerbot/toddlerbot.xml": (H4Error, "Pinocchio's MJCF reader fails")}


@pytest.mark.parametrize("path", sorted(REFUSED))
def test_refused_by_name(path):
    kind, match = REFUSED[path]
    with pytest.raises(kind, match=match):
        Mechanism.from_mjcf(HERE / path)


def _coupling_rows(mj, model, mech, q_mj):
    """MuJoCo's own rows of its joint-coupling equalities at qpos, in Pinocchio's columns."""
    mj.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    d = mujoco.MjData(mj)
    d.qpos[:] = q_mj
    mujoco.mj_forward(mj, d)
    rows = []
    joint_eq = [i for i in range(mj.neq) if int(mj.eq_type[i]) == int(mujoco.mjtEq.mjEQ_JOINT) and mj.eq_active0[i]]
    for r in range(d.nefc):
        if int(d.efc_type[r]) == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY) and d.efc_id[r] in joint_eq:
            row = np.zeros(model.nv)
            for i in range(mj.njnt):
                if int(mj.jnt_type[i]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
                    continue
                name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, i)
                row[model.joints[model.getJointId(name)].idx_v] = d.efc_J.reshape(-1, mj.nv)[r, mj.jnt_dofadr[i]]
            rows.append(row)
    return np.array(rows).reshape(-1, model.nv)


@pytest.mark.parametrize("path", sorted(LOADED))
def test_loads_assembles_and_agrees_with_kkt(path):
    from h4pin.mechanism import mjcf_reader

    motors, out = LOADED[path]
    mech = Mechanism.from_mjcf(HERE / path, actuated=motors)
    mj = mujoco.MjModel.from_xml_path(str(HERE / path))
    q = _assembled_in_range(mech)
    model = mech.model
    springs = {model.names[j]: 20.0 * (1 + 0.1 * (j % 5)) for j in range(1, model.njoints)
               if model.names[j] not in mech.free_flyers}
    springs.update(mech.springs)
    C = mech.compliance(q, springs, [out])
    # the KKT route: closures from their anchors, couplings from MuJoCo's Jacobian at the same state
    d = model.createData()
    pin.computeJointJacobians(model, d, q)
    pin.updateFramePlacements(model, d)
    rows = [closure_rows(model, d, cm) for cm in mech.constraint_models]
    qpos = np.array(mj.qpos0)
    for i in range(mj.njnt):  # the assembled state in MuJoCo's qpos, joint by joint
        jm = model.joints[model.getJointId(mjcf_reader._joint_name(mj, i))]
        adr, kind = mj.jnt_qposadr[i], int(mj.jnt_type[i])
        if kind == int(mujoco.mjtJoint.mjJNT_FREE):
            x = q[jm.idx_q:jm.idx_q + 7]
            qpos[adr:adr + 7] = [*x[:3], x[6], x[3], x[4], x[5]]
        elif kind == int(mujoco.mjtJoint.mjJNT_BALL):
            x = q[jm.idx_q:jm.idx_q + 4]
            qpos[adr:adr + 4] = [x[3], x[0], x[1], x[2]]
        else:
            qpos[adr] = q[jm.idx_q] + mjcf_reader._ref(mj, i)
    np.testing.assert_allclose(mjcf_reader.from_qpos(mj, model, qpos), q, rtol=0, atol=1e-14)
    coupling = _coupling_rows(mj, model, mech, qpos)
    assert coupling.shape[0] == len(mech.couplings)
    eye = np.eye(model.nv)
    for n in mech.free_flyers:
        jm = model.joints[model.getJointId(n)]
        rows.append(eye[jm.idx_v:jm.idx_v + jm.nv])
    a_full = np.vstack(rows + [coupling])
    _, sv, vt = np.linalg.svd(a_full, full_matrices=False)
    a = vt[sv > 1e-10 * sv[0]]
    k = np.zeros(model.nv)
    for name, value in springs.items():
        jm = model.joints[model.getJointId(name)]
        k[jm.idx_v:jm.idx_v + jm.nv] = value
    from h4pin.mechanism.engine import frame_id

    fid = frame_id(model, out)
    jo = pin.getFrameJacobian(model, d, fid, pin.LOCAL_WORLD_ALIGNED)
    n_c = a.shape[0]
    sol = np.linalg.solve(np.block([[np.diag(k), a.T], [a, np.zeros((n_c, n_c))]]),
                          np.vstack([jo.T, np.zeros((n_c, 6))]))
    want = jo @ sol[:model.nv]
    np.testing.assert_allclose(C, want, rtol=0, atol=1e-9 * np.abs(want).max())
    # natural frequencies: the first four against scipy's generalized eigenproblem on null(A)
    scipy_linalg = pytest.importorskip("scipy.linalg")
    n = scipy_linalg.null_space(a_full, rcond=1e-10)  # as the KKT rows: the xArm7's two gripper loops
    # leave one direction at 7.5e-12 of the largest singular value, numerical noise of the file's anchors
    mass = pin.crba(model, d, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    lam = scipy_linalg.eigvals(n.T @ np.diag(k) @ n, n.T @ mass @ n)
    lam = np.sort(lam[np.isfinite(lam)].real)
    got = mech.modes(q, springs).frequencies
    m = min(4, len(got))
    np.testing.assert_allclose(got[:m], np.sqrt(lam[lam > 0][:m]) / (2 * np.pi), rtol=1e-7)
