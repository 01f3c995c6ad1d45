# SPDX-License-Identifier: Apache-2.0
"""Tool deflection along the standard pick-and-place cycle, from Pinocchio's closed-loop inverse
dynamics and the quasi-static compliance (``h4pin cycle``, docs/cycle.md).

The cycle (:class:`AdeptCycle`, :func:`adept_cycle`): D rises ``height`` (25 mm), crosses
``length`` (305 mm) horizontally, comes down ``height``, and goes back the same way, in
``period`` seconds, centred on the workspace centre (:func:`h4pin.kinematics.closed_form.centre_pose`)
and with theta constant. Each of the three motions of a half cycle follows the 5th-order law
``s(u) = 10 u^3 - 15 u^4 + 6 u^5`` (zero velocity and acceleration at both ends); the horizontal
motion starts before the rise ends (``overlap``), which rounds the corners. Position, velocity
and acceleration of the pose are analytic.

At each sample (:func:`cycle_dynamics`):

1. the configuration q (all 8 closures closed) from the inverse geometry;
2. the velocities v (nv) of every joint from the 24 closure equations ``Jc v = 0`` (the world
   velocity of the bar end B_ij minus that of its ball joint on the lateral bar) and the four
   prescribed plate rates ``J_D v = [x_dot, y_dot, z_dot, theta_dot]``: one 28x28 solve;
3. the accelerations a from the same matrix: ``Jc a = -gamma_c`` and
   ``J_D a = x_ddot - gamma_D``, the drift terms being the classical accelerations of the anchor
   points and of D at ``a = 0`` (``pin.getFrameClassicalAcceleration``);
4. the closed-loop inverse dynamics ``M a + b = S^T tau + Jc^T lambda`` (``pin.rnea`` gives the
   left side, gravity included): the 4 actuator torques and the 24 closure forces from one exact
   28x28 solve. lambda_n acts on the bar at B_ij; the bar pulls the plate with ``-lambda_n``;
5. the load on the elastic structure, ``Gamma_ext = -J_p^T (inertial + gravity wrench of the
   plate bodies)``: the rows of ``pin.rnea`` of the plate's 8 velocity coordinates (free-flyer
   and two lateral revolutes: that subtree holds exactly the central bar, the two lateral bars
   and the payload), mapped to h4pin's ``dtp`` coordinates at D. At rest it is the plate's
   weight, ``F = -(m_plate + m_payload) g``;
6. ``dtp = K(pose) Gamma_ext`` with :func:`h4pin.compliance` (the payload does not change K).

Quasi-static assumption. K is the static compliance of the legs, massless springs. The plate
(with the payload) is the only body whose inertia loads the springs: its d'Alembert force and
weight are applied as a static load. The legs' own inertia and weight (forearms, bars) are not
in ``Gamma_ext``; they are carried by the actuators (they are in ``tau``) and would deform the
legs by loads that eq. 30 does not model (transverse loads on the bars, forearm inertia). The
deflection is also the static response to the instantaneous load: valid while the load's
frequencies stay well below the first natural frequency of the plate on its legs
(:attr:`CycleResult.f1_plate`, :attr:`CycleResult.f1_robot`, :attr:`CycleResult.f99`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from h4pin import limits
from h4pin.errors import ParameterError, PoseError
from h4pin.inputs import short
from h4pin.kinematics import closed_form as cf
from h4pin.robot import H4
from h4pin.stiffness.api import TERMS, compliance
from h4pin.verdicts import OK, raise_for_status

#: The standard ("Adept") cycle: rise, horizontal stroke (m).
HEIGHT, LENGTH = 0.025, 0.305
_LWA = pin.LOCAL_WORLD_ALIGNED
_POSE_ROWS = [0, 1, 2, 5]  # v_x, v_y, v_z, w_z of a frame's 6 rows


def quintic(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 5th-order law ``s(u) = 10 u^3 - 15 u^4 + 6 u^5`` and its first two derivatives, for
    any ``u`` (clipped to [0, 1]: s = 0 before, 1 after, derivatives 0 outside)."""
    u = np.clip(u, 0.0, 1.0)
    v = 1.0 - u
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u), 30.0 * u * u * v * v, 60.0 * u * v * (1.0 - 2.0 * u)


