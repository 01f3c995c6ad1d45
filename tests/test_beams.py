# SPDX-License-Identifier: Apache-2.0
"""Flexible links (h4pin.mechanism.Beam, Mechanism.with_beams): a cantilever and an L-shaped frame
against their hand formulas, and two robots of the corpus with a beam on every link against an
independent frame model written here by the direct stiffness method (12 x 12 Euler-Bernoulli
elements between a link's joint origin and its far end, rigid links as single nodes, joints as
exact constraints on the relative motion of their two bodies, closures as exact constraints,
joint springs), solved as one KKT system."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from h4pin.errors import H4Error, MechanismWarning, ParameterError
from h4pin.mechanism import Beam, Mechanism
from h4pin.mechanism.beams import insertion

ROBOTS = Path(__file__).parent / "robots"
ALU = {"E": 70e9, "G": 26e9}


def _cantilever(beam: Beam, length: float) -> np.ndarray:
    """The tip compliance (6 x 6, [u; theta] per [F; M]) of a cantilever along local x."""
    e, g = beam.E, beam.G
    c = np.zeros((6, 6))
    c[0, 0], c[3, 3] = length / (e * beam.A), length / (g * beam.J)
    c[1, 1], c[5, 5] = length**3 / (3 * e * beam.Iz), length / (e * beam.Iz)
    c[1, 5] = c[5, 1] = length**2 / (2 * e * beam.Iz)
    c[2, 2], c[4, 4] = length**3 / (3 * e * beam.Iy), length / (e * beam.Iy)
    c[2, 4] = c[4, 2] = -length**2 / (2 * e * beam.Iy)
    return c


def _chain(lengths, axes):
    """A serial chain: joint i (about axes[i]) carries link_i, the next joint at lengths[i] along
    the link's axis x (y for the second of an L); a frame 'tip' on the last joint."""
    m = pin.Model()
    parent, place = 0, pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 0.5), np.array([0.1, 0.2, 0.3]))
    for i, (length, axis) in enumerate(zip(lengths, axes, strict=True)):
        j = m.addJoint(parent, axis(), place, f"j{i}")
        m.appendBodyToJoint(j, pin.Inertia.FromBox(1.0, 0.3, 0.02, 0.02), pin.SE3.Identity())
        m.addFrame(pin.Frame(f"link{i}", j, pin.SE3.Identity(), pin.FrameType.BODY), False)
        parent, place = j, pin.SE3(np.eye(3), length)
    m.addFrame(pin.Frame("tip", parent, pin.SE3.Identity(), pin.FrameType.OP_FRAME), False)
    return m


def test_a_cantilever_is_its_hand_formula():
    length = 0.5
    m = _chain([np.array([length, 0, 0]), np.zeros(3)], [pin.JointModelRZ, pin.JointModelRY])
    beam = Beam.rect(0.02, 0.01, **ALU)
    mech = Mechanism(m, (), ["j0"]).with_beams({"link0": beam})
    c = mech.compliance(np.zeros(2), {}, ["tip"], locked=["j0", "j1"])  # the rigid q, accepted as it is
    d = m.createData()
    pin.framesForwardKinematics(m, d, np.zeros(2))
    r = d.oMi[1].rotation  # x along the span; y the link frame's axis most normal to it
    t = np.kron(np.eye(2), r)
    want = _cantilever(beam, length)
    np.testing.assert_allclose(t.T @ c @ t, want, rtol=0, atol=1e-13 * np.abs(want).max())


