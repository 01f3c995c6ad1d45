# SPDX-License-Identifier: Apache-2.0
"""Optional elements beyond eq. 30 (h4pin.stiffness.elements): unit loads on the statics route against
finite differences of the deformed robot, and exact reduction to eq. 30 when off."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from h4pin import ParameterError
from h4pin.checks import deformed, statics
from h4pin.checks.elements import element_terms_fd
from h4pin.description.elements import ELEMENTS, ILLUSTRATIVE, Elements
from h4pin.kinematics.closed_form import skew
from h4pin.stiffness import elements as el
from h4pin.stiffness.api import TERMS, compliance


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("n_pose", [2, 7])
def test_element_terms_equal_finite_differences(proto, poses, n_pose):
    """Each element: c sum g g^T (joint reactions, bar tensions from the plate equilibrium) vs
    c sum G G^T (plate motion of the deformed robot per joint displacement, tilt, bar length)."""
    x = poses[n_pose]
    ours = el.element_terms(proto.geometry, x, ILLUSTRATIVE)
    fd = element_terms_fd(proto.geometry, x, ILLUSTRATIVE)
    assert set(ours) == set(ELEMENTS) == set(fd)
    for name in ELEMENTS:
        assert rel(ours[name], fd[name]) < 1e-6, name


def test_plate_loads_agree_with_the_statics_route(proto, poses):
    """Bar tensions from this equilibrium (moments about D) = statics.bar_forces (about O);
    ball joints carry the bar tension, so their term is the tension term scaled."""
    x = poses[4]
    g = proto.geometry
    assert rel(el.plate_loads(g, x)["bars"], statics.bar_forces(g, x)) < 1e-12
    ball = el.element_terms(g, x, Elements(ball_radial=3e-8))["ball_radial"]
    tension = statics.compliance_terms(g, x)["tension"]
    c_tension = g.compliances()["tension"]
    assert np.ptp(c_tension) == 0.0  # the prototype's bars are equal: the terms are proportional
    assert rel(ball, tension * 2 * 3e-8 / c_tension[0]) < 1e-12


def test_joint_reactions_balance_the_lateral_bars(proto, poses):
    """Sum of forces on lateral bar k: joint force + bar pulls = 0 (world frame); the joint couple
    is normal to the joint axis."""
    from h4pin.kinematics.closed_form import points

    x = poses[6]
    loads = el.plate_loads(proto.geometry, x)
    pts = points(proto.geometry, proto.state(x))
    w = (pts.Bij - pts.Aij).reshape(8, 3)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    for k in range(2):
        bars = np.flatnonzero(proto.geometry.lat == k)
        pulls = -(w[bars].T @ loads["bars"][bars])  # (3, 8) world
        np.testing.assert_allclose(loads["force"][k] + pulls, 0.0, atol=1e-12)
        np.testing.assert_allclose(pts.v[k] @ loads["moment"][k], 0.0, atol=1e-12)


def test_off_is_exactly_eq_30(proto, poses):
    for model in ("paper", "consistent"):
        base = compliance(proto, poses[0], model)
        off = compliance(proto, poses[0], model, elements=Elements())
        np.testing.assert_array_equal(off.matrix, base.matrix)
        assert off.elements is None
        assert tuple(off.terms) == TERMS


def test_on_stays_symmetric_and_equals_the_deformed_route(proto, poses):
    """Consistent K + elements = sum over all springs of the deformed robot (finite differences)."""
    x = poses[3]
    res = compliance(proto, x, 'consistent', elements=ILLUSTRATIVE)
    assert rel(res.matrix, res.matrix.T) < 1e-13 and np.linalg.eigvalsh(res.matrix).min() > 0
    fd = sum(deformed.compliance_terms(proto.geometry, x).values()) + sum(
        element_terms_fd(proto.geometry, x, ILLUSTRATIVE).values())
    assert rel(res.matrix, fd) < 1e-6
    assert rel(sum(res.terms.values()), res.matrix) < 1e-14
    assert set(res.terms) == set(TERMS) | set(ELEMENTS)


@pytest.mark.parametrize("bad", [-1e-8, np.nan, "stiff"])
def test_bad_element_values(bad):
    with pytest.raises(ParameterError, match="revolute_tilt"):
        Elements(revolute_tilt=bad)
    assert dataclasses.replace(Elements(), ball_radial=1e-8).off is False


def test_element_terms_sum_to_the_table(proto, centre):
    res = compliance(proto, centre, "consistent", elements=ILLUSTRATIVE)
    entries = {t: m[[0, 1, 2, 0], [0, 1, 2, 2]] for t, m in res.terms.items()}
    np.testing.assert_allclose(sum(entries.values()), res.translational[[0, 1, 2, 0], [0, 1, 2, 2]], rtol=1e-14)
    assert entries["revolute_tilt"][0] > 0 and abs(entries["revolute_tilt"][2]) < 1e-12 * entries["revolute_tilt"][0]


PER_ELEMENT = Elements(revolute_radial=[1e-8, 3e-8], revolute_axial=[2e-8, 0.5e-8], revolute_tilt=[5e-5, 2e-5],
                          ball_radial=np.linspace(1e-8, 4.5e-8, 8), central_EI=[225.0, 400.0], central_GJ=[167.0, 90.0],
                          lateral_EI=[200.0, 250.0, 300.0, 350.0], lateral_GJ=[150.0, np.inf, 120.0, 180.0],
                          shaft_tilt=[1e-5, 2e-5, 3e-5, 4e-5], base_translation=[1e-8, 2e-8, 0.0, 3e-8],
                          base_rotation=[1e-5, 3e-5, 2e-5, 4e-5], forearm_out_EI=[1120.0, 900.0, np.inf, 1500.0])


def test_per_element_values_on_a_toleranced_robot_with_tilted_joint_axes():
    """Each joint and bar its own compliance, on a robot whose parallelograms are not exact and
    whose lateral axes are tilted (Newton-solved plate): unit loads vs finite differences."""
    from h4pin import load

    g = load("toleranced").geometry
    v = g.v + np.array([[0.02, -0.01, 0.0], [-0.015, 0.0, 0.0]])
    g = g.replace(v=v / np.linalg.norm(v, axis=1, keepdims=True))
    assert not g.ideal
    x = np.array([0.0, 0.0, -0.43, 0.2])
    ours = el.element_terms(g, x, PER_ELEMENT)
    fd = element_terms_fd(g, x, PER_ELEMENT)
    for name in ELEMENTS:
        assert rel(ours[name], fd[name]) < 1e-6, name
    # one element on, the others off: only its own term
    one = el.element_terms(g, x, Elements(revolute_tilt=[0.0, 2e-5]))
    assert set(one) == {"revolute_tilt"}
    assert rel(one["revolute_tilt"], element_terms_fd(g, x, Elements(revolute_tilt=[0.0, 2e-5]))
               ["revolute_tilt"]) < 1e-6


def test_elements_written_in_the_urdf_give_the_same_k_as_in_python(proto, poses):
    """<h4_revolute> in the lateral joints and <h4_ball> in the bar links, read at load, give
    the K of the same elements passed in Python; without them the robot's elements are off."""
    from h4pin import H4Params, load
    from h4pin.description.urdf import to_urdf

    assert proto.elements.off
    text = to_urdf(H4Params(), "h4_with_elements", elements=PER_ELEMENT)
    assert text.count("<h4_revolute ") == 2 and text.count("<h4_ball ") == 8
    assert text.count("<h4_plate_bar ") == 3 and text.count("<h4_base ") == 4 and text.count(" shaft_tilt=") == 4
    assert text.count(" out_EI=") == 3  # forearm 3 is rigid out of plane: not written
    assert 'GJ_2="' not in text.split('<link name="lateral_bar_1"')[1].split("</link>")[0]  # rigid: not written
    robot = load_text(text)
    assert robot.elements.allclose(PER_ELEMENT)
    x = poses[5]
    from_urdf = compliance(robot, x, 'consistent')
    from_python = compliance(proto, x, 'consistent', elements=PER_ELEMENT)
    np.testing.assert_array_equal(from_urdf.matrix, from_python.matrix)
    assert rel(from_urdf.matrix, compliance(proto, x, "consistent").matrix) > 1e-3  # the elements count
    # an element written by hand, one attribute only: the others stay off
    hand = to_urdf(H4Params()).replace('<limit lower="-0.7853981633974483"', '<h4_revolute tilt="3e-5"/>\n'
                                       '    <limit lower="-0.7853981633974483"', 1)
    one = load_text(hand).elements
    np.testing.assert_array_equal(one.revolute_tilt, [3e-5, 0.0])
    assert not np.any(one.revolute_radial) and not np.any(one.ball_radial)
    assert np.all(np.isinf(one.central_EI)) and not np.any(one.shaft_tilt) and one.on("revolute_tilt")
    assert load(H4Params()).elements.off


