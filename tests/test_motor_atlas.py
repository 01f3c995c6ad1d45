# SPDX-License-Identifier: Apache-2.0
"""The motor-space atlas of any closed-loop robot (h4pin.mechanism.atlas) against routes that
share nothing with its loop: Mechanism.assemble and Mechanism.compliance called directly, the
loops' own closure errors, an uninterrupted run for a resumed one; its CLI and its figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import xarray as xr
from conftest import run_cli_in_process

from h4pin.errors import ParameterError
from h4pin.limits import TooLargeError
from h4pin.mechanism import Mechanism, store
from h4pin.mechanism import atlas as motor_atlas
from h4pin.mechanism.engine import UnassembledError

ROBOTS = Path(__file__).resolve().parent / "robots"
DELTA = ROBOTS / "robot_delta" / "robot.urdf"
FIVE_BAR = ROBOTS / "5bar_linkage_iso3d" / "robot.urdf"
TOOL = "closedloop3D_1B"


@pytest.fixture(scope="module")
def five_bar() -> Mechanism:
    return Mechanism.from_urdf(FIVE_BAR)


@pytest.fixture(scope="module")
def delta() -> Mechanism:
    return Mechanism.from_urdf(DELTA)


def test_stored_numbers_equal_the_direct_route(five_bar):
    """At every grid point: the stored configuration holds the motors at the grid's values and
    closes the loop; the worst compliance, the ellipsoid's radii and axes, and the output's
    position equal eigh of Mechanism.compliance and the frame placement at q from
    assemble(motors=...) called directly."""
    ds = motor_atlas.atlas(five_bar, TOOL, {"mot2": (-0.2, 0.2, 3), "mot1": (-0.1, 0.3, 4)}, progress=False,
                           frequency=True)
    assert (ds.status.values == motor_atlas.OK).all()
    springs = motor_atlas.default_springs(five_bar)
    assert springs == {n: 100.0 for n in list(five_bar.model.names)[1:]}
    ref = five_bar.assemble()
    d = five_bar.model.createData()
    for i, j in [(0, 0), (1, 2), (2, 3)]:
        m = [float(ds.mot2[i]), float(ds.mot1[j])]
        q = ds.configuration.values[i, j]
        assert max(max(e) for e in five_bar.closure_errors(q).values()) <= 1e-9
        direct = five_bar.assemble(ref, motors=m)
        np.testing.assert_allclose(q, direct, atol=1e-8)
        C = five_bar.compliance(direct, springs, [TOOL], method="pinocchio")[:3, :3]
        vals, vecs = np.linalg.eigh((C + C.T) / 2)
        np.testing.assert_allclose(ds.compliance_max.values[i, j], vals[2], rtol=1e-8)
        np.testing.assert_allclose(ds.compliance_axes.values[i, j], vals, rtol=1e-8, atol=1e-12 * vals[2])
        stored = ds.compliance_vectors.values[i, j]
        assert abs(np.linalg.det(stored) - 1) < 1e-12
        np.testing.assert_allclose(abs(stored[:, 1:].T @ vecs[:, 1:]), np.eye(2), atol=1e-6)  # up to sign
        pin.framesForwardKinematics(five_bar.model, d, direct)
        np.testing.assert_allclose(ds.position.values[i, j], d.oMf[five_bar.model.getFrameId(TOOL)].translation,
                                   atol=1e-8)
        f = five_bar.modes(direct, springs).first
        np.testing.assert_allclose(ds.first_frequency.values[i, j], f, rtol=1e-8)


def test_status_is_unassembled_exactly_where_the_loops_do_not_close(delta):
    """The delta over a wide range of one motor: where the atlas says unassembled, assembling
    from the reference fails too, and NaN stands everywhere but the verdict; elsewhere the
    stored configuration closes, holds the motors and every joint in its range."""
    ds = motor_atlas.atlas(delta, "eff", {"mot1_rod1": [-2.5], "mot1_rod2": (-2.5, 2.5, 9)}, progress=False)
    status = ds.status.values[0]
    assert (status == motor_atlas.UNASSEMBLED).sum() >= 1 and (status == motor_atlas.OK).sum() >= 5
    ref = delta.assemble()
    lo, hi = delta.ranges
    idx = [delta.model.joints[delta.model.getJointId(n)].idx_q for n in delta.actuated]
    for k, s in enumerate(status):
        m = [-2.5, float(ds.mot1_rod2[k])]
        if s == motor_atlas.UNASSEMBLED:
            with pytest.raises(UnassembledError):
                delta.assemble(ref, motors=m)
            for v in ("compliance_max", "compliance_axes", "position", "configuration"):
                assert np.isnan(ds[v].values[0, k]).all()
        else:
            q = ds.configuration.values[0, k]
            assert max(max(e) for e in delta.closure_errors(q).values()) <= 1e-9
            np.testing.assert_allclose(q[idx], m, atol=1e-12)
            assert not np.any((q < lo - 1e-9) | (q > hi + 1e-9))
            assert np.isfinite(ds.compliance_max.values[0, k])


def test_a_stopped_stream_resumes_to_the_uninterrupted_store(five_bar, tmp_path):
    """Stopped after one block (the partial store left, out not written), the next run computes
    only the blocks left (their seeds read from the store) and gives the in-memory atlas exactly;
    another grid restarts the partial store."""
    axes = {"mot2": (-0.3, 0.3, 4), "mot1": (-0.3, 0.3, 5)}
    whole = motor_atlas.atlas(five_bar, TOOL, axes, progress=False, chunk=5)
    out = tmp_path / "five.zarr"
    assert motor_atlas.stream(five_bar, TOOL, axes, out=out, chunk=5, progress=False, stop_after=1) is None
    assert store.partial_path(out).is_dir() and not out.exists()
    calls = []
    real = motor_atlas._Run.block

    def counted(self, points):
        calls.append(len(points))
        return real(self, points)

    motor_atlas._Run.block = counted
    try:
        resumed = motor_atlas.stream(five_bar, TOOL, axes, out=out, chunk=5, progress=False).load()
    finally:
        motor_atlas._Run.block = real
    assert calls == [5, 5, 5]
    xr.testing.assert_identical(resumed, whole)
    assert not store.partial_path(out).exists()
    store.check_out(out)  # an h4pin atlas: the H4 atlas's rule lets a run replace it
    again = motor_atlas.atlas(five_bar, TOOL, axes, progress=False, out=tmp_path / "five.nc")
    xr.testing.assert_identical(store.open_store(tmp_path / "five.nc"), again)


def test_bad_input_is_refused_by_name(five_bar):
    with pytest.raises(ParameterError, match="no frame 'nope'"):
        motor_atlas.atlas(five_bar, "nope", progress=False)
    with pytest.raises(ParameterError, match="'foo' is not a motor"):
        motor_atlas.atlas(five_bar, TOOL, {"foo": (0, 1, 3)}, progress=False)
    with pytest.raises(ParameterError, match="lower < upper"):
        motor_atlas.atlas(five_bar, TOOL, {"mot1": (1, 0, 3)}, progress=False)
    with pytest.raises(ParameterError, match="finite values"):
        motor_atlas.atlas(five_bar, TOOL, {"mot1": [0.0, np.nan]}, progress=False)
    with pytest.raises(TooLargeError, match="motor-space atlas of 1,000,000,000,000 points"):
        motor_atlas.atlas(five_bar, TOOL, {"mot1": (0, 1, 10**6), "mot2": (0, 1, 10**6)}, progress=False)
    with pytest.raises(ParameterError, match="joint_stiffness"):
        motor_atlas.default_springs(five_bar, 100.0, -1.0)
    assert motor_atlas.default_springs(five_bar, 5.0, 0.0) == {"mot2": 5.0, "mot1": 5.0}


def test_cli_writes_the_store_and_the_maps(tmp_path, monkeypatch, capsys):
    """h4pin atlas --robot on the delta: a .zarr store that opens as the atlas of the same grid,
    and one map per quantity; the H4's options are refused with it."""
    out = tmp_path / "delta.zarr"
    code, stdout, err = run_cli_in_process(
        ["atlas", "--robot", str(DELTA), "--output", "eff", "--motor", "mot1_rod1=-0.2:0.2:3", "--motor",
         "mot1_rod2=-0.2:0.2:4", "--out", str(out), "--figures", str(tmp_path), "--frequency", "--quiet"],
        monkeypatch, capsys)
    assert code == 0, err
    assert "12 of 12 grid points assembled" in stdout
    ds = store.open_store(out)
    assert motor_atlas.motors(ds) == ["mot1_rod1", "mot1_rod2"] and ds.status.shape == (3, 4)
    assert np.isfinite(ds.first_frequency.values).all()
    for q in ("compliance_max", "first_frequency", "status"):
        assert (tmp_path / f"atlas_{q}.png").stat().st_size > 5000
    code, _, err = run_cli_in_process(["atlas", "--robot", str(DELTA), "--output", "eff", "--x", "0", "1", "3"],
                                      monkeypatch, capsys)
    assert code == 2 and "--x is an option of the H4's atlas" in err
