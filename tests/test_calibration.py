# SPDX-License-Identifier: Apache-2.0
"""Calibration of any mechanism from measured tool positions (h4pin.calibrate), against a
synthetic truth: a robot whose offsets, geometry, springs, lateral hinges and masses are drawn
from the prior, measured by a tracker with Gaussian noise under gravity and known loads; the fit
must recover the parameters within their stated uncertainty (coverage), leave residuals at the
noise, name what it cannot identify; its Jacobian must be the finite differences of its own
predictions; a calibrated robot written to URDF must predict the same markers once read back.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin.errors import ConvergenceError, MechanismWarning, ParameterError
from h4pin.mechanism import Beam, Mechanism
from h4pin.mechanism import calibration as cal
from h4pin.mechanism.measurements import Measurements

ROBOTS = Path(__file__).resolve().parent / "robots"


def _five_bar(beams: bool = False) -> Mechanism:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        mech = Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")
    if beams:
        mech = mech.with_beams({"part_3": Beam.tube(0.025, 0.002, E=70e9, G=26e9)})
    return mech


#: The five-bar's experiment: springs, the parameters and their prior (also the truth's spread).
SPRINGS = {"mot1": 2e3, "mot2": 2e3, "free1": 300.0}
PRIOR = {"base/tx": (0.0, 0.01), "base/ty": (0.0, 0.01), "base/tz": (0.0, 0.01), "base/rx": (0.0, 0.01),
         "base/ry": (0.0, 0.01), "base/rz": (0.0, 0.01), "offsets/mot1": (0.0, 0.005), "offsets/mot2": (0.0, 0.005),
         "springs/mot1": (2e3, 400.0), "springs/mot2": (2e3, 400.0), "springs/free1": (300.0, 60.0)}
GROUPS = {"base": None, "offsets": None, "geometry": ["free1"], "springs": None, "masses": ["free2"]}


def _experiment(mech: Mechanism, groups, springs, prior, n: int, noise: float, seed: int):
    """A synthetic tracker session (h4pin's ``synthetic``): n motor positions, loads at the
    effector, the truth drawn from the prior, the effector's marker with Gaussian noise (m)."""
    rng = np.random.default_rng(seed)
    motors = rng.uniform(-0.3, 0.3, (n, len(mech.actuated)))
    loads = {"effector": np.c_[rng.normal(0.0, 30.0, (n, 3)), np.zeros((n, 3))]}
    return cal.synthetic(mech, groups, ["effector"], motors=motors, loads=loads, springs=springs, prior=prior,
                         noise=noise, seed=seed)


def _z(c: cal.Calibration, truth: dict[str, float]) -> dict[str, float]:
    return {n: (c.values[n] - truth[n]) / c.std[n] for n in truth}


@pytest.fixture(scope="module")
def fitted():
    mech = _five_bar()
    meas, truth = _experiment(mech, GROUPS, SPRINGS, PRIOR, 80, 2e-4, seed=0)
    return mech, meas, truth, h4pin.calibrate(mech, meas, GROUPS, springs=SPRINGS, prior=PRIOR)


def test_a_synthetic_tracker_session_is_recovered(fitted):
    """The five-bar with offsets, a joint's placement, springs and a link's mass drawn from the
    prior, 80 poses under gravity and loads, 0.2 mm noise: every parameter within 3 sigma of the
    truth (its std the prior's along what the data do not inform), the data-identified ones (the
    motors' springs, the base) well inside their prior, the noise estimated within 10 %, the
    residuals at the noise; a motor's offset beside the placement of the joint it carries is named
    as not identified."""
    _, meas, truth, c = fitted
    z = _z(c, truth)
    assert max(abs(v) for v in z.values()) < 3.0, z
    for name in ("springs/mot1", "springs/mot2", "base/tx", "base/rz"):
        assert c.std[name] < 0.5 * PRIOR[name][1], (name, c.std[name])
    assert c.noise == pytest.approx(2e-4, rel=0.1)
    rms = float(np.sqrt(np.nanmean(c.residuals**2)))
    assert rms == pytest.approx(2e-4, rel=0.1)
    assert "error mean" in c.summary()
    assert any("offsets/mot1" in u and "geometry/free1" in u for u in c.unidentifiable), c.unidentifiable


def test_what_the_data_cannot_separate_is_named(fitted):
    """A motor's zero offset and its joint's rotation about its own axis move the robot alike: with
    both asked, the combination is held at the prior and named, and neither drifts."""
    mech, meas, _, _ = fitted
    meas = meas.subset(np.arange(30))
    c = h4pin.calibrate(mech, meas, {"offsets": ["mot1"], "geometry": ["mot1"]}, springs=SPRINGS,
                        prior={"offsets/mot1": (0.0, 0.005)}, iterations=20)
    assert any("offsets/mot1" in u and "geometry/mot1/rz" in u for u in c.unidentifiable), c.unidentifiable
    assert abs(c.values["offsets/mot1"] - 0.0) < 3 * c.std["offsets/mot1"]


def _jacobian_and_differences(model: cal.Model, rng: np.random.Generator):
    """At x a random 0.3 sigma from the nominal: the Jacobian, its scale and each parameter's
    central difference of the predicted markers (all in sigma units), checked equal (1e-6)."""
    x = model.x0 + 0.3 * model.sigma * rng.normal(size=len(model.params))
    jac = model.jacobian(x, model.predict(x)[1]) * model.sigma
    scale = np.abs(jac).max()
    for k, p in enumerate(model.params):
        h = 1e-6 * model.sigma[k]
        up, down = x.copy(), x.copy()
        up[k] += h
        down[k] -= h
        fd = (model.predict(up)[0] - model.predict(down)[0]) / (2 * h) * model.sigma[k]
        assert np.abs(jac[..., k] - fd).max() < 1e-6 * scale, p.name
        yield p, fd, scale


def test_the_jacobian_is_the_finite_difference_of_the_predictions():
    """Every group (base, markers, offsets, geometry, springs, lateral hinges, masses) on the
    five-bar under gravity and loads, away from the nominal: the implicit-differentiation Jacobian
    equals central differences of the predicted markers (1e-6 of the Jacobian's scale)."""
    mech = _five_bar()
    rng = np.random.default_rng(1)
    motors = rng.uniform(-0.3, 0.3, (3, 2))
    meas = Measurements(motors=motors, points={"effector": np.zeros((3, 3))},
                        loads={"effector": rng.normal(0.0, 20.0, (3, 6))})
    groups = {"base": None, "markers": None, "offsets": None, "geometry": ["free1", "mot2"], "springs": None,
              "lateral": ["free2"], "masses": ["free2", "mot1"]}
    work = cal.with_lateral(mech, ["free2"], SPRINGS)
    params = cal.parameters(work, groups, SPRINGS, meas.markers, tuple(mech.actuated))
    model = cal.Model(work, meas, params, {**work.beam_springs, **SPRINGS}, True, (), pin.SE3.Identity())
    assert len(list(_jacobian_and_differences(model, rng))) == len(params)


#: The Cassie-like leg (Gepetto): five motors, two 6D closures through rods on three-revolute ball
#: joints; each rod's spin about itself strains nothing: one joint of each rod pair held rigid.
LEG_LOCKED = ("foot_2_half_planta_rode_2_rev2", "tarsus_half_hachil_rode_rev2")
LEG_SPRINGS = {"motor_hip1": 300.0, "motor_hip2": 300.0, "motor_tigh": 300.0, "motor_knee": 300.0,
               "motor_ankle": 100.0}


def _leg() -> Mechanism:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        return Mechanism.from_urdf(ROBOTS / "cassie_like" / "robot.urdf")


def test_the_jacobian_of_a_closed_leg_with_held_joints():
    """The Cassie-like leg (two 6D closures, joints held rigid in the equilibrium that the loops'
    assembly still moves): the Jacobian of every group equals central differences (1e-6); a
    placement's rotation about a passive joint's own axis moves nothing (the joint takes it up)."""
    leg = _leg()
    rng = np.random.default_rng(0)
    meas = Measurements(motors=rng.uniform(-0.2, 0.2, (3, 5)), points={"foot": np.zeros((3, 3))},
                        loads={"foot": rng.normal(0.0, 20.0, (3, 6))})
    groups = {"base": None, "offsets": None, "springs": None, "masses": ["free_knee"], "geometry": ["free_ankle"]}
    params = cal.parameters(leg, groups, LEG_SPRINGS, meas.markers, tuple(leg.actuated))
    model = cal.Model(leg, meas, params, LEG_SPRINGS, True, LEG_LOCKED, pin.SE3.Identity())
    for p, fd, scale in _jacobian_and_differences(model, rng):
        if p.name == "geometry/free_ankle/rz":  # about the passive joint's own axis: the joint takes it up
            assert np.abs(fd).max() < 1e-5 * scale
        else:  # every other parameter moves the foot
            assert np.abs(fd).max() > 1e-4 * scale, p.name


def test_a_calibrated_robot_read_back_predicts_the_same_markers(fitted, tmp_path):
    """to_urdf, then Mechanism.from_urdf (its springs, elastic joints and gravity from the sidecar):
    the markers at the same motor positions, assembled and loaded, are where predict puts them
    (1e-9 m); Pinocchio reads the URDF alone too."""
    mech, meas, _, _ = fitted
    meas = meas.subset(np.arange(30))
    c = h4pin.calibrate(mech, meas, {"base": None, "offsets": None, "geometry": ["free1"], "springs": None,
                                     "lateral": ["free2"]}, springs=SPRINGS, prior=PRIOR, iterations=10)
    urdf, sidecar = c.to_urdf(tmp_path / "calibrated.urdf")
    pin.buildModelFromUrdf(str(urdf))
    back = Mechanism.from_urdf(urdf, sidecar)
    assert set(back.beam_springs) == {"free2_lateral_a", "free2_lateral_b"}
    loads = {f: w[:5] for f, w in meas.loads.items()}
    want = c.predict(motors=meas.motors[:5], loads=loads)
    turn = c.robot.base.rotation  # the file is in the tracker's frame: so are its loads' axes
    for i, m in enumerate(meas.motors[:5]):
        w = loads["effector"][i]
        eq = back.equilibrium(back.assemble(motors=m), back.springs, {"effector": np.r_[turn @ w[:3], turn @ w[3:]]},
                              gravity=True)
        d = back.model.createData()
        pin.framesForwardKinematics(back.model, d, eq.q)
        np.testing.assert_allclose(d.oMf[back.model.getFrameId("effector")].translation, want[i, 0], rtol=0, atol=1e-9)


def test_a_serial_arm_from_example_robot_data():
    """The UR5 (example-robot-data) as a tree with joint springs: its configurations commanded, its
    joint offsets and springs and the base recovered from a tool marker within 3 sigma."""
    erd = pytest.importorskip("example_robot_data", reason="the UR5 comes with the erd extra (example-robot-data)")
    from h4pin.studies.serial import UR5_JOINT_STIFFNESS

    ur5 = erd.load("ur5")
    mech = Mechanism(ur5.model, [], [])
    springs = {n: float(k) for n, k in zip(list(ur5.model.names)[1:], UR5_JOINT_STIFFNESS, strict=True)}
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, (60, ur5.model.nq))
    prior = {**{f"offsets/{n}": (0.0, 0.002) for n in springs},
             **{f"springs/{n}": (k, 0.2 * k) for n, k in springs.items()},
             **{f"base/{a}": (0.0, 0.01) for a in ("tx", "ty", "tz", "rx", "ry", "rz")}}
    groups = {"base": None, "offsets": None, "springs": ["shoulder_lift_joint", "elbow_joint"]}
    blank = Measurements(configurations=q, points={"tool0": np.zeros((60, 3))},
                         loads={"tool0": np.c_[np.zeros((60, 2)), np.full(60, -50.0), np.zeros((60, 3))]})
    params = cal._prior(cal.parameters(mech, groups, springs, blank.markers, tuple(list(ur5.model.names)[1:])), prior)
    model = cal.Model(mech, blank, params, springs, True, (), pin.SE3.Identity())
    truth = model.x0 + model.sigma * rng.normal(size=len(params))
    pts = model.predict(truth)[0][:, 0] + rng.normal(0.0, 1e-4, (60, 3))
    meas = Measurements(configurations=q, points={"tool0": pts}, loads=blank.loads)
    c = h4pin.calibrate(mech, meas, groups, springs=springs, prior=prior)
    values = {p.name: p.value(v) for p, v in zip(params, truth, strict=True)}
    z = _z(c, values)
    assert max(abs(v) for v in z.values()) < 3.0, z
    assert c.std["springs/elbow_joint"] < 0.5 * prior["springs/elbow_joint"][1]


