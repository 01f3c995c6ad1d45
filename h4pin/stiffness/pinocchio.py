# SPDX-License-Identifier: Apache-2.0
"""The Pinocchio path of eq. 30: M1 (eq. 6) and M2 M3 (eq. 11) from Pinocchio's joint Jacobians at
the assembled configuration, then the shared compiled core (:mod:`h4pin.stiffness.core`).

Per pose: the verdict (the compiled closed form's for an exact robot, else
:func:`h4pin.kinematics.closed_form.solve`), the configuration
(:func:`h4pin.kinematics.pinocchio.assemble`), then ``computeJointJacobians`` in the calling
thread's own ``pin.Data``, then one compiled call: the points from the joint placements, M1 rows ``w_n^T`` times
the Jacobian of B_n in plate coordinates, ``g_n = w_n^T`` times the Jacobian of A_n w.r.t.
actuator i, and eq. 30.
"""

from __future__ import annotations

import math
import weakref

import numpy as np
import pinocchio as pin
from numba import njit

from h4pin import _jit
from h4pin.kinematics import closed_form as cf
from h4pin.kinematics import pinocchio as kin
from h4pin.stiffness import core
from h4pin.verdicts import OK, SINGULAR, UNREACHABLE

_PACKS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@njit(cache=True, nogil=True)
def _cross3(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True, nogil=True)
def _pose(J, H, F, I, model, want_terms):  # noqa: E741  # pragma: no cover - compiled
    """K (8, 8), terms (4, 8, 8), condition, status and J of eq. 8 (4, 4) from Pinocchio's WORLD
    joint Jacobians ``J`` (6, nv: column c moves a point X by ``J[:3, c] + J[3:, c] x X``) and the
    joint placements ``H`` (nj, 4, 4), with the constants of :func:`_pack` in F, I."""
    point_joint, v_plate, v_act, lat = I[0:19], I[19:27], I[27:31], I[31:39]
    point_local, P = F[0:57].reshape(19, 3), F[57:69].reshape(4, 3)
    c_ctrl, c_bend, c_tors, c_tens = F[69:73], F[73:77], F[77:81], F[81:89]
    pts = np.empty((19, 3))
    for n in range(19):
        h = H[point_joint[n]]
        for r in range(3):
            pts[n, r] = h[r, 0] * point_local[n, 0] + h[r, 1] * point_local[n, 1] + h[r, 2] * point_local[n, 2] \
                + h[r, 3]
    D = pts[0]
    # dtp[:6] = T v_ff: velocity of D and angular velocity, from the free-flyer columns.
    T6 = np.zeros((6, 6))
    for c in range(6):
        col = v_plate[c]
        vd = J[:3, col] + _cross3(J[3:, col], D)
        for r in range(3):
            T6[r, c] = vd[r]
            T6[3 + r, c] = J[3 + r, col]
    Tinv = np.linalg.inv(T6)
    A, B, W, lw, M, Y, Gc, ws, g, d = core.scratch()
    for n in range(8):
        for r in range(3):
            B[n, r] = pts[3 + n, r]
            A[n, r] = pts[11 + n, r]
            W[n, r] = B[n, r] - A[n, r]
        lw[n] = math.sqrt(W[n, 0] ** 2 + W[n, 1] ** 2 + W[n, 2] ** 2)
        row_ff = np.empty(6)
        for c in range(6):
            col = v_plate[c]
            vb = J[:3, col] + _cross3(J[3:, col], B[n])
            row_ff[c] = W[n, 0] * vb[0] + W[n, 1] * vb[1] + W[n, 2] * vb[2]
        for c in range(6):
            acc = 0.0
            for k in range(6):
                acc += row_ff[k] * Tinv[k, c]
            M[n, c] = acc
        M[n, 6] = 0.0
        M[n, 7] = 0.0
        col = v_plate[6 + lat[n]]
        vb = J[:3, col] + _cross3(J[3:, col], B[n])
        M[n, 6 + lat[n]] = W[n, 0] * vb[0] + W[n, 1] * vb[1] + W[n, 2] * vb[2]
        col = v_act[n // 2]
        va = J[:3, col] + _cross3(J[3:, col], A[n])
        g[n] = W[n, 0] * va[0] + W[n, 1] * va[1] + W[n, 2] * va[2]  # row n of M2 M3 (eqs. 6, 11)
    K = np.empty((8, 8))
    terms = np.empty((4, 8, 8))
    Jo = np.empty((4, 4))
    cond, status = core.finish(M, W, lw, A, P, g, c_ctrl, c_bend, c_tors, c_tens, model, 0, K, terms, want_terms,
                               Jo, True, Y, Gc, ws, d)
    return K, terms, cond, status, Jo


#: Whether :func:`_pose` is compiled (else its interpreted twin runs: :mod:`h4pin._jit`).
POSE = _jit.Gate("Pinocchio path", _pose)


def _pack(h4) -> tuple[np.ndarray, np.ndarray]:
    """The robot's constants for :func:`_pose`, packed once per robot (a read-only cache keyed by
    the robot, outside it)."""
    packed = _PACKS.get(h4)
    if packed is None:
        ix, c = h4.index, h4.geometry.compliances()
        floats = np.concatenate([np.ravel(a) for a in (ix.point_local, h4.geometry.P, c["control"], c["bending"],
                                                       c["torsion"], c["tension"])])
        ints = np.concatenate([np.ravel(a) for a in (ix.point_joint_index, ix.v_plate, h4.v_act, h4.geometry.lat)])
        packed = (np.ascontiguousarray(floats, dtype=np.float64), np.ascontiguousarray(ints, dtype=np.int64))
        for a in packed:
            a.setflags(write=False)
        _PACKS[h4] = packed
    return packed


def backend(h4, x: np.ndarray, model: str, terms: bool):
    """The Pinocchio path as a backend of :func:`h4pin.compliance`, one pose at a time in the
    calling thread's ``pin.Data`` (:class:`h4pin.stiffness.eq30.Raw`). The verdicts before M1 come
    from the closed form (:func:`h4pin.kinematics.closed_form.solve`), shared by every path."""
    from h4pin.stiffness.eq30 import MODELS, Raw

    n = len(x)
    g = h4.geometry
    from h4pin.stiffness import kernel

    if g.ideal and (kernel.ONE if n == 1 else kernel.BATCH).ready:  # the compiled closed form's verdicts
        kern = kernel.for_geometry(g)
        if n == 1:  # no thread start-up for one pose
            _, q1, _, s1 = kern(x[0], model)
            q, status0 = q1[None], np.array([s1], dtype=np.int8)
        else:
            res = kernel.compliance_batch(kern, x, model)
            q, status0 = res.q, res.status
        status = np.where(status0 == SINGULAR, OK, status0).astype(np.int8)
        states = _rigid_states(x, q)
    else:
        sol = cf.solve(g, x)
        status = np.asarray(sol.status, dtype=np.int8).copy()
        q = np.where((status == UNREACHABLE)[:, None], np.nan, sol.state.q)
        states = sol.state
    cond, matrix = np.full(n, np.nan), np.full((n, 8, 8), np.nan)
    out = np.full((n, 4, 8, 8), np.nan) if terms else None
    code, d = MODELS.index(model), h4.data
    for k in np.flatnonzero(status == OK):
        st = states[k] if isinstance(states, list) else cf.PlateState(*(a[k] for a in states))
        K, T, c, s, _ = _at_state(h4, st, code, terms, d)
        cond[k], status[k] = c, s
        if s == OK:
            matrix[k] = K
            if out is not None:
                out[k] = T
    return Raw(matrix, out, q, cond, status)


def one(h4, x: np.ndarray, code: int) -> tuple[np.ndarray, np.ndarray, float, int] | None:
    """One finite pose of a robot with exact parallelograms, without the batch set-up of
    :func:`backend`: (K, q, condition, status), or None when the closed form refuses the pose
    (the caller then takes the long way, which names the reason)."""
    from h4pin.stiffness import kernel

    _, q, _, status, _ = kernel.one(kernel.for_geometry(h4.geometry), x, code)
    if status not in (OK, SINGULAR):
        return None
    K, _, cond, status, _ = _at_state(h4, _rigid_states(x[None], q[None])[0], code, False, h4.data)
    return K, q, float(cond), int(status)


def _rigid_states(x: np.ndarray, q: np.ndarray) -> list[cf.PlateState]:
    """:func:`h4pin.kinematics.closed_form.rigid_state` pose by pose (cheaper for a few poses)."""
    out = []
    for xk, qk in zip(x, q, strict=True):
        c, s = math.cos(xk[3]), math.sin(xk[3])
        out.append(cf.PlateState(qk, xk[:3], np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]),
                                 np.array([-xk[3], -xk[3]])))
    return out


def _at_state(h4, st: cf.PlateState, code: int, want_terms: bool, d: pin.Data):
    q = kin.assemble(h4, st)
    pin.computeJointJacobians(h4.model, d, q)
    homog = np.array([d.oMi[j].homogeneous for j in h4.index.point_joints])
    F, I = _pack(h4)  # noqa: E741
    pose = _pose if POSE.ready else _jit.interpreted(_pose)
    return pose(d.J, homog, F, I, code, want_terms)


__all__ = ["backend"]
