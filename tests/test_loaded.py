# SPDX-License-Identifier: Apache-2.0
"""The loaded robot (h4pin.mechanism.loaded): the non-linear equilibrium, its tangent compliance,
critical loads and deflection compensation, each against something independent of the solver:

* the linear compliance of the engine (``Mechanism.compliance``) in the small-load limit;
* central differences of the equilibrium itself in an extra wrench (the tangent compliance);
* closed forms: an inverted pendulum on a torsion spring (critical tip load ``k/L``, post-buckling
  ``k θ = P L sin θ``), a cantilever beam under axial load (Euler's ``π² EI / 4 L²`` as the
  segments grow), a two-bar toggle with axial springs (its snap-through load);
* MuJoCo: the elastic export settled under gravity and a payload, on two corpus robots and the
  H4 (its own elastic file), and the compensated motors put through it.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin.errors import ConvergenceError, MechanismWarning, ParameterError
from h4pin.kinematics.closed_form import centre_pose
from h4pin.limits import TooLargeError
from h4pin.mechanism import Beam, JointCoupling, Mechanism, Payload
from h4pin.mechanism.loaded import LimitLoadError

ROBOTS = Path(__file__).resolve().parent / "robots"


def _corpus(robot: str) -> tuple[Mechanism, np.ndarray, dict[str, float]]:
    """A corpus robot, assembled, a spring on every joint: motors 2e3, passive joints 50 N.m/rad."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        mech = Mechanism.from_urdf(ROBOTS / robot / "robot.urdf")
    springs = {n: 2e3 if n in mech.actuated else 50.0 for n in list(mech.model.names)[1:]}
    return mech, mech.assemble(), springs


@pytest.fixture(scope="module")
def five_bar():
    return _corpus("5bar_linkage_iso3d")


@pytest.fixture(scope="module")
def elastic_h4():
    h4 = h4pin.load("prototype")
    return h4, h4pin.elastic_model(h4)


def _pendulum(length: float) -> Mechanism:
    """A rigid rod of ``length`` m on a revolute joint about y at the origin, upright (+z), its tip
    a frame ``tip``: an inverted pendulum when a spring holds the joint."""
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "hinge")
    model.appendBodyToJoint(j, pin.Inertia(1.0, np.array([0.0, 0.0, length / 2]), np.eye(3) * 1e-3), pin.SE3.Identity())
    model.addFrame(pin.Frame("tip", j, 0, pin.SE3(np.eye(3), np.array([0.0, 0.0, length])), pin.FrameType.OP_FRAME))
    return Mechanism(model, [], [])


def _toggle(a: float, h: float) -> Mechanism:
    """Two bars pinned at (-a, 0) and (a, 0) (revolutes about z), meeting at the apex (0, h) (a 3-D
    closure), each with a slide along itself (its axial spring): a von Mises two-bar truss."""
    model = pin.Model()
    rest = math.hypot(a, h)
    ends = []
    for name, x, angle in (("left", -a, math.atan2(h, a)), ("right", a, math.pi - math.atan2(h, a))):
        j = model.addJoint(0, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([x, 0.0, 0.0])), f"{name}_pin")
        model.appendBodyToJoint(j, pin.Inertia(0.1, np.zeros(3), np.eye(3) * 1e-3), pin.SE3.Identity())
        axis = np.array([math.cos(angle), math.sin(angle), 0.0])
        s = model.addJoint(j, pin.JointModelPrismaticUnaligned(axis), pin.SE3.Identity(), f"{name}_axial")
        model.appendBodyToJoint(s, pin.Inertia(0.1, np.zeros(3), np.eye(3) * 1e-3), pin.SE3.Identity())
        place = pin.SE3(np.eye(3), rest * axis)
        model.addFrame(pin.Frame(f"{name}_tip", s, 0, place, pin.FrameType.OP_FRAME))
        ends.append((s, place))
    apex = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, ends[0][0], ends[0][1], ends[1][0], ends[1][1],
                                    pin.LOCAL)
    return Mechanism(model, [apex], [])


def _cantilever(length: float, beam: Beam) -> Mechanism:
    """A link along x from a locked joint at the origin, its far end the frame ``tip``, as ``beam``."""
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "root")
    model.appendBodyToJoint(j, pin.Inertia(0.1, np.array([length / 2, 0.0, 0.0]), np.eye(3) * 1e-4), pin.SE3.Identity())
    model.addFrame(pin.Frame("link", j, 0, pin.SE3.Identity(), pin.FrameType.BODY))
    model.addFrame(pin.Frame("tip", j, 0, pin.SE3(np.eye(3), np.array([length, 0.0, 0.0])), pin.FrameType.OP_FRAME))
    return Mechanism(model, [], ["root"]).with_beams({"link": beam})