def load_text(text: str):
    from h4pin.robot import H4

    return H4(text, "test URDF")


@pytest.mark.parametrize(("old", "new", "where"), [
    ('<h4_ball radial="4.5e-08"/>', '<h4_ball radial="-4.5e-08"/>', "bar link 'bar_42' (<h4_ball radial>)"),
    (' tilt="2e-05"', ' tilt="nan"', "<h4_revolute tilt> of joint 'lateral_2'"),
    ('tilt="5e-05"', 'tilt="-5e-05"', "lateral joint 'lateral_1' (<h4_revolute tilt>)"),
    ('axial="2e-08"', 'axial="stiff"', "<h4_revolute axial> of joint 'lateral_1'"),
    ('EI_2="400.0"', 'EI_2="0"', "central bar link 'central_bar' (<h4_plate_bar EI_2>): central_EI"),
    ('EI_2="400.0"', 'EI_3="400.0"', "central bar link 'central_bar': <h4_plate_bar EI_3> names no beam"),
    ('GJ_3="120.0"', 'GJ_3="-120.0"', "lateral bar link 'lateral_bar_2' (<h4_plate_bar GJ_3>): lateral_GJ"),
    ('EI_4="350.0"', 'EI_1="350.0"', "lateral bar link 'lateral_bar_2': <h4_plate_bar EI_1> names no beam"),
    ('shaft_tilt="4e-05"', 'shaft_tilt="-4e-05"', "actuated joint 'actuator_4' (<h4_actuator shaft_tilt>)"),
    ('rotation="3e-05"', 'rotation="nan"', "<h4_base rotation> of joint 'actuator_2'"),
    ('translation="3e-08"', 'translation="-3e-08"', "actuated joint 'actuator_4' (<h4_base translation>)"),
    ('<h4_revolute radial="1e-08"', '<h4_base rotation="1e-5"/><h4_revolute radial="1e-08"',
     "<h4_base rotation> sits in 'lateral_1', which is not an actuated joint"),
    ('<h4_ball radial="4.5e-08"/>', '<h4_revolute tilt="1e-5"/>',
     "<h4_revolute> sits in link 'bar_42'; it belongs inside a <joint>"),
    ('<h4_plate_bar EI_1="225.0"', '<h4_ball radial="1e-8"/><h4_plate_bar EI_1="225.0"',
     "<h4_ball radial> sits in 'central_bar', which is not a bar link"),
    ('out_EI="1500.0"', 'out_EI="0"', "forearm link 'forearm_4' (<h4_forearm out_EI>): forearm_out_EI = 0.0"),
    ('<h4_ball radial="4.5e-08"/>', '<h4_forearm out_EI="900"/>',
     "<h4_forearm out_EI> sits in 'bar_42', which is not a forearm link"),
])
def test_non_physical_element_in_the_urdf_names_it(old, new, where):
    from h4pin import H4Params, MalformedURDFError
    from h4pin.description.urdf import to_urdf

    text = to_urdf(H4Params(), elements=PER_ELEMENT)
    assert old in text
    with pytest.raises(MalformedURDFError, match=re.escape(where)):
        load_text(text.replace(old, new))


