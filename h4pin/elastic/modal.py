# SPDX-License-Identifier: Apache-2.0
"""Natural frequencies and mode shapes of the elastic H4 at a pose: :func:`modes`.

The mechanism is the elastic H4 of :func:`h4pin.elastic.elastic_model` (every compliance a
virtual elastic joint, the four actuators locked), with the inertia of every link from the robot's
URDF (Pinocchio's ``model.inertias``) and an optional rigid :class:`Payload` fixed to the central
bar. At the assembled configuration q of a rigid pose:

1. the admissible small motions are ``dq = N z``, N a basis of the null space of the closure
   Jacobian stacked on the locked rows (as :func:`h4pin.elastic.engine.compliance_matrix`; the same
   scaling, rank and singularity decisions);
2. stiffness ``Kz = N^T Ke N`` (the springs, Ke diagonal); mass ``Mz = N^T M N``, with M the joint
   space inertia matrix of ``pin.crba`` plus the payload's ``J_D^T I_p J_D`` (I_p its 6x6 spatial
   inertia in frame D, J_D the LOCAL Jacobian of frame D);
3. massless motions (virtual joints carry no mass, and a spring in series with another leaves a
   motion that moves no mass) are **condensed statically**: with ``Mz = V diag(mu) V^T``, the
   directions of ``mu <= MASSLESS_TOL * max(mu)`` are massless (index s), the others massive
   (index m), and ``K* = Kmm - Kms Kss^-1 Ksm`` (the massless coordinates follow the massive ones
   in static equilibrium, ``z_s = -Kss^-1 Ksm z_m``); ``M* = diag(mu_m)``;
4. the undamped modes solve ``K* a = lambda M* a``; the frequencies are ``sqrt(lambda) / (2 pi)``
   (Hz). A shape is the full motion ``dq = N (V_m a + V_s z_s)``, mass-normalised
   (``dq^T M dq = 1``), and the plate's ``dtp = Jo dq`` through the outputs of
   :attr:`ElasticH4.outputs <h4pin.elastic.h4.ElasticH4>` (dtp = [dD, dOmega, domega_1, domega_2]).

Assumptions: small vibrations about the rigid pose (linear), no damping, no preload (no geometric
stiffness, no gravity stiffness), locked actuators (the motor angle is held; its servo stiffness
kc is the ``actuator_i_elastic`` spring), rigid links with the URDF's inertias. The locked
actuator's own body (the forearm) would not move at all on the locked joint, but the forearm turns
with the actuator's elastic rotation (servo and bending lumped into one spring): its inertia is
carried by ``actuator_i_elastic`` (a rigid forearm on that spring). See ``docs/modes.md``.
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin._compat import constraint_calc
from h4pin.elastic import engine
from h4pin.elastic.engine import UnassembledError
from h4pin.elastic.h4 import ElasticH4, elastic_model
from h4pin.errors import ParameterError
from h4pin.kinematics.closed_form import as_pose

#: Eigenvalue of the scaled modal mass ``Mz`` (relative to its largest) at or under which a
#: direction is massless and condensed statically.
MASSLESS_TOL = 1e-12
#: Length (m) that turns the rotations of dtp into lengths when the sign of a shape is chosen.
_SIGN_LENGTH = 0.1


@dataclasses.dataclass(frozen=True, eq=False)
class Payload:
    """A rigid body fixed to the central bar (the tool and what it carries).

    Attributes:
        mass: kg, >= 0.
        com: (3,) m, its centre of mass from D, in the central bar's axes (frame ``D``: the world
            axes at theta = 0, turned by theta about z).
        inertia: (3, 3) kg.m^2, its inertia tensor about the centre of mass, same axes; symmetric,
            positive semi-definite and obeying the triangle inequalities (0 for a point mass).
    """

    mass: float
    com: Any = (0.0, 0.0, 0.0)
    inertia: Any = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    def __post_init__(self) -> None:
        from h4pin import limits
        from h4pin.inputs import describe, real_array, short

        if isinstance(self.mass, (str, bytes)) or any(isinstance(v, (str, bytes)) for v in
                                                      np.asarray(self.com, dtype=object).reshape(-1)):
            raise ParameterError(f"payload: mass and com must be numbers (kg, m), not text, got {self!r}")
        mass_arr = real_array(self.mass, "payload mass", ParameterError, "a real number (kg)")
        com = real_array(self.com, "payload com", ParameterError, "3 finite numbers (m)").copy()
        inertia = real_array(self.inertia, "payload inertia", ParameterError, "a finite 3x3 matrix (kg.m^2)").copy()
        if mass_arr.shape != ():
            raise ParameterError(f"payload mass must be one number (kg), got {describe(self.mass)}")
        mass = float(mass_arr)
        if not (math.isfinite(mass) and mass >= 0):
            raise ParameterError(f"payload mass must be finite and >= 0 (kg), got {short(self.mass)}")
        if com.shape != (3,) or not np.all(np.isfinite(com)):
            raise ParameterError(f"payload com must be 3 finite numbers (m), got {short(self.com)}")
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
            raise ParameterError(f"payload inertia must be a finite 3x3 matrix (kg.m^2), got {short(self.inertia)}")
        scale = max(float(np.abs(inertia).max()), 1e-300)
        if np.abs(inertia - inertia.T).max() > 1e-12 * scale:
            raise ParameterError(f"payload inertia must be symmetric, got {inertia.tolist()}")
        limits.check_range("payload mass", mass, "payload")
        limits.check_range("payload com", com, "com offset")
        principal = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
        limits.check_range("payload inertia (principal moments)", np.clip(principal, 0.0, None), "payload inertia")
        a, b, c = principal
        if principal[0] < -1e-12 * scale or a + b < c - 1e-12 * scale:
            raise ParameterError("payload inertia must be positive semi-definite and obey the triangle inequality "
                                 f"(principal moments {principal.tolist()} kg.m^2)")
        for name, value in (("mass", mass), ("com", com), ("inertia", 0.5 * (inertia + inertia.T))):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    def spatial(self) -> np.ndarray:
        """(6, 6) its spatial inertia in frame D, Pinocchio's order [linear; angular]
        (kg, kg.m, kg.m^2)."""
        return pin.Inertia(self.mass, self.com, self.inertia).matrix()


@dataclasses.dataclass(frozen=True, eq=False)
class Modes:
    """The undamped modes of the elastic H4 at a pose (:func:`h4pin.modes`), ascending frequency.

    Attributes:
        frequencies: (m,) Hz, ascending; m is the number of massive directions (the admissible
            motions less the massless ones, condensed).
        pose: (4,) the pose [x, y, z, theta] (m, rad).
        payload: the payload, or None.
        massless: how many admissible directions carried no mass and were condensed.
        shapes_tp: (m, 8) each mode's plate motion dtp = [dD (m), dOmega (rad), domega_1,
            domega_2 (rad)] (world axes at D, as :func:`h4pin.compliance`), mass-normalised as
            ``shapes_q``.
        shapes_q: (m, nv) each mode's motion of the elastic model's velocity coordinates,
            mass-normalised: ``shapes_q[i] @ M @ shapes_q[i] = 1`` (M the joint-space inertia
            with the payload); sign: the largest entry of ``shapes_tp`` (rotations times 0.1 m)
            is positive. Both shapes come from this module's Pinocchio route, computed on first
            access when the compiled twin gave the frequencies.
    """

    frequencies: np.ndarray
    pose: np.ndarray
    payload: Payload | None
    massless: int
    shapes: Any = dataclasses.field(default=None, repr=False)  # (shapes_tp, shapes_q), or a callable giving them

    def _shapes(self) -> tuple[np.ndarray, np.ndarray]:
        if callable(self.shapes):
            object.__setattr__(self, "shapes", self.shapes())
        return self.shapes

    @property
    def shapes_tp(self) -> np.ndarray:
        return self._shapes()[0]

    @property
    def shapes_q(self) -> np.ndarray:
        return self._shapes()[1]


_MASS_MODELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def mass_model(em: ElasticH4, link_inertias: bool = True) -> pin.Model:
    """The elastic model with the inertias :func:`modes` uses (a cached copy; never change it).

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


