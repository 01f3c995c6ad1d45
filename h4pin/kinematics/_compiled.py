# SPDX-License-Identifier: Apache-2.0
"""Compiled arithmetic of the Pinocchio configuration (numba, cached): the universal-joint angles
of every bar for an assembled state (:func:`h4pin.kinematics.pinocchio.assemble`).

Tests keep it honest: the assembled configuration closes Pinocchio's eight closure constraints
to round-off on every variant.
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
def _angle_about(a0, a1, a2, x0, x1, x2, y0, y1, y2):
    """Angle of the rotation about the unit axis a taking x to y (their parts normal to a)."""
    xa = a0 * x0 + a1 * x1 + a2 * x2
    ya = a0 * y0 + a1 * y1 + a2 * y2
    p0, p1, p2 = x0 - a0 * xa, x1 - a1 * xa, x2 - a2 * xa
    r0, r1, r2 = y0 - a0 * ya, y1 - a1 * ya, y2 - a2 * ya
    c0, c1, c2 = p1 * r2 - p2 * r1, p2 * r0 - p0 * r2, p0 * r1 - p1 * r0
    return math.atan2(a0 * c0 + a1 * c1 + a2 * c2, p0 * r0 + p1 * r1 + p2 * r2)


@njit(cache=True, nogil=True)
def universal_angles(q, D, R, omega, P, u, A0, lat, C0, b, v, e1, e2, p0):  # pragma: no cover - compiled
    """(alpha, beta) (8,) of each bar's two revolutes for an assembled state, as
    :meth:`h4pin.H4.assemble` (Paden-Kahan subproblem 2, the branch with the smaller |beta|)."""
    alpha = np.empty(8)
    beta = np.empty(8)
    lat_rot = np.empty((2, 3, 3))  # R Rot(v_k, omega_k)
    for k in range(2):
        for col in range(3):
            r0, r1, r2 = _rot(v[k, 0], v[k, 1], v[k, 2], omega[k], 1.0 if col == 0 else 0.0, 1.0 if col == 1 else 0.0,
                              1.0 if col == 2 else 0.0)
            for row in range(3):
                lat_rot[k, row, col] = R[row, 0] * r0 + R[row, 1] * r1 + R[row, 2] * r2
    for n in range(8):  # scalars only: no allocation in the loop (each costs tens of ns)
        i = n // 2
        k = lat[n]
        # A_ij and B_ij
        a0, a1, a2 = _rot(u[i, 0], u[i, 1], u[i, 2], q[i], A0[n, 0] - P[i, 0], A0[n, 1] - P[i, 1], A0[n, 2] - P[i, 2])
        bx0 = (D[0] + R[0, 0] * C0[k, 0] + R[0, 1] * C0[k, 1] + R[0, 2] * C0[k, 2]
               + lat_rot[k, 0, 0] * b[n, 0] + lat_rot[k, 0, 1] * b[n, 1] + lat_rot[k, 0, 2] * b[n, 2])
        bx1 = (D[1] + R[1, 0] * C0[k, 0] + R[1, 1] * C0[k, 1] + R[1, 2] * C0[k, 2]
               + lat_rot[k, 1, 0] * b[n, 0] + lat_rot[k, 1, 1] * b[n, 1] + lat_rot[k, 1, 2] * b[n, 2])
        bx2 = (D[2] + R[2, 0] * C0[k, 0] + R[2, 1] * C0[k, 1] + R[2, 2] * C0[k, 2]
               + lat_rot[k, 2, 0] * b[n, 0] + lat_rot[k, 2, 1] * b[n, 1] + lat_rot[k, 2, 2] * b[n, 2])
        w0, w1, w2 = bx0 - P[i, 0] - a0, bx1 - P[i, 1] - a1, bx2 - P[i, 2] - a2
        w0, w1, w2 = _rot(u[i, 0], u[i, 1], u[i, 2], -q[i], w0, w1, w2)
        norm_p = math.sqrt(p0[n, 0] ** 2 + p0[n, 1] ** 2 + p0[n, 2] ** 2)
        scale = norm_p / math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        t0, t1, t2 = w0 * scale, w1 * scale, w2 * scale
        f10, f11, f12 = e1[n, 0], e1[n, 1], e1[n, 2]
        f20, f21, f22 = e2[n, 0], e2[n, 1], e2[n, 2]
        pp0, pp1, pp2 = p0[n, 0], p0[n, 1], p0[n, 2]
        c12 = f10 * f20 + f11 * f21 + f12 * f22
        e1t = f10 * t0 + f11 * t1 + f12 * t2
        e2p = f20 * pp0 + f21 * pp1 + f22 * pp2
        den = 1.0 - c12 * c12
        ca = (e1t - c12 * e2p) / den
        cb = (e2p - c12 * e1t) / den
        n0, n1, n2 = f11 * f22 - f12 * f21, f12 * f20 - f10 * f22, f10 * f21 - f11 * f20
        g2 = (norm_p * norm_p - ca * ca - cb * cb - 2 * ca * cb * c12) / (n0 * n0 + n1 * n1 + n2 * n2)
        gam = math.sqrt(max(g2, 0.0))
        best_a, best_b = 0.0, 1e300
        for s in (1.0, -1.0):
            c0 = ca * f10 + cb * f20 + (s * gam) * n0
            c1 = ca * f11 + cb * f21 + (s * gam) * n1
            c2 = ca * f12 + cb * f22 + (s * gam) * n2
            bb = _angle_about(f20, f21, f22, pp0, pp1, pp2, c0, c1, c2)
            if abs(bb) < abs(best_b):
                best_b = bb
                best_a = _angle_about(f10, f11, f12, c0, c1, c2, t0, t1, t2)
        alpha[n] = best_a
        beta[n] = best_b
    return alpha, beta


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
    # (3 x 3 products written out: numba's ``@`` compiles a BLAS call and its checks per shape)
    Rw = np.empty((3, 3))
    Rm = np.empty((3, 3))
    tw = np.empty(3)
    tm = np.empty(3)
    for r in range(3):
        tw[r] = D[r] + R[r, 0] * (X0t[0] - D0[0]) + R[r, 1] * (X0t[1] - D0[1]) + R[r, 2] * (X0t[2] - D0[2])
        for c in range(3):
            Rw[r, c] = R[r, 0] * X0R[0, c] + R[r, 1] * X0R[1, c] + R[r, 2] * X0R[2, c]
    for r in range(3):
        tm[r] = X0R[0, r] * (tw[0] - X0t[0]) + X0R[1, r] * (tw[1] - X0t[1]) + X0R[2, r] * (tw[2] - X0t[2])
        for c in range(3):
            Rm[r, c] = X0R[0, r] * Rw[0, c] + X0R[1, r] * Rw[1, c] + X0R[2, r] * Rw[2, c]
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
def universal_packed(q, D, R, omega, F, I):  # noqa: E741  # pragma: no cover - compiled
    """:func:`universal_angles` with the constants of :func:`pack_configuration`."""
    return universal_angles(q, D, R, omega, F[0:12].reshape(4, 3), F[12:24].reshape(4, 3), F[24:48].reshape(8, 3),
                            I[0:8], F[48:54].reshape(2, 3), F[54:78].reshape(8, 3), F[78:84].reshape(2, 3),
                            F[84:108].reshape(8, 3), F[108:132].reshape(8, 3), F[132:156].reshape(8, 3))


@njit(cache=True, nogil=True)
def configuration_packed(q_out, q, D, R, omega, F, I):  # noqa: E741  # pragma: no cover - compiled
    """:func:`configuration` with the constants of :func:`pack_configuration`."""
    return configuration(q_out, q, D, R, omega, F[0:12].reshape(4, 3), F[12:24].reshape(4, 3),
                         F[24:48].reshape(8, 3), I[0:8], F[48:54].reshape(2, 3), F[54:78].reshape(8, 3),
                         F[78:84].reshape(2, 3), F[84:108].reshape(8, 3), F[108:132].reshape(8, 3),
                         F[132:156].reshape(8, 3), I[8:12], I[12:28].reshape(8, 2), I[28], I[29:31], F[156:158],
                         F[158:167].reshape(3, 3), F[167:170], F[170:173])
