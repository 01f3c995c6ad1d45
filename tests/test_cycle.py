# SPDX-License-Identifier: Apache-2.0
"""The standard cycle study (h4pin.studies.cycle): trajectory, closed-loop inverse dynamics, load.

Each number is checked against a route that does not share the study's code: the path against
its definition and finite differences; the torques at rest against ``H4.gravity_torques`` and the
robot's Jacobian; the joint velocities and accelerations against finite differences of the
assembled configurations; the torques in motion against the energy balance (Pinocchio's kinetic
and potential energy, differentiated in time); the load against Newton's law for the plate's
bodies (their centres of mass differentiated twice in time, masses read from the URDF text).
"""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin.errors import ParameterError, UnreachablePoseError
from h4pin.kinematics.closed_form import centre_pose
from h4pin.studies import cycle as cy

ROOT = Path(__file__).resolve().parent.parent
G = 9.81
PAYLOAD_AT = np.array([0.01, -0.02, -0.03])  # off D: the payload then loads T too


@pytest.fixture(scope="module")
def h4():
    return h4pin.load("prototype")


@pytest.fixture(scope="module")
def cycle(h4):
    return cy.adept_cycle(h4, 0.5)


def urdf_mass(h4, link: str) -> float:
    node = ET.fromstring(h4.urdf).find(f"link[@name='{link}']/inertial/mass")
    return float(node.get("value"))


def test_path_geometry(h4, cycle):
    c = centre_pose(h4)[:3]
    T = cycle.period
    pose, vel, acc = cycle.sample(np.array([0.0, T / 2, T]))
    start = c - np.array([0.1525, 0.0, 0.0125])
    np.testing.assert_allclose(pose[0, :3], start, atol=1e-15)
    np.testing.assert_allclose(pose[2], pose[0], atol=1e-15)
    np.testing.assert_allclose(pose[1, :3], start + [0.305, 0.0, 0.0], atol=1e-15)
    np.testing.assert_array_equal(pose[:, 3], 0.0)
    assert np.abs(vel).max() == 0 and np.abs(acc).max() == 0  # at rest at both ends and at the far end
    p = cycle.sample(np.linspace(0.0, T, 20001))[0]
    assert np.ptp(p[:, 2]) == pytest.approx(0.025, abs=1e-15)
    assert np.ptp(p[:, 0]) == pytest.approx(0.305, abs=1e-15)
    np.testing.assert_allclose(p[:, 1], 0.0, atol=1e-15)
    # The stroke starts only once D has risen: z is 25 mm on the whole middle of the stroke.
    mid = np.abs(p[:, 0] - c[0]) < 0.1
    np.testing.assert_allclose(p[mid, 2], start[2] + 0.025, atol=1e-15)
    # Along +y with heading pi/2.
    py = cy.adept_cycle(h4, 0.5, heading=np.pi / 2).sample(np.array([T / 2]))[0][0]
    np.testing.assert_allclose(py[:3], c + [0.0, 0.1525, -0.0125], atol=1e-15)


def test_path_derivatives_are_those_of_the_positions(cycle):
    h = 1e-5
    half, rise = cycle.period / 2, cycle.rise * cycle.period / 2
    lag = (1 - cycle.overlap) * rise
    knots = np.array([0.0, lag, rise, half - rise, half - lag, half])
    knots = np.r_[knots, knots + half]
    t = np.linspace(0.003, cycle.period - 0.003, 97)
    t = t[np.abs(t[:, None] - knots).min(axis=1) > 3 * h]  # the third derivative jumps at the knots
    assert len(t) > 90
    _, vel, acc = cycle.sample(t)
    p = [cycle.sample(t + k * h)[0] for k in (-2, -1, 0, 1, 2)]
    fd_v = (p[0] - 8 * p[1] + 8 * p[3] - p[4]) / (12 * h)
    fd_a = (-p[0] + 16 * p[1] - 30 * p[2] + 16 * p[3] - p[4]) / (12 * h * h)
    np.testing.assert_allclose(vel, fd_v, atol=1e-7 * np.abs(vel).max())
    np.testing.assert_allclose(acc, fd_a, atol=1e-4 * np.abs(acc).max())


