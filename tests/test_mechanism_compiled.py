# SPDX-License-Identifier: Apache-2.0
"""The compiled generic path (h4pin.mechanism.compiled, through h4pin.mechanism.batch) against the
Pinocchio route (h4pin.mechanism.engine with Pinocchio's Jacobians, SVD null space and CRBA) on
every robot of the corpus that assembles, and the batch calls of Mechanism: a batch gives what
one configuration gives, threads change nothing, a configuration the compiled path cannot judge
gets the Pinocchio route's error with its index, and assembly over motor positions."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from h4pin.errors import H4Error, MechanismWarning, ParameterError
from h4pin.limits import TooLargeError
from h4pin.mechanism import Beam, FrameOutput, JointOutput, Mechanism, Payload
from h4pin.mechanism import compiled as cp
from h4pin.mechanism.engine import CLOSURE_TOL, UnassembledError, UnrestrainedMotionError

yaml = pytest.importorskip("yaml")

HERE = Path(__file__).parent / "robots"
CORPUS = [e for e in yaml.safe_load((HERE / "corpus.yaml").read_text())["robots"]
          if e["name"] not in ("kangaroo_like", "kangaroo_like_2legs")]  # their files do not close (test_corpus)


def _load(entry: dict) -> tuple[Mechanism, np.ndarray]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        mech = Mechanism.from_urdf(HERE / entry["urdf"], HERE / entry["sidecar"], free_flyer=entry["free_flyer"])
        return mech, mech.assemble()


def _springs(mech: Mechanism, motors: bool = True) -> dict[str, float]:
    return {mech.model.names[j]: (2e3 if mech.model.names[j] in mech.actuated else 50.0) * (1 + 0.1 * (j % 7))
            for j in range(1, mech.model.njoints)
            if mech.model.names[j] not in mech.free_flyers and (motors or mech.model.names[j] not in mech.actuated)}


def _outputs(mech: Mechanism) -> list:
    """A frame of the first closure's first body in each reference, and a joint row."""
    model = mech.model
    frame = next(f.name for f in model.frames if f.parentJoint == mech.constraint_models[0].joint1_id)
    joint = model.names[model.njoints - 1]
    return [FrameOutput(frame, reference=pin.LOCAL_WORLD_ALIGNED), FrameOutput(frame, reference=pin.LOCAL),
            FrameOutput(frame, reference=pin.WORLD, rows=(0, 2, 4)), JointOutput(joint, scale=0.5)]


def _same_frequencies(got: np.ndarray, want: np.ndarray) -> None:
    """The compiled path's frequencies are the eigenvalues 1/w^2 of the mass over the Cholesky
    factor of the stiffness: each is exact to round-off times (f / f_1)^2."""
    got = got[:len(want)]
    tol = 1e-12 * (want / want[0]) ** 3 + 1e-10
    assert np.all(np.abs(got - want) <= tol * want), (got, want)


def _close(a: np.ndarray, b: np.ndarray, tol: float, scale: float = 0.0) -> float:
    """max |a - b| over the largest |b| (or ``scale``, the robot's compliance with every joint
    sprung, where the motors locked leave an output almost rigid: both then hold round-off)."""
    scale = max(scale, float(np.max(np.abs(b))))
    err = float(np.max(np.abs(a - b))) / (scale if scale > 0 else 1.0)
    assert err <= tol, err
    return err


@pytest.mark.parametrize("entry", CORPUS, ids=[e["name"] for e in CORPUS])
def test_compiled_equals_pinocchio_on_the_corpus(entry):
    mech, q = _load(entry)
    assert cp.tables(mech.model, mech.constraint_models) is not None  # every corpus joint kind is computed
    outs = _outputs(mech)
    scale = 0.0
    for springs, locked in ((_springs(mech), ()), (_springs(mech, motors=False), mech.actuated)):
        want = mech.compliance(q, springs, outs, locked, method="pinocchio")
        got = mech.compliance(q, springs, outs, locked, method="compiled")
        _close(got, want, 1e-12, scale)
        scale = float(np.max(np.abs(want)))
    f_want = mech.modes(q, _springs(mech), method="pinocchio").frequencies[:4]
    f_got = mech.modes(np.array([q, q]), _springs(mech), method="compiled").frequencies[:, :4]
    _same_frequencies(f_got[0], f_want)
    np.testing.assert_array_equal(f_got[0], f_got[1])


