# SPDX-License-Identifier: Apache-2.0
"""The two-shape gap analysis (h4pin.studies.gap): each claim against an independent computation."""

from __future__ import annotations

import numpy as np
import pytest

from h4pin import H4Params, load
from h4pin.checks import statics
from h4pin.description.geometry import geometry_from_params
from h4pin.stiffness.api import TERMS, compliance
from h4pin.studies import gap


@pytest.fixture(scope="module")
def blocks():
    return gap.term_blocks()


def test_control_and_bending_share_the_closed_form_shape(proto, centre, blocks):
    """Control = (J diag(1/kc_i) J^T)_xyz with J = Jx^-1 Jq (eq. 8, closed form), bending = a scalar
    times it (the prototype's legs have equal springs)."""
    jx, jq = proto.jx_jq(centre)
    j = np.linalg.solve(jx, jq)
    p = proto.params
    closed = ((j / p.kc) @ j.T)[:3, :3]
    np.testing.assert_allclose(blocks["control"], closed, rtol=1e-10, atol=1e-12 * closed.max())
    ratio = p.kc * p.r / (3 * p.E * p.I)
    assert np.ptp(ratio) == 0.0
    np.testing.assert_allclose(blocks["bending"], closed * ratio[0], rtol=1e-10, atol=1e-12 * closed.max())
    shp = gap.shapes(blocks)
    np.testing.assert_allclose(shp["control"], closed / closed[0, 0], atol=1e-12)
    np.testing.assert_allclose(shp["bending"], shp["control"], atol=1e-12)
    # the two shapes differ: yy/xx of the tilt is not the axial one
    assert abs(shp["torsion"][1, 1] - shp["control"][1, 1]) > 0.05


def test_terms_span_a_plane(centre, blocks):
    """SVD of the four term blocks from the independent statics route: rank 2, and tension is a
    non-negative combination of the axial and tilt shapes."""
    theirs = {t: b[:3, :3] for t, b in statics.compliance_terms(geometry_from_params(H4Params()), centre).items()}
    m = np.stack([b.ravel() / np.linalg.norm(b) for b in theirs.values()])
    s = np.linalg.svd(m, compute_uv=False)
    assert s[2] / s[0] < 1e-12 and s[1] / s[0] > 1e-2
    np.testing.assert_allclose(gap.span_singular_values(blocks), s, atol=1e-10)
    coef, res = gap.in_span(theirs)
    assert res < 1e-12 and np.all(coef > 0)


def _grid_fit(blocks, target, n=801):
    """Brute force over the two shapes' factors (a, tau) >= 0: least rms and least max misfit."""
    two = gap.two_shapes(blocks)
    ax, tl = gap.entries(two["axial"]), gap.entries(two["tilt"])
    a = np.linspace(0.0, 2.5, n)[:, None, None]
    tau = np.linspace(0.0, 10.0, n)[None, :, None]
    mis = a * ax + tau * tl - gap.entries(target)
    return np.sqrt(np.mean(mis**2, axis=-1)).min(), np.abs(mis).max(axis=-1).min()


def test_nnls_and_minimax_against_a_brute_force_grid(blocks):
    best = gap.best_combination(blocks)
    two = gap.best_combination(gap.two_shapes(blocks))
    worst_case = gap.minimax_combination(blocks)
    grid_rms, grid_max = _grid_fit(blocks, gap.COMPUTED)
    step = 1e-8  # m/N: the grid's resolution in the entries (factor steps ~0.01 x ~30 um/N)
    assert best.rms <= grid_rms + 1e-15 and grid_rms - best.rms < step
    assert abs(two.rms - best.rms) < 1e-12  # tension adds nothing: it lies inside the cone
    assert worst_case.max_abs <= grid_max + 1e-15 and grid_max - worst_case.max_abs < step
    assert worst_case.max_abs > gap.ROUNDING  # the claim: no spring constants meet the rounding
    np.testing.assert_allclose(best.misfit, best.fitted - gap.entries(gap.COMPUTED))


def test_ratio_range_bounds_random_combinations(blocks):
    rng = np.random.default_rng(3)
    w = rng.exponential(size=(2000, 4)) * rng.integers(0, 2, size=(2000, 4))
    w = w[w.sum(1) > 0]
    e = np.einsum("nt,te->ne", w, np.stack([gap.entries(blocks[t]) for t in TERMS]))
    for num, den in (("zz", "xx"), ("yy", "xx")):
        lo, hi = gap.ratio_range(blocks, num, den)
        r = e[:, list(gap.ENTRIES).index(num)] / e[:, list(gap.ENTRIES).index(den)]
        assert r.min() >= lo - 1e-12 and r.max() <= hi + 1e-12
        assert r.min() - lo < 1e-9 and hi - r.max() < 1e-9  # single terms reach the ends
    assert gap.MEASURED[2, 2] / gap.MEASURED[0, 0] < gap.ratio_range(blocks)[0]