def admissible_basis(model: pin.Model, constraint_models: Any, q: np.ndarray, locked: tuple[str, ...],
                     k: np.ndarray, d: pin.Data, extra_rows: np.ndarray | None = None) -> np.ndarray:
    """N (nv, nz): a basis of the admissible motions ``dq = N z`` in scaled coordinates
    (translations over the length scale), after the engine's closure and singularity checks;
    ``extra_rows`` (r, nv): further constraints (joint couplings). ``pin.computeJointJacobians``
    must have run in ``d`` at q. Used by :meth:`h4pin.elastic.Mechanism.modes` and the elastic
    cycle (:mod:`h4pin.studies.elastic_cycle`)."""
    length = engine.length_scale(model, d)
    cds = [cm.createData() for cm in constraint_models]
    for cm, cd in zip(constraint_models, cds, strict=True):
        constraint_calc(cm, model, d, cd)
        trans, rot = engine.closure_residual(cm, cd)
        if trans > engine.CLOSURE_TOL * length or rot > engine.CLOSURE_TOL:
            raise UnassembledError(f"closure {cm.name!r} does not hold at q: error {trans:.3e} m, {rot:.3e} rad")
    col, row = engine._scaling(model, d, constraint_models, length)
    jc = pin.getConstraintsJacobian(model, d, constraint_models, cds) * row[:, None] * col[None, :]
    lock_idx = np.concatenate([engine._velocity_slice(model, model.getJointId(n)) for n in locked] or
                              [np.zeros(0, dtype=int)])
    lock = np.eye(model.nv)[lock_idx]
    a = np.vstack([jc, lock] + ([] if extra_rows is None else [np.asarray(extra_rows, float) * col[None, :]]))
    frozen = np.vstack([a, np.eye(model.nv)[np.flatnonzero(k)]])
    sv = np.linalg.svd(frozen, compute_uv=False)
    cond = sv[0] / sv[-1] if len(sv) >= model.nv and sv[-1] > 0 else math.inf
    if not cond < engine.SINGULAR_COND:
        raise engine._unrestrained(model, frozen, cond)
    if a.shape[0] == 0:  # no closure, nothing locked: every motion is admissible
        return col[:, None] * np.eye(model.nv)
    _, s, vt = np.linalg.svd(a)
    rank = int(np.sum(s > engine.RANK_TOL * s[0])) if s.size else 0
    return col[:, None] * vt[rank:].T