def test_compiled_equals_pinocchio_with_a_free_root_and_beams():
    entry = next(e for e in CORPUS if e["name"] == "digit_like_2legs")
    mech, q = _load(entry)
    assert mech.free_flyers
    springs = _springs(mech)
    for free_root in (False, True):  # the root held, or free (then the springs alone hold it: refused)
        if free_root:
            with pytest.raises(UnrestrainedMotionError):
                mech.compliance(q, springs, _outputs(mech), free_root=True, method="compiled")
            continue
        _close(mech.compliance(q, springs, _outputs(mech), method="compiled"),
               mech.compliance(q, springs, _outputs(mech), method="pinocchio"), 1e-12)
    five = next(e for e in CORPUS if e["name"] == "5bar_linkage_iso3d")
    mech, q = _load(five)
    tube, beams, seen = Beam.tube(0.02, 0.002, E=70e9, G=26e9), {}, set()
    for f in mech.model.frames:  # one beam a joint, on the links that have a far end
        if f.type == pin.FrameType.BODY and f.parentJoint > 0 and f.parentJoint not in seen:
            seen.add(f.parentJoint)
            try:
                mech.with_beams({f.name: tube})
            except H4Error:
                continue
            beams[f.name] = tube
    assert len(beams) >= 3
    flex = mech.with_beams(beams)
    springs = _springs(mech)
    _close(flex.compliance(q, springs, _outputs(mech), method="compiled"),
           flex.compliance(q, springs, _outputs(mech), method="pinocchio"), 1e-12)


def _delta() -> tuple[Mechanism, np.ndarray, dict[str, float]]:
    mech, q = _load(next(e for e in CORPUS if e["name"] == "robot_delta"))
    return mech, q, _springs(mech)


def test_assemble_over_motor_positions_and_batches():
    mech, q0, springs = _delta()
    idx = [mech.model.joints[mech.model.getJointId(n)].idx_q for n in mech.actuated]
    m0 = q0[idx]
    motors = m0 + np.outer([0.0, 1.0, 2.0, 3.0], np.linspace(0.02, -0.01, len(idx)))
    Q = mech.assemble(motors=motors)
    assert Q.shape == (4, mech.model.nq)
    np.testing.assert_allclose(Q[:, idx], motors, atol=1e-14)
    for q in Q:
        assert max(max(e) for e in mech.closure_errors(q).values()) <= 1e-9
    # continuation: each row closed from the one before, so the robot stays on q0's branch and
    # moves about as much as its motors (a cold start from the file's reference may land on another)
    np.testing.assert_allclose(mech.assemble(Q[1], motors=motors[2]), Q[2], atol=1e-8)
    steps = np.abs(np.diff(np.vstack([q0, Q]), axis=0)).max(axis=1)
    assert steps[0] < 1e-8 and np.all(steps[1:] < 20 * np.abs(np.diff(motors, axis=0)).max()), steps
    outs = _outputs(mech)
    C = mech.compliance(Q, springs, outs)
    assert C.shape == (4, 12 + 3 + 1, 16)
    for i, q in enumerate(Q):  # a batch gives what one configuration gives
        np.testing.assert_array_equal(C[i], mech.compliance(q, springs, outs))
        _close(C[i], mech.compliance(q, springs, outs, method="pinocchio"), 1e-12)
    assert not np.allclose(C[0], C[3], rtol=1e-3)  # the motors moved the robot
    big = np.repeat(Q, 40, axis=0)  # several blocks: threads change nothing
    np.testing.assert_array_equal(mech.compliance(big, springs, outs, threads=1),
                                  mech.compliance(big, springs, outs, threads=2))
    freq = mech.modes(Q, springs)
    assert freq.frequencies.shape[0] == 4
    np.testing.assert_array_equal(freq.first, freq.frequencies[:, 0])
    for i, q in enumerate(Q):
        one = mech.modes(q, springs)
        _same_frequencies(freq.frequencies[i], one.frequencies)
        assert one.first == one.frequencies[0]


