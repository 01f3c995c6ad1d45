# SPDX-License-Identifier: Apache-2.0
"""A hand-tightened compiled kernel of eq. 30 ("paper" model) for one pose: the same K (8, 8) as
``scripts/independent_kernel.py`` (``independent_compliance``), rewritten for speed by hand from
the same math. It shares no code with h4pin's pipeline (nor with ``independent_kernel.py``):
scalar code, explicit loops, two small in-place Gauss-Jordan inverses with partial pivoting, and
the structurally zero blocks of m2, m3, m4, m5 and the diagonal matrices never formed.

    from independent_kernel import constants
    from independent_tight import tight_compliance
    K = np.empty((8, 8))
    tight_compliance(pose, *constants(params), K)

What the naive kernel's products reduce to (leg i, bars n = 2i + j, s_j = +1, -1 for j = 0, 1):

* the two bars of a leg are the same vector: w_ij = B_ij - A_ij = B_i - A_i = w_i, so
  lengths[2i] = lengths[2i + 1] = |w_i|;
* (m2 @ m3)[n, i] = w_i . ((P_i - A_ij) x u_i) = w_i . (u_i x (A_i - P_i)) = jq[i, i];
* (m2 @ m4)[n, 2i + j2] = s_j s_j2 hw_i^2 sigma_i^2 / |w_i| with sigma_i = w_i . (u_i x r_i),
  since (P_i - A_ij) x r_i = -s_j hw_i u_i x r_i (r_i is parallel to P_i - A_i);
* (m2 @ m5)[n, n] = |w_i| and jb_inv = (m1^T diag(1/lengths))^-1 = diag(lengths) m1^-T,
  so with m = m1^-1 and the 2x2 blocks S_i[j, j2] = s_j s_j2 hw_i^2 sigma_i^2 c_tors[2i + j2]
  + delta_jj2 |w_i|^2 c_tens[2i + j]:
  K = m diag(S_i) m^T + sum_i (m[:, 2i] + m[:, 2i + 1]) c_qb[i] jq_i^2 (jx^-1)[k, i] e_col(k)^T,
  col(k) = 0, 1, 2, 5 for k = 0, 1, 2, 3 (the selection rr).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, fastmath=False, error_model="numpy")
def _invert(a, piv):
    """Invert the square ``a`` in place (Gauss-Jordan, partial pivoting); ``piv`` int scratch >= n."""
    n = a.shape[0]
    for k in range(n):
        p = k
        best = abs(a[k, k])
        for i in range(k + 1, n):
            v = abs(a[i, k])
            if v > best:
                best = v
                p = i
        piv[k] = p
        if p != k:
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[p, j]
                a[p, j] = tmp
        inv = 1.0 / a[k, k]
        a[k, k] = 1.0
        for j in range(n):
            a[k, j] *= inv
        for i in range(n):
            if i != k:
                f = a[i, k]
                if f != 0.0:
                    a[i, k] = 0.0
                    for j in range(n):
                        a[i, j] -= f * a[k, j]
    for k in range(n - 1, -1, -1):  # undo the row interchanges as column interchanges
        p = piv[k]
        if p != k:
            for i in range(n):
                tmp = a[i, k]
                a[i, k] = a[i, p]
                a[i, p] = tmp


@njit(cache=True, fastmath=False, error_model="numpy")
def tight_compliance(pose, DC, DB, U, P, r, l, hw, lat, c_qb, c_tors, c_tens, K):  # noqa: E741
    """Write K (8, 8) of eq. 30 at ``pose`` (4,) into ``K``; the arguments between as for
    ``independent_compliance`` (from ``independent_kernel.constants``)."""
    x, y, z, th = pose[0], pose[1], pose[2], pose[3]
    ct, st = np.cos(th), np.sin(th)
    m = np.empty((8, 8))  # m1, then m1^-1
    jx = np.empty((4, 4))  # jx, then jx^-1
    leg = np.empty((4, 3))  # per leg: jq_i, hw_i^2 sigma_i^2, |w_i|^2
    piv = np.empty(8, np.int64)
    for i in range(4):
        k = lat[i]
        # c_k - d = rz @ DC[k]; c_k; B_i = c_k + DB_i - DC_k
        rx = ct * DC[k, 0] - st * DC[k, 1]
        ry = st * DC[k, 0] + ct * DC[k, 1]
        rz = DC[k, 2]
        cx, cy, cz = x + rx, y + ry, z + rz
        bx = cx + DB[i, 0] - DC[k, 0]
        by = cy + DB[i, 1] - DC[k, 1]
        bz = cz + DB[i, 2] - DC[k, 2]
        ux, uy, uz = U[i, 0], U[i, 1], U[i, 2]
        px, py, pz = P[i, 0], P[i, 1], P[i, 2]
        ri = r[i]
        # a = u x zz; the elbow angle: the branch with u . ((A - P) x (B - A)) > 0, else the other
        ax, ay = uy, -ux
        ex, ey, ez = bx - px, by - py, bz - pz
        ea = ex * ax + ey * ay
        rhs = (ex * ex + ey * ey + ez * ez + ri * ri - l[2 * i] * l[2 * i]) / (2.0 * ri)
        phi = np.arctan2(-ez, ea)
        acs = np.arccos(rhs / np.hypot(ea, ez))
        q = phi + acs
        cq, sq = np.cos(q), np.sin(q)
        dx, dy, dz = ri * ax * cq, ri * ay * cq, -ri * sq  # A - P
        wx, wy, wz = bx - px - dx, by - py - dy, bz - pz - dz  # B - A
        if ux * (dy * wz - dz * wy) + uy * (dz * wx - dx * wz) + uz * (dx * wy - dy * wx) <= 0.0:
            q = phi - acs
            cq, sq = np.cos(q), np.sin(q)
            dx, dy, dz = ri * ax * cq, ri * ay * cq, -ri * sq
            wx, wy, wz = bx - px - dx, by - py - dy, bz - pz - dz
        # jx row, jq (u x (A - P)), sigma (w . (u x r_i), r_i = (P - A) / |P - A|)
        jx[i, 0], jx[i, 1], jx[i, 2] = wx, wy, wz
        jx[i, 3] = -wx * ry + wy * rx
        vx, vy, vz = uy * dz - uz * dy, uz * dx - ux * dz, ux * dy - uy * dx
        jq = wx * vx + wy * vy + wz * vz
        sigma = -jq / np.sqrt(dx * dx + dy * dy + dz * dz)
        h = hw[i]
        leg[i, 0] = jq
        leg[i, 1] = h * h * sigma * sigma
        leg[i, 2] = wx * wx + wy * wy + wz * wz
        # m1 rows of the two bars: [w, w x (d - B_ij), (w x (c_k - B_ij))_z at column 6 + k]
        hx, hy, hz = h * ux, h * uy, h * uz
        for j in range(2):
            n = 2 * i + j
            s = 1.0 - 2.0 * j
            tx, ty, tz = cx - bx - s * hx, cy - by - s * hy, cz - bz - s * hz  # c_k - B_ij
            gx, gy, gz = tx - rx, ty - ry, tz - rz  # d - B_ij
            m[n, 0], m[n, 1], m[n, 2] = wx, wy, wz
            m[n, 3] = wy * gz - wz * gy
            m[n, 4] = wz * gx - wx * gz
            m[n, 5] = wx * gy - wy * gx
            m[n, 6 + k] = wx * ty - wy * tx
            m[n, 7 - k] = 0.0
    _invert(jx, piv)
    _invert(m, piv)
    for a in range(8):
        for b in range(8):
            K[a, b] = 0.0
    for i in range(4):
        n0, n1 = 2 * i, 2 * i + 1
        tau, wn2 = leg[i, 1], leg[i, 2]
        s00 = tau * c_tors[n0] + wn2 * c_tens[n0]
        s01 = -tau * c_tors[n1]
        s10 = -tau * c_tors[n0]
        s11 = tau * c_tors[n1] + wn2 * c_tens[n1]
        cq = c_qb[i] * leg[i, 0] * leg[i, 0]
        j0, j1, j2, j3 = cq * jx[0, i], cq * jx[1, i], cq * jx[2, i], cq * jx[3, i]
        for a in range(8):
            p0, p1 = m[a, n0], m[a, n1]
            w0 = p0 * s00 + p1 * s10
            w1 = p0 * s01 + p1 * s11
            for b in range(8):
                K[a, b] += w0 * m[b, n0] + w1 * m[b, n1]
            g = p0 + p1
            K[a, 0] += g * j0
            K[a, 1] += g * j1
            K[a, 2] += g * j2
            K[a, 5] += g * j3
    return 0
