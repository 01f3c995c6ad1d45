# SPDX-License-Identifier: Apache-2.0
"""Closed-loop stiffness of any Pinocchio model with loop closures, locked joints and elastic joints.

The mechanism is a ``pin.Model`` (a tree) closed by ``pin.RigidConstraintModel`` closures
(``CONTACT_3D`` or ``CONTACT_6D``). Its joints are of three kinds:

* **locked** (the actuators held by their controllers): their velocity is zero;
* **elastic** (a virtual joint that stands for a compliance): a linear spring on each of its
  velocity coordinates, stiffness ``k`` (N.m/rad for a rotation, N/m for a translation);
* **free**: every other joint (the passive joints of the linkage).

:func:`compliance_matrix` gives the compliance of chosen outputs (frames and joints) at an assembled
configuration ``q``. With ``A = [Jc; S_locked]`` the closure Jacobian (Pinocchio's
``getConstraintsJacobian``) stacked on the rows that select the locked velocities, every admissible
small motion is ``dq = N z`` with N a basis of ``null(A)`` (SVD). The springs store
``1/2 dq^T Ke dq`` (Ke diagonal, non-zero on the elastic coordinates only). A generalized load
``w`` on the outputs ``dy = Jo dq`` does the virtual work ``w^T dy``; equilibrium in z reads
``(N^T Ke N) z = N^T Jo^T w``, hence

    ``dy = C w``,  ``C = Jo N (N^T Ke N)^-1 N^T Jo^T``  (symmetric, positive semi-definite).

Assumptions: small deflections about the assembled configuration (first order in the joint
motions); no preload: the springs are at rest at ``q`` and the loads are small, so there is no
geometric stiffness (the term ``d(Jc^T lambda)/dq`` of the closure forces, and the change of the
output map under load, are left out; with a preload it would be added to ``N^T Ke N`` as
``N^T (d(J^T f)/dq) N``); ideal (frictionless, rigid) joints and rigid links, every compliance
being one of the elastic joints; the outputs' loads are the duals of their velocity coordinates
(a LOCAL_WORLD_ALIGNED frame output takes a force at the frame's origin and a torque, world axes;
a joint output its generalized force).

``N^T Ke N`` is invertible exactly when the mechanism with its springs frozen is rigid: no
admissible motion leaves every spring at rest. Otherwise :class:`UnrestrainedMotionError` names
the motion. Rank decisions are made on unit-free matrices: translations are divided by a length
of the mechanism (:func:`length_scale`).

:func:`insert_joints` builds such a model from a rigid one by inserting chains of virtual
revolute and prismatic joints (the H4's is :func:`h4pin.elastic.h4.elastic_model`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin._compat import constraint_calc
from h4pin.errors import ParameterError, SingularPoseError
from h4pin.lookup import frame_id
from h4pin.verdicts import CLOSURE_SINGULAR_COND

#: Relative size (scaled units) under which a singular value of the closure and lock rows is a
#: redundant constraint (for example the z rows of a planar loop closed by a 3-D point contact).
RANK_TOL = 1e-10
#: Closure residual (relative to :func:`length_scale` for translations, rad for rotations) above
#: which ``q`` is not assembled.
CLOSURE_TOL = 1e-9
#: Eigenvalue of the scaled modal mass ``Mz`` (relative to its largest) at or under which a
#: direction is massless and condensed statically (:func:`undamped_modes`).
MASSLESS_TOL = 1e-12


class UnassembledError(ParameterError):
    """The closures do not hold at the configuration given (residual above the tolerance)."""


class UnrestrainedMotionError(SingularPoseError):
    """An admissible motion strains no spring (or nearly none): the compliance is infinite.

    Attributes:
        mode: (nv,) the motion, unit norm in scaled units (translations over the length scale).
        joints: names of the joints that move most in it, largest first.
        cond: the frozen mechanism's scaled condition number (``inf`` when exactly mobile).
    """

    def __init__(self, message: str, mode: np.ndarray, joints: tuple[str, ...], cond: float):
        super().__init__(message)
        self.mode, self.joints, self.cond = mode, joints, cond


@dataclasses.dataclass(frozen=True)
class FrameOutput:
    """Output rows from a frame's Jacobian (``pin.getFrameJacobian``).

    Attributes:
        frame: the frame's name.
        reference: Pinocchio's reference frame of the Jacobian (default LOCAL_WORLD_ALIGNED: rows
            v_x, v_y, v_z of the frame's origin (m), w_x, w_y, w_z (rad), world axes; the dual load
            is a force at the origin (N) and a torque (N.m)).
        rows: which of the 6 rows to keep.
        kind: a ``pin.FrameType`` when several frames share the name (an MJCF body and site);
            default: the name alone (the first of the types OP_FRAME, BODY, FIXED_JOINT, JOINT,
            SENSOR that has it, when several do).
    """

    frame: str
    reference: Any = pin.LOCAL_WORLD_ALIGNED
    rows: tuple[int, ...] = (0, 1, 2, 3, 4, 5)
    kind: Any = None

    def __post_init__(self) -> None:
        if not isinstance(self.frame, str) or not self.frame:
            raise ParameterError(f"FrameOutput: frame must be a frame's name, got {self.frame!r}")
        frames = (pin.LOCAL, pin.WORLD, pin.LOCAL_WORLD_ALIGNED)
        if not any(self.reference is r or (type(self.reference) is type(r) and self.reference == r) for r in frames):
            raise ParameterError(f"FrameOutput: reference must be pin.LOCAL, pin.WORLD or pin.LOCAL_WORLD_ALIGNED, "
                                 f"got {self.reference!r}")
        rows = self.rows
        if isinstance(rows, (str, bytes)) or not hasattr(rows, "__iter__"):
            raise ParameterError(f"FrameOutput: rows must be indices 0 to 5, got {rows!r}")
        rows = tuple(rows)
        if not rows or any(isinstance(r, bool) or not isinstance(r, (int, np.integer)) or not 0 <= r <= 5
                           for r in rows):
            raise ParameterError(f"FrameOutput: rows must be indices 0 to 5, got {self.rows!r}")
        object.__setattr__(self, "rows", tuple(int(r) for r in rows))
        if self.kind is not None and not isinstance(self.kind, pin.FrameType):
            raise ParameterError(f"FrameOutput: kind must be a pin.FrameType or None, got {self.kind!r}")


@dataclasses.dataclass(frozen=True)
class JointOutput:
    """Output rows from a joint's velocity coordinates, each times ``scale`` (for example -1 to
    read a revolute about the opposite axis); the dual load is the generalized force."""

    joint: str
    scale: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.joint, str) or not self.joint:
            raise ParameterError(f"JointOutput: joint must be a joint's name, got {self.joint!r}")
        s = self.scale
        if isinstance(s, bool) or not isinstance(s, (int, float, np.integer, np.floating)) or not math.isfinite(s) \
                or s == 0:
            raise ParameterError(f"JointOutput: scale must be a finite non-zero number, got {s!r}")
        object.__setattr__(self, "scale", float(s))


Output = FrameOutput | JointOutput


@dataclasses.dataclass(frozen=True)
class VirtualJoint:
    """A 1-dof virtual joint for :func:`insert_joints`, given in world coordinates at the reference
    configuration.

    Attributes:
        name: a new joint name.
        kind: ``"revolute"`` (about ``axis`` through ``point``) or ``"prismatic"`` (along ``axis``).
        axis: (3,) direction (normalised here).
        point: (3,) m, a point of a revolute's axis (any point for a prismatic joint).
        stiffness: N.m/rad or N/m (``inf``: rigid, not inserted).
    """

    name: str
    kind: str
    axis: Any
    point: Any
    stiffness: float


@dataclasses.dataclass(frozen=True)
class Insertion:
    """A chain of virtual joints hung from joint ``parent``; the listed child joints, frames and
    closure sides move to the end of the chain (their placements are kept at the reference
    configuration).

    Attributes:
        parent: name of the joint whose body carries the chain (``"universe"`` for the ground).
        joints: the chain, in order from ``parent``.
        children: joints (children of ``parent``) now hung from the chain's end.
        frames: frames (on ``parent``) now on the chain's end.
        closures: ``(index, side)`` of closures whose side (1 or 2, on ``parent``) moves there.
    """

    parent: str
    joints: tuple[VirtualJoint, ...]
    children: tuple[str, ...] = ()
    frames: tuple[str, ...] = ()
    closures: tuple[tuple[int, int], ...] = ()


def length_scale(model: pin.Model, data: pin.Data) -> float:
    """A length of the mechanism (m): the RMS distance of the joint origins from their centroid, as
    ``data`` places them (after forward kinematics); 1 m for a mechanism of one point."""
    xyz = np.array([data.oMi[j].translation for j in range(model.njoints)])
    rms = float(np.sqrt(np.mean(np.sum((xyz - xyz.mean(axis=0)) ** 2, axis=1))))
    return rms if rms > 0 else 1.0


def _joint_id(model: pin.Model, name: str, what: str) -> int:
    if not model.existJointName(name):
        raise ParameterError(f"{what}: the model has no joint named {name!r}")
    return int(model.getJointId(name))


def _velocity_slice(model: pin.Model, j: int) -> np.ndarray:
    jm = model.joints[j]
    return np.arange(jm.idx_v, jm.idx_v + jm.nv)


def stiffness_vector(model: pin.Model, stiffness: Mapping[str, Any]) -> np.ndarray:
    """The diagonal of Ke (nv,) from ``{joint name: stiffness}`` (a scalar, or one value per
    velocity coordinate of the joint; > 0 and finite). Zero on every other coordinate."""
    k = np.zeros(model.nv)
    for name, value in stiffness.items():
        jm = model.joints[_joint_id(model, name, "stiffness")]
        if isinstance(value, (float, int)) and not isinstance(value, bool) and jm.nv == 1:  # the usual case
            val = float(value)
            if not (0 < val < math.inf):
                raise ParameterError(f"stiffness of joint {name!r} must be finite and > 0, got {value!r}")
            k[jm.idx_v] = val
            continue
        try:
            vals = np.broadcast_to(np.asarray(value, dtype=float), (jm.nv,))
        except (TypeError, ValueError):
            raise ParameterError(f"stiffness of joint {name!r} must be a number or {jm.nv} numbers, "
                                 f"got {value!r}") from None
        if not np.all(np.isfinite(vals) & (vals > 0)):
            raise ParameterError(f"stiffness of joint {name!r} must be finite and > 0, got {value!r}")
        k[jm.idx_v:jm.idx_v + jm.nv] = vals
    return k


def output_jacobian(model: pin.Model, data: pin.Data, outputs: Sequence[Output]) -> np.ndarray:
    """Jo (m, nv): the stacked output rows at the configuration of ``data`` (needs
    ``pin.computeJointJacobians`` first)."""
    rows = []
    for out in outputs:
        if isinstance(out, FrameOutput):
            jac = np.reshape(pin.getFrameJacobian(model, data, frame_id(model, out.frame, out.kind, "outputs"),
                                                  out.reference), (6, model.nv))  # (6,) for one coordinate
            rows.append(jac[list(out.rows)])
        elif isinstance(out, JointOutput):
            sel = np.zeros((model.joints[_joint_id(model, out.joint, "outputs")].nv, model.nv))
            sel[np.arange(len(sel)), _velocity_slice(model, model.getJointId(out.joint))] = out.scale
            rows.append(sel)
        else:
            raise ParameterError(f"outputs must be FrameOutput or JointOutput values, got {type(out).__name__}")
    return np.vstack(rows) if rows else np.zeros((0, model.nv))


def closure_residual(cm: Any, cd: Any) -> tuple[float, float]:
    """(translation (m), rotation (rad)) errors of one computed closure (``calc`` done)."""
    c1mc2 = cd.c1Mc2
    trans = float(np.linalg.norm(c1mc2.translation))
    rot = float(np.linalg.norm(pin.log3(c1mc2.rotation))) if cm.type == pin.ContactType.CONTACT_6D else 0.0
    return trans, rot


def _scaling(model: pin.Model, data: pin.Data, constraint_models: Any, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Column scale (nv,): L on translational velocity coordinates (zero angular part in
    ``data.J``), 1 elsewhere; row scale of Jc: 1/L on its translational rows."""
    col = np.where(np.linalg.norm(np.reshape(data.J, (6, model.nv))[3:], axis=0) == 0.0, length, 1.0)
    row = []
    for cm in constraint_models:
        if cm.type == pin.ContactType.CONTACT_3D:
            row += [1.0 / length] * 3
        elif cm.type == pin.ContactType.CONTACT_6D:
            row += [1.0 / length] * 3 + [1.0] * 3
        else:
            raise ParameterError(f"closure {cm.name!r}: only CONTACT_3D and CONTACT_6D closures are supported")
    return col, np.array(row)


