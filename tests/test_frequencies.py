# SPDX-License-Identifier: Apache-2.0
"""The compiled twin of the natural frequencies (h4pin.stiffness.frequencies) against the
Pinocchio route (h4pin.elastic.modes: crba on the elastic model, null space, static
condensation): every frequency, at 50 poses of every robot the twin takes, with and without the
optional elements and a payload; a point mass on massless links against the translational
compliance; the batch against one pose at a time."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import sample_poses

import h4pin
from h4pin import verdicts
from h4pin.description.elements import ILLUSTRATIVE
from h4pin.elastic.modal import modes as pinocchio_modes
from h4pin.stiffness import frequencies as fr

IDEAL = [name for name in h4pin.VARIANTS if h4pin.load(name).geometry.ideal]
PAYLOAD = h4pin.Payload(0.5, com=(0.01, -0.02, 0.03), inertia=np.diag([1e-3, 2e-3, 2.5e-3]))


@pytest.fixture(scope="module", params=IDEAL)
def robot(request) -> h4pin.H4:
    return h4pin.load(request.param)


@pytest.mark.parametrize("elements", [None, ILLUSTRATIVE], ids=["eq30", "elements"])
@pytest.mark.parametrize("payload", [None, PAYLOAD], ids=["bare", "payload"])
def test_every_frequency_equals_the_pinocchio_route(robot, elements, payload):
    """At least 50 poses with cond(M1) < 1e4: the same massive count and every frequency within
    1e-8 relative (measured 1e-12 bare, 1e-10 with every element kind on the prototype); at
    every pose within what the two routes can resolve where that is looser. The twin computes
    mu = 1 / (2 pi f)^2 (a flexibility): mu is known to eps times the largest, so f to
    ``eps (f / f_min)^2``; the Pinocchio route computes omega^2 (a stiffness), so f to
    ``eps (f_max / f)^2``; and both move by ``eps cond(M1)^2`` near a singularity. The element
    kinds give 4 to 6 directions with almost no mass, at 1e3 to 3e5 times the first frequency (a
    5e-8 kg.m^2 universal-joint cross turning on a 1e-8 m/N joint), and on the symmetric variant
    a first mode of 0.3 to 9 Hz beside modes of 1e5 Hz."""
    h4 = robot if elements is None else robot.with_elements(elements)
    xs = sample_poses(h4, 80, seed=31)
    cond = h4pin.compliance(h4, xs, elements=False).condition
    assert np.sum(cond < 1e4) >= 50
    got = h4pin.modes(h4, xs, payload, method="compiled")
    assert isinstance(got, h4pin.Modes) and np.all(got.status == verdicts.OK)
    em = h4pin.elastic_model(h4)
    worst = 0.0
    for k, x in enumerate(xs):
        ref = pinocchio_modes(em, x, payload).frequencies
        assert got.massive[k] == len(ref)
        eps = np.finfo(float).eps
        spread = np.maximum(ref / ref[0], ref[-1] / ref) ** 2
        bound = np.maximum(np.maximum(1e-8, 16 * eps * spread), eps * cond[k] ** 2)
        worst = max(worst, float(np.max(np.abs(got.frequencies[k, :got.massive[k]] / ref - 1) / bound)))
        assert np.all(np.isnan(got.frequencies[k, got.massive[k]:]))
    assert worst <= 1.0, worst


def test_a_point_mass_on_massless_links_is_the_translational_compliance(proto, centre):
    """Massless links and a point mass m at D: three modes, omega^2 the eigenvalues of
    (m K_tt)^-1, K_tt the translational block of the consistent compliance (the hand formula of a
    mass on a 3-D spring)."""
    m = 2.0
    got = h4pin.modes(proto, centre, h4pin.Payload(m), link_inertias=False, method="compiled")
    ktt = h4pin.compliance(proto, centre, "consistent").translational
    want = np.sqrt(1.0 / np.linalg.eigvalsh(m * ktt))[::-1] / (2 * np.pi)
    np.testing.assert_allclose(got.frequencies, np.sort(want), rtol=1e-10)
    assert got.condensed == 16 - 3


def test_one_pose_and_a_batch_agree_and_refused_poses_are_nan(proto, centre):
    xs = np.vstack([sample_poses(proto, 6, seed=2), [centre + [0, 0, 0.5, 0]]])  # the last one unreachable
    batch = h4pin.modes(proto, xs)
    assert batch.status[-1] == verdicts.UNREACHABLE and np.all(np.isnan(batch.frequencies[-1]))
    assert batch.massive[-1] == 0 and np.isnan(batch.first[-1])
    for k in range(6):
        one = h4pin.modes(proto, xs[k])
        np.testing.assert_allclose(one.frequencies, batch.frequencies[k, :batch.massive[k]], rtol=1e-13)
    with pytest.raises(h4pin.UnreachablePoseError):
        h4pin.modes(proto, xs[-1])


def test_shapes_come_from_the_pinocchio_route_on_first_access(proto, centre):
    one = h4pin.modes(proto, centre, PAYLOAD)
    assert callable(one.shapes)  # not computed yet
    ref = pinocchio_modes(proto, centre, PAYLOAD)
    np.testing.assert_allclose(one.shapes_tp, ref.shapes_tp, rtol=0, atol=1e-12 * np.abs(ref.shapes_tp).max())
    np.testing.assert_allclose(one.frequencies, ref.frequencies, rtol=1e-10)
    assert one.condensed == ref.condensed


def test_methods_and_robots():
    tol = h4pin.load("toleranced")
    x = h4pin.kinematics.closed_form.centre_pose(tol)
    assert not tol.geometry.ideal
    ref = pinocchio_modes(tol, x)
    np.testing.assert_array_equal(h4pin.modes(tol, x).frequencies, ref.frequencies)  # auto: Pinocchio
    with pytest.raises(h4pin.ParameterError, match="exact"):
        h4pin.modes(tol, x, method="compiled")
    with pytest.raises(h4pin.ParameterError, match="method"):
        h4pin.modes(tol, x, method="fast")
    with pytest.raises(h4pin.ParameterError, match="robot"):
        h4pin.modes("prototype", x)
    em = h4pin.elastic_model(h4pin.load())
    c = h4pin.kinematics.closed_form.centre_pose(em.robot)
    np.testing.assert_allclose(h4pin.modes(em, c).frequencies, pinocchio_modes(em, c).frequencies, rtol=1e-10)


def test_a_designs_mass_model_is_its_urdfs():
    """The mass model and configuration constants built from an H4Params (the design sweep's,
    without writing or loading a URDF) equal those read from the URDF it writes, and so do the
    frequencies."""
    from h4pin.kinematics import pinocchio as kin
    from h4pin.studies import sweep

    for row in sweep.designs(sweep.Spec(n_designs=8))[:4]:
        params = sweep.params_of(row)
        h4 = h4pin.load(params)
        MP, CF, CI = fr.pack_masses_params(params, PAYLOAD)
        np.testing.assert_allclose(MP, fr.pack_masses(h4, PAYLOAD), rtol=0, atol=1e-15)
        cf, ci = kin.configuration_pack(h4)
        np.testing.assert_allclose(CF[:156], cf[:156], rtol=0, atol=1e-15)
        np.testing.assert_array_equal(CI[:8], ci[:8])


def test_the_atlas_and_the_frequency_map_carry_the_first_frequency(proto, centre, tmp_path):
    """The atlas's first_frequency field (in memory and streamed to zarr) is h4pin.modes's first
    frequency at its grid points; NaN where the status is not 0."""
    from h4pin.studies import atlas

    xs = np.linspace(-0.3, 0.3, 7)
    ds = atlas.atlas(proto, xs, xs[:4], centre[2], 0.1, progress=False, frequency=True)
    gy, gx = np.meshgrid(xs[:4], xs, indexing="ij")
    poses = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, centre[2]), np.full(gx.size, 0.1)], axis=1)
    ref = h4pin.modes(proto, poses, method="pinocchio")
    got = ds.first_frequency.values.reshape(-1)
    np.testing.assert_array_equal(ds.status.values.reshape(-1), ref.status)
    ok = ref.status == 0
    assert 0 < ok.sum() < len(ok)
    np.testing.assert_allclose(got[ok], ref.first[ok], rtol=1e-10)
    assert np.all(np.isnan(got[~ok]))
    streamed = atlas.atlas(proto, xs, xs[:4], centre[2], 0.1, progress=False, frequency=True,
                           out=tmp_path / "a.zarr", chunk=8)
    np.testing.assert_array_equal(streamed.first_frequency.values, ds.first_frequency.values)
    with pytest.raises(h4pin.ParameterError, match="frequency"):
        atlas.atlas(h4pin.load("toleranced"), xs[:2], xs[:2], centre[2], progress=False, frequency=True)
