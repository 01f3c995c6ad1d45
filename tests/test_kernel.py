# SPDX-License-Identifier: Apache-2.0
"""The compiled kernel (eq. 30 per pose) against the numpy reference, the statics route and
independent numpy checks of its verdict."""

from __future__ import annotations

import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from conftest import sample_poses

from h4pin import ParameterError, PoseError, SingularPoseError, verdicts
from h4pin.checks import statics
from h4pin.kinematics import closed_form as geometry
from h4pin.kinematics.closed_form import centre_pose
from h4pin.stiffness import kernel
from h4pin.stiffness.api import TERMS, compliance
from h4pin.stiffness.matrices import from_points

ROOT = Path(__file__).resolve().parent.parent


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def per_pose_rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest over poses of max|a - b| / max|b| (one scale per pose)."""
    return float(np.max(np.max(np.abs(a - b), axis=(-2, -1)) / np.max(np.abs(b), axis=(-2, -1))))


def writable_geometry(g) -> types.SimpleNamespace:
    """The kernel's geometry object of a robot's geometry, with writable copies of its arrays."""
    ns = kernel._namespace(g)
    return types.SimpleNamespace(**{k: np.array(v) if isinstance(v, np.ndarray) else v for k, v in vars(ns).items()})


def closed_form(h4, xs: np.ndarray, q: np.ndarray):
    """The numpy closed-form matrices at rigid poses (the reference path)."""
    return from_points(h4.geometry, geometry.points(h4.geometry, geometry.rigid_state(xs, q)))


def open_geometry(geometry) -> types.SimpleNamespace:
    """A robot's geometry with every limit opened (only reachability and M1 remain)."""
    g = writable_geometry(geometry)
    g.q_lo[:], g.q_hi[:], g.omega_lo[:], g.omega_hi[:] = -9.0, 9.0, -9.0, 9.0
    g.bar_clearance = 0.0
    return g


def well_conditioned(h4, xs: np.ndarray, limit: float = 1e4) -> np.ndarray:
    """Poses whose (unscaled, numpy) cond(M1) is below ``limit``: away from singularities."""
    m1 = closed_form(h4, xs, h4.inverse_geometry(xs, check=False)).M1
    return xs[np.linalg.cond(m1, 1) < limit]


def bar_axis_distance(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, n: int = 801) -> float:
    """Least distance between segments a-b and c-d by brute force on n x n samples (upper bound,
    within half a sample spacing of the truth)."""
    s = np.linspace(0.0, 1.0, n)
    p = a + s[:, None] * (b - a)
    r = c + s[:, None] * (d - c)
    return float(np.sqrt(np.min(np.sum((p[:, None, :] - r[None, :, :]) ** 2, axis=-1))))


