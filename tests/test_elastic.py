# SPDX-License-Identifier: Apache-2.0
"""The generic closed-loop stiffness engine (:mod:`h4pin.elastic`) against independent routes.

* The H4: :func:`h4pin.elastic.elastic_model` (virtual elastic joints, Pinocchio's closure and frame
  Jacobians) equals ``h4pin.compliance(..., model="consistent")`` (the paper's matrices with
  erratum 4 fixed, plus the elements' unit-load terms) at poses across the workspace of every
  shipped variant, with and without elements, and element kind by element kind.
* A planar five-bar written here as a URDF, with torsion springs behind its two motors and axial
  springs in its distal links: the compliance of its tip equals the hand-derived
  ``C = G diag(1/k_theta) G^T + Jx^-1 diag(1/k_s) Jx^-T``.
* The typed errors: unassembled configuration, a motion that strains no spring, a singular pose.
* The usage example of ``docs/elastic.md`` runs as written.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import sample_poses

import h4pin
from h4pin.description.elements import ELEMENTS, ILLUSTRATIVE, RIGIDITIES, Elements
from h4pin.elastic import elastic_model
from h4pin.kinematics.closed_form import centre_pose
from h4pin.mechanism import (
    FrameOutput,
    Insertion,
    JointOutput,
    UnassembledError,
    UnrestrainedMotionError,
    VirtualJoint,
    compliance_matrix,
    insert_joints,
)

TOL = 1e-9


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# --- the H4 -------------------------------------------------------------------------------------


@pytest.fixture(scope="module", params=h4pin.VARIANTS)
def variant(request) -> str:
    return request.param


@pytest.mark.parametrize("elements", [None, ILLUSTRATIVE], ids=["own", "illustrative"])
def test_elastic_h4_equals_the_consistent_model(variant, elements):
    h4 = h4pin.load(variant, elements=elements)
    em = elastic_model(h4)
    xs = sample_poses(h4, 6, seed=1)
    assert np.ptp(xs, axis=0).min() > 0.05  # spread over the workspace (x, y, z in m; theta in rad)
    errors = [rel(em.compliance_matrix(x), h4pin.compliance(h4, x, model="consistent").matrix) for x in xs]
    assert max(errors) <= TOL, errors


@pytest.mark.parametrize("variant_name", ["prototype", "toleranced"])
@pytest.mark.parametrize("kind", ELEMENTS)
def test_each_element_kind_is_its_own_term(variant_name, kind):
    """One kind at a time, 100 times the illustrative value: the elastic model's change equals the
    unit-load term of that kind (which is then at least 1e-3 of K, so that 1e-9 of K checks it)."""
    base = h4pin.load(variant_name)
    value = getattr(ILLUSTRATIVE, kind)
    h4 = base.with_elements(Elements(**{kind: value / 100 if kind in RIGIDITIES else value * 100}))
    em, em0 = elastic_model(h4), elastic_model(base)
    for x in sample_poses(base, 2, seed=4):
        ref = h4pin.compliance(h4, x, model="consistent", terms=True)
        term, norm = ref.terms[kind], np.linalg.norm(ref.matrix)
        assert np.linalg.norm(term) > 1e-3 * norm
        assert np.linalg.norm(em.compliance_matrix(x) - em0.compliance_matrix(x) - term) <= TOL * norm


def test_elastic_h4_names_its_springs_from_the_robot(proto):
    em = elastic_model(proto)
    g = proto.geometry
    assert len(em.stiffness) == 16 and em.model.nv == proto.model.nv + 16
    c = 1 / g.springs["kc"][0] + g.r[0] / (3 * g.springs["E"][0] * g.springs["I"][0])
    assert em.stiffness["actuator_1_elastic"] == pytest.approx(1 / c, rel=1e-15)
    assert em.stiffness["bar_32_tension"] == pytest.approx(g.springs["Sb"][5] * g.springs["Eb"][5] / g.l[5], rel=1e-15)
    full = elastic_model(proto.with_elements(ILLUSTRATIVE))
    assert full.stiffness["bar_11_ball_A"] == pytest.approx(1 / ILLUSTRATIVE.ball_radial[0])
    # 16 + 16 ball + 2 x (5 revolute, 5 central beam) + 4 x 5 arm + 4 x (2 shaft + 6 mount + 2 out of plane)
    assert len(full.stiffness) == 16 + 16 + 20 + 20 + 40 == full.model.nv - proto.model.nv
    r, ei = g.r[0], ILLUSTRATIVE.forearm_out_EI[0]  # two Gauss points of the whole forearm
    assert full.stiffness["forearm_1_out_1"] == full.stiffness["forearm_1_out_2"] == pytest.approx(2 * ei / r)
    # the frames keep their ids and, at a rigid pose, their places
    x = centre_pose(proto)
    d = full.model.createData()
    pin.framesForwardKinematics(full.model, d, full.configuration(x))
    pin.framesForwardKinematics(proto.model, proto.data, proto.configuration(x))
    for name in ("D", "B_11", "A_42", "C_2", "bar_21_end"):
        f = proto.frames[name]
        assert full.model.frames[f].name == name
        np.testing.assert_allclose(d.oMf[f].translation, proto.data.oMf[f].translation, atol=1e-14)


def test_elastic_h4_refuses_the_singular_pose_as_the_paper_model_does(sym):
    x = centre_pose(sym)
    with pytest.raises(h4pin.SingularPoseError):
        h4pin.compliance(sym, x, model="consistent")
    with pytest.raises(UnrestrainedMotionError) as err:
        elastic_model(sym).compliance_matrix(x)
    assert isinstance(err.value, h4pin.SingularPoseError) and "plate" in err.value.joints


def test_elastic_h4_gives_one_answer_per_thread(proto):
    """Each thread works in its own pin.Data (ElasticH4.data): four at once give the serial K."""
    from concurrent.futures import ThreadPoolExecutor

    em = elastic_model(proto)
    xs = sample_poses(proto, 4, seed=9)
    serial = [em.compliance_matrix(x) for x in xs]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(em.compliance_matrix, xs))
    for a, b in zip(serial, threaded, strict=True):  # round-off apart (BLAS may split work differently)
        assert rel(b, a) <= 1e-13


# --- a planar five-bar --------------------------------------------------------------------------

L1, L2, HALF = 0.20, 0.30, 0.10  # proximal and distal lengths, half the base (m)
K_THETA = (900.0, 1500.0)  # N.m/rad behind motors 1, 2
K_S = (4e5, 2.5e5)  # N/m along distal links 1, 2


def five_bar_urdf(springs: bool = True) -> str:
    """Two branches from O_i = (-+HALF, 0, 0): motor_i (z), [spring_i (z)], proximal L1, elbow_i (z),
    [stretch_i (prismatic along the distal link)], tip_i at L2; closed by tip_1 = tip_2."""
    inertia = ('<inertial><mass value="0.1"/>'
               '<inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial>')
    out = ['<robot name="five_bar">', f'<link name="base">{inertia}</link>']

    def chain(parent: str, links: list[tuple[str, str, str, str]]) -> None:
        for name, kind, xyz, axis in links:
            out.append(f'<link name="{name}_link">{inertia}</link>')
            limit = '<limit lower="-10" upper="10" effort="1" velocity="1"/>' if kind != "fixed" else ""
            out.append(f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{name}_link"/>'
                       f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>{limit}</joint>')
            parent = f"{name}_link"

    for i, x0 in ((1, -HALF), (2, HALF)):
        links = [(f"motor_{i}", "revolute", f"{x0} 0 0", "0 0 1")]
        links += [(f"spring_{i}", "revolute", "0 0 0", "0 0 1")] if springs else []
        links += [(f"elbow_{i}", "revolute", f"{L1} 0 0", "0 0 1")]
        links += [(f"stretch_{i}", "prismatic", "0 0 0", "1 0 0")] if springs else []
        links += [(f"tip_{i}", "fixed", f"{L2} 0 0", "1 0 0")]
        chain("base", links)
    return "\n".join([*out, "</robot>"])


def five_bar_points(theta: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Elbows A (2, 2) and tip E (2,) (upper assembly) for motor angles theta (rad)."""
    o = np.array([[-HALF, 0.0], [HALF, 0.0]])
    a = o + L1 * np.column_stack([np.cos(theta), np.sin(theta)])
    mid, chord = 0.5 * (a[0] + a[1]), a[1] - a[0]
    half = np.linalg.norm(chord) / 2
    normal = np.array([-chord[1], chord[0]]) / (2 * half)
    return a, mid + np.sqrt(max(L2**2 - half**2, 0.0)) * normal