@dataclasses.dataclass(frozen=True)
class AdeptCycle:
    """The pick-and-place cycle of D: rise, horizontal stroke, descent, and back (SI units).

    Attributes:
        period: s, the whole cycle (out and back).
        start: (3,) m, D at t = 0 (the low end of the out stroke); D returns there at t = period.
        length: m, horizontal stroke (along ``heading``).
        height: m, rise and descent.
        heading: rad, direction of the stroke in the horizontal plane (0: +x).
        theta: rad, the constant rotation of the central bar.
        rise: the rise (and the descent) last ``rise * period / 2`` each, 0 < rise <= 0.5.
        overlap: the stroke starts ``(1 - overlap) * rise * period / 2`` after the rise starts (and
            ends as long before the descent ends): 0 stops at each corner, towards 1 the corners are
            cut more (0 <= overlap < 1).
    """

    period: float
    start: np.ndarray
    length: float = LENGTH
    height: float = HEIGHT
    heading: float = 0.0
    theta: float = 0.0
    rise: float = 0.3
    overlap: float = 0.5

    @property
    def direction(self) -> np.ndarray:
        """(3,) unit horizontal direction of the out stroke."""
        return np.array([math.cos(self.heading), math.sin(self.heading), 0.0])

    def times(self, n: int) -> np.ndarray:
        """(n + 1,) s: n equal steps over one period, both ends included."""
        return np.linspace(0.0, self.period, n + 1)

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose, its velocity and its acceleration at times ``t`` (N,) s: three (N, 4) arrays,
        [x, y, z, theta] in m, rad; [m/s, rad/s]; [m/s^2, rad/s^2]. Times outside [0, period]
        repeat the cycle."""
        t = np.mod(np.asarray(t, dtype=float), self.period)
        t = np.where(np.isclose(t, self.period, rtol=0.0, atol=1e-12 * self.period), 0.0, t)
        half = 0.5 * self.period
        back = t >= half
        tau = np.where(back, t - half, t)
        t_rise = self.rise * half
        t0 = (1.0 - self.overlap) * t_rise
        span = half - 2.0 * t0
        s, ds, dds = quintic((tau - t0) / span)
        sign = np.where(back, -1.0, 1.0)
        h = np.where(back, 1.0 - s, s) * self.length
        hd, hdd = sign * ds * self.length / span, sign * dds * self.length / span**2
        up, dup, ddup = quintic(tau / t_rise)
        down, ddown, dddown = quintic((tau - (half - t_rise)) / t_rise)
        z = (up - down) * self.height
        zd, zdd = (dup - ddown) * self.height / t_rise, (ddup - dddown) * self.height / t_rise**2
        e = self.direction
        n = t.size
        pose, vel, acc = np.zeros((n, 4)), np.zeros((n, 4)), np.zeros((n, 4))
        pose[:, :3] = self.start + h.reshape(-1, 1) * e + z.reshape(-1, 1) * np.array([0.0, 0.0, 1.0])
        pose[:, 3] = self.theta
        vel[:, :3] = hd.reshape(-1, 1) * e
        vel[:, 2] = zd.reshape(-1)
        acc[:, :3] = hdd.reshape(-1, 1) * e
        acc[:, 2] = zdd.reshape(-1)
        return pose, vel, acc


def positive(name: str, value: Any, *, zero: bool = False, unit: str = "") -> float:
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise ParameterError(f"{name} must be a number{unit}, got {type(value).__name__} {short(value)}")
    try:
        v = float(value)
    except OverflowError:  # an int beyond the floats
        v = math.inf
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number{unit}, got {short(value)}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not zero):
        raise ParameterError(f"{name} must be a finite number {'>= 0' if zero else '> 0'}{unit}, got {short(value)}")
    return v


#: The shortest rise of :func:`adept_cycle` (a fraction of the half cycle): shorter ones make the
#: accelerations overflow.
MIN_RISE = 1e-6
#: The most samples :func:`adept_cycle` checks the cycle's poses at.
MAX_CHECK = 10**6


def check_cycle_options(options: dict[str, Any]) -> None:
    """Refuse options of :func:`adept_cycle` it does not take (passed on by the cycle studies),
    naming them and the ones it takes."""
    import inspect

    known = [n for n in inspect.signature(adept_cycle).parameters if n not in ("h4", "period")]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ParameterError(f"no cycle option {unknown[0]!r}; the options are {', '.join(known)}")


def adept_cycle(h4: H4, period: float = 0.5, *, centre: np.ndarray | None = None, length: float = LENGTH,
                height: float = HEIGHT, heading: float = 0.0, theta: float = 0.0, rise: float = 0.3,
                overlap: float = 0.5, check: int = 400) -> AdeptCycle:
    """The standard cycle centred on ``centre`` (3,) m (default: D at the workspace centre,
    :func:`h4pin.kinematics.closed_form.centre_pose`): the stroke spans ``centre -+ length/2``
    along ``heading``, the path ``centre_z -+ height/2``.

    Args:
        period: s, the whole cycle (> 0).
        check: the cycle is sampled at this many equal steps and every sample must be a pose the
            robot can take (inverse geometry with joint limits and bar interference).

    Raises:
        ParameterError: a bad argument.
        UnreachablePoseError (and subclasses): the cycle leaves the workspace (the message gives
            the time).
    """
    from h4pin.inputs import check_real, real_array

    period = positive("period", period, unit=" (s)")
    length = limits.check_range("length", positive("length", length, zero=True, unit=" (m)"), "stroke")
    height = limits.check_range("height", positive("height", height, zero=True, unit=" (m)"), "stroke")
    rise = positive("rise", rise)
    overlap = positive("overlap", overlap, zero=True)
    if not MIN_RISE <= rise <= 0.5:
        raise ParameterError(f"rise must be in [{MIN_RISE:g}, 0.5] (fraction of the half cycle), got {short(rise)}")
    if overlap >= 1.0:
        raise ParameterError(f"overlap must be in [0, 1), got {short(overlap)}")
    heading, theta = (check_real(v, name, unit="rad") for name, v in (("heading", heading), ("theta", theta)))
    if check is None or isinstance(check, bool) or not isinstance(check, (int, np.integer)) or \
            not 0 <= check <= MAX_CHECK:
        raise ParameterError(f"check must be an integer in [0, {MAX_CHECK:,}] (samples; 0: none), got {short(check)}")
    c = cf.centre_pose(h4)[:3] if centre is None else real_array(centre, "centre", ParameterError,
                                                                  "a finite point (3,) in m")
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ParameterError(f"centre must be a finite point (3,) in m, got {short(centre)}")
    limits.check_range("centre", c, "stroke centre")
    e = np.array([math.cos(heading), math.sin(heading), 0.0])
    start = c - 0.5 * length * e - np.array([0.0, 0.0, 0.5 * height])
    cycle = AdeptCycle(float(period), start, float(length), float(height), float(heading), float(theta),
                       float(rise), float(overlap))
    if check:
        check_reachable(h4, cycle, cycle.times(int(check)))
    return cycle


def check_reachable(h4: H4, cycle: AdeptCycle, t: np.ndarray) -> None:
    """Raise the typed error (:class:`h4pin.UnreachablePoseError` and subclasses) of the first
    time in ``t`` (s) at which the robot cannot take the cycle's pose."""
    pose = cycle.sample(t)[0]
    sol = cf.solve(h4.geometry, pose, check=True)
    if np.any(sol.status != OK):
        k = int(np.argmax(sol.status != OK))
        try:
            raise_for_status(sol.status[k], [sol.detail[k]], batch=False)
        except PoseError as exc:
            raise type(exc)(f"the cycle leaves the workspace at t = {t[k]:.4f} s, D = "
                            f"({', '.join(f'{v * 1e3:.1f}' for v in pose[k, :3])}) mm: {exc}") from None