def test_an_l_frame_is_its_hand_formula():
    """Two members at right angles, both flexible, loaded at the tip: member 2's cantilever
    compliance plus member 1's carried to the tip by the rigid offset (u_tip = u_B + theta_B x
    (tip - B), the tip's load a wrench at B)."""
    l1, l2 = 0.4, 0.3
    m = _chain([np.array([l1, 0, 0]), np.array([0, l2, 0]), np.zeros(3)],
               [pin.JointModelRZ, pin.JointModelRX, pin.JointModelRY])
    b1, b2 = Beam.circle(0.02, **ALU), Beam.tube(0.03, 0.002, **ALU)
    mech = Mechanism(m, (), ["j0"]).with_beams({"link0": b1, "link1": b2})
    c = mech.compliance(np.zeros(3), {}, ["tip"], locked=["j0", "j1", "j2"])
    d = m.createData()
    pin.framesForwardKinematics(m, d, np.zeros(3))
    r = d.oMi[1].rotation
    x1 = r[:, 0]
    x2 = r[:, 1]  # member 2 along link1's y
    c1_world = _rot(r, x1) @ _cantilever(b1, l1) @ _rot(r, x1).T
    c2_world = _rot(r, x2) @ _cantilever(b2, l2) @ _rot(r, x2).T
    offset = d.oMf[m.getFrameId("tip")].translation - d.oMi[2].translation
    move = np.eye(6)
    move[:3, 3:] = -pin.skew(offset)  # u_tip = u_B - offset x theta_B
    want = move @ c1_world @ move.T + c2_world
    np.testing.assert_allclose(c, want, rtol=0, atol=1e-12 * np.abs(want).max())