def five_bar(springs: bool = True) -> tuple[pin.Model, pin.StdVec_RigidConstraintModel]:
    model = pin.buildModelFromXML(five_bar_urdf(springs))
    f1, f2 = (model.frames[model.getFrameId(f"tip_{i}")] for i in (1, 2))
    cms = pin.StdVec_RigidConstraintModel()
    cms.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, f1.parentJoint, f1.placement,
                                        f2.parentJoint, f2.placement, pin.ReferenceFrame.LOCAL))
    return model, cms


def five_bar_q(model: pin.Model, theta: tuple[float, float]) -> np.ndarray:
    a, e = five_bar_points(theta)
    q = np.zeros(model.nq)
    for i in range(2):
        d = e - a[i]
        q[model.joints[model.getJointId(f"motor_{i + 1}")].idx_q] = theta[i]
        q[model.joints[model.getJointId(f"elbow_{i + 1}")].idx_q] = np.arctan2(d[1], d[0]) - theta[i]
    return q


def five_bar_by_hand(theta: tuple[float, float]) -> np.ndarray:
    """C (2, 2) of the tip (m/N): e_i . (dE - dA_i) = ds_i with dA_i = L1 t_i dtheta_i, so
    dE = Jx^-1 (Jq dtheta + ds); by virtual work C = G K_theta^-1 G^T + Jx^-1 K_s^-1 Jx^-T."""
    a, e = five_bar_points(theta)
    u = (e - a) / L2
    t = np.column_stack([-np.sin(theta), np.cos(theta)])
    jx_inv = np.linalg.inv(u)
    g = jx_inv @ np.diag(L1 * np.sum(u * t, axis=1))
    return g @ np.diag(1 / np.array(K_THETA)) @ g.T + jx_inv @ np.diag(1 / np.array(K_S)) @ jx_inv.T