def test_measurements_files_round_trip(fitted, tmp_path):
    _, meas, _, _ = fitted
    for path in (meas.to_csv(tmp_path / "m.csv", ("mot2", "mot1")), meas.to_npz(tmp_path / "m.npz")):
        back = Measurements.read(path)
        np.testing.assert_array_equal(back.motors, meas.motors)
        np.testing.assert_array_equal(back.points["effector"], meas.points["effector"])
        np.testing.assert_array_equal(back.loads["effector"], meas.loads["effector"])


def test_holdout_and_the_stage_table(fitted):
    """Held-out samples are scored (their errors near the fitted ones'), and each stage of the
    table fits at least as well as the one before, from the nominal model."""
    mech, meas, _, _ = fitted
    small = meas.subset(np.arange(40))
    rows = cal.stages(mech, small, [["base"], ["offsets"], ["springs"]], holdout=0.25, springs=SPRINGS,
                      prior=PRIOR)
    assert [r.groups for r in rows] == [("nominal",), ("base",), ("base", "offsets"), ("base", "offsets", "springs")]
    means = [r.fit[0] for r in rows]
    assert all(b <= a * 1.001 for a, b in zip(means, means[1:], strict=False))
    assert rows[-1].held[0] < 2.0 * rows[-1].fit[0]
    assert "held mean" in cal.stage_table(rows)


