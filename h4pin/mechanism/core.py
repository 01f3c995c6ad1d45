# SPDX-License-Identifier: Apache-2.0
"""Any closed-loop robot as a value: :class:`Mechanism` (stiffness, natural frequencies, assembly).

A mechanism is a Pinocchio tree (``pin.Model``), its loop closures
(``pin.RigidConstraintModel``, ``CONTACT_3D`` or ``CONTACT_6D``) and its actuated joints. It reads
the formats closed-loop robots are published in:

* :meth:`Mechanism.from_urdf`: a URDF and the YAML sidecar of Gepetto's closed-loop toolbox
  (``closed_loop``: pairs of frame names, ``type``: ``3D``/``6D`` per pair, ``name_mot``: the motor
  joints), as that toolbox's loader builds them (fixed base, each pair a closure between the two
  frames' parent joints at the frames' placements);
* :meth:`Mechanism.from_mjcf`: an MJCF file whose loops are ``connect``/``weld`` equalities
  (Pinocchio 4's reader), its ``<actuator>`` joints as the motors;
* ``Mechanism(model, constraint_models, actuated=...)`` for a model built in code.

Then :meth:`~Mechanism.assemble` closes the loops, :meth:`~Mechanism.compliance` gives the
compliance of output frames under joint springs (the engine of :mod:`h4pin.mechanism.engine`), and
:meth:`~Mechanism.modes` the natural frequencies with the model's inertias
(:mod:`h4pin.elastic.modal`'s solver). The H4 is one such mechanism with many virtual springs
(:func:`h4pin.elastic.elastic_model`); ``docs/mechanisms.md`` walks through a five-bar linkage.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin._compat import constraint_calc
from h4pin.errors import MalformedURDFError, ParameterError, UnsupportedFeatureError
from h4pin.inputs import check_choice
from h4pin.lookup import finite_configuration, model_configuration
from h4pin.mechanism import assembly, batch, engine, loaded
from h4pin.mechanism.arguments import joint_names, locked_of, outputs_of, springs_of
from h4pin.mechanism.couplings import JointCoupling
from h4pin.mechanism.engine import (
    Modes,
    admissible_basis,
    undamped_modes,
)


def _urdf_ranges(model: pin.Model) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) (nq,): the model's position limits of one-coordinate joints where
    lower < upper (a URDF without ``lower``/``upper`` gives 0..0: no range), nan elsewhere."""
    lo, hi = np.full(model.nq, np.nan), np.full(model.nq, np.nan)
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nq == 1:
            a, b = model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q]
            if np.isfinite(a) and np.isfinite(b) and a < b and max(abs(a), abs(b)) < 1e100:
                lo[jm.idx_q], hi[jm.idx_q] = a, b
    return lo, hi


def _tied(model: pin.Model, constraint_models: Iterable[Any], root: int) -> bool:
    """Whether a closure joins a body of joint ``root``'s subtree to a body outside it (a floating
    plate closed on legs, as the H4's, is tied; a legged robot's free-flyer root, whose loops all
    lie within its own subtree, is not)."""
    inside = set(model.subtrees[root])
    return any((cm.joint1_id in inside) != (cm.joint2_id in inside) for cm in constraint_models)


def _closures(model: pin.Model, constraint_models: Iterable[Any]) -> Any:
    """The closures as a ``StdVec_RigidConstraintModel``, each named (``closure_<i>`` when unnamed)."""
    out = pin.StdVec_RigidConstraintModel()
    seen = set()
    for i, cm in enumerate(constraint_models):
        if not isinstance(cm, pin.RigidConstraintModel):
            raise ParameterError(f"constraint_models[{i}]: a pin.RigidConstraintModel, got {type(cm).__name__}")
        if cm.type not in (pin.ContactType.CONTACT_3D, pin.ContactType.CONTACT_6D):
            raise ParameterError(f"closure {cm.name or i!r}: type {cm.type} (CONTACT_3D or CONTACT_6D only)")
        for side in (cm.joint1_id, cm.joint2_id):
            if not 0 <= side < model.njoints:
                raise ParameterError(f"closure {cm.name or i!r}: joint id {side} is not in the model")
        copy = pin.RigidConstraintModel(cm)
        copy.name = cm.name or f"closure_{i + 1}"
        if copy.name in seen:
            raise ParameterError(f"two closures are named {copy.name!r}")
        seen.add(copy.name)
        out.append(copy)
    return out


