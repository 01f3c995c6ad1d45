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

from h4pin import verdicts
from h4pin.errors import ParameterError
from h4pin.io import viewer, viewer_atlas
from h4pin.kinematics import closed_form as geometry
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
    path = atlas.save(ds, tmp_path / f"a{suffix}")
    back = atlas.open_atlas(path)
    assert back.identical(ds) if suffix == ".nc" else back.equals(ds)
    for q in (*atlas.QUANTITIES, "status"):
        assert back[q].attrs["units"] == ds[q].attrs["units"]
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    assert files and all(stat.S_IMODE(p.stat().st_mode) == 0o644 for p in files)
    atlas.save(ds.isel(x=slice(0, 3)), path)  # overwrite in place
    assert atlas.open_atlas(path).sizes["x"] == 3
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left behind


def test_bad_arguments_are_typed(proto, tmp_path, ds):
    with pytest.raises(ParameterError, match="path"):
        atlas.save(ds, tmp_path / "a.csv")
    with pytest.raises(ParameterError, match="x"):
        atlas.atlas(proto, [], [0.0], [-0.6])
    with pytest.raises(ParameterError, match="quantity"):
        viewer_atlas.atlas_points(ds, "softness")


def test_maps_have_one_figure_per_quantity(ds, tmp_path):
    paths = atlas.plot(ds, tmp_path)
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
    with viewer.Scene(proto) as scene:
        assert viewer_atlas.show_atlas(scene, ds, "compliance_max", theta=0.4) == (lo, hi)
        assert "atlas: compliance_max" in scene.legend[-1]


def test_cli_writes_the_atlas(proto, tmp_path):
    out = subprocess.run([sys.executable, "-m", "h4pin.cli", "atlas", "--x", "-0.1", "0.1", "3", "--y", "0", "0.1",
                          "2", "--z", "-0.6", "--theta", "0.2", "--out", str(tmp_path / "a.nc"), "--quiet"],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "6 of 6 poses reachable" in out.stdout
    got = atlas.open_atlas(tmp_path / "a.nc")
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
