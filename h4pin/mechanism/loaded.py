# SPDX-License-Identifier: Apache-2.0
"""The loaded robot: the non-linear static equilibrium of a :class:`~h4pin.mechanism.Mechanism`
under finite loads, its tangent stiffness, its critical load, and the motor positions that
compensate its sag.

The rest state is an assembled configuration ``q`` where every spring is at rest (a file's
``springref`` where it has one: :attr:`Mechanism.spring_rest`). Under the loads scaled by a load
factor ``s`` (0: none, 1: all), the equilibrium configuration solves

    R(q) + A(q)ᵀ μ = 0,      c(q) = 0

on the joints that are not locked, with ``R = Dᵀ K d(q) + s (g(q) - Σ J_fᵀ w_f)``: the springs
(``d = q ⊖ q_rest`` per joint, ``D = ∂d/∂q``), gravity (Pinocchio's generalised gravity on every
body, and a payload's weight at its centre of mass) and the dead loads ``w_f = [F; T]`` at frame
origins, world axes (``J_f`` the frames' ``LOCAL_WORLD_ALIGNED`` Jacobians); ``c`` the closures'
residuals (a world point gap, or ``log6`` of a relative placement) and the joint couplings', ``A``
their Jacobian, ``μ`` the closure and coupling forces.

Newton's method on that system takes the *tangent* stiffness ``H = ∂(R + Aᵀμ)/∂q``: the springs'
``K``, and the geometric terms of the loads, gravity and closure forces, which make the stiffness
depend on the load (and vanish without one). For revolute, prismatic, ball and free joints
(:func:`closed_form_joint`), ``H`` is in closed form (:meth:`Problem.tangent_exact`): a dead
load and a 3-D closure's force are forces at body points, whose generalised force ``S_i · F``
changes as a joint above turns the column ``S_i`` and moves the point; gravity's derivative is
Pinocchio's; a coupling's row bends with its polynomial's curvature; a 6-D closure's force is a
wrench at its frame, turned with it and with ``Jlog6`` of the relative placement (whose change in
six local directions, and a ball or free joint's spring, are central differences of their own,
without kinematics). For other joints ``H`` is the
central difference of the exact generalised forces over each free coordinate
(:meth:`Problem.tangent_fd`, exact to about 1e-9 relative). On the admissible motions
``dq = N z`` (the null space of ``A`` and the locked
joints), ``Hr = Nᵀ H N``: the equilibrium is stable where ``Hr`` is positive definite, and the
tangent compliance of outputs is ``J N Hr⁻¹ Nᵀ Jᵀ`` (what a small extra wrench does there; the
engine's linear compliance at zero load).

Loads are applied by continuation in ``s`` (:func:`solve`): steps from the rest state, each
predicted along the path's tangent and corrected by Newton, halved where Newton fails or jumps.
Where ``Hr`` loses definiteness between two steps, the crossing is located (bisection on its
least eigenvalue) and a stable branch is sought beside the path (the critical mode's two
directions, then a descent with a shifted Hessian): past a bifurcation with a stable branch (a
buckling strut) the buckled state is the answer; past a limit point (snap-through), where no
stable state is near, :class:`LimitLoadError` names the factor reached.
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from h4pin import limits
from h4pin.errors import ConvergenceError, ParameterError
from h4pin.limits import ImplausibleValueError
from h4pin.mechanism import assembly, engine, mjcf_writer
from h4pin.mechanism.arguments import checked_springs, outputs_of
from h4pin.mechanism.batch import configurations
from h4pin.mechanism.engine import UnrestrainedMotionError
from h4pin.mechanism.payload import at_frame

#: Central-difference step of the tangent stiffness (rad, or this times the length scale).
FD_STEP = 1e-6
#: Newton stops when a step moves no coordinate more than this (rad, or times the length scale).
STEP_TOL = 1e-13
#: Newton iterations at most per load step.
ITERATIONS = 30
#: A continuation step moves no coordinate more than this (rad, or times the length scale) by its
#: predictor: the path is followed, never jumped across (a limit point, another branch).
MAX_MOVE = 0.05
#: Smallest load-factor step of the continuation before a limit point is declared.
MIN_STEP = 1e-7
#: A state is stable when the least eigenvalue of the reduced tangent stiffness is above this
#: fraction of its largest.
STABLE_TOL = 1e-10


class LimitLoadError(ConvergenceError):
    """The load cannot be carried: past a limit point (snap-through) no stable equilibrium is near
    the load path. ``factor``: the load factor reached (the limit, within ``MIN_STEP``);
    ``equilibrium``: the last stable state on the path."""

    def __init__(self, message: str, factor: float, equilibrium: Any):
        super().__init__(message)
        self.factor = factor
        self.equilibrium = equilibrium


def _wrench(value: Any, what: str) -> np.ndarray:
    raw = np.asarray(value, dtype=object).reshape(-1)
    if any(isinstance(v, (bool, np.bool_, complex, np.complexfloating, str, bytes)) for v in raw):
        raise ParameterError(f"{what}: real numbers (N, N.m), got {value!r}")
    try:
        w = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ParameterError(f"{what}: a force (3,) N or a wrench [force; torque] (6,) N, N.m, got {value!r}") from None
    if w.shape not in ((3,), (6,)) or not np.all(np.isfinite(w)):
        raise ParameterError(f"{what}: a finite force (3,) N or wrench [force; torque] (6,) N, N.m, got {value!r}")
    if np.abs(w).max() > 1e9:
        raise ParameterError(f"{what}: {np.abs(w).max():.3g} N or N.m is beyond any robot's load (at most 1e9)")
    return np.r_[w, np.zeros(6 - len(w))]


@dataclasses.dataclass(frozen=True, eq=False)
class Loads:
    """The checked loads of a call: ``points`` ``(joint id, placement in the joint's frame,
    wrench (6,) world)`` each (the frames' loads and a payload's weight), and whether gravity acts
    on the model's bodies."""

    points: tuple[tuple[int, pin.SE3, np.ndarray], ...]
    gravity: bool

    @classmethod
    def of(cls, model: pin.Model, loads: Mapping[str, Any] | None, gravity: bool, payload: Any) -> Loads:
        if not isinstance(gravity, bool):
            raise ParameterError(f"gravity: True or False, got {gravity!r}")
        if loads is None:
            loads = {}
        if not isinstance(loads, Mapping):
            raise ParameterError(f"loads: a mapping {{frame name: (6,) wrench}}, got {loads!r}")
        points = []
        for frame, value in loads.items():
            if not isinstance(frame, str) or not model.existFrame(frame):
                raise ParameterError(f"loads: no frame {frame!r} in the model")
            f = model.frames[model.getFrameId(frame)]
            points.append((int(f.parentJoint), f.placement, _wrench(value, f"loads[{frame!r}]")))
        if payload is not None:
            _, body, f = at_frame(model, payload)
            if not gravity:
                raise ParameterError("payload: its weight acts only with gravity=True (a payload changes no "
                                     "static load without it)")
            at = f.placement * pin.SE3(np.eye(3), np.asarray(body.com, float))
            points.append((int(f.parentJoint), at, np.r_[body.mass * model.gravity.linear, np.zeros(3)]))
        if gravity and not np.any(model.gravity.linear):
            raise ParameterError("gravity: the model's gravity (model.gravity) is zero")
        if not points and not gravity:
            raise ParameterError("no load: give loads={frame: wrench}, gravity=True or a payload")
        return cls(tuple(points), gravity)


