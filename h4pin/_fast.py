# SPDX-License-Identifier: Apache-2.0
"""Compiled arithmetic of the Pinocchio path (numba, cached): the universal-joint angles of every
bar for an assembled state (:meth:`h4pin.H4.assemble`), and eq. 30 from Pinocchio's joint
Jacobians (:meth:`h4pin.H4.pinocchio_compliance`).

Tests keep them honest: the assembled configuration closes Pinocchio's eight closure constraints
to round-off, and the Pinocchio path equals the numpy closed forms (:mod:`h4pin.matrices`) to
1e-12 on every variant.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _rot(axis0, axis1, axis2, angle, x0, x1, x2):
    """Rodrigues: x turned by angle about the unit axis."""
    c, s = math.cos(angle), math.sin(angle)
    dot = (axis0 * x0 + axis1 * x1 + axis2 * x2) * (1.0 - c)
    cx = axis1 * x2 - axis2 * x1
    cy = axis2 * x0 - axis0 * x2
    cz = axis0 * x1 - axis1 * x0
    return x0 * c + cx * s + axis0 * dot, x1 * c + cy * s + axis1 * dot, x2 * c + cz * s + axis2 * dot


@njit(cache=True, nogil=True)
def _angle_about(a, x, y):
    """Angle of the rotation about unit ``a`` taking x to y (their parts normal to a)."""
    xa = a[0] * x[0] + a[1] * x[1] + a[2] * x[2]
    ya = a[0] * y[0] + a[1] * y[1] + a[2] * y[2]
    xp = x - a * xa
    yp = y - a * ya
    cr = np.array([xp[1] * yp[2] - xp[2] * yp[1], xp[2] * yp[0] - xp[0] * yp[2], xp[0] * yp[1] - xp[1] * yp[0]])
    return math.atan2(a[0] * cr[0] + a[1] * cr[1] + a[2] * cr[2], xp[0] * yp[0] + xp[1] * yp[1] + xp[2] * yp[2])


@njit(cache=True, nogil=True)
def universal_angles(q, D, R, omega, P, u, A0, lat, C0, b, v, e1, e2, p0):  # pragma: no cover - compiled
    """(alpha, beta) (8,) of each bar's two revolutes for an assembled state, as
    :meth:`h4pin.H4.assemble` (Paden-Kahan subproblem 2, the branch with the smaller |beta|)."""
    alpha = np.empty(8)
    beta = np.empty(8)
    lat_rot = np.empty((2, 3, 3))
    for k in range(2):
        # R Rot(v_k, omega_k)
        for col in range(3):
            e = np.zeros(3)
            e[col] = 1.0
            r0, r1, r2 = _rot(v[k, 0], v[k, 1], v[k, 2], omega[k], e[0], e[1], e[2])
            for row in range(3):
                lat_rot[k, row, col] = R[row, 0] * r0 + R[row, 1] * r1 + R[row, 2] * r2
    for n in range(8):
        i = n // 2
        k = lat[n]
        # A_ij and B_ij
        a0, a1, a2 = _rot(u[i, 0], u[i, 1], u[i, 2], q[i], A0[n, 0] - P[i, 0], A0[n, 1] - P[i, 1], A0[n, 2] - P[i, 2])
        bx = np.empty(3)
        for r in range(3):
            bx[r] = (D[r] + R[r, 0] * C0[k, 0] + R[r, 1] * C0[k, 1] + R[r, 2] * C0[k, 2]
                     + lat_rot[k, r, 0] * b[n, 0] + lat_rot[k, r, 1] * b[n, 1] + lat_rot[k, r, 2] * b[n, 2])
        w0, w1, w2 = bx[0] - P[i, 0] - a0, bx[1] - P[i, 1] - a1, bx[2] - P[i, 2] - a2
        w0, w1, w2 = _rot(u[i, 0], u[i, 1], u[i, 2], -q[i], w0, w1, w2)
        norm_p = math.sqrt(p0[n, 0] ** 2 + p0[n, 1] ** 2 + p0[n, 2] ** 2)
        scale = norm_p / math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        t = np.array([w0 * scale, w1 * scale, w2 * scale])
        f1, f2, p = e1[n], e2[n], p0[n]
        c12 = f1[0] * f2[0] + f1[1] * f2[1] + f1[2] * f2[2]
        e1t = f1[0] * t[0] + f1[1] * t[1] + f1[2] * t[2]
        e2p = f2[0] * p[0] + f2[1] * p[1] + f2[2] * p[2]
        den = 1.0 - c12 * c12
        ca = (e1t - c12 * e2p) / den
        cb = (e2p - c12 * e1t) / den
        nn = np.array([f1[1] * f2[2] - f1[2] * f2[1], f1[2] * f2[0] - f1[0] * f2[2], f1[0] * f2[1] - f1[1] * f2[0]])
        g2 = (norm_p * norm_p - ca * ca - cb * cb - 2 * ca * cb * c12) / (nn[0] ** 2 + nn[1] ** 2 + nn[2] ** 2)
        gam = math.sqrt(max(g2, 0.0))
        best_a, best_b = 0.0, 1e300
        for s in (1.0, -1.0):
            c = ca * f1 + cb * f2 + (s * gam) * nn
            bb = _angle_about(f2, p, c)
            if abs(bb) < abs(best_b):
                best_b = bb
                best_a = _angle_about(f1, c, t)
        alpha[n] = best_a
        beta[n] = best_b
    return alpha, beta


@njit(cache=True, nogil=True)
def _cross3(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True, nogil=True)
def pinocchio_matrices(J, H, point_joint, point_local, v_plate, v_act, lat, P, u, comp_ctrl, comp_bend,
                       comp_tors, comp_tens, model):  # pragma: no cover - compiled
    """Eq. 30 from Pinocchio's kinematics at one pose (the arithmetic of the ``"pinocchio"`` path).

    Args:
        J: (6, nv) Pinocchio's joint Jacobians in the WORLD frame (``data.J`` after
            ``computeJointJacobians``): column c moves a point X by ``J[:3, c] + J[3:, c] x X``.
        H: (nj, 4, 4) world placements of the joints carrying the points.
        point_joint, point_local: the joint (index into H) and local position of the 19 points
            D, C_1, C_2, B_11..B_42, A_11..A_42.
        v_plate: the 8 velocity indices of the plate (free-flyer 6, lateral 2); v_act: the 4 of
            the actuators; lat: lateral bar of each bar; P, u: actuator axes.
        comp_*: per-element compliances; model: 0 ``paper``, 1 ``consistent``.

    Returns:
        K (8, 8), the scaled condition number of M1 (:func:`h4pin.stiffness.condition_number`),
        J (4, 4) of eq. 8, M1 (8, 8) and the points (19, 3).
    """
    pts = np.empty((19, 3))
    for n in range(19):
        h = H[point_joint[n]]
        for r in range(3):
            pts[n, r] = h[r, 0] * point_local[n, 0] + h[r, 1] * point_local[n, 1] + h[r, 2] * point_local[n, 2] \
                + h[r, 3]
    D = pts[0]
    # dtp[:6] = T v_ff: velocity of D and angular velocity, from the free-flyer columns.
    T = np.zeros((6, 6))
    for c in range(6):
        col = v_plate[c]
        w = J[3:, col]
        vd = J[:3, col] + _cross3(w, D)
        for r in range(3):
            T[r, c] = vd[r]
            T[3 + r, c] = w[r]
    Tinv = np.linalg.inv(T)
    M1 = np.zeros((8, 8))
    W = np.empty((8, 3))
    L = np.empty(8)
    g = np.empty(8)
    for n in range(8):
        B = pts[3 + n]
        A = pts[11 + n]
        wv = B - A
        W[n] = wv
        L[n] = math.sqrt(wv[0] ** 2 + wv[1] ** 2 + wv[2] ** 2)
        row_ff = np.empty(6)
        for c in range(6):
            col = v_plate[c]
            vb = J[:3, col] + _cross3(J[3:, col], B)
            row_ff[c] = wv[0] * vb[0] + wv[1] * vb[1] + wv[2] * vb[2]
        for c in range(6):
            acc = 0.0
            for k in range(6):
                acc += row_ff[k] * Tinv[k, c]
            M1[n, c] = acc
        col = v_plate[6 + lat[n]]
        vb = J[:3, col] + _cross3(J[3:, col], B)
        M1[n, 6 + lat[n]] = wv[0] * vb[0] + wv[1] * vb[1] + wv[2] * vb[2]
        col = v_act[n // 2]
        va = J[:3, col] + _cross3(J[3:, col], A)
        g[n] = wv[0] * va[0] + wv[1] * va[1] + wv[2] * va[2]  # row n of M2 M3 (eqs. 6, 11)
    Y = np.linalg.inv(M1)
    # Scaled 1-norm condition number: rows over l_n, rotation columns over the mean bar length.
    lm = L.mean()
    ms = np.empty((8, 8))
    ys = np.empty((8, 8))
    for n in range(8):
        for c in range(8):
            sc = 1.0 if c < 3 else 1.0 / lm
            ms[n, c] = M1[n, c] / L[n] * sc
            ys[c, n] = Y[c, n] / sc * L[n]
    cond = np.abs(ms).sum(axis=0).max() * np.abs(ys).sum(axis=0).max()
    # G = M1^-1 M2 M3 (8, 4); J = rows x, y, z, theta.
    G = np.zeros((8, 4))
    for n in range(8):
        for r in range(8):
            G[r, n // 2] += Y[r, n] * g[n]
    Jq = np.empty((4, 4))
    for c in range(4):
        Jq[0, c], Jq[1, c], Jq[2, c], Jq[3, c] = G[0, c], G[1, c], G[2, c], G[5, c]
    if model == 0:
        load = np.zeros((4, 8))
        for i in range(4):
            load[i, 0], load[i, 1], load[i, 2], load[i, 5] = Jq[0, i], Jq[1, i], Jq[2, i], Jq[3, i]
    else:
        load = G.T.copy()
    K = np.zeros((8, 8))
    for i in range(4):
        ci = comp_ctrl[i] + comp_bend[i]
        for r in range(8):
            for c in range(8):
                K[r, c] += ci * G[r, i] * load[i, c]
    # Torsion (eq. 23): M2 M4 per leg is d e^T with d_n = w_n.(p_n x r_i), e_n = (p_n x r_i).w_n/|w_n|.
    d = np.empty(8)
    e = np.empty(8)
    for n in range(8):
        i = n // 2
        A_i = 0.5 * (pts[11 + 2 * i] + pts[12 + 2 * i])
        rr = P[i] - A_i
        rr = rr / math.sqrt(rr[0] ** 2 + rr[1] ** 2 + rr[2] ** 2)
        pr = _cross3(P[i] - pts[11 + n], rr)
        d[n] = W[n, 0] * pr[0] + W[n, 1] * pr[1] + W[n, 2] * pr[2]
        e[n] = d[n] / L[n]
    for i in range(4):
        yd = np.zeros(8)
        ye = np.zeros(8)
        for j in range(2):
            n = 2 * i + j
            for r in range(8):
                yd[r] += Y[r, n] * d[n]
                ye[r] += Y[r, n] * e[n] * L[n]
        for r in range(8):
            for c in range(8):
                K[r, c] += comp_tors[i] * yd[r] * ye[c]
    for n in range(8):
        f = comp_tens[n] * L[n] * L[n]
        for r in range(8):
            for c in range(8):
                K[r, c] += f * Y[r, n] * Y[c, n]
    return K, cond, Jq, M1, pts


@njit(cache=True, nogil=True)
def configuration(q_out, q, D, R, omega, P, u, A0, lat, C0, b, v, e1, e2, p0, idx_act, idx_u, idx_ff, idx_lat,
                  lat_sign, X0R, X0t, D0):  # pragma: no cover - compiled
    """Fill the Pinocchio configuration ``q_out`` (nq, starting from the neutral one) of an
    assembled state: actuators, the universal joints (:func:`universal_angles`), the plate's
    free-flyer (its placement relative to the reference one, as x y z qx qy qz qw) and the
    lateral revolutes."""
    alpha, beta = universal_angles(q, D, R, omega, P, u, A0, lat, C0, b, v, e1, e2, p0)
    for i in range(4):
        q_out[idx_act[i]] = q[i]
    for n in range(8):
        q_out[idx_u[n, 0]] = alpha[n]
        q_out[idx_u[n, 1]] = beta[n]
    # World placement of the central bar: x -> R (x - D0) + D applied to its reference X0;
    # the free-flyer's motion is X0^-1 * world.
    Rw = R @ X0R
    tw = R @ (X0t - D0) + D
    Rm = X0R.T @ Rw
    tm = X0R.T @ (tw - X0t)
    tr = Rm[0, 0] + Rm[1, 1] + Rm[2, 2]
    if tr > 0.0:
        s = 0.5 / math.sqrt(tr + 1.0)
        qw, qx, qy, qz = 0.25 / s, (Rm[2, 1] - Rm[1, 2]) * s, (Rm[0, 2] - Rm[2, 0]) * s, (Rm[1, 0] - Rm[0, 1]) * s
    elif Rm[0, 0] > Rm[1, 1] and Rm[0, 0] > Rm[2, 2]:
        s = 2.0 * math.sqrt(1.0 + Rm[0, 0] - Rm[1, 1] - Rm[2, 2])
        qw, qx, qy, qz = (Rm[2, 1] - Rm[1, 2]) / s, 0.25 * s, (Rm[0, 1] + Rm[1, 0]) / s, (Rm[0, 2] + Rm[2, 0]) / s
    elif Rm[1, 1] > Rm[2, 2]:
        s = 2.0 * math.sqrt(1.0 + Rm[1, 1] - Rm[0, 0] - Rm[2, 2])
        qw, qx, qy, qz = (Rm[0, 2] - Rm[2, 0]) / s, (Rm[0, 1] + Rm[1, 0]) / s, 0.25 * s, (Rm[1, 2] + Rm[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + Rm[2, 2] - Rm[0, 0] - Rm[1, 1])
        qw, qx, qy, qz = (Rm[1, 0] - Rm[0, 1]) / s, (Rm[0, 2] + Rm[2, 0]) / s, (Rm[1, 2] + Rm[2, 1]) / s, 0.25 * s
    if qw < 0.0:
        qw, qx, qy, qz = -qw, -qx, -qy, -qz
    q_out[idx_ff + 0], q_out[idx_ff + 1], q_out[idx_ff + 2] = tm[0], tm[1], tm[2]
    q_out[idx_ff + 3], q_out[idx_ff + 4], q_out[idx_ff + 5], q_out[idx_ff + 6] = qx, qy, qz, qw
    for k in range(2):
        q_out[idx_lat[k]] = lat_sign[k] * omega[k]
    return q_out


def pack_configuration(P, u, A0, C0, b, v, e1, e2, p0, lat_sign, X0R, X0t, D0, lat, idx_act, idx_u, idx_ff,
                       idx_lat) -> tuple[np.ndarray, np.ndarray]:
    """The constants of :func:`configuration` packed into one float and one int array, so that a
    call passes 7 arguments instead of 23 (numba's dispatch costs per argument)."""
    floats = np.concatenate([np.ravel(a) for a in (P, u, A0, C0, b, v, e1, e2, p0, lat_sign, X0R, X0t, D0)])
    ints = np.concatenate([np.ravel(lat), np.ravel(idx_act), np.ravel(idx_u), [idx_ff], np.ravel(idx_lat)])
    return np.ascontiguousarray(floats, dtype=np.float64), np.ascontiguousarray(ints, dtype=np.int64)


@njit(cache=True, nogil=True)
def configuration_packed(q_out, q, D, R, omega, F, I):  # noqa: E741  # pragma: no cover - compiled
    """:func:`configuration` with the constants of :func:`pack_configuration`."""
    return configuration(q_out, q, D, R, omega, F[0:12].reshape(4, 3), F[12:24].reshape(4, 3),
                         F[24:48].reshape(8, 3), I[0:8], F[48:54].reshape(2, 3), F[54:78].reshape(8, 3),
                         F[78:84].reshape(2, 3), F[84:108].reshape(8, 3), F[108:132].reshape(8, 3),
                         F[132:156].reshape(8, 3), I[8:12], I[12:28].reshape(8, 2), I[28], I[29:31], F[156:158],
                         F[158:167].reshape(3, 3), F[167:170], F[170:173])


def pack_matrices(point_joint, point_local, v_plate, v_act, lat, P, u, c_ctrl, c_bend, c_tors,
                  c_tens) -> tuple[np.ndarray, np.ndarray]:
    """The constants of :func:`pinocchio_matrices` packed into one float and one int array."""
    floats = np.concatenate([np.ravel(a) for a in (point_local, P, u, c_ctrl, c_bend, c_tors, c_tens)])
    ints = np.concatenate([np.ravel(a) for a in (point_joint, v_plate, v_act, lat)])
    return np.ascontiguousarray(floats, dtype=np.float64), np.ascontiguousarray(ints, dtype=np.int64)


@njit(cache=True, nogil=True)
def pinocchio_matrices_packed(J, H, F, I, model):  # noqa: E741  # pragma: no cover - compiled
    """:func:`pinocchio_matrices` with the constants of :func:`pack_matrices`."""
    return pinocchio_matrices(J, H, I[0:19], F[0:57].reshape(19, 3), I[19:27], I[27:31], I[31:39],
                              F[57:69].reshape(4, 3), F[69:81].reshape(4, 3), F[81:85], F[85:89], F[89:93], F[93:101],
                              model)
