# SPDX-License-Identifier: Apache-2.0
"""The Jacobian of a calibration's predicted markers (:class:`Sensitivity`, the base of
:class:`h4pin.mechanism.calibration.Model`): implicit differentiation of the loaded equilibrium.

A rigid parameter (base, markers, offsets, geometry) moves the markers directly and, in a closed
loop, through the passive joints that keep the loops closed (projected on the closures); a joint
placement's change moves the joint's subtree rigidly (:meth:`Sensitivity._closed_columns`; central
differences of the placement for a joint without a closed form); an elastic one (springs, lateral hinges,
beams) and a mass through the equilibrium: ``dq = -N Hr⁻¹ Nᵀ ∂(R + Aᵀμ)/∂p`` with the
equilibrium's tangent stiffness (:class:`Implicit`), a mass's generalised force in closed form.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

#: Central-difference step of the rigid parameters' partial derivatives (m, rad).
STEP = 1e-7
#: The placements' partial derivatives in closed form where the model allows
#: (:meth:`Sensitivity._closed_columns`); False: central differences throughout.
CLOSED = True


class Sensitivity:
    """The Jacobian of :meth:`predict` (a mixin of the calibration's model: it reads ``params``,
    ``meas``, ``frames``, ``commanded``, ``base0`` and ``robot``)."""

    params: list[Any]  # the calibration's Parameter list
    meas: Any
    frames: list[int]
    commanded: tuple[str, ...]
    base0: pin.SE3
    robot: Any  # (x) -> Robot, the model's

    def _perturbed(self, rob: Any, p: Any, h: float, local: int) -> pin.Model:
        """The robot's model with a geometry parameter's joint placement moved along its local
        twist axis ``local`` by h (``M exp6(h e)``), at fixed configuration."""
        model = pin.Model(rob.mech.model)
        j = int(model.getJointId(p.target))
        d = np.zeros(6)
        d[local] = h
        model.jointPlacements[j] = model.jointPlacements[j] * pin.exp6(pin.Motion(d[:3], d[3:]))
        return model

    def _terms(self, rob: Any, model: pin.Model, q: np.ndarray, eq: Any) -> tuple[np.ndarray, ...]:
        """``(markers (m, 3) world, c, R + Aᵀμ (nv,) or None)`` of ``model`` at the fixed q: what
        a geometry or mass parameter moves at fixed configuration (μ the equilibrium's, its rows
        scaled as the equilibrium's problem scales them)."""
        from h4pin.mechanism import assembly

        d = model.createData()
        pin.computeJointJacobians(model, d, q)
        pin.updateFramePlacements(model, d)
        world = self._markers(rob, d)
        c, a = assembly.closure_rows(rob.mech, model, d, q, 1.0 if eq is None else eq.problem.length)
        if eq is None:
            return world, c, None
        p = eq.problem
        force = eq.torques.copy()
        for joint, place, w in p.loads.points:
            force -= eq.load_factor * np.reshape(pin.getFrameJacobian(model, d, joint, place, pin.LOCAL_WORLD_ALIGNED),
                                                 (6, model.nv)).T @ w
        if p.loads.gravity:
            force += eq.load_factor * pin.computeGeneralizedGravity(model, d, q)
        return world, c, force + a.T @ eq.mu

    def _markers(self, rob: Any, d: pin.Data) -> np.ndarray:
        """(m, 3) the markers in the world (frame placements computed in d)."""
        return np.array([d.oMf[f].act(rob.markers[n]) for f, n in zip(self.frames, self.meas.markers, strict=True)])

    def _closed_columns(self, rob: Any, target: str, q: np.ndarray, eq: Any,
                        d: pin.Data) -> list[tuple[Any, ...]] | None:
        """:meth:`_terms`' derivatives ``(dx (m, 3), dc, dF or None)`` along the six local twists
        of ``target``'s placement, in closed form: the placement's change moves the joint's subtree
        rigidly by the world twist ``V = Ad(oM_parent M) e``, so a marker or closure frame below
        moves by ``v + ω × x`` and the forces change as :meth:`Problem.moved_subtree
        <h4pin.mechanism.loaded.Problem.moved_subtree>` says; None where that has no closed form
        (d: Pinocchio's joint Jacobians and frame placements at q)."""
        from h4pin.mechanism.loaded import subtree

        if eq is not None and getattr(eq.problem, "_ancestors", None) is None:
            return None
        model = rob.mech.model
        jp = int(model.getJointId(target))
        twists = (d.oMi[int(model.parents[jp])] * model.jointPlacements[jp]).toActionMatrix()  # (6, 6)
        below, _ = subtree(model, jp)

        def moved(x: np.ndarray) -> np.ndarray:  # (3, 6): a point x's velocity under each twist
            return twists[:3] - pin.skew(x) @ twists[3:]

        dx = np.zeros((6, len(self.frames), 3))
        for k, (f, name) in enumerate(zip(self.frames, self.meas.markers, strict=True)):
            if below[int(model.frames[f].parentJoint)]:
                dx[:, k] = moved(d.oMf[f].act(rob.markers[name])).T
        length = 1.0 if eq is None else eq.problem.length
        rows = [np.zeros((0, 6))]
        for cm in rob.mech.constraint_models:
            o1 = d.oMi[cm.joint1_id] * cm.joint1_placement
            o2 = d.oMi[cm.joint2_id] * cm.joint2_placement
            b1, b2 = float(below[cm.joint1_id]), float(below[cm.joint2_id])
            if cm.type == pin.ContactType.CONTACT_3D:
                rows.append((b2 * moved(o2.translation) - b1 * moved(o1.translation)) / length)
            else:
                r = pin.Jlog6(o1.inverse() * o2) @ o2.inverse().toActionMatrix() @ ((b2 - b1) * twists)
                r[:3] /= length
                rows.append(r)
        rows += [np.zeros((1, 6))] * len(rob.mech.couplings)
        dc = np.vstack(rows)
        df = None if eq is None else eq.problem.moved_subtree(q, eq.load_factor, eq.mu, jp, twists)
        return [(dx[a], dc[:, a], None if df is None else df[:, a]) for a in range(6)]

    def _point_jacobian(self, rob: Any, d: pin.Data, f: int, marker: str) -> np.ndarray:
        """(3, nv) the LOCAL_WORLD_ALIGNED Jacobian of a marker's point (Jacobians computed in d)."""
        model = rob.mech.model
        frame = model.frames[f]
        jac = pin.getFrameJacobian(model, d, int(frame.parentJoint),
                                   frame.placement * pin.SE3(np.eye(3), rob.markers[marker]), pin.LOCAL_WORLD_ALIGNED)
        return np.reshape(jac, (6, model.nv))[:3]

    def _mass_partials(self, rob: Any, q: np.ndarray, eq: Any) -> dict[int, tuple[np.ndarray, ...]]:
        """The mass parameters' ``(0, 0, dF)`` at q: a body's weight at its centre c (joint frame)
        loads the joint by ``-Jᵀ [m g; m (R c) x g]`` (J its LOCAL_WORLD_ALIGNED joint Jacobian),
        linear in m and in m c: the markers and the closures do not move."""
        model = rob.mech.model
        m = len(self.meas.markers)
        if eq is None:  # no load: a mass moves nothing
            return {k: (np.zeros((m, 3)), None, None) for k, p in enumerate(self.params) if p.group == "masses"}
        d = model.createData()
        pin.computeJointJacobians(model, d, q)
        g = np.array(model.gravity.linear)
        zero_c = np.zeros(len(eq.mu))
        out: dict[int, tuple[np.ndarray, ...]] = {}
        jacobians: dict[int, np.ndarray] = {}
        for k, p in enumerate(self.params):
            if p.group != "masses":
                continue
            if not eq.problem.loads.gravity:
                out[k] = (np.zeros((m, 3)), zero_c, np.zeros(model.nv))
                continue
            j = int(model.getJointId(p.target))
            if j not in jacobians:
                jacobians[j] = np.reshape(pin.getJointJacobian(model, d, j, pin.LOCAL_WORLD_ALIGNED), (6, model.nv))
            jac, rot, inertia = jacobians[j], d.oMi[j].rotation, model.inertias[j]
            if p.index == 0:  # the log of the mass: m times the unit mass's
                wrench = float(inertia.mass) * np.r_[g, np.cross(rot @ np.array(inertia.lever), g)]
            else:
                wrench = np.r_[np.zeros(3), float(inertia.mass) * np.cross(rot[:, p.index - 1], g)]
            out[k] = (np.zeros((m, 3)), zero_c, -eq.load_factor * jac.T @ wrench)
        return out

    def _partials(self, rob: Any, x: np.ndarray, q: np.ndarray, eq: Any,
                  masses: bool = True) -> dict[int, tuple[np.ndarray, ...]]:
        """Each geometry and mass parameter's partial derivatives at the fixed q: ``(dx (m, 3),
        dc, dF)``; a geometry parameter's along the local twists (:meth:`_closed_columns`, else
        central differences), mapped to ``(t, r)``; a mass parameter's in closed form
        (:meth:`_mass_partials`; none with ``masses=False``)."""
        out: dict[int, tuple[np.ndarray, ...]] = {}
        done: dict[str, list[tuple[np.ndarray, ...]]] = {}
        if masses and any(p.group == "masses" for p in self.params):
            out.update(self._mass_partials(rob, q, eq))
        d = None
        if CLOSED and any(p.group == "geometry" for p in self.params):
            d = rob.mech.model.createData()
            pin.computeJointJacobians(rob.mech.model, d, q)
            pin.updateFramePlacements(rob.mech.model, d)
        for k, p in enumerate(self.params):
            if p.group == "geometry":
                if p.target not in done:  # the six local directions of this joint, once
                    cols = self._closed_columns(rob, p.target, q, eq, d) if d is not None else None
                    if cols is None:
                        cols = []
                        for axis in range(6):
                            plus = self._terms(rob, self._perturbed(rob, p, STEP, axis), q, eq)
                            minus = self._terms(rob, self._perturbed(rob, p, -STEP, axis), q, eq)
                            cols.append(tuple(None if a is None else (a - b) / (2 * STEP)
                                              for a, b in zip(plus, minus, strict=True)))
                    delta = np.array([x[i] for i, q_ in enumerate(self.params)
                                      if q_.group == "geometry" and q_.target == p.target])
                    jr = np.eye(6)  # the local twist of d(t, r): (Rᵀ dt, Jexp3(r) dr)
                    if len(delta) == 6:
                        jr[:3, :3] = pin.exp3(delta[3:]).T
                        jr[3:, 3:] = pin.Jexp3(delta[3:])
                    done[p.target] = [tuple(None if cols[0][t] is None else
                                            sum(jr[a, b] * cols[a][t] for a in range(6)) for t in range(3))
                                      for b in range(6)]
                out[k] = done[p.target][p.index]
        return out

    def jacobian(self, x: np.ndarray, states: Sequence[Any]) -> np.ndarray:
        """(N, m, 3, P) the markers' derivatives in the parameters at x (module docstring): the
        rest state's and the equilibrium's implicit differentiation, each term at the fixed
        configuration (:meth:`_partials`)."""
        rob = self.robot(x)
        model = rob.mech.model
        n, m, npar = len(states), len(self.frames), len(self.params)
        out = np.zeros((n, m, 3, npar))
        held = set()
        for name in (*self.commanded, *rob.mech.beam_springs):  # what the assembly holds (not the locked joints)
            jm = model.joints[model.getJointId(name)]
            held |= set(range(jm.idx_v, jm.idx_v + jm.nv))
        passive = np.array([k for k in range(model.nv) if k not in held], dtype=int)
        delta = np.array([x[k] for k, p in enumerate(self.params) if p.group == "base"])
        motion = pin.Motion(delta[:3], delta[3:]) if len(delta) == 6 else pin.Motion.Zero()
        tb = pin.exp6(motion)
        jr_base = pin.Jexp6(motion)
        for i, (rest, eq) in enumerate(states):
            q = rest if eq is None else eq.q
            d = model.createData()
            pin.computeJointJacobians(model, d, q)
            pin.updateFramePlacements(model, d)
            jx = np.stack([self._point_jacobian(rob, d, f, mk) for f, mk in zip(self.frames, self.meas.markers,
                                                                                  strict=True)])  # (m, 3, nv)
            pre = (self.base0.act(w) for w in self._markers(rob, d))  # the markers before the base's correction
            base_cols = np.array([tb.rotation @ np.c_[np.eye(3), -pin.skew(z)] @ jr_base for z in pre])  # (m, 3, 6)
            partials = self._partials(rob, x, q, eq)
            at_rest = partials if eq is None or not len(rob.mech.constraint_models) else \
                self._partials(rob, x, rest, None, masses=False)
            _, a_rest = self._closures(rob, model, rest)
            pinv = np.linalg.pinv(a_rest[:, passive]) if a_rest.shape[0] and passive.size else None
            solve = Implicit(eq) if eq is not None else None
            for k, p in enumerate(self.params):
                if p.group == "base":
                    out[i, :, :, k] = base_cols[:, :, p.index]
                    continue
                if p.group == "markers":
                    mk = self.meas.markers.index(p.target)
                    out[i, mk, :, k] = rb_col(rob, d.oMf[self.frames[mk]].rotation[:, p.index])
                    continue
                dx = np.zeros((m, 3))
                dq_rest = np.zeros(model.nv)
                if p.group == "offsets":
                    dq_rest[model.joints[model.getJointId(p.target)].idx_v] = 1.0
                if p.group in ("offsets", "geometry") and pinv is not None:
                    dc = a_rest @ dq_rest + (at_rest[k][1] if p.group == "geometry" else 0.0)
                    dq_rest[passive] -= pinv @ dc
                if p.group in ("geometry", "masses"):
                    dx = partials[k][0]
                if solve is None:
                    dq = dq_rest
                else:
                    df = partials[k][2] if k in partials else self._force_derivative(rob, p, eq)
                    dq = solve(dq_rest, df, partials[k][1] if p.group == "geometry" else None)
                out[i, :, :, k] = (dx + jx @ dq) @ rob.base.rotation.T
        return out

    def _closures(self, rob: Any, model: pin.Model, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(c, A)``: the closures' and couplings' residuals and Jacobian at q (world, m and rad)."""
        from h4pin.mechanism import assembly

        d = model.createData()
        pin.computeJointJacobians(model, d, q)
        return assembly.closure_rows(rob.mech, model, d, q)

    def _force_derivative(self, rob: Any, p: Any, eq: Any) -> np.ndarray:
        """``∂(R + Aᵀμ)/∂p`` (nv,) at the equilibrium of a spring's (log) stiffness or a beam's
        scale: the spring's own torque."""
        model = rob.mech.model
        out = np.zeros(model.nv)
        names = [p.target] if p.group == "springs" else [f"{p.target}_lateral_{'ab'[p.index]}"] \
            if p.group == "lateral" else [n for n in rob.mech.beam_springs if n.startswith(f"{p.target}_beam_")]
        for name in names:
            idx = model.joints[model.getJointId(name)].idx_v
            out[idx] = eq.torques[idx]
        return out


def rb_col(rob: Any, column: np.ndarray) -> np.ndarray:
    """A world direction in the tracker's frame."""
    return rob.base.rotation @ column


class Implicit:
    """The equilibrium's sensitivity: for a parameter that moves the rest state by ``dq_rest``,
    the forces at the fixed configuration by ``dF`` and the constraints by ``dc`` (scaled rows),
    the equilibrium's ``dq`` from ``H dq + Aᵀ dμ = -(dF - K dq_rest)``, ``A dq = -dc`` on the free
    coordinates, the held ones moving with the rest state."""

    def __init__(self, eq: Any):
        p = eq.problem
        self.p, self.eq = p, eq
        n, _, h = p.reduced(eq.q, eq.load_factor, eq.mu)
        self.n, self.h = n, h
        self.hr = n.T @ h @ n
        _, a = p.constraints(eq.q)
        self.a = a
        self.free = np.flatnonzero(p.free)
        self.held = np.flatnonzero(~p.free)
        af = a[:, self.free] * p.col[self.free][None, :]
        self.pinv = np.linalg.pinv(af) if af.shape[0] else None
        self.rest_k = p.k.copy()  # the springs whose rest is the rest state (a file's springref stays)
        for name in getattr(p.mech, "spring_rest", {}):
            j = p.model.joints[p.model.getJointId(name)]
            self.rest_k[j.idx_v:j.idx_v + j.nv] = 0.0

    def __call__(self, dq_rest: np.ndarray, df: np.ndarray, dc: np.ndarray | None) -> np.ndarray:
        p = self.p
        dq = np.zeros(p.model.nv)
        dq[self.held] = dq_rest[self.held]
        b1 = -(df - self.rest_k * dq_rest) - self.h @ dq  # the springs' rest moves with the rest state
        b2 = -(np.zeros(len(self.a)) if dc is None else dc) - self.a @ dq
        if self.pinv is not None:
            dq[self.free] += (self.pinv @ b2) * p.col[self.free]
        if self.hr.size:
            z = np.linalg.solve(self.hr, self.n.T @ (b1 - self.h @ (dq - np.where(p.free, 0.0, dq))))
            dq = dq + self.n @ z
        return dq
