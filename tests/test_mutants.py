# SPDX-License-Identifier: Apache-2.0
"""Tests written against single edits of the package (mutants) that the default run let through,
each against something that shares no code with the edited line:

* joint couplings between joints with a ``ref`` (MJCF ``<equality><joint polycoef>``, with and
  without joint2): MuJoCo's own equality residual (``efc_pos``) and the relation as MuJoCo defines
  it, ``joint1 - ref1 = poly(joint2 - ref2)``, evaluated here on MuJoCo's ``qpos``;
* a sidecar's joint conversions (``UJOINT_ab``: a hinge about a, then one about b; ``SPHERICAL``;
  ``FIXED``): every link's placement from a forward kinematics of the URDF written here (its XML
  read with ElementTree);
* the compiled route given a configuration whose loops close but whose coupling is 1 mm off: the
  Pinocchio route's error;
* an H4 atlas streamed, interrupted and resumed: the uninterrupted atlas, element by element;
* assembly over a grid of motor positions: the closures' own errors, below 1e-10; and
  ``compliance_matrix`` called directly on corpus robots: the KKT route of ``tests/kkt.py`` on a
  model built here with Pinocchio's URDF parser and the sidecar's frame pairs.

The last section holds the tests added for the survivors of a ``scripts/mutate.py`` run (which
makes such edits on demand, not in CI): couplings built in code with their default origins, the
order of the joints an UnrestrainedMotionError names, the documented refusals of a zero or
infinite stiffness and of ``iterations=0``, and the batches' size estimates.
"""

from __future__ import annotations

import dataclasses
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from kkt import closure_rows, kkt_compliance, spring_vector

from h4pin import limits
from h4pin.errors import MechanismWarning, ParameterError

try:  # the generic engine's own package (h4pin >= 0.2), else its names in h4pin.elastic
    from h4pin.mechanism import (
        FrameOutput,
        JointCoupling,
        JointOutput,
        Mechanism,
        UnassembledError,
        UnrestrainedMotionError,
        compliance_matrix,
    )
except ImportError:
    from h4pin.elastic import (
        FrameOutput,
        JointCoupling,
        JointOutput,
        Mechanism,
        UnassembledError,
        UnrestrainedMotionError,
        compliance_matrix,
    )

yaml = pytest.importorskip("yaml")

ROBOTS = Path(__file__).resolve().parent / "robots"


# --------------------------------------------------------------------------------------------
# 1. A joint coupling whose joints have a ref: MuJoCo's residual.

#: A chain of four single-joint bodies, every hinge with a ref (rad), the wrist coupled to the
#: coupler by a quadratic: wrist - 0.2 = 0.05 + 0.7 (coupler + 0.5) + 0.3 (coupler + 0.5)^2, and
#: the roll held by an equality without joint2: roll - 0.1 = 0.25.
COUPLED_REF = """<mujoco model="coupled_ref">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base">
      <geom type="sphere" size="0.01" mass="0.1"/>
      <body name="crank">
        <joint name="crank" type="hinge" axis="0 0 1" ref="0.3"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.01" mass="0.4"/>
        <body name="coupler" pos="0.2 0 0">
          <joint name="coupler" type="hinge" axis="0 0 1" ref="-0.5"/>
          <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.01" mass="0.6"/>
          <body name="tip" pos="0.4 0 0">
            <joint name="wrist" type="hinge" axis="0 1 0" ref="0.2"/>
            <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.01" mass="0.2"/>
            <body name="hand" pos="0.1 0 0">
              <joint name="roll" type="hinge" axis="1 0 0" ref="0.1"/>
              <geom type="box" size="0.02 0.03 0.01" mass="0.1"/>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <joint joint1="wrist" joint2="coupler" polycoef="0.05 0.7 0.3 0 0"/>
    <joint joint1="roll" polycoef="0.25 0 0 0 0"/>
  </equality>
</mujoco>
"""