def _rot(frame: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(6, 6) block rotation from a beam's section axes (x; y the frame's axis most normal to x,
    projected; z) to the world."""
    pick = int(np.argmin(np.abs(frame.T @ x)))
    y = frame[:, pick] - (frame[:, pick] @ x) * x
    y /= np.linalg.norm(y)
    r = np.column_stack([x, y, np.cross(x, y)])
    return np.kron(np.eye(2), r)


# ----------------------------------------------------------------------------- the frame model
def _element(beam: Beam, length: float) -> np.ndarray:
    """The 12 x 12 Euler-Bernoulli frame element in local axes, dofs [u1 th1 u2 th2]."""
    e, g, k = beam.E, beam.G, np.zeros((12, 12))
    ea, gj = e * beam.A / length, g * beam.J / length
    k[np.ix_([0, 6], [0, 6])] = ea * np.array([[1, -1], [-1, 1]])
    k[np.ix_([3, 9], [3, 9])] = gj * np.array([[1, -1], [-1, 1]])
    for w, th, second, sign in ((1, 5, beam.Iz, 1.0), (2, 4, beam.Iy, -1.0)):
        ei, ll = e * second, length
        idx = [w, th, w + 6, th + 6]
        kb = ei / ll**3 * np.array([[12, 6 * ll, -12, 6 * ll], [6 * ll, 4 * ll**2, -6 * ll, 2 * ll**2],
                                     [-12, -6 * ll, 12, -6 * ll], [6 * ll, 2 * ll**2, -6 * ll, 4 * ll**2]])
        s = np.diag([1.0, sign, 1.0, sign])  # theta_y = -dw/dx
        k[np.ix_(idx, idx)] = s @ kb @ s
    return k


def _frame_model(mech: Mechanism, q: np.ndarray, beams: dict, springs: dict, outputs: list[str],
                 locked: list[str]) -> np.ndarray:
    model = mech.model
    d = model.createData()
    pin.framesForwardKinematics(model, d, q)
    pin.computeJointJacobians(model, d, q)
    far: dict[int, tuple[np.ndarray, str, object]] = {}  # joint -> (far point, kind, which)
    for link, beam in beams.items():
        ins = insertion(model, d, mech.constraint_models, link, beam)
        j = model.getJointId(ins.parent)
        if ins.children:
            far[j] = ((d.oMi[j] * model.jointPlacements[model.getJointId(ins.children[0])]).translation, "joint",
                      model.getJointId(ins.children[0]))
        else:
            i, side = ins.closures[0]
            cm = mech.constraint_models[i]
            far[j] = ((d.oMi[j] * (cm.joint1_placement if side == 1 else cm.joint2_placement)).translation,
                      "closure", (i, side))
    nodes = {(j, "near"): k for k, j in enumerate(range(model.njoints))}
    for j in far:
        nodes[(j, "far")] = len(nodes)
    n_phi = model.nv
    size = 6 * len(nodes) + n_phi
    big_k = np.zeros((size, size))
    for link, beam in beams.items():
        j = model.frames[model.getFrameId(link, pin.FrameType.BODY)].parentJoint
        p0, p1 = d.oMi[j].translation, far[j][0]
        x = (p1 - p0) / np.linalg.norm(p1 - p0)
        t = _rot(d.oMi[j].rotation, x)
        ke = np.kron(np.eye(2), t) @ _element(beam, float(np.linalg.norm(p1 - p0))) @ np.kron(np.eye(2), t).T
        idx = [*range(6 * nodes[(j, "near")], 6 * nodes[(j, "near")] + 6),
               *range(6 * nodes[(j, "far")], 6 * nodes[(j, "far")] + 6)]
        big_k[np.ix_(idx, idx)] += ke
    for name, value in springs.items():
        jm = model.joints[model.getJointId(name)]
        for v in range(jm.idx_v, jm.idx_v + jm.nv):
            big_k[6 * len(nodes) + v, 6 * len(nodes) + v] += value

    def at(j: int, point: np.ndarray, which: str = "near") -> np.ndarray:
        """(6, size): [u; theta] of the point rigidly attached to node (j, which)."""
        n = nodes[(j, which)]
        g = np.zeros((6, size))
        origin = d.oMi[j].translation if which == "near" else far[j][0]
        g[:3, 6 * n:6 * n + 3] = np.eye(3)
        g[:3, 6 * n + 3:6 * n + 6] = -pin.skew(point - origin)
        g[3:, 6 * n + 3:6 * n + 6] = np.eye(3)
        return g

    def node_of_child(j: int) -> tuple[int, str]:
        parent = model.parents[j]
        return (parent, "far") if parent in far and far[parent][1] == "joint" and far[parent][2] == j else \
            (parent, "near")

    rows = [np.eye(6, size, 6 * nodes[(0, "near")])]  # the ground
    for j in range(1, model.njoints):
        o = d.oMi[j].translation
        pj, which = node_of_child(j)
        s = pin.getJointJacobian(model, d, j, pin.LOCAL_WORLD_ALIGNED)
        jm = model.joints[j]
        rel = at(j, o) - at(pj, o, which)
        rel[:, 6 * len(nodes) + jm.idx_v:6 * len(nodes) + jm.idx_v + jm.nv] -= s[:, jm.idx_v:jm.idx_v + jm.nv]
        rows.append(rel)
        if model.names[j] in locked:
            rows.append(np.eye(jm.nv, size, 6 * len(nodes) + jm.idx_v))
    for i, cm in enumerate(mech.constraint_models):
        sides = []
        for side, (jid, place) in enumerate(((cm.joint1_id, cm.joint1_placement), (cm.joint2_id, cm.joint2_placement)),
                                            start=1):
            which = "far" if jid in far and far[jid][1] == "closure" and far[jid][2] == (i, side) else "near"
            sides.append(at(jid, (d.oMi[jid] * place).translation, which))
        rel = sides[0] - sides[1]
        rows.append(rel[:3] if cm.type == pin.ContactType.CONTACT_3D else rel)
    a = np.vstack(rows)
    u, sv, vt = np.linalg.svd(a, full_matrices=False)
    a = vt[sv > 1e-12 * sv[0]]
    g = []
    for name in outputs:
        f = model.frames[model.getFrameId(name)]
        p = d.oMf[model.getFrameId(name)].translation
        which = "far" if f.parentJoint in far and np.linalg.norm(far[f.parentJoint][0] - p) < 1e-12 \
            and name not in beams else "near"
        g.append(at(f.parentJoint, p, which))
    g = np.vstack(g)
    n_c = a.shape[0]
    sol = np.linalg.solve(np.block([[big_k, a.T], [a, np.zeros((n_c, n_c))]]),
                          np.vstack([g.T, np.zeros((n_c, g.shape[0]))]))
    return g @ sol[:size]


def _beamable(mech: Mechanism, beam: Beam) -> dict[str, Beam]:
    """Every link with exactly one far end."""
    d = mech.model.createData()
    pin.framesForwardKinematics(mech.model, d, mech.reference)
    out, seen = {}, set()
    for f in mech.model.frames:
        if f.type != pin.FrameType.BODY or f.parentJoint == 0 or f.parentJoint in seen:
            continue
        try:
            insertion(mech.model, d, mech.constraint_models, f.name, beam)
        except ParameterError:
            continue
        out[f.name] = beam
        seen.add(f.parentJoint)
    return out


@pytest.mark.parametrize("robot", ["5bar_linkage_iso3d", "robot_delta", "cassie_like"])
def test_corpus_robots_with_beams_match_a_frame_model(robot):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        mech = Mechanism.from_urdf(ROBOTS / robot / "robot.urdf")
        q = mech.assemble()
    beams = _beamable(mech, Beam.tube(0.02, 0.002, **ALU))
    assert len(beams) >= 3
    flex = mech.with_beams(beams)
    # motors 500 N.m/rad; a soft spring on every passive joint too (the rods' free spins in 3-D contacts)
    springs = {mech.model.names[j]: 500.0 if mech.model.names[j] in mech.actuated else 5.0
               for j in range(1, mech.model.njoints)}
    out = [mech.model.frames[-1].name]
    got = flex.compliance(q, springs, out)
    rigid = mech.compliance(q, springs, out)
    want = _frame_model(mech, q, beams, springs, out, [])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.abs(want).max())
    assert np.abs(got - rigid).max() > 1e-6 * np.abs(rigid).max()  # the links do add compliance


def test_bad_beams_are_typed_errors():
    mech = Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")
    for bad in (lambda: Beam(0, 1, 1, 1, 1, 1), lambda: Beam.circle(-1, 1, 1), lambda: Beam.tube(0.01, 0.006, 1, 1),
                lambda: Beam(1, 1, 1, 1, 1, float("nan")), lambda: Beam("a", 1, 1, 1, 1, 1),
                lambda: mech.with_beams({"nope": Beam.circle(0.01, **ALU)}), lambda: mech.with_beams([]),
                lambda: mech.with_beams({next(iter(_beamable(mech, Beam.circle(0.01, **ALU)))): 5})):
        with pytest.raises(H4Error):
            bad()
    assert mech.with_beams({}) is mech  # no flexible link: the mechanism unchanged


def test_the_h4_with_beams_on_its_forearms_and_bars_is_eq30():
    """The H4 read as a Mechanism (its URDF and sidecar), its motors springs kc, a beam on each
    forearm (P_i to the tip A_i, the cross-bar and the two bars' joints carried: EI in its plane,
    an out-of-plane EI, GJ = G I0, axially rigid) and on each bar (axial Eb Sb, otherwise rigid):
    the compliance at D is h4pin.compliance's consistent model with the forearm_out_EI element,
    every term (control, bending, torsion, tension, out of plane) together, to round-off
    (measured 6e-15; each term alone 1e-15 to 1e-12)."""
    import h4pin
    from h4pin.kinematics.closed_form import centre_pose

    inf = float("inf")
    h4 = h4pin.load("prototype")
    sp = h4.geometry.springs
    out_ei = 4 * sp["E"][0] * sp["I"][0]
    ref = h4pin.load("prototype", elements={"forearm_out_EI": out_ei})
    pose = centre_pose(h4) + np.array([0.03, -0.02, 0.01, 0.1])
    mech = Mechanism.from_urdf(Path(h4pin.robot.urdf_dir()) / "h4_prototype.urdf")
    q = pin.neutral(mech.model)
    qh = h4.configuration(pose)
    for j in range(1, h4.model.njoints):
        jm, jh = mech.model.joints[mech.model.getJointId(h4.model.names[j])], h4.model.joints[j]
        q[jm.idx_q:jm.idx_q + jm.nq] = qh[jh.idx_q:jh.idx_q + jh.nq]
    d = mech.model.createData()
    pin.computeJointJacobians(mech.model, d, q)
    beams = {}
    for i in range(1, 5):
        ja = mech.model.getJointId(f"actuator_{i}")
        u = pin.getJointJacobian(mech.model, d, ja, pin.LOCAL_WORLD_ALIGNED)[3:, mech.model.joints[ja].idx_v]
        e, g, ei, i0 = sp["E"][i - 1], sp["G"][i - 1], sp["I"][i - 1], sp["I0"][i - 1]
        beam = Beam(e, g, inf, ei, out_ei / e, i0, to=f"A_{i}",
                    carry=(f"bar_{i}1_u1", f"bar_{i}2_u1", f"A_{i}1", f"A_{i}2"))
        # the section's y is the link frame's axis most normal to the span: here the actuator axis u_i
        ins = insertion(mech.model, d, mech.constraint_models, f"forearm_{i}", beam)
        bend_y = next(j for j in ins.joints if j.name.endswith("bend_y1"))
        assert abs(abs(np.dot(bend_y.axis, u)) - 1) < 1e-12  # bending about y = about u_i: in its plane
        beams[f"forearm_{i}"] = beam
        for k in (1, 2):
            beams[f"bar_{i}{k}"] = Beam(sp["Eb"][0], 1.0, sp["Sb"][2 * (i - 1) + k - 1], inf, inf, inf)
    flex = mech.with_beams(beams)
    got = flex.compliance(q, dict(zip(mech.actuated, sp["kc"], strict=True)), ["D"])
    want = h4pin.compliance(ref, pose, "consistent").matrix
    scale = np.abs(want[:3, :3]).max()
    np.testing.assert_allclose(got[:3, :3], want[:3, :3], rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(got[5, :3], want[5, :3], rtol=0, atol=1e-10 * scale)
    print(f"H4 with beams vs eq. 30: {np.abs(got[:3, :3] - want[:3, :3]).max() / scale:.1e}")


def test_the_sidecar_carries_beams(tmp_path):
    """``beams:`` in the sidecar (a round section by d, or the six values) gives what
    with_beams gives; a bad entry is a MalformedURDFError naming the link and the key."""
    import yaml

    from h4pin.errors import MalformedURDFError

    src = ROBOTS / "5bar_linkage_iso3d"
    content = yaml.safe_load((src / "robot.yaml").read_text())
    mech = Mechanism.from_urdf(src / "robot.urdf")
    links = list(_beamable(mech, Beam.circle(0.01, **ALU)))[:2]
    content["beams"] = {links[0]: {"E": 70e9, "G": 26e9, "d": 0.01},
                        links[1]: {"E": 70e9, "G": 26e9, "A": 1e-4, "Iy": 1e-9, "Iz": 2e-9, "J": 3e-9}}
    side = tmp_path / "robot.yaml"
    side.write_text(yaml.safe_dump(content))
    flex = Mechanism.from_urdf(src / "robot.urdf", side)
    by_hand = mech.with_beams({links[0]: Beam.circle(0.01, **ALU), links[1]: Beam(70e9, 26e9, 1e-4, 1e-9, 2e-9, 3e-9)})
    q = mech.assemble()
    springs = {m: 300.0 for m in mech.actuated}
    out = [mech.model.frames[-1].name]
    np.testing.assert_array_equal(flex.compliance(q, springs, out), by_hand.compliance(q, springs, out))
    for bad, match in (({links[0]: {"E": 70e9, "G": 26e9}}, "missing A"), ({links[0]: {"E": 1, "G": 1, "d": -1}}, "d"),
                       ({links[0]: {"E": 1, "G": 1, "d": 1, "wat": 2}}, "unknown key 'wat'"), ({"nope": {"E": 1, "G": 1,
                       "d": 1}}, "no link 'nope'"), ([1, 2], "beams must be a mapping")):
        content["beams"] = bad
        side.write_text(yaml.safe_dump(content))
        with pytest.raises(MalformedURDFError, match=match):
            Mechanism.from_urdf(src / "robot.urdf", side)
