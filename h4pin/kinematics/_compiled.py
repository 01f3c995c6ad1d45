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
