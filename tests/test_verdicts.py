# SPDX-License-Identifier: Apache-2.0
"""One verdict per pose on every path, and what an accepted pose's K is worth."""

from __future__ import annotations

import numpy as np
import pytest

import h4pin
from h4pin import InterferenceError, JointLimitError, SingularPoseError, UnreachablePoseError
from h4pin.checks import statics
from h4pin.kinematics.closed_form import centre_pose
from h4pin.stiffness.api import SINGULAR_COND, compliance
from h4pin.verdicts import INTERFERENCE, LIMITS, OK, SINGULAR, UNREACHABLE

ERRORS = {UNREACHABLE: UnreachablePoseError, LIMITS: JointLimitError, INTERFERENCE: InterferenceError,
          SINGULAR: SingularPoseError}


def verdict(h4, x, method):
    """Status code of one pose from the single-pose API (the exception it raises)."""
    try:
        compliance(h4, x, "consistent", method=method)
    except (JointLimitError, InterferenceError, SingularPoseError) as exc:
        return next(k for k, e in ERRORS.items() if type(exc) is e)
    except UnreachablePoseError:
        return UNREACHABLE
    return OK


@pytest.mark.parametrize("name", ["prototype", "symmetric", "toleranced"])
def test_sweep_of_random_poses(name):
    """10 000 poses around and across the workspace boundary (and, for the symmetric variant,
    through its singular centre): every result is finite with a symmetric positive definite
    consistent K, or a typed verdict; the single-pose paths give the same verdicts."""
    h4 = h4pin.load(name)
    c = h4.forward_geometry(np.full(4, np.pi / 4))
    rng = np.random.default_rng(7)
    x = c + rng.uniform(-1, 1, (10_000, 4)) * [0.35, 0.35, 0.3, 1.2]
    x[:500] = c + rng.normal(0, 1, (500, 4)) * 10 ** rng.uniform(-12, -3, (500, 1))  # at and near the centre
    res = compliance(h4, x, "consistent", on_error="nan")
    ok = res.valid
    assert set(np.unique(res.status)) <= {OK, UNREACHABLE, LIMITS, INTERFERENCE, SINGULAR}
    assert np.sum(ok) > 1000 and np.sum(~ok) > 1000  # the sweep does cross the boundary
    k = res.matrix[ok]
    assert np.all(np.isfinite(k)) and np.all(np.isnan(res.matrix[~ok]))
    asym = np.max(np.abs(k - np.swapaxes(k, 1, 2)), axis=(1, 2)) / np.max(np.abs(k), axis=(1, 2))
    assert asym.max() < 1e-9
    # Positive definite to within K's accuracy (about cond x 1e-16 relative): the eigenvalues of
    # a pose near a singularity span many decades, and round-off bounds the smallest ones.
    eig = np.linalg.eigvalsh((k + np.swapaxes(k, 1, 2)) / 2)
    assert np.all(eig[:, 0] > -1e-14 * res.condition[ok] * eig[:, -1])
    assert np.mean(eig[:, 0] > 0) > 0.99
    assert np.all(res.condition[ok] < SINGULAR_COND)
    picks = rng.choice(len(x), 300, replace=False)
    for n in picks:
        assert verdict(h4, x[n], "closed_form") == res.status[n]
    for n in picks[:60]:
        assert verdict(h4, x[n], "pinocchio") == res.status[n]
    if name == "symmetric":
        assert np.sum(res.status[:500] == SINGULAR) > 0


def test_accepted_poses_near_a_singularity_are_accurate():
    """Approaching the symmetric variant's singular centre, cond(M1) grows like 1/distance; the
    verdict flips where it crosses SINGULAR_COND on both paths, and every accepted K still agrees
    with the independent statics route to 1e-6 (observed: about cond x 1e-17)."""
    sym = h4pin.load("symmetric")
    c = sym.forward_geometry(np.full(4, np.pi / 4))
    direction = np.array([1.0, 0.6, -0.3, 2.0]) * 1e-3
    # Down to 10 nm from the centre: closer than that, the distance is below the accuracy of the
    # centre itself (a singular forward geometry, ~1e-9 m) and cond stops growing.
    scales = np.logspace(0, -5, 20)
    poses = c + scales[:, None] * direction
    res = compliance(sym, poses, "consistent", on_error="nan")
    assert np.all(np.diff(np.log(res.condition)) > 0)  # closer is worse
    assert res.status[0] == OK and res.status[-1] == SINGULAR
    for n in range(len(poses)):
        assert verdict(sym, poses[n], "pinocchio") == res.status[n]
        if res.valid[n]:
            ref = statics.compliance_matrix(sym.geometry, poses[n])
            assert np.max(np.abs(res.matrix[n] - ref)) / np.max(np.abs(ref)) < 1e-6


@pytest.mark.parametrize(("pose", "error", "message"), [
    ([0.0, 0.0, 0.5, 0.0], JointLimitError, "actuator . would be at .* outside its joint limits"),
    ([0.0, 0.0, -0.58814, -1.720436729412], JointLimitError, "lateral bar 1 would turn by 1.720"),
    ([0.0, 0.0, -0.58814, -1.72044], JointLimitError, "outside its limits"),
    ([0.0, 0.0, -1.2, 0.0], UnreachablePoseError, "leg . cannot reach"),
])
def test_poses_the_robot_cannot_take_are_refused_with_the_reason(proto, pose, error, message):
    for method in ("closed_form", "pinocchio"):
        with pytest.raises(error, match=message):
            compliance(proto, pose, method=method)
    with pytest.raises(error, match=message):
        proto.configuration(pose)


def test_interfering_bars_are_refused(proto):
    """Bars of legs 1 and 2 cross when the plate swings far to -x, -y: the verdict names them and
    the distance, and equals a direct computation of the segment distances."""
    from h4pin.kinematics.closed_form import points, rigid_state, segment_distances

    c = centre_pose(proto)
    rng = np.random.default_rng(3)
    x = c + rng.uniform(-1, 1, (4000, 4)) * [0.35, 0.35, 0.3, 0.7]
    res = compliance(proto, x, on_error="nan")
    hit = np.flatnonzero(res.status == INTERFERENCE)
    assert hit.size > 0
    q = proto.inverse_geometry(x[hit[0]], check=False)
    pts = points(proto.geometry, rigid_state(x[hit[0]], q))
    a, b = pts.Aij.reshape(8, 3), pts.Bij.reshape(8, 3)
    d = min(segment_distances(a[m], b[m], a[n], b[n]) for m in range(8) for n in range(8) if m // 2 != n // 2)
    assert d < proto.geometry.bar_clearance
    with pytest.raises(InterferenceError, match=r"bars \d\d and \d\d interpenetrate"):
        compliance(proto, x[hit[0]])


def test_nan_poses_give_nan_rows(proto, centre):
    x = np.vstack([centre, [np.nan, 0, -0.6, 0], centre])
    res = compliance(proto, x, on_error="nan")
    assert res.valid.tolist() == [True, False, True] and np.isnan(res.matrix[1]).all()
    with pytest.raises(h4pin.PoseError, match="non-finite"):
        compliance(proto, x)


def test_condition_is_exposed(proto, centre):
    res = compliance(proto, centre)
    assert 1 < res.condition < 1e4
    batch = compliance(proto, np.vstack([centre, centre]))
    np.testing.assert_allclose(batch.condition, res.condition, rtol=1e-12)