# ---------------------------------------------------------------- the linear limit and the tangent
@pytest.mark.parametrize("robot", ["5bar_linkage_iso3d", "h4"])
def test_a_tiny_load_moves_the_output_by_the_linear_compliance(robot, five_bar, elastic_h4):
    """Under a small wrench (microns of motion), displacement -> C w (relative 1e-6), and the
    tangent compliance there is the linear one (motors without a spring held, as equilibrium
    holds them)."""
    if robot == "h4":
        h4, em = elastic_h4
        mech, q, springs, frame, scale = em.mechanism, em.configuration(centre_pose(h4)), {}, "D", 1e-4
    else:
        (mech, q, springs), frame, scale = five_bar, "effector", 1e-4
    w = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05]) * scale
    eq = mech.equilibrium(q, springs, {frame: w})
    C = mech.compliance(q, springs, [frame], [n for n in mech.actuated if n not in springs])
    want = C @ w
    assert np.linalg.norm(eq.displacement(frame) - want) <= 1e-6 * np.linalg.norm(want)
    np.testing.assert_allclose(eq.compliance([frame]), C, rtol=0, atol=1e-6 * np.abs(C).max())
    assert eq.stable and eq.load_factor == 1.0 and eq.critical == ()


def test_the_tangent_compliance_is_the_derivative_of_the_equilibrium(five_bar):
    """Under its own weight and a payload (a sag of millimetres), eq.compliance equals the central
    differences of the equilibrium's output displacement in an extra wrench at the output
    (relative 1e-6), and differs from the unloaded compliance by far more than round-off."""
    mech, q, springs = five_bar
    base = dict(gravity=True, payload=("effector", Payload(0.5)))
    eq = mech.equilibrium(q, springs, **base)
    assert np.linalg.norm(eq.displacement("effector")[:3]) > 1e-3
    tangent = eq.compliance(["effector"])
    fd = np.empty((6, 6))
    for i in range(6):
        dw = np.zeros(6)
        dw[i] = 1e-2 if i < 3 else 1e-3
        plus = mech.equilibrium(q, springs, {"effector": dw}, **base).displacement("effector")
        minus = mech.equilibrium(q, springs, {"effector": -dw}, **base).displacement("effector")
        fd[:, i] = (plus - minus) / (2 * dw[i])
    np.testing.assert_allclose(tangent, fd, rtol=0, atol=1e-6 * np.abs(fd).max())
    linear = mech.compliance(q, springs, ["effector"])
    assert np.abs(tangent - linear).max() > 1e-3 * np.abs(linear).max()


def _coupled_chain() -> tuple[Mechanism, np.ndarray, dict[str, float]]:
    """Four hinges about y in a horizontal chain, j2 held to a cubic of j1 (a coupling whose row
    bends with q), the last link's end a frame ``tip``."""
    model = pin.Model()
    parent = 0
    for i in (1, 2, 3, 4):
        parent = model.addJoint(parent, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.2, 0.0, 0.0])), f"j{i}")
        body = pin.Inertia(0.5, np.array([0.1, 0.0, 0.0]), np.eye(3) * 1e-3)
        model.appendBodyToJoint(parent, body, pin.SE3.Identity())
    model.addFrame(pin.Frame("tip", parent, 0, pin.SE3(np.eye(3), np.array([0.2, 0.0, 0.0])), pin.FrameType.OP_FRAME))
    mech = Mechanism(model, couplings=[JointCoupling("j2", "j1", (0.05, 1.5, -2.0, 4.0), 0.0, 0.1)])
    q = mech.assemble(np.array([0.3, 0.0, -0.2, 0.1]), fixed=["j1"])
    return mech, q, {"j1": 40.0, "j2": 40.0, "j3": 25.0, "j4": 10.0}


