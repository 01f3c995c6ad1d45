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
* ``geometry/<joint>/tx`` ... ``/rz``: the joint's placement in its parent, ``M (t, exp3(r))``
  (a translation, then a rotation about the moved origin: a rotation about the joint's own axis
  is exactly its zero offset, whatever the translation);
* ``springs/<joint>``: a joint spring's stiffness (N.m/rad, N/m), fitted in ``log``;
* ``lateral/<joint>/a``, ``/b``: two elastic hinges about the axes perpendicular to the joint's
  (the bearing's tilt and the link's bending, inserted where asked), fitted in ``log``;
* ``beams/<link>``: a flexible link's stiffness scale (all its virtual joints), in ``log``;
* ``masses/<joint>/m``, ``/cx``, ``/cy``, ``/cz``: the mass a joint carries (fitted in ``log``)
  and its centre (its frame), what gravity makes identifiable.

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
from the data alone above :data:`HELD_STD` prior sigmas): they are left to the prior and listed in
:attr:`Calibration.unidentifiable`, never left to drift: the fit weighs every combination with
its prior, so one the data do not see stays at the prior's nominal to first order (and moves only
as the others' curvature asks: a joint's offset beside its neighbour's placement is a curved
degeneracy, and held on its straight line its second-order part would bend the identified
parameters). The covariance is ``(Jᵀ J + I)⁻¹`` in prior units on the identified combinations, the
prior's on the others; the noise is estimated from the residuals unless given. The standard
deviations are the linearisation's at the solution: where a degeneracy bends over the prior's
width, :func:`coverage` tells how honest they are for an experiment.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import H4Error, ParameterError
from h4pin.mechanism import assembly, fitting, loaded
from h4pin.mechanism.engine import Insertion, VirtualJoint
from h4pin.mechanism.measurements import Measurements
from h4pin.mechanism.sensitivity import Sensitivity

#: The parameter groups, in the order a stage table usually adds them.
GROUPS = ("base", "markers", "offsets", "geometry", "springs", "lateral", "beams", "masses")
#: The prior's default sigma of each group (SI; of the log for the log-fitted groups and a mass).
SIGMA = {"base": (0.1, 0.1), "markers": 0.01, "offsets": (0.05, 0.005), "geometry": (0.005, 0.01),
         "springs": math.log(10.0), "lateral": math.log(100.0), "beams": math.log(10.0), "masses": (0.5, 0.05)}