def test_beam_compliance_is_the_cantilever():
    """Tip force normal to the beam: L^3/(3EI) along it, slope L^2/(2EI); tip couple: L/(EI)
    bending, L/(GJ) torsion; an axial force does nothing; symmetric, positive semi-definite."""
    e = np.array([0.6, 0.8, 0.0])
    n = np.array([0.0, 0.0, 1.0])
    length, ei, gj = 0.08, 225.0, 167.0
    bend, tors = el.beam_compliance(e, length, ei, gj)
    tip = bend @ np.r_[n, 0.0, 0.0, 0.0]
    np.testing.assert_allclose(tip[:3], length**3 / (3 * ei) * n, atol=1e-20)
    np.testing.assert_allclose(tip[3:], length**2 / (2 * ei) * np.cross(e, n), atol=1e-20)
    np.testing.assert_allclose((bend @ np.r_[0.0, 0.0, 0.0, n])[:3], length**2 / (2 * ei) * np.cross(n, e), atol=1e-20)
    np.testing.assert_allclose((bend @ np.r_[0.0, 0.0, 0.0, n])[3:], length / ei * n, atol=1e-20)
    np.testing.assert_allclose((tors @ np.r_[0.0, 0.0, 0.0, e])[3:], length / gj * e, atol=1e-20)
    np.testing.assert_allclose(bend @ np.r_[e, 0.0, 0.0, 0.0], 0.0, atol=1e-20)
    for c in (bend, tors):
        np.testing.assert_array_equal(c, c.T)
        assert np.linalg.eigvalsh(c).min() > -1e-18
    np.testing.assert_array_equal(el.beam_compliance(e, length, np.inf, np.inf)[0], 0.0)


