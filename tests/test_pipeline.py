# SPDX-License-Identifier: Apache-2.0
"""The compiled pipeline (eq. 30 and the elements, one pose or a batch: h4pin.stiffness.pipeline
through h4pin.stiffness.kernel) against the numpy reference, the statics route and independent
numpy checks of its verdicts: the same verdicts on a 10 000-pose fuzz, the same K, q, condition."""

from __future__ import annotations

import subprocess
import sys
import types
from pathlib import Path

import numba
import numpy as np
import pytest
from conftest import sample_poses

import h4pin
from h4pin import ParameterError, PoseError, SingularPoseError, verdicts
from h4pin.checks import statics
from h4pin.description.elements import ELEMENTS, ILLUSTRATIVE, Elements
from h4pin.kinematics import closed_form as geometry
from h4pin.kinematics.closed_form import centre_pose
from h4pin.stiffness import elements as statics_elements
from h4pin.stiffness import kernel, numpy_backend, packed, pipeline
from h4pin.stiffness.api import TERMS, compliance
from h4pin.stiffness.matrices import from_points

IDEAL = [name for name in h4pin.VARIANTS if h4pin.load(name).geometry.ideal]

ROOT = Path(__file__).resolve().parent.parent


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def per_pose_rel_each(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """max|a - b| / max|b| per pose (one scale per pose)."""
    return np.max(np.abs(a - b), axis=(-2, -1)) / np.max(np.abs(b), axis=(-2, -1))


def per_pose_rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest over poses of max|a - b| / max|b| (one scale per pose)."""
    return float(np.max(per_pose_rel_each(a, b)))


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


def fuzz(h4: h4pin.H4, n: int = 10_000, seed: int = 7) -> np.ndarray:
    """Poses around and across the workspace boundary, and at and near the robot's centre
    (singular for the symmetric variant): unreachable, outside the limits, interfering bars,
    singular and regular poses."""
    rng = np.random.default_rng(seed)
    c = h4.forward_geometry(np.full(4, np.pi / 4))
    x = c + rng.uniform(-1, 1, (n, 4)) * [0.35, 0.35, 0.3, 1.2]
    m = min(n, 500)
    x[:m] = c + rng.normal(0, 1, (m, 4)) * 10 ** rng.uniform(-12, -3, (m, 1))
    return x


def bound(cond: np.ndarray) -> np.ndarray:
    """1e-13 relative, or K's own accuracy (about cond x 1e-16) where M1 is ill-conditioned."""
    return np.maximum(1e-13, 2e-16 * cond)


def cond_rel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Relative difference of condition numbers (themselves accurate to about cond x 1e-16)."""
    return np.abs(a - b) / b


def one_by_one(kern: kernel.Kernel, xs: np.ndarray, model: str = "paper") -> kernel.KernelResult:
    """The one-pose entry of the pipeline (:func:`h4pin.stiffness.pipeline.one`) pose by pose."""
    rows = [kern(x, model) for x in xs]
    return kernel.KernelResult(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                               np.array([r[2] for r in rows]), np.array([r[3] for r in rows], dtype=np.int8))


@pytest.fixture(scope="module", params=IDEAL)
def robot(request) -> h4pin.H4:
    return h4pin.load(request.param)


@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_fuzz_equals_reference(robot, model):
    """The batch entry on 10 000 poses of every kind: the numpy reference's verdict for every
    pose, its K within K's own accuracy, its q and condition; and the one-pose entry the same on
    the first 600 (the near-centre ones and 100 of the others)."""
    x = fuzz(robot)
    ref = numpy_backend.backend(robot, x, model, False)
    res = kernel.compliance_batch(robot.geometry, x, model)
    np.testing.assert_array_equal(res.status, ref.status)
    counts = np.bincount(res.status, minlength=5)
    assert counts[verdicts.OK] > 1000 and counts[verdicts.UNREACHABLE] > 1000 and counts[verdicts.LIMITS] > 1000
    assert counts[verdicts.INTERFERENCE] > 0
    ok = ref.status == verdicts.OK
    rel = per_pose_rel_each(res.K[ok], ref.matrix[ok])
    assert np.all(rel <= bound(ref.condition[ok])), float(np.max(rel / bound(ref.condition[ok])))
    well = ref.condition[ok] < 1e3
    assert well.sum() > 500 and rel[well].max() <= 1e-13
    assert np.all(np.isnan(res.K[~ok]))
    np.testing.assert_allclose(res.q, ref.q, rtol=0, atol=1e-12)  # NaN where unreachable, in both
    assert np.all(cond_rel(res.condition[ok], ref.condition[ok]) <= np.maximum(1e-10, 1e-16 * ref.condition[ok]))
    one = one_by_one(kernel.prepare(robot.geometry), x[:600], model)
    np.testing.assert_array_equal(one.status, ref.status[:600])
    ok1 = ok[:600]
    assert np.all(per_pose_rel_each(one.K[ok1], ref.matrix[:600][ok1]) <= bound(ref.condition[:600][ok1]))
    np.testing.assert_allclose(one.q, ref.q[:600], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.isnan(one.K), np.isnan(res.K[:600]))


def test_singular_poses_are_found(sym):
    x = fuzz(sym)
    res = kernel.compliance_batch(sym.geometry, x)
    assert np.sum(res.status == verdicts.SINGULAR) > 100
    assert np.all(~(res.condition[res.status == verdicts.SINGULAR] < verdicts.SINGULAR_COND))


def test_non_finite_poses_are_unreachable_in_the_compiled_code(proto):
    """The public calls refuse a non-finite pose before the compiled code sees it; the compiled
    entries themselves give it status 1, q and condition NaN."""
    x = fuzz(proto, 200, seed=3)
    x[[3, 50, 120], [0, 2, 3]] = np.nan
    x[77] = np.inf
    kern = kernel.prepare(proto.geometry)
    res = kernel.run_poses(kern, x, 0, kernel.empty_result(len(x), False, False), False, False)
    bad = [3, 50, 77, 120]
    assert np.all(res.status[bad] == verdicts.UNREACHABLE)
    assert np.all(np.isnan(res.q[bad])) and np.all(np.isnan(res.condition[bad])) and np.all(np.isnan(res.K[bad]))
    K, q, cond, status, _ = kernel.one(kern, kernel.readonly(x[77]), 0)
    assert status == verdicts.UNREACHABLE and np.isnan(cond) and np.all(np.isnan(q)) and np.all(np.isnan(K))
    with pytest.raises(PoseError):
        kernel.compliance_batch(kern, x)


@pytest.mark.parametrize("n", [1, 3, 63, 64, 65, 255, 256, 1023, 1025, 2100])
def test_every_batch_length(proto, n):
    """Partial blocks (fewer poses than lanes, padded), the serial and the threaded runs give the
    one-pose entry's rows."""
    x = fuzz(proto, n, seed=n)
    a = kernel.compliance_batch(proto.geometry, x)
    b = one_by_one(kernel.prepare(proto.geometry), x)
    np.testing.assert_array_equal(a.status, b.status)
    ok = a.status == verdicts.OK
    assert np.all(per_pose_rel_each(a.K[ok], b.K[ok]) <= bound(a.condition[ok]))
    np.testing.assert_array_equal(np.isnan(a.K), np.isnan(b.K))


def test_threads_give_the_same_bits(proto):
    x = fuzz(proto, 3000, seed=5)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        serial = kernel.compliance_batch(proto.geometry, x, terms=True, jacobian=True)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        parallel = kernel.compliance_batch(proto.geometry, x, terms=True, jacobian=True)
    finally:
        numba.set_num_threads(before)
    for s, p in zip(serial, parallel, strict=True):
        np.testing.assert_array_equal(s, p)


def test_atan2_matches_numpy():
    """The branch-free atan2 of the pipeline: within 2 ulp of numpy's over eight decades of
    both arguments and all four quadrants, numpy's signed zeros on the axes, NaN in -> NaN out."""
    from numba import njit

    @njit(cache=False)
    def many(y, x):
        out = np.empty_like(y)
        for k in range(y.size):
            out[k] = pipeline.atan2(y[k], x[k])
        return out

    rng = np.random.default_rng(7)
    n = 400_000
    y = rng.standard_normal(n) * 10.0 ** rng.uniform(-4, 4, n)
    x = rng.standard_normal(n) * 10.0 ** rng.uniform(-4, 4, n)
    ref = np.arctan2(y, x)
    ulp = np.abs(many(y, x) - ref) / np.spacing(np.abs(ref))
    assert ulp.max() <= 2.0
    z = np.array([0.0, -0.0, 0.0, -0.0, 1.0, -1.0, 0.0, -0.0, np.nan, 1.0])
    w = np.array([0.0, 0.0, -0.0, -0.0, 0.0, 0.0, -2.0, -2.0, 1.0, np.nan])
    got, want = many(z, w), np.arctan2(z, w)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(np.signbit(got), np.signbit(want))


@pytest.mark.parametrize("variant", ["proto", "sym"])
@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_kernel_equals_reference(request, variant, model):
    """K, q of the batch and the one-pose entries vs the numpy closed-form batch of eq. 30,
    <= 1e-12 relative per pose."""
    h4 = request.getfixturevalue(variant)
    xs = well_conditioned(h4, sample_poses(h4, 150, seed=7))
    assert len(xs) > 50
    ref = compliance(h4, xs, model, method="closed_form")  # the numpy reference, not the kernel
    for res in (kernel.compliance_batch(h4.geometry, xs, model), one_by_one(kernel.prepare(h4.geometry), xs, model)):
        np.testing.assert_array_equal(res.status, 0)
        assert per_pose_rel(res.K, ref.matrix) <= 1e-12
        np.testing.assert_allclose(res.q, ref.q, rtol=0, atol=1e-12)
        assert res.terms is None and res.J is None


@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_terms_and_jacobian_equal_reference(proto, model):
    """The terms and J vs the numpy reference; J NaN where the pose is refused."""
    xs = sample_poses(proto, 60, seed=8)
    res = kernel.compliance_batch(proto.geometry, xs, model, terms=True, jacobian=True)
    ref = compliance(proto, xs, model, terms=True, method="closed_form")
    for t, name in enumerate(TERMS):
        assert per_pose_rel(res.terms[:, t], ref.terms[name]) <= 1e-12, name
    assert per_pose_rel(res.K, sum(ref.terms.values())) <= 1e-12
    assert per_pose_rel(res.J, closed_form(proto, xs, ref.q).J) <= 1e-12
    far = np.vstack([xs[:3], xs[0] + [1.0, 0.0, 0.0, 0.0]])  # the last one unreachable
    got = kernel.compliance_batch(proto.geometry, far, model, jacobian=True)
    assert got.status[-1] == verdicts.UNREACHABLE and np.all(np.isnan(got.J[-1]))
    np.testing.assert_array_equal(got.J[:3], res.J[:3])


def test_one_pose_equals_batch(proto):
    """The two entries agree to round-off (the batch's lanes are vectorised, the one pose's are
    not: the same operations, possibly fused differently)."""
    xs = sample_poses(proto, 5, seed=9)
    kern = kernel.prepare(proto.geometry)
    batch = kernel.compliance_batch(kern, xs, "consistent")
    for n, x in enumerate(xs):
        K, q, cond, status = kern(x, "consistent")
        assert rel(K, batch.K[n]) < 1e-14
        np.testing.assert_allclose(q, batch.q[n], rtol=0, atol=1e-15)
        assert cond == pytest.approx(batch.condition[n], rel=1e-12) and status == batch.status[n] == verdicts.OK
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
    out = kernel.empty_result(len(xs), False, False)
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
    """A fresh interpreter loads both entries of the compiled pipeline from numba's cache (no
    recompile), whatever the writability of the caller's arrays (one compiled version each)."""
    kern = kernel.prepare(proto.geometry)
    kernel.compliance_batch(kern, centre)  # compiles here if no cache yet, and writes it
    kern(centre)
    code = ("import numpy as np, h4pin; from h4pin.stiffness import kernel, pipeline; g = h4pin.load().geometry;"
            "k = kernel.prepare(g); x = np.array([0, 0, -0.6, 0.0]); k(x); kernel.compliance_batch(k, x);"
            "y = np.tile(x, (300, 1)); y.setflags(write=False); kernel.compliance_batch(k, y); k(y[0]);"
            "s = [f.stats for f in (pipeline.run, pipeline.one)];"
            "print(*[sum(t.cache_hits.values()) for t in s], *[sum(t.cache_misses.values()) for t in s],"
            " len(pipeline.run.signatures), len(pipeline.one.signatures))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    h1, h2, m1, m2, n1, n2 = map(int, out.stdout.split())
    assert h1 >= 1 and h2 >= 1 and [m1, m2] == [0, 0] and [n1, n2] == [1, 1]


def test_pack_broadcasts_over_robots(proto, sym):
    """kernel.pack over a leading robot axis gives, row by row, the vectors of Kernel (prepare);
    Kernel.from_packed wraps one as a read-only kernel without a geometry."""
    geoms = [writable_geometry(h4.geometry) for h4 in (proto, sym, proto)]
    stacked = {name: np.stack([getattr(g, name) for g in geoms]) for name in packed.SHAPES}
    stacked["bar_clearance"] = np.array([g.bar_clearance for g in geoms])
    G = packed.pack(**stacked)
    assert G.shape == (3, packed.G_SIZE)
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


@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_element_terms_equal_the_statics_route(robot, model):
    """Every element kind in the compiled pipeline (batch and one pose), term by term, against the
    numpy statics route (:mod:`h4pin.stiffness.elements`: the 18 x 18 equilibrium of the plate's
    three bodies, unit loads on each element): within 1e-12 of the pose's K at well-conditioned
    poses; K is eq. 30's plus their sum, and each kind alone gives its own term."""
    xs = well_conditioned(robot, sample_poses(robot, 40, seed=21))
    assert len(xs) > 20
    kern = kernel.for_geometry(robot.geometry, ILLUSTRATIVE)
    names = [n for n in ELEMENTS if ILLUSTRATIVE.on(n)]
    assert names == list(ELEMENTS) and kern.kinds == len(ELEMENTS)
    res = kernel.compliance_batch(kern, xs, model, terms=True)
    bare = kernel.compliance_batch(kernel.prepare(robot.geometry), xs, model, terms=True)
    np.testing.assert_array_equal(res.status, 0)
    np.testing.assert_array_equal(res.terms[:, :4], bare.terms)
    for p, x in enumerate(xs):
        ref = statics_elements.element_terms(robot.geometry, x, ILLUSTRATIVE)
        scale = np.max(np.abs(res.K[p]))
        for t, name in enumerate(names):
            assert np.max(np.abs(res.terms[p, 4 + t] - ref[name])) <= 1e-12 * scale, name
        np.testing.assert_allclose(res.K[p], bare.K[p] + sum(ref.values()), rtol=0, atol=1e-12 * scale)
    K1, _, _, status, T1 = kernel.one(kern, kernel.readonly(xs[0]), kernel.model_code(model), terms=True)
    assert status == verdicts.OK
    assert rel(K1, res.K[0]) < 1e-13 and rel(T1, res.terms[0]) < 1e-13
    for name in names[::3]:  # one kind alone: its term, and K = eq. 30 + it
        alone = Elements(**{name: getattr(ILLUSTRATIVE, name)})
        got = kernel.compliance_batch(kernel.for_geometry(robot.geometry, alone), xs[:5], model, terms=True)
        np.testing.assert_allclose(got.terms[:, 4], res.terms[:5, 4 + names.index(name)], rtol=0,
                                   atol=1e-14 * np.max(np.abs(res.K[:5])))
        np.testing.assert_allclose(got.K, bare.K[:5] + got.terms[:, 4], rtol=0, atol=1e-14 * np.max(np.abs(got.K)))


def test_element_table(proto):
    """The table the pipeline reads: one row per kind on (site, form, axis, count, offset), each
    element's compliance (1 / rigidity for beams, times the joints in series) and length."""
    assert kernel.pack_elements(None, kernel.prepare(proto.geometry).packed) is packed.NO_ELEMENTS
    off = Elements(central_EI=np.inf, ball_radial=0.0)
    assert kernel.prepare(proto.geometry).with_elements(off).elements is packed.NO_ELEMENTS
    el = Elements(ball_radial=[1e-8] * 4 + [0.0] * 4, central_EI=[200.0, np.inf])
    table = kernel.for_geometry(proto.geometry, el).elements
    assert not table.flags.writeable and table[0] == 2
    rows = table[packed.EL_HEADER:packed.EL_HEADER + 2 * packed.EL_ROW].reshape(2, packed.EL_ROW)
    ball, beam = (table[int(r[4]):int(r[4]) + 2 * int(r[3])].reshape(-1, 2) for r in rows)
    np.testing.assert_array_equal(ball[:, 0], [2e-8] * 4 + [0.0] * 4)
    np.testing.assert_allclose(beam[:, 0], [1 / 200.0, 0.0])
    np.testing.assert_allclose(beam[:, 1], np.linalg.norm(proto.geometry.C0, axis=1), rtol=1e-15)
    with pytest.raises(ParameterError, match="Elements"):
        kernel.prepare(proto.geometry).with_elements({"ball_radial": 1e-8})
