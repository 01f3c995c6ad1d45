# SPDX-License-Identifier: Apache-2.0
"""H4Params: defaults from the paper in SI, documented choices, validation that names the field."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from h4pin import H4Params, ParameterError, symmetric_params


def test_defaults_are_the_paper_in_si():
    p = H4Params()
    # Section V.A: kc = 7.4e6 N.mm/rad, E = 70 000 N/mm^2, I = 1.6e4 mm^4, Sb = 28 mm^2, Eb = 200 000 N/mm^2.
    assert p.kc == pytest.approx(7.4e6 * 1e-3)
    assert p.E == pytest.approx(70_000 * 1e6) and p.G == pytest.approx(0.4 * p.E)
    assert p.I == pytest.approx(1.6e4 * 1e-12) and p.I0 == pytest.approx(2 * p.I)
    assert p.Sb == pytest.approx(28e-6) and p.Eb == pytest.approx(2e11)
    assert (p.r, p.l) == pytest.approx((0.26, 0.48))


def test_forearms_point_outward_with_the_p1_fix():
    """With P_1 = (-200, -60, 0) mm every a_i = u_i x z points away from the centre."""
    p = H4Params()
    assert np.all(np.einsum("ai,ai->i", p.forearm_dirs[:2], p.P[:2]) > 0)
    printed = p.P.copy()
    printed[0, 0] = 0.2
    assert np.einsum("a,a->", p.forearm_dirs[:2, 0], printed[:2, 0]) < 0


def test_symmetric_variant_is_leg_1_rotated():
    p, s = H4Params(), symmetric_params()
    for i in range(4):
        c, si = np.cos(i * np.pi / 2), np.sin(i * np.pi / 2)
        rot = np.array([[c, -si, 0], [si, c, 0], [0, 0, 1]])
        for f in ("P", "U", "DB"):
            np.testing.assert_allclose(getattr(s, f)[:, i], rot @ getattr(p, f)[:, 0], atol=1e-15)
    np.testing.assert_array_equal(s.DC, p.DC)


def test_arrays_are_read_only_copies():
    src = np.array(H4Params().P)
    p = H4Params(P=src)
    src[0, 0] = 99.0
    assert p.P[0, 0] == pytest.approx(-0.2)
    with pytest.raises(ValueError):
        p.P[0, 0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.r = 1.0  # type: ignore[misc]


def test_equality_and_replace():
    assert H4Params() == H4Params()
    assert H4Params().replace(half_width=0.02) != H4Params()
    assert np.all(H4Params().replace(half_width=0.02).half_width == 0.02)
    assert H4Params(r=[0.26, 0.27, 0.26, 0.25]).r.tolist() == [0.26, 0.27, 0.26, 0.25]


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"P": np.zeros((3, 3))}, "P"),
        ({"DB": np.full((3, 4), np.nan)}, "DB"),
        ({"DC": np.zeros((2, 3))}, "DC"),
        ({"r": -0.26}, "r"),
        ({"l": 0.0}, "l"),
        ({"kc": np.inf}, "kc"),
        ({"E": "steel"}, "E"),
        ({"Sb": -1.0}, "Sb"),
        ({"U": H4Params().U * 2}, "U"),
        ({"U": np.array([[0, 1, -1, 0], [-0.6, 0, 0, -1], [0.8, 0, 0, 0.0]])}, "U"),
        ({"half_width": 0.058}, "half_width"),
        ({"forearm_stressed_fraction": 1.5}, "forearm_stressed_fraction"),
        ({"half_width": 0.07}, "legs 1 and 4 collide or cross"),
        ({"half_width": 10.0}, "collide or cross"),
        ({"l": True}, "l must be a real number"),
        ({"r": "0.26"}, "r must be a real number"),
        ({"kc": [1.0, 2.0]}, "kc must be a scalar or have 4 entries"),
        ({"l": 0.05}, "cannot hold the plate"),
        ({"ball_radius": np.nan}, "ball_radius"),
    ],
)
def test_bad_parameters_are_refused_naming_the_field(changes, field):
    with pytest.raises(ParameterError, match=field):
        H4Params(**changes)


def test_half_width_collision_names_the_legs():
    """Legs 1 and 4 share the x = -60 mm side of the plate: their inner balls meet at h = 60 mm."""
    with pytest.raises(ParameterError, match="legs 1 and 4"):
        H4Params(half_width=0.059)
    H4Params(half_width=0.05)  # 20 mm apart: accepted


def test_compliances_closed_form():
    p = H4Params(forearm_stressed_fraction=2 / 3)
    c = p.compliances()
    assert c["control"] == pytest.approx(np.full(4, 1 / 7400))
    assert c["bending"] == pytest.approx(np.full(4, (2 / 3) ** 3 * 0.26 / (3 * 7e10 * 1.6e-8)))
    assert c["torsion"] == pytest.approx(np.full(4, (2 / 3) * 0.26 / (2.8e10 * 3.2e-8)))
    assert c["tension"] == pytest.approx(np.full(8, 0.48 / (28e-6 * 2e11)))


def test_batched_checks_agree_with_h4params():
    """ball_joints_apart and bars_reach over a design axis: False exactly where H4Params raises
    the matching error (per-leg half-widths and per-bar lengths)."""
    from h4pin.description.params import _reach_table, ball_joints_apart, bars_reach

    rng = np.random.default_rng(7)
    p = H4Params()
    n = 300
    hw = rng.uniform(0.02, 0.075, (n, 4))
    r = rng.uniform(0.1, 0.4, (n, 4))
    l = np.repeat(rng.uniform(0.05, 0.7, (n, 4)), 2, axis=1)
    apart = ball_joints_apart(p.DB, p.U, hw, p.ball_radius)
    reach = bars_reach(p.P, p.U, p.DB, r, l)
    assert apart.shape == reach.shape == (n,)
    assert 0 < apart.sum() < n and 0 < reach.sum() < n
    # bars_reach tries every 8th height first: the same verdicts as the whole table of heights
    assert np.array_equal(reach, np.all(_reach_table(p.P, p.U, p.DB, r, l), axis=-1).any(axis=-1))
    for k in range(n):
        try:
            H4Params(half_width=hw[k], r=r[k], l=l[k])
        except ParameterError as exc:
            assert not (apart[k] and reach[k])
            assert ("collide or cross" in str(exc)) == (not apart[k])
            continue
        assert apart[k] and reach[k]
