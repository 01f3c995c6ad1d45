# SPDX-License-Identifier: Apache-2.0
"""The compiled generic path: any closed-loop Pinocchio model's compliance and first natural
frequencies over blocks of configurations, without Python in the loop.

:func:`tables` reads a ``pin.Model`` and its closures once into plain arrays (joint placements,
parents, kinds and axes; body inertias; the closures' two frames); :func:`batch` then runs, per
configuration and without the interpreter:

1. the placements of the joints (revolute, unbounded revolute, prismatic, each on any axis;
   spherical; free-flyer: what the robot corpus and the beams' virtual joints use),
2. the world Jacobian columns of every velocity coordinate (Pinocchio's ``data.J``: the spatial
   velocity at the world origin, linear part first),
3. the closures' errors and rows (the relative velocity of their two frames: Pinocchio's
   ``LOCAL`` constraint Jacobian up to a rotation of its rows, so the same admissible motions)
   scaled as :mod:`h4pin.mechanism.engine` scales them (translations over the length scale),
4. a basis of the admissible motions by Gauss-Jordan elimination with the largest entry of each
   row as pivot (rows found dependent dropped, locked coordinates left out), skipping the zeros
   of the closures' sparse rows,
5. the reduced stiffness ``H = N^T K N``, its Cholesky factor, and ``C = (Jo N) H^-1 (Jo N)^T``,
6. on request, the joint-space inertia (composite rigid bodies, world frame) and the undamped
   frequencies over the same basis: the eigenvalues ``1/w^2`` of the reduced inertia over the
   Cholesky factor of ``H`` (one symmetric eigenvalue problem; a massless direction's is 0, an
   infinite frequency, which is exactly its static condensation). Frequency i is exact to
   round-off times ``(f_i / f_1)^2``.

Pinocchio stays the reference route (:func:`h4pin.mechanism.engine.compliance_matrix`): a
configuration this path cannot judge with certainty (a closure off by more than the tolerance, a
pivot or a Cholesky pivot below :data:`FLAG_RATIO`, nothing with mass) gets status
:data:`FLAGGED` and the caller runs the Pinocchio route for it, whose verdict and message stand.
``tests/test_mechanism_compiled.py`` keeps the two routes equal to 1e-12 on every robot of the
corpus.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin
from numba import njit

from h4pin.lookup import frame_id

REVOLUTE, UNBOUNDED, PRISMATIC, SPHERICAL, FREE_FLYER = 1, 2, 3, 4, 5
WORLD, LOCAL, LOCAL_WORLD_ALIGNED = 0, 1, 2
OK, FLAGGED = 0, 1
#: Smallest accepted ratio of an elimination pivot to the largest entry, and of a squared
#: Cholesky pivot of H to its largest diagonal entry: below it, the Pinocchio route decides.
FLAG_RATIO = 1e-7
_RANK_TOL = 1e-10
_MASSLESS_TOL = 1e-12
_KINDS = {"JointModelRX": REVOLUTE, "JointModelRY": REVOLUTE, "JointModelRZ": REVOLUTE,
          "JointModelRevoluteUnaligned": REVOLUTE, "JointModelRUBX": UNBOUNDED, "JointModelRUBY": UNBOUNDED,
          "JointModelRUBZ": UNBOUNDED, "JointModelRevoluteUnboundedUnaligned": UNBOUNDED,
          "JointModelPX": PRISMATIC, "JointModelPY": PRISMATIC, "JointModelPZ": PRISMATIC,
          "JointModelPrismaticUnaligned": PRISMATIC, "JointModelSpherical": SPHERICAL,
          "JointModelFreeFlyer": FREE_FLYER}
_REFERENCES = {pin.WORLD: WORLD, pin.LOCAL: LOCAL, pin.LOCAL_WORLD_ALIGNED: LOCAL_WORLD_ALIGNED}


class Tables(NamedTuple):
    """A model and its closures as arrays (:func:`tables`); read-only."""

    parents: np.ndarray  # (nj,) int64
    kind: np.ndarray  # (nj,) int64
    axis: np.ndarray  # (nj, 3) unit axis of a 1-dof joint, its own frame
    rot: np.ndarray  # (nj, 3, 3) joint placement in the parent's frame
    pos: np.ndarray  # (nj, 3)
    idx_q: np.ndarray  # (nj,) int64
    idx_v: np.ndarray  # (nj,) int64
    nv_j: np.ndarray  # (nj,) int64
    ancestor: np.ndarray  # (nj, nj) bool: [j, i] when joint i moves body j (i = j included)
    col_joint: np.ndarray  # (nv,) int64 joint of each velocity coordinate
    col_scale: np.ndarray  # (nv,) 1 on rotations, 0 on translations (times the length scale later)
    mass: np.ndarray  # (nj,) kg
    lever: np.ndarray  # (nj, 3) centre of mass, joint frame
    inertia: np.ndarray  # (nj, 3, 3) about the centre of mass, joint frame
    armature: np.ndarray  # (nv,) rotor inertia on each coordinate (Pinocchio's model.armature)
    c_joint: np.ndarray  # (nc, 2) int64 the two joints of each closure
    c_rot: np.ndarray  # (nc, 2, 3, 3) each side's frame in its joint's frame
    c_pos: np.ndarray  # (nc, 2, 3)
    c_six: np.ndarray  # (nc,) bool: a 6-D closure (else 3-D)


def tables(model: pin.Model, constraint_models: Any, extra_inertias: dict[int, pin.Inertia] | None = None
           ) -> Tables | None:
    """The arrays of ``model`` and its closures, or None when a joint is of a kind this path does
    not compute (the caller then keeps the Pinocchio route). ``extra_inertias``: ``{joint id:
    pin.Inertia}`` added to those bodies (a payload)."""
    nj, nv = model.njoints, model.nv
    kind = np.zeros(nj, dtype=np.int64)
    axis = np.zeros((nj, 3))
    neutral = pin.neutral(model)
    for j in range(1, nj):
        jm = model.joints[j]
        k = _KINDS.get(jm.shortname())
        if k is None:
            return None
        kind[j] = k
        if k in (REVOLUTE, UNBOUNDED, PRISMATIC):
            jd = jm.createData()
            jm.calc(jd, neutral)
            s = np.asarray(jd.S, dtype=float).reshape(6)
            axis[j] = s[3:] if k != PRISMATIC else s[:3]
    parents = np.array(model.parents, dtype=np.int64)
    ancestor = np.zeros((nj, nj), dtype=np.bool_)
    for j in range(nj):
        i = j
        while i > 0:
            ancestor[j, i] = True
            i = parents[i]
    idx_v = np.array([model.joints[j].idx_v if j else 0 for j in range(nj)], dtype=np.int64)
    nv_j = np.array([model.joints[j].nv if j else 0 for j in range(nj)], dtype=np.int64)
    col_joint = np.zeros(nv, dtype=np.int64)
    col_scale = np.ones(nv)
    for j in range(1, nj):
        col_joint[idx_v[j]:idx_v[j] + nv_j[j]] = j
        if kind[j] == PRISMATIC:
            col_scale[idx_v[j]] = 0.0
        elif kind[j] == FREE_FLYER:
            col_scale[idx_v[j]:idx_v[j] + 3] = 0.0
    inertias = [pin.Inertia(model.inertias[j]) for j in range(nj)]
    for j, extra in (extra_inertias or {}).items():
        inertias[j] = inertias[j] + extra
    cms = list(constraint_models)
    c_rot, c_pos = np.zeros((len(cms), 2, 3, 3)), np.zeros((len(cms), 2, 3))
    for i, cm in enumerate(cms):
        for side, pl in enumerate((cm.joint1_placement, cm.joint2_placement)):
            c_rot[i, side], c_pos[i, side] = pl.rotation, pl.translation
    return Tables(parents, kind, axis, np.array([p.rotation for p in model.jointPlacements]),
                  np.array([p.translation for p in model.jointPlacements]),
                  np.array([model.joints[j].idx_q if j else 0 for j in range(nj)], dtype=np.int64), idx_v, nv_j,
                  ancestor, col_joint, col_scale, np.array([i.mass for i in inertias]),
                  np.array([i.lever for i in inertias]), np.array([i.inertia for i in inertias]),
                  np.array(model.armature, dtype=float).reshape(nv),
                  np.array([[cm.joint1_id, cm.joint2_id] for cm in cms], dtype=np.int64).reshape(-1, 2), c_rot, c_pos,
                  np.array([cm.type == pin.ContactType.CONTACT_6D for cm in cms], dtype=np.bool_))


class Outputs(NamedTuple):
    """Output rows as arrays (:func:`outputs`): each row is a frame row or a joint coordinate."""

    frame_joint: np.ndarray  # (nf,) int64 the frame's joint
    frame_rot: np.ndarray  # (nf, 3, 3) the frame in its joint's frame
    frame_pos: np.ndarray  # (nf, 3)
    frame_ref: np.ndarray  # (nf,) int64 WORLD, LOCAL or LOCAL_WORLD_ALIGNED
    row_frame: np.ndarray  # (m,) int64 frame of each row, -1 for a joint row
    row_index: np.ndarray  # (m,) int64 row 0-5 of the frame's Jacobian, or the velocity coordinate
    row_scale: np.ndarray  # (m,) a joint row's scale


def outputs(model: pin.Model, resolved: list[Any]) -> Outputs:
    """Arrays of outputs already checked by :func:`h4pin.mechanism.engine.output_jacobian`'s callers
    (``FrameOutput`` and ``JointOutput`` values)."""
    from h4pin.mechanism.engine import FrameOutput

    fj, fr, fp, fref, rf, ri, rs = [], [], [], [], [], [], []
    for out in resolved:
        if isinstance(out, FrameOutput):
            f = model.frames[frame_id(model, out.frame, out.kind, "outputs")]
            fj.append(f.parentJoint)
            fr.append(f.placement.rotation)
            fp.append(f.placement.translation)
            fref.append(_REFERENCES[out.reference])
            for r in out.rows:
                rf.append(len(fj) - 1)
                ri.append(int(r))
                rs.append(1.0)
        else:
            jm = model.joints[model.getJointId(out.joint)]
            for c in range(jm.nv):
                rf.append(-1)
                ri.append(jm.idx_v + c)
                rs.append(float(out.scale))
    return Outputs(np.array(fj, dtype=np.int64), np.array(fr).reshape(-1, 3, 3), np.array(fp).reshape(-1, 3),
                   np.array(fref, dtype=np.int64), np.array(rf, dtype=np.int64), np.array(ri, dtype=np.int64),
                   np.array(rs, dtype=float))


# ---------------------------------------------------------------------------------------------
# Compiled kernels


@njit(cache=True, nogil=True)
def _mul(a, b, out):  # 3x3 products without BLAS
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@njit(cache=True, nogil=True)
def _quat(x, y, z, w, r):
    r[0, 0] = 1 - 2 * (y * y + z * z)
    r[0, 1] = 2 * (x * y - z * w)
    r[0, 2] = 2 * (x * z + y * w)
    r[1, 0] = 2 * (x * y + z * w)
    r[1, 1] = 1 - 2 * (x * x + z * z)
    r[1, 2] = 2 * (y * z - x * w)
    r[2, 0] = 2 * (x * z - y * w)
    r[2, 1] = 2 * (y * z + x * w)
    r[2, 2] = 1 - 2 * (x * x + y * y)


@njit(cache=True, nogil=True)
def _turn(a, c, s, r):  # rotation about unit axis a, cos c, sin s
    t = 1.0 - c
    r[0, 0] = c + t * a[0] * a[0]
    r[0, 1] = t * a[0] * a[1] - s * a[2]
    r[0, 2] = t * a[0] * a[2] + s * a[1]
    r[1, 0] = t * a[0] * a[1] + s * a[2]
    r[1, 1] = c + t * a[1] * a[1]
    r[1, 2] = t * a[1] * a[2] - s * a[0]
    r[2, 0] = t * a[0] * a[2] - s * a[1]
    r[2, 1] = t * a[1] * a[2] + s * a[0]
    r[2, 2] = c + t * a[2] * a[2]


@njit(cache=True, nogil=True)
def placements(parents, kind, axis, rot, pos, idx_q, q, orot, opos):
    """Joint placements (world) at q: ``orot`` (nj, 3, 3), ``opos`` (nj, 3)."""
    rj, tmp = np.zeros((3, 3)), np.zeros((3, 3))
    orot[0] = 0.0
    orot[0, 0, 0] = orot[0, 1, 1] = orot[0, 2, 2] = 1.0
    opos[0] = 0.0
    for j in range(1, len(parents)):
        par, iq, k = parents[j], idx_q[j], kind[j]
        _mul(orot[par], rot[j], tmp)
        for i in range(3):
            opos[j, i] = opos[par, i] + orot[par, i, 0] * pos[j, 0] + orot[par, i, 1] * pos[j, 1] \
                + orot[par, i, 2] * pos[j, 2]
        tx, ty, tz = 0.0, 0.0, 0.0
        if k == REVOLUTE:
            _turn(axis[j], math.cos(q[iq]), math.sin(q[iq]), rj)
        elif k == UNBOUNDED:
            _turn(axis[j], q[iq], q[iq + 1], rj)
        elif k == PRISMATIC:
            rj[:] = 0.0
            rj[0, 0] = rj[1, 1] = rj[2, 2] = 1.0
            tx, ty, tz = axis[j, 0] * q[iq], axis[j, 1] * q[iq], axis[j, 2] * q[iq]
        elif k == SPHERICAL:
            _quat(q[iq], q[iq + 1], q[iq + 2], q[iq + 3], rj)
        else:
            tx, ty, tz = q[iq], q[iq + 1], q[iq + 2]
            _quat(q[iq + 3], q[iq + 4], q[iq + 5], q[iq + 6], rj)
        for i in range(3):
            opos[j, i] += tmp[i, 0] * tx + tmp[i, 1] * ty + tmp[i, 2] * tz
        _mul(tmp, rj, orot[j])


@njit(cache=True, nogil=True)
def world_jacobian(parents, kind, axis, idx_v, orot, opos, jac):
    """Pinocchio's ``data.J`` (6, nv): each coordinate's spatial velocity at the world origin."""
    for j in range(1, len(parents)):
        k, iv = kind[j], idx_v[j]
        r = orot[j]
        px, py, pz = opos[j, 0], opos[j, 1], opos[j, 2]
        if k == PRISMATIC:
            for u in range(3):
                jac[u, iv] = r[u, 0] * axis[j, 0] + r[u, 1] * axis[j, 1] + r[u, 2] * axis[j, 2]
                jac[3 + u, iv] = 0.0
            continue
        n = 1 if k <= UNBOUNDED else 3
        first = iv + 3 if k == FREE_FLYER else iv
        for c in range(n):
            if k <= UNBOUNDED:
                wx = r[0, 0] * axis[j, 0] + r[0, 1] * axis[j, 1] + r[0, 2] * axis[j, 2]
                wy = r[1, 0] * axis[j, 0] + r[1, 1] * axis[j, 1] + r[1, 2] * axis[j, 2]
                wz = r[2, 0] * axis[j, 0] + r[2, 1] * axis[j, 1] + r[2, 2] * axis[j, 2]
            else:
                wx, wy, wz = r[0, c], r[1, c], r[2, c]
            jac[0, first + c] = py * wz - pz * wy
            jac[1, first + c] = pz * wx - px * wz
            jac[2, first + c] = px * wy - py * wx
            jac[3, first + c], jac[4, first + c], jac[5, first + c] = wx, wy, wz
            if k == FREE_FLYER:
                for u in range(3):
                    jac[u, iv + c] = r[u, c]
                    jac[3 + u, iv + c] = 0.0


@njit(cache=True, nogil=True)
def _frame(orot, opos, j, rot, pos, r, x):
    """World rotation ``r`` and origin ``x`` of a frame fixed to joint j's body."""
    _mul(orot[j], rot, r)
    for u in range(3):
        x[u] = opos[j, u] + orot[j, u, 0] * pos[0] + orot[j, u, 1] * pos[1] + orot[j, u, 2] * pos[2]