@pytest.mark.parametrize(("robot", "loads"), [
    ("5bar_linkage_iso3d", {"effector": [5.0, -3.0, 8.0, 0.2, 0.1, -0.3]}),
    ("5bar with a beam", {"effector": [5.0, -3.0, 8.0, 0.2, 0.1, -0.3]}),
    ("robot_delta", {"eff": [1.0, 2.0, -3.0, 0.01, 0.0, 0.02]}),
    ("cassie_like", {}),
    ("toggle", {"left_tip": [0.0, -40.0, 0.0, 0.0, 0.0, 0.0]}),
    ("coupled chain", {"tip": [0.0, 0.0, -3.0, 0.0, 0.2, 0.0]}),
])
def test_the_closed_form_tangent_is_the_difference_of_the_forces(robot, loads):
    """At a loaded equilibrium under gravity, the tangent stiffness in closed form (dead loads and
    3-D closures as forces at body points, gravity's derivatives, a coupling's curvature, the 6-D
    closures' own differences) equals central differences of the generalised forces: to 1e-6 of
    its geometric part (H - K), which stands far above the differences' round-off."""
    if robot == "toggle":
        mech, springs = _toggle(0.3, 0.1), {"left_axial": 1e4, "right_axial": 1e4, "left_pin": 1.0, "right_pin": 1.0}
        q = mech.assemble()
    elif robot == "coupled chain":
        mech, q, springs = _coupled_chain()
    elif robot == "5bar with a beam":
        mech, _, springs = _corpus("5bar_linkage_iso3d")
        mech = mech.with_beams({"part_3": Beam.tube(0.025, 0.002, E=70e9, G=26e9)})
        q = mech.assemble()
    else:
        mech, q, springs = _corpus(robot)
    eq = mech.equilibrium(q, springs, loads, gravity=robot != "toggle")
    p = eq.problem
    assert p._ancestors is not None  # one-coordinate joints: the closed form
    exact = p.tangent_exact(eq.q, eq.load_factor, eq.mu)
    fd = p.tangent_fd(eq.q, eq.load_factor, eq.mu)
    geometric = fd - np.diag(p.k * p.free)
    assert np.abs(geometric).max() > 1e-6 * np.abs(p.k).max()  # far above the differences' round-off (~1e-9 K)
    np.testing.assert_allclose(exact, fd, rtol=0, atol=1e-6 * np.abs(geometric).max())


@pytest.mark.parametrize(("robot", "loads"), [
    ("5bar_linkage_iso3d", {"effector": [5.0, -3.0, 8.0, 0.2, 0.1, -0.3]}),
    ("robot_delta", {"eff": [1.0, 2.0, -3.0, 0.01, 0.0, 0.02]}),
    ("cassie_like", {}),
])
def test_a_moved_subtree_changes_the_forces_as_differences_of_the_placement_say(robot, loads):
    """Problem.moved_subtree (a joint placement's change at the fixed configuration, calibration's
    geometry partials) against central differences of the generalised forces with the placement
    itself moved (``M exp6(h e)``), for every joint and the six local directions: 1e-6 of the
    largest. The 6-D closures' frames sit on one side of some joints (the delta's, the leg's)."""
    mech, q, springs = _corpus(robot)
    eq = mech.equilibrium(q, springs, loads, gravity=True)
    p, model = eq.problem, mech.model
    step = 1e-6
    for jp in range(1, model.njoints):
        place = model.jointPlacements[jp].copy()
        pin.forwardKinematics(model, p.mech.data, eq.q)
        twists = (p.mech.data.oMi[int(model.parents[jp])] * place).toActionMatrix()
        closed = p.moved_subtree(eq.q, eq.load_factor, eq.mu, jp, twists)
        fd = np.zeros_like(closed)
        try:
            for a in range(6):
                e = np.zeros(6)
                e[a] = step
                model.jointPlacements[jp] = place * pin.exp6(pin.Motion(e))
                plus = p.gradient(eq.q, eq.load_factor, eq.mu)
                model.jointPlacements[jp] = place * pin.exp6(pin.Motion(-e))
                fd[:, a] = (plus - p.gradient(eq.q, eq.load_factor, eq.mu)) / (2 * step)
        finally:
            model.jointPlacements[jp] = place
        np.testing.assert_allclose(closed, fd, rtol=0, atol=1e-6 * max(np.abs(fd).max(), 1.0),
                                   err_msg=model.names[jp])


