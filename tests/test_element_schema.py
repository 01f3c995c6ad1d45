# SPDX-License-Identifier: Apache-2.0
"""The element schema (h4pin.description.elements.KINDS): a kind is one row, a form one compiled
term. A kind the library does not define, added as one row, goes through every path; each form's
compiled term equals its numpy reading."""

from __future__ import annotations

import numpy as np
import pytest

import h4pin
from h4pin.checks import statics
from h4pin.description import elements as schema
from h4pin.description.elements import FORMS, Elements, Kind
from h4pin.description.params import H4Params
from h4pin.description.urdf import to_urdf
from h4pin.kinematics.closed_form import assembled_points
from h4pin.limits import ImplausibleValueError
from h4pin.robot import H4
from h4pin.stiffness import elements as statics_elements
from h4pin.stiffness import pipeline

#: A kind no row defines: the base mounts' vertical compliance alone (site mount, form force_axial,
#: axis z), written as ``<h4_base vertical=...>`` in the actuated joints.
VERTICAL = Kind("mount_vertical", 4, "m/N", "mount", "force_axial", "z", urdf=("h4_base", "vertical"),
                place="actuated_joint", elastic="mount_{s}_vertical", describe="vertical mount of actuator {s}")
C = np.array([1e-8, 2e-8, 0.5e-8, 3e-8])


@pytest.mark.parametrize("form", FORMS)
def test_each_form_is_one_compiled_term_equal_to_its_numpy_reading(form):
    """pipeline.form_part (the rank-one parts the compliance and the frequencies both read) sums
    to the numpy form of h4pin.stiffness.elements.form_compliance (beam_compliance,
    out_of_plane_compliance), on random axes, second axes and lengths."""
    rng = np.random.default_rng(FORMS.index(form))
    code = FORMS.index(form)
    for _ in range(5):
        e = rng.normal(size=3)
        e /= np.linalg.norm(e)
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        length, c = rng.uniform(0.05, 0.4), rng.uniform(0.5, 2.0)
        a, b = np.array(pipeline.form_frame(pipeline.form_plane(code), *e, *n)).reshape(2, 3)
        got = np.zeros((6, 6))
        for t in range(pipeline.form_count(code)):
            ct, fe, fa, fb, fw, me, ma, mb, mw = pipeline.form_part(code, t, c, length)
            world = np.eye(3)[t] if t < 3 else np.zeros(3)
            u = np.r_[fe * e + fa * a + fb * b + fw * world, me * e + ma * a + mb * b + mw * world]
            got += ct * np.outer(u, u)
        want = c * statics_elements.form_compliance(form, e, n, length)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * np.max(np.abs(want)))


@pytest.fixture
def with_vertical(monkeypatch):
    """The schema with one more row (every path reads the rows at call time)."""
    monkeypatch.setattr(schema, "KINDS", (*schema.KINDS, VERTICAL))
    return VERTICAL


def _vertical_term(h4: H4, x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The independent expectation: sum_i c_i b_i b_i^T, b_i the vertical force of leg i on its
    base mount per unit load, its bars' tensions (the Newton-Euler statics route) times their
    directions' z."""
    pts = assembled_points(h4.geometry, x)
    w = (pts.Bij - pts.Aij).reshape(8, 3)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    tensions = statics.bar_forces(h4.geometry, x)  # (8, 8) per unit load
    b = np.stack([w[2 * i, 2] * tensions[2 * i] + w[2 * i + 1, 2] * tensions[2 * i + 1] for i in range(4)])
    return (b.T * c) @ b


def test_a_new_element_kind_is_one_schema_row(with_vertical, proto, poses):
    """One row, no code: Elements takes it (its count, unit, plausible range), the URDF writes and
    reads it, the compiled and numpy compliances add exactly sum_i c_i b_i b_i^T (an independent
    statics route), the elastic model's virtual joints give the same K, and a very stiff one
    changes nothing within round-off."""
    el = Elements(mount_vertical=C)
    assert el.on("mount_vertical") and [k.name for k in el.kinds_on()] == ["mount_vertical"]
    with pytest.raises(ImplausibleValueError, match="vertical mount of actuator 1: mount_vertical = 1"):
        Elements(mount_vertical=1.0)
    text = to_urdf(H4Params(), "h4_vertical", elements=el)
    assert text.count("<h4_base vertical=") == 4 and 'vertical="3e-08"' in text
    robot = H4(text, "h4_vertical")
    np.testing.assert_array_equal(robot.elements.mount_vertical, C)
    bare = h4pin.compliance(proto, poses[:6], "consistent", method="closed_form").matrix
    for method in ("kernel", "closed_form"):
        got = h4pin.compliance(robot, poses[:6], "consistent", method=method, terms=True)
        for p, x in enumerate(poses[:6]):
            want = _vertical_term(proto, x, C)
            scale = np.max(np.abs(bare[p]))
            assert np.max(np.abs(got.terms["mount_vertical"][p] - want)) <= 1e-12 * scale, method
            assert np.max(np.abs(got.matrix[p] - bare[p] - want)) <= 1e-12 * scale, method
    elastic = h4pin.elastic_model(robot)
    assert [j for j in elastic.elastic_joints if "vertical" in j] == [f"mount_{i}_vertical" for i in range(1, 5)]
    x = poses[3]
    np.testing.assert_allclose(elastic.compliance_matrix(x), h4pin.compliance(robot, x, "consistent").matrix,
                               rtol=0, atol=1e-9 * np.max(np.abs(bare)))
    stiff = robot.with_elements(Elements(mount_vertical=1e-15))
    k_stiff = h4pin.compliance(stiff, poses[:6], "consistent", method="kernel").matrix
    assert np.max(np.abs(k_stiff - bare)) <= 1e-9 * np.max(np.abs(bare))


def test_a_new_element_kind_has_its_natural_frequencies(with_vertical, proto, centre):
    """The new row in the compiled natural frequencies (its form's compiled term) equals the
    Pinocchio route on the elastic model (its virtual joints); a compliance in series lowers
    every frequency, a very stiff one changes none within round-off."""
    robot = proto.with_elements(Elements(mount_vertical=C))
    twin = h4pin.modes(robot, centre, method="compiled").frequencies
    ref = h4pin.modes(robot, centre, method="pinocchio").frequencies
    np.testing.assert_allclose(twin, ref, rtol=1e-9)
    before = h4pin.modes(proto, centre, method="compiled").frequencies
    m = len(before)  # the new springs may add massive directions (the forearms' vertical motions): above these
    assert len(twin) >= m and np.all(twin[:m] < before)
    stiff = h4pin.modes(proto.with_elements(Elements(mount_vertical=1e-15)), centre, method="compiled").frequencies
    np.testing.assert_allclose(stiff[:m], before, rtol=1e-8)
