# SPDX-License-Identifier: Apache-2.0
"""Tolerance study (h4pin.studies.tolerance): nominal with zero sigmas, single robots against the
one-robot routes (stiffness.compliance, forward_geometry on an H4 built for that robot),
seeded reproducibility, argument errors."""

from __future__ import annotations

import types

import numpy as np
import pytest

import h4pin
from h4pin import plots
from h4pin.description.params import H4Params
from h4pin.errors import ParameterError
from h4pin.stiffness.api import compliance
from h4pin.studies import tolerance

ZERO = {k: 0.0 for k in tolerance.KINDS}


@pytest.fixture(scope="module")
def poses(proto):
    return tolerance.default_poses(proto)[:4]


def test_zero_sigmas_is_nominal(proto, poses):
    res = tolerance.study(proto, poses, n_robots=3, sigmas=ZERO)
    ref = compliance(proto, poses).translational
    assert np.all(res.converged)
    assert np.max(np.abs(res.compliance - ref)) <= 1e-12 * np.max(np.abs(ref))
    assert np.max(np.abs(res.pose_error)) <= 1e-12
    assert np.max(res.tilt) <= 1e-12


@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_forearm_and_bar_draw_matches_h4params_robot(proto, poses, model):
    # Forearm length per leg and bar length per bar only: expressible as H4Params(r=..., l=...).
    sig = dict(ZERO, forearm=2e-4, l=1e-4, mismatch=1e-4)
    res = tolerance.study(proto, poses, n_robots=4, sigmas=sig, seed=7, model=model)
    batch = tolerance.sample(proto.geometry, 4, sig, seed=7)
    k = 2
    base = H4Params()
    r = np.linalg.norm(batch.A0[k].reshape(4, 2, 3).mean(axis=1) - proto.geometry.P, axis=1)
    h4k = h4pin.load(base.replace(r=r, l=batch.l[k]))
    assert not h4k.geometry.ideal
    ref = compliance(h4k, poses, model).translational
    assert np.max(np.abs(res.compliance[k] - ref)) <= 1e-10 * np.max(np.abs(ref))
    q_nom = compliance(proto, poses).q
    for m, x in enumerate(poses):
        fg = h4k.forward_geometry(q_nom[m])
        err = fg - x
        assert np.allclose(res.pose_error[k, m], err, rtol=1e-10, atol=1e-10 * np.max(np.abs(err)))
        assert np.max(np.abs(err)) > 1e-6  # a real error, not a trivial zero


def load_geometry(h4, g):
    """A robot whose geometry is ``g`` (the backends read only ``h4.geometry`` and ``h4.elements``)."""
    return types.SimpleNamespace(geometry=g, elements=h4.elements)


def test_joint_offsets_match_geometry_route(proto, poses):
    # All kinds at once: robot k alone as an H4Geometry through the numpy backend of compliance()
    # (solve, then the matrices and eq. 30) and forward_state.
    from h4pin.kinematics import closed_form as geometry

    res = tolerance.study(proto, poses, n_robots=3, seed=3)
    batch = tolerance.sample(proto.geometry, 3, None, seed=3)
    g = tolerance.robot_geometry(proto.geometry, batch, 1)
    from h4pin.stiffness.numpy_backend import backend

    raw = backend(load_geometry(proto, g), np.asarray(poses, float), "paper", False)  # the numpy route alone
    assert np.all(raw.status == 0)
    ref = raw.matrix[:, :3, :3]
    assert np.max(np.abs(res.compliance[1] - ref)) <= 1e-10 * np.max(np.abs(ref))
    q_nom = compliance(proto, poses).q
    for m, x in enumerate(poses):
        pose, state = geometry.forward_state(g, q_nom[m], x)
        assert np.allclose(res.pose_error[1, m], pose - x, rtol=1e-10, atol=1e-12)


def test_seeded_reproducible(proto, poses):
    a = tolerance.study(proto, poses, n_robots=20, seed=11)
    b = tolerance.study(proto, poses, n_robots=20, seed=11)
    c = tolerance.study(proto, poses, n_robots=20, seed=12)
    assert np.array_equal(a.compliance, b.compliance) and np.array_equal(a.pose_error, b.pose_error)
    assert not np.array_equal(a.pose_error, c.pose_error)


def test_report_and_sensitivity(proto, poses, tmp_path):
    res = tolerance.study(proto, poses[:2], n_robots=30)
    sens = tolerance.sensitivity(proto, poses[:2], n_robots=30)
    assert set(sens) == set(tolerance.KINDS)
    text = tolerance.report(res, sens)
    assert "p95" in text and "matters most" in text
    out = plots.tolerance(res, tmp_path / "t.png")
    assert out.stat().st_size > 1000


@pytest.mark.parametrize("sigmas", [{"l": -1e-5}, {"l": float("nan")}, {"bogus": 1e-5}, {"P": "x"}])
def test_bad_sigma_is_parameter_error(proto, sigmas):
    name = next(iter(sigmas))
    with pytest.raises(ParameterError, match=name):
        tolerance.study(proto, n_robots=2, sigmas=sigmas)


def test_bad_n_robots_and_model(proto):
    with pytest.raises(ParameterError, match="n_robots"):
        tolerance.study(proto, n_robots=0)
    with pytest.raises(ParameterError, match="model"):
        tolerance.study(proto, n_robots=2, model="nope")
