# SPDX-License-Identifier: Apache-2.0
"""The stiffness model of eq. 30 against independent routes, closed forms and symmetries."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import sample_poses

from h4pin import H4Params, PoseError, SingularPoseError, UnreachablePoseError, load
from h4pin.checks import deformed, statics
from h4pin.kinematics import closed_form as geometry
from h4pin.stiffness.api import TERMS, compliance, matrices_at
from h4pin.stiffness.matrices import from_points


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def test_result_structure(proto, centre):
    res = compliance(proto, centre)
    assert res.matrix.shape == (8, 8) and res.translational.shape == (3, 3)
    assert tuple(res.terms) == TERMS
    # The terms are computed on access, by the same kernel but summed in another order: equal to
    # round-off of the largest entry.
    np.testing.assert_allclose(sum(res.terms.values()), res.matrix, rtol=0, atol=4e-16 * np.abs(res.matrix).max())
    eager = compliance(proto, centre, terms=True)
    np.testing.assert_allclose(sum(eager.terms.values()), eager.matrix, rtol=0, atol=1e-20)
    np.testing.assert_allclose(res.q, np.pi / 4, atol=1e-12)
    np.testing.assert_array_equal(res.pose, centre)


def test_independent_implementation_numbers(proto, centre):
    """docs/parameters.md: an independent implementation gets these at q_i = 45 deg (um/N)."""
    res = compliance(proto, centre)
    np.testing.assert_allclose(res.translational * 1e6, [[33.6, 0, 15.9], [0, 16.6, 0], [15.9, 0, 14.2]], atol=0.05)
    split = {t: res.terms[t][0, 0] * 1e6 for t in TERMS}
    np.testing.assert_allclose([split[t] for t in TERMS], [20.0, 11.5, 1.8, 0.26], atol=0.05)


def test_control_term_hand_computation(proto, poses):
    """Eq. 10: the control term on (x, y, z, theta) is J J^T / kc, J = Jx^-1 Jq in closed form."""
    for x in poses:
        jx, jq = proto.jx_jq(x)
        j = np.linalg.solve(jx, jq)
        for model in ("paper", "consistent"):
            ctrl = compliance(proto, x, model).terms["control"][np.ix_([0, 1, 2, 5], [0, 1, 2, 5])]
            assert rel(ctrl, j @ j.T / proto.geometry.springs['kc'][0]) < 1e-12


def test_bending_and_torsion_scale_with_the_stressed_fraction(centre):
    """Bending is the control term times kc phi^3 r / (3 E I); torsion scales with phi."""
    full, part = load(H4Params()), load(H4Params(forearm_stressed_fraction=2 / 3))
    a, b = compliance(full, centre), compliance(part, centre)
    p = full.params
    assert rel(a.terms["bending"], a.terms["control"] * p.kc[0] * p.r[0] / (3 * p.E[0] * p.I[0])) < 1e-12
    assert rel(b.terms["bending"], a.terms["bending"] * (2 / 3) ** 3) < 1e-12
    assert rel(b.terms["torsion"], a.terms["torsion"] * (2 / 3)) < 1e-12
    assert rel(b.terms["tension"], a.terms["tension"]) < 1e-12


def test_consistent_equals_statics_route(proto, poses):
    """Newton-Euler equilibrium of the three plate bodies + unit loads, term by term, <= 1e-9."""
    worst = 0.0
    for x in poses:
        ours = compliance(proto, x, "consistent").terms
        theirs = statics.compliance_terms(proto.geometry, x)
        worst = max(worst, *(rel(ours[t], theirs[t]) for t in TERMS))
    assert worst <= 1e-9, f"consistent K vs statics route: {worst:.1e} relative"


def test_jb_inverse_equals_statics_bar_forces(proto, poses):
    """Eq. 17 f_b = Jb^-1 Gamma_ext with Jb = M1^T diag(1/l) vs the plate equilibrium."""
    for x in poses[:4]:
        jb = matrices_at(proto, x).Jb
        assert rel(np.linalg.inv(jb), statics.bar_forces(proto.geometry, x)) < 1e-10


def test_translational_block_equals_finite_differences(proto, poses):
    """Perturb each spring, re-solve the closure, difference the plate pose: <= 1e-6."""
    worst = 0.0
    for x in poses[:3]:
        fd = sum(deformed.compliance_terms(proto.geometry, x).values())
        for model in ("paper", "consistent"):
            worst = max(worst, rel(compliance(proto, x, model).translational, fd[:3, :3]))
    assert worst <= 1e-6, f"translational block vs finite differences: {worst:.1e} relative"


def test_consistent_full_matrix_equals_finite_differences(proto, poses):
    fd = sum(deformed.compliance_terms(proto.geometry, poses[0]).values())
    assert rel(compliance(proto, poses[0], "consistent").matrix, fd) <= 1e-6


@pytest.mark.parametrize("direction", [[1, 0, 0], [0, 1, 0], [0, 0, -1], [0.3, -0.4, -0.8]])
def test_nonlinear_loaded_equilibrium(proto, poses, direction):
    """Non-linear equilibrium under 10 N at D moves D by K F within 0.5 %, and what is left over
    is second order: the residual under 20 N is 4 times the one under 10 N (as a vector, 1 %).
    A K wrong by any amount would leave a first-order residual, which only doubles."""
    x = poses[1]
    force = 10.0 * np.asarray(direction) / np.linalg.norm(direction)
    k = compliance(proto, x).translational
    residual = {}
    for factor in (1.0, 2.0):
        d_nonlinear, _ = deformed.loaded_equilibrium(proto.geometry, x, factor * force)
        residual[factor] = d_nonlinear - k @ (factor * force)
    err = np.linalg.norm(residual[1.0]) / np.linalg.norm(k @ force)
    assert err < 5e-3, f"non-linear vs K F: {err:.2%}"
    quadratic = np.linalg.norm(residual[2.0] - 4 * residual[1.0]) / np.linalg.norm(residual[2.0])
    assert quadratic < 1e-2, f"residual under 20 N is not 4x the one under 10 N: {quadratic:.2%} off"


def test_consistent_is_symmetric_positive_definite(proto, poses):
    for x in poses:
        k = compliance(proto, x, "consistent").matrix
        assert rel(k, k.T) < 1e-13
        assert np.linalg.eigvalsh((k + k.T) / 2).min() > 0


def test_paper_model_differs_only_in_the_joint_torque_columns(proto, poses):
    """Erratum 4: R drops t1, t2; both models agree in the F and T columns, not in t1, t2."""
    for x in poses:
        paper, cons = compliance(proto, x, "paper").matrix, compliance(proto, x, "consistent").matrix
        assert rel(paper[:, :6], cons[:, :6]) < 1e-12
        assert rel(paper[:, 6:], cons[:, 6:]) > 1e-3
        assert rel(paper, paper.T) > 1e-3


def test_mirror_symmetry_zeroes_the_y_couplings(proto, centre):
    """The prototype is mirror-symmetric about y = 0: at the centre, y decouples from x and z."""
    k = compliance(proto, centre).translational
    assert np.max(np.abs(k[[0, 1, 1, 2], [1, 0, 2, 1]])) < 1e-12 * np.max(np.abs(k))


def test_pinocchio_matrices_equal_cross_product_formulas(proto, poses):
    """M1 rows w^T JB (Pinocchio) = eq. 6 cross products; M3 from Pinocchio = eq. 11; J = eq. 8."""
    for x in poses:
        pin_m = matrices_at(proto, x)
        cf = from_points(proto.geometry, geometry.points(proto.geometry, proto.state(x)))
        for name in ("M1", "M2", "J", "M3", "M4", "Jb"):
            a, b = getattr(pin_m, name), getattr(cf, name)
            assert rel(a, b) < 1e-12, name


def test_rigid_motion_of_m1_recovers_j(proto, poses):
    """M1^-1 M2 M3 (eqs. 6, 11) moves the plate as eq. 8 says, with d omega_k = -d theta."""
    for x in poses:
        m = matrices_at(proto, x)
        g3 = np.linalg.solve(m.M1, m.M2 @ m.M3)
        assert rel(g3[[0, 1, 2, 5]], m.J) < 1e-12
        np.testing.assert_allclose(g3[[3, 4]], 0.0, atol=1e-12 * np.max(np.abs(g3)))
        np.testing.assert_allclose(g3[6], -g3[5], atol=1e-12 * np.max(np.abs(g3)))
        np.testing.assert_allclose(g3[7], -g3[5], atol=1e-12 * np.max(np.abs(g3)))


def test_batch_equals_single_pose(proto):
    xs = sample_poses(proto, 40, seed=1)
    for model in ("paper", "consistent"):
        batch = compliance(proto, xs, model, terms=True)
        assert not compliance(proto, xs[:2], model).terms.computed  # terms only when asked for
        assert batch.matrix.shape == (40, 8, 8) and batch.terms["torsion"].shape == (40, 8, 8)
        for n in (0, 17, 39):
            single = compliance(proto, xs[n], model)
            assert rel(batch.matrix[n], single.matrix) < 1e-12
            for t in TERMS:
                assert rel(batch.terms[t][n], single.terms[t]) < 1e-12
        pin_batch = compliance(proto, xs[:5], model, method="pinocchio")
        assert rel(pin_batch.matrix, batch.matrix[:5]) < 1e-12


def test_singular_pose_is_an_error_with_the_condition_number(sym):
    centre = sym.forward_geometry(np.full(4, np.pi / 4))
    for method in ("pinocchio", "closed_form"):
        with pytest.raises(SingularPoseError, match=r"cond = (\d\.\d+e\+\d+|inf)"):
            compliance(sym, centre, method=method)


def test_batch_errors_name_the_first_bad_index(proto, sym):
    xs = sample_poses(proto, 6)
    bad = xs.copy()
    bad[4, 2] -= 0.4
    with pytest.raises(UnreachablePoseError, match="pose #4") as info:
        compliance(proto, bad)
    assert info.value.index == 4
    res = compliance(proto, bad, on_error="nan")
    np.testing.assert_array_equal(res.valid, [True, True, True, True, False, True])
    assert np.isnan(res.matrix[4]).all() and np.isfinite(res.matrix[res.valid]).all()
    centre = sym.forward_geometry(np.full(4, np.pi / 4))
    ys = np.vstack([centre + [0.05, 0.02, 0, 0.1], centre])
    with pytest.raises(SingularPoseError, match="pose #1"):
        compliance(sym, ys)
    assert compliance(sym, ys, on_error="nan").valid.tolist() == [True, False]


@pytest.mark.parametrize("bad", [[0, 0, -0.6], [0, 0, np.inf, 0], [[0, 0, -0.6, 0, 0]]])
def test_bad_input_is_a_clear_error(proto, bad):
    with pytest.raises(PoseError):
        compliance(proto, bad)


def test_bad_options(proto, centre):
    with pytest.raises(ValueError, match="model"):
        compliance(proto, centre, model="exact")
    with pytest.raises(ValueError, match="on_error"):
        compliance(proto, centre, on_error="ignore")


def test_n_matrix_moves_the_anchors_like_a_forearm_twist(proto, poses):
    """Eq. 22-23: (r/(G I0)) N_i [f_i1, f_i2] is the move of A_i1, A_i2 when forearm i twists
    under the bar forces (statics route), here against the twisted geometry of h4pin.checks.deformed."""
    from h4pin.stiffness.matrices import n_matrix

    x = poses[5]
    gamma = np.array([3.0, -1.0, -8.0, 0.2, -0.1, 0.3, 0.05, -0.02])
    c = proto.geometry.compliances()["torsion"]
    forces = statics.bar_forces(proto.geometry, x) @ gamma
    twist = c * (statics.spring_loads(proto.geometry, x)["torsion"] @ gamma)  # rad, per forearm
    n = n_matrix(geometry.points(proto.geometry, proto.state(x)))
    robot = deformed.DeformedH4(proto.geometry, x)
    for i in range(4):
        eps = np.zeros(16)
        eps[4 + i] = twist[i]
        moved = (robot.anchors(eps)[0] - robot.anchors(-eps)[0])[2 * i:2 * i + 2].reshape(6) / 2
        predicted = c[i] * n[i] @ forces[2 * i:2 * i + 2]
        assert np.max(np.abs(predicted - moved)) < 1e-7 * np.max(np.abs(moved))  # O(twist^2) truncation
        # Independent size: A_ij lies h off the forearm's axis, so a twist moves it by |twist| h.
        np.testing.assert_allclose(np.linalg.norm(moved.reshape(2, 3), axis=1),
                                   abs(twist[i]) * proto.params.half_width[i], rtol=1e-6)


def test_one_pose_fast_path_is_per_robot_and_equals_the_general_path(proto, poses):
    """The one-pose path (looked up per robot, model and method, stiffness.api._FAST) gives the
    numbers of the general path (the compiled kernel with its terms, and the numpy reference),
    each robot its own elements, and its entry goes with its robot."""
    import gc

    from h4pin.description.elements import ILLUSTRATIVE
    from h4pin.stiffness import api

    other = proto.with_elements(ILLUSTRATIVE)
    for robot in (proto, other, proto):
        for model in ("paper", "consistent"):
            x = poses[3]
            fast = compliance(robot, x, model, method="kernel")
            full = compliance(robot, x, model, method="kernel", terms=True)
            ref = compliance(robot, x, model, method="closed_form")
            np.testing.assert_allclose(fast.matrix, full.matrix, rtol=0, atol=1e-14 * np.max(np.abs(full.matrix)))
            assert np.max(np.abs(fast.matrix - ref.matrix)) <= 1e-12 * np.max(np.abs(ref.matrix))
            assert fast.elements is (None if robot.elements.off else robot.elements)
            assert not fast.pose.flags.writeable and fast.status == 0 and set(fast.terms) == set(full.terms)
    key = (id(other), "paper", "kernel")
    assert api._FAST[key][2] is other.elements
    del other, fast, full, ref, robot
    gc.collect()
    assert key not in api._FAST
    with pytest.raises(UnreachablePoseError):  # a refused pose still takes the long way for its error
        compliance(proto, np.array([0.0, 0.0, -1.2, 0.0]), method="kernel")