def _mujoco_state(mj, mech, q):
    """MuJoCo's data at Pinocchio's q of COUPLED_REF (every hinge its body's only joint: qpos is
    q), checked by the bodies' world positions, then ``mj_forward``."""
    mujoco = pytest.importorskip("mujoco")
    d = mujoco.MjData(mj)
    for i in range(mj.njnt):
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, i)
        d.qpos[mj.jnt_qposadr[i]] = q[mech.model.joints[mech.model.getJointId(name)].idx_q]
    mujoco.mj_forward(mj, d)
    pd = mech.model.createData()
    pin.framesForwardKinematics(mech.model, pd, q)
    for b in range(1, mj.nbody):
        f = pd.oMf[mech.model.getFrameId(mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b), pin.FrameType.BODY)]
        np.testing.assert_allclose(f.translation, d.xpos[b], rtol=0, atol=1e-12)
    return d


def _mujoco_couplings(mj, d):
    """{joint1: (MuJoCo's own residual of its joint equality, the relation evaluated here on
    qpos: joint1 - ref1 - poly(joint2 - ref2), or joint1 - ref1 - polycoef[0] without joint2;
    ref = qpos0)}."""
    mujoco = pytest.importorskip("mujoco")
    rows = {int(d.efc_id[r]): r for r in range(d.nefc)
            if int(d.efc_type[r]) == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)}
    assert sorted(rows) == list(range(mj.neq))
    out = {}
    for i in range(mj.neq):
        a1 = mj.jnt_qposadr[mj.eq_obj1id[i]]
        u1 = d.qpos[a1] - mj.qpos0[a1]
        if mj.eq_obj2id[i] < 0:
            mine = u1 - mj.eq_data[i, 0]
        else:
            a2 = mj.jnt_qposadr[mj.eq_obj2id[i]]
            u2 = d.qpos[a2] - mj.qpos0[a2]
            mine = u1 - sum(c * u2**k for k, c in enumerate(mj.eq_data[i, :5]))
        out[mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, mj.eq_obj1id[i])] = (float(d.efc_pos[rows[i]]),
                                                                                  float(mine))
    return out


def test_a_coupling_between_joints_with_a_ref_holds_as_mujoco_defines_it(tmp_path):
    """Every joint of the couplings has a non-zero ref: the configuration h4pin assembles (the
    coupler 0.4 rad off its ref, held) has MuJoCo's residuals 0; at random configurations h4pin's
    coupling errors are MuJoCo's residuals."""
    mujoco = pytest.importorskip("mujoco")
    if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
        pytest.skip("Pinocchio < 4 reads no closures from MJCF")
    path = tmp_path / "coupled_ref.xml"
    path.write_text(COUPLED_REF)
    mech = Mechanism.from_mjcf(path)
    mj = mujoco.MjModel.from_xml_path(str(path))
    assert len(mech.couplings) == 2 and np.all(mj.qpos0 != 0)
    model = mech.model
    start = np.array(mech.reference)
    start[model.joints[model.getJointId("coupler")].idx_q] += 0.4
    q = mech.assemble(start, fixed=["crank", "coupler"])
    assert q[model.joints[model.getJointId("coupler")].idx_q] == start[model.joints[model.getJointId("coupler")].idx_q]
    for theirs, mine in _mujoco_couplings(mj, _mujoco_state(mj, mech, q)).values():
        assert abs(theirs) < 1e-10 and abs(mine) < 1e-10
    rng = np.random.default_rng(4)
    for _ in range(5):
        q = np.array(mech.reference) + rng.uniform(-0.6, 0.6, model.nq)
        errors = mech.closure_errors(q)
        for joint, (theirs, mine) in _mujoco_couplings(mj, _mujoco_state(mj, mech, q)).items():
            assert abs(theirs - mine) < 1e-12 and abs(theirs) > 1e-3
            assert errors[f"coupling {joint}"][0] == pytest.approx(abs(theirs), rel=1e-12, abs=1e-14)


