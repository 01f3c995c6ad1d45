# SPDX-License-Identifier: Apache-2.0
"""The workspace atlas against the reference compliance (eq. 30), its files, maps, viewer and CLI."""

from __future__ import annotations

import stat
import subprocess
import sys
from pathlib import Path

import matplotlib
import numpy as np
import pytest

from h4pin import plots, verdicts
from h4pin.errors import ParameterError
from h4pin.io import viewer, viewer_atlas
from h4pin.kinematics import closed_form as geometry
from h4pin.mechanism import store
from h4pin.stiffness.api import compliance
from h4pin.stiffness.matrices import from_points
from h4pin.studies import atlas

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def grid(centre):
    return {"x": np.linspace(-0.32, 0.32, 9), "y": np.linspace(-0.3, 0.3, 7), "z": [centre[2] - 0.1, centre[2]],
            "theta": [0.0, 0.4]}


@pytest.fixture(scope="module")
def ds(proto, grid):
    return atlas.atlas(proto, **grid, model="consistent", chunk=50, progress=False)


def test_values_equal_the_reference_at_the_grid_points(proto, ds):
    """Every reachable grid point: the five quantities from h4pin.compliance (numpy) and eq. 8."""
    stacked = ds.stack(p=("theta", "z", "y", "x"))
    poses = np.stack([stacked.x.values, stacked.y.values, stacked.z.values, stacked.theta.values], axis=1)
    ok = stacked.status.values == verdicts.OK
    assert 20 < ok.sum() < len(ok)
    x = poses[ok]
    ref = compliance(proto, x, "consistent")
    ktt = ref.translational
    lam = np.linalg.eigvalsh((ktt + np.swapaxes(ktt, 1, 2)) / 2)
    np.testing.assert_allclose(stacked.compliance_max.values[ok], lam[:, 2], rtol=1e-11)
    np.testing.assert_allclose(stacked.isotropy.values[ok], lam[:, 0] / lam[:, 2], rtol=1e-10)
    np.testing.assert_allclose(stacked.stiffness_z.values[ok], 1 / ref.matrix[:, 2, 2], rtol=1e-11)
    m = from_points(proto.geometry, geometry.points(proto.geometry, geometry.rigid_state(x, ref.q)))
    np.testing.assert_allclose(stacked.cond_J.values[ok], np.linalg.cond(m.J), rtol=1e-9)
    scaled = m.M1 / m.l[..., :, None] * np.r_[np.ones(3), np.full(5, 1 / np.mean(m.l))]
    np.testing.assert_allclose(stacked.cond_M1.values[ok], np.linalg.cond(scaled, 1), rtol=1e-9)


def test_unreachable_points_are_nan_with_their_status(proto, ds):
    stacked = ds.stack(p=("theta", "z", "y", "x"))
    poses = np.stack([stacked.x.values, stacked.y.values, stacked.z.values, stacked.theta.values], axis=1)
    q = geometry.inverse_geometry(proto.geometry, poses, on_error="nan", check=False)
    unreachable = np.any(np.isnan(q), axis=1)
    assert unreachable.sum() > 10
    np.testing.assert_array_equal(stacked.status.values == verdicts.UNREACHABLE, unreachable)
    for q in atlas.QUANTITIES:
        assert np.all(np.isnan(stacked[q].values[unreachable])), q
        if q != "cond_M1":
            assert np.all(np.isnan(stacked[q].values[stacked.status.values != verdicts.OK])), q
    assert ds.compliance_max.attrs["units"] == "m/N" and ds.stiffness_z.attrs["units"] == "N/m"
    assert ds.x.attrs["units"] == "m" and ds.theta.attrs["units"] == "rad"


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_file_round_trip(ds, tmp_path, suffix):
    path = store.save(ds, tmp_path / f"a{suffix}")
    back = store.open_store(path)
    assert back.identical(ds) if suffix == ".nc" else back.equals(ds)
    for q in (*atlas.QUANTITIES, "status"):
        assert back[q].attrs["units"] == ds[q].attrs["units"]
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    assert files and all(stat.S_IMODE(p.stat().st_mode) == 0o644 for p in files)
    store.save(ds.isel(x=slice(0, 3)), path)  # overwrite in place
    assert store.open_store(path).sizes["x"] == 3
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left behind


