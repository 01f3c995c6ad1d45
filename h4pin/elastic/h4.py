# SPDX-License-Identifier: Apache-2.0
"""The H4 as an elastic closed-loop Pinocchio model: :func:`elastic_model`.

Every compliance of eq. 30, and every optional element the robot carries
(:attr:`H4.elements <h4pin.H4>`), becomes virtual joints with springs inserted into a copy of the
robot's own ``pin.Model`` (:func:`h4pin.mechanism.engine.insert_joints`); the eight closures are
re-created on the new model. :func:`h4pin.mechanism.engine.compliance_matrix` then gives K from Pinocchio's
closure and frame Jacobians alone, with the four actuators locked: nothing of the paper's
matrices or of :mod:`h4pin.stiffness` is used, only the spring data (read from
:attr:`H4.geometry <h4pin.H4>` and :attr:`H4.elements <h4pin.H4>`).

The virtual joints (world axes and points at the model's neutral configuration, where they read 0):

* ``actuator_i_elastic``: revolute about u_i through P_i, in series with actuator i, compliance
  ``1/kc + phi^3 r/(3 E I)`` (the actuator and the forearm's bending, eq. 30's rotation of the
  forearm about u_i); ``forearm_i_torsion``: revolute about the forearm axis P_i -> A_i through
  A_i, compliance ``phi r/(G I0)``; both carry the forearm tip (A_i1, A_i2 and the universal joints);
* ``bar_ij_tension``: prismatic along bar ij, compliance ``l/(Sb Eb)``; the closure's bar side
  moves to its end;
* elements, each only when on: ``bar_ij_ball_A``, ``bar_ij_ball_B`` (prismatic along the bar,
  ``ball_radial`` each); ``lateral_k_radial_a``, ``_b`` (prismatic normal to v_k),
  ``lateral_k_axial`` (prismatic along v_k), ``lateral_k_tilt_a``, ``_b`` (revolutes about the
  normals through C_k), between the central bar and the revolute of lateral bar k;
  ``shaft_i_tilt_a``, ``_b`` (revolutes about the normals to u_i through P_i) and
  ``mount_i_x``, ``_y``, ``_z`` (prismatic) and ``mount_i_rx``, ``_ry``, ``_rz`` (revolutes
  through P_i) between the base and actuator i; beams (``central_k_*`` on segment D-C_k,
  ``arm_i_*`` on lateral bar k's arm C_k-B_i, whose tip carries B_i1, B_i2): torsion, a revolute
  about the beam axis, ``L/(GJ)``; bending, revolutes about the two normals at the two Gauss points
  ``L/2 -+ L/(2 sqrt 3)`` from the root, ``L/(2 EI)`` each, which gives the Euler-Bernoulli
  cantilever's tip compliance exactly (the two-point Gauss rule integrates ``(L - x)^2`` exactly);
  ``forearm_i_out_1``, ``_2``: forearm i bending out of its plane (``forearm_out_EI``), revolutes
  about e x u_i (e the forearm's axis) at the two Gauss points of P_i-A_i, ``r/(2 EI)`` each,
  beside the forearm's other virtual joints.

Outputs: frame D (LOCAL_WORLD_ALIGNED, the 6 rows) and the two lateral revolutes (signed so that
omega_k is right-handed about v_k with v_k . z > 0), i.e. ``dtp = [dD, dOmega, domega_1, domega_2]``
and ``Gamma_ext = [F, T, t1, t2]`` as :func:`h4pin.compliance`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
import weakref
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.description.elements import ELASTIC_SUFFIXES, Kind
from h4pin.kinematics import pinocchio as kin
from h4pin.mechanism import engine
from h4pin.mechanism.engine import FrameOutput, Insertion, JointOutput, Output, VirtualJoint

_GAUSS = (0.5 - 0.5 / math.sqrt(3.0), 0.5 + 0.5 / math.sqrt(3.0))


def _normals(axis: np.ndarray) -> np.ndarray:
    """(2, 3): two orthonormal vectors normal to the unit ``axis``."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(axis, e1)])