# --------------------------------------------------------------------------------------------
# 2. The sidecar's joint conversions (universal, ball, fixed), from the URDF's own geometry.

def _axis_rotation(axis, angle: float) -> np.ndarray:
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw: Rz(y) Ry(p) Rx(r)."""
    return _axis_rotation([0, 0, 1], y) @ _axis_rotation([0, 1, 0], p) @ _axis_rotation([1, 0, 0], r)


def _quaternion(x: float, y: float, z: float, w: float) -> np.ndarray:
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def urdf_placements(urdf: Path, conversions: dict[str, str], value) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every link's world (rotation, position), from the URDF's XML: each joint's origin (xyz,
    rpy), then its motion -- about its axis by ``value(joint)``, or as the sidecar converts it:
    ``UJOINT_ab`` turns about the joint frame's axis a by ``value(<joint>_a)``, then about the
    turned axis b by ``value(<joint>_b)``; ``SPHERICAL`` by the quaternion ``value(joint)``
    (x, y, z, w); ``FIXED`` not at all."""
    root = ET.parse(urdf).getroot()
    unit = {"X": [1, 0, 0], "Y": [0, 1, 0], "Z": [0, 0, 1]}
    joint_of = {}
    for j in root.findall("joint"):
        o = j.find("origin")
        xyz = np.array([float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()])
        rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
        ax = j.find("axis")
        axis = [float(v) for v in ax.get("xyz").split()] if ax is not None else [1.0, 0.0, 0.0]
        joint_of[j.find("child").get("link")] = (j.get("name"), j.get("type"), j.find("parent").get("link"), xyz,
                                                 _rpy(*rpy), axis)
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def place(link: str) -> tuple[np.ndarray, np.ndarray]:
        if link in out:
            return out[link]
        if link not in joint_of:  # the root
            out[link] = (np.eye(3), np.zeros(3))
            return out[link]
        name, kind, parent, xyz, rot, axis = joint_of[link]
        r0, p0 = place(parent)
        r, p = r0 @ rot, p0 + r0 @ xyz
        conv = conversions.get(name)
        if conv is not None and conv.startswith("UJOINT"):
            a, b = conv[-2], conv[-1]
            r = r @ _axis_rotation(unit[a], value(f"{name}_{a}")) @ _axis_rotation(unit[b], value(f"{name}_{b}"))
        elif conv == "SPHERICAL":
            r = r @ _quaternion(*value(name))
        elif conv == "FIXED" or kind == "fixed":
            pass
        elif kind == "revolute":
            r = r @ _axis_rotation(axis, value(name))
        elif kind == "prismatic":
            p = p + r @ (np.asarray(axis) / np.linalg.norm(axis)) * value(name)
        else:
            raise AssertionError(f"joint {name!r}: type {kind!r} not handled here")
        out[link] = (r, p)
        return out[link]

    for link in root.findall("link"):
        place(link.get("name"))
    return out


