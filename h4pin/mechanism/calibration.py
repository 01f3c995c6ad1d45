# SPDX-License-Identifier: Apache-2.0
"""Elastic and geometric calibration of any mechanism from measured tool positions:
:func:`calibrate` (``h4pin.calibrate``), and what the data can and cannot identify.

**The model of a measurement.** Sample i commands a configuration (a tree) or motor positions (a
closed loop), plus each joint's zero offset; the rigid robot, with its joint placements corrected,
takes the rest configuration (a closed loop: the loops closed with the motors held); under its
weight and the sample's known loads it settles in the loaded equilibrium
(:mod:`h4pin.mechanism.loaded`: the joint springs, the lateral hinges and beams, the masses); the
markers, each a frame plus an offset, are seen in the tracker's frame, the robot's world placed by
the base pose. The parameters, SI, named ``group/target[/axis]``:

* ``base/tx`` ... ``base/rz``: the world's pose in the tracker's frame (``exp6`` of the six
  around the given start);
* ``markers/<frame>/x`` ...: each marker's offset from its frame, in the frame's axes;
* ``offsets/<joint>``: a commanded coordinate's zero offset (the motors' of a closed loop);
* ``geometry/<joint>/tx`` ... ``/rz``: the joint's placement in its parent, ``M exp6(δ)``;
* ``springs/<joint>``: a joint spring's stiffness (N.m/rad, N/m), fitted in ``log``;
* ``lateral/<joint>/a``, ``/b``: two elastic hinges about the axes perpendicular to the joint's
  (the bearing's tilt and the link's bending, inserted where asked), fitted in ``log``;
* ``beams/<link>``: a flexible link's stiffness scale (all its virtual joints), in ``log``;
* ``masses/<joint>/m``, ``/cx``, ``/cy``, ``/cz``: the mass a joint carries and its centre (its
  frame), what gravity makes identifiable.

**The fit.** Levenberg-Marquardt (trust region, SciPy's ``least_squares`` through
:mod:`h4pin.mechanism.fitting`, a robust ``loss`` as SciPy's) of the residuals ``(predicted -
measured) / noise`` and the prior's ``(p - nominal) / sigma``; the Jacobian by implicit
differentiation at each equilibrium: a rigid parameter moves the markers directly and through the
passive joints that keep the loops closed (central differences of the placements at the fixed
configuration, projected on the closures), an elastic one through ``dq = -N Hr⁻¹ Nᵀ ∂R/∂p`` with
the equilibrium's tangent stiffness (the sag's second-order change with the geometry left out: it
slows the convergence a little, never moves the solution).

**Identifiability.** The SVD of the Jacobian in prior units names the combinations the data do not
inform (a singular value below :data:`IDENTIFIABLE_TOL` of the largest, or a standard deviation
from the data alone above :data:`HELD_STD` prior sigmas): they are held at the prior (the fit moves
in the others only) and listed in :attr:`Calibration.unidentifiable`, never left to drift. The
covariance is ``(Jᵀ J + I)⁻¹`` in prior units on the identified combinations, the prior's on the
held ones (the noise estimated from the residuals unless given).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import H4Error, ParameterError
from h4pin.mechanism import fitting, loaded
from h4pin.mechanism.engine import Insertion, VirtualJoint
from h4pin.mechanism.measurements import Measurements

#: The parameter groups, in the order a stage table usually adds them.
GROUPS = ("base", "markers", "offsets", "geometry", "springs", "lateral", "beams", "masses")
#: The prior's default sigma of each group (SI; a factor for the log-fitted groups).
SIGMA = {"base": (0.1, 0.1), "markers": 0.01, "offsets": (0.05, 0.005), "geometry": (0.005, 0.01),
         "springs": math.log(10.0), "lateral": math.log(100.0), "beams": math.log(10.0), "masses": (0.5, 0.05)}
#: A lateral hinge's nominal stiffness: this times its joint's spring (or LATERAL_STIFFNESS).
LATERAL_FACTOR, LATERAL_STIFFNESS = 10.0, 1e4
#: Central-difference step of the rigid parameters' partial derivatives (m, rad).
STEP = 1e-7
#: Relative singular value under which a combination is not identified; and the standard deviation
#: (in prior sigmas) the data alone leave a combination above which it is held at the prior: the
#: data tell it less than a hundredth of what the prior does.
IDENTIFIABLE_TOL, HELD_STD = 1e-6, 10.0
#: The fit's relative tolerance (SciPy's ftol, xtol, gtol): a cost a few hundred noise-scaled
#: squares stops changing below a thousandth of one (a fraction of its statistical spread, ~1).
TOL = 1e-6
_AXES = ("tx", "ty", "tz", "rx", "ry", "rz")


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One calibrated quantity: its name, group, target (joint, frame, link), component, nominal
    value and prior sigma (in the fitted variable: the value, or its log for ``log`` ones)."""

    name: str
    group: str
    target: str
    index: int
    nominal: float
    sigma: float
    log: bool = False

    def value(self, x: float) -> float:
        """The SI value of the fitted variable x."""
        return float(math.exp(x)) if self.log else float(x)


def _joint_of(model: pin.Model, name: str, what: str) -> int:
    if not isinstance(name, str) or not model.existJointName(name):
        raise ParameterError(f"parameters: {what}: no joint {name!r} in the model")
    return int(model.getJointId(name))


def _targets(spec: Any, default: Sequence[str], what: str) -> list[str]:
    if spec is None or spec is True:
        return list(default)
    if isinstance(spec, str):
        return [spec]
    return list(spec)


