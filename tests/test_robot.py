# SPDX-License-Identifier: Apache-2.0
"""Loader, closed-loop geometry and Jacobians, checked against independent routes."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin import ConvergenceError, H4Params, PoseError, SingularPoseError, UnreachablePoseError
from h4pin.kinematics import closed_form as geometry


def test_load_sources(proto, tmp_path):
    from h4pin.robot import variant_path

    assert isinstance(proto.model, pin.Model) and len(proto.constraint_models) == 8
    assert h4pin.load(variant_path("prototype")).params.allclose(proto.params, atol=0)
    assert h4pin.load(H4Params(half_width=0.03)).params.half_width == pytest.approx(np.full(4, 0.03))
    with pytest.raises(ValueError, match="prototype, symmetric"):
        h4pin.load("protoype")
    with pytest.raises(FileNotFoundError):
        h4pin.load(tmp_path / "none.urdf")


def test_named_frames(proto):
    names = ["D"] + [f"{p}_{i}" for p in "PAB" for i in range(1, 5)] + ["C_1", "C_2"]
    names += [f"{p}_{i}{j}" for p in "AB" for i in range(1, 5) for j in (1, 2)]
    assert all(n in proto.frames for n in names)


def test_centre_pose(proto, centre):
    """All actuators at 45 deg: D is on the z axis (mirror symmetry) and theta = 0; its height by
    hand from leg 1 (A_1 = P_1 + r (-x cos 45 - z sin 45), B_1 = D + DB_1, |B_1 - A_1| = l)."""
    np.testing.assert_allclose(centre[[0, 1, 3]], 0.0, atol=1e-12)
    r, l, s = 0.260, 0.480, np.sqrt(0.5)
    dx = (0.200 + r * s) - 0.060  # x gap between A_1 and B_1; their y are both -60 mm
    z = -r * s - 0.050 - np.sqrt(l**2 - dx**2)
    assert centre[2] == pytest.approx(z, abs=1e-12)
    assert centre[2] == pytest.approx(-0.58814, abs=5e-6)  # as printed by h4pin table2


def test_inverse_forward_round_trip(proto, poses):
    for x in poses:
        q = proto.inverse_geometry(x)
        np.testing.assert_allclose(proto.forward_geometry(q, guess=x + [0.01, -0.01, 0.01, 0.05]), x, atol=1e-12)
        np.testing.assert_allclose(proto.inverse_geometry(proto.forward_geometry(q)), q, atol=1e-12)
        np.testing.assert_allclose(geometry.closure_residual(proto.geometry, proto.state(x)), 0.0, atol=1e-15)


def test_inverse_geometry_is_elbow_out_and_vectorised(proto, poses):
    q = proto.inverse_geometry(poses)
    assert q.shape == (len(poses), 4)
    np.testing.assert_array_equal(q[3], proto.inverse_geometry(poses[3]))
    pts = geometry.points(proto.geometry, geometry.rigid_state(poses, q))
    elbow = np.einsum("nia,ia->ni", np.cross(pts.A - pts.P, pts.B - pts.A), proto.geometry.u)
    assert np.all(elbow > 0)


def test_unreachable_pose_names_the_leg(proto, centre, poses):
    far = centre + [0.0, 0.0, -0.3, 0.0]
    with pytest.raises(UnreachablePoseError, match=r"leg \d cannot reach B_\d"):
        proto.inverse_geometry(far)
    batch = np.vstack([poses[:3], far, poses[3:]])
    with pytest.raises(UnreachablePoseError, match="pose #3") as info:
        proto.inverse_geometry(batch)
    assert info.value.index == 3
    q = proto.inverse_geometry(batch, on_error="nan")
    assert np.isnan(q[3]).all() and np.isfinite(np.delete(q, 3, axis=0)).all()


@pytest.mark.parametrize("bad", [[0, 0, -0.5], [0, 0, np.nan, 0], "x", np.zeros((2, 2, 4))])
def test_bad_pose_input(proto, bad):
    with pytest.raises(PoseError):
        proto.inverse_geometry(bad)


def test_forward_geometry_failure_is_clear(proto):
    with pytest.raises(ConvergenceError, match="forward geometry"):
        proto.forward_geometry(np.array([0.0, 0.0, 0.0, 3.0]))


def test_configuration_closes_all_loops(proto, poses):
    for x in poses:
        q = proto.configuration(x)
        assert np.max(np.abs(proto.closure_residuals(q))) < 1e-10
        pin.framesForwardKinematics(proto.model, proto.data, q)
        np.testing.assert_allclose(proto.frame_position("D"), x[:3], atol=1e-15)
        for k in (1, 2):  # lateral bars only translate
            lat = proto.data.oMf[proto.frames[f"C_{k}"]].rotation
            np.testing.assert_allclose(lat, np.eye(3), atol=1e-14)


def test_jacobian_against_finite_differences(proto, poses):
    """J from Pinocchio's closure Jacobians vs central differences of the forward geometry."""
    h = 1e-6
    for x in poses[:6]:
        q = proto.inverse_geometry(x)
        fd = np.column_stack([
            (proto.forward_geometry(q + h * e, guess=x) - proto.forward_geometry(q - h * e, guess=x)) / (2 * h)
            for e in np.eye(4)
        ])
        j = proto.jacobian(x)
        assert np.max(np.abs(j - fd)) < 1e-7 * np.max(np.abs(j))