class Mechanism(loaded.UnderLoad):
    """A closed-loop robot: a Pinocchio tree, its loop closures and its actuated joints (module
    docstring). Immutable; the model and closures are copies of what was given, a ``pin.Data``
    is made per calling thread.

    Args:
        model: the tree (``pin.Model``).
        constraint_models: the closures (``pin.RigidConstraintModel``; unnamed ones are named
            ``closure_<i>``, 1-based).
        actuated: the motor joints, names or Pinocchio joint ids.
        name: for messages (default the model's name).
        reference: the file's reference configuration, where :meth:`assemble` starts (default
            Pinocchio's neutral one).
        ranges: (lower, upper) (nq,) each, nan where a coordinate has no range (default: the
            model's limits of one-coordinate joints where lower < upper).
        springs: the file's joint springs ``{joint: stiffness}`` (default none).
        couplings: joint couplings (:class:`JointCoupling`), constraints like the closures.

    Attributes:
        reference, ranges, springs: as given (read-only). spring_rest: each file spring's rest
            position (MJCF ``springref``), where it has one. free_flyers: the free-flyer joints on
            the universe that no closure ties to the rest (a legged robot's root, whose loops all
            lie within it; not a plate closed on legs), held by :meth:`compliance` and
            :meth:`modes` unless freed.

    Raises:
        ParameterError: not a ``pin.Model``, a closure of another kind, an unknown joint.
    """

    def __init__(self, model: pin.Model, constraint_models: Iterable[Any] = (), actuated: Iterable[Any] = (), *,
                 name: str | None = None, reference: Any = None, ranges: tuple[Any, Any] | None = None,
                 springs: Mapping[Any, Any] | None = None, couplings: Iterable[JointCoupling] = ()):
        if not isinstance(model, pin.Model):
            raise ParameterError(f"model: a pinocchio.Model, got {type(model).__name__}")
        model = pin.Model(model)
        object.__setattr__(self, "model", model)
        object.__setattr__(self, "constraint_models", _closures(model, constraint_models))
        object.__setattr__(self, "actuated", joint_names(model, actuated, "actuated"))
        object.__setattr__(self, "name", name or model.name or "mechanism")
        object.__setattr__(self, "_local", threading.local())
        values = _file_data(model, self.constraint_models, reference, ranges, springs, couplings)
        for name, value in values.items():
            object.__setattr__(self, name, value)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"a Mechanism is immutable (cannot set {name!r})")

    def __repr__(self) -> str:
        return (f"Mechanism({self.name!r}, nq={self.model.nq}, nv={self.model.nv}, closures="
                f"{len(self.constraint_models)}, actuated={list(self.actuated)})")

    @property
    def data(self) -> pin.Data:
        """The calling thread's own ``pin.Data`` of :attr:`model`."""
        d = getattr(self._local, "data", None)
        if d is None:
            d = self._local.data = self.model.createData()
        return d

    # ------------------------------------------------------------------ readers
    @classmethod
    def from_urdf(cls, urdf_path: str | Path, sidecar: str | Path | None = None, *,
                  actuated: Iterable[Any] | None = None, free_flyer: bool = False) -> Mechanism:
        """A URDF and its closed-loop sidecar (YAML: ``closed_loop``, ``type``, ``name_mot``,
        ``joint_name``/``joint_type``; default: the URDF's path with ``.yaml``), as Gepetto's
        loader builds them (:mod:`h4pin.mechanism.sidecar`: the joint conversions applied before
        the closures are built), and the sidecar's ``beams:`` as flexible links
        (:meth:`with_beams`); ``actuated`` overrides ``name_mot``; ``free_flyer``: the root on
        a free-flyer joint (legged robots; held in :meth:`compliance` and :meth:`modes` unless
        freed). The reference configuration is Pinocchio's neutral one; a joint's range is the
        URDF's ``lower``..``upper`` where they differ (URDF's default 0..0 states none).

        Raises:
            MissingExtraError: PyYAML is not installed. MalformedURDFError: the URDF does not
            parse; the sidecar is not such a mapping, a key holds the wrong kind, or it names a
            frame or motor the model lacks.
        """
        return _from_urdf(cls, urdf_path, sidecar, actuated, free_flyer)

    @classmethod
    def from_elastic(cls, em: Any) -> Mechanism:
        """An elastic H4 (:func:`h4pin.elastic.elastic_model`) as a mechanism: its tree, closures
        and four actuators, with the inertias :func:`h4pin.modes` uses (each forearm on its
        actuator's spring), its virtual joints' springs as the mechanism's own (as a beam's:
        :attr:`beam_springs`, held in a rigid assembly) and the H4's rigid configurations lifted
        (:meth:`configuration`): ``compliance(q, {}, ["D"], locked=em.locked)`` and :meth:`modes`
        give the elastic model's numbers through the generic calls. (Nothing of the H4 is
        imported here: ``em`` gives its own mass model.)"""
        if not all(hasattr(em, a) for a in ("mass_model", "constraint_models", "locked", "stiffness", "q_index")):
            raise ParameterError(f"em: an h4pin.elastic.ElasticH4 (h4pin.elastic_model(h4)), got {type(em).__name__}")
        mech = cls(em.mass_model(), em.constraint_models, em.locked, name="elastic H4")
        object.__setattr__(mech, "beam_springs", dict(em.stiffness))
        object.__setattr__(mech, "_lift", (np.asarray(em.q_index), len(em.q_index)))
        return mech

    @classmethod
    def from_mjcf(cls, path: str | Path, *, actuated: Iterable[Any] | None = None) -> Mechanism:
        """An MJCF file as MuJoCo means it: the tree and its ``connect``/``weld`` equalities as
        closures (Pinocchio 4's reader; a body's several joints, which that reader merges into
        one composite joint, are split back into the file's joints, each with its name; a fixed
        root body's placement on the world, which it drops, put back), its ``<equality><joint>``
        couplings as :attr:`couplings` (:class:`~h4pin.mechanism.couplings.JointCoupling`), the
        joints of its ``<actuator>`` elements as the motors (or ``actuated``), and from MuJoCo's
        own compiler: the reference configuration (the first keyframe, else ``qpos0``: each
        joint's ``ref``), the joints' ranges as the file states them, the joints' ``stiffness``
        as :attr:`springs` (``springref``: :attr:`spring_rest`), and every body's mass, centre of
        mass and inertia. Pinocchio's configuration is MuJoCo's ``qpos`` (a ball's or free
        joint's quaternion reordered); world positions are MuJoCo's (``xpos``, ``site_xpos``).

        Raises:
            MissingExtraError: Pinocchio < 4 (its MJCF reader gives no closures), or MuJoCo is
                not installed (the ``mujoco`` extra).
            MalformedURDFError: MuJoCo or Pinocchio cannot read the file (its message), the
                readers disagree on the closures, or a file value h4pin would drop (a negative or
                non-finite joint ``stiffness`` or ``springref``, a ``range`` not finite or
                reversed, a first keyframe's ``qpos`` of another length than the model's): the
                element and attribute named.
            UnsupportedFeatureError: tendon equalities, an actuator not on a joint (unless
                ``actuated`` is given), a second body with joints on the world (Pinocchio's reader
                reads one tree), a body the two readers place differently: refused by name, never
                dropped.
            ParameterError: a motor on a joint the model lacks.
        """
        from h4pin.mechanism import mjcf_reader

        model, cms, info = mjcf_reader.read(path)
        if info.refused and actuated is None:
            raise UnsupportedFeatureError(f"{path}: actuator(s) {', '.join(map(repr, info.refused[:4]))} drive no "
                                          "joint (tendon, site or body transmission); give the motor joints with "
                                          "actuated=...")
        motors = info.motors if actuated is None else actuated
        mech = cls(model, cms, motors, name=info.name, reference=info.reference, ranges=info.ranges,
                   springs=info.springs, couplings=info.couplings)
        object.__setattr__(mech, "spring_rest", info.spring_rest)
        return mech

    def with_beams(self, beams: Mapping[str, Any]) -> Mechanism:
        """A new mechanism whose links ``{link name: h4pin.mechanism.Beam}`` are flexible: each
        beam's six virtual joints (:mod:`h4pin.mechanism.beams`: the virtual joint method, exact for
        an Euler-Bernoulli cantilever from the link's joint to its far end) inserted, with their
        springs in :attr:`beam_springs`, added to every :meth:`compliance` and :meth:`modes`
        call. A configuration of this (rigid) mechanism is accepted as it is (the virtual joints
        at 0); so are its closures, motors, ranges and couplings.

        Raises:
            ParameterError: not a mapping of link names to beams, an unknown link, a link with no
                far end or several without ``to``.
        """
        return _with_beams(self, beams)

    def with_model(self, model: pin.Model) -> Mechanism:
        """The same mechanism (closures, motors, springs, beams, ranges) on ``model``: the same
        tree, with other joint placements, frames or inertias (a calibrated robot, say)."""
        return on_model(self, model)

    def to_mjcf(self, path: str | Path, springs: Mapping[Any, Any], q: Any = None, **options: Any) -> Path:
        """Write an elastic MuJoCo model, the springs as joint stiffness at rest at q (default
        :meth:`assemble`): :func:`h4pin.mechanism.mjcf_writer.write` (options, file, errors)."""
        from h4pin.mechanism import mjcf_writer

        return mjcf_writer.write(self, path, springs, q, **options)

    # ------------------------------------------------------------------ geometry
    def configuration(self, q: Any, what: str = "q") -> np.ndarray:
        """``q`` checked as a configuration (nq,) of this mechanism (finite, the right size, unit
        quaternions), a new array; for a mechanism with beams (:meth:`with_beams`), a
        configuration of the rigid mechanism is accepted too, its beams' joints at 0.

        Raises:
            ParameterError: not such a configuration (``what`` names it)."""
        lift = self._lift
        if lift is not None and np.shape(q) == (lift[1],):
            return self.lift(finite_configuration(q, lift[1], what))
        return model_configuration(self.model, q, what)

    def lift(self, q: np.ndarray) -> np.ndarray:
        """Configurations of the rigid mechanism, (..., rigid nq), as this mechanism's with beams,
        (..., nq), each beam joint at 0; anything else (this mechanism's own, or no beams) as it
        is."""
        lift = self._lift
        if lift is None or np.shape(q)[-1:] != (lift[1],):
            return q
        full = np.zeros((*np.shape(q)[:-1], self.model.nq))
        full[..., lift[0]] = q
        return full

    def closure_errors(self, q: Any) -> dict[str, tuple[float, float]]:
        """``{closure: (translation error m, rotation error rad)}`` at q (rotation 0 for 3-D)."""
        q = self.configuration(q)
        d = self.data
        pin.forwardKinematics(self.model, d, q)
        out = {}
        for cm in self.constraint_models:
            cd = cm.createData()
            constraint_calc(cm, self.model, d, cd)
            out[cm.name] = engine.closure_residual(cm, cd)
        for c in self.couplings:
            out[f"coupling {c.joint1}"] = (abs(c.residual_row(self.model, q)[0]), 0.0)
        return out

    def assemble(self, q: Any = None, *, motors: Any = None, fixed: Iterable[Any] | None = None,
                 tol: float = assembly.ASSEMBLY_TOL, iterations: int = 100) -> np.ndarray:
        """A configuration with every closure closed (within ``tol`` m, and rad for 6-D
        closures), from ``q`` (default :attr:`reference`, the file's) with the joints ``fixed``
        (default the actuated ones) held, every other one-coordinate joint kept in its range.
        ``motors``: (n_act,) or (N, n_act) motor positions in :attr:`actuated` order (rad, m)
        give (nq,) or (N, nq) configurations with the motors there, each closed from the one
        before (continuation: order a grid so that neighbours follow each other); an error names
        the first that does not close.

        The solver is a bounded trust-region least-squares (scipy's ``least_squares``, method
        ``trf``) on the closures' residuals, then Gauss-Newton to ``tol``. When ``fixed`` is not
        given and the loops cannot close with the motors held, the motors are freed too: the
        configuration nearest the start that the solver reaches, with a
        :class:`~h4pin.errors.MechanismWarning` saying how far each motor moved.

        Raises:
            UnassembledError: it does not close (names the worst closure and its error), or a
                held joint is outside its range (names it).
            ParameterError: a bad q, joint, tol or iterations.
        """
        return assembly.assemble(self, q, motors, fixed, tol, iterations)

    # ------------------------------------------------------------------ stiffness
    def compliance(self, q: Any, springs: Mapping[Any, Any], outputs: Sequence[Any],
                   locked: Iterable[Any] = (), *, free_root: bool = False, method: str = "auto",
                   threads: int | None = None) -> np.ndarray:
        """The (6 n, 6 n) compliance of n output frames at an assembled q (nq,), or (N, 6 n, 6 n)
        at each of a batch Q (N, nq): force at each frame's origin and torque, world axes
        (``dy = C w``, m/N, rad/(N.m)); ``springs``: ``{joint: stiffness}`` (N.m/rad, N/m; a
        scalar for every coordinate of a multi-coordinate joint, or one value each), joints
        without a spring free, ``locked`` held, and a free-flyer root (:attr:`free_flyers`)
        held unless ``free_root`` or it has a spring (:func:`h4pin.mechanism.engine.compliance_matrix`).
        ``method``: ``auto``, ``compiled`` or ``pinocchio`` (:mod:`h4pin.mechanism.batch`: the
        compiled generic path, equal to the Pinocchio route to round-off); ``threads``: for a
        batch (default one per core).

        Raises:
            ParameterError: an unknown joint or frame, a bad stiffness or q.
            UnassembledError: a closure does not hold at q (its name and error; for a batch, the
                first such configuration's index).
            UnrestrainedMotionError: a motion strains no spring (the joints it moves).
            TooLargeError: a batch over the memory or time limit.
        """
        stiff = springs_of(self, springs)
        lock = locked_of(self, locked, stiff, free_root)
        outs = outputs_of(self, outputs)
        method, threads = check_choice(method, batch.METHODS, "method"), batch.check_threads(threads)
        Q, one = batch.configurations(self, q)
        out = batch.compliance(self, Q, one, stiff, outs, lock, method, threads)
        return out[0] if one else out

    def modes(self, q: Any, springs: Mapping[Any, Any], locked: Iterable[Any] = (), *,
              payload: tuple[str, Any] | None = None, free_root: bool = False, method: str = "auto",
              threads: int | None = None) -> Modes:
        """Undamped natural modes at an assembled q (nq,), or the frequencies at each of a batch
        Q (N, nq), with the model's inertias, the springs and the locked joints of
        :meth:`compliance` (a free-flyer root held unless ``free_root``), and an optional
        ``payload``: ``(frame, h4pin.mechanism.Payload)`` fixed to that frame (its com and inertia in
        the frame's axes). Massless directions are condensed statically
        (:func:`h4pin.elastic.modal.undamped_modes`). One configuration gives the shapes too (the
        Pinocchio route); a batch gives frequencies (N, m) (``method`` and ``threads`` as in
        :meth:`compliance`); :attr:`Modes.first <h4pin.mechanism.engine.Modes>` is the first frequency.

        Raises:
            as :meth:`compliance`; ParameterError: nothing has mass.
        """
        stiff = springs_of(self, springs)
        lock = locked_of(self, locked, stiff, free_root)
        method, threads = check_choice(method, batch.METHODS, "method"), batch.check_threads(threads)
        Q, one = batch.configurations(self, q)
        if one:
            return _modes_one(self, Q[0], stiff, lock, payload)
        freq = batch.frequencies(self, Q, stiff, lock, payload, method, threads,
                                 lambda x: _modes_one(self, x, stiff, lock, payload).frequencies)
        return Modes(freq, np.sum(np.isfinite(freq), axis=1), np.zeros(len(freq), dtype=np.int8), payload)


