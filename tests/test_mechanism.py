# SPDX-License-Identifier: Apache-2.0
"""h4pin.mechanism.Mechanism: any closed-loop robot read from its own files (URDF + the closed-loop
toolbox's YAML sidecar, MJCF equalities), assembled, its compliance and its natural frequencies,
each against an independent route."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from kkt import constraint_rows, kkt_compliance, mass_matrix, nullspace_frequencies, spring_vector

import h4pin
from h4pin import ParameterError
from h4pin.kinematics.closed_form import centre_pose
from h4pin.mechanism import Mechanism
from h4pin.mechanism.engine import UnassembledError, UnrestrainedMotionError
from h4pin.robot import urdf_dir

ROOT = urdf_dir().parent


@pytest.fixture(scope="module")
def h4():
    return h4pin.load("prototype")


@pytest.fixture(scope="module")
def pose(h4):
    return centre_pose(h4) + np.array([0.03, -0.02, 0.01, 0.1])


def _by_name(mech: Mechanism, h4, q_h4: np.ndarray) -> np.ndarray:
    """The H4's configuration in the mechanism's coordinates, joint by joint by name."""
    q = pin.neutral(mech.model)
    for j in range(1, h4.model.njoints):
        name = h4.model.names[j]
        if mech.model.existJointName(name):
            jm, jh = mech.model.joints[mech.model.getJointId(name)], h4.model.joints[j]
            if jm.nq == jh.nq:
                q[jm.idx_q:jm.idx_q + jm.nq] = q_h4[jh.idx_q:jh.idx_q + jh.nq]
    return q


def test_the_h4_from_its_urdf_and_sidecar(h4, pose):
    """The H4's URDF and its toolbox sidecar: 8 named closures, the 4 motors of name_mot; with
    springs kc on the motors and everything else rigid, the compliance of D is eq. 30's control
    term (h4pin.compliance, consistent): another route entirely (the paper's matrices)."""
    mech = Mechanism.from_urdf(ROOT / "urdf" / "h4_prototype.urdf")
    assert mech.actuated == tuple(h4.actuated_joint_names) and len(mech.constraint_models) == 8
    q = _by_name(mech, h4, h4.configuration(pose))
    kc = h4.geometry.springs["kc"]
    C = mech.compliance(q, dict(zip(mech.actuated, kc, strict=True)), ["D"])
    control = h4pin.compliance(h4, pose, "consistent", terms=True).terms["control"]
    assert C.shape == (6, 6)
    np.testing.assert_allclose(C[:3, :3], control[:3, :3], rtol=0, atol=1e-10 * np.abs(control).max())
    np.testing.assert_allclose(C[5, :3], control[5, :3], rtol=0, atol=1e-10 * np.abs(control).max())


def test_the_h4_from_its_mjcf(h4, pose):
    """The H4's MJCF (connect equalities): assembled from the neutral configuration with the
    motors held at the pose's angles, D is at the pose and the control term is found again."""
    if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
        pytest.skip(f"needs Pinocchio >= 4 (closures read from MJCF), this is {pin.__version__}")
    mech = Mechanism.from_mjcf(ROOT / "mjcf" / "h4_prototype.xml")
    assert mech.actuated == tuple(h4.actuated_joint_names)
    # the file's own equality names (Pinocchio's reader leaves them unnamed)
    assert [cm.name for cm in mech.constraint_models] == [f"closure_{i}{j}" for i in range(1, 5) for j in (1, 2)]
    start = _by_name(mech, h4, h4.configuration(pose))  # motors at the pose; the plate left at its neutral place
    q = mech.assemble(start)
    assert max(max(e) for e in mech.closure_errors(q).values()) <= 1e-10
    d = mech.model.createData()
    pin.framesForwardKinematics(mech.model, d, q)
    from h4pin.mechanism.engine import frame_id

    np.testing.assert_allclose(d.oMf[frame_id(mech.model, "D")].translation, pose[:3], rtol=0, atol=1e-9)
    kc = h4.geometry.springs["kc"]
    C = mech.compliance(q, dict(zip(mech.actuated, kc, strict=True)), "D")
    control = h4pin.compliance(h4, pose, "consistent", terms=True).terms["control"]
    np.testing.assert_allclose(C[:3, :3], control[:3, :3], rtol=0, atol=1e-9 * np.abs(control).max())


def test_the_elastic_h4_is_a_mechanism(h4, pose):
    """The H4's elastic model as a Mechanism: its compliance at D and its modes with the elastic
    model's masses equal the plain Pinocchio + numpy route of tests/kkt.py (the KKT system
    ``[[K, Aᵀ], [A, 0]]`` for the compliance, the generalized eigenproblem on null(A) for every
    frequency), A from ``getFrameJacobian`` at the closures' anchors and the locked actuators'
    rows: none of the engine's scaling, null-space or condensation code."""
    em = h4pin.elastic_model(h4)
    mech = em.mechanism
    assert mech is em.mechanism and isinstance(mech, Mechanism)  # made once, kept
    q = em.configuration(pose)
    C = mech.compliance(q, em.stiffness, ["D"], locked=em.locked)
    a, d = constraint_rows(mech.model, mech.constraint_models, q, em.locked)
    k = spring_vector(mech.model, em.stiffness)
    jo = pin.getFrameJacobian(mech.model, d, mech.model.getFrameId("D"), pin.LOCAL_WORLD_ALIGNED)
    want = kkt_compliance(a, k, jo)
    np.testing.assert_allclose(C, want, rtol=0, atol=1e-10 * np.abs(want).max())
    got = mech.modes(q, em.stiffness, locked=em.locked).frequencies
    want = nullspace_frequencies(a, k, mass_matrix(mech.model, d, q))
    assert len(got) == len(want) == 16
    np.testing.assert_allclose(got, want, rtol=1e-10)


def test_assemble_closes_the_loops_or_says_which_does_not(h4):
    mech = Mechanism.from_urdf(ROOT / "urdf" / "h4_prototype.urdf")
    q = mech.assemble()  # from the neutral configuration (the URDF's reference is assembled)
    q_off = pin.integrate(mech.model, q, 0.02 * np.random.default_rng(1).normal(size=mech.model.nv))
    assert max(max(e) for e in mech.closure_errors(q_off).values()) > 1e-3
    back = mech.assemble(q_off)
    assert max(max(e) for e in mech.closure_errors(back).values()) <= 1e-10
    every = list(mech.model.names)[1:]  # nothing free: the loops cannot close
    with pytest.raises(UnassembledError, match=r"closure '.*' is off by"):
        mech.assemble(q_off, fixed=every, iterations=5)


def test_joints_by_id_and_typed_errors(h4):
    """Joints may be Pinocchio ids; unknown joints, frames and closures are typed errors naming them."""
    base = Mechanism.from_urdf(ROOT / "urdf" / "h4_prototype.urdf")
    ids = [base.model.getJointId(n) for n in base.actuated]
    again = Mechanism(base.model, base.constraint_models, actuated=ids)
    assert again.actuated == base.actuated
    q = base.assemble()
    with pytest.raises(ParameterError, match="no joint 'motor_9'"):
        Mechanism(base.model, base.constraint_models, actuated=["motor_9"])
    with pytest.raises(ParameterError, match="joint id 99"):
        base.compliance(q, {99: 1.0}, ["D"])
    with pytest.raises(ParameterError, match="no frame 'tool'"):
        base.compliance(q, dict.fromkeys(base.actuated, 1e3), ["tool"])
    with pytest.raises(ParameterError, match="a pinocchio.Model"):
        Mechanism("h4_prototype.urdf")
    with pytest.raises(UnrestrainedMotionError):
        base.compliance(q, {base.actuated[0]: 1e3}, ["D"])  # three motors free: the plate moves freely
    with pytest.raises(UnassembledError, match="closure"):
        base.compliance(pin.neutral(base.model) + 0.1, dict.fromkeys(base.actuated, 1e3), ["D"])
    with pytest.raises(AttributeError, match="immutable"):
        base.name = "x"


ROBOTS = ROOT / "tests" / "robots"
#: Robots of Gepetto's example-parallel-robots (tests/robots/README.md): the output frame, and the
#: joints locked to hold the spin a 6-D weld between two dummy links leaves free (one per loop).
ELSEWHERE = {
    "5bar_linkage_iso3d": ("closedloop3D_1B", ()),
    "5bar_linkage": ("closedloop1_A", ("closedloop1_A",)),
    "robot_delta": ("closedloop1_A", ("closedloop1_A", "closedloop2_B", "closedloop3_A")),
}


def _motion_per_motor(mech, q, held, h=1e-6):
    """G (nv, motors): d q / d theta of the assembled mechanism, by central differences of
    :meth:`Mechanism.assemble` with the motors (and ``held``) fixed: an independent route
    (Gauss-Newton on the closures, no admissible-motion basis, no springs)."""
    cols = []
    for name in mech.actuated:
        idx = mech.model.joints[mech.model.getJointId(name)].idx_q
        ends = []
        for sign in (1.0, -1.0):
            start = q.copy()
            start[idx] += sign * h
            ends.append(mech.assemble(start, fixed=(*mech.actuated, *held), tol=1e-13))
        cols.append(pin.difference(mech.model, ends[1], ends[0]) / (2 * h))
    return np.column_stack(cols)


@pytest.mark.parametrize("robot", list(ELSEWHERE))
def test_robots_from_elsewhere(robot):
    """Each robot from its own URDF and sidecar: assembled to 1e-10; the compliance of its output
    frame under motor springs equals J diag(1/k) J^T with J = d p / d theta by finite differences
    of the assembly (to 1e-6); its natural frequencies equal those of the reduced model
    G^T M G, G = d q / d theta (to 1e-5)."""
    frame, held = ELSEWHERE[robot]
    mech = Mechanism.from_urdf(ROBOTS / robot / "robot.urdf")
    assert len(mech.actuated) == 2 and len(mech.constraint_models) >= 1
    q0 = pin.neutral(mech.model) + 0.05  # q = 0 is not assembled in these files
    q = mech.assemble(q0, fixed=held)
    assert max(max(e) for e in mech.closure_errors(q).values()) <= 1e-10
    k = np.array([2.0e3, 3.0e3])
    springs = dict(zip(mech.actuated, k, strict=True))
    C = mech.compliance(q, springs, [frame], locked=held)
    G = _motion_per_motor(mech, q, held)
    d = mech.model.createData()
    pin.computeJointJacobians(mech.model, d, q)
    from h4pin.mechanism.engine import frame_id

    J = pin.getFrameJacobian(mech.model, d, frame_id(mech.model, frame), pin.LOCAL_WORLD_ALIGNED) @ G
    want = J @ np.diag(1.0 / k) @ J.T
    np.testing.assert_allclose(C, want, rtol=0, atol=1e-6 * np.abs(want).max())
    assert np.abs(want[:3, :3]).max() > 0
    modes = mech.modes(q, springs, locked=held)
    M = pin.crba(mech.model, d, q)
    M = np.triu(M) + np.triu(M, 1).T
    reduced = G.T @ M @ G
    lam = np.linalg.eigvals(np.linalg.solve(reduced, np.diag(k))).real
    np.testing.assert_allclose(modes.frequencies, np.sort(np.sqrt(lam)) / (2 * np.pi), rtol=1e-5)


def test_the_walk_through_of_the_doc_runs(monkeypatch):
    """docs/mechanisms.md's python blocks, in order, from the repository's root."""
    import re

    text = (ROOT / "docs" / "mechanisms.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    try:
        import mujoco  # noqa: F401
    except ImportError:  # the elastic MuJoCo block needs the mujoco extra (CI's oldest-Pinocchio run lacks it)
        blocks = [b for b in blocks if "import mujoco" not in b]
    code = "\n".join(blocks)
    monkeypatch.chdir(ROOT)
    namespace: dict = {}
    exec(compile(code, "docs/mechanisms.md", "exec"), namespace)
    assert namespace["C"].shape == (6, 6) and len(namespace["modes"].frequencies) == 2
    assert np.all(namespace["modes"].frequencies > 0)


def test_the_viewer_draws_any_mechanism_and_its_ellipsoid(no_process_left):
    """A five-bar from elsewhere in meshcat: a self-contained page with its joints, links, closure
    points and the ellipsoid of the tool's compliance (axes and radii of the compliance's
    translational block), and no server left behind."""
    import base64
    import re

    import umsgpack

    from h4pin.mechanism import scene as scene_module

    five_bar = Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")
    q = five_bar.assemble(pin.neutral(five_bar.model) + 0.05)
    springs = {"mot1": 2.0e3, "mot2": 3.0e3}
    with scene_module.show(five_bar, q, springs, "closedloop3D_1B", scale=1.0) as scene:
        page = scene.html()
    objects = {}
    for blob in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", page):
        msg = umsgpack.unpackb(base64.b64decode(blob))
        objects.setdefault(msg["path"], []).append(msg)
    paths = set(objects)
    assert {f"/meshcat/mechanism/joints/{n}" for n in list(five_bar.model.names)[1:]} <= paths
    assert "/meshcat/mechanism/closures/" + five_bar.constraint_models[0].name + "/1" in paths
    ellipsoid = objects["/meshcat/mechanism/ellipsoid"]
    mesh = next(m for m in ellipsoid if m["type"] == "set_object")["object"]["object"]
    drawn = np.diag(np.reshape(mesh["matrix"], (4, 4), order="F"))[:3]  # a unit sphere scaled by the radii
    block = five_bar.compliance(q, springs, ["closedloop3D_1B"])[:3, :3]
    radii = np.linalg.eigvalsh(block) * 1e6 * 1e-3  # 1 mm per um/N
    np.testing.assert_allclose(np.sort(drawn), np.sort(np.maximum(radii, 1e-5)), rtol=1e-6)
    with pytest.raises(ParameterError, match="Mechanism"):
        scene_module.show("five bar", q)


def test_one_meaning_per_name_and_the_old_names_warn(h4, pose):
    """h4pin.compliance returns a Compliance; the arrays are compliance_matrix (engine, ElasticH4);
    h4pin.elastic.modes is the function, its module h4pin.elastic.modal. The names deprecated in
    0.1 are gone in 0.2; the generic names that moved from h4pin.elastic to h4pin.mechanism still
    resolve, with a DeprecationWarning naming the release that removes them, to the same objects."""
    import importlib

    import h4pin.elastic as elastic
    from h4pin import deprecations
    from h4pin.elastic import modal
    from h4pin.mechanism import engine

    assert callable(elastic.modes) and elastic.modes is modal.modes
    em = h4pin.elastic_model(h4)
    assert em.compliance_matrix(pose).shape == (8, 8)
    for owner, name in ((em, "compliance"), (elastic, "compliance"), (elastic, "MechanismModes"),
                        (engine, "SINGULAR_COND"), (engine, "compliance"), (h4pin, "Frequencies")):
        assert not hasattr(owner, name), name
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("h4pin.elastic.modes")
    for old, (new, removed) in deprecations.MOVED["h4pin.elastic"].items():
        with pytest.warns(DeprecationWarning, match=f"removed in h4pin {removed}"):
            assert getattr(elastic, old) is deprecations.resolve(new)


def test_the_h4_doors_point_a_mechanism_to_its_own_methods():
    """h4pin.compliance and h4pin.modes take the H4; given a Mechanism they say, in a whole
    message, which method of the Mechanism computes the same."""
    mech = Mechanism.from_urdf(ROOT / "tests" / "robots" / "5bar_linkage_iso3d" / "robot.urdf")
    with pytest.raises(h4pin.ParameterError) as err:
        h4pin.compliance(mech, np.zeros(4))
    assert "Mechanism.compliance(q, springs, outputs)" in str(err.value) and "..." not in str(err.value)
    with pytest.raises(h4pin.ParameterError) as err:
        h4pin.modes(mech, np.zeros(4))
    assert "Mechanism.modes(q, springs, locked)" in str(err.value) and "..." not in str(err.value)