def test_jacobian_against_closed_form(proto, poses):
    """Pinocchio's J equals the paper's Jx^-1 Jq (eq. 8)."""
    for x in poses:
        jx, jq = proto.jx_jq(x)
        np.testing.assert_allclose(proto.jacobian(x), np.linalg.solve(jx, jq), atol=1e-12)


def test_singular_pose_of_the_symmetric_variant(sym):
    centre = sym.forward_geometry(np.full(4, np.pi / 4))
    with pytest.raises(SingularPoseError, match="cond = "):
        sym.jacobian(centre)


def test_gravity_torques_against_potential_energy(proto, poses):
    """Holding torques from Pinocchio's dynamics and closures = gradient of the potential energy."""
    h = 1e-6
    for x in poses[:4]:
        q = proto.inverse_geometry(x)

        def energy(qa, guess=x):
            return proto.potential_energy(proto.forward_geometry(qa, guess=guess))

        fd = np.array([(energy(q + h * e) - energy(q - h * e)) / (2 * h) for e in np.eye(4)])
        tau = proto.gravity_torques(x)
        np.testing.assert_allclose(tau, fd, rtol=1e-6, atol=1e-6 * np.max(np.abs(fd)))
        assert np.max(np.abs(tau)) > 0.1  # the robot weighs a few kg: torques are not trivially zero


def test_gravity_torques_change_sign_with_gravity(proto, centre):
    tau = proto.gravity_torques(centre)
    np.testing.assert_allclose(proto.gravity_torques(centre, gravity=[0, 0, 9.81]), -tau, rtol=1e-12)


@pytest.mark.parametrize("variant", h4pin.VARIANTS)
def test_q0_is_the_assembled_reference_configuration(variant):
    """h4.q0 and model.referenceConfigurations["q0"] (Pinocchio's convention) are the configuration
    with every actuator at 45 deg, all loops closed; the shipped SRDF's q0 agrees to its rounding
    (1 um, 1 urad on the pose)."""
    from h4pin.robot import urdf_dir

    h4 = h4pin.load(variant)
    assert h4.q0 is not None and not h4.q0.flags.writeable
    np.testing.assert_array_equal(h4.model.referenceConfigurations["q0"], h4.q0)
    assert np.abs(h4.closure_residuals(h4.q0)).max() < 1e-12
    np.testing.assert_allclose(h4.q0[h4.index.q_act], np.pi / 4, atol=1e-9)
    model = pin.buildModelFromUrdf(str(urdf_dir() / f"h4_{variant}.urdf"))
    pin.loadReferenceConfigurations(model, str(urdf_dir().parent / "srdf" / f"h4_{variant}.srdf"))
    np.testing.assert_allclose(model.referenceConfigurations["q0"], h4.q0, atol=1e-5)


# ----------------------------------------------------------------- Pinocchio 4 point constraints
def _needs_point_constraints():
    if not hasattr(pin, "PointAnchorConstraintModel"):
        pytest.skip(f"Pinocchio {pin.__version__} has no point constraints (Pinocchio >= 4); "
                    "h4pin keeps the legacy RigidConstraintModel there")


def _selection(h4) -> np.ndarray:
    """(nv, 4): the actuators' columns of the identity (tau_full = S tau_act)."""
    s = np.zeros((h4.model.nv, 4))
    s[h4.v_act, np.arange(4)] = 1.0
    return s


def _jacobian(h4, models, q, data, vector=None, datas=None):
    """The stacked constraint Jacobian of ``models`` at q, by Pinocchio (its own getConstraintsJacobian)."""
    vector = vector or pin.StdVec_ConstraintData
    datas = datas if datas is not None else vector()
    if not len(datas):
        for cm in models:
            datas.append(cm.createData())
    pin.computeJointJacobians(h4.model, data, q)
    for cm, cd in zip(models, datas, strict=True):
        cm.calc(h4.model, data, cd)
    if isinstance(models, pin.StdVec_PointContactConstraintModel):  # not taken by getConstraintsJacobian
        return np.vstack([cm.jacobian(h4.model, data, cd) for cm, cd in zip(models, datas, strict=True)]), datas
    return pin.getConstraintsJacobian(h4.model, data, models, datas), datas