def _element_joints(kind: Kind, s: int, c: float, point: np.ndarray, vec: np.ndarray, normal: np.ndarray
                    ) -> list[VirtualJoint]:
    """The virtual joints of element s of a schema row (its compliance c, the row's ``series``
    included), in its form (:data:`h4pin.description.elements.ELASTIC_SUFFIXES`): at its site's
    ``point``, its axis ``vec`` from its root to that point (a beam's length), its second axis
    ``normal``. A 6-D spring: three prismatic or revolute joints along or about x, y, z; normal to
    or along the axis: one joint along or about each normal, or the axis; a beam: torsion, a
    revolute about the axis, ``L/(GJ)``; bending, revolutes about the normals (out of plane:
    about axis x normal) at the two Gauss points ``L/2 -+ L/(2 sqrt 3)`` from the root, ``L/(2
    EI)`` each, which gives the Euler-Bernoulli cantilever's tip compliance exactly (the
    two-point Gauss rule integrates ``(L - x)^2`` exactly). Elements in series: one joint each."""
    form, length = kind.form, float(np.linalg.norm(vec))
    e = vec / length
    root = point - vec
    normals = _normals(e)
    if form in ("force", "couple"):
        parts = [(d, point, c) for d in np.eye(3)]
    elif form.endswith("_normal"):
        parts = [(n, point, c) for n in normals]
    elif form.endswith("_axial"):
        parts = [(e, point, c)]
    elif form == "beam_torsion":
        parts = [(e, root, c * length)]
    else:  # bending about the normals (out of plane: about e x normal) at the Gauss points
        about = normals if form == "beam_bending" else [np.cross(e, normal)]
        parts = [(n, root + x * vec, 0.5 * c * length) for x in _GAUSS for n in about]
    joint = "prismatic" if form.startswith("force") else "revolute"
    name = kind.elastic.format(s=kind.label(s))
    chain = [f"_{'AB'[r]}" if kind.series > 1 else "" for r in range(kind.series)]
    return [VirtualJoint(f"{name}{suffix}{tail}", joint, axis, at, kind.series / comp)
            for suffix, (axis, at, comp) in zip(ELASTIC_SUFFIXES[form], parts, strict=True) for tail in chain]