def test_bad_arguments_are_typed(proto, tmp_path, ds):
    with pytest.raises(ParameterError, match="path"):
        store.save(ds, tmp_path / "a.csv")
    with pytest.raises(ParameterError, match="x"):
        atlas.atlas(proto, [], [0.0], [-0.6])
    with pytest.raises(ParameterError, match="quantity"):
        viewer_atlas.atlas_points(ds, "softness")


def test_maps_have_one_figure_per_quantity(ds, tmp_path):
    paths = plots.atlas_maps(ds, tmp_path)
    assert sorted(p.name for p in paths) == sorted(f"atlas_{q}.png" for q in (*atlas.QUANTITIES, "status"))
    img = matplotlib.image.imread(paths[0])
    assert img.shape[0] > 200 and img[..., :3].std() > 0.05  # a picture, not a blank page


def test_viewer_point_cloud(proto, ds):
    positions, colours, lo, hi = viewer_atlas.atlas_points(ds, "compliance_max", theta=0.4)
    sl = ds.sel(theta=0.4)
    ok = sl.status.values == verdicts.OK
    assert positions.shape == (3, ok.sum()) and colours.shape == (3, ok.sum())
    values = sl.compliance_max.values[ok]
    assert lo >= values.min() * (1 - 1e-12) and hi <= values.max() * (1 + 1e-12) and lo < hi
    z, y, x = np.meshgrid(sl.z.values, sl.y.values, sl.x.values, indexing="ij")
    np.testing.assert_array_equal(positions, np.stack([x[ok], y[ok], z[ok]]))
    darkest = np.argmin(values)  # the stiffest point is drawn in viridis' darkest colour
    np.testing.assert_allclose(colours[:, darkest], matplotlib.colormaps["viridis"](0.0)[:3])
    with viewer.scene(proto) as scene:
        assert viewer_atlas.show_atlas(scene, ds, "compliance_max", theta=0.4) == (lo, hi)
        assert "atlas: compliance_max" in scene.legend[-1]


def test_the_viewer_draws_the_quantities_the_atlas_holds(proto, ds):
    """The point cloud's quantities are the store's data variables with their units: the atlas's
    five; a variable added to the store is drawn (twice the compliance: twice the range, the same
    colours), one dropped from it is refused, and the legend gives the stored unit."""
    assert viewer_atlas.quantities(ds) == {q: unit for q, (unit, _) in atlas.QUANTITIES.items()}
    extra = ds.assign(doubled=(ds.compliance_max.dims, 2 * ds.compliance_max.values, {"units": "m/N (twice)"}))
    _, colours, lo, hi = viewer_atlas.atlas_points(extra, "doubled", theta=0.4)
    _, colours_1, lo_1, hi_1 = viewer_atlas.atlas_points(extra, "compliance_max", theta=0.4)
    np.testing.assert_allclose([lo, hi], [2 * lo_1, 2 * hi_1], rtol=1e-12)
    np.testing.assert_allclose(colours, colours_1, rtol=0, atol=1e-12)
    with pytest.raises(ParameterError, match="quantity must be one of the atlas's"):
        viewer_atlas.atlas_points(ds.drop_vars("cond_J"), "cond_J")
    with viewer.scene(proto) as scene:
        viewer_atlas.show_atlas(scene, extra, "doubled", theta=0.4)
        assert scene.legend[-1].endswith("m/N (twice)")