def test_point_constraints_are_the_closures(proto, poses):
    """Pinocchio 4's PointAnchorConstraintModel of each closure: same joints, placements and names as
    the legacy CONTACT_3D models, closed at q0 (its own position error), Jacobian = -legacy one."""
    _needs_point_constraints()
    points = proto.point_constraints()
    assert len(points) == 8 and all(p.shortname() == "PointAnchorConstraintModel" for p in points)
    assert [p.name for p in points] == [cm.name for cm in proto.constraint_models]
    data = proto.model.createData()
    pin.forwardKinematics(proto.model, data, proto.q0)
    for p, cm in zip(points, proto.constraint_models, strict=True):
        anchor = p.extract()
        assert (anchor.joint1_id, anchor.joint2_id) == (cm.joint1_id, cm.joint2_id)
        cd = anchor.createData()
        anchor.calc(proto.model, data, cd)
        assert np.linalg.norm(cd.constraint_position_error) < 1e-12
    for x in poses[:4]:
        q = proto.configuration(x)
        j_point, _ = _jacobian(proto, points, q, data)
        j_legacy, _ = _jacobian(proto, proto.constraint_models, q, data, pin.StdVec_RigidConstraintData)
        assert np.abs(j_legacy).max() > 0.1
        np.testing.assert_allclose(j_point, -j_legacy, rtol=0, atol=1e-14)


def test_point_constraints_balance_the_legacy_forward_dynamics(proto, poses):
    """Moving robot: Pinocchio's legacy constrained forward dynamics (RigidConstraintModel) gives the
    accelerations a and closure forces of some actuator torques at a velocity that keeps the loops
    closed; the inverse dynamics with the point constraints, rnea(q, v, a) = S tau + Jp^T lambda
    (a square solve), gives back those torques and the same J^T lambda."""
    _needs_point_constraints()
    from h4pin import _compat

    m, data = proto.model, proto.model.createData()
    points, s = proto.point_constraints(), _selection(proto)
    rng = np.random.default_rng(5)
    for x in poses[:3]:
        q = proto.configuration(x)
        v = proto.passive_map(q, data) @ rng.uniform(-1, 1, 4)
        tau = rng.uniform(-5, 5, 4)
        datas = pin.StdVec_RigidConstraintData()
        for cm in proto.constraint_models:
            datas.append(cm.createData())
        _compat.init_constraint_dynamics(m, data, proto.constraint_models, datas)
        a = pin.constraintDynamics(m, data, q, v, s @ tau, proto.constraint_models, datas).copy()
        lam_legacy = data.lambda_c.copy()
        j_legacy, _ = _jacobian(proto, proto.constraint_models, q, data, pin.StdVec_RigidConstraintData)
        j_point, _ = _jacobian(proto, points, q, data)
        assert np.abs(j_point @ v).max() < 1e-12  # the loops stay closed
        rhs = pin.rnea(m, data, q, v, a)
        sol = np.linalg.solve(np.hstack([s, j_point.T]), rhs)
        np.testing.assert_allclose(sol[:4], tau, rtol=0, atol=1e-9 * np.abs(rhs).max())
        np.testing.assert_allclose(j_point.T @ sol[4:], j_legacy.T @ lam_legacy, rtol=0,
                                   atol=1e-9 * np.abs(rhs).max())