def test_leg_wrenches_on_the_base_balance_the_external_load(proto, poses):
    """Sum over legs of the wrench on the base at P_i = the external wrench at D (the joint
    torques t_k are internal to the plate); each central segment's tip wrench and each lateral
    arm's tip wrench balance the rest of their body."""
    x = poses[6]
    g = proto.geometry
    loads = el.element_loads(g, x)
    pts = el.plate_loads(g, x)["points"]
    base = loads["base"]
    force = base[:, :3].sum(axis=0)
    moment = sum(base[i, 3:] + np.cross(pts.P[i], base[i, :3], axis=0) for i in range(4))
    want_m = np.zeros((3, 8))
    want_m[:, :3] = skew(pts.D)
    want_m[:, 3:6] = np.eye(3)
    np.testing.assert_allclose(force, np.eye(3, 8), atol=1e-12)
    np.testing.assert_allclose(moment, want_m, atol=1e-12)
    # the central bar: external load at D + the loads on both segments' tips = 0
    central = loads["central"]
    f_sum = np.eye(3, 8) + central[:, :3].sum(axis=0)
    m_sum = np.eye(3, 8, 3) + sum(central[k, 3:] + np.cross(pts.C[k] - pts.D, central[k, :3], axis=0)
                                  for k in range(2))
    np.testing.assert_allclose(f_sum, 0.0, atol=1e-12)
    np.testing.assert_allclose(m_sum, 0.0, atol=1e-12)
    # the shaft tilt carries the base couple's part normal to u_i: its term, spring by spring
    c = np.array([1e-5, 2e-5, 3e-5, 4e-5])
    springs = np.concatenate([el.normal_pair(g.u[i]).T @ base[i, 3:] for i in range(4)])  # (8, 8)
    hand = (springs.T * np.repeat(c, 2)) @ springs
    term = el.element_terms(g, x, Elements(shaft_tilt=c))["shaft_tilt"]
    np.testing.assert_allclose(term, hand, rtol=0, atol=1e-13 * np.max(np.abs(hand)))


@pytest.mark.parametrize("one", [Elements(central_EI=[np.inf, 300.0]), Elements(lateral_GJ=[80.0, np.inf, np.inf,
                                 np.inf]), Elements(shaft_tilt=[0.0, 0.0, 3e-5, 0.0]),
                                 Elements(base_translation=[0.0, 2e-8, 0.0, 0.0]), Elements(base_rotation=2e-5)])
def test_one_new_element_on_alone(proto, poses, one):
    """One element of one kind on: only its term, equal to finite differences; K stays symmetric
    positive definite and equals the deformed route's total."""
    x = poses[1]
    ours = el.element_terms(proto.geometry, x, one)
    fd = element_terms_fd(proto.geometry, x, one)
    assert len(ours) == 1 and set(ours) == set(fd)
    name = next(iter(ours))
    assert rel(ours[name], fd[name]) < 1e-6, name
    res = compliance(proto, x, 'consistent', elements=one)
    assert rel(res.matrix, res.matrix.T) < 1e-13 and np.linalg.eigvalsh(res.matrix).min() > 0
    total = sum(deformed.compliance_terms(proto.geometry, x).values()) + fd[name]
    assert rel(res.matrix, total) < 1e-6