def undamped_modes(n: np.ndarray, k: np.ndarray, mass: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Frequencies (Hz, ascending), mass-normalised shapes (m, nv) and the number of massless
    directions of the undamped modes of springs ``k`` (nv,) and joint-space inertia ``mass``
    (nv, nv) over the admissible motions ``dq = n z`` (steps 2 to 4 of the module docstring).

    Raises:
        ParameterError: nothing has mass.
    """
    kz = n.T @ (k[:, None] * n)
    mz = n.T @ mass @ n
    mu, v = np.linalg.eigh(0.5 * (mz + mz.T))
    if not mu[-1] > 0:
        raise ParameterError("nothing has mass: give a payload of mass > 0, or keep link_inertias=True")
    heavy = mu > MASSLESS_TOL * mu[-1]
    vm, vs, mum = v[:, heavy], v[:, ~heavy], mu[heavy]
    kmm, kms, kss = vm.T @ kz @ vm, vm.T @ kz @ vs, vs.T @ kz @ vs
    follow = -np.linalg.solve(kss, kms.T) if vs.shape[1] else np.zeros((0, len(mum)))
    kstar = kmm + kms @ follow
    root = np.sqrt(mum)
    lam, y = np.linalg.eigh(kstar / root[:, None] / root[None, :])
    amp = y / root[:, None]
    shapes_q = (n @ (vm @ amp + vs @ (follow @ amp))).T
    return np.sqrt(np.maximum(lam, 0.0)) / (2.0 * math.pi), shapes_q, int(np.count_nonzero(~heavy))


def modes(robot: Any, pose: np.ndarray, payload: Payload | None = None, *, link_inertias: bool = True,
          data: pin.Data | None = None) -> Modes:
    """Natural frequencies and mode shapes of the elastic H4 at a rigid pose (module docstring).

    Args:
        robot: an :class:`h4pin.H4` (its elastic model is built, about 15 ms) or an
            :class:`~h4pin.elastic.h4.ElasticH4` (``h4pin.elastic_model(h4)``, reused: faster for
            many poses; its elements are the robot's).
        pose: [x, y, z, theta] (m, rad).
        payload: a rigid body on the central bar (:class:`Payload`), or None.
        link_inertias: True: the URDF's link inertias (module docstring); False: massless links, so
            that only the payload has mass.
        data: a ``pin.Data`` of the elastic model to work in (default: the calling thread's own,
            :attr:`ElasticH4.data <h4pin.elastic.h4.ElasticH4>`).

    Returns:
        :class:`Modes`: frequencies (m,) Hz ascending, shapes_tp (m, 8), shapes_q (m, nv).

    Raises:
        PoseError, UnreachablePoseError: a bad pose, or one the robot cannot take.
        UnrestrainedMotionError: a singular pose (a motion strains no spring).
        ParameterError: ``payload`` is not a :class:`Payload`, or nothing has mass
            (``link_inertias=False`` without a payload of mass > 0).
    """
    em = robot if isinstance(robot, ElasticH4) else elastic_model(robot)
    if payload is not None and not isinstance(payload, Payload):
        raise ParameterError(f"payload must be an h4pin.elastic.Payload or None, got {type(payload).__name__}")
    x = as_pose(pose).copy()
    mm = mass_model(em, bool(link_inertias))
    d = em.data if data is None else data
    q = em.configuration(x)
    k = engine.stiffness_vector(mm, em.stiffness)
    pin.computeJointJacobians(mm, d, q)
    n = admissible_basis(mm, em.constraint_models, q, em.locked, k, d)
    jo = engine.output_jacobian(mm, d, em.outputs)
    jd = pin.getFrameJacobian(mm, d, mm.getFrameId("D"), pin.LOCAL)  # from data.J, before crba
    mass = pin.crba(mm, d, q)
    mass = np.triu(mass) + np.triu(mass, 1).T  # Pinocchio may fill the upper triangle only
    if payload is not None and payload.mass > 0:
        mass = mass + jd.T @ payload.spatial() @ jd
    freq, shapes_q, massless = undamped_modes(n, k, mass)
    shapes_tp = shapes_q @ jo.T
    sized = shapes_tp * np.r_[np.ones(3), np.full(5, _SIGN_LENGTH)]
    sign = np.sign(sized[np.arange(len(sized)), np.argmax(np.abs(sized), axis=1)])
    sign[sign == 0] = 1.0
    shapes_q *= sign[:, None]
    shapes_tp *= sign[:, None]
    for a in (freq, shapes_tp, shapes_q, x):
        a.setflags(write=False)
    return Modes(freq, x, payload, massless, (shapes_tp, shapes_q))


__all__ = ["MASSLESS_TOL", "Modes", "Payload", "admissible_basis", "mass_model", "modes", "undamped_modes"]