#: A lateral hinge's nominal stiffness: this times its joint's spring (or LATERAL_STIFFNESS).
LATERAL_FACTOR, LATERAL_STIFFNESS = 10.0, 1e4
#: Relative singular value under which a combination is not identified; and the standard deviation
#: (in prior sigmas) the data alone leave a combination above which it is held at the prior: the
#: data tell it less than a hundredth of what the prior does.
IDENTIFIABLE_TOL, HELD_STD = 1e-6, 10.0
#: The fit's relative tolerance (SciPy's ftol, xtol, gtol): a cost a few hundred noise-scaled
#: squares stops changing below a thousandth of one (a fraction of its statistical spread, ~1).
TOL = 1e-6
#: The most fits of one calibration: again from the solution while the noise's estimate changes.
ROUNDS = 4
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
    movable = [model.names[j] for j in range(1, model.njoints)
               if model.joints[j].nq == 1 and model.names[j] not in mech.beam_springs]  # not a virtual joint
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
                prismatic = assembly.motor_range(model, j) == "motor travel"
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
                out.append(Parameter(f"masses/{j}/m", group, j, 0, math.log(max(float(inertia.mass), 1e-3)),
                                     SIGMA["masses"][0], True))
                out += [Parameter(f"masses/{j}/c{a}", group, j, k + 1, float(inertia.lever[k]), SIGMA["masses"][1])
                        for k, a in enumerate("xyz")]
    names = [p.name for p in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ParameterError(f"parameters: {twice[0]!r} is asked twice")
    if not out:
        raise ParameterError("parameters: give at least one group (groups: " + ", ".join(GROUPS) + ")")
    return out


def placement_error(d: np.ndarray) -> pin.SE3:
    """A geometry parameter's correction ``(t, exp3(r))`` of a joint placement, d = (t, r)."""
    return pin.SE3(pin.exp3(np.asarray(d[3:], float)), np.asarray(d[:3], float))


def commanded_joints(mech: Any, meas: Measurements, motors: bool = True) -> tuple[str, ...]:
    """The joints a sample commands: the motors of a closed loop measured by ``motors`` (with
    ``motors=True``), else every joint of the model but the mechanism's own virtual joints (a
    beam's, a lateral hinge's)."""
    if motors and meas.motors is not None:
        return tuple(mech.actuated)
    model = mech.model
    return tuple(model.names[j] for j in range(1, model.njoints) if model.names[j] not in mech.beam_springs)


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



#: The most steps of the motor path :func:`_assemble_towards` takes from a far start.
PATH_STEPS = 64


def _assemble_towards(mech: Any, start: np.ndarray, motors: np.ndarray, idx: Sequence[int]) -> np.ndarray:
    """The loops closed at ``motors`` from ``start``: directly, else along the straight motor
    path from the start's motors in steps halved until each closes from the one before (a first
    sample far from the reference, as a tracker session's usually is)."""
    from h4pin.mechanism.engine import UnassembledError

    try:
        return mech.assemble(start, motors=motors)
    except UnassembledError:
        steps = 4
        while True:
            path = start[idx] + np.linspace(0.0, 1.0, steps + 1)[1:, None] * (motors - start[idx])[None, :]
            try:
                return mech.assemble(start, motors=path)[-1]
            except UnassembledError:
                if steps >= PATH_STEPS:
                    raise
                steps *= 2


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


class Model(Sensitivity):
    """The forward model of a calibration (module docstring): the mechanism (lateral hinges
    inserted where asked), the measurements' commands and loads, the parameters; predicts the
    markers of a parameter vector; their Jacobian (:class:`~h4pin.mechanism.sensitivity.Sensitivity`)."""

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
            self.commanded = commanded_joints(mech, meas)
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
                    mass = p.value(v)
                else:
                    lever[p.index - 1] = v
                model.inertias[j] = pin.Inertia(mass, lever, inertia.inertia)
        for j, d in geometry.items():
            model.jointPlacements[j] = model.jointPlacements[j] * placement_error(d)
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
            rest = _assemble_towards(mech, start, meas.motors[i] + rob.offsets[idx], idx)
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


def _fit(model: Model, noise: float, loss: str, iterations: int, x: np.ndarray, at: tuple[Any, ...]
         ) -> tuple[np.ndarray, float]:
    """The fit of ``model`` from x (``at``: x's prediction, states and Jacobian) in the prior's
    units, along the combinations of the Jacobian at x: ``(x, cost)``. Every combination is
    fitted with its prior: one the data do not inform stays at the prior's nominal to first order
    and moves only as far as the others' curvature asks (an offset beside a placement is a curved
    degeneracy: held on its straight line, its second-order part would bend the others)."""
    obs = model.meas.observed()
    seen = np.isfinite(obs)
    x0, sig = model.x0, model.sigma
    jac_at = at[2] / noise
    _, vt, _ = _split(at[2], noise, sig)
    v = vt.T
    rest = np.zeros(len(x0))
    w0 = v.T @ ((x - x0) / sig)
    cache: dict[bytes, Any] = {w0.tobytes(): at[:2]}

    def evaluate(w: np.ndarray) -> tuple[np.ndarray, list[Any]]:
        key = w.tobytes()
        if key not in cache:
            cache.clear()
            try:
                cache[key] = model.predict(x0 + sig * (v @ w + rest))
            except H4Error:
                cache[key] = (np.full_like(obs, 1e3), None)
        return cache[key]

    def fun(w: np.ndarray) -> np.ndarray:
        pred, _ = evaluate(w)
        return np.r_[(pred - obs)[seen] / noise, v @ w + rest]

    def jac(w: np.ndarray) -> np.ndarray:
        pred, states = evaluate(w)
        if states is None or np.array_equal(w, w0):
            return np.r_[jac_at * sig @ v, v]
        j = model.jacobian(x0 + sig * (v @ w + rest), states)[seen] / noise
        return np.r_[j * sig @ v, v]

    sol = fitting.solve(fun, [w0], jac=jac, loss=loss, f_scale=3.0, max_nfev=iterations, tol=TOL)
    return x0 + sig * (v @ sol.x + rest), sol.cost


def _split(jac: np.ndarray, noise: float, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(s, vt, keep)``: the combinations of the Jacobian (the seen rows, m) in prior units at the
    noise, and those the data identify."""
    s, vt = fitting.combinations(jac / noise, sigma)
    return s, vt, fitting.split(s, IDENTIFIABLE_TOL, HELD_STD)


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
    obs = measurements.observed()
    seen = np.isfinite(obs)
    x, cost = model.x0, math.inf
    pred, states = model.predict(x)
    at = (pred, states, model.jacobian(x, states)[seen])
    # The fit; again from its solution while the noise's estimate changes the prior's weight.
    for _ in range(ROUNDS):
        x, cost = _fit(model, sigma, loss, iterations, x, at)
        pred, states = model.predict(x)
        at = (pred, states, model.jacobian(x, states)[seen])
        if noise is not None:
            break
        # the noise of the residuals, over the data's share of the degrees of freedom
        res = (pred - obs)[seen]
        s, _, _ = _split(at[2], sigma, model.sigma)
        estimate = float(np.sqrt(np.sum(res**2) / max(res.size - float(np.sum(s**2 / (s**2 + 1.0))), 1.0)))
        changed = not 0.5 < estimate / sigma < 2.0
        sigma = estimate
        if not changed:
            break
    return _result(model, x, sigma, cost, at)


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
                            [n for n in commanded_joints(mech, measurements, motors=False)
                             if mech.model.joints[mech.model.getJointId(n)].nq == 1],
                            nominal)
    base = pin.SE3.Identity() if base is None else pin.SE3(np.asarray(base, float)) if not isinstance(base, pin.SE3) \
        else base
    commanded = commanded_joints(mech, measurements)
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


@dataclasses.dataclass(frozen=True)
class Coverage:
    """Repeated synthetic experiments (:func:`coverage`): is the stated uncertainty honest, and
    what will the data identify?

    Attributes:
        names: the parameters. z: (runs, parameters) ``(fitted - truth) / std``.
        identified: (runs, parameters) the data informed the parameter (its std under half its
            prior sigma). rms: (runs,) the residuals' RMS per axis over the noise.
        noise: (runs,) the estimated noise over the true one.
        unidentifiable: each run's :attr:`Calibration.unidentifiable`. seconds: each fit's time.
    """

    names: tuple[str, ...]
    z: np.ndarray
    identified: np.ndarray
    rms: np.ndarray
    noise: np.ndarray
    unidentifiable: tuple[tuple[str, ...], ...]
    seconds: np.ndarray

    @property
    def fraction(self) -> float:
        """The fraction of runs in which every parameter the run identified is within 3 std of
        the truth (the others are the prior's: within 3 std as often as the prior draws so)."""
        return float(np.mean(np.all((np.abs(self.z) < 3.0) | ~self.identified, axis=1)))

    @property
    def every(self) -> float:
        """The fraction of runs in which every parameter is within 3 std of the truth."""
        return float(np.mean(np.all(np.abs(self.z) < 3.0, axis=1)))

    def table(self) -> str:
        """Per parameter: the runs within 3 std, identified, and the z's spread (honest: ~1)."""
        lines = [f"{'parameter':<34}{'within 3 std':>13}{'identified':>11}{'z std':>8}"]
        for k, n in enumerate(self.names):
            lines.append(f"{n:<34}{np.mean(np.abs(self.z[:, k]) < 3.0):>13.0%}{np.mean(self.identified[:, k]):>11.0%}"
                         f"{np.std(self.z[:, k]):>8.2f}")
        lines.append(f"{len(self.z)} runs: every identified parameter within 3 std in {self.fraction:.0%}, every "
                     f"parameter in {self.every:.0%}; residual RMS / noise {np.mean(self.rms):.3f} (min "
                     f"{np.min(self.rms):.3f}, max {np.max(self.rms):.3f}); the noise estimated within "
                     f"{np.max(np.abs(self.noise - 1.0)):.0%} (mean {np.mean(self.noise):.3f}); a fit "
                     f"{np.mean(self.seconds):.1f} s")
        return "\n".join(lines)


def coverage(mech: Any, parameters: Any, markers: Sequence[str], *, runs: int = 50, seed: int = 0,
             motors: Any = None, configurations: Any = None, loads: Mapping[str, Any] | None = None,
             springs: Mapping[Any, Any] | None = None, prior: Mapping[str, Any] | None = None, noise: float = 1e-4,
             gravity: bool = True, locked: Iterable[Any] = (), workers: int = 1, progress: bool = False,
             **options: Any) -> Coverage:
    """``runs`` synthetic experiments (:func:`synthetic`, seeds ``seed`` ...) of one design (the
    commands and loads), each calibrated (:func:`calibrate`, ``options``; the noise estimated):
    the coverage of the stated uncertainty, the parameters the design identifies, the residuals
    against the noise. An experiment planned before the robot is measured. ``workers`` > 1 runs
    them in that many forked processes (POSIX)."""
    import multiprocessing

    from tqdm import tqdm

    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ParameterError(f"runs: a positive integer, got {runs!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers: a positive integer, got {workers!r}")
    job = functools.partial(_coverage_run, mech, parameters, tuple(markers), motors, configurations, loads, noise,
                            {"springs": springs, "prior": prior, "gravity": gravity, "locked": locked}, options)
    seeds = range(seed, seed + runs)
    with tqdm(total=runs, desc="coverage", unit="run", disable=not progress) as bar:
        out = [job(seeds[0])]  # here first: a bad argument is its typed error, not a worker's traceback
        bar.update()
        if workers == 1 or runs == 1 or "fork" not in multiprocessing.get_all_start_methods():
            for s in seeds[1:]:
                out.append(job(s))
                bar.update()
        else:  # forked: the job (its mechanism is not picklable) inherited, the results sent back
            global _JOB
            _JOB = job
            try:
                with multiprocessing.get_context("fork").Pool(min(workers, runs - 1)) as pool:
                    for o in pool.imap(_run_job, seeds[1:]):
                        out.append(o)
                        bar.update()
            finally:
                _JOB = None
    names = out[0][0]
    return Coverage(names, *(np.array([o[k] for o in out]) for k in range(1, 5)),
                    tuple(o[5] for o in out), np.array([o[6] for o in out]))


_JOB: Any = None


def _run_job(seed: int) -> tuple[Any, ...]:
    return _JOB(seed)


def _coverage_run(mech: Any, parameters: Any, markers: tuple[str, ...], motors: Any, configurations: Any,
                  loads: Any, noise: float, common: dict[str, Any], options: dict[str, Any], seed: int
                  ) -> tuple[Any, ...]:
    """One run of :func:`coverage`: ``(names, z, identified, rms / noise, noise estimate / noise,
    unidentifiable, seconds)``."""
    import time

    meas, truth = synthetic(mech, parameters, markers, motors=motors, configurations=configurations, loads=loads,
                            noise=noise, seed=seed, **common)
    start = time.perf_counter()
    c = calibrate(mech, meas, parameters, **common, **options)
    seconds = time.perf_counter() - start
    names = tuple(truth)
    params = {p.name: p for p in c.model.params}

    def fitted(name: str, value: float) -> float:  # z in the fitted variable (a stiffness's log)
        return math.log(value) if params[name].log else value

    std = {n: c.std[n] / (c.values[n] if params[n].log else 1.0) for n in names}
    res = c.residuals[np.isfinite(c.residuals)]
    return (names, [(fitted(n, c.values[n]) - fitted(n, truth[n])) / std[n] for n in names],
            [std[n] < 0.5 * params[n].sigma for n in names], float(np.sqrt(np.mean(res**2))) / noise, c.noise / noise,
            c.unidentifiable, seconds)

def parameters_of(mech: Any, spec: Mapping[str, Any], springs: Mapping[str, float], markers: Sequence[str],
                  commanded: Sequence[str]) -> list[Parameter]:
    """:func:`parameters` of a calibration, the lateral group's targets those inserted."""
    return parameters(mech, spec, springs, markers, commanded)


def _result(model: Model, x: np.ndarray, noise: float, cost: float, at: tuple[Any, ...]) -> Calibration:
    pred, obs = at[0], model.meas.observed()
    s, vt, keep = _split(at[2], noise, model.sigma)
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
    commanded = commanded_joints(mech, meas)
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

__all__ = ["GROUPS", "IDENTIFIABLE_TOL", "LATERAL_FACTOR", "LATERAL_STIFFNESS", "SIGMA", "Calibration",
           "Model", "Parameter", "Robot", "Stage", "calibrate", "cross_validate", "errors", "parameters",
           "stage_table", "stages", "with_lateral"]