def test_compute_inverse_dynamics_constraint_forces_holds_the_robot(proto, poses):
    """Pinocchio 4's computeInverseDynamicsConstraintForces on the closures, at rest under gravity.

    It takes unilateral point contacts with Coulomb friction (PointContactConstraintModel) and
    compliance R, and returns the forces lambda in the friction cone with c_ref + R lambda = 0 (for
    forces inside the cone): a compliant-contact law, not the closed-loop dynamics. So each closure
    is given as a contact whose normal lies along its bar (the way the bar pushes or pulls at this
    pose; a bar nearly unloaded along its axis still carries part of its weight across it, hence
    a friction coefficient of 1e3) and c_ref = -R lambda*, lambda* the closure forces of the rigid
    robot held by its motors (from rnea = S tau + Jc^T lambda). The forces it returns must make the
    inverse dynamics balance: tau = rnea - Jc^T lambda is zero on every passive joint and equals h4.gravity_torques (the
    closed-loop velocity map, an independent route) on the actuators. It is solved as the convex
    problem (solve_ncp=False): the NCP's De Saxce correction would read the tangential part of c_ref
    as sliding (and does not converge with this friction coefficient).

    pin 4.1.0's Python binding of computeInverseDynamicsConstraintForces cannot be called (its
    argument checker reads the first argument as a Model: TypeError); pin.contactInverseDynamics,
    which calls it and then computes rnea - Jc^T lambda, is used then.
    """
    _needs_point_constraints()
    if not hasattr(pin, "PointContactConstraintModel"):
        pytest.skip(f"needs pinocchio.PointContactConstraintModel (Pinocchio >= 4), this is {pin.__version__}")
    m, data = proto.model, proto.model.createData()
    s, zero = _selection(proto), np.zeros(proto.model.nv)
    compliance, dt, friction = 1e-6, 1e-3, 1e3
    for x in poses[:3]:
        q = proto.configuration(x)
        up = pin.StdVec_PointContactConstraintModel()
        for cm in proto.constraint_models:  # contact z along the bar (z of the bar end's frame)
            up.append(pin.PointContactConstraintModel(m, cm.joint1_id, cm.joint1_placement, cm.joint2_id,
                                                      cm.joint2_placement))
        j_up, _ = _jacobian(proto, up, q, data, pin.StdVec_PointContactConstraintData)
        g = pin.rnea(m, data, q, zero, zero)
        lam_up = np.linalg.solve(np.hstack([s, j_up.T]), g)[4:].reshape(8, 3)
        flip = pin.SE3(np.diag([1.0, -1.0, -1.0]), np.zeros(3))  # normal the other way along the bar
        contacts = pin.StdVec_PointContactConstraintModel()
        for cm, lam in zip(proto.constraint_models, lam_up, strict=True):
            turn = pin.SE3.Identity() if lam[2] > 0 else flip
            c = pin.PointContactConstraintModel(m, cm.joint1_id, cm.joint1_placement * turn, cm.joint2_id,
                                                cm.joint2_placement * turn)
            c.setCompliance(np.full(3, compliance))
            c.setFriction(friction)
            contacts.append(c)
        jc, datas = _jacobian(proto, contacts, q, data, pin.StdVec_PointContactConstraintData)
        lam_star = np.linalg.solve(np.hstack([s, jc.T]), g)[4:]
        normal, tangent = lam_star.reshape(8, 3)[:, 2], np.linalg.norm(lam_star.reshape(8, 3)[:, :2], axis=1)
        assert np.all(normal > 0) and np.all(tangent < friction * normal)  # inside the friction cones
        settings = pin.ProximalSettings(1e-12, 1e-12, 1e-9, 200)  # absolute, relative accuracy; mu; iterations
        try:
            converged, lam = pin.computeInverseDynamicsConstraintForces(-compliance * lam_star, contacts, datas,
                                                                        np.zeros(24), settings, False)
            tau = g - jc.T @ lam
        except TypeError as exc:  # pin 4.1.0's binding (see the docstring)
            assert "ModelTpl" in str(exc)
            converged, tau, lam = pin.contactInverseDynamics(m, data, q, zero, zero, dt, contacts, datas,
                                                             -dt * compliance * lam_star, settings,
                                                             np.zeros(24), False)
        assert converged
        np.testing.assert_allclose(lam, lam_star, rtol=0, atol=1e-9 * np.abs(lam_star).max())
        np.testing.assert_allclose(tau[proto.v_pas], 0, atol=1e-9 * np.abs(g).max())
        np.testing.assert_allclose(tau[proto.v_act], proto.gravity_torques(x), rtol=0, atol=1e-9 * np.abs(g).max())


def test_point_constraints_need_pinocchio_4(proto, monkeypatch):
    monkeypatch.delattr(pin, "PointAnchorConstraintModel", raising=False)
    with pytest.raises(h4pin.H4Error, match="Pinocchio >= 4.*constraint_models"):
        proto.point_constraints()


