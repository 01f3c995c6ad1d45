# SPDX-License-Identifier: Apache-2.0
"""Design sweeps against the numpy reference of eq. 30; resume after a kill; local = Dask."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import h4pin
from h4pin.description.geometry import geometry_from_params
from h4pin.errors import ParameterError
from h4pin.kinematics import closed_form as geometry
from h4pin.stiffness.api import compliance
from h4pin.stiffness.matrices import from_points
from h4pin.studies import sweep

ROOT = Path(__file__).resolve().parent.parent
SPEC = sweep.Spec(n_designs=12, seed=3, chunk=4, task=sweep.Task(half=(0.2, 0.2, 0.1, 0.5), counts=(3, 3, 2, 2)),
                  volume=sweep.VolumeGrid(counts=(6, 6, 5)))


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    return sweep.run(tmp_path_factory.mktemp("sweep") / "s.zarr", SPEC, progress=False)


def bars_clear(params: h4pin.H4Params, x: np.ndarray, q: np.ndarray, clearance: float = 0.01) -> np.ndarray:
    """Bar axes of different legs at least ``clearance`` apart, by sampling one segment (201
    points) against the other in closed form (point to segment), per pose."""
    pts = geometry.points(geometry_from_params(params), geometry.rigid_state(x, q))
    a, b = pts.Aij.reshape(-1, 8, 3), pts.Bij.reshape(-1, 8, 3)
    s = np.linspace(0, 1, 201)[:, None]
    least = np.full(len(x), np.inf)
    for n in range(8):
        for m in range(2 * (n // 2) + 2, 8):
            p = a[:, None, n] + s * (b[:, None, n] - a[:, None, n])  # (N, 201, 3)
            d = (b[:, m] - a[:, m])[:, None, :]
            t = np.clip(np.sum((p - a[:, None, m]) * d, -1) / np.sum(d * d, -1), 0, 1)
            gap = np.linalg.norm(p - (a[:, None, m] + t[..., None] * d), axis=-1).min(axis=1)
            least = np.minimum(least, gap)
    return least >= clearance


def status_ok(params: h4pin.H4Params, x: np.ndarray) -> np.ndarray:
    """Status 0 by numpy: reachable, joint limits of the default geometry, bars clear, scaled
    cond(M1) < 1e9."""
    g = geometry_from_params(params)
    q = geometry.inverse_geometry(g, x, on_error="nan", check=False)
    ok = np.all(np.isfinite(q), axis=1)
    ok[ok] &= np.all((q[ok] >= -1) & (q[ok] <= 2), axis=1) & (np.abs(x[ok, 3]) <= np.pi / 4)
    idx = np.flatnonzero(ok)
    m = from_points(g, geometry.points(g, geometry.rigid_state(x[idx], q[idx])))
    scaled = m.M1 / m.l[..., :, None] * np.r_[np.ones(3), np.full(5, 1 / np.mean(params.l))]
    ok[idx] &= np.linalg.cond(scaled, 1) < 1e9
    idx = np.flatnonzero(ok)
    ok[idx] &= bars_clear(params, x[idx], q[idx])
    return ok


def test_sweep_equals_the_numpy_reference(local):
    task, grid = SPEC.task.poses(), SPEC.volume.poses()
    assert len(local["designs"]) == SPEC.n_designs and local["done"].all()
    assert local["reach_all"].sum() >= 3 and not local["reach_all"].all()
    for d, row in enumerate(local["designs"]):
        try:
            params = sweep.params_of(row)
        except ParameterError:
            assert not local["valid"][d]
            continue
        ok = status_ok(params, task)
        assert local["reach_all"][d] == ok.all() and local["task_ok"][d] == ok.sum()
        if ok.any():
            k = compliance(h4pin.load(params), task[ok], "consistent", method="closed_form").translational
            worst = np.linalg.eigvalsh((k + np.swapaxes(k, 1, 2)) / 2)[:, 2].max()
            assert abs(local["worst"][d] - worst) <= 1e-12 * worst
        assert local["volume"][d] == pytest.approx(status_ok(params, grid).sum() * SPEC.volume.cell, rel=1e-12)


def test_the_frequency_is_the_lowest_over_the_task_centre_and_16_corners():
    """``Spec.frequency``'s value is what docs/cli.md says: the lowest first natural frequency
    over the task box's centre and its 16 corners (built here from the box's centre and half
    sizes), those the design reaches; each design loaded from its parameters (a URDF) and its
    modes by the Pinocchio route (rtol 1e-9): one design that reaches all 17, one that misses 8."""
    import itertools

    task = sweep.Task(half=(0.2, 0.2, 0.1, 0.5))
    spec = sweep.Spec(n_designs=8, seed=3, task=task, frequency=True, volume=sweep.VolumeGrid(counts=(2, 2, 2)))
    rows = sweep.designs(spec)[[0, 3]]
    res = sweep.evaluate(rows, spec)
    poses = np.array([task.centre] + [np.add(task.centre, np.multiply(s, task.half))
                                      for s in itertools.product((-1.0, 1.0), repeat=4)])
    reached = []
    for d, row in enumerate(rows):
        f = h4pin.modes(h4pin.elastic_model(h4pin.load(sweep.params_of(row))), poses, method="pinocchio")
        ok = f.status == 0
        reached.append(int(ok.sum()))
        assert res["first_frequency"][d] == pytest.approx(np.min(f.first[ok]), rel=1e-9)
    assert reached == [9, 17]


def test_killed_sweep_resumes_to_the_same_numbers(local, tmp_path):
    path = tmp_path / "s.zarr"
    part = sweep.run(path, SPEC, stop_after=1, progress=False)  # "killed" after one chunk
    assert part["done"].tolist() == [True, False, False]
    assert np.all(np.isnan(part["worst"][SPEC.chunk:]))
    again = sweep.run(path, SPEC, stop_after=1, progress=False)
    assert again["done"].tolist() == [True, True, False]
    final = sweep.run(path, SPEC, progress=False)
    for name in ("designs", "valid", "reach_all", "worst", "volume", "task_ok", "done"):
        np.testing.assert_array_equal(final[name], local[name], err_msg=name)
    with pytest.raises(ParameterError, match="different sweep"):
        sweep.run(path, sweep.Spec(n_designs=12, seed=4, chunk=4), progress=False)


def test_two_dask_workers_give_the_same_numbers(local, tmp_path):
    dist = sweep.run(tmp_path / "d.zarr", SPEC, workers=2, progress=False)
    for name in ("designs", "valid", "reach_all", "worst", "volume", "task_ok", "done"):
        np.testing.assert_array_equal(dist[name], local[name], err_msg=name)


def test_pareto_front():
    res = {"reach_all": np.array([True, True, True, False, True]), "worst": np.array([1.0, 2.0, 1.5, 0.1, 3.0]),
           "volume": np.array([1.0, 3.0, 0.5, 9.0, 2.0])}
    np.testing.assert_array_equal(sweep.pareto(res), [0, 1])


def test_best_designs_are_loadable_urdf_variants(local, tmp_path):
    paths = sweep.write_best(local, tmp_path, k=2)
    assert 1 <= len(paths) <= 2
    front = sweep.pareto(local)
    for path in paths:
        d = int(path.stem.split("_")[-1])
        assert d in front
        h4 = h4pin.load(path)
        assert h4.params.allclose(sweep.params_of(local["designs"][d]), atol=1e-15)
        assert np.all(np.isfinite(h4.inverse_geometry(SPEC.task.poses())))


def test_cli_sweep(tmp_path):
    out = subprocess.run([sys.executable, "-m", "h4pin.cli", "sweep", "--out", str(tmp_path / "c.zarr"), "--designs",
                          "6", "--chunk", "3", "--quiet", "--figure", str(tmp_path / "p.png")],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    res = sweep.load(tmp_path / "c.zarr")
    assert f"2 of 2 chunks done; {res['valid'].sum()} valid designs" in out.stdout
    assert (tmp_path / "p.png").stat().st_size > 10_000


def test_packed_kernels_equal_the_canonical_route():
    """sweep.kernels runs the checks of H4Params, geometry_from_params and the packing of
    kernel.prepare over a design axis: the same validity as params_of (ParameterError) and,
    bit for bit, the same packed vectors as kernel.prepare(geometry_from_params(params_of(row))),
    over the default bounds and wider ones where about a quarter of the designs are invalid."""
    from h4pin.stiffness import kernel

    wide = {**sweep.BOUNDS, "half_width": (0.005, 0.09), "r": (0.1, 0.45), "l": (0.2, 0.8), "layout": (0.5, 1.6),
            "plate": (0.5, 2.0)}
    n_invalid = 0
    for bounds in (sweep.BOUNDS, wide):
        rows = sweep.designs(sweep.Spec(n_designs=600, seed=5, bounds=bounds))
        for row, kern in zip(rows, sweep.kernels(rows), strict=True):
            try:
                ref = kernel.prepare(geometry_from_params(sweep.params_of(row)))
            except ParameterError:
                assert kern is None
                n_invalid += 1
                continue
            np.testing.assert_array_equal(kern.packed, ref.packed)
            assert kern.geometry is None and not kern.packed.flags.writeable
    assert 50 < n_invalid < 600
    assert sweep.kernels(np.array([[0.09, 0.1, 0.2, 1.6, 0.5, 5e3]] * 3)) == [None] * 3  # no valid design


def test_designs_are_generated_once(tmp_path, monkeypatch):
    """The design table is made once, with the store; chunks (and a resumed run) read it."""
    calls = []
    real = sweep.designs
    monkeypatch.setattr(sweep, "designs", lambda spec: (calls.append(spec), real(spec))[1])
    path = tmp_path / "once.zarr"
    sweep.run(path, SPEC, stop_after=1, progress=False)
    assert len(calls) == 1
    res = sweep.run(path, SPEC, progress=False)
    assert len(calls) == 1 and res["done"].all()
    np.testing.assert_array_equal(res["designs"], real(SPEC))