def compliance_matrix(model: pin.Model, constraint_models: Any, q: np.ndarray, *, locked: Sequence[str],
               stiffness: Mapping[str, Any], outputs: Sequence[Output], data: pin.Data | None = None,
               constraint_datas: Any = None, closure_tol: float = CLOSURE_TOL,
               singular_cond: float = CLOSURE_SINGULAR_COND, extra_rows: np.ndarray | None = None) -> np.ndarray:
    """Compliance C (m, m) of the outputs at an assembled configuration: ``dy = C w`` (module docstring).

    Args:
        model: the mechanism's tree (never changed).
        constraint_models: its closures (``pin.RigidConstraintModel``, CONTACT_3D or CONTACT_6D).
        q: (nq,) a configuration where every closure holds.
        locked: names of the locked (actuated) joints.
        stiffness: ``{elastic joint name: stiffness}`` (N.m/rad or N/m; a scalar or one per
            velocity coordinate of the joint).
        outputs: :class:`FrameOutput` and :class:`JointOutput` values; their rows are stacked in
            order (m rows in all).
        data: a ``pin.Data`` of ``model`` to work in (default: a new one, owned by the call).
        constraint_datas: the closures' data (default: new ones).
        closure_tol: largest closure error accepted, relative to :func:`length_scale` (rad for
            the rotation of a CONTACT_6D closure).
        singular_cond: scaled condition number of the frozen mechanism from which ``q`` is refused.
        extra_rows: (r, nv) further constraints ``rows @ dq = 0`` (a mechanism's joint couplings).

    Returns:
        C (m, m), in the units of the outputs per unit dual load (m/N, rad/(N.m), ...).

    Raises:
        ParameterError: unknown joint or frame, bad stiffness or q, a joint both locked and elastic.
        UnassembledError: a closure does not hold at q.
        UnrestrainedMotionError: an admissible motion strains no spring, exactly or within
            ``singular_cond`` (a missing spring, or a singular configuration).
    """
    qv = np.asarray(q, dtype=float)
    if qv.shape != (model.nq,) or not np.all(np.isfinite(qv)):
        raise ParameterError(f"q must be a finite configuration of shape ({model.nq},), got shape {qv.shape}")
    for name in locked:
        _joint_id(model, name, "locked")
    both = set(locked) & set(stiffness)
    if both:
        raise ParameterError(f"joint(s) {', '.join(sorted(both))} cannot be both locked and elastic")
    k = stiffness_vector(model, stiffness)
    d = model.createData() if data is None else data
    pin.computeJointJacobians(model, d, qv)
    n = admissible_basis(model, constraint_models, qv, tuple(locked), k, d, extra_rows,
                         constraint_datas=constraint_datas, closure_tol=closure_tol, singular_cond=singular_cond)
    elastic = np.flatnonzero(k)
    b = n[elastic]  # elastic deflections per basis motion
    chol = np.linalg.cholesky(b.T @ (k[elastic, None] * b))
    x = np.linalg.solve(chol, (output_jacobian(model, d, outputs) @ n).T)
    return x.T @ x


