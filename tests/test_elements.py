# SPDX-License-Identifier: Apache-2.0
"""Optional elements beyond eq. 30 (h4pin.elements): unit loads on the statics route against
finite differences of the deformed robot, and exact reduction to eq. 30 when off."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from h4pin import ParameterError, deformed, statics
from h4pin import elements as el
from h4pin.stiffness import TERMS, compliance


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("n_pose", [2, 7])
def test_element_terms_equal_finite_differences(proto, poses, n_pose):
    """Each element: c sum g g^T (joint reactions, bar tensions from the plate equilibrium) vs
    c sum G G^T (plate motion of the deformed robot per joint displacement, tilt, bar length)."""
    x = poses[n_pose]
    ours = el.element_terms(proto.params, x, el.ILLUSTRATIVE)
    fd = el.element_terms_fd(proto.params, x, el.ILLUSTRATIVE)
    assert set(ours) == set(el.ELEMENTS) == set(fd)
    for name in el.ELEMENTS:
        assert rel(ours[name], fd[name]) < 1e-6, name


def test_plate_loads_agree_with_the_statics_route(proto, poses):
    """Bar tensions from this equilibrium (moments about D) = statics.bar_forces (about O);
    ball joints carry the bar tension, so their term is the tension term scaled."""
    x = poses[4]
    assert rel(el.plate_loads(proto.params, x)["bars"], statics.bar_forces(proto.params, x)) < 1e-12
    ball = el.element_terms(proto.params, x, el.Elements(ball_radial=3e-8))["ball_radial"]
    tension = statics.compliance_terms(proto.params, x)["tension"]
    assert rel(ball, tension * 2 * 3e-8 / proto.params.compliances()["tension"]) < 1e-12


def test_joint_reactions_balance_the_lateral_bars(proto, poses):
    """Sum of forces on lateral bar k: joint force + bar pulls = 0, in the central-bar frame."""
    from h4pin.geometry import points, rot_z

    x = poses[6]
    loads = el.plate_loads(proto.params, x)
    pts = points(proto.params, x, proto.inverse_geometry(x))
    w = (pts.Bij - pts.Aij).reshape(8, 3)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    for k in range(2):
        pulls = -(w[4 * k:4 * k + 4].T @ loads["bars"][4 * k:4 * k + 4])  # (3, 8) world
        np.testing.assert_allclose(rot_z(x[3]) @ loads["force"][k] + pulls, 0.0, atol=1e-12)


def test_off_is_exactly_eq_30(proto, poses):
    for model in ("paper", "consistent"):
        base = compliance(proto, poses[0], model)
        off = el.compliance_with_elements(proto, poses[0], el.Elements(), model)
        np.testing.assert_array_equal(off.matrix, base.matrix)
        assert tuple(off.terms) == TERMS


def test_on_stays_symmetric_and_equals_the_deformed_route(proto, poses):
    """Consistent K + elements = sum over all springs of the deformed robot (finite differences)."""
    x = poses[3]
    res = el.compliance_with_elements(proto, x, el.ILLUSTRATIVE)
    assert rel(res.matrix, res.matrix.T) < 1e-13 and np.linalg.eigvalsh(res.matrix).min() > 0
    fd = sum(deformed.compliance_terms(proto.params, x).values()) + sum(
        el.element_terms_fd(proto.params, x, el.ILLUSTRATIVE).values())
    assert rel(res.matrix, fd) < 1e-6
    assert rel(sum(res.terms.values()), res.matrix) < 1e-14
    assert set(res.terms) == set(TERMS) | set(el.ELEMENTS)


@pytest.mark.parametrize("bad", [-1e-8, np.nan, "stiff"])
def test_bad_element_values(bad):
    with pytest.raises(ParameterError, match="revolute_tilt"):
        el.Elements(revolute_tilt=bad)
    assert dataclasses.replace(el.Elements(), ball_radial=1e-8).off is False


def test_term_entries_sum_to_the_table(proto, centre):
    entries = el.term_entries(proto, centre)
    table = el.compliance_with_elements(proto, centre, el.ILLUSTRATIVE).translational
    np.testing.assert_allclose(sum(entries.values()), table[[0, 1, 2, 0], [0, 1, 2, 2]], rtol=1e-14)
    assert entries["revolute_tilt"][0] > 0 and abs(entries["revolute_tilt"][2]) < 1e-12 * entries["revolute_tilt"][0]