def parameters(mech: Any, groups: Any, springs: Mapping[str, float], markers: Sequence[str],
               commanded: Sequence[str]) -> list[Parameter]:
    """The :class:`Parameter` list of ``groups``: names (each a whole group) or ``{group: targets}``
    (the targets of a group: joints, markers, links); ``springs`` the nominal springs (names),
    ``commanded`` the joints whose coordinate a sample commands (their offsets)."""
    model = mech.model
    spec = {g: None for g in groups} if not isinstance(groups, Mapping) else dict(groups)
    unknown = [g for g in spec if g not in GROUPS]
    if unknown:
        raise ParameterError(f"parameters: unknown group {unknown[0]!r} (groups: {', '.join(GROUPS)})")
    out: list[Parameter] = []
    movable = [model.names[j] for j in range(1, model.njoints) if model.joints[j].nq == 1]
    for group, targets in spec.items():
        if group == "base":
            out += [Parameter(f"base/{a}", "base", "base", k, 0.0, SIGMA["base"][k // 3]) for k, a in enumerate(_AXES)]
        elif group == "markers":
            for f in _targets(targets, markers, group):
                if f not in markers:
                    raise ParameterError(f"parameters: markers: {f!r} is not a measured marker ({', '.join(markers)})")
                out += [Parameter(f"markers/{f}/{a}", group, f, k, 0.0, SIGMA["markers"]) for k, a in enumerate("xyz")]
        elif group == "offsets":
            for j in _targets(targets, commanded, group):
                jm = model.joints[_joint_of(model, j, group)]
                if j not in commanded or jm.nq != 1:
                    raise ParameterError(f"parameters: offsets: {j!r} is not a commanded one-coordinate joint")
                prismatic = "Prismatic" in jm.shortname() or jm.shortname().startswith("JointModelP")
                out.append(Parameter(f"offsets/{j}", group, j, 0, 0.0, SIGMA["offsets"][int(prismatic)]))
        elif group == "geometry":
            for j in _targets(targets, movable, group):
                _joint_of(model, j, group)
                out += [Parameter(f"geometry/{j}/{a}", group, j, k, 0.0, SIGMA["geometry"][k // 3])
                        for k, a in enumerate(_AXES)]
        elif group == "springs":
            for j in _targets(targets, [n for n in springs if n not in mech.beam_springs], group):
                if j not in springs:
                    raise ParameterError(f"parameters: springs: joint {j!r} has no spring to calibrate")
                out.append(Parameter(f"springs/{j}", group, j, 0, math.log(springs[j]), SIGMA["springs"], True))
        elif group == "lateral":
            for j in _targets(targets, movable, group):
                nominal = LATERAL_FACTOR * springs[j] if j in springs else LATERAL_STIFFNESS
                _joint_of(model, j, group)
                out += [Parameter(f"lateral/{j}/{a}", group, j, k, math.log(nominal), SIGMA["lateral"], True)
                        for k, a in enumerate("ab")]
        elif group == "beams":
            links = sorted({n.split("_beam_")[0] for n in mech.beam_springs if "_beam_" in n})
            for link in _targets(targets, links, group):
                if link not in links:
                    raise ParameterError(f"parameters: beams: {link!r} is not a beam ({', '.join(links) or 'none'})")
                out.append(Parameter(f"beams/{link}", group, link, 0, 0.0, SIGMA["beams"], True))
        else:  # masses
            heavy = [model.names[j] for j in range(1, model.njoints) if model.inertias[j].mass > 0]
            for j in _targets(targets, heavy, group):
                jid = _joint_of(model, j, group)
                inertia = model.inertias[jid]
                out.append(Parameter(f"masses/{j}/m", group, j, 0, float(inertia.mass),
                                     SIGMA["masses"][0] * max(float(inertia.mass), 1e-3)))
                out += [Parameter(f"masses/{j}/c{a}", group, j, k + 1, float(inertia.lever[k]), SIGMA["masses"][1])
                        for k, a in enumerate("xyz")]
    names = [p.name for p in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ParameterError(f"parameters: {twice[0]!r} is asked twice")
    if not out:
        raise ParameterError("parameters: give at least one group (groups: " + ", ".join(GROUPS) + ")")
    return out


def with_lateral(mech: Any, joints: Iterable[str], springs: Mapping[str, float]) -> Any:
    """``mech`` with two elastic hinges before each joint of ``joints``, about the two axes
    perpendicular to the joint's at its origin (names ``<joint>_lateral_a``, ``_b``), their nominal
    stiffness :data:`LATERAL_FACTOR` times the joint's spring."""
    from h4pin.mechanism.core import inserted

    model = mech.model
    d = model.createData()
    pin.framesForwardKinematics(model, d, mech.reference)
    ins = []
    for name in dict.fromkeys(joints):
        j = _joint_of(model, name, "lateral")
        jm = model.joints[j]
        if jm.nv != 1:
            raise ParameterError(f"parameters: lateral: joint {name!r} has {jm.nv} coordinates (one-coordinate only)")
        motion = _axis_of(model, d, j)
        axis = motion / np.linalg.norm(motion)
        a = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(axis, a)
        k = LATERAL_FACTOR * springs[name] if name in springs else LATERAL_STIFFNESS
        point = d.oMi[j].translation
        parent = model.names[model.parents[j]] if model.parents[j] else "universe"
        ins.append(Insertion(parent, (VirtualJoint(f"{name}_lateral_a", "revolute", a, point, k),
                                      VirtualJoint(f"{name}_lateral_b", "revolute", b, point, k)), children=(name,)))
    return inserted(mech, ins, f"{mech.name} with lateral hinges")


def _axis_of(model: pin.Model, d: pin.Data, j: int) -> np.ndarray:
    """The world direction of one-coordinate joint j's motion (its axis), at the placement in d."""
    jm = model.joints[j]
    data = model.createData()
    q = pin.neutral(model)
    pin.computeJointJacobians(model, data, q)
    col = np.reshape(pin.getJointJacobian(model, data, j, pin.LOCAL), (6, model.nv))[:, jm.idx_v]
    local = col[3:] if np.linalg.norm(col[3:]) > 0 else col[:3]
    return d.oMi[j].rotation @ local



@dataclasses.dataclass(frozen=True, eq=False)
class Robot:
    """The robot one parameter vector describes: its mechanism (placements and masses set), its
    springs, its base pose (tracker <- world) and marker offsets, and each commanded coordinate's
    offset (nq,)."""

    mech: Any
    springs: dict[str, float]
    base: pin.SE3
    markers: dict[str, np.ndarray]
    offsets: np.ndarray


class Model:
    """The forward model of a calibration (module docstring): the mechanism (lateral hinges
    inserted where asked), the measurements' commands and loads, the parameters; predicts the
    markers of a parameter vector and their Jacobian."""

    def __init__(self, mech: Any, meas: Measurements, params: Sequence[Parameter], springs: Mapping[str, float],
                 gravity: bool, locked: Sequence[str], base: pin.SE3):
        self.mech, self.meas, self.params = mech, meas, list(params)
        self.springs, self.gravity, self.locked, self.base0 = dict(springs), bool(gravity), tuple(locked), base
        model = mech.model
        self.frames = []
        for f in meas.markers:
            if not model.existFrame(f):
                raise ParameterError(f"measurements: marker {f!r} is not a frame of {mech.name}")
            self.frames.append(int(model.getFrameId(f)))
        if meas.motors is not None:
            if meas.motors.shape[1] != len(mech.actuated):
                raise ParameterError(f"measurements: motors has {meas.motors.shape[1]} columns, the mechanism "
                                     f"{len(mech.actuated)} motors ({', '.join(mech.actuated)})")
            self.commanded = tuple(mech.actuated)
        else:
            nq = mech.configuration(meas.configurations[0]).shape[0]
            if nq != model.nq:
                raise ParameterError("measurements: a configuration of the mechanism (nq)")
            self.commanded = tuple(model.names[j] for j in range(1, model.njoints))
        for f in (meas.loads or {}):
            if not model.existFrame(f):
                raise ParameterError(f"measurements: load on {f!r}, not a frame of {mech.name}")
        self.x0 = np.array([p.nominal for p in self.params])
        self.sigma = np.array([p.sigma for p in self.params])
        self.rests: list[np.ndarray | None] = [None] * meas.n
        self.sags: list[tuple[np.ndarray, np.ndarray] | None] = [None] * meas.n

    # -------------------------------------------------------------- the robot of a vector
    def robot(self, x: np.ndarray) -> Robot:
        model = pin.Model(self.mech.model)
        springs = dict(self.springs)
        base = pin.SE3(self.base0)
        delta_base = np.zeros(6)
        markers = {f: np.zeros(3) for f in self.meas.markers}
        offsets = np.zeros(model.nq)
        geometry: dict[int, np.ndarray] = {}
        for p, v in zip(self.params, x, strict=True):
            g = p.group
            if g == "base":
                delta_base[p.index] = v
            elif g == "markers":
                markers[p.target][p.index] = v
            elif g == "offsets":
                offsets[model.joints[model.getJointId(p.target)].idx_q] = v
            elif g == "geometry":
                geometry.setdefault(int(model.getJointId(p.target)), np.zeros(6))[p.index] = v
            elif g == "springs":
                springs[p.target] = p.value(v)
            elif g == "lateral":
                springs[f"{p.target}_lateral_{'ab'[p.index]}"] = p.value(v)
            elif g == "beams":
                for n, k in self.mech.beam_springs.items():
                    if n.startswith(f"{p.target}_beam_"):
                        springs[n] = k * p.value(v)
            else:
                j = int(model.getJointId(p.target))
                inertia = model.inertias[j]
                mass, lever = float(inertia.mass), np.array(inertia.lever)
                if p.index == 0:
                    mass = max(float(v), 0.0)
                else:
                    lever[p.index - 1] = v
                model.inertias[j] = pin.Inertia(mass, lever, inertia.inertia)
        for j, d in geometry.items():
            model.jointPlacements[j] = model.jointPlacements[j] * pin.exp6(pin.Motion(d[:3], d[3:]))
        base = pin.exp6(pin.Motion(delta_base[:3], delta_base[3:])) * base
        return Robot(self.mech.with_model(model), springs, base, markers, offsets)

    # -------------------------------------------------------------- predictions
    def state(self, rob: Robot, i: int) -> tuple[np.ndarray, Any]:
        """The rest configuration and loaded equilibrium (or None, no load) of sample i."""
        mech, meas = rob.mech, self.meas
        if meas.motors is None:
            rest = mech.configuration(meas.configurations[i]) + rob.offsets
        else:
            idx = [mech.model.joints[mech.model.getJointId(n)].idx_q for n in mech.actuated]
            start = self.rests[i] if self.rests[i] is not None else (
                self.rests[i - 1] if i and self.rests[i - 1] is not None else mech.reference)
            rest = mech.assemble(start, motors=meas.motors[i] + rob.offsets[idx])
            self.rests[i] = rest
        loads = {f: w[i] for f, w in (meas.loads or {}).items()} or None
        if not self.gravity and loads is None:
            return rest, None
        p = loaded.problem(mech, rest, rob.springs, loads, self.gravity, None, self.locked)
        eq = None
        if self.sags[i] is not None:  # the previous parameters' equilibrium: Newton from there
            eq = loaded.warm(p, pin.integrate(mech.model, rest, self.sags[i][0]), self.sags[i][1])
        if eq is None:
            eq, _ = loaded.solve(p)
        self.sags[i] = (pin.difference(mech.model, rest, eq.q), eq.mu)
        return rest, eq

    def markers_at(self, rob: Robot, q: np.ndarray) -> np.ndarray:
        """(m, 3) the markers in the tracker's frame at configuration q."""
        model = rob.mech.model
        d = model.createData()
        pin.framesForwardKinematics(model, d, q)
        return np.array([rob.base.act(d.oMf[f].act(rob.markers[n]))
                         for f, n in zip(self.frames, self.meas.markers, strict=True)])

    def predict(self, x: np.ndarray, rows: Iterable[int] | None = None) -> tuple[np.ndarray, list[Any]]:
        """``(markers (N, m, 3), states)`` of the parameter vector x."""
        rob = self.robot(x)
        rows = range(self.meas.n) if rows is None else rows
        out, states = [], []
        for i in rows:
            rest, eq = self.state(rob, i)
            q = rest if eq is None else eq.q
            out.append(self.markers_at(rob, q))
            states.append((rest, eq))
        return np.array(out), states


    # -------------------------------------------------------------- the Jacobian
    def _perturbed(self, rob: Robot, p: Parameter, h: float, local: int | None = None) -> pin.Model:
        """The robot's model with a geometry parameter moved along its local axis ``local`` by h
        (``M exp6(δ) exp6(h e)``), or a mass parameter by h, at fixed configuration."""
        model = pin.Model(rob.mech.model)
        j = int(model.getJointId(p.target))
        if p.group == "geometry":
            d = np.zeros(6)
            d[p.index if local is None else local] = h
            model.jointPlacements[j] = model.jointPlacements[j] * pin.exp6(pin.Motion(d[:3], d[3:]))
        else:  # masses
            inertia = model.inertias[j]
            mass, lever = float(inertia.mass), np.array(inertia.lever)
            if p.index == 0:
                mass += h
            else:
                lever[p.index - 1] += h
            model.inertias[j] = pin.Inertia(mass, lever, inertia.inertia)
        return model

    def _terms(self, rob: Robot, model: pin.Model, q: np.ndarray, eq: Any) -> tuple[np.ndarray, ...]:
        """``(markers (m, 3) world, c, R + Aᵀμ (nv,) or None)`` of ``model`` at the fixed q: what
        a geometry or mass parameter moves at fixed configuration (μ the equilibrium's, its rows
        scaled as the equilibrium's problem scales them)."""
        from h4pin.mechanism import assembly

        d = model.createData()
        pin.computeJointJacobians(model, d, q)
        pin.updateFramePlacements(model, d)
        world = np.array([d.oMf[f].act(rob.markers[n]) for f, n in zip(self.frames, self.meas.markers, strict=True)])
        res, rows = [np.zeros(0)], [np.zeros((0, model.nv))]
        length = 1.0 if eq is None else eq.problem.length
        for cm in rob.mech.constraint_models:
            r, jac, _ = assembly.closure_step(model, d, cm)
            w = np.ones(len(r))
            w[:3] = 1.0 / length
            res.append(r * w)
            rows.append(jac * w[:, None])
        for c in rob.mech.couplings:
            r, row = c.residual_row(model, q)
            res.append(np.array([r]))
            rows.append(row[None])
        c, a = np.concatenate(res), np.vstack(rows)
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

    def _point_jacobian(self, rob: Robot, d: pin.Data, f: int, marker: str) -> np.ndarray:
        """(3, nv) the LOCAL_WORLD_ALIGNED Jacobian of a marker's point (Jacobians computed in d)."""
        model = rob.mech.model
        frame = model.frames[f]
        jac = pin.getFrameJacobian(model, d, int(frame.parentJoint),
                                   frame.placement * pin.SE3(np.eye(3), rob.markers[marker]), pin.LOCAL_WORLD_ALIGNED)
        return np.reshape(jac, (6, model.nv))[:3]

    def _mass_partials(self, rob: Robot, q: np.ndarray, eq: Any) -> dict[int, tuple[np.ndarray, ...]]:
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
            if p.index == 0:
                wrench = np.r_[g, np.cross(rot @ np.array(inertia.lever), g)]
            else:
                wrench = np.r_[np.zeros(3), float(inertia.mass) * np.cross(rot[:, p.index - 1], g)]
            out[k] = (np.zeros((m, 3)), zero_c, -eq.load_factor * jac.T @ wrench)
        return out

    def _partials(self, rob: Robot, x: np.ndarray, q: np.ndarray, eq: Any,
                  masses: bool = True) -> dict[int, tuple[np.ndarray, ...]]:
        """Each geometry and mass parameter's partial derivatives at the fixed q: ``(dx (m, 3),
        dc, dF)``; a geometry parameter's by central differences through exp6's right Jacobian, a
        mass parameter's in closed form (:meth:`_mass_partials`; none with ``masses=False``)."""
        out: dict[int, tuple[np.ndarray, ...]] = {}
        done: dict[str, list[tuple[np.ndarray, ...]]] = {}
        if masses and any(p.group == "masses" for p in self.params):
            out.update(self._mass_partials(rob, q, eq))
        for k, p in enumerate(self.params):
            if p.group == "geometry":
                if p.target not in done:  # the six local directions of this joint, once
                    cols = []
                    for axis in range(6):
                        plus = self._terms(rob, self._perturbed(rob, p, STEP, axis), q, eq)
                        minus = self._terms(rob, self._perturbed(rob, p, -STEP, axis), q, eq)
                        cols.append(tuple(None if a is None else (a - b) / (2 * STEP)
                                          for a, b in zip(plus, minus, strict=True)))
                    delta = np.array([x[i] for i, q_ in enumerate(self.params)
                                      if q_.group == "geometry" and q_.target == p.target])
                    jr = pin.Jexp6(pin.Motion(delta[:3], delta[3:])) if len(delta) == 6 else np.eye(6)
                    done[p.target] = [tuple(None if cols[0][t] is None else
                                            sum(jr[a, b] * cols[a][t] for a in range(6)) for t in range(3))
                                      for b in range(6)]
                out[k] = done[p.target][p.index]
        return out

    def jacobian(self, x: np.ndarray, states: Sequence[Any]) -> np.ndarray:
        """(N, m, 3, P) the markers' derivatives in the parameters at x (module docstring): the
        rest state's and the equilibrium's implicit differentiation, each term at the fixed
        configuration by central differences of Pinocchio's kinematics and forces."""
        rob = self.robot(x)
        model = rob.mech.model
        n, m, npar = len(states), len(self.frames), len(self.params)
        out = np.zeros((n, m, 3, npar))
        held = set()
        for name in (*self.commanded, *rob.mech.beam_springs, *self.locked):
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
            world = self._terms(rob, model, q, None)[0]
            pre = (self.base0.act(w) for w in world)  # the markers before the base's correction
            base_cols = np.array([tb.rotation @ np.c_[np.eye(3), -pin.skew(z)] @ jr_base for z in pre])  # (m, 3, 6)
            partials = self._partials(rob, x, q, eq)
            at_rest = partials if eq is None or not len(rob.mech.constraint_models) else \
                self._partials(rob, x, rest, None, masses=False)
            _, a_rest = self._closures(rob, model, rest)
            pinv = np.linalg.pinv(a_rest[:, passive]) if a_rest.shape[0] and passive.size else None
            solve = _Implicit(eq) if eq is not None else None
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

    def _closures(self, rob: Robot, model: pin.Model, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(c, A)``: the closures' and couplings' residuals and Jacobian at q (world, m and rad)."""
        from h4pin.mechanism import assembly

        d = model.createData()
        pin.computeJointJacobians(model, d, q)
        res, rows = [np.zeros(0)], [np.zeros((0, model.nv))]
        for cm in rob.mech.constraint_models:
            r, jac, _ = assembly.closure_step(model, d, cm)
            res.append(r)
            rows.append(jac)
        for c in rob.mech.couplings:
            r, row = c.residual_row(model, q)
            res.append(np.array([r]))
            rows.append(row[None])
        return np.concatenate(res), np.vstack(rows)

    def _force_derivative(self, rob: Robot, p: Parameter, eq: Any) -> np.ndarray:
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


def rb_col(rob: Robot, column: np.ndarray) -> np.ndarray:
    """A world direction in the tracker's frame."""
    return rob.base.rotation @ column


class _Implicit:
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


@dataclasses.dataclass(frozen=True, eq=False)
class Calibration:
    """A calibrated mechanism (:func:`calibrate`).

    Attributes:
        values, std: ``{name: value}`` (SI; a stiffness in N.m/rad or N/m) and its standard
            deviation, the prior's along the combinations the data do not inform (a parameter the
            data identify has a std well under its prior sigma).
        residuals: (N, m, 3) predicted minus measured markers at the solution (m; NaN where a
            marker was not seen), on the fitted samples; held: the same on the held-out samples
            (``holdout``; their indices ``held_rows``), or None.
        unidentifiable: the parameter combinations the data do not inform, held at the prior.
        noise: the measurement noise used (m): given, or estimated from the residuals.
        mechanism: the calibrated :class:`~h4pin.mechanism.Mechanism` (placements, masses, lateral
            hinges); springs: its springs; base: the world's pose in the tracker's frame;
            markers: each marker's offset; offsets: each commanded coordinate's zero offset.
    """

    values: dict[str, float]
    std: dict[str, float]
    residuals: np.ndarray
    unidentifiable: tuple[str, ...]
    noise: float
    model: Model = dataclasses.field(repr=False)
    x: np.ndarray = dataclasses.field(repr=False)
    cost: float = 0.0
    held: np.ndarray | None = dataclasses.field(default=None, repr=False)
    held_rows: np.ndarray | None = dataclasses.field(default=None, repr=False)

    @property
    def robot(self) -> Robot:
        return self.model.robot(self.x)

    @property
    def mechanism(self) -> Any:
        return self.robot.mech

    @property
    def springs(self) -> dict[str, float]:
        return self.robot.springs

    def summary(self, residuals: np.ndarray | None = None) -> str:
        """mean, std and max of the markers' errors (mm): of ``residuals`` (default the fit's)."""
        err = np.linalg.norm(self.residuals if residuals is None else residuals, axis=-1)
        err = err[np.isfinite(err)] * 1e3
        return (f"{err.size} marker readings: error mean {err.mean():.3f} mm, std {err.std():.3f} mm, "
                f"max {err.max():.3f} mm")

    def predict(self, configurations: Any = None, *, motors: Any = None, loads: Any = None) -> np.ndarray:
        """(N, m, 3) the markers in the tracker's frame, the elastic sag included, of commands
        (configurations of a tree, or motor positions of a closed loop) and their known loads."""
        if configurations is None and motors is None:
            raise ParameterError("predict: give configurations or motors")
        cmd = np.atleast_2d(np.asarray(configurations if motors is None else motors, float))
        fake = {f: np.zeros((len(cmd), 3)) for f in self.model.meas.markers}
        meas = Measurements(**({"motors": cmd} if motors is not None else {"configurations": cmd}), points=fake,
                            loads=loads)
        model = Model(self.model.mech, meas, self.model.params, self.model.springs, self.model.gravity,
                      self.model.locked, self.model.base0)
        return model.predict(self.x)[0]

    def to_urdf(self, path: Any, sidecar: Any = None, *, overwrite: bool = False) -> tuple[Any, Any]:
        """Write the calibrated robot as a URDF and its closed-loop sidecar (YAML, default beside
        it): the placements, masses, lateral hinges and beams, the joints' offsets folded into
        their placements, the base pose on the root and each marker a frame at its offset, the
        springs in the sidecar's ``springs:``; loadable by Pinocchio and by
        :meth:`Mechanism.from_urdf <h4pin.mechanism.Mechanism.from_urdf>`, whose markers then
        are where :meth:`predict` puts them. Returns the two paths."""
        from h4pin.mechanism import urdf_writer

        rob = self.robot
        return urdf_writer.write(rob.mech, path, sidecar, springs=rob.springs, base=rob.base,
                                 markers=rob.markers, offsets=rob.offsets, overwrite=overwrite)


def _prior(params: list[Parameter], prior: Mapping[str, Any] | None) -> list[Parameter]:
    """``params`` with the nominal values and sigmas of ``prior`` (names of parameters not fitted
    are passed over: one prior serves every stage of a table)."""
    if prior is None:
        return params
    if not isinstance(prior, Mapping):
        raise ParameterError("prior: a mapping {parameter name: (nominal, sigma)}")
    out = []
    for name in prior:
        if not isinstance(name, str) or name.split("/", 1)[0] not in GROUPS:
            raise ParameterError(f"prior: {name!r} is not a parameter of a group ({', '.join(GROUPS)}/...)")
    for p in params:
        if p.name in prior:
            try:
                nominal, sigma = (float(v) for v in prior[p.name])
            except (TypeError, ValueError):
                raise ParameterError(f"prior[{p.name!r}]: (nominal, sigma), got {prior[p.name]!r}") from None
            if not (math.isfinite(nominal) and math.isfinite(sigma) and sigma > 0) or (p.log and nominal <= 0):
                raise ParameterError(f"prior[{p.name!r}]: a finite nominal{' > 0' if p.log else ''} and sigma > 0")
            if p.log:
                nominal, sigma = math.log(nominal), sigma / nominal
            p = dataclasses.replace(p, nominal=nominal, sigma=sigma)
        out.append(p)
    return out


def _fit(model: Model, noise: float, loss: str, iterations: int, start: np.ndarray | None = None,
         nominal: tuple[Any, ...] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float,
                                                       tuple[Any, ...]]:
    """The fit of ``model`` in the identified subspace from ``start`` (default the prior's
    nominal): ``(x, s, vt, keep, cost, nominal)``, ``nominal`` the prediction and Jacobian at the
    prior's nominal (given back to a second fit, not computed again)."""
    obs = model.meas.observed()
    seen = np.isfinite(obs)
    x0, sig = model.x0, model.sigma
    if nominal is None:
        pred, states = model.predict(x0)
        nominal = (pred, states, model.jacobian(x0, states)[seen])
    jac0 = nominal[2] / noise
    s, vt = fitting.combinations(jac0, sig)
    keep = fitting.split(s, IDENTIFIABLE_TOL, HELD_STD)
    v = vt[keep].T
    w0 = np.zeros(v.shape[1]) if start is None else np.linalg.lstsq(v, (start - x0) / sig, rcond=None)[0]
    # the nominal's prediction and Jacobian serve the fit's first step from there
    cache: dict[bytes, Any] = {np.zeros(v.shape[1]).tobytes(): nominal[:2]}

    def evaluate(w: np.ndarray) -> tuple[np.ndarray, list[Any]]:
        key = w.tobytes()
        if key not in cache:
            cache.clear()
            x = x0 + sig * (v @ w)
            try:
                cache[key] = model.predict(x)
            except H4Error:
                cache[key] = (np.full_like(obs, 1e3), None)
        return cache[key]

    def fun(w: np.ndarray) -> np.ndarray:
        pred, _ = evaluate(w)
        return np.r_[(pred - obs)[seen] / noise, w]

    def jac(w: np.ndarray) -> np.ndarray:
        pred, states = evaluate(w)
        if states is None or not np.any(w):
            return np.r_[jac0 * sig @ v, np.eye(len(w))]
        j = model.jacobian(x0 + sig * (v @ w), states)[seen] / noise
        return np.r_[j * sig @ v, np.eye(len(w))]

    sol = fitting.solve(fun, [w0], jac=jac, loss=loss, f_scale=3.0, max_nfev=iterations, tol=TOL)
    x = x0 + sig * (v @ sol.x)
    return x, s, vt, keep, sol.cost, nominal


def calibrate(mech: Any, measurements: Measurements, parameters: Any = ("base", "markers"), *,
              springs: Mapping[Any, Any] | None = None, prior: Mapping[str, Any] | None = None,
              gravity: bool = True, locked: Iterable[Any] = (), base: Any = None, noise: float | None = None,
              loss: str = "linear", iterations: int = 50, holdout: Any = None, seed: int = 0) -> Calibration:
    """Calibrate ``mech`` from ``measurements`` (module docstring).

    Args:
        mech: any :class:`~h4pin.mechanism.Mechanism` (tree or closed loop).
        measurements: :class:`~h4pin.mechanism.measurements.Measurements`.
        parameters: group names, or ``{group: targets}`` (:data:`GROUPS`).
        springs: the nominal joint springs ``{joint: stiffness}`` (default the file's, else none).
        prior: ``{parameter name: (nominal, sigma)}`` (SI; a stiffness's sigma in N.m/rad)
            replacing the defaults (:data:`SIGMA`, around the nominal model).
        gravity: the robot's weight deflects it (the loaded equilibrium in every prediction).
        locked: joints held rigid (the motors without a spring are).
        base: the start of the world's pose in the tracker's frame (``pin.SE3`` or 4x4).
        noise: the markers' noise (m, per axis); default estimated from the residuals.
        loss: SciPy's robust loss (``linear``, ``soft_l1``, ``huber``, ``cauchy``, ``arctan``).
        iterations: the most model evaluations of the fit.
        holdout: samples kept out of the fit and scored (:attr:`Calibration.held`): a fraction,
            drawn with ``seed``, or sample indices.

    Raises:
        ParameterError: mismatched shapes, an unknown group, joint, marker or prior name, a bad
            option. ConvergenceError: the fit does not converge.
    """
    if not isinstance(measurements, Measurements):
        raise ParameterError(f"measurements: an h4pin.Measurements, got {type(measurements).__name__}")
    if holdout is not None:
        fit_rows, held_rows = _rows(measurements.n, holdout, seed)
        cal = calibrate(mech, measurements.subset(fit_rows), parameters, springs=springs, prior=prior,
                        gravity=gravity, locked=locked, base=base, noise=noise, loss=loss, iterations=iterations)
        test = measurements.subset(held_rows)
        return dataclasses.replace(cal, held=cal.predict(**_commands(test)) - test.observed(), held_rows=held_rows)
    model = _model(mech, measurements, parameters, springs, prior, gravity, locked, base)
    if noise is not None and not (isinstance(noise, (int, float)) and 0 < noise < 1):
        raise ParameterError(f"noise: a finite noise in m (0 < noise < 1), got {noise!r}")
    sigma = 1e-4 if noise is None else float(noise)
    x, s, vt, keep, cost, nominal = _fit(model, sigma, loss, iterations)
    if noise is None:  # the noise of the residuals; the fit again from there if it weighs the prior otherwise
        pred, _ = model.predict(x)
        res = (pred - measurements.observed())[np.isfinite(measurements.observed())]
        estimate = float(np.sqrt(np.sum(res**2) / max(res.size - int(keep.sum()), 1)))
        if not 0.5 < estimate / sigma < 2.0:
            x, s, vt, keep, cost, _ = _fit(model, estimate, loss, iterations, x, nominal)
        sigma = estimate
    return _result(model, x, sigma, cost)


def _model(mech: Any, measurements: Measurements, parameters: Any, springs: Mapping[Any, Any] | None,
           prior: Mapping[str, Any] | None, gravity: bool, locked: Iterable[Any], base: Any) -> Model:
    """The forward :class:`Model` of a calibration: the nominal springs by name, the lateral
    hinges inserted where asked, the parameters and their prior (:func:`calibrate`'s arguments)."""
    from h4pin.mechanism.arguments import joint_names

    if springs is None:
        springs = dict(mech.springs)
    names = joint_names(mech.model, list(springs), "springs")
    nominal = {n: float(k) for n, k in zip(names, springs.values(), strict=True)}
    spec = {g: None for g in parameters} if not isinstance(parameters, Mapping) else dict(parameters)
    if "lateral" in spec:
        mech = with_lateral(mech, _targets(spec["lateral"], [], "lateral") or
                            [mech.model.names[j] for j in range(1, mech.model.njoints) if mech.model.joints[j].nq == 1],
                            nominal)
    base = pin.SE3.Identity() if base is None else pin.SE3(np.asarray(base, float)) if not isinstance(base, pin.SE3) \
        else base
    commanded = tuple(mech.actuated) if measurements.motors is not None else \
        tuple(mech.model.names[j] for j in range(1, mech.model.njoints))
    params = parameters_of(mech, spec, nominal, measurements.markers, commanded)
    params = _prior(params, prior)
    lock = tuple(joint_names(mech.model, locked, "locked"))
    return Model(mech, measurements, params, {**mech.beam_springs, **nominal}, gravity, lock, base)


def synthetic(mech: Any, parameters: Any, markers: Sequence[str], *, motors: Any = None, configurations: Any = None,
              loads: Mapping[str, Any] | None = None, springs: Mapping[Any, Any] | None = None,
              prior: Mapping[str, Any] | None = None, noise: float = 1e-4, gravity: bool = True,
              locked: Iterable[Any] = (), base: Any = None, seed: int = 0) -> tuple[Measurements, dict[str, float]]:
    """A synthetic tracker session, to plan an experiment before measuring (how many poses, which
    loads, what the data will identify) and to test a calibration: a true robot drawn from the
    prior (each parameter of ``parameters`` its nominal plus a normal draw of its sigma, ``seed``),
    its markers predicted at the commanded ``motors`` (N, n_act) or ``configurations`` (N, nq) under
    gravity and ``loads``, plus Gaussian ``noise`` (m, per axis).

    Returns:
        ``(measurements, truth)``: the :class:`Measurements` to fit and the true values by name
        (:attr:`Calibration.values`' names, SI).
    """
    if motors is None and configurations is None:
        raise ParameterError("synthetic: give motors= (a closed loop) or configurations= (a tree)")
    if not (isinstance(noise, (int, float)) and 0 <= noise < 1):
        raise ParameterError(f"noise: a noise in m (0 <= noise < 1), got {noise!r}")
    n = len(np.asarray(motors if motors is not None else configurations))
    blank = Measurements(motors=motors, configurations=configurations, loads=loads,
                         points={f: np.zeros((n, 3)) for f in markers})
    spec = {g: None for g in parameters} if not isinstance(parameters, Mapping) else dict(parameters)
    model = _model(mech, blank, spec, springs, prior, gravity, locked, base)
    rng = np.random.default_rng(seed)
    truth = model.x0 + model.sigma * rng.normal(size=len(model.params))
    points, _ = model.predict(truth)
    points = points + rng.normal(0.0, noise, points.shape)
    meas = Measurements(motors=motors, configurations=configurations, loads=loads,
                        points={f: points[:, i] for i, f in enumerate(markers)})
    return meas, {p.name: p.value(v) for p, v in zip(model.params, truth, strict=True)}


def parameters_of(mech: Any, spec: Mapping[str, Any], springs: Mapping[str, float], markers: Sequence[str],
                  commanded: Sequence[str]) -> list[Parameter]:
    """:func:`parameters` of a calibration, the lateral group's targets those inserted."""
    return parameters(mech, spec, springs, markers, commanded)


def _result(model: Model, x: np.ndarray, noise: float, cost: float) -> Calibration:
    pred, states = model.predict(x)
    obs = model.meas.observed()
    seen = np.isfinite(obs)
    jac = model.jacobian(x, states)[seen] / noise
    s, vt = fitting.combinations(jac, model.sigma)
    keep = fitting.split(s, IDENTIFIABLE_TOL, HELD_STD)
    # The posterior in prior units: an identified combination's variance 1 / (s^2 + 1) (the data
    # and the prior), a held one's the prior's, 1: each parameter's std includes what is not known.
    var = np.where(keep, 1.0 / (s**2 + 1.0), 1.0)
    cov = (vt.T * var) @ vt * model.sigma[:, None] * model.sigma[None, :]
    names = [p.name for p in model.params]
    values = {p.name: p.value(v) for p, v in zip(model.params, x, strict=True)}
    std = {}
    for k, p in enumerate(model.params):
        sd = float(np.sqrt(cov[k, k]))
        std[p.name] = sd * values[p.name] if p.log else sd
    held = tuple(fitting.describe(vt[i], names) for i in np.flatnonzero(~keep))
    return Calibration(values, std, pred - obs, held, noise, model, x, cost)


def _rows(n: int, holdout: Any, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``(fit rows, held-out rows)``: ``holdout`` a fraction of the samples (drawn with ``seed``),
    sample indices, or None (none held out)."""
    if holdout is None:
        return np.arange(n), np.zeros(0, dtype=int)
    if isinstance(holdout, float) and not isinstance(holdout, bool):
        if not 0 < holdout < 1:
            raise ParameterError(f"holdout: a fraction in (0, 1) or sample indices, got {holdout!r}")
        held = np.sort(np.random.default_rng(seed).choice(n, max(1, int(round(holdout * n))), replace=False))
    else:
        try:
            held = np.unique(np.asarray(holdout, dtype=int).reshape(-1))
        except (TypeError, ValueError):
            raise ParameterError(f"holdout: a fraction in (0, 1) or sample indices, got {holdout!r}") from None
        if held.size and (held.min() < 0 or held.max() >= n):
            raise ParameterError(f"holdout: sample indices in 0..{n - 1}")
    fit = np.setdiff1d(np.arange(n), held)
    if fit.size == 0:
        raise ParameterError("holdout: every sample is held out; keep some to fit")
    return fit, held


def errors(residuals: np.ndarray) -> tuple[float, float, float]:
    """``(mean, std, max)`` of the markers' position errors (m) in ``residuals`` (N, m, 3)."""
    e = np.linalg.norm(residuals, axis=-1)
    e = e[np.isfinite(e)]
    return (float(e.mean()), float(e.std()), float(e.max())) if e.size else (math.nan,) * 3


@dataclasses.dataclass(frozen=True)
class Stage:
    """One row of a stage table (:func:`stages`): the groups fitted so far, the errors (mean, std,
    max, m) on the fitted and the held-out samples, the calibration."""

    groups: tuple[str, ...]
    fit: tuple[float, float, float]
    held: tuple[float, float, float]
    calibration: Any


def stages(mech: Any, measurements: Measurements, steps: Sequence[Any], *, holdout: Any = 0.2, seed: int = 0,
           **options: Any) -> list[Stage]:
    """A stage-by-stage table, as users publish it: the nominal model, then a calibration with each
    step's groups added to the ones before (``[["base", "markers"], ["offsets"], ["geometry"],
    ["springs"], ["lateral"]]``), each fitted on the same samples and scored on the held-out ones
    (``holdout``: a fraction, drawn with ``seed``, or indices); a step may name targets
    (``{"geometry": ["free1"]}``); ``options`` as :func:`calibrate`."""
    fit_rows, held_rows = _rows(measurements.n, holdout, seed)
    train = measurements.subset(fit_rows)
    test = measurements.subset(held_rows) if held_rows.size else None
    out: list[Stage] = []
    spec: dict[str, Any] = {}
    for step in [None, *steps]:
        if step is not None:
            _add_step(spec, step)
        cal = calibrate(mech, train, dict(spec), **options) if spec else _nominal(mech, train, options)
        held = errors(cal.predict(**_commands(test)) - test.observed()) if test is not None else (math.nan,) * 3
        out.append(Stage(tuple(spec) or ("nominal",), errors(cal.residuals), held, cal))
    return out


def _add_step(spec: dict[str, Any], step: Any) -> None:
    """A stage's groups added to ``spec``: a group name, a list of names or ``{group: targets}``;
    a group named again with targets adds them (``None``, all targets, stays all)."""
    items = step.items() if isinstance(step, Mapping) else \
        [(step, None)] if isinstance(step, str) else [(g, None) for g in step]
    for group, targets in items:
        if group in spec and (spec[group] is None or targets is None):
            spec[group] = None
        elif group in spec:
            spec[group] = list(dict.fromkeys([*spec[group], *targets]))
        else:
            spec[group] = None if targets is None else list(targets)


def _commands(meas: Measurements) -> dict[str, Any]:
    return {"motors": meas.motors, "loads": meas.loads} if meas.motors is not None else \
        {"configurations": meas.configurations, "loads": meas.loads}


def _nominal(mech: Any, meas: Measurements, options: Mapping[str, Any]) -> Calibration:
    """The nominal model as a :class:`Calibration` of nothing (its residuals, its predictions)."""
    from h4pin.mechanism.arguments import joint_names

    springs = options.get("springs")
    springs = dict(mech.springs) if springs is None else springs
    names = joint_names(mech.model, list(springs), "springs")
    nominal = {n: float(k) for n, k in zip(names, springs.values(), strict=True)}
    base = options.get("base")
    base = pin.SE3.Identity() if base is None else base if isinstance(base, pin.SE3) else pin.SE3(np.asarray(base))
    commanded = tuple(mech.actuated) if meas.motors is not None else \
        tuple(mech.model.names[j] for j in range(1, mech.model.njoints))
    params = parameters(mech, ["base"], nominal, meas.markers, commanded)
    model = Model(mech, meas, params, {**mech.beam_springs, **nominal}, options.get("gravity", True),
                  tuple(joint_names(mech.model, options.get("locked", ()), "locked")), base)
    x = model.x0
    pred, _ = model.predict(x)
    nan = {p.name: math.nan for p in params}
    return Calibration({p.name: p.value(v) for p, v in zip(params, x, strict=True)}, nan, pred - meas.observed(),
                       (), math.nan, model, x)


def stage_table(rows: Sequence[Stage]) -> str:
    """The stage table as text, errors in mm: a row a stage, named by the groups it adds."""
    head = f"{'stage':<44}{'fit mean':>10}{'std':>8}{'max':>8}{'held mean':>11}{'std':>8}{'max':>8}"
    lines = [head, "-" * len(head)]
    before: tuple[str, ...] = ("nominal",)
    for r in rows:
        added = [g for g in r.groups if g not in before]
        name = "+ " + " + ".join(added) if before != ("nominal",) and added else " + ".join(r.groups)
        before = r.groups
        f, h = (np.array(v) * 1e3 for v in (r.fit, r.held))
        lines.append(f"{name[:43]:<44}{f[0]:>10.3f}{f[1]:>8.3f}{f[2]:>8.3f}{h[0]:>11.3f}{h[1]:>8.3f}{h[2]:>8.3f}")
    return "\n".join(lines)


def cross_validate(mech: Any, measurements: Measurements, parameters: Any, folds: int = 5, *, seed: int = 0,
                   **options: Any) -> list[tuple[tuple[float, float, float], tuple[float, float, float]]]:
    """``folds``-fold cross-validation: the samples shuffled (``seed``) into ``folds`` parts, each
    held out once; per fold, the errors ``(mean, std, max)`` (m) on the fitted and the held-out
    samples (``options`` as :func:`calibrate`)."""
    if isinstance(folds, bool) or not isinstance(folds, int) or not 2 <= folds <= measurements.n:
        raise ParameterError(f"folds: an integer from 2 to the number of samples, got {folds!r}")
    order = np.random.default_rng(seed).permutation(measurements.n)
    out = []
    for part in np.array_split(order, folds):
        cal = calibrate(mech, measurements, parameters, holdout=np.sort(part), **options)
        out.append((errors(cal.residuals), errors(cal.held)))
    return out

__all__ = ["GROUPS", "IDENTIFIABLE_TOL", "LATERAL_FACTOR", "LATERAL_STIFFNESS", "SIGMA", "STEP", "Calibration",
           "Model", "Parameter", "Robot", "Stage", "calibrate", "cross_validate", "errors", "parameters",
           "stage_table", "stages", "with_lateral"]