@pytest.mark.parametrize("joint", ["ball", "free"])
def test_a_ball_or_free_joints_tangent_is_in_closed_form_too(joint):
    """A rod on a ball joint (or a free joint, its six coordinates sprung) with a hinge below it,
    tilted and loaded: the closed form (the joint's own coordinates turning its columns, its
    spring's curvature by differences) equals central differences of the generalised forces."""
    model = pin.Model()
    kind = pin.JointModelSpherical() if joint == "ball" else pin.JointModelFreeFlyer()
    j = model.addJoint(0, kind, pin.SE3.Identity(), "root")
    model.appendBodyToJoint(j, pin.Inertia(1.0, np.array([0.0, 0.0, 0.3]), np.eye(3) * 1e-3), pin.SE3.Identity())
    h = model.addJoint(j, pin.JointModelRX(), pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.6])), "hinge")
    model.appendBodyToJoint(h, pin.Inertia(0.5, np.array([0.0, 0.1, 0.2]), np.eye(3) * 1e-3), pin.SE3.Identity())
    model.addFrame(pin.Frame("tip", h, 0, pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.4])), pin.FrameType.OP_FRAME))
    mech = Mechanism(model)
    q = pin.integrate(model, pin.neutral(model), np.r_[np.zeros(model.nv - 4), 0.3, -0.2, 0.1, 0.4])
    eq = mech.equilibrium(q, {"root": 300.0, "hinge": 40.0}, {"tip": [2.0, -1.0, 0.5, 0.1, 0.0, 0.2]}, gravity=True)
    p = eq.problem
    assert p._ancestors is not None and p._curved.sum() == model.joints[j].nv
    exact, fd = p.tangent_exact(eq.q, 1.0, eq.mu), p.tangent_fd(eq.q, 1.0, eq.mu)
    geometric = fd - np.diag(p.k * p.free)
    assert np.abs(geometric).max() > 1e-3 * np.abs(p.k).max()
    np.testing.assert_allclose(exact, fd, rtol=0, atol=1e-6 * np.abs(geometric).max())


def test_a_joint_without_a_closed_form_takes_the_tangent_by_differences():
    """A ZYX-Euler ball joint (its columns depend on its angles): the tangent is :meth:`tangent_fd`'s."""
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelSphericalZYX(), pin.SE3.Identity(), "ball")
    model.appendBodyToJoint(j, pin.Inertia(1.0, np.array([0.0, 0.0, 0.3]), np.eye(3) * 1e-3), pin.SE3.Identity())
    mech = Mechanism(model)
    eq = mech.equilibrium(pin.neutral(model), {"ball": 200.0}, gravity=True)
    p = eq.problem
    assert p._ancestors is None
    np.testing.assert_array_equal(p.tangent(eq.q, 1.0, eq.mu), p.tangent_fd(eq.q, 1.0, eq.mu))


def test_a_batch_gives_each_configurations_equilibrium(five_bar):
    mech, q, springs = five_bar
    Q = mech.assemble(motors=[[0.0, 0.0], [0.05, -0.02]])
    loads = {"effector": [0.0, 0.0, -20.0]}
    got = mech.equilibrium(Q, springs, loads)
    for row, eq in zip(Q, got, strict=True):
        np.testing.assert_array_equal(eq.q, mech.equilibrium(row, springs, loads).q)


# ---------------------------------------------------------------- closed forms
def test_an_inverted_pendulum_buckles_at_k_over_l_onto_its_stable_branch():
    """Critical tip load k/L (a bifurcation, the rotation its mode); past it the equilibrium is the
    buckled one, k θ = P L sin θ, reported stable, with the crossing it took."""
    k, length = 20.0, 0.5
    mech = _pendulum(length)
    q = mech.assemble()
    crit = mech.critical_load(q, {"hinge": k}, {"tip": [0.0, 0.0, -1.0]})
    assert crit.kind == "bifurcation" and crit.factor == pytest.approx(k / length, rel=1e-6)
    assert abs(crit.mode[0]) == pytest.approx(1.0)
    p = 1.5 * k / length
    eq = mech.equilibrium(q, {"hinge": k}, {"tip": [0.0, 0.0, -p]})
    theta = float(eq.q[0])
    assert abs(theta) > 1.0 and eq.stable
    assert k * theta == pytest.approx(p * length * math.sin(theta), rel=1e-9)
    assert eq.critical[0] == pytest.approx(1 / 1.5, rel=1e-6)
    below = mech.equilibrium(q, {"hinge": k}, {"tip": [0.0, 0.0, -0.9 * k / length]})
    assert below.q[0] == 0.0 and below.stable  # straight below the critical load