@njit(cache=True, nogil=True)
def _point_rows(ancestor, col_joint, jac, j, x, sign, out, row, six):
    """``out[row:row+3]`` (+ ``[row+3:row+6]`` if six) += sign * (velocity of point x of body j,
    angular velocity), world axes, over the coordinates that move body j."""
    for c in range(jac.shape[1]):
        if not ancestor[j, col_joint[c]]:
            continue
        wx, wy, wz = jac[3, c], jac[4, c], jac[5, c]
        out[row, c] += sign * (jac[0, c] + wy * x[2] - wz * x[1])
        out[row + 1, c] += sign * (jac[1, c] + wz * x[0] - wx * x[2])
        out[row + 2, c] += sign * (jac[2, c] + wx * x[1] - wy * x[0])
        if six:
            out[row + 3, c] += sign * wx
            out[row + 4, c] += sign * wy
            out[row + 5, c] += sign * wz


@njit(cache=True, nogil=True)
def _length(opos):
    n = opos.shape[0]
    mean = np.zeros(3)
    for j in range(n):
        mean += opos[j]
    mean /= n
    s = 0.0
    for j in range(n):
        d = opos[j] - mean
        s += d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    rms = math.sqrt(s / n)
    return rms if rms > 0 else 1.0


@njit(cache=True, nogil=True)
def _closure_rows(ancestor, col_joint, c_joint, c_rot, c_pos, c_six, orot, opos, jac, col, length, tol, a):
    """Scaled closure rows into ``a``; False when a closure is off by more than ``tol``."""
    row = 0 * len(c_six)  # a run-time 0: a constant argument compiles its callee's own version
    r1, r2, rel = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    x1, x2 = np.zeros(3), np.zeros(3)
    for i in range(len(c_six)):
        j1, j2 = c_joint[i, 0], c_joint[i, 1]
        _frame(orot, opos, j1, c_rot[i, 0], c_pos[i, 0], r1, x1)
        _frame(orot, opos, j2, c_rot[i, 1], c_pos[i, 1], r2, x2)
        if math.sqrt((x2[0] - x1[0]) ** 2 + (x2[1] - x1[1]) ** 2 + (x2[2] - x1[2]) ** 2) > tol * length:
            return False
        six = c_six[i]
        if six:  # the angle of r1^T r2, by atan2 (acos loses small angles)
            for u in range(3):
                for v in range(3):
                    rel[u, v] = r1[0, u] * r2[0, v] + r1[1, u] * r2[1, v] + r1[2, u] * r2[2, v]
            sx, sy, sz = rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]
            angle = math.atan2(0.5 * math.sqrt(sx * sx + sy * sy + sz * sz),
                               0.5 * (rel[0, 0] + rel[1, 1] + rel[2, 2] - 1.0))
            if angle > tol:
                return False
        _point_rows(ancestor, col_joint, jac, j1, x1, 1.0, a, row, six)
        _point_rows(ancestor, col_joint, jac, j2, x2, -1.0, a, row, six)
        for u in range(3):
            for c in range(a.shape[1]):
                a[row + u, c] /= length
        row += 6 if six else 3
    for r in range(row):
        for c in range(a.shape[1]):
            a[r, c] *= col[c]
    return True