FIVE_BAR_STIFFNESS = {"spring_1": K_THETA[0], "spring_2": K_THETA[1], "stretch_1": K_S[0], "stretch_2": K_S[1]}
FIVE_BAR_POSES = [(1.2, 1.9), (0.9, 2.4), (1.6, 1.4), (0.5, 1.8), (1.0, 1.0)]


@pytest.mark.parametrize("theta", FIVE_BAR_POSES)
def test_five_bar_equals_the_hand_derived_compliance(theta):
    model, cms = five_bar()
    c = compliance_matrix(model, cms, five_bar_q(model, theta), locked=["motor_1", "motor_2"],
                          stiffness=FIVE_BAR_STIFFNESS, outputs=[FrameOutput("tip_1", rows=(0, 1))])
    assert rel(c, five_bar_by_hand(theta)) <= TOL


def test_five_bar_built_by_inserting_joints_equals_the_urdf_one():
    """The rigid five-bar plus insert_joints (springs behind the motors, stretches along the distal
    links, the closure's sides moved to the links' new ends) gives the same compliance."""
    rigid, cms = five_bar(springs=False)
    theta = FIVE_BAR_POSES[1]
    q_rigid = five_bar_q(rigid, theta)
    d = rigid.createData()
    pin.framesForwardKinematics(rigid, d, q_rigid)
    insertions = []
    for i in (1, 2):
        motor, elbow = rigid.getJointId(f"motor_{i}"), rigid.getJointId(f"elbow_{i}")
        tip = d.oMf[rigid.getFrameId(f"tip_{i}")].translation
        insertions.append(Insertion(f"motor_{i}", (VirtualJoint(f"spring_{i}", "revolute", [0, 0, 1],
                                                                d.oMi[motor].translation, K_THETA[i - 1]),),
                                    children=(f"elbow_{i}",)))
        insertions.append(Insertion(f"elbow_{i}", (VirtualJoint(f"stretch_{i}", "prismatic",
                                                                tip - d.oMi[elbow].translation, tip, K_S[i - 1]),),
                                    frames=(f"tip_{i}",), closures=((0, i),)))
    model, closures, q_index = insert_joints(rigid, insertions, cms, q_ref=q_rigid)
    q = np.zeros(model.nq)
    q[q_index] = q_rigid
    c = compliance_matrix(model, closures, q, locked=["motor_1", "motor_2"], stiffness=FIVE_BAR_STIFFNESS,
                   outputs=[FrameOutput("tip_2", rows=(0, 1))])
    assert rel(c, five_bar_by_hand(theta)) <= TOL