def test_a_payload_in_a_batch_is_the_single_configuration_payload():
    mech, q, springs = _delta()
    frame = _outputs(mech)[0].frame
    body = Payload(0.4, com=(0.01, -0.02, 0.03), inertia=np.diag([1e-3, 2e-3, 2.5e-3]))
    batch = mech.modes(np.array([q]), springs, payload=(frame, body), method="compiled").frequencies[0]
    one = mech.modes(q, springs, payload=(frame, body)).frequencies
    plain = mech.modes(q, springs).frequencies
    _same_frequencies(batch, one)
    assert one[0] < plain[0]  # a mass added lowers the first frequency


def test_errors_name_the_configuration():
    mech, q, springs = _delta()
    outs = _outputs(mech)
    bad = q.copy()
    bad[0] += 0.3  # a motor moved without closing the loops
    for method in ("compiled", "pinocchio"):
        with pytest.raises(UnassembledError, match=r"^configuration 2: closure"):
            mech.compliance(np.array([q, q, bad]), springs, outs, method=method)
        with pytest.raises(UnassembledError, match=r"^closure"):
            mech.compliance(bad, springs, outs, method=method)
    few = {mech.actuated[0]: 100.0}  # a motor free: an unrestrained motion, by both routes
    for method in ("compiled", "pinocchio"):
        with pytest.raises(UnrestrainedMotionError, match="^configuration 0: an admissible motion"):
            mech.compliance(np.array([q, q]), few, outs, method=method)
    with pytest.raises(ParameterError, match="method"):
        mech.compliance(q, springs, outs, method="fast")
    with pytest.raises(ParameterError, match="threads"):
        mech.compliance(np.array([q]), springs, outs, threads=0)
    with pytest.raises(ParameterError, match="empty batch"):
        mech.compliance(np.zeros((0, mech.model.nq)), springs, outs)
    with pytest.raises(ParameterError, match=r"q\[1\]"):
        mech.compliance(np.array([q, q * np.nan]), springs, outs)


def test_assembly_errors_name_the_motor_position(monkeypatch):
    mech, q, _ = _delta()
    n = len(mech.actuated)
    idx = [mech.model.joints[mech.model.getJointId(j)].idx_q for j in mech.actuated]
    far = np.array([q[idx], q[idx] + [2.5, -2.5]])  # the second: a passive joint would leave its range
    with pytest.raises(UnassembledError, match=r"^motors\[1\]"):
        mech.assemble(motors=far)
    with pytest.raises(ParameterError, match="shape"):
        mech.assemble(motors=np.zeros((2, n + 1)))
    with pytest.raises(ParameterError, match=r"motors\[0\]: not finite"):
        mech.assemble(motors=[[np.nan] * n])
    with pytest.raises(ParameterError, match="not both"):
        mech.assemble(motors=q[idx], fixed=mech.actuated)
    monkeypatch.setenv("H4PIN_MEMORY_LIMIT", "1MiB")
    with pytest.raises(TooLargeError, match="configurations"):
        mech.compliance(np.zeros((10**6, mech.model.nq)), {mech.actuated[0]: 1.0}, _outputs(mech))


def test_unsupported_joint_kinds_take_the_pinocchio_route():
    model = pin.Model()
    j1 = model.addJoint(0, pin.JointModelSphericalZYX(), pin.SE3.Identity(), "ball_zyx")
    model.appendBodyToJoint(j1, pin.Inertia.FromSphere(1.0, 0.1), pin.SE3.Identity())
    model.addFrame(pin.Frame("tip", j1, 0, pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.5])), pin.FrameType.OP_FRAME))
    mech = Mechanism(model)
    assert cp.tables(model, []) is None
    q = pin.neutral(model)
    with pytest.raises(ParameterError, match="compiled path does not compute"):
        mech.compliance(q, {"ball_zyx": 10.0}, ["tip"], method="compiled")
    auto = mech.compliance(np.array([q]), {"ball_zyx": 10.0}, ["tip"])  # auto: the Pinocchio route
    np.testing.assert_array_equal(auto[0], mech.compliance(q, {"ball_zyx": 10.0}, ["tip"], method="pinocchio"))