def admissible_basis(model: pin.Model, constraint_models: Any, q: np.ndarray, locked: tuple[str, ...],
                     k: np.ndarray, d: pin.Data, extra_rows: np.ndarray | None = None, *,
                     constraint_datas: Any = None, closure_tol: float = CLOSURE_TOL,
                     singular_cond: float = CLOSURE_SINGULAR_COND) -> np.ndarray:
    """N (nv, nz): a basis of the admissible motions ``dq = N z`` (z in scaled coordinates:
    translations over the length scale), after the closure and singularity checks (module
    docstring); ``k`` (nv,) the springs (zero where none), ``extra_rows`` (r, nv): further
    constraints (joint couplings). ``pin.computeJointJacobians`` must have run in ``d`` at q.
    :func:`compliance_matrix`, :meth:`h4pin.mechanism.Mechanism.modes` and the elastic cycle use it.

    Raises:
        UnassembledError: a closure does not hold at q. UnrestrainedMotionError: a motion strains
        no spring (the joints it moves).
    """
    length = length_scale(model, d)
    cds = [cm.createData() for cm in constraint_models] if constraint_datas is None else constraint_datas
    for cm, cd in zip(constraint_models, cds, strict=True):
        constraint_calc(cm, model, d, cd)
        trans, rot = closure_residual(cm, cd)
        if trans > closure_tol * length or rot > closure_tol:
            raise UnassembledError(f"closure {cm.name!r} does not hold at q: error {trans:.3e} m, {rot:.3e} rad "
                                   f"(tolerance {closure_tol * length:.1e} m)")
    col, row = _scaling(model, d, constraint_models, length)
    if len(constraint_models):
        jc = pin.getConstraintsJacobian(model, d, constraint_models, cds) * row[:, None] * col[None, :]
    else:
        jc = np.zeros((0, model.nv))
    lock_idx = np.concatenate([_velocity_slice(model, model.getJointId(n)) for n in locked] or
                              [np.zeros(0, dtype=int)])
    a = np.vstack([jc, np.eye(model.nv)[lock_idx]] +
                  ([] if extra_rows is None else [np.asarray(extra_rows, float) * col[None, :]]))
    frozen = np.vstack([a, np.eye(model.nv)[np.flatnonzero(k)]])
    sv = np.linalg.svd(frozen, compute_uv=False)
    cond = sv[0] / sv[-1] if len(sv) >= model.nv and sv[-1] > 0 else math.inf
    if not cond < singular_cond:
        raise _unrestrained(model, frozen, cond)
    if a.shape[0] == 0:  # no closure, nothing locked: every motion is admissible
        return col[:, None] * np.eye(model.nv)
    _, s, vt = np.linalg.svd(a)
    rank = int(np.sum(s > RANK_TOL * s[0])) if s.size and s[0] > 0 else 0
    return col[:, None] * vt[rank:].T