@pytest.mark.parametrize(("field", "bad"), [("central_EI", 0.0), ("lateral_GJ", -5.0), ("central_GJ", np.nan),
                                            ("shaft_tilt", np.inf), ("base_rotation", -1e-5),
                                            ("base_translation", "soft")])
def test_bad_new_element_values(field, bad):
    with pytest.raises(ParameterError, match=field):
        Elements(**{field: bad})
    assert Elements(central_EI=np.inf, lateral_GJ=np.inf, shaft_tilt=0.0).off


def test_new_elements_off_are_bitwise_eq_30(proto, poses):
    """Rigid beams (inf) and zero compliances written explicitly: K is eq. 30's, bit for bit."""
    off = Elements(central_EI=np.inf, central_GJ=np.inf, lateral_EI=np.inf, lateral_GJ=np.inf, shaft_tilt=0.0,
                      base_translation=0.0, base_rotation=0.0)
    assert off.off
    for model in ("paper", "consistent"):
        base = compliance(proto, poses[2], model)
        np.testing.assert_array_equal(compliance(proto, poses[2], model, elements=off).matrix, base.matrix)


def test_forearm_out_of_plane_is_the_cantilever():
    """The forearm's out-of-plane compliance: a tip force along u gives L^3/(3EI) along u and a
    slope L^2/(2EI) about e x u; a couple about e x u, L^2/(2EI) and L/(EI); nothing in the
    forearm's own plane. With the in-plane part (normal e x u) it is the isotropic cantilever."""
    e = np.array([0.6, 0.8, 0.0])
    u = np.array([0.8, -0.6, 0.0])
    length, ei = 0.2, 1120.0
    c = el.out_of_plane_compliance(e, u + 0.3 * e, length, ei)  # the normal is made normal to e
    b = np.cross(e, u)
    np.testing.assert_allclose(c @ np.r_[u, 0, 0, 0], np.r_[length**3 / (3 * ei) * u, length**2 / (2 * ei) * b],
                               atol=1e-20)
    np.testing.assert_allclose(c @ np.r_[0, 0, 0, b], np.r_[length**2 / (2 * ei) * u, length / ei * b], atol=1e-20)
    for load in (np.r_[np.cross(u, e), 0, 0, 0], np.r_[e, 0, 0, 0], np.r_[0, 0, 0, u], np.r_[0, 0, 0, e]):
        np.testing.assert_allclose(c @ load, 0.0, atol=1e-20)
    in_plane = el.out_of_plane_compliance(e, np.cross(u, e), length, ei)
    np.testing.assert_allclose(c + in_plane, el.beam_compliance(e, length, ei, np.inf)[0], rtol=0, atol=1e-18)
    np.testing.assert_array_equal(el.out_of_plane_compliance(e, u, length, np.inf), 0.0)


def test_forearm_out_of_plane_on_every_route(proto, poses):
    """forearm_out_EI alone: the statics route equals finite differences of the deformed robot
    (tips moved along u_i and turned), the compiled pipeline (one pose and batch) and the elastic
    model (two Gauss-point revolutes per forearm); rigid (inf) is eq. 30 bit for bit; softer
    forearms only add compliance."""
    from h4pin import elastic_model

    one = Elements(forearm_out_EI=[1120.0, 800.0, 1500.0, 1000.0])
    xs = poses[:6]
    bare = compliance(proto, xs, "consistent").matrix
    batch = compliance(proto, xs, "consistent", elements=one).matrix
    elastic = elastic_model(proto.with_elements(one))
    for k, x in enumerate(xs):
        term = el.element_terms(proto.geometry, x, one)["forearm_out_EI"]
        assert rel(term, element_terms_fd(proto.geometry, x, one)["forearm_out_EI"]) < 1e-6
        single = compliance(proto, x, "consistent", elements=one).matrix
        assert rel(single - bare[k], term) < 1e-10 and rel(batch[k] - bare[k], term) < 1e-10
        assert rel(elastic.compliance_matrix(x), single) < 1e-10
        assert np.linalg.eigvalsh(term).min() > -1e-12 * np.abs(term).max()
    rigid = compliance(proto, xs, "consistent", elements=Elements(forearm_out_EI=np.inf)).matrix
    np.testing.assert_array_equal(rigid, bare)