@njit(cache=True, nogil=True)
def _basis(a, working):
    """N (nv, nz) with a N = 0 on the working coordinates (others 0), by Gauss-Jordan with the
    largest entry of each row as pivot; and the smallest pivot over the largest entry (1 when no
    row). ``a`` is overwritten."""
    m, nv = a.shape
    amax = 0.0
    for i in range(m):
        for c in range(nv):
            if working[c] and abs(a[i, c]) > amax:
                amax = abs(a[i, c])
    pivot = np.zeros(m, dtype=np.int64) - 1
    used = np.zeros(nv, dtype=np.bool_)
    nonzero = np.zeros(nv, dtype=np.int64)
    worst = 1.0
    for i in range(m):
        best, p = 0.0, -1
        for c in range(nv):
            if working[c] and not used[c] and abs(a[i, c]) > best:
                best, p = abs(a[i, c]), c
        if best <= _RANK_TOL * amax:
            continue
        worst = min(worst, best / amax)
        used[p] = True
        pivot[i] = p
        inv = 1.0 / a[i, p]
        nnz = 0
        for c in range(nv):
            if a[i, c] != 0.0:
                a[i, c] *= inv
                nonzero[nnz] = c
                nnz += 1
        for r in range(m):
            f = a[r, p]
            if r != i and f != 0.0:
                for t in range(nnz):
                    a[r, nonzero[t]] -= f * a[i, nonzero[t]]
    free = np.zeros(nv, dtype=np.int64)
    nfree = 0
    for c in range(nv):
        if working[c] and not used[c]:
            free[nfree] = c
            nfree += 1
    n = np.zeros((nv, nfree))
    for t in range(nfree):
        n[free[t], t] = 1.0
        for i in range(m):
            if pivot[i] >= 0:
                n[pivot[i], t] = -a[i, free[t]]
    return n, worst