def test_torques_at_rest_are_the_gravity_torques(h4, cycle):
    model0, model1 = cy.payload_model(h4), cy.payload_model(h4, 0.5)
    zero = np.zeros(4)
    for pose in cycle.sample(np.array([0.0, 0.11, 0.25]))[0]:
        tau = cy.sample(h4, model0, model0.createData(), pose, zero, zero).torque
        ref = h4.gravity_torques(pose)
        np.testing.assert_allclose(tau, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
        # 0.5 kg at D adds tau = J^T F with F = (0, 0, 0.5 g) (virtual work, J of eq. 8).
        tau1 = cy.sample(h4, model1, model1.createData(), pose, zero, zero).torque
        np.testing.assert_allclose(tau1 - tau, h4.jacobian(pose).T @ [0.0, 0.0, 0.5 * G, 0.0], rtol=1e-9,
                                   atol=1e-12)


def test_load_at_rest_is_the_weight_of_the_plate(h4, cycle):
    plate = urdf_mass(h4, "central_bar") + urdf_mass(h4, "lateral_bar_1") + urdf_mass(h4, "lateral_bar_2")
    assert plate == pytest.approx(0.396293, abs=1e-6)
    model = cy.payload_model(h4, 0.5)
    pose = cycle.sample(np.array([0.1]))[0][0]
    load = cy.sample(h4, model, model.createData(), pose, np.zeros(4), np.zeros(4)).load
    np.testing.assert_allclose(load[:3], [0.0, 0.0, -(plate + 0.5) * G], atol=1e-12)
    assert np.abs(load[6:]).max() < 1e-12


def _com(h4, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World centres of mass (3, 3) of the central bar and the lateral bars, the payload's point
    and D, from the joint placements."""
    d = h4.model.createData()
    pin.framesForwardKinematics(h4.model, d, q)
    joints = [h4.model.frames[h4.index.fid_D].parentJoint, *h4.index.jid_lat]
    com = np.array([d.oMi[j].act(h4.model.inertias[j].lever) for j in joints])
    D = d.oMf[h4.index.fid_D]
    return com, D.act(PAYLOAD_AT), D.translation.copy()


def test_load_is_newtons_law_for_the_plate_bodies(h4, cycle):
    """F = sum m_i (g - a_i), T = sum (c_i - D) x m_i (g - a_i): the plate only translates
    (theta constant) and the accelerations a_i come from positions at neighbouring times."""
    masses = np.array([urdf_mass(h4, name) for name in ("central_bar", "lateral_bar_1", "lateral_bar_2")])
    m_p, g = 0.5, np.array([0.0, 0.0, -G])
    model = cy.payload_model(h4, m_p, PAYLOAD_AT)
    data = model.createData()
    h = 2e-4
    for t in (0.02, 0.06, 0.11, 0.2, 0.245, 0.41):
        pose, vel, acc = cycle.sample(np.array([t]))
        load = cy.sample(h4, model, data, pose[0], vel[0], acc[0]).load
        pts = [_com(h4, h4.configuration(cycle.sample(np.array([t + k * h]))[0][0])) for k in (-2, -1, 0, 1, 2)]
        bodies = np.array([np.vstack([p[0], p[1]]) for p in pts])  # (5, 4, 3): 3 bodies and the payload
        a = (-bodies[0] + 16 * bodies[1] - 30 * bodies[2] + 16 * bodies[3] - bodies[4]) / (12 * h * h)
        f = np.r_[masses, m_p][:, None] * (g - a)
        D = pts[2][2]
        F, T = f.sum(axis=0), np.cross(bodies[2] - D, f).sum(axis=0)
        scale = np.abs(load[:3]).max()
        np.testing.assert_allclose(load[:3], F, atol=1e-8 * scale)
        np.testing.assert_allclose(load[3:6], T, atol=1e-9 * scale)
        assert np.abs(load[6:]).max() < 1e-9 * scale  # the lateral bars' centres are on their axes


def test_joint_motion_is_the_derivative_of_the_configurations(h4, cycle):
    model = cy.payload_model(h4)
    data = model.createData()
    h = 1e-4
    for t in (0.03, 0.12, 0.3, 0.47):
        s = cy.cycle_dynamics(h4, cycle, np.array([t]))[0]
        qs = [h4.configuration(cycle.sample(np.array([t + k * h]))[0][0]) for k in (-2, -1, 1, 2)]
        d1, d2 = pin.difference(model, qs[1], qs[2]) / (2 * h), pin.difference(model, qs[0], qs[3]) / (4 * h)
        np.testing.assert_allclose(s.v, (4 * d1 - d2) / 3, atol=1e-8 * np.abs(s.v).max())
        vs = [cy.sample(h4, model, data, *(x[0] for x in cycle.sample(np.array([t + k * h])))).v
              for k in (-2, -1, 1, 2)]
        fd = (vs[0] - 8 * vs[1] + 8 * vs[2] - vs[3]) / (12 * h)
        np.testing.assert_allclose(s.a, fd, atol=1e-9 * np.abs(s.a).max())
        pin.computeJointJacobians(model, data, s.q)
        assert np.abs(cy.closure_rows(h4, model, data) @ s.v).max() < 1e-12 * np.abs(s.v).max()


def test_actuator_power_is_the_rate_of_energy(h4, cycle):
    """tau . q_dot = d/dt (kinetic + potential energy): the closure forces do no work."""
    model = cy.payload_model(h4, 0.5, PAYLOAD_AT)
    data = model.createData()
    h = 2e-4

    def energy(t: float) -> float:
        s = cy.cycle_dynamics(h4, cycle, np.array([t]), 0.5, payload_at=PAYLOAD_AT)[0]
        return pin.computeKineticEnergy(model, data, s.q, s.v) + pin.computePotentialEnergy(model, data, s.q)

    ts = np.array([0.015, 0.05, 0.09, 0.16, 0.23, 0.27, 0.33, 0.48])
    rows = cy.cycle_dynamics(h4, cycle, ts, 0.5, payload_at=PAYLOAD_AT)
    power = np.array([s.torque @ s.v[h4.v_act] for s in rows])
    rate = np.array([(energy(t - 2 * h) - 8 * energy(t - h) + 8 * energy(t + h) - energy(t + 2 * h)) / (12 * h)
                     for t in ts])
    assert np.abs(power).max() > 10.0  # watts: the check is not empty
    np.testing.assert_allclose(power, rate, rtol=0, atol=1e-7 * np.abs(power).max())


def test_inertial_deflection_scales_with_the_inverse_square_of_the_cycle_time(h4):
    zero_g = np.zeros(3)
    fast = cy.run(h4, 0.4, 0.5, samples=16, gravity=zero_g)
    slow = cy.run(h4, 0.8, 0.5, samples=16, gravity=zero_g)
    np.testing.assert_allclose(fast.load, 4 * slow.load, rtol=0, atol=1e-10 * np.abs(fast.load).max())
    np.testing.assert_allclose(fast.deflection, 4 * slow.deflection, rtol=0,
                               atol=1e-10 * np.abs(fast.deflection).max())
    np.testing.assert_allclose(fast.torque, 4 * slow.torque, rtol=0, atol=1e-10 * np.abs(fast.torque).max())
    assert fast.peak_norm == pytest.approx(4 * slow.peak_norm, rel=1e-10)
    # With gravity, the start (at rest) deflects by the weight alone: K times the static load.
    res = cy.run(h4, 0.4, 0.5, samples=16)
    K = h4pin.compliance(h4, res.pose[0], "consistent").matrix
    static = K @ res.load[0]  # relative to its size: its y and theta entries are round-off (1e-18)
    np.testing.assert_allclose(res.deflection[0], static, rtol=0, atol=1e-12 * np.abs(static).max())
    assert res.load[0, 2] == pytest.approx(-(0.396293 + 0.5) * G, rel=1e-6)


def test_result_summaries(h4):
    res = cy.run(h4, 0.5, 0.0, samples=40, tool=[0.0, 0.0, -0.1])
    d = res.deflection[:, :3]
    assert res.peak_norm == pytest.approx(np.linalg.norm(d, axis=1).max())
    np.testing.assert_allclose(res.rms, np.sqrt(np.mean(d[:-1] ** 2, axis=0)))
    # 10 cm below D: dD + dOmega x (p - D).
    np.testing.assert_allclose(res.tool_deflection, d + np.cross(res.deflection[:, 3:6], [0.0, 0.0, -0.1]))
    total = sum(res.term_deflection.values())
    np.testing.assert_allclose(total, d, atol=1e-12 * np.abs(d).max())
    assert res.f99 > 0
    assert "peak |dD| [um]" in cy.report(res)


@pytest.mark.parametrize("payload", [0.0, 0.5])
def test_the_reduced_first_frequencies_against_the_elastic_robot(h4, payload):
    """The cycle's reduced vibration models against the elastic robot's own (the elastic cycle's
    ``M_s = T^T M T`` over ``diag(k)`` in spring coordinates: every body's inertia, every spring;
    h4pin.elastic_model's modes) at each of 41 samples of the 0.5 s cycle: ``f1_robot`` (the legs
    moving rigidly with the plate) is above it by 0.6 to 3.6 % (measured; bound 4 %), and the
    lowest over the cycle by 1.6 % (0 kg) and 0.7 % (0.5 kg) (bound 2 %); ``f1_plate`` (the legs
    massless) by 10.8 % and 5.1 % (bound 12 %): what docs/cycle.md states."""
    from scipy.linalg import eigh

    from h4pin.studies import elastic_cycle as ec

    res = cy.run(h4, 0.5, payload, samples=40)
    sp = ec.springs_along(h4, res.cycle, res.t, payload, motion=False)
    elastic = np.array([1 / (2 * np.pi * np.sqrt(eigh(m, np.diag(sp.k), eigvals_only=True)[-1])) for m in sp.mass])
    rows = cy.cycle_dynamics(h4, res.cycle, res.t, payload)
    sub = np.ix_(cy._POSE_ROWS, cy._POSE_ROWS)
    robot = np.array([cy._natural_frequency(np.linalg.inv(k[sub]), s.inertia_x)
                      for k, s in zip(res.compliance, rows, strict=True)])
    assert res.f1_robot == robot.min()
    assert np.all(robot > elastic) and np.all(robot / elastic - 1 < 0.04)
    assert 0 < res.f1_robot / elastic.min() - 1 < 0.02
    assert 0 < res.f1_plate / elastic.min() - 1 < 0.12


def test_dynamic_deflection_of_a_harmonic_load_is_the_textbook_response():
    """One dof at omega_1 under F0 sin(omega t), omega = omega_1 / 2: steady-state amplitude
    F0 / k / sqrt((1 - r^2)^2 + (2 zeta r)^2) (stiffness-proportional damping c = 2 zeta / omega_1 k
    = 2 zeta omega_1 for this dof); the other dofs are stiffer and unloaded."""
    n, zeta, f1 = 400, 0.05, 20.0
    k = (2 * np.pi * f1) ** 2  # unit mass
    compliance = np.tile(np.diag([1 / k] + [1 / (4 * k)] * 7), (n + 1, 1, 1))
    inertia = np.tile(np.eye(8), (n + 1, 1, 1))
    period = 2.0 / f1  # r = 1/2
    t = np.linspace(0.0, period, n + 1)
    load = np.zeros((n + 1, 8))
    load[:, 0] = np.sin(2 * np.pi * t / period)
    x = cy.dynamic_deflection(compliance, inertia, load, period, zeta, periods=40)
    r = 0.5
    amplitude = 1 / k / np.hypot(1 - r * r, 2 * zeta * r)
    assert np.abs(x[:, 0]).max() == pytest.approx(amplitude, rel=2e-4)
    assert np.abs(x[:, 1:]).max() == 0


def test_a_slow_cycle_is_quasi_static(h4):
    slow = cy.run(h4, 5.0, 0.5, samples=100)
    assert slow.dynamic_peak_norm == pytest.approx(slow.peak_norm, rel=1e-2)
    fast = cy.run(h4, 0.5, 0.5, samples=100)
    assert fast.f99 / fast.f1_robot > 1 and fast.dynamic_peak_norm > 2 * fast.peak_norm


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"period": -0.5}, ParameterError, "period"),
    ({"period": 0.5, "payload": -1.0}, ParameterError, "payload"),
    ({"period": float("nan")}, ParameterError, "period"),
    ({"period": 0.5, "samples": 3}, ParameterError, "samples"),
    ({"period": 0.5, "length": 2.0}, UnreachablePoseError, r"t = .* s"),
    ({"period": 0.5, "rise": 0.7}, ParameterError, "rise"),
])
def test_bad_input_is_a_typed_error(h4, kwargs, error, match):
    with pytest.raises(error, match=match):
        cy.run(h4, **kwargs)


@pytest.mark.slow  # a whole cycle command in a subprocess, 7 s
def test_cli(tmp_path):
    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "h4pin.cli", "cycle", *args], capture_output=True, text=True,
                              cwd=ROOT)

    png = tmp_path / "cycle.png"
    out = run("--time", "0.5", "--payload", "0", "--payload", "0.5", "--samples", "40", "--figure", str(png))
    assert out.returncode == 0, out.stderr
    assert "peak |dD| [um]" in out.stdout and png.stat().st_size > 10_000
    for args in (("--time", "-0.5"), ("--payload", "-1"), ("--time", "0")):
        bad = run(*args)
        assert bad.returncode == 2 and bad.stderr.startswith("error: ") and bad.stderr.count("\n") == 1
    far = run("--samples", "16", "--heading", "0", "--variant", "prototype", "--time", "0.5")
    assert far.returncode == 0


def test_the_paper_model_runs_and_vibrates_with_the_symmetric_k(h4):
    """model='paper' (a K that is not symmetric): the quasi-static answer is the paper's, the
    vibration and f1 the consistent model's, whose F and T columns are the same."""
    paper, consistent = (cy.run(h4, 0.5, samples=64, model=m) for m in ("paper", "consistent"))
    scale = np.abs(consistent.dynamic_deflection).max()
    np.testing.assert_allclose(paper.dynamic_deflection, consistent.dynamic_deflection, rtol=0, atol=1e-12 * scale)
    assert paper.f1_plate == pytest.approx(consistent.f1_plate, rel=1e-12) and np.isfinite(paper.peak_norm)
    np.testing.assert_allclose(paper.deflection[:, :6], consistent.deflection[:, :6], rtol=0,
                               atol=1e-6 * np.abs(consistent.deflection).max())