def test_a_cantilevers_buckling_load_converges_to_eulers():
    """An aluminium rod, 0.5 m, 10 mm across, axial tip load: the critical load of the beam's
    virtual joints tends to Euler's pi^2 EI / 4 L^2 as the segments grow, like 1/n^2; three
    segments are within 1 %; the far end's compliance is the same for every count."""
    length, d, e = 0.5, 0.01, 70e9
    euler = math.pi**2 * e * (math.pi * d**4 / 64) / (4 * length**2)
    errors, tips = [], []
    for n in (1, 2, 3, 4):
        rod = Beam(**{**Beam.circle(d, e, 0.4 * e, to="tip").__dict__, "segments": n})
        mech = _cantilever(length, rod)
        q = mech.assemble()
        crit = mech.critical_load(q, {}, {"tip": [-1.0, 0.0, 0.0]}, max_factor=1e6)
        assert crit.kind == "bifurcation"
        errors.append(crit.factor / euler - 1.0)
        tips.append(mech.compliance(q, {}, ["tip"], ["root"]))
    assert all(-0.06 < err < 0 for err in errors) and abs(errors[2]) < 0.01
    for a, b in zip(errors, errors[1:], strict=False):
        assert abs(b) < abs(a)
    assert abs(errors[3]) * 16 == pytest.approx(abs(errors[1]) * 4, rel=0.05)  # second order in 1/n
    for tip in tips[1:]:
        np.testing.assert_allclose(tip, tips[0], rtol=1e-9, atol=1e-12 * np.abs(tips[0]).max())


def test_a_two_bar_toggle_snaps_through_at_its_limit_load():
    """The von Mises truss: apex load P(y) = 2 k y (l0 / l - 1), l = sqrt(a^2 + y^2), greatest at
    l^3 = l0 a^2. critical_load finds that limit; a larger load is refused with the factor
    reached; below it, the apex height solves P(y) = P."""
    a, h, k = 1.0, 0.2, 1e3
    mech = _toggle(a, h)
    q = mech.assemble()
    springs = {"left_axial": k, "right_axial": k}
    rest = math.hypot(a, h)
    ls = (rest * a * a) ** (1 / 3)
    ys = math.sqrt(ls**2 - a**2)
    limit = 2 * k * ys * (rest / ls - 1)
    crit = mech.critical_load(q, springs, {"left_tip": [0.0, -1.0, 0.0]}, max_factor=1e4)
    assert crit.kind == "limit" and crit.factor == pytest.approx(limit, rel=1e-6)
    with pytest.raises(LimitLoadError, match="limit point") as info:
        mech.equilibrium(q, springs, {"left_tip": [0.0, -1.2 * limit, 0.0]})
    assert info.value.factor * 1.2 == pytest.approx(1.0, rel=1e-6) and info.value.equilibrium.stable
    eq = mech.equilibrium(q, springs, {"left_tip": [0.0, -0.5 * limit, 0.0]})
    y = h + eq.displacement("left_tip")[1]
    assert 2 * k * y * (rest / math.hypot(a, y) - 1) == pytest.approx(0.5 * limit, rel=1e-9)


# ---------------------------------------------------------------- MuJoCo


def _mujoco():
    mj = pytest.importorskip("mujoco", reason="the MuJoCo checks need the mujoco extra (pip install h4pin[mujoco])")
    from h4pin.mechanism import mjcf_writer as mw

    if mw.version(mj.__version__) < mw.version(mw.MIN_MUJOCO_ELASTIC):
        pytest.skip(f"the elastic export needs MuJoCo >= {mw.MIN_MUJOCO_ELASTIC}; this is {mj.__version__}")
    return mj


