# SPDX-License-Identifier: Apache-2.0
"""The lane-vector kernel (h4pin.stiffness.vector) against the numpy reference and the scalar
kernel: same verdicts on a 10 000-pose fuzz, same K, q, condition."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import h4pin
from h4pin import verdicts
from h4pin.kinematics.closed_form import centre_pose
from h4pin.stiffness import core, kernel, numpy_backend, packed, vector

#: The vector kernel whatever the batch size (kernel.compliance_batch's arguments).
vector_batch = functools.partial(kernel.compliance_batch, vector=True)

IDEAL = [name for name in h4pin.VARIANTS if h4pin.load(name).geometry.ideal]


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


def per_pose_rel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.max(np.abs(a - b), axis=(-2, -1)) / np.max(np.abs(b), axis=(-2, -1))


def cond_rel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Relative difference of condition numbers (themselves accurate to about cond x 1e-16)."""
    return np.abs(a - b) / b


def bound(cond: np.ndarray) -> np.ndarray:
    """1e-13 relative, or K's own accuracy (about cond x 1e-16) where M1 is ill-conditioned: the
    scalar kernel needs the same bound (it reaches 8e-9 at cond 1e9 on the symmetric variant)."""
    return np.maximum(1e-13, 2e-16 * cond)


def raw(h4: h4pin.H4, x: np.ndarray, model: str) -> tuple[kernel.KernelResult, kernel.KernelResult]:
    """The scalar and the vector batch kernel called directly (the public functions refuse
    non-finite poses before the compiled code sees them)."""
    G, code, n = kernel.prepare(h4.geometry).packed, kernel._model_code(model), len(x)
    a, b = kernel._empty(n, False, False), kernel._empty(n, False, False)
    kernel._batch(x, G, code, a.K, a.q, a.condition, a.status, packed.NO_TERMS_N, False, packed.NO_J_N, False,
                  kernel._BLOCK)
    vector._vbatch(x, G, code, b.K, b.q, b.condition, b.status, packed.NO_TERMS_N, False, packed.NO_J_N, False)
    return a, b


@pytest.fixture(scope="module", params=IDEAL)
def robot(request) -> h4pin.H4:
    return h4pin.load(request.param)


@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_fuzz_equals_reference(robot, model):
    x = fuzz(robot)
    ref = numpy_backend.backend(robot, x, model, False)
    res = vector_batch(robot.geometry, x, model)
    np.testing.assert_array_equal(res.status, ref.status)
    counts = np.bincount(res.status, minlength=5)
    assert counts[verdicts.OK] > 1000 and counts[verdicts.UNREACHABLE] > 1000 and counts[verdicts.LIMITS] > 1000
    assert counts[verdicts.INTERFERENCE] > 0
    ok = ref.status == verdicts.OK
    rel = per_pose_rel(res.K[ok], ref.matrix[ok])
    assert np.all(rel <= bound(ref.condition[ok])), float(np.max(rel / bound(ref.condition[ok])))
    well = ref.condition[ok] < 1e3
    assert well.sum() > 500 and rel[well].max() <= 1e-13
    assert np.all(np.isnan(res.K[~ok]))
    np.testing.assert_allclose(res.q, ref.q, rtol=0, atol=1e-12)  # NaN where unreachable, in both
    assert np.all(cond_rel(res.condition[ok], ref.condition[ok]) <= np.maximum(1e-10, 1e-16 * ref.condition[ok]))