@njit(cache=True, nogil=True)
def _cholesky(h):
    """Lower Cholesky factor of h and its smallest squared pivot over h's largest diagonal
    entry (0 when h is not positive definite)."""
    n = h.shape[0]
    lo = np.zeros((n, n))
    dmax = 0.0
    for i in range(n):
        dmax = max(dmax, h[i, i])
    worst = 1.0
    for j in range(n):
        s = h[j, j]
        for k in range(j):
            s -= lo[j, k] * lo[j, k]
        if not s > 0.0 or dmax <= 0.0:
            return lo, 0.0
        worst = min(worst, s / dmax)
        d = math.sqrt(s)
        lo[j, j] = d
        for i in range(j + 1, n):
            s2 = h[i, j]
            for k in range(j):
                s2 -= lo[i, k] * lo[j, k]
            lo[i, j] = s2 / d
    return lo, worst


@njit(cache=True, nogil=True)
def _reduced(nz, ks):
    """H = nz^T diag(ks) nz over the coordinates with a spring."""
    nv, n = nz.shape
    h = np.zeros((n, n))
    for e in range(nv):
        if ks[e] != 0.0:
            for u in range(n):
                f = ks[e] * nz[e, u]
                if f != 0.0:
                    for v in range(u + 1):
                        h[u, v] += f * nz[e, v]
    for u in range(n):
        for v in range(u):
            h[v, u] = h[u, v]
    return h