def test_collision_model_is_made_once_and_shared(proto):
    """The collision pairs are added on first use (h4pin.load stays as fast as before), once."""
    import threading

    robot = h4pin.load("prototype")
    assert "collision_model" not in robot._lazy
    seen = []
    threads = [threading.Thread(target=lambda: seen.append(robot.collision_model)) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len({id(cm) for cm in seen}) == 1
    assert robot.with_elements(robot.elements).collision_model is seen[0]
    assert len(seen[0].collisionPairs) == len(proto.collision_model.collisionPairs) > 0


def _travellers(proto) -> dict[str, h4pin.H4]:
    """Robots made by each route that changes what defines one: as shipped, other elements
    (``with_elements``), and springs and bar clearance given at load (numbers from ``proto``)."""
    from h4pin.description.elements import ILLUSTRATIVE

    kc = proto.geometry.springs["kc"] * np.array([1.0, 2.0, 3.0, 4.0])
    return {"prototype": proto, "elements": proto.with_elements(ILLUSTRATIVE),
            "springs": h4pin.load("prototype", springs={"kc": kc, "Eb": proto.geometry.springs["Eb"] / 3},
                                  bar_clearance=proto.geometry.bar_clearance / 2)}


@pytest.mark.parametrize("kind", ["prototype", "elements", "springs"])
@pytest.mark.parametrize("how", ["pickle", "deepcopy"])
def test_a_robot_travels_by_being_rebuilt(proto, poses, kind, how):
    """pickle and copy.deepcopy rebuild the robot from its URDF text, source, springs override,
    bar clearance and elements: a new model, the same numbers to the bit."""
    import copy
    import pickle

    robot = _travellers(proto)[kind]
    if kind != "prototype":  # the route changed the robot: a copy that lost it would show
        changed = not robot.elements.allclose(proto.elements) if kind == "elements" else not np.array_equal(
            robot.geometry.compliances()["control"], proto.geometry.compliances()["control"])
        assert changed
    twin = pickle.loads(pickle.dumps(robot)) if how == "pickle" else copy.deepcopy(robot)
    assert type(twin) is h4pin.H4 and twin is not robot
    assert twin.model is not robot.model and twin.data is not robot.data
    assert twin.constraint_datas is not robot.constraint_datas
    assert twin.urdf == robot.urdf and twin.source == robot.source
    assert twin.elements.allclose(robot.elements, rtol=0) and robot.elements.allclose(twin.elements, rtol=0)
    assert twin.geometry.bar_clearance == robot.geometry.bar_clearance
    for name, value in robot.geometry.springs.items():
        np.testing.assert_array_equal(twin.geometry.springs[name], value)
    np.testing.assert_array_equal(twin.q0, robot.q0)
    for x in poses[:3]:
        np.testing.assert_array_equal(h4pin.compliance(twin, x).matrix, h4pin.compliance(robot, x).matrix)
    np.testing.assert_array_equal(h4pin.compliance(twin, poses[3:6]).matrix, h4pin.compliance(robot, poses[3:6]).matrix)
    np.testing.assert_array_equal(twin.jacobian(poses[0]), robot.jacobian(poses[0]))
    assert copy.copy(robot) is robot  # immutable: a shallow copy is the robot itself


def test_a_springs_override_travels_as_loaded(proto, centre):
    """The override travels as it was at load: changing the caller's array afterwards changes
    neither the robot nor its copies."""
    import pickle

    kc = proto.geometry.springs["kc"] * 2
    robot = h4pin.load("prototype", springs={"kc": kc})
    before = h4pin.compliance(robot, centre).matrix
    kc *= 10
    twin = pickle.loads(pickle.dumps(robot))
    np.testing.assert_array_equal(twin.geometry.springs["kc"], robot.geometry.springs["kc"])
    np.testing.assert_array_equal(h4pin.compliance(twin, centre).matrix, before)


def _compliance_elsewhere(h4: h4pin.H4, pose: np.ndarray) -> tuple[int, np.ndarray]:
    """(this process's id, the compliance matrix): what a pool worker sends back."""
    import os

    return os.getpid(), h4pin.compliance(h4, pose, method="closed_form").matrix


@pytest.fixture(scope="module")
def resource_tracker():
    """multiprocessing's resource tracker, started before ``no_process_left`` tags this test's
    processes: it serves the whole test session, it is not the pool's to stop."""
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()


def test_a_robot_goes_to_a_process_pool(proto, poses, resource_tracker, no_process_left):
    """A spawned worker (a fresh interpreter: nothing inherited) gets the robot by pickle and
    computes the same matrices, to the bit, as this process; the pool's worker is gone after."""
    import concurrent.futures
    import multiprocessing
    import os

    from h4pin.description.elements import ILLUSTRATIVE

    robot = proto.with_elements(ILLUSTRATIVE)
    chosen = poses[:2]
    with concurrent.futures.ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        out = list(pool.map(_compliance_elsewhere, [robot] * len(chosen), chosen, timeout=60))
    assert len(out) == len(chosen) and all(pid != os.getpid() for pid, _ in out)
    for (_, matrix), x in zip(out, chosen, strict=True):
        np.testing.assert_allclose(matrix, h4pin.compliance(robot, x, method="closed_form").matrix, rtol=0, atol=0)