@pytest.mark.parametrize("robot", ["battobot_6d", "digit_like_2legs", "digit_like_2legs_6D"])
def test_sidecar_joint_conversions_match_the_urdf_geometry(robot):
    """Every link's placement at a random configuration (all hinges and balls turned) equals the
    URDF's own forward kinematics with each ``UJOINT_ab`` a hinge about a then one about b, each
    ``SPHERICAL`` a ball, each ``FIXED`` joint at 0 (and not a joint of the model)."""
    urdf = ROBOTS / robot / "robot.urdf"
    side = yaml.safe_load((ROBOTS / robot / "robot.yaml").read_text())
    conversions = dict(zip(side["joint_name"], side["joint_type"], strict=True))
    assert any(c == "FIXED" or (c.startswith("UJOINT") and c[-2] != c[-1]) for c in conversions.values())
    mech = Mechanism.from_urdf(urdf)
    model = mech.model
    assert not any(model.existJointName(n) for n, c in conversions.items() if c == "FIXED")
    rng = np.random.default_rng(2)
    q = pin.neutral(model)
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nq == 1:
            q[jm.idx_q] = rng.uniform(-1.2, 1.2)
        else:
            assert jm.nq == 4, model.names[j]
            x = rng.normal(size=4)
            q[jm.idx_q:jm.idx_q + 4] = x / np.linalg.norm(x)

    def value(name: str):
        jm = model.joints[model.getJointId(name)]
        assert model.existJointName(name), name
        return q[jm.idx_q] if jm.nq == 1 else q[jm.idx_q:jm.idx_q + 4]

    want = urdf_placements(urdf, conversions, value)
    d = model.createData()
    pin.framesForwardKinematics(model, d, q)
    assert len(want) == sum(f.type == pin.FrameType.BODY for f in model.frames)
    for link, (r, p) in want.items():
        got = d.oMf[model.getFrameId(link, pin.FrameType.BODY)]
        np.testing.assert_allclose(got.rotation, r, rtol=0, atol=1e-12, err_msg=link)
        np.testing.assert_allclose(got.translation, p, rtol=0, atol=1e-12, err_msg=link)


# --------------------------------------------------------------------------------------------
# 3. The compiled route and a coupling that does not hold.

def test_the_compiled_route_refuses_a_configuration_whose_coupling_is_off():
    """coupled.xml (a loop and rocker_pitch = coupler_roll), assembled with the coupling shifted
    by 1 mm (1e-3 rad): the loop closes, the file's coupling is 1e-3 off; the compiled route
    raises the Pinocchio route's UnassembledError, for one configuration and in a batch, for
    compliance and natural frequencies."""
    if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
        pytest.skip("Pinocchio < 4 reads no closures from MJCF")
    pytest.importorskip("mujoco")
    mech = Mechanism.from_mjcf(ROBOTS / "synthetic" / "coupled.xml")
    (c,) = mech.couplings
    shifted = dataclasses.replace(c, poly=(c.poly[0] + 1e-3, *c.poly[1:]))
    other = Mechanism(mech.model, mech.constraint_models, mech.actuated, reference=mech.reference,
                      ranges=mech.ranges, couplings=[shifted])
    q, good = other.assemble(), mech.assemble()
    errors = mech.closure_errors(q)
    assert errors["closure_1"][0] < 1e-12 and errors["coupling rocker_pitch"][0] == pytest.approx(1e-3, rel=1e-9)
    springs = {n: 50.0 * (1 + 0.1 * i) for i, n in enumerate(list(mech.model.names)[1:])}
    out = [FrameOutput("coupler", kind=pin.FrameType.BODY)]
    for call in (lambda m: mech.compliance(q, springs, out, method=m),
                 lambda m: mech.compliance(np.array([good, q]), springs, out, method=m),
                 lambda m: mech.modes(np.array([good, q]), springs, method=m)):
        messages = []
        for method in ("pinocchio", "compiled"):
            with pytest.raises(UnassembledError, match="coupling of 'rocker_pitch' does not hold") as info:
                call(method)
            messages.append(str(info.value))
        assert messages[0] == messages[1]
    # and the compiled route does compute the good configuration (the refusal is not a blanket one)
    want = mech.compliance(good, springs, out, method="pinocchio")
    assert np.abs(want).max() > 1e-3
    np.testing.assert_allclose(mech.compliance(np.array([good]), springs, out, method="compiled")[0], want, rtol=0,
                               atol=1e-12 * np.abs(want).max())


# --------------------------------------------------------------------------------------------
# 4. An H4 atlas interrupted and resumed.

