# SPDX-License-Identifier: Apache-2.0
"""Natural frequencies and mode shapes of the elastic H4 (:func:`h4pin.elastic.modes`).

* Closed form: with massless links and a rigid payload on the central bar, the modes are those of
  the payload's 6x6 spatial inertia at D (written here by hand, world axes) on the plate's
  stiffness ``inv(C[:6, :6])`` from ``h4pin.compliance(model="consistent")`` (the paper's matrices,
  not the elastic model): the lateral-bar torques are zero, so the lateral bars follow statically.
  With the illustrative elements, 50 of the 56 admissible directions are massless and condensed.
  A point mass alone: three modes on Table II's translational block.
* Rotation of the whole layout about z (a robot generated from rotated H4Params: other joint
  types and link frames, inertias recomputed by the URDF writer): same frequencies, rotated shapes.
* Rayleigh: a payload lowers every frequency; every spring times s scales them by sqrt(s).
* The forearm's inertia rides on its actuator's spring, with its mass and centre of mass kept.
* Errors, and the usage example of ``docs/modes.md``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import sample_poses

import h4pin
from h4pin.description.elements import ILLUSTRATIVE
from h4pin.elastic import elastic_model, modes
from h4pin.elastic.modal import mass_model
from h4pin.kinematics.closed_form import centre_pose, rot_z
from h4pin.mechanism import Modes, Payload

TOL = 1e-8
BODY = Payload(0.5, com=[0.01, -0.02, -0.06], inertia=[[2e-3, 1e-4, 0.0], [1e-4, 1.5e-3, -2e-4], [0.0, -2e-4, 1e-3]])


def skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def spatial_world(p: Payload, theta: float) -> np.ndarray:
    """The payload's 6x6 inertia for the twist [v_D; omega] (world axes), from its kinetic energy
    1/2 m |v_D + omega x c|^2 + 1/2 omega^T Ic omega, c and Ic turned by theta about z."""
    r = rot_z(theta)
    c, ic = r @ p.com, r @ p.inertia @ r.T
    sc = skew(c)
    return np.block([[p.mass * np.eye(3), -p.mass * sc], [p.mass * sc, ic - p.mass * sc @ sc]])


def same_up_to_sign(a: np.ndarray, b: np.ndarray) -> float:
    """Largest relative difference of the rows of a and b, each row's sign free."""
    return max(min(np.linalg.norm(x - y), np.linalg.norm(x + y)) / np.linalg.norm(y) for x, y in zip(a, b, strict=True))


@pytest.fixture(scope="module")
def em(proto):
    return elastic_model(proto)


@pytest.mark.parametrize("elements", [None, ILLUSTRATIVE], ids=["own", "illustrative"])
def test_payload_on_massless_links_is_the_closed_form(proto, elements):
    h4 = proto if elements is None else proto.with_elements(elements)
    model = elastic_model(h4)
    poses = np.vstack([centre_pose(h4), sample_poses(h4, 2, seed=3)])
    assert np.abs(poses[1:, 3]).min() > 0.05  # theta != 0: the payload's axes turn with the bar
    for x in poses:
        res = modes(model, x, BODY, link_inertias=False)
        c = h4pin.compliance(h4, x, model="consistent").matrix
        k6, m6 = np.linalg.inv(c[:6, :6]), spatial_world(BODY, x[3])
        lam, phi = np.linalg.eig(np.linalg.solve(m6, k6))
        order = np.argsort(lam.real)
        lam, phi = lam.real[order], phi.real[:, order]
        phi /= np.sqrt(np.einsum("im,ij,jm->m", phi, m6, phi))  # mass-normalised
        assert res.frequencies.shape == (6,)
        assert res.condensed == model.model.nv - 28 - 6  # 16 or 56 springs; 6 massive directions
        np.testing.assert_allclose(res.frequencies, np.sqrt(lam) / (2 * np.pi), rtol=TOL, atol=0)
        assert same_up_to_sign(res.shapes_tp[:, :6], phi.T) <= 1e-6
        # the lateral bars follow in static equilibrium (zero torque on their revolutes)
        follow = c[6:, :6] @ np.linalg.solve(c[:6, :6], res.shapes_tp[:, :6].T)
        np.testing.assert_allclose(res.shapes_tp[:, 6:], follow.T, atol=1e-6 * np.abs(res.shapes_tp).max())