# ---------------------------------------------------------------- hostile input
@pytest.mark.parametrize(("change", "match"), [
    (lambda m: {"motors": m.motors[:, :1]}, "motors has 1 columns"),
    (lambda m: {"points": {"effector": np.full((m.n, 3), np.nan)}}, "never seen"),
    (lambda m: {"points": {"effector": m.points["effector"][:5]}}, "rows"),
    (lambda m: {"points": {"nowhere": m.points["effector"]}}, "not a frame"),
    (lambda m: {"points": {"effector": m.points["effector"] + 1j}}, "real numbers"),
])
def test_bad_measurements_are_typed_errors(fitted, change, match):
    mech, meas, _, _ = fitted
    args = {"motors": meas.motors, "points": meas.points, "loads": meas.loads, **change(meas)}
    with pytest.raises(ParameterError, match=match):
        h4pin.calibrate(mech, Measurements(**args), ["base"], springs=SPRINGS)


@pytest.mark.parametrize(("groups", "options", "error", "match"), [
    ({"springs": ["nowhere"]}, {}, ParameterError, "no joint 'nowhere'|no spring"),
    (["bogus"], {}, ParameterError, "unknown group 'bogus'"),
    (["base"], {"prior": {"bogus/qq": (0, 1)}}, ParameterError, "not a parameter of a group"),
    (["base"], {"prior": {"base/tx": (0, -1)}}, ParameterError, "sigma > 0"),
    (["base"], {"loss": "l3"}, ParameterError, "loss"),
    (["base"], {"noise": -1.0}, ParameterError, "noise"),
])
def test_bad_options_are_typed_errors(fitted, groups, options, error, match):
    mech, meas, _, _ = fitted
    with pytest.raises(error, match=match):
        h4pin.calibrate(mech, meas, groups, springs=SPRINGS, **options)