def test_a_small_h4_atlas_resumed_equals_the_uninterrupted_one(proto, centre, tmp_path, monkeypatch):
    """A 2 x 4 x 4 atlas of 8 blocks of 4 poses, interrupted in its 3rd block, then resumed: the
    resumed run computes the 6 blocks not done, and the store equals the atlas computed in memory
    without interruption, element by element (every pose reachable)."""
    pytest.importorskip("zarr")
    from h4pin.studies import atlas

    grid = {"x": centre[0] + np.linspace(-0.06, 0.06, 4), "y": centre[1] + np.linspace(-0.05, 0.05, 4),
            "z": [centre[2]], "theta": [0.0, 0.3]}
    want = atlas.atlas(proto, **grid, chunk=4, progress=False)
    assert (want.status.values == 0).all()
    real = atlas._derived.atlas_fields
    calls = []

    def interrupted_at_3(*args):
        calls.append(len(args[2]))
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args)

    path = tmp_path / "a.zarr"
    monkeypatch.setattr(atlas._derived, "atlas_fields", interrupted_at_3)
    with pytest.raises(KeyboardInterrupt):
        atlas.stream(proto, **grid, chunk=4, progress=False, out=path)
    assert not path.exists() and [p.name for p in tmp_path.iterdir()]  # the partial store, beside
    calls.clear()
    monkeypatch.setattr(atlas._derived, "atlas_fields", lambda *a: (calls.append(len(a[2])), real(*a))[1])
    got = atlas.stream(proto, **grid, chunk=4, progress=False, out=path).load()
    assert calls == [4] * 6
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.zarr"]  # no partial store left
    for name in (*atlas.QUANTITIES, "status"):
        a, b = got[name].values, want[name].values
        assert a.shape == b.shape == (2, 1, 4, 4), name
        assert np.all(np.isfinite(b)), name
        np.testing.assert_array_equal(a, b, err_msg=name)


# --------------------------------------------------------------------------------------------
# 5. Assembly to its tolerance, and compliance_matrix against the KKT route.

@pytest.mark.parametrize(("robot", "n", "span"), [("5bar_linkage_iso3d", 7, 0.3), ("5bar_linkage", 9, 0.4)])
def test_assembly_over_a_motor_grid_closes_to_1e_10(robot, n, span):
    """assemble(motors=grid) (continuation, Newton's steps first) over n x n motor positions
    around the reference's: every configuration holds the motors and closes the loop within
    1e-10 m, the closures' own errors at each."""
    mech = Mechanism.from_urdf(ROBOTS / robot / "robot.urdf")
    ref = mech.assemble()
    idx = [mech.model.joints[mech.model.getJointId(m)].idx_q for m in mech.actuated]
    steps = np.linspace(-span, span, n)
    grid = np.array([ref[idx] + [a, b] for a in steps for b in steps])
    Q = mech.assemble(ref, motors=grid)
    np.testing.assert_array_equal(Q[:, idx], grid)
    worst = [max(max(e) for e in mech.closure_errors(q).values()) for q in Q]
    assert max(worst) < 1e-10, (int(np.argmax(worst)), max(worst))


def _sidecar_model(robot: str) -> tuple[pin.Model, list, dict]:
    """The robot as Gepetto's loader builds it when the sidecar converts no joint: Pinocchio's URDF
    parser, each frame pair a closure between the frames' parent joints at their placements."""
    side = yaml.safe_load((ROBOTS / robot / "robot.yaml").read_text())
    assert not side.get("joint_name")
    model = pin.buildModelFromUrdf(str(ROBOTS / robot / "robot.urdf"))
    cms = []
    for (a, b), kind in zip(side["closed_loop"], side["type"], strict=True):
        f1, f2 = (model.frames[model.getFrameId(n)] for n in (a, b))
        ctype = pin.ContactType.CONTACT_3D if kind.upper() == "3D" else pin.ContactType.CONTACT_6D
        cms.append(pin.RigidConstraintModel(ctype, model, f1.parentJoint, f1.placement, f2.parentJoint, f2.placement,
                                            pin.ReferenceFrame.LOCAL))
    return model, cms, side