@njit(cache=True, nogil=True)
def _product(a, b):
    """a @ b, skipping the zeros of a (the closures' and the tree's sparse rows)."""
    out = np.zeros((a.shape[0], b.shape[1]))
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            f = a[i, k]
            if f != 0.0:
                for u in range(b.shape[1]):
                    out[i, u] += f * b[k, u]
    return out


@njit(cache=True, nogil=True)
def _compliance(lo, g, nz, out):
    """out = (g nz) H^-1 (g nz)^T with H = lo lo^T: forward substitution, then X^T X."""
    m = g.shape[0]
    n = nz.shape[1]
    x = _product(g, nz).T.copy()
    for u in range(n):
        for v in range(u):
            for r in range(m):
                x[u, r] -= lo[u, v] * x[v, r]
        for r in range(m):
            x[u, r] /= lo[u, u]
    for r in range(m):
        for s in range(r + 1):
            t = 0.0
            for u in range(n):
                t += x[u, r] * x[u, s]
            out[r, s] = t
            out[s, r] = t


@njit(cache=True, nogil=True)
def _output_rows(ancestor, col_joint, frame_joint, frame_rot, frame_pos, frame_ref, row_frame, row_index, row_scale,
                 orot, opos, jac, col, g):
    """Jo (m, nv), columns scaled by ``col``, into g."""
    nf = len(frame_joint)
    block = np.zeros((6, jac.shape[1]))
    rf, xf = np.zeros((3, 3)), np.zeros(3)
    for f in range(nf):
        j = frame_joint[f]
        _frame(orot, opos, j, frame_rot[f], frame_pos[f], rf, xf)
        block[:] = 0.0
        if frame_ref[f] == WORLD:
            for c in range(jac.shape[1]):
                if ancestor[j, col_joint[c]]:
                    for u in range(6):
                        block[u, c] = jac[u, c]
        else:
            # (row and six as run-time values, as the closures': constants compile another version)
            _point_rows(ancestor, col_joint, jac, j, xf, 1.0, block, 0 * j, frame_ref[f] != WORLD)
            if frame_ref[f] == LOCAL:
                for c in range(jac.shape[1]):
                    for h in (0, 3):
                        x, y, z = block[h, c], block[h + 1, c], block[h + 2, c]
                        for u in range(3):
                            block[h + u, c] = rf[0, u] * x + rf[1, u] * y + rf[2, u] * z
        for r in range(len(row_frame)):
            if row_frame[r] == f:
                for c in range(len(col)):
                    g[r, c] = block[row_index[r], c] * col[c]
    for r in range(len(row_frame)):
        if row_frame[r] < 0:
            g[r, row_index[r]] = row_scale[r] * col[row_index[r]]