def test_a_point_mass_on_massless_links_sees_the_translational_compliance(proto):
    """Three modes: eig(inv(C[:3, :3])) / m, C[:3, :3] being Table II's block (torque-free plate)."""
    mass = 0.5
    model = elastic_model(proto)
    for x in np.vstack([centre_pose(proto), sample_poses(proto, 2, seed=8)]):
        res = modes(model, x, Payload(mass), link_inertias=False)
        ctt = h4pin.compliance(proto, x, model="consistent").translational
        lam, vec = np.linalg.eigh(np.linalg.inv(ctt) / mass)
        assert res.condensed == 16 - 3
        np.testing.assert_allclose(res.frequencies, np.sqrt(lam) / (2 * np.pi), rtol=TOL, atol=0)
        assert same_up_to_sign(res.shapes_tp[:, :3], vec.T / np.sqrt(mass)) <= 1e-6


def test_frequencies_do_not_depend_on_the_layouts_orientation(proto):
    """The whole robot turned by 0.4 rad about z (P, U, DB, DC rotated; a URDF generated from it,
    with unaligned joints where the prototype has RX and RY, and inertias recomputed): at the
    turned pose and with the turned payload, the same frequencies, and shapes turned with it."""
    alpha = 0.4
    r = rot_z(alpha)
    p = proto.params
    turned = h4pin.load(p.replace(P=r @ p.P, U=r @ p.U, DB=r @ p.DB, DC=r @ p.DC))
    body = Payload(BODY.mass, r @ BODY.com, r @ BODY.inertia @ r.T)
    for x in sample_poses(proto, 2, seed=5):
        xt = np.r_[r @ x[:3], x[3]]
        a, b = modes(proto, x, BODY), modes(turned, xt, body)
        assert len(a.frequencies) == 16
        np.testing.assert_allclose(b.frequencies, a.frequencies, rtol=1e-9, atol=0)
        rot = np.zeros((8, 8))
        rot[:3, :3] = rot[3:6, 3:6] = r
        rot[6:, 6:] = np.eye(2)
        assert same_up_to_sign(b.shapes_tp, a.shapes_tp @ rot.T) <= 1e-6


def test_a_payload_lowers_every_frequency(em, proto):
    for x in sample_poses(proto, 2, seed=7):
        bare, loaded = modes(em, x), modes(em, x, BODY)
        assert len(bare.frequencies) == len(loaded.frequencies) == 16
        assert np.all(loaded.frequencies <= bare.frequencies * (1 + 1e-12))
        assert loaded.frequencies[0] < 0.9 * bare.frequencies[0]
        point = modes(em, x, Payload(BODY.mass, BODY.com))  # the body is this point plus an inertia
        assert np.all(loaded.frequencies <= point.frequencies * (1 + 1e-12))
        assert np.all(point.frequencies <= bare.frequencies * (1 + 1e-12))


def test_frequencies_scale_as_the_square_root_of_the_stiffness(proto, centre):
    s = 3.7
    springs = proto.geometry.springs
    stiffer = h4pin.load("prototype", springs={name: s * springs[name] for name in ("kc", "E", "G", "Eb")})
    base, scaled = modes(proto, centre, BODY), modes(stiffer, centre, BODY)
    np.testing.assert_allclose(scaled.frequencies, np.sqrt(s) * base.frequencies, rtol=1e-10, atol=0)
    np.testing.assert_allclose(scaled.shapes_tp, base.shapes_tp, atol=1e-8 * np.abs(base.shapes_tp).max())


def test_shapes_are_mass_normalised_modes(em, proto):
    """K* and M* are built inside; here K and M of the full coordinates: K dq = w^2 M dq on the
    admissible motions, dq^T M dq = 1, distinct modes M-orthogonal; the shapes are admissible."""
    x = sample_poses(proto, 1, seed=11)[0]
    res = modes(em, x, BODY)
    mm = mass_model(em)
    d = mm.createData()
    q = em.configuration(x)
    m = pin.crba(mm, d, q)
    m = np.triu(m) + np.triu(m, 1).T
    jd = pin.computeFrameJacobian(mm, mm.createData(), q, mm.getFrameId("D"), pin.LOCAL)
    m += jd.T @ BODY.spatial() @ jd
    phi = res.shapes_q.T
    np.testing.assert_allclose(phi.T @ m @ phi, np.eye(16), atol=1e-9)
    k = np.zeros(mm.nv)
    for name, value in em.stiffness.items():
        k[mm.joints[mm.getJointId(name)].idx_v] = value
    w2 = (2 * np.pi * res.frequencies) ** 2
    np.testing.assert_allclose(phi.T @ (k[:, None] * phi), np.diag(w2), atol=1e-9 * w2.max())
    cds = [cm.createData() for cm in em.constraint_models]
    pin.computeJointJacobians(mm, d, q)
    for cm, cd in zip(em.constraint_models, cds, strict=True):
        cm.calc(mm, d, cd)
    jc = pin.getConstraintsJacobian(mm, d, em.constraint_models, cds)
    assert np.abs(jc @ phi).max() <= 1e-9 * np.abs(phi).max()
    for name in em.locked:
        assert np.all(phi[mm.joints[mm.getJointId(name)].idx_v] == 0.0) or np.abs(
            phi[mm.joints[mm.getJointId(name)].idx_v]).max() <= 1e-12 * np.abs(phi).max()


