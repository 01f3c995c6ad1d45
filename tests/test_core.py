# SPDX-License-Identifier: Apache-2.0
"""One robot, one math: every backend x every shipped variant x both models x terms on/off x
elements on/off against the numpy reference; the elements against the independent routes; a
URDF edited by hand; one robot shared by threads and by Dask's threaded scheduler."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from conftest import sample_poses

import h4pin
from h4pin.checks import deformed
from h4pin.checks.elements import element_terms_fd
from h4pin.description.elements import ILLUSTRATIVE, Elements
from h4pin.description.params import VARIANTS
from h4pin.kinematics import closed_form as cf
from h4pin.stiffness import eq30
from h4pin.stiffness.api import BACKENDS
from h4pin.stiffness.elements import element_terms
from h4pin.stiffness.matrices import from_points, products_of

#: The backends tested against the reference (``closed_form`` is the reference itself).
COMPARED = tuple(m for m in BACKENDS if m != "closed_form") + ("auto",)


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.fixture(scope="module", params=VARIANTS)
def robot(request) -> h4pin.H4:
    return h4pin.load(request.param)


def reference(h4: h4pin.H4, x: np.ndarray, model: str, elements: Elements | None) -> dict[str, np.ndarray]:
    """Eq. 30 from the paper's dense matrices (M1, M2, M3, M4 of the closed forms, products taken
    here) and the numpy reference formula, plus the elements' unit-load terms: per pose."""
    g = h4.geometry
    state = cf.solve(g, x).state
    mats = from_points(g, cf.points(g, state))
    m1, H, N, l = products_of(mats)
    out = eq30.terms(eq30.inverse(m1), H, N, l, g.compliances(), model)
    if elements is not None and not elements.off:
        out |= element_terms(g, x, elements)
    return out


@pytest.mark.parametrize("elements", [None, ILLUSTRATIVE], ids=["eq30", "elements"])
@pytest.mark.parametrize("terms", [False, True], ids=["K", "terms"])
@pytest.mark.parametrize("model", ["paper", "consistent"])
@pytest.mark.parametrize("method", COMPARED)
def test_every_backend_equals_the_reference(robot, method, model, terms, elements):
    h4 = robot if elements is None else robot.with_elements(elements)
    xs = sample_poses(robot, 3, seed=7)
    if method == "kernel" and not robot.geometry.ideal:
        with pytest.raises(h4pin.ParameterError, match="exact"):
            h4pin.compliance(h4, xs, model, method=method)
        return
    batch = h4pin.compliance(h4, xs, model, method=method, terms=terms)
    for k, x in enumerate(xs):
        ref = reference(robot, x, model, elements)
        one = h4pin.compliance(h4, x, model, method=method, terms=terms)
        for res in (one.matrix, batch.matrix[k]):
            assert rel(res, sum(ref.values())) < 1e-12
        assert set(one.terms) == set(ref) == set(batch.terms)
        for name, term in ref.items():
            scale = np.max(np.abs(sum(ref.values())))
            assert np.max(np.abs(one.terms[name] - term)) < 1e-12 * scale, name
            assert np.max(np.abs(batch.terms[name][k] - term)) < 1e-12 * scale, name


def test_eq30_alone_is_one_argument_away(robot):
    h4 = robot.with_elements(ILLUSTRATIVE)
    x = sample_poses(robot, 1, seed=5)[0]
    plain = h4pin.compliance(robot, x, "consistent")
    alone = h4pin.compliance(h4, x, "consistent", elements=False)
    np.testing.assert_array_equal(alone.matrix, plain.matrix)
    assert alone.elements is None and tuple(alone.terms) == eq30.TERMS
    assert rel(h4pin.compliance(h4, x, "consistent").matrix, plain.matrix) > 1e-3


def test_elements_against_the_independent_routes(robot):
    """Consistent K with elements = sum over every spring of the non-linear deformed robot,
    differentiated numerically (no unit loads, no eq. 30)."""
    h4 = robot.with_elements(ILLUSTRATIVE)
    x = sample_poses(robot, 1, seed=3)[0]
    res = h4pin.compliance(h4, x, "consistent", method="pinocchio")
    fd = sum(deformed.compliance_terms(robot.geometry, x).values()) + sum(
        element_terms_fd(robot.geometry, x, ILLUSTRATIVE).values())
    assert rel(res.matrix, fd) < 1e-5  # central differences, step 1e-6
    assert rel(res.matrix, sum(deformed.compliance_terms(robot.geometry, x).values())) > 1e-3


HAND_EDIT = '<h4_revolute radial="3e-7" axial="2e-7" tilt="4e-5"/>\n    <limit lower="-0.7853981633974483"'


def test_urdf_element_data_edited_by_hand_reach_compliance(tmp_path, proto, poses):
    text = proto.urdf.replace('<limit lower="-0.7853981633974483"', HAND_EDIT)
    assert text.count("<h4_revolute ") == 2
    path = tmp_path / "edited.urdf"
    path.write_text(text)
    h4 = h4pin.load(path)
    want = Elements(revolute_radial=3e-7, revolute_axial=2e-7, revolute_tilt=4e-5)
    assert h4.elements.allclose(want)
    xs = poses[:4]
    batch = h4pin.compliance(h4, xs)
    for k, x in enumerate(xs):
        single = h4pin.compliance(h4, x)
        np.testing.assert_allclose(batch.matrix[k], single.matrix, rtol=0, atol=1e-12 * np.abs(single.matrix).max())
        rigid = h4pin.compliance(proto, x).matrix
        fd = element_terms_fd(proto.geometry, x, want)
        assert set(fd) == {"revolute_radial", "revolute_axial", "revolute_tilt"}
        assert rel(single.matrix - rigid, sum(fd.values())) < 1e-5
        assert rel(single.matrix, rigid) > 1e-3