def closed_form_joint(jm: Any) -> bool:
    """Whether a joint's world Jacobian columns are constant local ones carried by its placement,
    moved by ``q ⊕ v = q exp(v)``: a revolute or prismatic joint (any axis, bounded or not), a
    ball or a free joint. An ancestor's (or the joint's own) coordinate j then turns column i as
    ``S_j × S_i``, which gives the tangent stiffness in closed form (:meth:`Problem.tangent_exact`)."""
    return (mjcf_writer.is_revolute(jm) or mjcf_writer.is_prismatic(jm) or mjcf_writer.is_free(jm)
            or jm.shortname() == "JointModelSpherical")


_ANCESTRY: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def ancestry(mech: Any) -> tuple[np.ndarray | None, tuple[slice, ...]]:
    """``(A, multi)`` of a mechanism, computed once (read-only): ``A[j, i]`` = 1 where coordinate j
    turns coordinate i's Jacobian column (j's joint is an ancestor of i's, or the same ball or free
    joint), None when a joint is not a :func:`closed_form_joint`; ``multi`` the coordinates of each
    joint of several coordinates."""
    out = _ANCESTRY.get(mech)
    if out is None:
        model, table = mech.model, None
        multi = tuple(slice(jm.idx_v, jm.idx_v + jm.nv) for jm in model.joints[1:] if jm.nv > 1)
        if all(closed_form_joint(model.joints[j]) for j in range(1, model.njoints)):
            table = np.zeros((model.nv, model.nv))
            for j in range(1, model.njoints):
                jm = model.joints[j]
                for a in list(model.supports[j])[1:]:
                    am = model.joints[a]
                    table[am.idx_v:am.idx_v + am.nv, jm.idx_v:jm.idx_v + jm.nv] = 1.0
            table.flags.writeable = False
        out = _ANCESTRY[mech] = (table, multi)
    return out


def subtree(model: pin.Model, joint: int) -> tuple[np.ndarray, np.ndarray]:
    """``(below (njoints,) bool, coordinates (nv,) 0/1)``: the joints of ``joint``'s subtree (itself
    and every joint under it) and their coordinates."""
    below = np.array([joint in list(model.supports[b]) for b in range(model.njoints)])
    coordinates = np.zeros(model.nv)
    for b in np.flatnonzero(below).tolist():
        coordinates[model.joints[b].idx_v:model.joints[b].idx_v + model.joints[b].nv] = 1.0
    return below, coordinates