def test_cli_writes_the_atlas(proto, tmp_path):
    out = subprocess.run([sys.executable, "-m", "h4pin.cli", "atlas", "--x", "-0.1", "0.1", "3", "--y", "0", "0.1",
                          "2", "--z", "-0.6", "--theta", "0.2", "--out", str(tmp_path / "a.nc"), "--quiet"],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "6 of 6 poses reachable" in out.stdout
    got = store.open_store(tmp_path / "a.nc")
    want = atlas.atlas(proto, [-0.1, 0.0, 0.1], [0.0, 0.1], [-0.6], [0.2], progress=False)
    assert got.equals(want)


def test_a_toleranced_robot_goes_through_the_numpy_path(grid):
    """The kernel needs exact parallelograms; a toleranced robot's atlas comes from the numpy path
    and equals h4pin.compliance and the statics route at its grid points."""
    import h4pin
    from h4pin.checks import statics

    tol = h4pin.load("toleranced")
    small = {"x": grid["x"][2:6], "y": grid["y"][2:5], "z": grid["z"][1:], "theta": [0.0]}
    res = atlas.atlas(tol, **small, model="consistent", progress=False).stack(p=("theta", "z", "y", "x"))
    poses = np.stack([res.x.values, res.y.values, res.z.values, res.theta.values], axis=1)
    ok = res.status.values == verdicts.OK
    assert ok.sum() >= 6
    ref = compliance(tol, poses[ok], "consistent", method="closed_form")
    lam = np.linalg.eigvalsh(ref.translational)
    np.testing.assert_allclose(res.compliance_max.values[ok], lam[:, 2], rtol=1e-12)
    k = statics.compliance_matrix(tol.geometry, poses[np.flatnonzero(ok)[0]])
    assert abs(res.stiffness_z.values[ok][0] * k[2, 2] - 1.0) < 1e-9


# ---------------------------------------------------------------------------------------------
# Compiled derived quantities (h4pin.studies._derived) and the streamed atlas.


def _exact_roots(coefficients, estimates):
    """Roots of the polynomial sum c_k x^(n-k) (exact Fractions) near each estimate, by bisection
    in 90-digit decimals on [estimate / 2, 2 estimate]."""
    from decimal import Decimal, localcontext

    with localcontext() as ctx:
        ctx.prec = 90
        c = [Decimal(f.numerator) / Decimal(f.denominator) for f in coefficients]

        def p(x):
            acc = Decimal(0)
            for ck in c:
                acc = acc * x + ck
            return acc

        roots = []
        for est in estimates:
            lo, hi = Decimal(float(est)) / 2, Decimal(float(est)) * 2
            flo = p(lo)
            assert flo * p(hi) < 0, "the estimate does not bracket a root"
            for _ in range(320):
                mid = (lo + hi) / 2
                if (p(mid) < 0) == (flo < 0):
                    lo = mid
                else:
                    hi = mid
            roots.append(float((lo + hi) / 2))
    return roots


def _exact(a):
    """The entries of the float matrix a as exact Fractions."""
    from fractions import Fraction

    return [[Fraction(float(v)) for v in row] for row in np.asarray(a)]


def _charpoly(m):
    """Characteristic polynomial of the square matrix m of Fractions (exact, Faddeev-LeVerrier)."""
    from fractions import Fraction

    n = len(m)
    mk = [[Fraction(0)] * n for _ in range(n)]
    c = [Fraction(1)]
    for k in range(1, n + 1):
        mk = [[sum(m[i][l] * mk[l][j] for l in range(n)) + (c[-1] if i == j else 0) for j in range(n)]
              for i in range(n)]
        c.append(-sum(sum(m[i][l] * mk[l][i] for l in range(n)) for i in range(n)) / k)
    return c


def _rotation(rng, n):
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return q


def _sym3(a):
    return atlas._derived.sym3_eigvals(a[0, 0], a[0, 1], a[0, 2], a[1, 1], a[1, 2], a[2, 2])


def test_sym3_eigenvalues_equal_eigvalsh_and_the_exact_ones():
    """Jacobi eigenvalues of symmetric 3x3: to 1e-10 relative of numpy's eigvalsh when the matrix
    is well conditioned or nearly degenerate (exactly repeated eigenvalues included). Against the
    exact eigenvalues (90-digit roots of the exact characteristic polynomial) of positive definite
    matrices of condition up to 1e8: the largest to 1e-14 relative, the others to 1e-15 of the
    largest (as eigvalsh), and every one to 1e-12 relative when the matrix is graded."""
    rng = np.random.default_rng(7)
    cases = [np.diag([3.0, 1.0, 2.0]), np.eye(3) * 2.5, np.diag([1.0, 1.0, 4.0]), np.zeros((3, 3))]
    for _ in range(300):
        q = _rotation(rng, 3)
        for lam in (rng.uniform(-1, 1, 3), np.array([1.0, 1.0 + 1e-9 * rng.normal(), 2.0]),
                    1.0 + 1e-13 * rng.normal(size=3), np.array([2.0, 2.0, -1.0])):
            cases.append((q * lam) @ q.T)
    for a in cases:
        a = (a + a.T) / 2
        ref = np.linalg.eigvalsh(a)
        got = np.array(_sym3(a))
        np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-15 * np.abs(ref).max())
    for cond in (1e4, 1e6, 1e8):
        for _ in range(5):
            q = _rotation(rng, 3)
            a = (q * np.array([1.0, 1.0 / np.sqrt(cond), 1.0 / cond])) @ q.T * 1e-6  # m/N-like scale
            a = (a + a.T) / 2
            got = np.array(_sym3(a))
            exact = np.array(_exact_roots(_charpoly(_exact(a)), np.linalg.eigvalsh(a)))
            assert abs(got[-1] / exact[-1] - 1) < 1e-14
            np.testing.assert_allclose(got, exact, rtol=0, atol=1e-15 * exact[-1])  # as eigvalsh: eps * |K|
            # graded: ill-conditioned by the scales of its rows and columns; Jacobi keeps every
            # eigenvalue to 1e-12 relative (Demmel and Veselic)
            d = np.geomspace(1.0, 1.0 / np.sqrt(cond), 3)[rng.permutation(3)]
            b = (q * rng.uniform(1, 2, 3)) @ q.T
            g = d[:, None] * ((b + b.T) / 2) * d[None, :]
            exact = _exact_roots(_charpoly(_exact(g)), np.linalg.eigvalsh(g))
            np.testing.assert_allclose(_sym3(g), exact, rtol=1e-12)