@pytest.mark.parametrize("robot", ["5bar_linkage_iso3d", "5bar_linkage_iso6d"])
def test_compliance_matrix_equals_the_kkt_route(robot):
    """engine.compliance_matrix called directly (a 3-D and a 6-D closure; a frame in world-aligned
    and local axes and a joint output; springs everywhere, then with an extra constraint row, then
    with a motor locked)
    equals the dense KKT solve of tests/kkt.py on the same closures' rows."""
    model, cms, side = _sidecar_model(robot)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        q = Mechanism(model, cms, side["name_mot"]).assemble()
    d = model.createData()
    pin.computeJointJacobians(model, d, q)
    pin.updateFramePlacements(model, d)
    for cm in cms:  # closed, by the closure's own frames
        o1, o2 = d.oMi[cm.joint1_id] * cm.joint1_placement, d.oMi[cm.joint2_id] * cm.joint2_placement
        assert np.linalg.norm(o1.translation - o2.translation) < 1e-10
        if cm.type == pin.ContactType.CONTACT_6D:
            assert np.linalg.norm(pin.log3(o1.rotation.T @ o2.rotation)) < 1e-10
    names = list(model.names)[1:]
    frame = side["closed_loop"][0][0]
    free = next(n for n in names if n not in side["name_mot"])
    outputs = [FrameOutput(frame), FrameOutput(frame, reference=pin.LOCAL, rows=(0, 1, 5)), JointOutput(free, -2.0)]
    fid = model.getFrameId(frame)
    jo = np.vstack([pin.getFrameJacobian(model, d, fid, pin.LOCAL_WORLD_ALIGNED),
                    pin.getFrameJacobian(model, d, fid, pin.LOCAL)[[0, 1, 5]],
                    -2.0 * np.eye(model.nv)[model.joints[model.getJointId(free)].idx_v]])
    eye = np.eye(model.nv)
    extra = np.zeros((1, model.nv))
    extra[0, model.joints[model.getJointId(free)].idx_v] = 1.0
    extra[0, model.joints[model.getJointId(side["name_mot"][1])].idx_v] = -0.5
    closures = np.vstack([closure_rows(model, d, cm) for cm in cms])
    for locked, rows in (((), None), ((), extra), (side["name_mot"][:1], None)):
        springs = {n: 30.0 * (1 + 0.2 * i) for i, n in enumerate(names) if n not in locked}
        held = [eye[model.joints[model.getJointId(m)].idx_v] for m in locked]
        a = np.vstack([closures, *held] + ([] if rows is None else [rows]))
        got = compliance_matrix(model, cms, q, locked=tuple(locked), stiffness=springs, outputs=outputs,
                                extra_rows=rows)
        want = kkt_compliance(a, spring_vector(model, springs), jo)
        assert np.abs(want).max() > 1e-4
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())


# --------------------------------------------------------------------------------------------
# 6. Survivors of scripts/mutate.py (its run of 40 mutants over the generic engine).

def test_couplings_built_in_code_measure_from_zero_by_default():
    """JointCoupling's origins default to 0 (``u = q``): on a chain of three hinges,
    j2 = 0.1 + 2 j1 and j3 = 0.25 (no joint2) hold, by hand, where the assembly puts them."""
    model = pin.Model()
    parent = 0
    for i in (1, 2, 3):
        parent = model.addJoint(parent, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([0.2, 0.0, 0.0])), f"j{i}")
        model.appendBodyToJoint(parent, pin.Inertia.FromSphere(1.0, 0.05), pin.SE3.Identity())
    mech = Mechanism(model, couplings=[JointCoupling("j2", "j1", (0.1, 2.0)), JointCoupling("j3", None, (0.25,))])
    q = mech.assemble(np.array([0.3, -0.4, 0.9]), fixed=["j1"])
    np.testing.assert_allclose(q, [0.3, 0.1 + 2.0 * 0.3, 0.25], rtol=0, atol=1e-12)
    errors = mech.closure_errors(np.array([0.5, 1.0, -0.5]))
    assert errors["coupling j2"][0] == pytest.approx(abs(1.0 - 0.1 - 2.0 * 0.5), rel=1e-14)
    assert errors["coupling j3"][0] == pytest.approx(abs(-0.5 - 0.25), rel=1e-14)