def _cross_dot(twists: np.ndarray, jac: np.ndarray, f: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``[i, a] = (V_a × S_i) · F`` (nv, k): the twists V_a (6, k) turning the columns S_i of
    ``jac`` (6, nv), against the world force ``F = [f; n]``."""
    sf = pin.skew(f)
    v, w = jac[:3], jac[3:]
    return v.T @ sf @ twists[3:] + w.T @ sf @ twists[:3] + w.T @ pin.skew(n) @ twists[3:]


def _turned(motions: np.ndarray, f: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``M_a ×* F`` (6, k): how the world force ``F = [f; n]`` changes as its frame moves by each
    twist ``M_a`` (6, k)."""
    return np.r_[-pin.skew(f) @ motions[3:], -pin.skew(n) @ motions[3:] - pin.skew(f) @ motions[:3]]


def _jlog6_bend(rel: pin.SE3, wmu: np.ndarray) -> np.ndarray:
    """``d(Jlog6(rel exp(e))ᵀ W μ)/de`` (6, 6): central differences in the six local directions."""
    bend = np.zeros((6, 6))
    for k in range(6):
        e = np.zeros(6)
        e[k] = FD_STEP
        plus, minus = rel * pin.exp6(pin.Motion(e)), rel * pin.exp6(pin.Motion(-e))
        bend[:, k] = (pin.Jlog6(plus) - pin.Jlog6(minus)).T @ wmu / (2.0 * FD_STEP)
    return bend


def _dead(model: pin.Model, d: pin.Data, ancestors: np.ndarray, joint: int, p: np.ndarray, f: np.ndarray,
          m: np.ndarray) -> np.ndarray:
    """``∂(Jᵀ w)/∂q`` (nv, nv) of a dead wrench ``w = [f; m]`` (world) at the point p (world)
    of joint ``joint``'s body (J the point's LOCAL_WORLD_ALIGNED Jacobian), the joints'
    Jacobians computed in d. With the joint's world-frame columns ``S_i = [v_i; ω_i]`` and
    the wrench about the origin ``F = [f; p × f + m]``, ``(Jᵀw)_i = S_i · F``: joint j moves
    S_i when it is an ancestor of i (``∂S_i/∂q_j = S_j × S_i``, every column ``d.J``) and moves F
    through p (``∂p/∂q_j = v_j + ω_j × p``)."""
    jac = np.reshape(pin.getJointJacobian(model, d, joint, pin.WORLD), (6, model.nv))
    v, w = jac[:3], jac[3:]
    moved = _cross_dot(np.reshape(d.J, (6, model.nv)), jac, f, pin.skew(p) @ f + m) * ancestors.T
    return moved - w.T @ pin.skew(f) @ (v - pin.skew(p) @ w)


class _Weld(NamedTuple):
    """A 6-D closure's rows ``Jlog6(rel) Ad(o2⁻¹) (J2 - J1)`` (``J_k`` the world columns of joint
    k's chain, the rows scaled as :meth:`Problem.constraints` scales them) as a force:
    ``Aᵀμ = (J2 - J1)ᵀ F``, F = [f; n] the world force of the wrench ``λ = Jlog6(rel)ᵀ W μ`` at
    frame 2."""

    joints: tuple[int, int]
    o2: pin.SE3
    rel: pin.SE3
    wmu: np.ndarray
    j2: np.ndarray
    jd: np.ndarray
    f: np.ndarray
    n: np.ndarray

    @classmethod
    def of(cls, model: pin.Model, d: pin.Data, length: float, cm: Any, mu: np.ndarray) -> _Weld:
        o2 = d.oMi[cm.joint2_id] * cm.joint2_placement
        rel = (d.oMi[cm.joint1_id] * cm.joint1_placement).inverse() * o2
        wmu = mu * np.r_[np.full(3, 1.0 / length), np.ones(3)]
        j2 = np.reshape(pin.getJointJacobian(model, d, cm.joint2_id, pin.WORLD), (6, model.nv))
        jd = j2 - np.reshape(pin.getJointJacobian(model, d, cm.joint1_id, pin.WORLD), (6, model.nv))
        f, n = np.split(o2.toDualActionMatrix() @ (pin.Jlog6(rel).T @ wmu), 2)
        return cls((int(cm.joint1_id), int(cm.joint2_id)), o2, rel, wmu, j2, jd, f, n)

    def bent(self, motions: np.ndarray) -> np.ndarray:
        """F's change (6, k) as the relative placement moves by ``Ad(o2⁻¹) M_a`` (world twists M_a)."""
        return self.o2.toDualActionMatrix() @ _jlog6_bend(self.rel, self.wmu) @ self.o2.inverse().toActionMatrix() \
            @ motions

    def tangent(self, d: pin.Data, ancestors: np.ndarray) -> np.ndarray:
        """``∂(Aᵀμ)/∂q`` (nv, nv): the columns turned, F turned with frame 2 (``S_j ×* F``) and
        with ``Jlog6`` along the relative motion (its change in six local directions by differences)."""
        moved = _cross_dot(np.reshape(d.J, self.jd.shape), self.jd, self.f, self.n) * ancestors.T
        return moved + self.jd.T @ (_turned(self.j2, self.f, self.n) + self.bent(self.jd))

    def moved(self, below: np.ndarray, sub: np.ndarray, twists: np.ndarray) -> np.ndarray:
        """:meth:`Problem.moved_subtree`'s term (nv, k): the subtree's columns turned; F turned when
        frame 2 is below, and bent when one frame is below and the other not."""
        out = sub[:, None] * _cross_dot(twists, self.jd, self.f, self.n)
        dforce = np.zeros((6, twists.shape[1]))
        if below[self.joints[1]]:
            dforce += _turned(twists, self.f, self.n)
        side = float(below[self.joints[1]]) - float(below[self.joints[0]])
        if side:
            dforce += self.bent(side * twists)
        return out + self.jd.T @ dforce


class Problem:
    """One loaded mechanism: the model, its closures and couplings, the springs and their rest
    positions, the free coordinates, the loads, and the length scale of its translations.
    Evaluates the generalised forces, the constraints and the tangent stiffness (module docstring)
    in the calling thread's ``pin.Data`` of the mechanism."""

    def __init__(self, mech: Any, rest: np.ndarray, springs: Mapping[str, Any], locked: Sequence[str],
                 loads: Loads):
        self.mech, self.model, self.loads = mech, mech.model, loads
        model = self.model
        self.k = engine.stiffness_vector(model, springs)
        self.free = np.ones(model.nv, dtype=bool)
        for name in locked:
            j = model.joints[model.getJointId(name)]
            self.free[j.idx_v:j.idx_v + j.nv] = False
        self.rest = np.array(rest, dtype=float)
        self.spring_rest = self.rest.copy()  # the springs' rest: q, or the file's springref
        for name, value in getattr(mech, "spring_rest", {}).items():
            j = model.joints[model.getJointId(name)]
            if j.nq == 1:
                self.spring_rest[j.idx_q] = value
        d = mech.data
        pin.computeJointJacobians(model, d, self.rest)
        self.length = engine.length_scale(model, d)
        self.col = np.where(np.linalg.norm(np.reshape(d.J, (6, model.nv))[3:], axis=0) == 0.0, self.length, 1.0)
        self._last: tuple[Any, Any] | None = None  # the last reduced tangent (its state, its value)
        #: ``[j, i]``: coordinate j turns coordinate i's Jacobian column (:func:`ancestry`); None:
        #: a joint without a closed form, the tangent is taken by differences.
        self._ancestors, multi = ancestry(mech)
        #: The coordinates of ball and free joints with a spring (their spring's tangent by differences).
        self._curved = np.zeros(model.nv, dtype=bool)
        for cols in multi:
            self._curved[cols] = np.any(self.k[cols] != 0.0)

    # -------------------------------------------------------------- evaluations
    def forces(self, q: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
        """``(R (nv,), the load part's derivative in s (nv,))`` at q (module docstring)."""
        model, d = self.model, self.mech.data
        spring = self._springs(q)
        pin.computeJointJacobians(model, d, q)
        load = np.zeros(model.nv)
        for joint, place, w in self.loads.points:
            jac = pin.getFrameJacobian(model, d, joint, place, pin.LOCAL_WORLD_ALIGNED)
            load -= np.reshape(jac, (6, model.nv)).T @ w
        if self.loads.gravity:
            load += pin.computeGeneralizedGravity(model, d, q)
        return spring + s * load, load

    def constraints(self, q: np.ndarray, kinematics: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """``(c (m,), A (m, nv))`` at q: the closures' residuals (translations over the length
        scale) and the couplings', and their Jacobian (``kinematics``: Pinocchio's Jacobians
        computed at q first; False: they are, by :meth:`forces`)."""
        model, d = self.model, self.mech.data
        if kinematics:
            pin.computeJointJacobians(model, d, q)
        return assembly.closure_rows(self.mech, model, d, q, self.length)

    def gradient(self, q: np.ndarray, s: float, mu: np.ndarray) -> np.ndarray:
        """``R + Aᵀ μ`` (nv,) at q."""
        r, _ = self.forces(q, s)
        _, a = self.constraints(q, kinematics=False)
        return r + a.T @ mu

    def tangent(self, q: np.ndarray, s: float, mu: np.ndarray) -> np.ndarray:
        """``H`` (nv, nv) at q, μ fixed (columns of locked coordinates zero): in closed form
        (:meth:`tangent_exact`) where every joint is a :func:`closed_form_joint`, else
        :meth:`tangent_fd`."""
        return self.tangent_exact(q, s, mu) if self._ancestors is not None else self.tangent_fd(q, s, mu)

    def tangent_fd(self, q: np.ndarray, s: float, mu: np.ndarray,
                   part: Any = None, columns: np.ndarray | None = None) -> np.ndarray:
        """``H`` (nv, nv) at q, μ fixed: the central difference of :meth:`gradient` (or of
        ``part(q)``) along each free coordinate (or each of ``columns``; the others zero)."""
        model = self.model
        part = part or (lambda x: self.gradient(x, s, mu))
        h = np.zeros((model.nv, model.nv))
        for j in np.flatnonzero(self.free if columns is None else self.free & columns):
            step = np.zeros(model.nv)
            step[j] = FD_STEP * self.col[j]
            h[:, j] = (part(pin.integrate(model, q, step)) - part(pin.integrate(model, q, -step))) / (2.0 * step[j])
        return h

    def tangent_exact(self, q: np.ndarray, s: float, mu: np.ndarray) -> np.ndarray:
        """``H`` at q for a model of :func:`closed_form_joint` joints: the springs' ``K`` (a ball
        or free joint's by differences of the springs alone); the forces at body points (the dead
        loads', the 3-D closures': :func:`_dead`); gravity (Pinocchio's derivatives); the
        couplings' curvature; the 6-D closures' wrenches (:class:`_Weld`)."""
        model, d = self.model, self.mech.data
        pin.computeJointJacobians(model, d, q)
        h = np.diag(np.where(self._curved, 0.0, self.k))
        if self._curved.any():  # a ball or free joint's spring: Dᵀ K d bends with q
            h[:, self._curved] = self.tangent_fd(q, s, mu, part=self._springs, columns=self._curved)[:, self._curved]
        if self.loads.gravity:
            h += s * pin.computeGeneralizedGravityDerivatives(model, d, q)
        points, welds = self._closure_loads(mu)
        for joint, place, w in [(b, pl, s * w) for b, pl, w in self.loads.points] + points:  # -Jᵀw each
            h -= _dead(model, d, self._ancestors, joint, (d.oMi[joint] * place).translation, w[:3], w[3:])
        for weld in welds:
            h += _Weld.of(model, d, self.length, *weld).tangent(d, self._ancestors)
        row = len(mu) - len(self.mech.couplings)
        for c in self.mech.couplings:
            if c.joint2 is not None:  # the row's -slope(q2): its derivative -mu curvature
                j2 = model.joints[model.getJointId(c.joint2)]
                u2 = q[j2.idx_q] - c.origin2
                curve = sum(k * (k - 1) * a * u2 ** (k - 2) for k, a in enumerate(c.poly) if k > 1)
                h[j2.idx_v, j2.idx_v] -= mu[row] * curve
            row += 1
        h[:, ~self.free] = 0.0
        return h

    def _closure_loads(self, mu: np.ndarray) -> tuple[list[tuple[int, pin.SE3, np.ndarray]], list[tuple[Any, ...]]]:
        """The closures' forces μ as loads: each 3-D closure's ``Aᵀμ`` as two dead wrenches
        ``(joint, placement, w)`` whose generalised forces are ``-Jᵀw`` (as the loads'); each 6-D
        closure as ``(closure, its μ (6,))``."""
        points, welds, row, none = [], [], 0, np.zeros(3)
        for cm in self.mech.constraint_models:
            if cm.type == pin.ContactType.CONTACT_3D:
                f = np.asarray(mu[row:row + 3]) / self.length
                points += [(cm.joint2_id, cm.joint2_placement, np.r_[-f, none]),
                           (cm.joint1_id, cm.joint1_placement, np.r_[f, none])]
                row += 3
            else:
                welds.append((cm, np.asarray(mu[row:row + 6])))
                row += 6
        return points, welds

    def moved_subtree(self, q: np.ndarray, s: float, mu: np.ndarray, joint: int, twists: np.ndarray) -> np.ndarray:
        """``∂(R + Aᵀμ)/∂ε`` (nv, k) at the fixed q when the subtree of ``joint`` (the joint and
        every body below it) moves rigidly by ``exp(ε V_a)``, ``twists`` (6, k) the world twists
        V_a (a change of ``joint``'s placement): for :func:`closed_form_joint` models (raises
        RuntimeError otherwise). Each force at a body point (the loads, the bodies' weights, the
        3-D closures') changes as the subtree's columns turn and its points move; a 6-D closure's
        wrench as its frame turns and its relative placement changes (:class:`_Weld`)."""
        if self._ancestors is None:
            raise RuntimeError("moved_subtree: a joint without a closed form")
        model, d = self.model, self.mech.data
        pin.computeJointJacobians(model, d, q)
        below, sub = subtree(model, joint)
        out = np.zeros((model.nv, twists.shape[1]))
        points = [(b, pl, s * np.asarray(w, float)) for b, pl, w in self.loads.points]
        if self.loads.gravity:
            g = np.asarray(model.gravity.linear)
            points += [(b, pin.SE3(np.eye(3), np.asarray(model.inertias[b].lever)),
                        np.r_[s * model.inertias[b].mass * g, np.zeros(3)]) for b in range(1, model.njoints)]
        extra, welds = self._closure_loads(mu)
        for weld in welds:
            out += _Weld.of(model, d, self.length, *weld).moved(below, sub, twists)
        for b, place, w in points + extra:  # the generalised force -Jᵀw of each
            jac = np.reshape(pin.getJointJacobian(model, d, b, pin.WORLD), (6, model.nv))
            p = (d.oMi[b] * place).translation
            f, n = w[:3], pin.skew(p) @ w[:3] + w[3:]
            out -= sub[:, None] * _cross_dot(twists, jac, f, n)
            if below[b]:
                dp = twists[:3] - pin.skew(p) @ twists[3:]  # the point's velocities v_a + ω_a × p
                out -= jac[3:].T @ (-pin.skew(f) @ dp)
        return out

    def _springs(self, q: np.ndarray) -> np.ndarray:
        """The springs' generalised force ``Dᵀ K d`` (nv,) at q."""
        dv = pin.difference(self.model, self.spring_rest, q)
        return pin.dDifference(self.model, self.spring_rest, q, pin.ARG1).T @ (self.k * dv)

    def reduced(self, q: np.ndarray, s: float, mu: np.ndarray, h: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(N (nv, nz), Hr (nz, nz), H)``: the admissible motions in scaled coordinates (``dq =
        N z``) and the reduced tangent stiffness, symmetrised (``tangent`` computed if not given;
        the last state's kept: asked again at the same state, nothing is recomputed)."""
        key = (q.tobytes(), float(s), np.asarray(mu).tobytes())
        if h is None and self._last is not None and self._last[0] == key:
            return self._last[1]
        _, a = self.constraints(q)
        if h is None:
            h = self.tangent(q, s, mu)
        free = np.flatnonzero(self.free)
        af = a[:, free] * self.col[free][None, :]
        if af.shape[0]:
            _, sv, vt = np.linalg.svd(af)
            rank = int(np.sum(sv > engine.RANK_TOL * sv[0])) if sv.size and sv[0] > 0 else 0
            basis = vt[rank:].T
        else:
            basis = np.eye(len(free))
        n = np.zeros((self.model.nv, basis.shape[1]))
        n[free] = self.col[free][:, None] * basis
        hr = n.T @ h @ n
        out = (n, 0.5 * (hr + hr.T), h)
        self._last = (key, out)
        return out

    # -------------------------------------------------------------- Newton
    def newton(self, q: np.ndarray, s: float, mu: np.ndarray, shift: bool = False
               ) -> tuple[np.ndarray, np.ndarray, bool]:
        """``(q, μ, converged)``: Newton's method on the equilibrium at load factor s from q
        (``shift``: the reduced Hessian shifted to positive definite and a backtracking line
        search on the residual: a descent to a stable state from beside an unstable one)."""
        model = self.model
        free = np.flatnonzero(self.free)
        last, h = math.inf, None
        for _ in range(ITERATIONS * (3 if shift else 1)):
            r, _ = self.forces(q, s)
            c, a = self.constraints(q)
            if h is None or shift:  # modified Newton: the tangent kept while the steps shrink ten-fold
                h = self.tangent(q, s, mu)
                n, _, _ = self.reduced(q, s, mu, h)
                hr = n.T @ h @ n  # not symmetrised: a dead torque's tangent is not symmetric
            af = a[:, free]
            dq = np.zeros(model.nv)
            if af.shape[0]:
                dq[free] = -np.linalg.lstsq(af * self.col[free][None, :], c, rcond=None)[0] * self.col[free]
            g = n.T @ (r + a.T @ mu + h @ dq)
            if shift:
                least = float(np.linalg.eigvalsh(hr)[0]) if hr.size else 0.0
                scale = float(np.abs(hr).max()) if hr.size else 1.0
                hr = hr + max(0.0, -least + 1e-3 * scale) * np.eye(len(hr))
            try:
                z = -np.linalg.solve(hr, g) if hr.size else np.zeros(0)
            except np.linalg.LinAlgError:
                return q, mu, False
            dq = dq + n @ z
            if af.shape[0]:
                mu = np.linalg.lstsq(af.T, -(r + h @ dq)[free], rcond=None)[0]
            size = float(np.max(np.abs(dq / self.col))) if dq.size else 0.0
            if shift and size > 0.1:  # a descent takes bounded steps
                dq, size = dq * (0.1 / size), 0.1
            if not np.isfinite(size) or size > 1.0:
                return q, mu, False
            q = pin.integrate(model, q, dq)
            if size <= STEP_TOL or (size < 1e-10 and size >= 0.5 * last):  # done, or at round-off
                c, _ = self.constraints(q)
                return q, mu, bool(np.max(np.abs(c), initial=0.0) <= 1e-11)
            if size > 0.1 * last:  # slow: a new tangent next step
                h = None
            last = size
        return q, mu, False

    def stability(self, q: np.ndarray, s: float, mu: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """``(least eigenvalue of Hr over its largest, its mode dq (nv,), N)`` at an equilibrium."""
        n, hr, _ = self.reduced(q, s, mu)
        if not hr.size:
            return 1.0, np.zeros(self.model.nv), n
        vals, vecs = np.linalg.eigh(hr)
        top = max(float(np.abs(vals).max()), 1e-300)
        return float(vals[0] / top), n @ vecs[:, 0], n

    def predictor(self, q: np.ndarray, s: float, mu: np.ndarray, ds: float) -> np.ndarray:
        """q moved by the path's tangent over ``ds``: ``Hr z = -Nᵀ ∂R/∂s``."""
        _, load = self.forces(q, s)
        n, hr, _ = self.reduced(q, s, mu)
        if not hr.size:
            return q
        try:
            z = -np.linalg.solve(hr, n.T @ load)
        except np.linalg.LinAlgError:
            return q
        return pin.integrate(self.model, q, ds * (n @ z))


@dataclasses.dataclass(frozen=True, eq=False)
class Equilibrium:
    """A loaded equilibrium of a :class:`~h4pin.mechanism.Mechanism`
    (:meth:`Mechanism.equilibrium <h4pin.mechanism.Mechanism.equilibrium>`).

    Attributes:
        q: (nq,) the loaded configuration. rest: (nq,) the unloaded one it started from.
        load_factor: 1.0 when the whole load is carried.
        stable: the reduced tangent stiffness is positive definite there.
        torques: (nv,) the springs' generalised forces ``K d`` (N.m, N).
        closure_forces: ``{closure or coupling: its force}`` (μ: N for a closure's position rows,
            N.m for its rotation rows and for a coupling).
        critical: the load factors at which the path crossed a critical point on the way (a
            buckled branch was taken there); empty for a path that stayed stable.
    """

    q: np.ndarray
    rest: np.ndarray
    load_factor: float
    stable: bool
    torques: np.ndarray
    closure_forces: Mapping[str, np.ndarray]
    critical: tuple[float, ...]
    problem: Problem = dataclasses.field(repr=False)
    mu: np.ndarray = dataclasses.field(repr=False)

    def displacement(self, frame: str) -> np.ndarray:
        """(6,) the frame's motion from the rest state: ``[dp; dθ]``, its origin's translation
        (m) and its rotation (rad, ``log3(R Rrestᵀ)``), world axes."""
        model = self.problem.model
        if not isinstance(frame, str) or not model.existFrame(frame):
            raise ParameterError(f"frame: no frame {frame!r} in the model")
        fid = model.getFrameId(frame)
        d = model.createData()
        pin.framesForwardKinematics(model, d, self.rest)
        before = pin.SE3(d.oMf[fid])
        pin.framesForwardKinematics(model, d, self.q)
        after = d.oMf[fid]
        return np.r_[after.translation - before.translation, pin.log3(after.rotation @ before.rotation.T)]

    def compliance(self, outputs: Sequence[Any]) -> np.ndarray:
        """The tangent compliance (6 n, 6 n) of n output frames at the loaded state: what a small
        extra wrench at each frame's origin (world axes) does there, ``J N Hr⁻¹ Nᵀ Jᵀ`` with the
        geometric terms of the loads, gravity and closure forces (module docstring).

        Raises:
            ParameterError: an unknown frame. UnrestrainedMotionError: the state is critical
            (the reduced tangent stiffness is singular).
        """
        p = self.problem
        outs = outputs_of(p.mech, outputs)
        n, hr, _ = p.reduced(self.q, self.load_factor, self.mu)
        d = p.mech.data
        pin.computeJointJacobians(p.model, d, self.q)
        jo = engine.output_jacobian(p.model, d, outs) @ n
        try:
            return jo @ np.linalg.solve(hr, jo.T)
        except np.linalg.LinAlgError:
            raise UnrestrainedMotionError("the loaded state is critical: its tangent stiffness is singular") from None


def _equilibrium(p: Problem, q: np.ndarray, s: float, mu: np.ndarray, stable: bool,
                 critical: tuple[float, ...]) -> Equilibrium:
    model = p.model
    dv = pin.difference(model, p.spring_rest, q)
    torques = pin.dDifference(model, p.spring_rest, q, pin.ARG1).T @ (p.k * dv)
    forces, at = {}, 0
    for cm in p.mech.constraint_models:
        size = 3 if cm.type == pin.ContactType.CONTACT_3D else 6
        f = np.array(mu[at:at + size])
        f[:3] /= p.length  # the rows were scaled by 1/L: back to N
        forces[cm.name] = f
        at += size
    for c in p.mech.couplings:
        forces[f"coupling {c.joint1}"] = np.array(mu[at:at + 1])
        at += 1
    for a in (q, torques):
        a.setflags(write=False)
    return Equilibrium(q, p.rest, float(s), bool(stable), torques, forces, critical, p, mu)


def _switch(p: Problem, q: np.ndarray, s: float, mu: np.ndarray, mode: np.ndarray) -> tuple[np.ndarray,
                                                                                            np.ndarray] | None:
    """A stable equilibrium at s beside the unstable q: a descent from q pushed each way along
    the critical mode (scaled to a hundredth of the length scale, or 0.01 rad); None if none."""
    size = float(np.max(np.abs(mode / p.col))) or 1.0
    for sign in (1.0, -1.0):
        start = pin.integrate(p.model, q, sign * 1e-2 * mode / size)
        q1, mu1, ok = p.newton(start, s, mu, shift=True)
        if ok:
            q2, mu2, ok = p.newton(q1, s, mu1)
            if ok and p.stability(q2, s, mu2)[0] > STABLE_TOL:
                return q2, mu2
    return None


def _crossing(p: Problem, q: np.ndarray, s: float, mu: np.ndarray, s1: float) -> float:
    """The load factor in (s, s1] where the least eigenvalue of Hr crosses 0 (bisection along the
    path, 40 halvings at most, from the stable q at s)."""
    lo, hi, qlo, mulo = s, s1, q, mu
    for _ in range(40):
        if hi - lo <= 1e-9 * max(1.0, abs(hi)):
            break
        mid = 0.5 * (lo + hi)
        qm, mum, ok = p.newton(p.predictor(qlo, lo, mulo, mid - lo), mid, mulo)
        if ok and p.stability(qm, mid, mum)[0] > STABLE_TOL:
            lo, qlo, mulo = mid, qm, mum
        else:
            hi = mid
    return 0.5 * (lo + hi)


def solve(p: Problem, target: float = 1.0, *, stop_at_critical: bool = False) -> tuple[Equilibrium, float | None]:
    """The equilibrium at load factor ``target`` by continuation from the rest state (module
    docstring), and the first critical load factor met (None if none). ``stop_at_critical``:
    return at the first critical point instead (:func:`critical`).

    Raises:
        UnrestrainedMotionError: the rest state is not restrained by the springs.
        LimitLoadError: a limit point before ``target`` (no stable state beyond it).
    """
    q, mu = p.rest.copy(), np.zeros(len(p.constraints(p.rest)[0]))
    least, mode, _ = p.stability(q, 0.0, mu)
    if not least > STABLE_TOL:
        model = p.model
        moving = [model.names[j] for j in range(1, model.njoints)
                  if np.abs(mode[model.joints[j].idx_v:model.joints[j].idx_v + model.joints[j].nv]).max(initial=0.0)
                  > 0.1 * np.abs(mode).max(initial=0.0)]
        raise UnrestrainedMotionError(f"{p.mech.name}: at rest a motion strains no spring (least reduced stiffness "
                                      f"{least:.2e} of the largest; it moves {', '.join(moving[:6])}); give springs "
                                      "or lock joints", mode, tuple(moving), math.inf)
    s, ds, first, crossed = 0.0, float(target), None, []
    while s < target:
        s1 = min(s + ds, target)
        pred = p.predictor(q, s, mu, s1 - s)
        moved = float(np.max(np.abs(pin.difference(p.model, q, pred) / p.col)))
        if moved > MAX_MOVE and ds > MIN_STEP * max(1.0, s):
            ds *= max(0.5 * MAX_MOVE / moved, 1e-3)
            continue
        q1, mu1, ok = p.newton(pred, s1, mu)
        jump = float(np.max(np.abs(pin.difference(p.model, pred, q1) / p.col))) if ok else math.inf
        if not ok or jump > 0.5 * moved + 1e-9:  # no convergence, or onto another branch
            ds *= 0.5
            if ds < MIN_STEP * max(1.0, s):
                eq = _equilibrium(p, q, s, mu, True, tuple(crossed))
                raise LimitLoadError(f"{p.mech.name}: the load cannot be carried past load factor {s:.6g} (a limit "
                                     "point: no stable equilibrium beyond it on the load path)", s, eq)
            continue
        least, mode, _ = p.stability(q1, s1, mu1)
        if least > STABLE_TOL:
            q, mu, s = q1, mu1, s1
            ds = min(2.0 * ds, target)
            continue
        star = _crossing(p, q, s, mu, s1)
        first = star if first is None else first
        crossed.append(star)
        if stop_at_critical:
            return _equilibrium(p, q, s, mu, True, tuple(crossed)), first
        branch = _switch(p, q1, s1, mu1, mode)
        if branch is None:
            eq = _equilibrium(p, q, s, mu, True, tuple(crossed))
            raise LimitLoadError(f"{p.mech.name}: the load cannot be carried past load factor {star:.6g} (the tangent "
                                 "stiffness becomes singular there and no stable state is near)", star, eq)
        (q, mu), s = branch, s1
    return _equilibrium(p, q, s, mu, True, tuple(crossed)), first


def warm(p: Problem, start: np.ndarray, mu: np.ndarray) -> Equilibrium | None:
    """The equilibrium at the whole load by Newton from ``start`` (a neighbouring problem's
    equilibrium: a calibration's previous parameters), or None when it does not converge to a
    stable state within :data:`MAX_MOVE` of ``start`` (then :func:`solve`, from the rest state)."""
    q, mu, ok = p.newton(start, 1.0, mu)
    if not ok or float(np.max(np.abs(pin.difference(p.model, start, q) / p.col))) > MAX_MOVE:
        return None
    if not p.stability(q, 1.0, mu)[0] > STABLE_TOL:
        return None
    return _equilibrium(p, q, 1.0, mu, True, ())


@dataclasses.dataclass(frozen=True)
class CriticalLoad:
    """The first critical point on a proportional load path
    (:meth:`Mechanism.critical_load <h4pin.mechanism.Mechanism.critical_load>`).

    Attributes:
        factor: the load factor λ at which the reduced tangent stiffness becomes singular
            (``inf``: none up to ``max_factor``). kind: ``"bifurcation"`` (an equilibrium goes on
            past it: a buckling mode), ``"limit"`` (none does: snap-through) or ``"none"``.
        mode: (nv,) the critical motion (the tangent's null direction), unit-scaled.
        equilibrium: the last stable equilibrium before it.
    """

    factor: float
    kind: str
    mode: np.ndarray
    equilibrium: Any


def critical(p: Problem, max_factor: float) -> CriticalLoad:
    """:meth:`Mechanism.critical_load`: the path followed up to ``max_factor``."""
    try:
        eq, first = solve(p, max_factor, stop_at_critical=True)
    except LimitLoadError as exc:
        _, mode, _ = p.stability(exc.equilibrium.q, exc.factor, exc.equilibrium.mu)
        return CriticalLoad(exc.factor, "limit", mode / max(np.abs(mode).max(), 1e-300), exc.equilibrium)
    if first is None:
        return CriticalLoad(math.inf, "none", np.zeros(p.model.nv), eq)
    _, mode, _ = p.stability(*_at(p, eq, first))
    return CriticalLoad(first, "bifurcation", mode / max(np.abs(mode).max(), 1e-300), eq)


def _at(p: Problem, eq: Equilibrium, s: float) -> tuple[np.ndarray, float, np.ndarray]:
    """The equilibrium on the path at s, from eq (just before it)."""
    q, mu, ok = p.newton(p.predictor(eq.q, eq.load_factor, eq.mu, s - eq.load_factor), s, eq.mu)
    return (q, s, mu) if ok else (eq.q, eq.load_factor, eq.mu)


def problem(mech: Any, q: Any, springs: Mapping[Any, Any], loads: Any, gravity: bool, payload: Any,
            locked: Iterable[Any], free_root: bool = False) -> Problem:
    """The :class:`Problem` of a :class:`Mechanism` call, its arguments checked."""
    stiff, lock = checked_springs(mech, springs, locked, free_root)
    lock = lock + tuple(n for n in mech.actuated if n not in stiff and n not in lock)  # a motor without a servo
    rest = mech.configuration(q)
    worst = max(((max(e), n) for n, e in mech.closure_errors(rest).items()), default=(0.0, ""))
    if not worst[0] <= 1e-9:
        raise engine.UnassembledError(f"q: closure {worst[1]!r} is off by {worst[0]:.3e} (m or rad): the rest state "
                                      "must be assembled (mech.assemble())")
    return Problem(mech, rest, stiff, lock, Loads.of(mech.model, loads, gravity, payload))


@dataclasses.dataclass(frozen=True, eq=False)
class Compensation:
    """Motor positions that put the loaded robot's output frames at their targets
    (:meth:`Mechanism.compensate <h4pin.mechanism.Mechanism.compensate>`).

    Attributes:
        motors: (n_act,) the compensated motor positions (rad, m), in ``actuated`` order.
        rigid: (n_act,) the rigid robot's inverse: the motors that put the outputs there with no
            load.
        sag: (3 n,) the outputs' error from the targets at ``rigid`` under the loads (m): what
            the compensation removes.
        error: (3 n,) the outputs' error from the targets at ``motors`` under the loads (m).
        equilibrium: the loaded :class:`Equilibrium` at ``motors``.
    """

    motors: np.ndarray
    rigid: np.ndarray
    sag: np.ndarray
    error: np.ndarray
    equilibrium: Equilibrium


def _targets(model: pin.Model, targets: Any) -> tuple[list[int], np.ndarray]:
    """The output frames' ids and their target positions (3 n,), world, m."""
    if not isinstance(targets, Mapping) or not targets:
        raise ParameterError(f"targets: a mapping {{frame name: (3,) position, m}}, got {targets!r}")
    ids, out = [], []
    for frame, value in targets.items():
        if not isinstance(frame, str) or not model.existFrame(frame):
            raise ParameterError(f"targets: no frame {frame!r} in the model")
        try:
            v = np.asarray(value.translation if isinstance(value, pin.SE3) else value, dtype=float)
        except (TypeError, ValueError):
            v = np.zeros(0)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ParameterError(f"targets[{frame!r}]: a finite position (3,) in m, got {value!r}")
        ids.append(int(model.getFrameId(frame)))
        out.append(v)
    return ids, np.concatenate(out)


def _rigid_jacobian(mech: Any, q: np.ndarray, frames: list[int], held: Sequence[str]) -> np.ndarray:
    """(3 n, n_act): how the output frames' origins move with the motors in the rigid mechanism
    at q (the motors and ``held`` joints fixed but the motors' own motion, the loops closed)."""
    model, d = mech.model, mech.data
    pin.computeJointJacobians(model, d, q)
    pin.updateFramePlacements(model, d)
    rows = [assembly.closure_step(model, d, cm)[1] for cm in mech.constraint_models]
    rows += [c.residual_row(model, q)[1][None] for c in mech.couplings]
    a = np.vstack(rows) if rows else np.zeros((0, model.nv))
    motor = [model.joints[model.getJointId(n)].idx_v for n in mech.actuated]
    fixed = set(motor)
    for n in held:
        j = model.joints[model.getJointId(n)]
        fixed |= set(range(j.idx_v, j.idx_v + j.nv))
    passive = [i for i in range(model.nv) if i not in fixed]
    t = np.zeros((model.nv, len(motor)))
    t[motor, np.arange(len(motor))] = 1.0
    if a.shape[0] and passive:
        t[passive] = -np.linalg.lstsq(a[:, passive], a[:, motor], rcond=None)[0]
    jo = np.vstack([np.reshape(pin.getFrameJacobian(model, d, f, pin.LOCAL_WORLD_ALIGNED), (6, model.nv))[:3]
                    for f in frames])
    return jo @ t


def _outputs_at(mech: Any, q: np.ndarray, frames: list[int]) -> np.ndarray:
    d = mech.model.createData()
    pin.framesForwardKinematics(mech.model, d, q)
    return np.concatenate([d.oMf[f].translation for f in frames])


def compensate(mech: Any, targets: Any, springs: Mapping[Any, Any], loads: Any, gravity: bool, payload: Any,
               locked: Iterable[Any], start: Any, tol: float, iterations: int) -> Compensation:
    """:meth:`Mechanism.compensate`: Gauss-Newton on the motors, each step's Jacobian the rigid
    mechanism's at the rest state (the loaded one differs from it by the sag's own derivative,
    so the iteration converges linearly, at a rate of the sag's relative change)."""
    frames, want = _targets(mech.model, targets)
    rest = mech.assemble() if start is None else mech.configuration(start)
    motor = [mech.model.joints[mech.model.getJointId(n)].idx_q for n in mech.actuated]
    held = tuple(mech.beam_springs)

    def solve_for(loaded: bool, m: np.ndarray, rest: np.ndarray) -> tuple[np.ndarray, np.ndarray, Any]:
        eq, err = None, np.array([np.inf])
        for _ in range(iterations):
            try:
                rest = mech.assemble(rest, motors=m)
            except ImplausibleValueError:  # the motors sent beyond ten turns: the targets are out of reach
                break
            if loaded:
                eq, _ = solve(problem(mech, rest, springs, loads, gravity, payload, locked))
                err = _outputs_at(mech, eq.q, frames) - want
            else:
                err = _outputs_at(mech, rest, frames) - want
            if np.max(np.abs(err)) <= tol:
                return m, rest, eq
            step = np.linalg.lstsq(_rigid_jacobian(mech, rest, frames, held), err, rcond=None)[0]
            if not np.all(np.isfinite(step)):
                break
            m = m - step
        raise ConvergenceError(f"{mech.name}: the outputs do not reach their targets within {tol:g} m in "
                               f"{iterations} steps (last error {np.max(np.abs(err)):.3e} m); start nearer "
                               "(start=...), or check that the targets are reachable")

    m0 = np.asarray(rest[motor], dtype=float)
    rigid, rest_rigid, _ = solve_for(False, m0, rest)
    eq_rigid, _ = solve(problem(mech, rest_rigid, springs, loads, gravity, payload, locked))
    sag = _outputs_at(mech, eq_rigid.q, frames) - want
    motors, _, eq = solve_for(True, rigid.copy(), rest_rigid)
    error = _outputs_at(mech, eq.q, frames) - want
    for a in (motors, rigid, sag, error):
        a.setflags(write=False)
    return Compensation(motors, rigid, sag, error, eq)


class UnderLoad:
    """What a :class:`~h4pin.mechanism.Mechanism` does under finite loads: its equilibrium, its
    critical load, and the motors that compensate its sag (the module's functions, as methods)."""

    def equilibrium(self, q: Any, springs: Mapping[Any, Any], loads: Mapping[str, Any] | None = None, *,
                    gravity: bool = False, payload: tuple[str, Any] | None = None, locked: Iterable[Any] = (),
                    free_root: bool = False) -> Any:
        """The non-linear static equilibrium under finite loads (:mod:`h4pin.mechanism.loaded`),
        from the assembled rest state ``q`` (nq,) where every spring is at rest (a file's
        ``springref``: :attr:`spring_rest`), or one per row of a batch Q (N, nq): ``loads``
        ``{frame: (6,) [force; torque]}`` at the frame's origin, world axes (N, N.m; a (3,) force);
        ``gravity``: the model's gravity on every body; ``payload``: ``(frame, Payload)``, its
        weight; ``springs``, ``locked``, ``free_root`` as :meth:`compliance` (motors without a
        spring are held). Returns an :class:`~h4pin.mechanism.loaded.Equilibrium` (a list of them
        for a batch): ``.q``, ``.load_factor``, ``.stable``, ``.displacement(frame)``,
        ``.torques``, ``.closure_forces``, ``.compliance(outputs)`` (the tangent compliance).

        Raises:
            ParameterError: a bad load, frame, spring or q. UnassembledError: q is not assembled.
            UnrestrainedMotionError: the rest state is not restrained. LimitLoadError: the load
            cannot be carried (a limit point: snap-through), naming the factor reached.
        """
        Q, one = configurations(self, q)
        if not one:
            limits.check_size(f"{self.name}: {len(Q):,} loaded equilibria", len(Q) * 64.0 * self.model.nv ** 2,
                              len(Q) * 2e-4 * self.model.nv ** 2)
        out = [solve(problem(self, x, springs, loads, gravity, payload, locked, free_root))[0]
               for x in Q]
        return out[0] if one else out

    def critical_load(self, q: Any, springs: Mapping[Any, Any], loads: Mapping[str, Any] | None = None, *,
                      gravity: bool = False, payload: tuple[str, Any] | None = None, locked: Iterable[Any] = (),
                      max_factor: float = 100.0) -> Any:
        """The factor λ at which the tangent stiffness along the proportional load path ``λ
        loads`` (arguments as :meth:`equilibrium`) first becomes singular: a bifurcation (a
        buckling mode) or a limit point (snap-through), up to ``max_factor``; a
        :class:`~h4pin.mechanism.loaded.CriticalLoad` (``factor``, ``kind``, ``mode``)."""
        if isinstance(max_factor, bool) or not isinstance(max_factor, (int, float)) or not 0 < max_factor < 1e12:
            raise ParameterError(f"max_factor: a load factor > 0, got {max_factor!r}")
        return critical(problem(self, q, springs, loads, gravity, payload, locked), float(max_factor))

    def compensate(self, targets: Mapping[str, Any], springs: Mapping[Any, Any],
                   loads: Mapping[str, Any] | None = None, *, gravity: bool = False,
                   payload: tuple[str, Any] | None = None, locked: Iterable[Any] = (), start: Any = None,
                   tol: float = 1e-9, iterations: int = 50) -> Any:
        """The motor positions at which the loaded robot (:meth:`equilibrium`'s arguments) puts
        the output frames' origins at ``targets`` ``{frame: (3,) position}`` (m, world): the
        rigid inverse is not enough, its tool sags. ``start``: an assembled configuration near the
        targets (default :meth:`assemble`). A :class:`~h4pin.mechanism.loaded.Compensation`
        (``motors``, ``rigid``, ``sag``, ``error``, ``equilibrium``).

        Raises:
            as :meth:`equilibrium`; ConvergenceError: the targets are not reached within ``tol``.
        """
        return compensate(self, targets, springs, loads, gravity, payload, locked, start, tol, iterations)


__all__ = ["Compensation", "CriticalLoad", "Equilibrium", "LimitLoadError", "Loads", "Problem", "UnderLoad", "ancestry",
           "closed_form_joint", "compensate", "critical", "problem", "solve", "subtree", "warm"]