def undamped_modes(n: np.ndarray, k: np.ndarray, mass: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Frequencies (Hz, ascending), mass-normalised shapes (m, nv) and the number of massless
    directions of the undamped modes of springs ``k`` (nv,) and joint-space inertia ``mass``
    (nv, nv) over the admissible motions ``dq = n z``: with ``Mz = n^T M n = V diag(mu) V^T``,
    the directions of ``mu <= MASSLESS_TOL * max(mu)`` carry no mass and are condensed
    statically (``K* = Kmm - Kms Kss^-1 Ksm``), the others solve ``K* a = lambda diag(mu) a``.

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




@dataclasses.dataclass(frozen=True, eq=False)
class Modes:
    """Undamped natural modes, of one configuration or of a batch, the same fields either way:
    what :func:`h4pin.modes` (the H4 at a pose or many), :func:`h4pin.elastic.modal.modes` and
    :meth:`h4pin.mechanism.Mechanism.modes` (a configuration or many) return.

    Attributes:
        frequencies: (m,) Hz ascending, or (N, m) for a batch (NaN past each one's count, and
            where its status is not 0).
        massive: how many frequencies each has: the admissible directions that carry mass (the
            massless ones are condensed statically); an int, or (N,).
        status: the verdict (:mod:`h4pin.verdicts`, 0: computed); an int, or (N,) int8.
        payload: the payload, or None.
        poses: the H4's pose (4,) or poses (N, 4) [x, y, z, theta] (m, rad); None for a mechanism.
        shapes_q: (m, nv) each mode's joint motion, mass-normalised (``dq^T M dq = 1``); one
            configuration only, computed on first access when a compiled twin gave the frequencies.
        shapes_tp: (m, 8) the H4 plate's motion of each mode (the H4 only).
        first: the first frequency, a float or (N,).
    """

    frequencies: np.ndarray
    massive: Any
    status: Any = 0
    payload: Any = None
    poses: np.ndarray | None = None
    shapes: Any = dataclasses.field(default=None, repr=False)  # (shapes_tp or None, shapes_q), or a callable
    condensed: Any = dataclasses.field(default=None, repr=False)  # massless directions condensed (a count)

    @property
    def first(self) -> Any:
        f = self.frequencies
        return float(f[0]) if f.ndim == 1 else f[:, 0]

    def _shapes(self) -> tuple[np.ndarray | None, np.ndarray]:
        if self.frequencies.ndim != 1:
            raise ParameterError("shapes: of one configuration at a time (a batch gives its frequencies)")
        if callable(self.shapes):
            object.__setattr__(self, "shapes", self.shapes())
        if self.shapes is None:
            raise ParameterError("shapes: not computed for these modes")
        return self.shapes

    @property
    def shapes_q(self) -> np.ndarray:
        return self._shapes()[1]

    @property
    def shapes_tp(self) -> np.ndarray:
        tp = self._shapes()[0]
        if tp is None:
            raise ParameterError("shapes_tp: the H4 plate's motions (a mechanism's modes have shapes_q)")
        return tp






def _unrestrained(model: pin.Model, frozen: np.ndarray, cond: float) -> UnrestrainedMotionError:
    """The error naming the frozen mechanism's least restrained motion."""
    _, s, vt = np.linalg.svd(frozen)
    mode = vt[-1] if len(s) >= model.nv else vt[len(s)]
    names = []
    for j in range(1, model.njoints):
        amp = float(np.linalg.norm(mode[_velocity_slice(model, j)]))
        if amp > 0.1 * np.max(np.abs(mode)):
            names.append((amp, model.names[j]))
    joints = tuple(n for _, n in sorted(names, reverse=True))
    what = "strains no spring" if not math.isfinite(cond) or cond > 1e15 else "nearly strains no spring"
    return UnrestrainedMotionError(
        f"an admissible motion {what} (frozen mechanism's scaled condition number {cond:.2e}): it moves "
        f"{', '.join(joints[:6])}{' ...' if len(joints) > 6 else ''}; add a spring there or lock a joint "
        "(or the configuration is singular)", mode, joints, cond)


def insert_joints(model: pin.Model, insertions: Sequence[Insertion], constraint_models: Any = (),
                  q_ref: np.ndarray | None = None) -> tuple[pin.Model, Any, np.ndarray]:
    """A copy of ``model`` with chains of virtual joints inserted, and its closures re-created.

    Each :class:`Insertion` hangs its chain from its parent joint; the virtual joints are placed
    from their world axes and points at the reference configuration ``q_ref`` (default:
    ``pin.neutral(model)``), where they all read 0. Original joints keep their names, joint
    models, limits and inertias; original frames keep their ids. The new tree is in depth-first
    order. Virtual joints of infinite stiffness are left out (and an empty chain with them).

    Returns:
        (new model, its closures as a new ``pin.StdVec_RigidConstraintModel``, ``q_index`` (nq,)
        the new configuration index of each original one: ``q_new[q_index] = q``, virtual ones 0).

    Raises:
        ParameterError: unknown names, or a child, frame or closure side not on the chain's parent.
    """
    d = model.createData()
    pin.framesForwardKinematics(model, d, pin.neutral(model) if q_ref is None else np.asarray(q_ref, dtype=float))
    chains, moved_joint, moved_frame, moved_side = [], {}, {}, {}
    for ins in insertions:
        parent = _joint_id(model, ins.parent, "insertion") if ins.parent != "universe" else 0
        joints = [v for v in ins.joints if math.isfinite(v.stiffness)]
        if not joints:
            continue
        chains.append((parent, joints))
        for name in ins.children:
            j = _joint_id(model, name, "insertion")
            if model.parents[j] != parent:
                raise ParameterError(f"insertion: joint {name!r} is not a child of {ins.parent!r}")
            moved_joint[j] = len(chains) - 1
        for name in ins.frames:
            if not model.existFrame(name) or model.frames[model.getFrameId(name)].parentJoint != parent:
                raise ParameterError(f"insertion: no frame {name!r} on joint {ins.parent!r}")
            moved_frame[model.getFrameId(name)] = len(chains) - 1
        for index, side in ins.closures:
            cm = constraint_models[index]
            if (cm.joint1_id if side == 1 else cm.joint2_id) != parent:
                raise ParameterError(f"insertion: side {side} of closure {index} is not on {ins.parent!r}")
            moved_side[(index, side)] = len(chains) - 1
    # Depth-first order: original joints by id, each chain just before its first moved child.
    children: dict[Any, list[Any]] = {}
    for j in range(1, model.njoints):
        owner = ("chain", moved_joint[j]) if j in moved_joint else ("joint", model.parents[j])
        children.setdefault(owner, []).append(("joint", j))
    for c, (parent, _) in enumerate(chains):
        first = min([j for j, cc in moved_joint.items() if cc == c], default=model.njoints)
        children.setdefault(("joint", parent), []).append(("chain", c, first))
    for key in children:
        children[key].sort(key=lambda n: (n[1] if n[0] == "joint" else n[2] - 0.5))
    new = pin.Model()
    new.name = model.name
    new.gravity = model.gravity
    jmap: dict[int, int] = {0: 0}
    chain_end: dict[int, tuple[int, pin.SE3]] = {}  # chain -> (joint id, its placement in parent's frame)
    stack = list(reversed(children.get(("joint", 0), [])))
    while stack:
        node = stack.pop()
        if node[0] == "joint":
            j = node[1]
            if j in moved_joint:
                parent_id, offset = chain_end[moved_joint[j]]
                placement = offset.actInv(model.jointPlacements[j])
            else:
                parent_id, placement = jmap[model.parents[j]], model.jointPlacements[j]
            sl = slice(model.joints[j].idx_q, model.joints[j].idx_q + model.joints[j].nq)
            sv = slice(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv)
            jmap[j] = new.addJoint(parent_id, model.joints[j], placement, model.names[j], model.effortLimit[sv],
                                   model.velocityLimit[sv], model.lowerPositionLimit[sl],
                                   model.upperPositionLimit[sl])
            new.appendBodyToJoint(jmap[j], model.inertias[j], pin.SE3.Identity())
            stack.extend(reversed(children.get(("joint", j), [])))
        else:
            c = node[1]
            parent, joints = chains[c]
            chain_end[c] = _add_chain(new, jmap[parent], d.oMi[parent], joints)
            stack.extend(reversed(children.get(("chain", c), [])))
    for f, frame in enumerate(model.frames):
        if f == 0:
            continue
        joint, placement = jmap[frame.parentJoint], frame.placement
        if f in moved_frame:
            joint, offset = chain_end[moved_frame[f]]
            placement = offset.actInv(placement)
        new.addFrame(pin.Frame(frame.name, joint, frame.parentFrame, placement, frame.type, frame.inertia), False)
    for j in range(1, new.njoints):
        if not new.existFrame(new.names[j]):
            new.addJointFrame(j, 0)
    closures = pin.StdVec_RigidConstraintModel()
    for n, cm in enumerate(constraint_models):
        sides = []
        for side, joint, placement in ((1, cm.joint1_id, cm.joint1_placement), (2, cm.joint2_id, cm.joint2_placement)):
            if (n, side) in moved_side:
                end, offset = chain_end[moved_side[(n, side)]]
                sides.append((end, offset.actInv(placement)))
            else:
                sides.append((jmap[joint], placement))
        new_cm = pin.RigidConstraintModel(cm.type, new, sides[0][0], sides[0][1], sides[1][0], sides[1][1],
                                          cm.reference_frame)
        new_cm.name = cm.name
        closures.append(new_cm)
    q_index = np.zeros(model.nq, dtype=int)
    for j in range(1, model.njoints):
        nq = model.joints[j].nq
        q_index[model.joints[j].idx_q + np.arange(nq)] = new.joints[jmap[j]].idx_q + np.arange(nq)
    return new, closures, q_index


def _add_chain(new: pin.Model, parent_id: int, o_m_parent: pin.SE3, joints: list[VirtualJoint]) -> tuple[int, pin.SE3]:
    """Append the virtual joints under ``parent_id``; frames parallel to the parent's, origins on
    the axes' points. Returns the chain end and its placement in the parent's frame."""
    rot = o_m_parent.rotation
    previous = np.zeros(3)
    jid = parent_id
    for v in joints:
        axis = np.asarray(v.axis, dtype=float)
        norm = float(np.linalg.norm(axis))
        if v.kind not in ("revolute", "prismatic") or not norm > 0:
            raise ParameterError(f"virtual joint {v.name!r}: kind must be 'revolute' or 'prismatic' with a non-zero "
                                 f"axis, got {v.kind!r}, {v.axis!r}")
        local_axis = rot.T @ axis / norm
        point = o_m_parent.actInv(np.asarray(v.point, dtype=float))
        jm = (pin.JointModelRevoluteUnaligned if v.kind == "revolute" else pin.JointModelPrismaticUnaligned)(local_axis)
        big = np.array([1e10])
        jid = new.addJoint(jid, jm, pin.SE3(np.eye(3), point - previous), v.name, big, big, -big, big)
        previous = point
    return jid, pin.SE3(np.eye(3), previous)




__all__ = ["CLOSURE_TOL", "MASSLESS_TOL", "RANK_TOL", "FrameOutput", "Insertion", "JointOutput",
           "Modes", "Output", "admissible_basis", "compliance_matrix", "undamped_modes",
           "UnassembledError", "UnrestrainedMotionError", "VirtualJoint", "closure_residual",
           "insert_joints", "length_scale", "output_jacobian", "stiffness_vector"]