@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_terms_equal_reference(proto, model):
    """With terms: each of the four terms as the numpy reference's (same bound as K), K their
    sum, NaN terms on refused poses; and the public batch call (which takes this kernel from
    VECTOR_FROM poses) gives the same terms."""
    x = fuzz(proto, 3000, seed=11)
    ref = numpy_backend.backend(proto, x, model, True)
    res = vector_batch(proto.geometry, x, model, terms=True)
    np.testing.assert_array_equal(res.status, ref.status)
    ok = ref.status == verdicts.OK
    assert ok.sum() > 300
    b = bound(ref.condition[ok])
    for t in range(4):
        scale = np.max(np.abs(ref.matrix[ok]), axis=(-2, -1))
        err = np.max(np.abs(res.terms[ok, t] - ref.terms[ok, t]), axis=(-2, -1)) / scale
        assert np.all(err <= b), (t, float(np.max(err / b)))
    np.testing.assert_allclose(res.terms[ok].sum(axis=1), res.K[ok], rtol=0,
                               atol=1e-15 * np.max(np.abs(res.K[ok])))
    assert np.all(np.isnan(res.terms[~ok]))
    api = h4pin.compliance(proto, x[ok][:200], model, terms=True, elements=False)
    for t, name in enumerate(("control", "bending", "torsion", "tension")):
        np.testing.assert_array_equal(api.terms[name], res.terms[ok][:200, t])


def test_singular_poses_are_found(sym):
    x = fuzz(sym)
    res = vector_batch(sym.geometry, x)
    assert np.sum(res.status == verdicts.SINGULAR) > 100
    assert np.all(~(res.condition[res.status == verdicts.SINGULAR] < verdicts.SINGULAR_COND))


@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_fuzz_equals_scalar_kernel(robot, model):
    """Every field as the scalar kernel, non-finite poses included (NaN: status 1, q and
    condition NaN, as the scalar kernel; the public API refuses them before)."""
    x = fuzz(robot, 4000, seed=3)
    rng = np.random.default_rng(4)
    nan_rows = rng.choice(len(x), 40, replace=False)
    x[nan_rows, rng.integers(0, 4, 40)] = np.nan
    x[nan_rows[:5]] = np.inf
    a, b = raw(robot, x, model)
    np.testing.assert_array_equal(b.status, a.status)
    assert np.all(b.status[nan_rows[5:]] == verdicts.UNREACHABLE)
    ok = a.status == verdicts.OK
    assert np.all(per_pose_rel(b.K[ok], a.K[ok]) <= bound(a.condition[ok]))
    np.testing.assert_array_equal(np.isnan(b.K), np.isnan(a.K))
    np.testing.assert_array_equal(np.isnan(b.q), np.isnan(a.q))
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.isnan(b.condition), np.isnan(a.condition))
    finite = np.isfinite(a.condition)
    np.testing.assert_array_equal(np.isfinite(b.condition), finite)
    c = a.condition[finite]
    assert np.all(cond_rel(b.condition[finite], c) <= np.maximum(1e-10, 1e-16 * c))


@pytest.mark.parametrize("n", [1, 3, 31, 32, 33, 1023, 1025, 2100])
def test_every_batch_length(proto, n):
    """Partial blocks (fewer poses than lanes) and partial parallel tasks give the same rows."""
    x = fuzz(proto, n, seed=n)
    a = kernel.compliance_batch(proto.geometry, x)
    b = vector_batch(proto.geometry, x)
    np.testing.assert_array_equal(b.status, a.status)
    ok = a.status == verdicts.OK
    assert np.all(per_pose_rel(b.K[ok], a.K[ok]) <= bound(a.condition[ok]))


def test_one_pose_and_threads(proto):
    import numba

    x = fuzz(proto, 3000, seed=5)
    one = vector_batch(proto.geometry, centre_pose(proto))
    assert one.K.shape == (1, 8, 8) and one.status[0] == verdicts.OK
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        serial = vector_batch(proto.geometry, x)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        parallel = vector_batch(proto.geometry, x)
    finally:
        numba.set_num_threads(before)
    for s, p in zip(serial, parallel, strict=True):
        if s is not None:
            np.testing.assert_array_equal(s, p)


def test_model_is_checked(proto):
    with pytest.raises(h4pin.ParameterError, match="model"):
        vector_batch(proto.geometry, centre_pose(proto), model="exact")


def test_atan2_matches_numpy():
    """The branch-free atan2 of the kernels: within 2 ulp of numpy's over eight decades of
    both arguments and all four quadrants, numpy's signed zeros on the axes, NaN in -> NaN out."""
    from numba import njit

    @njit(cache=False)
    def many(y, x):
        out = np.empty_like(y)
        for k in range(y.size):
            out[k] = core.atan2(y[k], x[k])
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