def payload_model(h4: H4, payload: float = 0.0, at: np.ndarray | None = None,
                  gravity: np.ndarray | None = None) -> pin.Model:
    """A copy of the robot's model (the shared one is never changed) with a point mass
    ``payload`` (kg) fixed to the central bar at ``at`` (3,) m from D in the central-bar frame
    (world-aligned at theta = 0; default D itself), and gravity ``gravity`` (3,) m/s^2 (default:
    the model's)."""
    payload = positive("payload", payload, zero=True, unit=" (kg)")
    o = np.zeros(3) if at is None else np.asarray(at, dtype=float)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise ParameterError(f"the payload's point must be a finite offset (3,) in m, got {short(at)}")
    model = pin.Model(h4.model)
    frame = model.frames[h4.index.fid_D]
    joint = frame.parentJoint
    if payload > 0:
        model.inertias[joint] = model.inertias[joint] + pin.Inertia(payload, frame.placement.act(o), np.zeros((3, 3)))
    if gravity is not None:
        g = np.asarray(gravity, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ParameterError(f"gravity must be a finite vector (3,) in m/s^2, got {short(gravity)}")
        model.gravity = pin.Motion(g, np.zeros(3))
    return model


class Sample(NamedTuple):
    """The closed-loop motion and inverse dynamics at one instant (SI).

    Attributes:
        q: (nq,) configuration; v, a: (nv,) joint velocities and accelerations.
        torque: (4,) N.m, actuator torques (leg order).
        closure_forces: (8, 3) N, force of bar ij on the plate at B_ij, world axes (bar order).
        load: (8,) Gamma_ext = [F (N), T (N.m) at D, t1, t2 (N.m)], the load on the elastic legs.
        inertia_x: (4, 4) the whole robot's inertia reflected to [x, y, z, theta]
            (``G^T M G`` with ``v = G x_dot``), kg, kg.m, kg.m^2.
        inertia_plate: (8, 8) the plate's (and payload's) inertia in dtp coordinates.
    """

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    torque: np.ndarray
    closure_forces: np.ndarray
    load: np.ndarray
    inertia_x: np.ndarray
    inertia_plate: np.ndarray


def closure_rows(h4: H4, model: pin.Model, data: pin.Data) -> np.ndarray:
    """(24, nv): rows n = 3 k .. 3 k + 2 give the world velocity of bar k's end minus that of its
    ball joint on the lateral bar (zero when the closures hold). Needs
    ``pin.computeJointJacobians`` at the configuration in ``data``."""
    rows = np.empty((24, model.nv))
    for k, cm in enumerate(h4.constraint_models):
        j1 = pin.getFrameJacobian(model, data, cm.joint1_id, cm.joint1_placement, _LWA)[:3]
        j2 = pin.getFrameJacobian(model, data, cm.joint2_id, cm.joint2_placement, _LWA)[:3]
        rows[3 * k:3 * k + 3] = j1 - j2
    return rows


def closure_drift(h4: H4, model: pin.Model, data: pin.Data) -> np.ndarray:
    """(24,) m/s^2: the closure rows' ``J_dot v``, the classical acceleration of each bar end minus
    that of its ball joint at zero joint acceleration. Needs ``pin.forwardKinematics(model, data,
    q, v, 0)``."""
    out = np.empty(24)
    for k, cm in enumerate(h4.constraint_models):
        a1 = pin.getFrameClassicalAcceleration(model, data, cm.joint1_id, cm.joint1_placement, _LWA).linear
        a2 = pin.getFrameClassicalAcceleration(model, data, cm.joint2_id, cm.joint2_placement, _LWA).linear
        out[3 * k:3 * k + 3] = a1 - a2
    return out


def sample(h4: H4, model: pin.Model, data: pin.Data, pose: np.ndarray, velocity: np.ndarray,
           acceleration: np.ndarray) -> Sample:
    """Closed-loop motion and inverse dynamics of the robot (``model``: :func:`payload_model`,
    worked in ``data``, the caller's) at a pose (4,) with its velocity and acceleration (4,).

    Raises:
        UnreachablePoseError (and subclasses): the robot cannot take the pose.
        SingularPoseError: the closure and plate equations do not fix the joint motion.
    """
    from h4pin.errors import SingularPoseError

    nv = model.nv
    q = h4.configuration(np.asarray(pose, dtype=float))
    pin.computeJointJacobians(model, data, q)
    fid = h4.index.fid_D
    jd = pin.getFrameJacobian(model, data, fid, _LWA)
    A = np.vstack([closure_rows(h4, model, data), jd[_POSE_ROWS]])
    try:
        lu = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        lu = None
    if lu is None or not np.linalg.cond(A) < 1e12:
        raise SingularPoseError(f"the closures and the plate's motion do not fix the joints at pose {pose}")
    G = lu[:, 24:]  # v = G x_dot
    v = G @ np.asarray(velocity, dtype=float)
    pin.forwardKinematics(model, data, q, v, np.zeros(nv))
    a_d = pin.getFrameClassicalAcceleration(model, data, fid, _LWA)
    drift_d = np.r_[a_d.linear, a_d.angular[2]]
    a = lu @ np.r_[-closure_drift(h4, model, data), np.asarray(acceleration, dtype=float) - drift_d]
    b = pin.rnea(model, data, q, v, a).copy()
    B = np.zeros((nv, 28))
    B[h4.v_act, np.arange(4)] = 1.0
    B[:, 4:] = A[:24].T
    sol = np.linalg.solve(B, b)
    vp = h4.index.v_plate
    to_tp = np.eye(8)
    to_tp[:6, :6] = jd[:, vp[:6]]
    load = -np.linalg.solve(to_tp.T, b[vp])
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    inv_tp = np.linalg.inv(to_tp)
    return Sample(q, v, a, sol[:4], -sol[4:].reshape(8, 3), load, G.T @ M @ G,
                  inv_tp.T @ M[np.ix_(vp, vp)] @ inv_tp)


def _natural_frequency(stiffness: np.ndarray, inertia: np.ndarray) -> float:
    """Lowest natural frequency (Hz) of ``inertia * x'' + stiffness * x = 0``."""
    ls = np.linalg.cholesky(0.5 * (inertia + inertia.T))
    li = np.linalg.inv(ls)
    w2 = np.linalg.eigvalsh(li @ (0.5 * (stiffness + stiffness.T)) @ li.T)
    return float(math.sqrt(max(w2.min(), 0.0)) / (2.0 * math.pi))


@dataclasses.dataclass(frozen=True)
class CycleResult:
    """The cycle, its closed-loop dynamics and the quasi-static deflection (SI; N + 1 samples,
    the last one at t = period repeating the first).

    Attributes:
        cycle: the :class:`AdeptCycle`.
        payload: kg, a point mass at ``payload_at`` (3,) m from D (central-bar frame).
        model: the compliance model (``"consistent"`` or ``"paper"``).
        t: (N + 1,) s. pose, velocity, acceleration: (N + 1, 4) of [x, y, z, theta].
        q: (N + 1, nq), v, a: (N + 1, nv) the joints' motion.
        load: (N + 1, 8) Gamma_ext = [F, T, t1, t2] on the elastic legs (N, N.m), and what
            carries it: torque (N + 1, 4) N.m, the actuator torques; closure_forces
            (N + 1, 8, 3) N, the force of each bar on the plate at B_ij.
        deflection: (N + 1, 8) dtp = K Gamma_ext = [dD (m), dOmega (rad), domega_1, domega_2].
        tool: (3,) m, the tool point's offset from D (central-bar frame).
        tool_deflection: (N + 1, 3) m, the tool point's displacement ``dD + dOmega x (p - D)``.
        term_deflection: per term of K (``"control"``, ``"bending"``, ...): (N + 1, 3) m, its part
            of dD.
        f1_plate: Hz, the lowest natural frequency of the plate and payload on the massless
            elastic legs (8 dofs of dtp), lowest over the cycle.
        f1_robot: Hz, the lowest natural frequency in [x, y, z, theta] with the whole robot's
            inertia reflected there (legs moving rigidly with the plate), lowest over the cycle.
        f99: Hz, the frequency below which 99 % of the power of the load's force F (mean
            removed) lies, from its Fourier series over one period.
        compliance: (N + 1, 8, 8) K at each sample. plate_inertia: (N + 1, 8, 8) the plate's and
            payload's inertia in dtp coordinates.
        damping: the damping ratio of :attr:`dynamic_deflection` at :attr:`f1_plate`.
        dynamic_deflection: (N + 1, 8) dtp of the plate and payload on the massless elastic legs
            driven by the same load (:func:`dynamic_deflection`), periodic steady state: what the
            quasi-static :attr:`deflection` becomes when the plate's own vibration is kept.
    """

    cycle: AdeptCycle
    payload: float
    payload_at: np.ndarray
    model: str
    t: np.ndarray
    pose: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    load: np.ndarray
    torque: np.ndarray
    closure_forces: np.ndarray
    deflection: np.ndarray
    tool: np.ndarray
    tool_deflection: np.ndarray
    term_deflection: dict[str, np.ndarray]
    f1_plate: float
    f1_robot: float
    f99: float
    compliance: np.ndarray
    plate_inertia: np.ndarray
    damping: float
    dynamic_deflection: np.ndarray

    @property
    def _period(self) -> slice:
        return slice(0, len(self.t) - 1)  # one period, the repeated end left out

    @property
    def peak(self) -> np.ndarray:
        """(3,) m, the largest abs(dD) per axis over the cycle."""
        return np.abs(self.deflection[:, :3]).max(axis=0)

    @property
    def peak_norm(self) -> float:
        """m, the largest ‖dD‖ over the cycle."""
        return float(np.linalg.norm(self.deflection[:, :3], axis=1).max())

    @property
    def rms(self) -> np.ndarray:
        """(3,) m, the RMS of dD per axis over one period (time average)."""
        return np.sqrt(np.mean(self.deflection[self._period, :3] ** 2, axis=0))

    @property
    def rms_norm(self) -> float:
        """m, the RMS of ‖dD‖ over one period."""
        return float(np.sqrt(np.mean(np.sum(self.deflection[self._period, :3] ** 2, axis=1))))

    @property
    def dynamic_peak_norm(self) -> float:
        """m, the largest ‖dD‖ of :attr:`dynamic_deflection` over the cycle."""
        return float(np.linalg.norm(self.dynamic_deflection[:, :3], axis=1).max())

    @property
    def tool_peak_norm(self) -> float:
        """m, the largest displacement of the tool point over the cycle."""
        return float(np.linalg.norm(self.tool_deflection, axis=1).max())


def cycle_dynamics(h4: H4, cycle: AdeptCycle, t: np.ndarray, payload: float = 0.0, *,
                   payload_at: np.ndarray | None = None, gravity: np.ndarray | None = None) -> list[Sample]:
    """:func:`sample` at each time of ``t`` (s), in a model with the payload and a ``pin.Data``
    of this call's own."""
    return samples_along(h4, payload_model(h4, payload, payload_at, gravity), cycle, t)


def samples_along(h4: H4, model: pin.Model, cycle: AdeptCycle, t: np.ndarray) -> list[Sample]:
    """:func:`sample` at each time of ``t`` (s) in ``model`` (the robot's, or a copy with other
    inertias), with a ``pin.Data`` of this call's own."""
    data = model.createData()
    pose, vel, acc = cycle.sample(t)
    return [sample(h4, model, data, p, dv, da) for p, dv, da in zip(pose, vel, acc, strict=True)]


def newmark(mass: np.ndarray, stiffness: np.ndarray, load: np.ndarray, dt: float, damping: float,
            s0: np.ndarray | None = None, substeps: int = 4, *, velocity: np.ndarray | None = None,
            extra: np.ndarray | None = None) -> np.ndarray:
    """(N, n) the response of ``M(t) s'' + (damping K(t) + G(t)) s' + (K(t) + E(t)) s = f(t)`` at N
    equal steps ``dt`` of the sampled mass (N, n, n), stiffness K (N, n, n), or (n,) for a constant
    diagonal one, and load (N, n), by Newmark's average acceleration (unconditionally stable;
    ``substeps`` steps per sample, every matrix and f linear in between), from rest at ``s0``
    (default: the static answer of the first sample). ``velocity`` G and ``extra`` E (N, n, n),
    default 0: velocity-dependent and further position-dependent terms, not damped. Coordinates
    that move no mass follow their load through the damping (a first-order lag)."""
    beta, gamma = 0.25, 0.5
    h = dt / substeps
    diagonal = np.ndim(stiffness) == 1
    base = (lambda n: np.diag(stiffness)) if diagonal else (lambda n: stiffness[n])
    stiff = base if extra is None else (lambda n: base(n) + extra[n])
    gyro = (lambda n: 0.0) if velocity is None else (lambda n: velocity[n])
    s = np.linalg.solve(stiff(0), load[0]) if s0 is None else np.array(s0, dtype=float)
    v = np.zeros_like(s)
    acc = np.linalg.pinv(mass[0]) @ (load[0] - stiff(0) @ s)  # at rest: M a = f - K s (0 at equilibrium)
    out = np.empty_like(load)
    out[0] = s
    for n in range(len(load) - 1):
        k0, k1 = stiff(n), stiff(n + 1)
        c0, c1 = damping * base(n) + gyro(n), damping * base(n + 1) + gyro(n + 1)
        for j in range(1, substeps + 1):
            w = j / substeps
            mm = (1 - w) * mass[n] + w * mass[n + 1]
            kk = (1 - w) * k0 + w * k1
            cc = (1 - w) * c0 + w * c1
            ff = (1 - w) * load[n] + w * load[n + 1]
            rhs = ff + mm @ (s / (beta * h * h) + v / (beta * h) + (0.5 / beta - 1.0) * acc) \
                + cc @ (gamma * s / (beta * h) + (gamma / beta - 1.0) * v + h * (0.5 * gamma / beta - 1.0) * acc)
            s_new = np.linalg.solve(kk + gamma / (beta * h) * cc + mm / (beta * h * h), rhs)
            a_new = (s_new - s) / (beta * h * h) - v / (beta * h) - (0.5 / beta - 1.0) * acc
            v = v + h * ((1.0 - gamma) * acc + gamma * a_new)
            s, acc = s_new, a_new
        out[n + 1] = s
    return out


def dynamic_deflection(compliance_matrix: np.ndarray, inertia: np.ndarray, load: np.ndarray, period: float,
                       damping: float = 0.05, periods: int = 4, substeps: int = 4) -> np.ndarray:
    """dtp (N + 1, 8) of ``M x'' + C x' + K^-1 x = Gamma_ext(t)``: the plate (inertia ``M`` in dtp
    coordinates) on the massless elastic legs, under the load sampled at N + 1 equal steps of one
    period (the last sample repeating the first), integrated over ``periods`` periods by
    :func:`newmark` (``substeps`` steps per sample) from the static deflection of the first
    sample; the last period is returned. Damping is stiffness-proportional,
    ``C = 2 damping / omega_1 K^-1``: ratio ``damping`` at the lowest natural frequency omega_1 of
    the first sample, more above it."""
    stiff = np.linalg.inv(compliance_matrix)
    n = len(load) - 1
    omega1 = 2.0 * math.pi * _natural_frequency(stiff[0], inertia[0])
    every = np.r_[np.tile(np.arange(n), periods), n]
    x = newmark(inertia[every], stiff[every], load[every], period / n, 2.0 * damping / omega1,
                s0=compliance_matrix[0] @ load[0], substeps=substeps)
    out = x[-(n + 1):].copy()
    out[0] = out[-1]
    return out


def run(h4: H4, period: float = 0.5, payload: float = 0.0, *, samples: int = 400, model: str = "consistent",
        payload_at: np.ndarray | None = None, tool: np.ndarray | None = None, gravity: np.ndarray | None = None,
        damping: float = 0.05, **cycle_options: Any) -> CycleResult:
    """The standard cycle of ``period`` seconds with ``payload`` kg: dynamics, load and deflection.

    Args:
        h4: the robot.
        period: s, cycle time (> 0).
        payload: kg (>= 0), a point mass at ``payload_at`` (3,) m from D, central-bar frame
            (default D).
        samples: equal time steps over the period (>= 8).
        model: compliance model, ``"consistent"`` (default, symmetric K) or ``"paper"``.
        tool: (3,) m, the point whose displacement :attr:`CycleResult.tool_deflection` gives
            (default ``payload_at``).
        gravity: (3,) m/s^2 (default the model's, 9.81 down); zero gives the inertial part alone.
        damping: damping ratio of the plate's vibration (:func:`dynamic_deflection`).
        cycle_options: passed to :func:`adept_cycle` (``length``, ``height``, ``heading``,
            ``theta``, ``rise``, ``overlap``, ``centre``).

    Raises:
        ParameterError: a bad argument.
        UnreachablePoseError (and subclasses): the cycle leaves the workspace.
        SingularPoseError: a pose of the cycle is singular.
    """
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 8:
        raise ParameterError(f"samples must be an integer >= 8, got {short(samples)}")
    limits.check_cycle_samples(int(samples))
    limits.check_range("period", positive("period", period, unit=" (s)"), "cycle_time")
    payload = limits.check_range("payload", positive("payload", payload, zero=True, unit=" (kg)"), "payload")
    damping = positive("damping", damping, zero=True)
    at = np.zeros(3) if payload_at is None else np.asarray(payload_at, dtype=float)
    check_cycle_options({**cycle_options, "check": 0})
    cycle = adept_cycle(h4, period, check=0, **cycle_options)
    t = cycle.times(int(samples))
    check_reachable(h4, cycle, t)
    rows = cycle_dynamics(h4, cycle, t, payload, payload_at=at, gravity=gravity)
    pose, vel, acc = cycle.sample(t)
    load = np.array([r.load for r in rows])
    res = compliance(h4, pose, model, terms=True)
    dtp = np.einsum("nij,nj->ni", res.matrix, load)
    o = at if tool is None else np.asarray(tool, dtype=float)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise ParameterError(f"tool must be a finite offset (3,) in m, got {short(tool)}")
    r = np.einsum("nab,b->na", cf.rot_z(pose[:, 3]), o)
    tool_d = dtp[:, :3] + cf.cross(dtp[:, 3:6], r)
    terms = {name: np.einsum("nij,nj->ni", res.terms[name], load)[:, :3] for name in res.terms}
    # the vibration needs a symmetric K: the paper's is not (erratum 4, the t1, t2 columns), so
    # the plate's frequency and vibration take the consistent model's (the same F and T columns)
    sym = res.matrix if model == "consistent" else compliance(h4, pose, "consistent").matrix
    pairs = list(zip(sym, rows, strict=True))
    f1_plate = min(_natural_frequency(np.linalg.inv(k), s.inertia_plate) for k, s in pairs)
    sub = np.ix_(_POSE_ROWS, _POSE_ROWS)  # static condensation to [x, y, z, theta]: the 4x4 compliance block
    f1_robot = min(_natural_frequency(np.linalg.inv(k[sub]), s.inertia_x) for k, s in pairs)
    force = load[:-1, :3] - load[:-1, :3].mean(axis=0)
    power = np.sum(np.abs(np.fft.rfft(force, axis=0)) ** 2, axis=1)
    power[1:] *= 2.0
    share = np.cumsum(power) / power.sum() if power.sum() > 0 else np.ones_like(power)
    f99 = float(np.argmax(share >= 0.99)) / cycle.period
    inertia = np.array([s.inertia_plate for s in rows])
    dynamic = dynamic_deflection(sym, inertia, load, cycle.period, damping)
    return CycleResult(cycle, payload, at, model, t, pose, vel, acc, np.array([s.q for s in rows]),
                       np.array([s.v for s in rows]), np.array([s.a for s in rows]), load,
                       np.array([s.torque for s in rows]), np.array([s.closure_forces for s in rows]), dtp,
                       o, tool_d, {n: terms[n] for n in (*TERMS, *(k for k in terms if k not in TERMS))},
                       f1_plate, f1_robot, f99, res.matrix, inertia, damping, dynamic)


def report(results: CycleResult | Sequence[CycleResult]) -> str:
    """Text table: peak and RMS deflection of D (um) per axis, peak torque, peak load, and the
    quasi-static check; one column per result."""
    rs = [results] if isinstance(results, CycleResult) else list(results)
    c = rs[0].cycle
    acc = np.linalg.norm(rs[0].acceleration[:, :3], axis=1).max()
    lines = [f"standard cycle: {c.height * 1e3:.0f} mm up, {c.length * 1e3:.0f} mm across, {c.height * 1e3:.0f} mm "
             f"down and back, {c.period:g} s, start D = ({', '.join(f'{v * 1e3:.1f}' for v in c.start)}) mm, "
             f"peak acceleration {acc:.1f} m/s^2 ({acc / 9.81:.1f} g); compliance model '{rs[0].model}'", ""]
    w = 14

    def row(name: str, cells: list[str]) -> None:
        lines.append(f"{name:<34}" + "".join(f"{x:>{w}}" for x in cells))

    row("payload [kg]", [f"{r.payload:g}" for r in rs])
    for k, ax in enumerate("xyz"):
        row(f"peak |d{ax}| [um]", [f"{r.peak[k] * 1e6:.1f}" for r in rs])
    row("peak |dD| [um]", [f"{r.peak_norm * 1e6:.1f}" for r in rs])
    for k, ax in enumerate("xyz"):
        row(f"RMS d{ax} [um]", [f"{r.rms[k] * 1e6:.1f}" for r in rs])
    row("RMS |dD| [um]", [f"{r.rms_norm * 1e6:.1f}" for r in rs])
    if any(np.any(r.tool != 0) for r in rs):
        row("peak tool displacement [um]", [f"{r.tool_peak_norm * 1e6:.1f}" for r in rs])
    def peak(v: np.ndarray) -> float:  # the largest norm of rows over the cycle
        return np.linalg.norm(v, axis=1).max()

    cells = [("peak |dOmega| [mrad]", ".3f", lambda r: peak(r.deflection[:, 3:6]) * 1e3),
             ("peak actuator torque [N.m]", ".2f", lambda r: np.abs(r.torque).max()),
             ("peak |F| on the legs [N]", ".1f", lambda r: peak(r.load[:, :3])),
             ("peak |T| at D [N.m]", ".3f", lambda r: peak(r.load[:, 3:6])),
             ("peak |t_k| [N.m]", ".2e", lambda r: np.abs(r.load[:, 6:]).max())]
    cells += [(f"  peak |dD|, {name} term [um]", ".1f", lambda r, name=name: peak(r.term_deflection[name]) * 1e6)
              for name in rs[0].term_deflection]
    cells += [("f1 plate on massless legs [Hz]", ".0f", lambda r: r.f1_plate),
              ("f1 whole robot, x y z theta [Hz]", ".0f", lambda r: r.f1_robot),
              ("99 % of the load below [Hz]", ".0f", lambda r: r.f99),
              ("  ratio to f1 (whole robot)", ".2f", lambda r: r.f99 / r.f1_robot),
              ("peak |dD| with vibration [um]", ".1f", lambda r: r.dynamic_peak_norm * 1e6),
              ("  ratio to quasi-static", ".2f", lambda r: r.dynamic_peak_norm / r.peak_norm)]
    for name, spec, value in cells:
        row(name, [format(value(r), spec) for r in rs])
    lines += ["", "Quasi-static: dD = K Gamma_ext, Gamma_ext the plate's (and payload's) weight and d'Alembert "
              "load; the legs' own", "inertia is carried by the actuators and not in the load. 'With vibration': "
              f"the plate on the massless legs, {rs[0].damping:.0%} damping", "at f1, periodic steady state "
              "(docs/cycle.md)."]
    return "\n".join(lines)


__all__ = ["HEIGHT", "LENGTH", "AdeptCycle", "CycleResult", "Sample", "adept_cycle", "check_reachable",
           "closure_drift", "closure_rows", "cycle_dynamics", "dynamic_deflection", "newmark", "payload_model",
           "quintic", "report", "run", "sample", "samples_along"]