def _elements(h4, at: Callable[[str], np.ndarray], ends: list[np.ndarray]) -> dict[str, list[list[VirtualJoint]]]:
    """The virtual joints of the robot's elements that are on, per site and element, from their
    schema rows (the model's neutral configuration: ``at(frame)`` a frame's position there,
    ``ends`` the bars' plate ends)."""
    g = h4.geometry
    z = np.array([0.0, 0.0, 1.0])
    d = at("D")
    c = [at(f"C_{k + 1}") for k in range(2)]
    b = [0.5 * (at(f"B_{i + 1}1") + at(f"B_{i + 1}2")) for i in range(4)]
    points = {"joint": c, "arm": b, "mount": list(g.P), "tip": list(g.A0_leg), "bar": ends}
    axes = {"none": [z] * 8, "z": [z] * 8, "revolute": list(g.v), "actuator": list(g.u),
            "central": [ck - d for ck in c], "arm": [b[i] - c[int(g.leg_lat[i])] for i in range(4)],
            "forearm": [g.A0_leg[i] - g.P[i] for i in range(4)], "bar": [ends[n] - g.A0[n] for n in range(8)]}
    out: dict[str, list[list[VirtualJoint]]] = {site: [[] for _ in points[site]] for site in points}
    for k in h4.elements.kinds_on():
        comp = k.compliance(getattr(h4.elements, k.name))
        for s in np.flatnonzero(comp):
            out[k.site][s] += _element_joints(k, int(s), float(comp[s]), points[k.site][s], axes[k.axis][s],
                                              axes[k.normal][s])
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class ElasticH4:
    """An H4 whose compliances are virtual elastic joints (:func:`elastic_model`); immutable.

    Attributes:
        robot: the :class:`h4pin.H4` it was built from.
        model: the elastic ``pin.Model`` (shared; never changed).
        constraint_models: its 8 closures (``pin.StdVec_RigidConstraintModel``, CONTACT_3D).
        stiffness: ``{elastic joint name: stiffness}`` (N.m/rad or N/m), read-only.
        locked: the four actuated joints.
        outputs: D (6 rows) and the two lateral revolutes.
        q_index: (robot nq,) where each coordinate of the robot's configuration sits in the
            elastic model's.
        data: the calling thread's own ``pin.Data`` of :attr:`model` (one per thread).
    """

    robot: Any
    model: pin.Model
    constraint_models: Any
    stiffness: Mapping[str, float]
    locked: tuple[str, ...]
    outputs: tuple[Output, ...]
    q_index: np.ndarray
    _local: threading.local = dataclasses.field(default_factory=threading.local, repr=False)

    @property
    def data(self) -> pin.Data:
        """The calling thread's own ``pin.Data`` of :attr:`model`, made on first use (Pinocchio
        takes tens of ms to make one for this model, so it is kept, one per thread)."""
        d = getattr(self._local, "data", None)
        if d is None:
            d = self._local.data = self.model.createData()
        return d

    @functools.cached_property
    def mechanism(self) -> Any:
        """The elastic H4 as a :class:`~h4pin.mechanism.Mechanism` (made on first use, then kept):
        its tree with the inertias of :func:`h4pin.modes`, its 8 closures and its 4 actuators, so
        that every generic route takes the H4: ``em.mechanism.compliance(q, em.stiffness, ["D"])``
        (the actuators held as motors without a spring), ``.modes``, ``.to_mjcf``,
        :func:`h4pin.mechanism.atlas.atlas`, the scene."""
        from h4pin.mechanism import Mechanism

        return Mechanism.from_elastic(self)

    def mass_model(self, link_inertias: bool = True) -> pin.Model:
        """The model with the inertias of its natural modes (:func:`mass_model`)."""
        return mass_model(self, link_inertias)

    @property
    def elastic_joints(self) -> tuple[str, ...]:
        """Names of the elastic joints, in insertion order."""
        return tuple(self.stiffness)

    def configuration(self, pose: np.ndarray) -> np.ndarray:
        """(nq,) the elastic model's configuration at a rigid pose [x, y, z, theta] (m, rad): the
        robot's assembled one (:meth:`h4pin.H4.configuration`), every virtual joint at 0.

        Raises:
            UnreachablePoseError (and subclasses): as :meth:`h4pin.H4.configuration`.
        """
        q = np.zeros(self.model.nq)
        q[self.q_index] = kin.configuration(self.robot, pose)
        return q

    def compliance_matrix(self, pose: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """K (8, 8) at a pose (4,): ``dtp = K Gamma_ext``, dtp = [dD, dOmega, domega_1, domega_2]
        (m, rad), Gamma_ext = [F at D, T, t1, t2] (N, N.m), world axes (as :func:`h4pin.compliance`).

        Args:
            pose: [x, y, z, theta] (m, rad).
            data: a ``pin.Data`` of :attr:`model` to work in (default: the calling thread's own,
                :attr:`data`).

        Raises:
            UnreachablePoseError (and subclasses): the robot cannot take the pose.
            UnrestrainedMotionError: the pose is singular (a motion strains no spring).
        """
        return engine.compliance_matrix(self.model, self.constraint_models, self.configuration(pose),
                                        locked=self.locked, stiffness=self.stiffness, outputs=self.outputs,
                                        data=self.data if data is None else data)


def elastic_model(h4) -> ElasticH4:
    """The elastic model of an H4 (module docstring), with its own elements (``h4.elements``).

    Args:
        h4: the robot (:func:`h4pin.load`; ``load(..., elements=...)`` for other elements).

    Returns:
        An :class:`ElasticH4`; ``elastic_model(h4).compliance_matrix(pose)`` equals
        ``h4pin.compliance(h4, pose, model="consistent").matrix``.

    Raises:
        ParameterError: ``h4`` is not an :class:`h4pin.H4`.
    """
    from h4pin.inputs import check_instance
    from h4pin.robot import H4

    check_instance(h4, H4, "h4", "an h4pin.H4 (from h4pin.load)")  # the door (issue 30)
    m, g, ix = h4.model, h4.geometry, h4.index
    d = m.createData()
    pin.framesForwardKinematics(m, d, pin.neutral(m))

    def at(name: str) -> np.ndarray:
        return d.oMf[m.getFrameId(name)].translation.copy()

    def frames(*names: str) -> tuple[str, ...]:  # the named frames and their fixed joints' frames
        return tuple(f for n in names for f in (n, f"{n}_frame") if m.existFrame(f))

    s = g.springs
    phi = s["forearm_stressed_fraction"]
    c_act = 1.0 / s["kc"] + phi**3 * g.r / (3.0 * s["E"] * s["I"])
    c_tors = phi * g.r / (s["G"] * s["I0"])
    c_tens = g.l / (s["Sb"] * s["Eb"])
    cms = h4.constraint_models
    ends = [(d.oMi[cm.joint1_id] * cm.joint1_placement).translation.copy() for cm in cms]
    extra = _elements(h4, at, ends)
    insertions = []
    for i in range(4):
        act, p, u = h4.actuated_joint_names[i], g.P[i], g.u[i]
        insertions.append(Insertion("universe", tuple(extra["mount"][i]), children=(act,)))
        tip = g.A0_leg[i]
        forearm = (VirtualJoint(f"actuator_{i + 1}_elastic", "revolute", u, p, 1.0 / c_act[i]),
                   VirtualJoint(f"forearm_{i + 1}_torsion", "revolute", tip - p, tip, 1.0 / c_tors[i]),
                   *extra["tip"][i])
        universal = tuple(m.names[m.parents[cms[2 * i + j].joint1_id]] for j in range(2))
        insertions.append(Insertion(act, forearm, children=universal,
                                    frames=frames(f"A_{i + 1}", f"A_{i + 1}1", f"A_{i + 1}2")))
    for n, cm in enumerate(cms):
        end = ends[n]
        bar = (VirtualJoint(f"bar_{n // 2 + 1}{n % 2 + 1}_tension", "prismatic", end - g.A0[n], end, 1.0 / c_tens[n]),
               *extra["bar"][n])
        on_end = tuple(f.name for fid, f in enumerate(m.frames) if f.parentJoint == cm.joint1_id
                       and np.linalg.norm(d.oMf[fid].translation - end) < 1e-12)
        insertions.append(Insertion(m.names[cm.joint1_id], bar, frames=on_end, closures=((n, 1),)))
    central = m.names[m.parents[ix.jid_lat[0]]]
    for k in range(2):
        insertions.append(Insertion(central, tuple(extra["joint"][k]), children=(m.names[ix.jid_lat[k]],)))
    for i in range(4):
        k = int(g.leg_lat[i])
        names = (f"B_{i + 1}1", f"B_{i + 1}2")
        insertions.append(Insertion(m.names[ix.jid_lat[k]], tuple(extra["arm"][i]),
                                    frames=frames(f"B_{i + 1}", *names), closures=((2 * i, 2), (2 * i + 1, 2))))
    model, closures, q_index = engine.insert_joints(m, insertions, cms)
    stiffness = {v.name: float(v.stiffness) for ins in insertions for v in ins.joints if math.isfinite(v.stiffness)}
    outputs = (FrameOutput("D"), *(JointOutput(m.names[ix.jid_lat[k]], float(ix.lat_sign[k])) for k in range(2)))
    q_index.setflags(write=False)
    return ElasticH4(h4, model, closures, MappingProxyType(stiffness), tuple(h4.actuated_joint_names), outputs,
                     q_index)



_MASS_MODELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def mass_model(em: ElasticH4, link_inertias: bool = True) -> pin.Model:
    """The elastic model with the inertias its natural modes use (:func:`h4pin.elastic.modal.modes`;
    a cached copy; never change it).

    ``link_inertias=True``: the URDF's, with each locked actuator's body moved onto its
    ``<actuator>_elastic`` joint (the forearm turns with the actuator's spring). ``False``: every
    link massless (only a payload has mass).
    """
    models = _MASS_MODELS.setdefault(em, {})
    if link_inertias not in models:
        m = pin.Model(em.model)
        for j in range(1, m.njoints):
            if not link_inertias:
                m.inertias[j] = pin.Inertia.Zero()
        if link_inertias:
            for name in em.locked:
                spring = f"{name}_elastic"
                if name in em.stiffness or not m.existJointName(spring):
                    continue
                j, je = m.getJointId(name), m.getJointId(spring)
                if m.parents[je] != j:
                    continue
                # at the assembled configuration the virtual joint reads 0: jMje = jointPlacements[je]
                m.inertias[je] = m.inertias[je] + m.jointPlacements[je].actInv(m.inertias[j])
                m.inertias[j] = pin.Inertia.Zero()
        models[link_inertias] = m
    return models[link_inertias]


__all__ = ["ElasticH4", "elastic_model", "mass_model"]