def test_five_bar_joint_output_is_the_dual_of_a_joint_torque():
    """Output the elbow angle of branch 1 with the tip: the elbow's row is its rotation per unit
    load; by hand, elbow_1 = atan2(E - A_1) - theta_1, differentiated with the same G."""
    model, cms = five_bar()
    theta = FIVE_BAR_POSES[0]
    c = compliance_matrix(model, cms, five_bar_q(model, theta), locked=["motor_1", "motor_2"],
                          stiffness=FIVE_BAR_STIFFNESS,
                          outputs=[FrameOutput("tip_1", rows=(0, 1)), JointOutput("elbow_1", scale=-1.0)])
    a, e = five_bar_points(theta)
    u = (e - a) / L2
    t = np.column_stack([-np.sin(theta), np.cos(theta)])
    jx_inv = np.linalg.inv(u)
    jq = np.diag(L1 * np.sum(u * t, axis=1))
    # motion per spring coordinate [dpsi_1, dpsi_2, ds_1, ds_2]: tip, then the elbow angle
    tip = np.hstack([jx_inv @ jq, jx_inv])
    n1 = np.array([-u[0, 1], u[0, 0]])  # d(angle of E - A_1) = n1 . (dE - dA_1) / L2
    da1 = np.hstack([L1 * np.outer(t[0], [1, 0]), np.zeros((2, 2))])
    elbow = n1 @ (tip - da1) / L2 - np.array([1.0, 0, 0, 0])
    y = np.vstack([tip, -elbow])
    by_hand = y @ np.diag(1 / np.r_[K_THETA, K_S]) @ y.T
    assert rel(c, by_hand) <= TOL


def test_five_bar_errors():
    model, cms = five_bar()
    theta = FIVE_BAR_POSES[0]
    q = five_bar_q(model, theta)
    kw = {"locked": ["motor_1", "motor_2"], "outputs": [FrameOutput("tip_1", rows=(0, 1))]}
    bent = q.copy()
    bent[model.joints[model.getJointId("motor_1")].idx_q] += 1e-3
    with pytest.raises(UnassembledError, match="does not hold"):
        compliance_matrix(model, cms, bent, stiffness=FIVE_BAR_STIFFNESS, **kw)
    free = {k: v for k, v in FIVE_BAR_STIFFNESS.items() if k != "spring_1"}
    with pytest.raises(UnrestrainedMotionError) as err:
        compliance_matrix(model, cms, q, stiffness=free, **kw)
    assert "spring_1" in err.value.joints and "spring_2" not in err.value.joints
    assert err.value.cond == np.inf or err.value.cond > 1e15
    # distal links in line (|A_1 - A_2| = 2 L2): the tip moves across them, straining nothing
    assert 2 * L2 == pytest.approx(2 * HALF + 2 * L1)  # reached with both arms along the base
    with pytest.raises(h4pin.SingularPoseError):
        compliance_matrix(model, cms, five_bar_q(model, (np.pi, 0.0)), stiffness=FIVE_BAR_STIFFNESS, **kw)
    with pytest.raises(h4pin.ParameterError, match="both locked and elastic"):
        compliance_matrix(model, cms, q, stiffness={**FIVE_BAR_STIFFNESS, "motor_1": 1.0}, **kw)
    with pytest.raises(h4pin.ParameterError, match="no joint named"):
        compliance_matrix(model, cms, q, stiffness={"nope": 1.0}, **kw)
    with pytest.raises(h4pin.ParameterError, match="finite and > 0"):
        compliance_matrix(model, cms, q, stiffness={**FIVE_BAR_STIFFNESS, "spring_1": -1.0}, **kw)


# --- docs/elastic.md ----------------------------------------------------------------------------


def test_the_docs_example_runs():
    text = (Path(__file__).resolve().parent.parent / "docs" / "elastic.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, "docs/elastic.md", "exec"), namespace)  # noqa: S102
    assert namespace["error"] <= TOL