def test_an_unrestrained_motion_names_its_joints_largest_first():
    """The five-bar with a spring on one motor only: one admissible motion strains no spring; the
    error names the joints it moves in decreasing amplitude, the motion computed here as the null
    space of the closure's rows and the sprung motor's (tests/kkt.py, scipy)."""
    from kkt import constraint_rows
    from scipy.linalg import null_space

    mech = Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")
    model = mech.model
    q = mech.assemble()
    with pytest.raises(UnrestrainedMotionError) as info:
        mech.compliance(q, {"mot1": 10.0}, ["closedloop3D_1B"])
    a, _ = constraint_rows(model, mech.constraint_models, q, ["mot1"])
    motion = null_space(a)
    assert motion.shape[1] == 1
    amp = {model.names[j]: abs(motion[model.joints[j].idx_v, 0]) for j in range(1, model.njoints)}
    want = tuple(sorted((n for n in amp if amp[n] > 0.1 * max(amp.values())), key=lambda n: -amp[n]))
    assert len(want) >= 3 and info.value.joints == want
    assert str(info.value).index(want[0]) < str(info.value).index(want[-1])


def test_documented_refusals_of_a_spring_and_of_the_assembly():
    """A zero or an infinite stiffness is refused ("finite and > 0"), and so is ``iterations=0``
    ("an integer >= 1"), by name."""
    mech = Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")
    q = mech.assemble()
    springs = {n: 10.0 for n in list(mech.model.names)[1:]}
    for bad in (0.0, float("inf")):
        with pytest.raises(ParameterError, match="stiffness of joint 'mot1' must be finite and > 0"):
            mech.compliance(q, {**springs, "mot1": bad}, ["closedloop3D_1B"])
    with pytest.raises(ParameterError, match="iterations: an integer >= 1, got 0"):
        mech.assemble(iterations=0)


def test_batch_size_estimates_cover_the_arrays_the_calls_hold(monkeypatch):
    """Each memory estimate of a batch call (h4pin.limits.check_size's ``need``) is at least the
    bytes of the arrays the call holds: the batch's own copy (N, nq), the compliances (N, m, m)
    and the frequencies it returns -- on WL16 (nq = 42: a configuration's copy alone is larger
    than the fixed part of the estimate)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        mech = Mechanism.from_urdf(ROBOTS / "wl16_like" / "robot.urdf")
        q = mech.assemble()
    names = list(mech.model.names)[1:]
    springs = {n: (2e3 if n in mech.actuated else 50.0) * (1 + 0.1 * (i % 7)) for i, n in enumerate(names)}
    frame = yaml.safe_load((ROBOTS / "wl16_like" / "robot.yaml").read_text())["closed_loop"][0][0]
    Q = np.array([q, q, q])
    seen: list[tuple[str, float]] = []
    real = limits.check_size

    def recorder(what, need, *args, **kwargs):
        seen.append((what, float(need)))
        return real(what, need, *args, **kwargs)

    monkeypatch.setattr(limits, "check_size", recorder)
    C = mech.compliance(Q, springs, [frame, FrameOutput(frame, reference=pin.LOCAL)])
    freq = mech.modes(Q, springs).frequencies
    assert mech.model.nq * 8 > 256 and np.all(np.isfinite(freq[:, 0]))
    batch = [need for what, need in seen if what.endswith(": 3 configurations")]
    assert len(batch) == 2 and min(batch) >= Q.nbytes
    (comp,) = [need for what, need in seen if "compliance of 3 configurations" in what]
    assert comp >= C.nbytes
    (modal,) = [need for what, need in seen if "natural frequencies of 3 configurations" in what]
    assert modal >= np.isfinite(freq).sum() * 8