def _settled_site(path: Path, site: str) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's (rest, settled) position of ``site`` under gravity: every joint damped near
    critically on its own inertia, stepped until the site moves less than 1e-8 of its sag in 500
    steps."""
    mj = _mujoco()
    from h4pin.mechanism import mjcf_writer as mw

    m = mj.MjModel.from_xml_path(str(path))
    k = m.jnt_stiffness[m.dof_jntid]
    m.dof_damping[:] = 2.0 * np.sqrt(np.maximum(k, 1e-9) * (m.dof_M0 + m.dof_armature))
    d = mj.MjData(m)
    mj.mj_resetDataKeyframe(m, d, m.key(mw.KEYFRAME).id)
    mj.mj_forward(m, d)
    start = d.site(site).xpos.copy()
    last = start
    for _ in range(400):
        for _ in range(500):
            mj.mj_step(m, d)
        x = d.site(site).xpos.copy()
        assert np.all(np.isfinite(x)), "MuJoCo diverged"
        if np.linalg.norm(x - last) < 1e-8 * max(np.linalg.norm(x - start), 1e-15):
            return start, x
        last = x
    raise AssertionError("not settled")


#: robot -> (output frame, MuJoCo time step: the delta's gram links need a small one for its
#: closures to stay far stiffer than its springs).
MUJOCO_ROBOTS = {"5bar_linkage_iso3d": ("effector", 5e-5), "robot_delta": ("eff", 3e-6)}


@pytest.mark.parametrize("robot", sorted(MUJOCO_ROBOTS))
def test_mujoco_settles_where_the_equilibrium_is(robot, tmp_path):
    """The elastic export (Mechanism.to_mjcf, the payload a body of its own) settled under gravity:
    the output moves as equilibrium says within 0.5 % (measured: 5-bar 3.5e-8, delta 2.0e-3)."""
    _mujoco()
    frame, dt = MUJOCO_ROBOTS[robot]
    mech, q, springs = _corpus(robot)
    payload = (frame, Payload(0.2))
    want = mech.equilibrium(q, springs, gravity=True, payload=payload).displacement(frame)[:3]
    path = mech.to_mjcf(tmp_path / f"{robot}.xml", springs, q, sites=[frame], timestep=dt, payload=payload)
    start, end = _settled_site(path, frame)
    assert np.linalg.norm(end - start - want) < 5e-3 * np.linalg.norm(want)


def _h4_settled(h4, q_rigid: np.ndarray, payload: float) -> tuple[np.ndarray, np.ndarray]:
    """The H4's own elastic MuJoCo file (h4pin.io.mjcf.elastic_spec, actuators locked at q_rigid, a
    point payload at D) under gravity: D at rest and settled (0.3 s, the springs damped)."""
    mj = _mujoco()
    from h4pin.io import mjcf

    m = mjcf.elastic_spec(h4, q=q_rigid, payload=payload).compile()
    heavy = m.dof_armature == 0
    m.dof_damping[heavy] = 1e-2 * m.jnt_stiffness[m.dof_jntid[heavy]]
    d = mj.MjData(m)
    mj.mj_resetDataKeyframe(m, d, m.key(mjcf.KEYFRAME).id)
    mj.mj_forward(m, d)
    start = d.site("D").xpos.copy()
    for _ in range(int(round(0.3 / m.opt.timestep))):
        mj.mj_step(m, d)
    assert np.abs(d.qvel).max() < 1e-6, "not settled"
    return start, d.site("D").xpos.copy()


@pytest.mark.parametrize("kg", [0.0, 2.0])
def test_the_h4s_sag_in_mujoco_is_its_equilibrium(kg, elastic_h4):
    """The H4 under its own weight (and a 2 kg payload at D): its elastic MuJoCo file settles where
    the equilibrium of its elastic model (as a Mechanism) is, within 0.5 % (measured 3e-6, 7e-7)."""
    h4, em = elastic_h4
    x = centre_pose(h4)
    payload = ("D", Payload(kg)) if kg else None
    want = em.mechanism.equilibrium(em.configuration(x), {}, gravity=True, payload=payload).displacement("D")[:3]
    start, end = _h4_settled(h4, h4.configuration(x), kg)
    assert np.linalg.norm(end - start - want) < 5e-3 * np.linalg.norm(want)


# ---------------------------------------------------------------- compensation
def test_compensated_motors_land_the_five_bars_tool_on_target(five_bar, tmp_path):
    """Under gravity and a payload the rigid inverse's tool sags by millimetres; the compensated
    motors put it on the target through the equilibrium (1 um), and in MuJoCo within 0.5 % of the
    sag MuJoCo shows at the rigid inverse."""
    mech, q, springs = five_bar
    d = mech.model.createData()
    pin.framesForwardKinematics(mech.model, d, q)
    target = d.oMf[mech.model.getFrameId("effector")].translation + [0.01, 0.0, 0.005]
    payload = ("effector", Payload(0.2))
    comp = mech.compensate({"effector": target}, springs, gravity=True, payload=payload)
    assert np.linalg.norm(comp.sag) > 1e-3 and np.max(np.abs(comp.error)) < 1e-6
    check = mech.equilibrium(comp.equilibrium.rest, springs, gravity=True, payload=payload)
    pin.framesForwardKinematics(mech.model, d, check.q)
    assert np.linalg.norm(d.oMf[mech.model.getFrameId("effector")].translation - target) < 1e-6
    _mujoco()
    errors = []
    for motors in (comp.rigid, comp.motors):
        rest = mech.assemble(comp.equilibrium.rest, motors=motors)
        path = mech.to_mjcf(tmp_path / "five.xml", springs, rest, sites=["effector"], payload=payload, overwrite=True)
        errors.append(np.linalg.norm(_settled_site(path, "effector")[1] - target))
    assert errors[1] < 5e-3 * errors[0]


def test_compensated_motors_land_the_h4s_tool_on_target(elastic_h4):
    """The H4 with a 0.5 kg payload off the centre: the compensated actuator angles put D on the
    target through the equilibrium (1 um) and in its elastic MuJoCo file within 0.5 % of the sag
    the file shows at the rigid inverse."""
    h4, em = elastic_h4
    x = centre_pose(h4) + np.array([0.05, -0.03, 0.02, 0.0])
    comp = em.mechanism.compensate({"D": x[:3]}, {}, gravity=True, payload=("D", Payload(0.5)),
                                   start=em.configuration(x))
    assert np.linalg.norm(comp.sag) > 1e-4 and np.max(np.abs(comp.error)) < 1e-6
    np.testing.assert_allclose(comp.rigid, h4.configuration(x)[[h4.model.joints[h4.model.getJointId(n)].idx_q
                                                                  for n in em.locked]], atol=1e-9)
    errors = []
    for eq_rest in (em.mechanism.assemble(comp.equilibrium.rest, motors=comp.rigid), comp.equilibrium.rest):
        _, end = _h4_settled(h4, eq_rest[em.q_index], 0.5)
        errors.append(np.linalg.norm(end - x[:3]))
    assert errors[1] < 5e-3 * errors[0]


# ---------------------------------------------------------------- hostile input
@pytest.mark.parametrize(("loads", "options", "error", "match"), [
    ({"effector": [np.nan, 0, 0]}, {}, ParameterError, "finite force"),
    ({"effector": [1e12, 0, 0]}, {}, ParameterError, "beyond any robot"),
    ({"effector": [1 + 2j, 0, 0]}, {}, ParameterError, "real numbers"),
    ({"effector": [True, 0, 0]}, {}, ParameterError, "real numbers"),
    ({"effector": [1, 2]}, {}, ParameterError, "force \\(3,\\)"),
    ({"nowhere": [1, 0, 0]}, {}, ParameterError, "no frame 'nowhere'"),
    (None, {}, ParameterError, "no load"),
    (None, {"payload": ("effector", Payload(1.0))}, ParameterError, "only with gravity"),
    (None, {"gravity": True, "payload": ("nowhere", Payload(1.0))}, ParameterError, "frame name of the model"),
    (None, {"gravity": "yes"}, ParameterError, "gravity: True or False"),
    ([1, 2, 3], {}, ParameterError, "a mapping"),
])
def test_bad_loads_are_typed_errors_naming_them(five_bar, loads, options, error, match):
    mech, q, springs = five_bar
    with pytest.raises(error, match=match):
        mech.equilibrium(q, springs, loads, **options)


def test_refusals_of_the_state_and_the_size(five_bar, monkeypatch):
    """An unassembled rest state, a rest state no spring restrains, too large a batch, an
    unreachable target: typed errors naming them."""
    from h4pin.mechanism.engine import UnassembledError, UnrestrainedMotionError

    mech, q, springs = five_bar
    with pytest.raises(UnassembledError, match="assembled"):
        mech.equilibrium(q + 0.1, springs, {"effector": [1.0, 0, 0]})
    toggle = _toggle(1.0, 0.2)
    with pytest.raises(UnrestrainedMotionError, match="strains no spring"):  # one bar's slide free
        toggle.equilibrium(toggle.assemble(), {"left_axial": 1e3}, {"left_tip": [0.0, -1.0, 0.0]})
    monkeypatch.setenv("H4PIN_TIME_LIMIT", "1")
    with pytest.raises(TooLargeError, match="loaded equilibria"):
        mech.equilibrium(np.tile(q, (10_000, 1)), springs, {"effector": [1.0, 0, 0]})
    with pytest.raises(ConvergenceError, match="targets"):
        mech.compensate({"effector": [10.0, 0.0, 0.0]}, springs, gravity=True, iterations=3)


# ---------------------------------------------------------------- the page's numbers
def _table(section: str) -> list[list[str]]:
    text = (Path(__file__).resolve().parent.parent / "docs" / "loaded.md").read_text(encoding="utf-8")
    body = text.split(section, 1)[1].split("\n\n", 2)[1]
    return [[c.strip() for c in line.strip("|").split("|")] for line in body.splitlines()[2:]]


def _number(cell: str) -> float:
    return float(cell.replace("−", "-").replace("%", "").strip())


def test_the_pages_numbers_are_the_codes(elastic_h4):
    """docs/loaded.md's tables against the code: the H4's sag and K_tt change at Table II's pose
    (own weight, 0.5 and 2 kg), and the cantilever's critical loads (1 to 4 segments)."""
    from h4pin.studies import loaded

    h4, _ = elastic_h4
    rows = _table("At Table II's pose (all actuators at 45°):")
    assert [r[0] for r in rows] == ["0 kg (own weight)", "0.5 kg", "2 kg"]
    for row, kg in zip(rows, (0.0, 0.5, 2.0), strict=True):
        s = loaded.sag(h4, centre_pose(h4), kg)
        d = s.displacement[0]
        assert [_number(v) for v in row[1].split(",")] == [round(v * 1e6, 1) + 0.0 for v in d[:3]]
        assert _number(row[2]) == round(d[4] * 1e6, 1)
        assert _number(row[3]) == round(s.change[0] * 100, 3)
    rows = _table("= 339.1 N):")
    length, d, e = 0.5, 0.01, 70e9
    for row in rows[:4]:
        n = int(row[0])
        rod = Beam(**{**Beam.circle(d, e, 0.4 * e, to="tip").__dict__, "segments": n})
        mech = _cantilever(length, rod)
        crit = mech.critical_load(mech.assemble(), {}, {"tip": [-1.0, 0.0, 0.0]}, max_factor=1e6)
        assert _number(row[1]) == round(crit.factor, 1)