def test_design_reduce_prunes_without_changing_the_worst():
    """The sweep's reduction (:func:`_derived.design_reduce`) skips a pose when an upper bound on
    its largest eigenvalue is not above the worst so far: the bound holds on every kind of K_tt
    (nearly scalar ones, where the Wolkowicz-Styan bound is tight, indefinite, non-symmetric),
    and the worst equals eigvalsh's over all the task poses, the counts those of the status."""
    rng = np.random.default_rng(11)
    n = 3000
    K = np.zeros((n, 8, 8))
    for p in range(n):
        q = _rotation(rng, 3)
        kind = p % 3
        lam = (rng.uniform(0.5, 2, 3) if kind == 0 else 1.0 + 1e-12 * rng.normal(size=3) if kind == 1
               else rng.uniform(-1, 1, 3))
        K[p, :3, :3] = (q * lam) @ q.T * 1e-6 + rng.normal(size=(3, 3)) * 1e-8  # non-symmetric too
    sym = (K[:, :3, :3] + np.swapaxes(K[:, :3, :3], 1, 2)) / 2
    lam_max = np.linalg.eigvalsh(sym)[:, 2]
    bound = np.array([atlas._derived._ktt_bound(K, p) for p in range(n)])
    assert np.all(bound >= lam_max)
    status = rng.choice(np.array([0, 0, 0, 1, 3], dtype=np.int8), n)
    for n_task in (1, 2000, n):
        ok = status[:n_task] == 0
        n_ok, worst, n_grid = atlas._derived.design_reduce(K, status, n_task)
        assert n_ok == ok.sum() and n_grid == (status[n_task:] == 0).sum()
        if ok.any():
            assert abs(worst / lam_max[:n_task][ok].max() - 1) < 1e-13
        else:
            assert np.isnan(worst)


def _exact_cond(a):
    """2-norm condition number of the 4x4 a: the exact eigenvalues of a^T a (Fractions)."""
    f = _exact(a)
    gram = [[sum(f[k][i] * f[k][j] for k in range(4)) for j in range(4)] for i in range(4)]
    lam = np.linalg.svd(a, compute_uv=False) ** 2
    hi, lo = _exact_roots(_charpoly(gram), [lam[0], lam[-1]])
    return float(np.sqrt(hi / lo))