def test_noise_from_asymmetry_hand_formula():
    m = gap.MEASURED
    by_hand = (m[0, 1] ** 2 + m[1, 0] ** 2 + m[1, 2] ** 2 + m[2, 1] ** 2 + (m[0, 2] - m[2, 0]) ** 2 / 2) / 5
    sigma, dof = gap.noise_from_asymmetry()
    assert dof == 5 and sigma == pytest.approx(np.sqrt(by_hand), rel=1e-12)
    assert gap.noise_from_asymmetry(gap.COMPUTED)[0] == 0.0


def test_fit_region_against_robots_built_with_the_factors():
    """A feasible (C_k offset, tilt, axial) point read from the sweep gives a robot whose Table II
    meets the computed table within rounding when built with kc/a, I/a, I0/tau; the stated
    geometry is infeasible for every tilt factor."""
    taus = np.arange(1.0, 10.0, 0.05)
    region = gap.fit_region(np.array([-0.014, 0.0]), np.array([0.0]), taus)
    assert not region.feasible[1].any()
    k = np.flatnonzero(region.feasible[0, 0])
    assert k.size
    tau = taus[k[k.size // 2]]
    lo, hi = region.axial[0, 0, k[k.size // 2]]
    base = gap.moved_joints(H4Params(), -0.014, 0.0)
    for a, inside in (((lo + hi) / 2, True), (hi + 0.05, False)):
        h4 = load(base.replace(kc=base.kc / a, I=base.I / a, I0=base.I0 / tau))
        t = compliance(h4, h4.forward_geometry(np.full(4, np.pi / 4))).translational
        err = np.max(np.abs(gap.entries(t) - gap.entries(gap.COMPUTED)))
        assert (err <= gap.ROUNDING + 1e-12) == inside, (a, err)


def test_half_width_acts_only_through_tension(centre):
    """At the centre, h leaves control, bending and torsion unchanged (statics route) and moves the
    tension block within the span of the two shapes: it cannot be told from the tilt factor."""
    a = statics.compliance_terms(geometry_from_params(H4Params(half_width=0.02)), centre)
    b = statics.compliance_terms(geometry_from_params(H4Params(half_width=0.05)), centre)
    for t in ("control", "bending", "torsion"):
        np.testing.assert_allclose(b[t][:3, :3], a[t][:3, :3], rtol=1e-10, atol=1e-12 * np.abs(a[t]).max())
    change = {"tension": b["tension"][:3, :3] - a["tension"][:3, :3], "control": a["control"][:3, :3],
              "torsion": a["torsion"][:3, :3]}
    assert np.abs(change["tension"]).max() > 0.3 * np.abs(a["tension"][:3, :3]).max()
    assert gap.in_span(change)[1] < 1e-10


def test_robustness_rows_recompute_sections_1_and_2():
    """Each row of gap.robustness equals sections 1-2 recomputed on a robot built by hand with the
    change (actuators at 42 deg through forward geometry; C_k's |y| scaled in H4Params)."""
    from h4pin import H4Params, compliance, load

    rows = {r.name: r for r in gap.robustness(("nominal", "q -3 deg", "C_k |y| +5 %"))}
    h4 = load()
    res = compliance(h4, h4.forward_geometry(np.full(4, np.deg2rad(42.0))), elements=False)
    blocks = {t: res.terms[t][:3, :3] for t in ("control", "bending", "torsion", "tension")}
    assert rows["q -3 deg"].yy_xx == pytest.approx(gap.ratio_range(blocks, "yy", "xx"), rel=1e-12)
    assert rows["q -3 deg"].least_miss == pytest.approx(gap.minimax_combination(blocks).max_abs, rel=1e-9)
    dc = H4Params().DC.copy()
    dc[1] *= 1.05
    moved = gap.term_blocks(H4Params(DC=dc))
    assert rows["C_k |y| +5 %"].zz_xx == pytest.approx(gap.ratio_range(moved), rel=1e-12)
    # the robust conclusion: yy/xx never reaches the computed 21/40, springs alone never meet it
    for r in rows.values():
        assert r.yy_xx[1] < 21 / 40 and not r.meets and r.least_miss > gap.ROUNDING