MJCF = {"agility_cassie/cassie.xml": (None, "left-foot"), "iit_softfoot/softfoot.xml": (None, "heel"),
        "ufactory_xarm7/hand.xml": (["left_driver_joint"], "left_finger")}


@pytest.mark.parametrize("path", sorted(MJCF))
def test_compiled_equals_pinocchio_on_the_mjcf_corpus(path):
    """The MJCF robots as MuJoCo means them: a free-flyer root, joints on any axis, the file's
    joint couplings (rows the compiled path takes per configuration)."""
    pytest.importorskip("mujoco")
    if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
        pytest.skip(f"needs Pinocchio >= 4 (closures read from MJCF), this is {pin.__version__}")
    motors, frame = MJCF[path]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        mech = Mechanism.from_mjcf(HERE / "mjcf" / path, actuated=motors)
        q = mech.assemble()
    assert cp.tables(mech.model, mech.constraint_models) is not None
    springs = _springs(mech)
    outs = [FrameOutput(frame), FrameOutput(frame, reference=pin.LOCAL)]
    _close(mech.compliance(np.array([q, q]), springs, outs, method="compiled")[1],
           mech.compliance(q, springs, outs, method="pinocchio"), 1e-12)
    _same_frequencies(mech.modes(np.array([q]), springs, method="compiled").frequencies[0],
                      mech.modes(q, springs, method="pinocchio").frequencies[:4])


def test_coupling_rows_over_a_batch_equal_the_per_configuration_loop():
    """The couplings' rows the compiled path takes, built over the whole batch at once
    (batch.coupling_batch, JointCoupling.residual_rows), are residual_row's at each configuration
    to 1e-14, with the same verdicts: the corpus's SoftFoot (45 couplings) at random
    configurations (most off its couplings), and quartic couplings (with and without a second
    joint, off their origins) on the synthetic MJCF."""
    pytest.importorskip("mujoco")
    if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
        pytest.skip("Pinocchio < 4 reads no closures from MJCF")
    from h4pin.mechanism import batch
    from h4pin.mechanism.couplings import JointCoupling

    rng = np.random.default_rng(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        foot = Mechanism.from_mjcf(HERE / "mjcf" / "iit_softfoot" / "softfoot.xml")
        q = foot.assemble()
    Q = q + rng.normal(scale=0.05, size=(200, len(q))) * (rng.random((200, 1)) < 0.7)
    rows, off = batch.coupling_batch(foot, Q)
    assert rows.shape == (200, 45, foot.model.nv)
    for i, qi in enumerate(Q):
        loop = [c.residual_row(foot.model, qi) for c in foot.couplings]
        np.testing.assert_allclose(rows[i], [r for _, r in loop], rtol=0, atol=1e-14)
        assert off[i] == any(not abs(res) <= CLOSURE_TOL for res, _ in loop)
    assert 0 < off.sum() < len(Q)

    loop_model = Mechanism.from_mjcf(HERE / "synthetic" / "coupled.xml").model
    Q = rng.uniform(-2, 2, size=(100, loop_model.nq))
    for c in (JointCoupling("rocker_pitch", "coupler_roll", (0.1, 0.9, -0.3, 0.05, 0.02), 0.2, -0.1),
              JointCoupling("tilt", None, (0.3,), 0.05)):
        res, rows = c.residual_rows(loop_model, Q)
        for i, qi in enumerate(Q):
            want_res, want_row = c.residual_row(loop_model, qi)
            assert abs(res[i] - want_res) <= 1e-14 * max(1.0, abs(want_res))
            np.testing.assert_allclose(rows[i], want_row, rtol=1e-14, atol=1e-14)