def test_cond4_equals_numpy_and_the_exact_condition_number():
    """One-sided Jacobi cond of 4x4: within 1e-9 relative of np.linalg.cond up to cond 1e6; at
    cond 1e8 both are only good to about eps * cond of the exact value (the 4x4 in floats), so
    there it is held to the exact one: 1e-8 for any matrix, 1e-13 for one ill-conditioned by its
    rows' scales (as J of eq. 8, m/rad and rad/rad) -- numpy's is 1e-8 there too."""
    cond4 = atlas._derived.cond4
    rng = np.random.default_rng(11)
    for c in (1.0, 1e2, 1e4, 1e6):
        for _ in range(50):
            a = (_rotation(rng, 4) * np.geomspace(1, 1 / c, 4)) @ _rotation(rng, 4) * 10 ** rng.uniform(-3, 3)
            assert cond4(a) == pytest.approx(np.linalg.cond(a), rel=1e-9)
    numpy_worst = 0.0
    for _ in range(10):
        a = (_rotation(rng, 4) * np.geomspace(1, 1e-8, 4)) @ _rotation(rng, 4)
        exact = _exact_cond(a)
        assert cond4(a) == pytest.approx(exact, rel=1e-8)
        graded = np.diag(np.geomspace(1, 1e-8, 4)[rng.permutation(4)]) @ (
            (_rotation(rng, 4) * rng.uniform(1, 3, 4)) @ _rotation(rng, 4))
        exact = _exact_cond(graded)
        assert cond4(graded) == pytest.approx(exact, rel=1e-13)
        numpy_worst = max(numpy_worst, abs(np.linalg.cond(graded) / exact - 1))
    assert numpy_worst > 1e-12  # the exact route is needed: numpy's own error is larger than 1e-13
    assert cond4(np.diag([1.0, 2.0, 3.0, 0.0])) == np.inf
    assert np.isnan(cond4(np.full((4, 4), np.nan)))
    np.testing.assert_allclose(atlas._derived.singular_values4(a), np.linalg.svd(a, compute_uv=False), rtol=0,
                               atol=1e-15)


def test_streamed_atlas_equals_the_one_in_memory(proto, grid, ds, tmp_path):
    """A .zarr atlas streamed block by block (blocks of whole rows, or pieces of a row when a row
    is longer than a chunk) equals the atlas in memory, is opened lazily, leaves no partial store."""
    for chunk in (50, 4):  # 50: 5 rows of 9 per block; 4: pieces of rows (4 + 4 + 1 poses)
        path = tmp_path / f"s{chunk}.zarr"
        got = atlas.atlas(proto, **grid, model="consistent", chunk=chunk, progress=False, out=path)
        assert got.chunks["y"][0] == (5 if chunk == 50 else 1) and got.chunks["x"][0] == min(9, chunk)
        assert type(got.compliance_max.data).__module__.startswith("dask")
        assert got.equals(ds) and store.open_store(path).equals(ds)
        assert got.attrs == ds.attrs and got.status.attrs["flag_meanings"] == ds.status.attrs["flag_meanings"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s4.zarr", "s50.zarr"]
    files = [p for p in (tmp_path / "s4.zarr").rglob("*") if p.is_file()]
    assert all(stat.S_IMODE(p.stat().st_mode) == 0o644 for p in files)


def test_a_killed_stream_resumes_from_its_blocks(proto, grid, ds, tmp_path, monkeypatch):
    """Killed after 3 blocks (an exception in the 4th), a streamed atlas leaves its partial store
    and no target; the next run computes only the blocks not done and gives the same atlas; a run
    with another grid at the same path starts the partial store anew."""
    path = tmp_path / "k.zarr"
    real = atlas._derived.atlas_fields
    calls = []

    def killed_at_4(*args):
        calls.append(len(args[2]))
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(*args)

    monkeypatch.setattr(atlas._derived, "atlas_fields", killed_at_4)
    with pytest.raises(KeyboardInterrupt):
        atlas.stream(proto, **grid, model="consistent", chunk=18, progress=False, out=path)
    assert not path.exists() and store.partial_path(path).is_dir()
    n_blocks = 2 * 2 * 4  # theta x z x ceil(7 rows / 2 rows per block)
    calls.clear()
    monkeypatch.setattr(atlas._derived, "atlas_fields", lambda *a: (calls.append(len(a[2])), real(*a)))
    got = atlas.stream(proto, **grid, model="consistent", chunk=18, progress=False, out=path)
    assert len(calls) == n_blocks - 3 and sum(calls) == ds.status.size - 3 * 18
    assert got.equals(ds) and not store.partial_path(path).exists()
    with pytest.raises(KeyboardInterrupt):  # another grid, killed: its partial store is left
        calls.clear()
        monkeypatch.setattr(atlas._derived, "atlas_fields", killed_at_4)
        atlas.stream(proto, **grid, model="paper", chunk=18, progress=False, out=path)
    monkeypatch.setattr(atlas._derived, "atlas_fields", real)
    small = {**grid, "x": grid["x"][:3]}
    got = atlas.stream(proto, **small, model="consistent", chunk=18, progress=False, out=path)
    assert got.equals(ds.isel(x=slice(0, 3)))  # the paper-model partial store was not resumed
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.zarr"]