@njit(cache=True, nogil=True)
def _mass_matrix(parents, ancestor, col_joint, mass, lever, inertia, armature, orot, opos, jac, out):
    """Joint-space inertia (nv, nv) by composite rigid bodies, in the world frame, with the
    coordinates' armature on the diagonal (as Pinocchio's ``crba``)."""
    nj, nv = len(parents), jac.shape[1]
    comp = np.zeros((nj, 6, 6))
    tmp, ic, cx, c = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3)
    for j in range(1, nj):
        m = mass[j]
        _frame(orot, opos, j, inertia[j], lever[j], tmp, c)
        for u in range(3):
            for v in range(3):
                ic[u, v] = tmp[u, 0] * orot[j][v, 0] + tmp[u, 1] * orot[j][v, 1] + tmp[u, 2] * orot[j][v, 2]
        cx[0, 1], cx[0, 2], cx[1, 2] = -c[2], c[1], -c[0]
        cx[1, 0], cx[2, 0], cx[2, 1] = c[2], -c[1], c[0]
        for u in range(3):
            comp[j, u, u] += m
            for v in range(3):
                comp[j, u, 3 + v] -= m * cx[u, v]
                comp[j, 3 + u, v] += m * cx[u, v]
                s = 0.0
                for w in range(3):
                    s += cx[u, w] * cx[w, v]
                comp[j, 3 + u, 3 + v] += ic[u, v] - m * s
    for j in range(nj - 1, 0, -1):
        if parents[j] > 0:
            for u in range(6):
                for v in range(6):
                    comp[parents[j], u, v] += comp[j, u, v]
    out[:] = 0.0
    for a in range(nv):
        j = col_joint[a]
        f = np.zeros(6)
        for u in range(6):
            for v in range(6):
                f[u] += comp[j, u, v] * jac[v, a]
        for b in range(a + 1):
            if ancestor[j, col_joint[b]]:
                s = 0.0
                for u in range(6):
                    s += f[u] * jac[u, b]
                out[a, b] = s
                out[b, a] = s
        out[a, a] += armature[a]