# ---------------------------------------------------------------- the commands and the viewer
def test_the_atlas_maps_the_sag_where_the_equilibrium_puts_it(five_bar):
    """A motor-space atlas with gravity=True: its sag at each grid point is the output's
    displacement of Mechanism.equilibrium called there directly."""
    from h4pin.mechanism import atlas as motor_atlas

    mech, _, springs = five_bar
    ds = motor_atlas.atlas(mech, "effector", {m: (-0.05, 0.05, 2) for m in mech.actuated}, springs, gravity=True,
                           payload=0.2, progress=False)
    assert int((ds.status == motor_atlas.OK).sum()) == 4 and ds.attrs["gravity"] == 1
    for i in range(2):
        for j in range(2):
            q = ds.configuration.values[i, j]
            want = mech.equilibrium(q, springs, gravity=True, payload=("effector", Payload(0.2))).displacement(
                "effector")[:3]
            np.testing.assert_allclose(ds.sag.values[i, j], want, rtol=1e-12, atol=1e-15)
    with pytest.raises(ParameterError, match="only with gravity"):
        motor_atlas.atlas(mech, "effector", {m: (0.0, 0.0, 1) for m in mech.actuated}, springs, payload=0.2,
                          progress=False)


def test_table2_and_view_show_the_loaded_robot(monkeypatch, capsys, tmp_path, elastic_h4):
    """`h4pin table2 --gravity --payload 2` prints D's sag of the elastic model's equilibrium;
    `h4pin view --gravity` draws the loaded equilibrium and states its true |dD|; a payload without
    gravity or a mode is refused in one line."""
    from conftest import run_cli_in_process

    h4, em = elastic_h4
    eq = em.mechanism.equilibrium(em.configuration(centre_pose(h4)), {}, gravity=True, payload=("D", Payload(2.0)))
    d = eq.displacement("D") * 1e6
    code, out, err = run_cli_in_process(["table2", "--gravity", "--payload", "2"], monkeypatch, capsys)
    assert code == 0, err
    assert f"D sags by ({d[0]:.1f}, {d[1]:.1f}, {d[2]:.1f}) um" in out
    code, out, err = run_cli_in_process(["view", "--gravity", "--payload", "2", "--out", str(tmp_path / "v.html")],
                                        monkeypatch, capsys)
    assert code == 0, err
    assert "loaded equilibrium under its weight and 2 kg at D" in out
    assert f"true |dD| = {np.linalg.norm(d[:3]):.1f} um" in out
    code, _, err = run_cli_in_process(["table2", "--payload", "2"], monkeypatch, capsys)
    assert code == 2 and err.count("\n") == 1 and "--gravity" in err