def test_a_fit_that_cannot_converge_says_so():
    """Markers a metre off any pose the robot can take: the fit ends without converging (its
    evaluations spent) or far from the data; either is stated, never silent."""
    mech = _five_bar()
    meas = Measurements(motors=np.zeros((3, 2)), points={"effector": np.full((3, 3), 50.0)})
    try:
        c = h4pin.calibrate(mech, meas, ["offsets"], springs=SPRINGS, gravity=False, iterations=3)
    except ConvergenceError as exc:
        assert "fit" in str(exc)
    else:
        assert np.nanmax(np.abs(c.residuals)) > 1.0  # the error stays in the residuals, for all to see


def test_the_command_calibrates_from_a_csv_and_writes_the_robot(tmp_path):
    """``h4pin calibrate``: the tracker's CSV in, the stage table out with the nominal model's error
    above the calibrated one's, the fitted offsets within 3 sigma of the truth, the calibrated URDF
    and its sidecar written; a bad --spring is a usage error (exit 2) that writes nothing."""
    from typer.testing import CliRunner

    from h4pin.cli import app

    mech = _five_bar()
    meas, truth = _experiment(mech, {"base": None, "offsets": None, "springs": None}, SPRINGS, PRIOR, 40, 2e-4, seed=5)
    csv = meas.to_csv(tmp_path / "tracker.csv", ("mot1", "mot2"))
    robot = ROBOTS / "5bar_linkage_iso3d" / "robot.urdf"
    springs = [f"--spring={j}={k}" for j, k in SPRINGS.items()]
    out = tmp_path / "calibrated.urdf"
    result = CliRunner().invoke(app, ["calibrate", "--robot", str(robot), "--measurements", str(csv),
                                      "--stages", "base +offsets +springs:mot1|mot2|free1", *springs,
                                      "--holdout", "0.2", "--out", str(out)])
    assert result.exit_code == 0, result.output
    rows = {line.split()[0]: line.split() for line in result.output.splitlines() if line.strip()}
    assert out.exists() and out.with_suffix(".yaml").exists()
    for joint in ("mot1", "mot2"):
        value, std = float(rows[f"offsets/{joint}"][1]), float(rows[f"offsets/{joint}"][2])
        assert abs(value - truth[f"offsets/{joint}"]) < 3.0 * std, (joint, value, std)
    table = {line.split()[line.startswith("+ ")]: float(line.split()[-6])
             for line in result.output.splitlines() if line.startswith(("nominal ", "base ", "+ "))}
    assert list(table) == ["nominal", "base", "offsets", "springs"]
    assert table["springs"] < 0.5 * table["nominal"], table
    bad = CliRunner().invoke(app, ["calibrate", "--robot", str(robot), "--measurements", str(csv),
                                   "--spring", "mot1", "--out", str(tmp_path / "no.urdf")])
    assert bad.exit_code == 2 and "JOINT=K" in bad.output
    assert not (tmp_path / "no.urdf").exists()