def _modes_one(mech: Mechanism, q: np.ndarray, stiff: dict[str, Any], lock: tuple[str, ...],
               payload: Any) -> Modes:
    """:meth:`Mechanism.modes` at one configuration, by the Pinocchio route."""
    model, d = mech.model, mech.data
    k = engine.stiffness_vector(model, stiff)
    pin.computeJointJacobians(model, d, q)
    batch.check_couplings(mech, q)
    n = admissible_basis(model, mech.constraint_models, q, lock, k, d, batch.coupling_rows(mech, q))
    mass = pin.crba(model, d, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    pay = batch.payload_inertia(model, payload)
    if pay is not None:
        jf = pin.getJointJacobian(model, d, pay[0], pin.LOCAL)
        mass = mass + jf.T @ pay[1].matrix() @ jf
    freq, shapes, massless = undamped_modes(n, k, mass)
    return Modes(freq, len(freq), 0, payload, None, (None, shapes), massless)


def _file_data(model: pin.Model, closures: Any, reference: Any, ranges: Any, springs: Any,
               couplings: Iterable[Any]) -> dict[str, Any]:
    """The checked file data of a :class:`Mechanism` (its constructor's keywords), and its
    free-flyer roots."""
    ref = pin.neutral(model) if reference is None else model_configuration(model, reference, "reference")
    ref.setflags(write=False)
    lo, hi = _urdf_ranges(model) if ranges is None else (np.array(r, dtype=float) for r in ranges)
    if lo.shape != (model.nq,) or hi.shape != (model.nq,) or np.any(lo > hi):
        raise ParameterError(f"ranges: (lower, upper), each ({model.nq},) with lower <= upper (nan: none)")
    for r in (lo, hi):
        r.setflags(write=False)
    stiff = {} if springs is None else dict(springs)
    if stiff:
        stiff = dict(zip(joint_names(model, list(stiff), "springs"), stiff.values(), strict=True))
        engine.stiffness_vector(model, stiff)  # checked now
    cps = tuple(couplings)
    for c in cps:
        if not isinstance(c, JointCoupling):
            raise ParameterError(f"couplings: JointCoupling values, got {c!r}")
        joint_names(model, [c.joint1] + ([c.joint2] if c.joint2 is not None else []), "couplings")
        c.residual_row(model, pin.neutral(model))
    roots = tuple(model.names[j] for j in range(1, model.njoints)
                  if model.parents[j] == 0 and model.joints[j].shortname() == "JointModelFreeFlyer"
                  and not _tied(model, closures, j))
    return {"reference": ref, "ranges": (lo, hi), "springs": stiff, "spring_rest": {}, "couplings": cps,
            "beam_springs": {}, "_lift": None, "free_flyers": roots}


def _with_beams(mech: Mechanism, beams: Mapping[str, Any]) -> Mechanism:
    """:meth:`Mechanism.with_beams`."""
    from h4pin.mechanism import beams as bm

    if not isinstance(beams, Mapping) or not beams:
        raise ParameterError(f"beams: a mapping {{link name: h4pin.mechanism.Beam}}, got {beams!r}")
    d = mech.model.createData()
    pin.framesForwardKinematics(mech.model, d, mech.reference)
    ins = [bm.insertion(mech.model, d, mech.constraint_models, link, beam) for link, beam in beams.items()]
    parents = [i.parent for i in ins]
    if len(set(parents)) != len(parents):
        raise ParameterError("beams: two links on one joint; one beam per joint")
    return inserted(mech, ins, f"{mech.name} with beams")


def _from_urdf(cls: Any, urdf_path: Any, sidecar: Any, actuated: Any, free_flyer: bool) -> Mechanism:
    """:meth:`Mechanism.from_urdf`."""
    from h4pin.mechanism import sidecar as sc

    if not isinstance(free_flyer, bool):
        raise ParameterError(f"free_flyer: True or False, got {free_flyer!r}")
    urdf_path = Path(urdf_path)
    side = sc.read(urdf_path.with_suffix(".yaml") if sidecar is None else sidecar)
    model, cms = sc.build(urdf_path, side, free_flyer=free_flyer)
    if side.gravity is not None:
        model.gravity = pin.Motion(np.array(side.gravity), np.zeros(3))
    motors = side.motors if actuated is None else actuated
    try:
        names = joint_names(model, motors, f"{side.path}: name_mot")
    except ParameterError as exc:
        raise MalformedURDFError(str(exc)) from None
    ranges = _urdf_ranges(model)
    try:
        springs = {n: k for n, k in side.springs.items() if n not in side.elastic}
        mech = cls(model, cms, names, name=model.name or urdf_path.stem, reference=pin.neutral(model),
                   ranges=ranges, springs=springs or None)
        if side.elastic:
            joint_names(model, side.elastic, "elastic")
            object.__setattr__(mech, "beam_springs", {n: side.springs[n] for n in side.elastic})
    except ParameterError as exc:
        raise MalformedURDFError(f"{side.path}: {exc}") from None
    if side.beams:
        try:
            return mech.with_beams(side.beams)
        except ParameterError as exc:
            raise MalformedURDFError(f"{side.path}: beams: {exc}") from None
    return mech


def inserted(mech: Mechanism, insertions: Sequence[Any], name: str, internal: bool = True) -> Mechanism:
    """A new mechanism with the chains of virtual joints ``insertions``
    (:func:`h4pin.mechanism.engine.insert_joints`) at the reference configuration, its closures,
    motors, ranges, springs and couplings carried over; a configuration of ``mech`` is accepted as it
    is (the new joints at 0). ``internal``: the new joints' springs are the mechanism's own
    (:attr:`Mechanism.beam_springs`, held in a rigid assembly), as a beam's."""
    model = mech.model
    new_model, new_cms, q_index = engine.insert_joints(model, insertions, mech.constraint_models, mech.reference)
    lift = np.zeros(new_model.nq)
    lift[q_index] = mech.reference
    lo, hi = (np.full(new_model.nq, np.nan) for _ in range(2))
    lo[q_index], hi[q_index] = mech.ranges
    out = Mechanism(new_model, new_cms, mech.actuated, name=name, reference=lift, ranges=(lo, hi),
                    springs=mech.springs, couplings=mech.couplings)
    own = {j.name: j.stiffness for i in insertions for j in i.joints if math.isfinite(j.stiffness)}
    object.__setattr__(out, "beam_springs", {**mech.beam_springs, **own} if internal else dict(mech.beam_springs))
    previous = mech._lift
    index = np.asarray(q_index) if previous is None else np.asarray(q_index)[previous[0]]
    object.__setattr__(out, "_lift", (index, model.nq if previous is None else previous[1]))
    object.__setattr__(out, "spring_rest", dict(mech.spring_rest))
    return out


def on_model(mech: Mechanism, model: pin.Model) -> Mechanism:
    """:meth:`Mechanism.with_model`."""
    if not isinstance(model, pin.Model) or model.njoints != mech.model.njoints or list(model.names) != list(
            mech.model.names) or any(a.shortname() != b.shortname() for a, b in zip(model.joints, mech.model.joints,
                                                                                     strict=True)):
        raise ParameterError("model: the same tree as the mechanism's (its joints, names and kinds), other "
                             "placements or inertias")
    out = object.__new__(Mechanism)
    out.__dict__.update(mech.__dict__)
    object.__setattr__(out, "model", pin.Model(model))
    object.__setattr__(out, "_local", threading.local())
    return out


__all__ = ["Mechanism"]