def min_bar_distance(h4, pose: np.ndarray) -> float:
    q = geometry.inverse_geometry(h4.geometry, pose, check=False)
    pts = geometry.points(h4.geometry, geometry.rigid_state(pose, q))
    a, b = pts.Aij.reshape(8, 3), pts.Bij.reshape(8, 3)
    return min(bar_axis_distance(a[n], b[n], a[m], b[m]) for n in range(8) for m in range(8) if n // 2 < m // 2)


@pytest.mark.parametrize("vector", [False, True], ids=["scalar", "vector"])
@pytest.mark.parametrize("variant", ["proto", "sym"])
@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_kernel_equals_reference(request, variant, model, vector):
    """K, q of both kernels vs the numpy closed-form batch of eq. 30, <= 1e-12 relative per pose."""
    h4 = request.getfixturevalue(variant)
    xs = well_conditioned(h4, sample_poses(h4, 150, seed=7))
    assert len(xs) > 50
    res = kernel.compliance_batch(h4.geometry, xs, model, vector=vector)
    ref = compliance(h4, xs, model, method="closed_form")  # the numpy reference, not the kernel
    np.testing.assert_array_equal(res.status, 0)
    assert per_pose_rel(res.K, ref.matrix) <= 1e-12
    np.testing.assert_allclose(res.q, ref.q, rtol=0, atol=1e-12)
    assert res.terms is None and res.J is None


@pytest.mark.parametrize("vector", [False, True], ids=["scalar", "vector"])
@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_terms_and_jacobian_equal_reference(proto, model, vector):
    """The terms and J of both kernels vs the numpy reference; J NaN where the pose is refused."""
    xs = sample_poses(proto, 60, seed=8)
    res = kernel.compliance_batch(proto.geometry, xs, model, terms=True, jacobian=True, vector=vector)
    ref = compliance(proto, xs, model, terms=True, method="closed_form")
    for t, name in enumerate(TERMS):
        assert per_pose_rel(res.terms[:, t], ref.terms[name]) <= 1e-12, name
    assert per_pose_rel(res.K, sum(ref.terms.values())) <= 1e-12
    assert per_pose_rel(res.J, closed_form(proto, xs, ref.q).J) <= 1e-12
    far = np.vstack([xs[:3], xs[0] + [1.0, 0.0, 0.0, 0.0]])  # the last one unreachable
    got = kernel.compliance_batch(proto.geometry, far, model, jacobian=True, vector=vector)
    assert got.status[-1] == verdicts.UNREACHABLE and np.all(np.isnan(got.J[-1]))
    np.testing.assert_array_equal(got.J[:3], res.J[:3])


def test_one_pose_equals_batch(proto):
    xs = sample_poses(proto, 5, seed=9)
    kern = kernel.prepare(proto.geometry)
    batch = kernel.compliance_batch(kern, xs, "consistent")
    for n, x in enumerate(xs):
        K, q, cond, status = kern(x, "consistent")
        np.testing.assert_array_equal(K, batch.K[n])
        np.testing.assert_array_equal(q, batch.q[n])
        assert cond == batch.condition[n] and status == batch.status[n] == verdicts.OK
        K2, *_ = kernel.compliance_one(proto.geometry, x, "consistent")
        np.testing.assert_array_equal(K2, K)


def test_streaming_and_out_arrays_equal_batch(proto):
    xs = sample_poses(proto, 70, seed=10)
    whole = kernel.compliance_batch(proto.geometry, xs, "paper")
    seen = 0
    for start, part in kernel.iter_compliance(proto.geometry, xs, "paper", chunk=16):
        np.testing.assert_array_equal(part.K, whole.K[start:start + len(part.K)])
        seen += len(part.K)
    assert seen == len(xs)
    parts = (xs[s:s + 30] for s in range(0, len(xs), 30))
    got = np.concatenate([p.K.copy() for _, p in kernel.iter_compliance(proto.geometry, parts, "paper", chunk=8)])
    np.testing.assert_array_equal(got, whole.K)
    out = kernel._empty(len(xs), False, False)
    res = kernel.compliance_batch(proto.geometry, xs, "paper", out)
    assert res.K is out.K
    np.testing.assert_array_equal(out.K, whole.K)


def test_unreachable_status_matches_inverse_geometry(proto, centre):
    rng = np.random.default_rng(11)
    xs = centre + rng.uniform(-1, 1, (400, 4)) * [0.4, 0.4, 0.4, 0.3]
    res = kernel.compliance_batch(open_geometry(proto.geometry), xs)
    unreachable = np.any(np.isnan(geometry.inverse_geometry(proto.geometry, xs, on_error="nan", check=False)), axis=1)
    assert 50 < unreachable.sum() < 350
    np.testing.assert_array_equal(res.status == verdicts.UNREACHABLE, unreachable)
    np.testing.assert_array_equal(res.status[~unreachable], verdicts.OK)
    assert np.all(np.isnan(res.K[unreachable])) and np.all(np.isnan(res.q[unreachable]))
    assert np.all(np.isfinite(res.K[~unreachable]))


def test_joint_limit_status(proto, centre):
    """Actuator limits on q (numpy inverse geometry) and lateral limits on omega_k = -theta."""
    g = writable_geometry(proto.geometry)
    rng = np.random.default_rng(12)
    xs = centre + rng.uniform(-1, 1, (300, 4)) * [0.15, 0.15, 0.1, 1.2]
    q = geometry.inverse_geometry(proto.geometry, xs, on_error="nan", check=False)
    reach = np.all(np.isfinite(q), axis=1)
    xs, q = xs[reach], q[reach]
    g.q_lo[:] = [-1.0, -0.5, -1.0, -1.0]
    g.q_hi[:] = [2.0, 2.0, 0.9, 2.0]
    outside = (np.any((q < g.q_lo) | (q > g.q_hi), axis=1) | (-xs[:, 3] < -np.pi / 4) | (-xs[:, 3] > np.pi / 4))
    assert 30 < outside.sum() < len(xs) - 30
    res = kernel.compliance_batch(g, xs)
    np.testing.assert_array_equal(res.status == verdicts.LIMITS, outside)
    np.testing.assert_array_equal(res.status[~outside], verdicts.OK)
    np.testing.assert_allclose(res.q, q, rtol=0, atol=1e-12)  # q is given even outside the limits


def test_bar_interpenetration_status(proto, centre):
    """The legs' bars cross when the central bar turns by 1.5 rad; at the centre the closest bar
    axes of two legs (bars 12 and 41) are 120 mm - 2 h = 40 mm apart."""
    g = open_geometry(proto.geometry)
    g.bar_clearance = 0.01
    turned = centre + [0, 0, 0, 1.5]
    assert min_bar_distance(proto, turned) < 0.005
    assert min_bar_distance(proto, centre + [0, 0, 0, 1.0]) > 0.015
    res = kernel.compliance_batch(g, np.array([turned, centre + [0, 0, 0, 1.0]]))
    np.testing.assert_array_equal(res.status, [verdicts.INTERFERENCE, verdicts.OK])
    gap = min_bar_distance(proto, centre)
    assert abs(gap - (0.12 - 2 * proto.params.half_width[0])) < 1e-9
    for clearance, status in ((gap + 0.002, verdicts.INTERFERENCE), (gap - 0.002, verdicts.OK)):
        g.bar_clearance = clearance
        assert kernel.compliance_batch(g, centre).status[0] == status


def test_symmetric_centre_is_singular(sym):
    x = centre_pose(sym)
    with pytest.raises(SingularPoseError):
        compliance(sym, x, method="closed_form")
    K, q, cond, status = kernel.prepare(sym.geometry)(x)
    assert status == verdicts.SINGULAR and not cond < verdicts.SINGULAR_COND
    assert np.all(np.isnan(K))
    np.testing.assert_allclose(q, np.pi / 4, atol=1e-12)
    # 2 cm away it is regular again and the kernel agrees with the reference.
    K2, _, cond2, status2 = kernel.prepare(sym.geometry)(x + [0.02, 0.01, 0, 0.1])
    assert status2 == verdicts.OK and cond2 < 1e6
    assert rel(K2, compliance(sym, x + [0.02, 0.01, 0, 0.1]).matrix) < 1e-11


def test_condition_is_the_scaled_one_norm_condition_of_m1(proto, poses):
    m = closed_form(proto, poses, proto.inverse_geometry(poses))
    scale_cols = np.r_[np.ones(3), np.full(5, 1 / np.mean(proto.params.l))]
    scaled = m.M1 / m.l[..., :, None] * scale_cols
    want = np.linalg.cond(scaled, 1)
    got = kernel.compliance_batch(proto.geometry, poses).condition
    np.testing.assert_allclose(got, want, rtol=1e-10)


@pytest.mark.parametrize("element", [("c_tens", 3, "tension"), ("c_tens", 6, "tension"), ("c_tors", 1, "torsion"),
                                     ("c_ctrl", 2, "control"), ("c_bend", 0, "bending")])
def test_per_element_compliance_equals_unit_load_route(proto, poses, element):
    """K is linear in each spring: doubling c_s adds c_s g_s g_s^T, g_s the load of spring s per
    unit Gamma_ext from the Newton-Euler statics route (consistent model)."""
    attr, index, term = element
    g = writable_geometry(proto.geometry)
    for x in poses[:4]:
        before = kernel.prepare(g)(x, "consistent")[0]
        g2 = writable_geometry(proto.geometry)
        getattr(g2, attr)[index] *= 2.0
        after = kernel.prepare(g2)(x, "consistent")[0]
        gs = statics.spring_loads(proto.geometry, x)[term][index]
        c = getattr(g, attr)[index]
        assert rel(after - before, c * np.outer(gs, gs)) < 1e-9
        if term in ("tension", "torsion"):  # the paper's model differs only in the actuator terms
            paper = kernel.prepare(g2)(x, "paper")[0] - kernel.prepare(g)(x, "paper")[0]
            assert rel(paper, c * np.outer(gs, gs)) < 1e-9


def test_typed_errors(proto):
    g = writable_geometry(proto.geometry)
    del g.c_tens
    with pytest.raises(ParameterError, match="c_tens"):
        kernel.prepare(g)
    g = writable_geometry(proto.geometry)
    g.A0 = g.A0[:4]
    with pytest.raises(ParameterError, match="A0"):
        kernel.prepare(g)
    with pytest.raises(ParameterError, match="model"):
        kernel.compliance_batch(proto.geometry, np.zeros(4), model="exact")
    with pytest.raises(PoseError):
        kernel.compliance_batch(proto.geometry, np.zeros((3, 5)))
    with pytest.raises(ParameterError, match="chunk"):
        next(kernel.iter_compliance(proto.geometry, np.zeros((3, 4)), chunk=0))


def test_compiled_code_is_cached(proto, centre):
    """A fresh interpreter loads the compiled batch kernels (threaded, serial and vector) from
    numba's cache (no recompile)."""
    big = np.tile(centre, (kernel.SERIAL_BELOW, 1))
    kernel.compliance_batch(proto.geometry, centre)  # compiles here if no cache yet, and writes it
    kernel.compliance_batch(proto.geometry, big, vector=False)
    kernel.compliance_batch(proto.geometry, big, vector=True)
    code = ("import numpy as np, h4pin; from h4pin.stiffness import kernel, vector; g = h4pin.load().geometry;"
            "kernel.compliance_batch(g, np.array([0, 0, -0.6, 0.0]));"
            "big = np.tile([0, 0, -0.6, 0.0], (kernel.SERIAL_BELOW, 1));"
            "kernel.compliance_batch(g, big, vector=False); kernel.compliance_batch(g, big, vector=True);"
            "s = [f.stats for f in (kernel._batch, kernel._batch_serial, vector._run)];"
            "print(*[sum(t.cache_hits.values()) for t in s], *[sum(t.cache_misses.values()) for t in s])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    *hits, m1, m2, m3 = map(int, out.stdout.split())
    assert all(h >= 1 for h in hits) and [m1, m2, m3] == [0, 0, 0]


def test_pack_broadcasts_over_robots(proto, sym):
    """kernel.pack over a leading robot axis gives, row by row, the vectors of Kernel (prepare);
    Kernel.from_packed wraps one as a read-only kernel without a geometry."""
    geoms = [writable_geometry(h4.geometry) for h4 in (proto, sym, proto)]
    stacked = {name: np.stack([getattr(g, name) for g in geoms]) for name in kernel._SHAPES}
    stacked["bar_clearance"] = np.array([g.bar_clearance for g in geoms])
    G = kernel.pack(**stacked)
    assert G.shape == (3, kernel._SIZE)
    for row, h4 in zip(G, (proto, sym, proto), strict=True):
        ref = kernel.prepare(h4.geometry)
        np.testing.assert_array_equal(row, ref.packed)
        kern = kernel.Kernel.from_packed(row)
        assert kern.geometry is None and not kern.packed.flags.writeable
        np.testing.assert_array_equal(kern.packed, ref.packed)
    kern = kernel.Kernel.from_packed(G[1])
    G[1] = 0.0  # a copy: the kernel keeps its vector
    np.testing.assert_array_equal(kern.packed, kernel.prepare(sym.geometry).packed)
    with pytest.raises(ParameterError, match="shape"):
        kernel.Kernel.from_packed(G[:, :10])


def test_pack_fields_checks_as_prepare_does(proto):
    """The batched route refuses what prepare refuses (here a non-unit actuator axis)."""
    from h4pin.description.geometry import geometry_arrays, geometry_from_params
    from h4pin.description.params import SPRINGS

    p = proto.params
    fields = geometry_arrays(np.stack([p.P, p.P]), p.U, p.forearm_dirs, p.r, p.l, p.half_width, p.DB, p.DC,
                             {name: getattr(p, name) for name in SPRINGS})
    np.testing.assert_array_equal(kernel.pack_fields(fields)[1], kernel.prepare(geometry_from_params(p)).packed)
    fields["u"] = fields["u"] * np.array([1.0, 1.1])[:, None, None, None]
    with pytest.raises(ParameterError, match="unit vectors"):
        kernel.pack_fields(fields)
