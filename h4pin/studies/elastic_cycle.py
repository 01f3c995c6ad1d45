# SPDX-License-Identifier: Apache-2.0
"""The pick-and-place cycle on the elastic robot itself: the whole robot's loads, and its dynamics.

:func:`h4pin.studies.cycle.run` loads eq. 30's K with the plate's weight and d'Alembert load
alone. Here the robot is the elastic model of :func:`h4pin.elastic.elastic_model` (every
compliance a virtual joint with a spring, the actuators locked at the commanded motion, the
URDF's inertias of :func:`h4pin.elastic.modal.mass_model` and a point payload at D), driven by
the rigid motion of the cycle. Along it, at each sample:

1. the rigid motion (q, v, a) of the closed loop (:func:`h4pin.studies.cycle.sample`), carried to
   the elastic model's coordinates, every virtual joint at rest;
2. the load of every body: ``f = -rnea(q, v, a)`` (inertia and weight of the plate, payload,
   forearms, crosses and bars);
3. the springs' coordinates: the admissible small motions (closures kept, actuators locked) are
   ``dq = T s``, s the deflection of each spring (one coordinate per spring: the structure is
   statically determinate), so the stiffness is ``diag(k)`` and the load on spring i is
   ``f_s = T^T f``: the force it carries. The actuator spring ``actuator_i_elastic`` carries the
   whole motor torque (its control part ``f / kc``), each element its own load;
4. quasi-static: ``s = f_s / k``; dynamic: ``M_s s'' + C s' + diag(k) s = f_s(t)`` with
   ``M_s = T^T M T`` (M from ``pin.crba``), stiffness-proportional damping ``C = damping diag(k)``
   (s; :data:`h4pin.io.mjcf.DAMPING` by default, the elastic MuJoCo file's), integrated by
   Newmark's average acceleration from the static deflection at t = 0, through one cycle, then
   held at rest at the end pose (the stop) until the residual vibration has settled.

Linearised about the rigid motion: the deflection's own Coriolis and centrifugal terms, the
geometric stiffness of the preload and the change of T and M within a sample step (linear
interpolation) are neglected. ``tests/test_elastic_cycle.py`` checks the springs' loads against
the rigid closed-loop inverse dynamics, the quasi-static answer against ``K Gamma_ext`` with
massless legs, the legs' share of the motor torque against finite differences of their
potential energy, the slow-cycle limit and the elastic MuJoCo model driving the same cycle.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin import limits
from h4pin.elastic.h4 import elastic_model
from h4pin.elastic.modal import admissible_basis, mass_model
from h4pin.errors import ParameterError
from h4pin.kinematics import closed_form as cf
from h4pin.mechanism import engine
from h4pin.robot import H4
from h4pin.studies import cycle as rigid

#: Stiffness-proportional damping (s) by default: the elastic MuJoCo file's (1 % at 32.7 Hz).
DAMPING = 1e-4
#: The settling band at the tool after the stop (m), and how long the stop is followed (s).
BAND, HOLD = 50e-6, 1.5


@dataclasses.dataclass(frozen=True, eq=False)
class Springs:
    """The elastic robot along a motion, in spring coordinates (SI).

    Attributes:
        names: (ns,) the springs (virtual joints), in the elastic model's order.
        k: (ns,) their stiffness. kc: (4,) the actuators' servo stiffness.
        actuators: (4,) index in ``names`` of each ``actuator_i_elastic`` spring.
        t: (N,) s. load: (N, ns) ``f_s``, the force in each spring. mass: (N, ns, ns) ``M_s``.
        output: (N, 8, ns) dtp per unit deflection of each spring (dtp = [dD, dOmega, domega_1,
            domega_2]). rotation: (N, 3, 3) the central bar's orientation (the tool's offset).
        torque: (N, 4) N.m, the motor torques of the rigid closed-loop inverse dynamics.
        gamma: (N, 8) the plate's load Gamma_ext (weight and d'Alembert load of plate and payload).
        velocity: (N, ns, ns) the velocity terms of the dynamics linearised about the rigid motion
            (``T^T dtau/dv T + 2 T^T M T'``: ``M_s'`` and the gyroscopic terms; docs/cycle.md).
        stiffness: (N, ns, ns) the stiffness the motion adds to ``diag(k)`` (``T^T dtau/dq T +
            T^T dtau/dv T' + T^T M T''`` and the closures' curvature under their forces: gravity's
            and the motion's loads).
    """

    names: tuple[str, ...]
    k: np.ndarray
    kc: np.ndarray
    actuators: np.ndarray
    t: np.ndarray
    load: np.ndarray
    mass: np.ndarray
    output: np.ndarray
    rotation: np.ndarray
    torque: np.ndarray
    gamma: np.ndarray
    velocity: np.ndarray
    stiffness: np.ndarray

    def static(self) -> np.ndarray:
        """(N, ns) the quasi-static deflections ``f_s / k``."""
        return self.load / self.k

    def dtp(self, s: np.ndarray) -> np.ndarray:
        """(N, 8) dtp of deflections s (N, ns)."""
        return np.einsum("nij,nj->ni", self.output, s)

    def tool(self, s: np.ndarray, offset: np.ndarray) -> np.ndarray:
        """(N, 3) m, the displacement of the point ``offset`` (3,) m from D (central-bar frame)."""
        d = self.dtp(s)
        return d[:, :3] + np.cross(d[:, 3:6], np.einsum("nab,b->na", self.rotation, offset))

    def control(self, s_load: np.ndarray | None = None) -> np.ndarray:
        """(N, 8) dtp of the actuators' servos alone: each ``actuator_i_elastic`` spring's force
        over kc (its bending part left out)."""
        load = self.load if s_load is None else s_load
        s = np.zeros_like(load)
        s[:, self.actuators] = load[:, self.actuators] / self.kc
        return self.dtp(s)


def _velocity_map(rigid_model: pin.Model, model: pin.Model) -> np.ndarray:
    """(rigid nv,) the elastic model's velocity index of each rigid velocity coordinate."""
    out = np.empty(rigid_model.nv, dtype=int)
    for j in range(1, rigid_model.njoints):
        jr, je = rigid_model.joints[j], model.joints[model.getJointId(rigid_model.names[j])]
        out[jr.idx_v:jr.idx_v + jr.nv] = np.arange(je.idx_v, je.idx_v + je.nv)
    return out


_CHAIN = (pin.JointModelPX, pin.JointModelPY, pin.JointModelPZ, pin.JointModelRZ, pin.JointModelRY, pin.JointModelRX)


class _Coordinates:
    """The elastic model in vector coordinates: the same bodies, each free flyer (the plate) a
    chain of three slides and three hinges (x, y, z, then Z-Y-X angles), so that a configuration
    is a vector, v = q' and a = q'' and the linearisation ``q = q_r(t) + T(t) s`` is exact to first
    order (on a free flyer, q (+) T s would bring Lie-bracket terms). Velocity coordinates keep
    their indices (a free flyer's six are the chain's six)."""

    def __init__(self, model: pin.Model, constraint_models: Any) -> None:
        vm, jmap, self.free = pin.Model(), {0: 0}, []
        vm.gravity = model.gravity
        for j in range(1, model.njoints):
            parent = jmap[model.parents[j]]
            if model.joints[j].shortname() == "JointModelFreeFlyer":
                if parent != 0:
                    raise ParameterError(f"free flyer {model.names[j]!r} is not on the universe")
                for i, kind in enumerate(_CHAIN):
                    placement = model.jointPlacements[j] if i == 0 else pin.SE3.Identity()
                    parent = vm.addJoint(parent, kind(), placement, f"{model.names[j]}_{i}")
                self.free.append((model.joints[j].idx_q, model.joints[j].idx_v, parent))
                jmap[j] = parent
            else:
                jmap[j] = vm.addJoint(parent, model.joints[j], model.jointPlacements[j], model.names[j])
            vm.appendBodyToJoint(jmap[j], model.inertias[j], pin.SE3.Identity())
        self.model, self.data, self.source = vm, vm.createData(), model
        self.qmap = [(model.joints[j].idx_q, vm.joints[jmap[j]].idx_q) for j in range(1, model.njoints)
                     if model.joints[j].shortname() != "JointModelFreeFlyer"]
        for cm in constraint_models:
            if cm.type != pin.ContactType.CONTACT_3D:
                raise ParameterError(f"closure {cm.name!r}: only point (3-D) closures are linearised here")
        self.points = [(jmap[cm.joint1_id], cm.joint1_placement, jmap[cm.joint2_id], cm.joint2_placement)
                       for cm in constraint_models]

    def configuration(self, q: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """The vector configuration of q, and each free flyer's 6 x 6 Jacobian (its local twist
        per rate of its chain)."""
        qv = np.empty(self.model.nq)
        for old, new in self.qmap:
            qv[new] = q[old]
        for iq, _, last in self.free:
            x = q[iq:iq + 7]
            roll, pitch, yaw = pin.rpy.matrixToRpy(pin.Quaternion(x[6], x[3], x[4], x[5]).toRotationMatrix())
            qv[self.model.joints[last].idx_q - 5:self.model.joints[last].idx_q + 1] = [*x[:3], yaw, pitch, roll]
        pin.computeJointJacobians(self.model, self.data, qv)
        jac = [pin.getJointJacobian(self.model, self.data, last, pin.LOCAL)[:, iv:iv + 6] for _, iv, last in self.free]
        return qv, jac

    def tangent(self, x: np.ndarray, jac: list[np.ndarray]) -> np.ndarray:
        """Velocities (nv, ...) of the source model as rates of the vector model."""
        out = np.array(x, dtype=float)
        for (_, iv, _), j6 in zip(self.free, jac, strict=True):
            out[iv:iv + 6] = np.linalg.solve(j6, x[iv:iv + 6])
        return out

    def closure_jacobian(self, qv: np.ndarray) -> np.ndarray:
        """(3 n_closures, nv) d(p1 - p2)/dq of the closures' two points, world axes: the gradient
        of the closure function itself."""
        m, d = self.model, self.data
        pin.computeJointJacobians(m, d, qv)
        return np.vstack([pin.getFrameJacobian(m, d, j1, p1, pin.LOCAL_WORLD_ALIGNED)[:3]
                          - pin.getFrameJacobian(m, d, j2, p2, pin.LOCAL_WORLD_ALIGNED)[:3]
                          for j1, p1, j2, p2 in self.points])


def _motion_terms(co: _Coordinates, q: np.ndarray, v: np.ndarray, a: np.ndarray, T: np.ndarray,
                  neighbours: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], h: float,
                  locked: np.ndarray, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The velocity and stiffness matrices (ns, ns) of the dynamics linearised about the rigid
    motion (docs/cycle.md): ``T^T (dtau/dv T + 2 M T')`` and ``T^T (dtau/dq T + dtau/dv T' + M T'')
    - T^T d(A^T lambda)/dq T``, in the vector coordinates of ``co``; ``neighbours`` = (q, T) at
    t - h and t + h (T' and T'' by central differences)."""
    qv, jac = co.configuration(q)
    tv = co.tangent(T, jac)
    around = []
    for qn, tn in (neighbours[:2], neighbours[2:]):
        around.append(co.tangent(tn, co.configuration(qn)[1]))
    td = (around[1] - around[0]) / (2.0 * h)
    tdd = (around[1] - 2.0 * tv + around[0]) / (h * h)
    m, d = co.model, co.data
    vv = co.tangent(v, jac)
    pin.forwardKinematics(m, d, qv, vv, np.zeros(m.nv))
    bias = np.zeros(m.nv)
    for (_, iv, last), _j in zip(co.free, jac, strict=True):
        bias[iv:iv + 6] = d.a[last].vector
    av = co.tangent(a - bias, jac)
    dq, dv, mass = pin.computeRNEADerivatives(m, d, qv, vv, av)
    mass = np.triu(mass) + np.triu(mass, 1).T
    r0 = pin.rnea(m, d, qv, vv, av)
    # closure forces: r0 = A^T lambda + (locked actuators' torques) + (springs' forces), one square solve
    a_c = co.closure_jacobian(qv)
    eye = np.eye(m.nv)
    lam = np.linalg.solve(np.vstack([a_c, eye[locked], eye[dofs]]).T, r0)[:a_c.shape[0]]
    eps = 1e-6
    curvature = np.column_stack([(co.closure_jacobian(qv + eps * c).T - co.closure_jacobian(qv - eps * c).T) @ lam
                                 for c in tv.T]) / (2.0 * eps)
    velocity = tv.T @ (dv @ tv + 2.0 * mass @ td)
    stiffness = tv.T @ (dq @ tv + dv @ td + mass @ tdd - curvature)
    return velocity, stiffness


def springs_along(h4: H4, cycle: rigid.AdeptCycle, t: np.ndarray, payload: float = 0.0, *,
                  legs: bool = True, gravity: np.ndarray | None = None, motion: bool = True) -> Springs:
    """:class:`Springs` of the elastic robot (its elements included) along ``cycle`` at times
    ``t`` (s), with a point ``payload`` (kg) at D. ``legs=False``: the forearms, crosses and bars
    massless (only the plate and payload load the springs, as :func:`h4pin.studies.cycle.run`).
    ``motion=False``: the velocity and motion-stiffness matrices left at 0 (only ``M_s``, the
    model before the terms of the moving configuration were added).

    Raises:
        UnreachablePoseError (and subclasses), SingularPoseError: as the cycle's poses.
        ParameterError: a bad payload.
    """
    payload = rigid.positive("payload", payload, zero=True, unit=" (kg)")
    em = elastic_model(h4)
    mm = pin.Model(mass_model(em))
    plate_joints = {em.model.getJointId(h4.model.names[j]) for j in _plate_joints(h4)}
    if not legs:
        for j in range(1, mm.njoints):
            if j not in plate_joints:
                mm.inertias[j] = pin.Inertia.Zero()
    frame = mm.frames[mm.getFrameId("D")]
    if payload > 0:
        mm.inertias[frame.parentJoint] = mm.inertias[frame.parentJoint] + pin.Inertia(
            payload, frame.placement.translation, np.zeros((3, 3)))
    if gravity is not None:
        mm.gravity = pin.Motion(np.asarray(gravity, dtype=float), np.zeros(3))
    rigid_model = rigid.payload_model(h4, payload, gravity=gravity)
    if not legs:
        for j in range(1, rigid_model.njoints):
            if em.model.getJointId(rigid_model.names[j]) not in plate_joints:
                rigid_model.inertias[j] = pin.Inertia.Zero()
    rows = rigid.samples_along(h4, rigid_model, cycle, t)
    vmap = _velocity_map(h4.model, mm)
    names = tuple(n for n in em.stiffness)
    dofs = np.array([mm.joints[mm.getJointId(n)].idx_v for n in names])
    k = np.array([em.stiffness[n] for n in names])
    kfull = engine.stiffness_vector(mm, em.stiffness)
    kc = np.asarray(h4.geometry.springs["kc"], dtype=float)
    actuators = np.array([names.index(f"{a}_elastic") for a in h4.actuated_joint_names])
    locked = np.array([mm.joints[mm.getJointId(n)].idx_v for n in em.locked])
    d = mm.createData()
    n_t, ns = len(t), len(names)
    load, mass, output = np.empty((n_t, ns)), np.empty((n_t, ns, ns)), np.empty((n_t, 8, ns))
    velocity, stiffness = np.zeros((n_t, ns, ns)), np.zeros((n_t, ns, ns))
    pose = cycle.sample(t)[0]
    coordinates = _Coordinates(mm, em.constraint_models) if motion else None
    h = 4e-5 * cycle.period  # T' and T'' by central differences along q(t +- h) (Taylor: closures to ~1e-11 m)

    def basis(q: np.ndarray) -> np.ndarray:
        pin.computeJointJacobians(mm, d, q)
        b = admissible_basis(mm, em.constraint_models, q, em.locked, kfull, d)
        if b.shape[1] != ns:
            raise ParameterError(f"the elastic robot has {b.shape[1]} admissible motions for {ns} springs: "
                                 "it is not statically determinate")
        return b @ np.linalg.inv(b[dofs])

    for i, row in enumerate(rows):
        q = em.configuration(pose[i])
        v, a = np.zeros(mm.nv), np.zeros(mm.nv)
        v[vmap], a[vmap] = row.v, row.a
        T = basis(q)
        jo = engine.output_jacobian(mm, d, em.outputs)  # d at q (basis's kinematics), before the neighbours'
        if coordinates is not None:
            near = [pin.integrate(mm, q, sign * h * v + 0.5 * h * h * a) for sign in (-1.0, 1.0)]
            velocity[i], stiffness[i] = _motion_terms(coordinates, q, v, a, T, (near[0], basis(near[0]), near[1],
                                                      basis(near[1])), h, locked, dofs)
        f = -pin.rnea(mm, d, q, v, a)
        M = pin.crba(mm, d, q)
        M = np.triu(M) + np.triu(M, 1).T
        load[i] = T.T @ f
        mass[i] = T.T @ M @ T
        output[i] = jo @ T
    rotation = cf.rot_z(pose[:, 3])
    return Springs(names, k, kc, actuators, np.asarray(t, dtype=float), load, mass, output, rotation,
                   np.array([r.torque for r in rows]), np.array([r.load for r in rows]), velocity, stiffness)


def _plate_joints(h4: H4) -> list[int]:
    """The rigid model's joints that carry the plate (its free flyer and the two lateral
    revolutes): the subtree of the central bar."""
    central = h4.model.parents[h4.index.jid_lat[0]]
    return list(h4.model.subtrees[central])


@dataclasses.dataclass(frozen=True, eq=False)
class ElasticCycle:
    """One cycle on the elastic robot and the stop after it (SI).

    Attributes:
        cycle: the :class:`h4pin.studies.cycle.AdeptCycle`; payload: kg at D; damping: s.
        springs: the :class:`Springs` over the cycle and the hold (the last ``hold`` samples at
            rest at the end pose).
        t: (N,) s, from 0 to ``cycle.period + hold``. stop: index of t = period.
        tool: (3,) m, the tool's offset from D (central-bar frame).
        quasi_static, dynamic: (N, 3) m, the tool's displacement, quasi-static and dynamic.
        control_whole, control_plate: (N, 3) m, the servos' part of the quasi-static displacement
            of D, from the whole motor torque and from the plate's load alone (eq. 30's term).
        rest: (3,) m, the tool's displacement at rest at the end pose, where the dynamic answer
            settles (the springs' loads over ``diag(k)`` plus the stiffness of gravity's load on
            the closures' curvature; within 0.1 um of the quasi-static sag on the prototype).
    """

    cycle: rigid.AdeptCycle
    payload: float
    damping: float
    springs: Springs
    t: np.ndarray
    stop: int
    tool: np.ndarray
    quasi_static: np.ndarray
    dynamic: np.ndarray
    control_whole: np.ndarray
    control_plate: np.ndarray
    rest: np.ndarray

    @property
    def peak_quasi_static(self) -> float:
        """m, the largest ‖tool displacement‖ over the cycle, quasi-static."""
        return float(np.linalg.norm(self.quasi_static[:self.stop + 1], axis=1).max())

    @property
    def peak_dynamic(self) -> float:
        """m, the largest ‖tool displacement‖ over the cycle and the stop, dynamic."""
        return float(np.linalg.norm(self.dynamic, axis=1).max())

    @property
    def residual(self) -> np.ndarray:
        """(N - stop,) m, ‖dynamic - rest‖ at the tool after the stop (the static sag at rest,
        :attr:`rest`, taken away)."""
        return np.linalg.norm(self.dynamic[self.stop:] - self.rest, axis=1)

    @property
    def settling_time(self) -> float:
        """s after the stop until the residual stays within :data:`BAND` (inf if it does not
        within the hold)."""
        r = self.residual
        out = np.flatnonzero(r > BAND)
        if not out.size:
            return 0.0
        if out[-1] == len(r) - 1:
            return math.inf
        return float(self.t[self.stop + out[-1] + 1] - self.t[self.stop])


def run(h4: H4, period: float = 0.5, payload: float = 0.0, *, samples: int = 400, damping: float = DAMPING,
        hold: float = HOLD, tool: np.ndarray | None = None, motion: bool = True,
        **cycle_options: Any) -> ElasticCycle:
    """The standard cycle of ``period`` s with ``payload`` kg on the elastic robot (module
    docstring): quasi-static and dynamic tool displacement, and the stop after it.
    ``motion=False`` leaves out the terms of the moving configuration (:class:`Springs`'
    ``velocity`` and ``stiffness``): the model of h4pin 0.1's first release, kept for comparison.

    Raises:
        ParameterError: a bad argument. UnreachablePoseError, SingularPoseError: as the cycle.
    """
    from h4pin.inputs import check_flag, real_array, short

    if not isinstance(h4, H4):
        raise ParameterError(f"h4 must be an h4pin.H4 (h4pin.load(...)), got {type(h4).__name__} {h4!r:.60}")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 8:
        raise ParameterError(f"samples must be an integer >= 8, got {short(samples)}")
    limits.check_elastic_cycle(int(samples), 0)  # the motion alone, before its step is computed from it
    period = limits.check_range("period", rigid.positive("period", period, unit=" (s)"), "cycle_time")
    payload = limits.check_range("payload", rigid.positive("payload", payload, zero=True, unit=" (kg)"), "payload")
    damping = limits.check_range("damping", rigid.positive("damping", damping, zero=True, unit=" (s)"), "damping")
    hold = rigid.positive("hold", hold, zero=True, unit=" (s)")
    motion = check_flag(motion, "motion")
    rigid.check_cycle_options(cycle_options)
    dt = float(period) / samples
    n_hold = int(math.ceil(hold / dt))
    limits.check_elastic_cycle(int(samples), n_hold)
    o = np.zeros(3) if tool is None else real_array(tool, "tool", ParameterError, "a finite offset (3,) in m")
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise ParameterError(f"tool must be a finite offset (3,) in m, got {short(tool)}")
    limits.check_range("tool", o, "tool offset")
    cycle = rigid.adept_cycle(h4, period, **cycle_options)
    t = np.arange(samples + 1 + n_hold) * dt
    sp = springs_along(h4, cycle, t[:samples + 1], payload, motion=motion)
    # the stop: at rest at the end pose (the start pose) for the hold, the last sample repeated
    stay = np.r_[np.arange(samples + 1), np.full(n_hold, samples)]
    sp = dataclasses.replace(sp, t=t, **{f: getattr(sp, f)[stay] for f in (
        "load", "mass", "output", "rotation", "torque", "gamma", "velocity", "stiffness")})
    cyc = np.minimum(t, cycle.period)
    static = sp.static()
    dyn = rigid.newmark(sp.mass, sp.k, sp.load, dt, damping, velocity=sp.velocity, extra=sp.stiffness)
    plate = np.einsum("nij,nj->ni", _control_term(h4, cycle.sample(cyc)[0]), sp.gamma)
    rest = np.linalg.solve(np.diag(sp.k) + sp.stiffness[-1], sp.load[-1])
    at_rest = dataclasses.replace(sp, output=sp.output[-1:], rotation=sp.rotation[-1:])
    return ElasticCycle(cycle, float(payload), float(damping), sp, t, samples, o, sp.tool(static, o),
                        sp.tool(dyn, o), sp.control()[:, :3], plate[:, :3], at_rest.tool(rest[None], o)[0])


@dataclasses.dataclass(frozen=True, eq=False)
class MujocoCycle:
    """The elastic MuJoCo model driven along a cycle (:func:`mujoco_cycle`), SI.

    Attributes:
        t: (N,) s, MuJoCo's time steps from the start of the cycle. stop: index of t = period.
        displacement: (N, 3) m, D's displacement from the rigid pose at t, read from the state at
            t (MuJoCo's kinematics of that state, not the positions an ``mj_step`` leaves behind,
            which belong to the state before it).
        timestep: s.
    """

    t: np.ndarray
    stop: int
    displacement: np.ndarray
    timestep: float

    @property
    def residual(self) -> np.ndarray:
        """(N - stop,) m, ‖displacement - the static sag at rest‖ after the stop (the sag: the
        settled start, the same pose)."""
        return np.linalg.norm(self.displacement[self.stop:] - self.displacement[0], axis=1)


def mujoco_cycle(h4: H4, period: float = 0.5, payload: float = 0.0, *, timestep: float = 2.5e-5,
                 hold: float = HOLD, damping: float = DAMPING, settle: float = 0.6,
                 **cycle_options: Any) -> MujocoCycle:
    """The same cycle on the elastic MuJoCo model (:func:`h4pin.io.mjcf.elastic_spec` with
    ``servo=True`` and the payload at D): its position servos follow the cycle's actuator angles
    (rates by central differences), gravity on, from the sag at the start pose (``settle`` s with
    extra damping first), through the cycle and ``hold`` s at rest after it. The independent
    nonlinear route of :func:`run`'s dynamics (``tests/test_elastic_cycle.py``,
    ``scripts/cycle_mujoco.py``). Needs MuJoCo (the ``mujoco`` extra).

    Raises:
        MissingExtraError: MuJoCo missing or too old. ParameterError: a bad argument.
    """
    from h4pin.io import mjcf

    hold = rigid.positive("hold", hold, zero=True, unit=" (s)")
    settle = rigid.positive("settle", settle, zero=True, unit=" (s)")
    cycle = rigid.adept_cycle(h4, period, **cycle_options)
    spec = mjcf.elastic_spec(h4, q=h4.configuration(cycle.sample(np.zeros(1))[0][0]), damping=damping,
                             timestep=timestep, servo=True, payload=payload)
    import mujoco

    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(mjcf.KEYFRAME).id)
    site = m.site("D").id
    kept = m.dof_damping.copy()
    heavy = m.dof_armature == 0
    m.dof_damping[heavy] = 1e-2 * m.jnt_stiffness[m.dof_jntid[heavy]]  # settle the sag fast
    for _ in range(int(round(settle / timestep))):
        mujoco.mj_step(m, d)
    m.dof_damping[:] = kept
    n, n_hold = int(round(cycle.period / timestep)), int(round(hold / timestep))
    t = np.arange(n + n_hold + 1) * timestep
    pose = cycle.sample(np.minimum(t, cycle.period))[0]
    angles = np.asarray(cf.solve(h4.geometry, pose).state.q)
    rate = np.gradient(angles, timestep, axis=0)
    rate[n:] = 0.0
    out = np.empty((len(t), 3))
    for i in range(len(t)):
        mujoco.mj_kinematics(m, d)
        out[i] = d.site_xpos[site] - pose[i, :3]
        d.ctrl[:4], d.ctrl[4:] = angles[i], rate[i]
        mujoco.mj_step(m, d)
    return MujocoCycle(t, n, out, float(timestep))


def _control_term(h4: H4, poses: np.ndarray) -> np.ndarray:
    """(N, 8, 8) the control term of eq. 30 (consistent model) at the poses."""
    from h4pin.stiffness.api import compliance

    return compliance(h4, poses, "consistent", terms=True, elements=False).terms["control"]


def chart(h4: H4, periods: Sequence[float] = (0.3, 0.4, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0),
          payloads: Sequence[float] = (0.0, 0.5, 1.0), samples: int = 200, damping: float = DAMPING,
          hold: float = 4.0, progress: Any = None) -> dict[str, np.ndarray]:
    """Peak tool displacement (quasi-static and dynamic), residual amplitude and settling time
    after the stop (followed for ``hold`` s), for each cycle time and payload: arrays
    (len(payloads), len(periods)); ``progress(a, b, result)`` after each run."""
    shape = (len(payloads), len(periods))
    out = {name: np.empty(shape) for name in ("quasi_static", "dynamic", "residual", "settling")}
    for a, m in enumerate(payloads):
        for b, p in enumerate(periods):
            r = run(h4, p, m, samples=samples, damping=damping, hold=hold)
            out["quasi_static"][a, b] = r.peak_quasi_static
            out["dynamic"][a, b] = r.peak_dynamic
            out["residual"][a, b] = r.residual.max()
            out["settling"][a, b] = r.settling_time
            if progress is not None:
                progress(a, b, r)
    out["periods"], out["payloads"] = np.asarray(periods, float), np.asarray(payloads, float)
    return out


def report(results: ElasticCycle | Sequence[ElasticCycle]) -> str:
    """Text table of :func:`run`'s results, one column each: the peak tool displacement,
    quasi-static and dynamic, the largest residual after the stop and the settling time to
    :data:`BAND` (``h4pin cycle --elastic``)."""
    rs = [results] if isinstance(results, ElasticCycle) else list(results)
    settle = [f"> {r.t[-1] - r.t[r.stop]:.2f}" if math.isinf(r.settling_time) else f"{r.settling_time:.2f}" for r in rs]
    rows = [("payload [kg]", [f"{r.payload:g}" for r in rs]),
            ("peak tool |d|, quasi-static [um]", [f"{r.peak_quasi_static * 1e6:.1f}" for r in rs]),
            ("peak tool |d|, dynamic [um]", [f"{r.peak_dynamic * 1e6:.1f}" for r in rs]),
            ("largest residual after the stop [um]", [f"{r.residual.max() * 1e6:.1f}" for r in rs]),
            (f"settling to {BAND * 1e6:.0f} um after the stop [s]", settle)]
    lines = ["The elastic robot along the same cycle (every compliance a spring, the whole robot's "
             "inertia and weight, actuators", f"locked at the commanded motion; damping {rs[0].damping:g} s, "
             f"the stop followed for {rs[0].t[-1] - rs[0].t[rs[0].stop]:.2f} s; h4pin.studies.elastic_cycle):", ""]
    lines += [f"{name:<40}" + "".join(f"{x:>14}" for x in cells) for name, cells in rows]
    return "\n".join(lines)


__all__ = ["BAND", "DAMPING", "HOLD", "ElasticCycle", "MujocoCycle", "Springs", "chart", "mujoco_cycle", "report",
           "run", "springs_along"]