@njit(cache=True, nogil=True)
def _frequencies(nz, lo, mass, col, freq):
    """Undamped frequencies (Hz, ascending) over ``dq = col * nz z`` into freq (NaN past the
    last), from the Cholesky factor ``lo`` of the reduced stiffness: the eigenvalues of
    ``lo^-1 Mz lo^-T`` are ``1 / omega^2``; a massless direction's is 0 (an infinite frequency:
    exactly its static condensation). False when nothing has mass."""
    nv, n = nz.shape
    b = np.zeros((nv, n))
    for c in range(nv):
        for u in range(n):
            b[c, u] = nz[c, u] * col[c]
    mb = _product(mass, b)
    w = np.zeros((n, n))
    for c in range(nv):
        for u in range(n):
            if b[c, u] != 0.0:
                for v in range(n):
                    w[u, v] += b[c, u] * mb[c, v]
    for c in range(n):  # lo^-1 w, then (lo^-1 (lo^-1 w)^T)
        for u in range(n):
            for v in range(u):
                w[u, c] -= lo[u, v] * w[v, c]
            w[u, c] /= lo[u, u]
    w = w.T.copy()
    for c in range(n):
        for u in range(n):
            for v in range(u):
                w[u, c] -= lo[u, v] * w[v, c]
            w[u, c] /= lo[u, u]
    lam = np.linalg.eigvalsh(0.5 * (w + w.T))
    freq[:] = np.nan
    if not lam[-1] > 0:
        return False
    for i in range(min(n, len(freq))):
        if not lam[n - 1 - i] > _MASSLESS_TOL * lam[-1]:
            break
        freq[i] = 1.0 / (2.0 * math.pi * math.sqrt(lam[n - 1 - i]))
    return True