def test_results_own_their_inputs(proto, poses):
    P = poses[:2].copy()
    r = h4pin.compliance(proto, P)
    before = r.matrix.copy()
    P[:, 0] += 0.1
    assert not np.shares_memory(r.pose, P)
    np.testing.assert_allclose(sum(r.terms.values()), before, rtol=0, atol=1e-15 * np.abs(before).max())
    np.testing.assert_array_equal(r.pose, poses[:2])
    with pytest.raises(ValueError):
        r.pose[0, 0] = 1.0


def test_the_robot_is_immutable(proto):
    with pytest.raises(AttributeError, match="immutable"):
        proto.geometry = None
    with pytest.raises(AttributeError, match="immutable"):
        proto.elements = ILLUSTRATIVE


def serial_results(h4: h4pin.H4, xs: np.ndarray, fixed: np.ndarray) -> list[dict[str, np.ndarray]]:
    from h4pin.stiffness.deflection import deflection

    out = []
    for x in xs:
        out.append({
            **{f"K_{m}": h4pin.compliance(h4, x, "consistent", method=m).matrix for m in (*BACKENDS, "auto")},
            "batch": h4pin.compliance(h4, fixed, method="pinocchio").matrix,
            "jacobian": h4.jacobian(x),
            "configuration": h4.configuration(x),
            "gravity": h4.gravity_torques(x),
            "gravity_x": h4.gravity_torques(x, gravity=[3.0, 0.0, -9.0]),
            "deflection": deflection(h4, x, [0.0, 0.0, -10.0])[0],
        })
    return out


def test_one_robot_shared_by_eight_threads(poses):
    h4 = h4pin.load("prototype").with_elements(Elements(revolute_tilt=4e-5))
    xs = poses[:8]
    want = serial_results(h4, xs, xs[:3])
    barrier = threading.Barrier(8)

    def run(k: int) -> list[dict[str, np.ndarray]]:
        barrier.wait()
        return serial_results(h4, np.roll(xs, -k, axis=0), xs[:3])

    with ThreadPoolExecutor(8) as pool:
        got = list(pool.map(run, range(8)))
    for k, res in enumerate(got):
        for j, row in enumerate(res):
            ref = want[(j + k) % 8]
            for name, value in row.items():
                if name == "batch":
                    np.testing.assert_array_equal(value, want[0]["batch"])
                else:
                    np.testing.assert_array_equal(value, ref[name], err_msg=name)
    # nothing a call did changed the shared model
    np.testing.assert_array_equal(h4.model.gravity.linear, [0.0, 0.0, -9.81])


def test_gravity_torques_for_any_gravity_are_linear_in_it(proto, centre):
    """tau(g) is linear in the gravity vector; the default is the model's (0, 0, -9.81)."""
    gx, gz = proto.gravity_torques(centre, [1.0, 0, 0]), proto.gravity_torques(centre, [0, 0, 1.0])
    np.testing.assert_allclose(proto.gravity_torques(centre, [2.0, 0, 3.0]), 2 * gx + 3 * gz, rtol=1e-12)
    np.testing.assert_allclose(proto.gravity_torques(centre), -9.81 * gz, rtol=1e-12)


def test_dask_threaded_scheduler_sharing_one_robot_equals_serial(poses):
    dask = pytest.importorskip("dask")
    h4 = h4pin.load("prototype")
    xs = sample_poses(h4, 64, seed=11)
    chunks = np.array_split(xs, 16)

    def task(c: np.ndarray) -> np.ndarray:
        return np.concatenate([h4pin.compliance(h4, c, "consistent", method="pinocchio").matrix.reshape(len(c), -1),
                               np.stack([h4.jacobian(x).ravel() for x in c])], axis=1)

    serial = np.concatenate([task(c) for c in chunks])
    parallel = np.concatenate(dask.compute(*[dask.delayed(task)(c) for c in chunks], scheduler="threads",
                                           num_workers=8))
    np.testing.assert_array_equal(parallel, serial)


def test_the_atlas_sees_the_robots_elements(proto):
    """An atlas of a robot that carries elements equals compliance() of that robot, pose by pose."""
    from h4pin.studies.atlas import atlas

    h4 = proto.with_elements(ILLUSTRATIVE)
    c = cf.centre_pose(proto)
    xs, ys = c[0] + np.array([-0.05, 0.0, 0.04]), c[1] + np.array([-0.03, 0.02])
    with_el = atlas(h4, xs, ys, [c[2]], c[3], progress=False)
    rigid = atlas(proto, xs, ys, [c[2]], c[3], progress=False)
    for iy, y in enumerate(ys):
        for ix, x in enumerate(xs):
            k = h4pin.compliance(h4, np.array([x, y, c[2], c[3]]), "consistent").translational
            want = np.linalg.eigvalsh(0.5 * (k + k.T))[-1]
            got = with_el.compliance_max.values[0, 0, iy, ix]
            assert abs(got - want) < 1e-12 * want
            assert got > rigid.compliance_max.values[0, 0, iy, ix] * (1 + 1e-3)