def test_the_forearm_rides_on_its_actuator_spring(em, proto, centre):
    """Mass and centre of mass of the mass model equal the URDF's; the locked actuators carry none."""
    mm = mass_model(em)
    q = em.configuration(centre)
    com = pin.centerOfMass(mm, mm.createData(), q)
    com0 = pin.centerOfMass(proto.model, proto.model.createData(), proto.configuration(centre))
    np.testing.assert_allclose(com, com0, atol=1e-14)
    total = sum(i.mass for i in proto.model.inertias[1:])  # [0] is the fixed base
    assert sum(i.mass for i in mm.inertias[1:]) == pytest.approx(total, rel=1e-14)
    for name in em.locked:
        assert mm.inertias[mm.getJointId(name)].mass == 0.0
        assert mm.inertias[mm.getJointId(f"{name}_elastic")].mass == proto.model.inertias[
            proto.model.getJointId(name)].mass
    assert all(i.mass == 0 for i in mass_model(em, False).inertias)
    assert em.model.inertias[em.model.getJointId(em.locked[0])].mass > 0  # the elastic model is untouched


def test_one_answer_per_thread(em, proto):
    """Each thread works in its own pin.Data: four at once give the serial modes bit for bit."""
    from concurrent.futures import ThreadPoolExecutor

    xs = sample_poses(proto, 4, seed=13)
    serial = [modes(em, x, BODY).shapes_q for x in xs]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda x: modes(em, x, BODY).shapes_q, xs))
    for a, b in zip(serial, threaded, strict=True):
        np.testing.assert_array_equal(a, b)


def test_errors(em, centre, sym):
    with pytest.raises(h4pin.ParameterError, match="nothing has mass"):
        modes(em, centre, link_inertias=False)
    with pytest.raises(h4pin.ParameterError, match="payload must be"):
        modes(em, centre, payload=0.5)
    for bad in (dict(mass=-1), dict(mass=float("nan")), dict(mass=1, com=[0, 0]),
                dict(mass=1, inertia=np.diag([1.0, 1.0, 3.0])),
                dict(mass=1, inertia=[[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]),
                dict(mass=1, inertia=-np.eye(3))):
        with pytest.raises(h4pin.ParameterError):
            Payload(**bad)
    with pytest.raises(h4pin.PoseError):
        modes(em, [0.0, 0.0, np.nan, 0.0])
    with pytest.raises(h4pin.UnreachablePoseError):
        modes(em, centre + [0, 0, -5.0, 0])
    with pytest.raises(h4pin.SingularPoseError):
        modes(sym, centre_pose(sym))


def test_the_usage_example_of_the_doc_runs():
    text = (Path(__file__).resolve().parents[1] / "docs" / "modes.md").read_text(encoding="utf-8")
    code = "\n".join(re.findall(r"```python\n(.*?)```", text, re.S))  # the blocks in order, one session
    namespace: dict = {}
    exec(compile(code, "docs/modes.md", "exec"), namespace)
    assert isinstance(namespace["res"], Modes)
    assert isinstance(namespace["batch"], h4pin.Modes) and namespace["batch"].first.shape == (2,)


def test_a_new_payload_is_never_served_a_freed_ones_mass_model():
    """The compiled twin caches the mass model per robot and payload: by value, so that a payload
    made after another was freed (which may take its id) gets its own, as the Pinocchio route."""
    import h4pin
    from h4pin.kinematics import closed_form as cf

    h4 = h4pin.load()
    x = cf.centre_pose(h4)
    got = [h4pin.modes(h4, x, h4pin.Payload(m), method="compiled").frequencies[0] for m in (0.0, 0.5, 1.0)]
    want = [h4pin.modes(h4, x, h4pin.Payload(m), method="pinocchio").frequencies[0] for m in (0.0, 0.5, 1.0)]
    np.testing.assert_allclose(got, want, rtol=1e-8)
    assert got[0] > got[1] > got[2]