@njit(cache=True, nogil=True)
def batch(parents, kind, axis, rot, pos, idx_q, idx_v, nv_j, ancestor, col_joint, col_scale, mass_j, lever, inertia,
          armature, c_joint, c_rot, c_pos, c_six, frame_joint, frame_rot, frame_pos, frame_ref, row_frame, row_index,
          row_scale, Q, k, working, extra, tol, start, stop, comp, freq, status):
    """The arrays of :class:`Tables` and :class:`Outputs`, in order, then: compliance (m, m)
    into ``comp[i]`` and, when ``freq`` has columns, the first frequencies into ``freq[i]``, for
    configurations ``Q[start:stop]``; ``k`` (nv,) springs, ``working`` (nv,) the coordinates not
    locked, ``extra`` (N, r, nv) further rows (couplings), ``tol`` the closures' tolerance.
    ``status[i]``: OK, or FLAGGED for the Pinocchio route to decide."""
    nj, nv = len(parents), len(k)
    orot, opos = np.zeros((nj, 3, 3)), np.zeros((nj, 3))
    jac = np.zeros((6, nv))
    mrows = 0
    for i in range(len(c_six)):
        mrows += 6 if c_six[i] else 3
    a = np.zeros((mrows + extra.shape[1], nv))
    g = np.zeros((len(row_frame), nv))
    mass, col, ks = np.zeros((nv, nv)), np.zeros(nv), np.zeros(nv)
    for i in range(start, stop):
        status[i] = FLAGGED
        placements(parents, kind, axis, rot, pos, idx_q, Q[i], orot, opos)
        world_jacobian(parents, kind, axis, idx_v, orot, opos, jac)
        length = _length(opos)
        for c in range(nv):
            col[c] = length if col_scale[c] == 0.0 else 1.0
        a[:] = 0.0
        if not _closure_rows(ancestor, col_joint, c_joint, c_rot, c_pos, c_six, orot, opos, jac, col, length, tol, a):
            continue
        for r in range(extra.shape[1]):
            for c in range(nv):
                a[mrows + r, c] = extra[i, r, c] * col[c]
        nz, piv = _basis(a, working)
        if piv < FLAG_RATIO:
            continue
        for c in range(nv):
            ks[c] = k[c] * col[c] * col[c]
        h = _reduced(nz, ks)
        lo, chol = _cholesky(h)
        if chol < FLAG_RATIO * FLAG_RATIO:
            continue
        g[:] = 0.0
        _output_rows(ancestor, col_joint, frame_joint, frame_rot, frame_pos, frame_ref, row_frame, row_index,
                     row_scale, orot, opos, jac, col, g)
        _compliance(lo, g, nz, comp[i])
        if freq.shape[1]:
            _mass_matrix(parents, ancestor, col_joint, mass_j, lever, inertia, armature, orot, opos, jac, mass)
            if not _frequencies(nz, lo, mass, col, freq[i]):
                continue
        status[i] = OK

