# SPDX-License-Identifier: Apache-2.0
"""An independent compiled kernel of eq. 30 ("paper" model) for one pose: the plain per-pose
implementation of ``scripts/bench.py`` (``naive_compliance``: per-bar loops, ``np.cross``,
explicit inverses), ported line for line to numba and nothing more. It shares no code with
h4pin's pipeline; ``scripts/bench.py`` times a bare call of it beside one pose through
``h4pin.compliance`` and checks that both give the same K.

    from independent_kernel import constants, independent_compliance
    K = independent_compliance(pose, *constants(params))
"""

from __future__ import annotations

import numpy as np
from numba import njit


def constants(p) -> tuple[np.ndarray, ...]:
    """The arrays of an :class:`h4pin.H4Params` the kernel reads (columns as rows, contiguous)."""
    from h4pin.description.params import LEG_LATERAL

    cc = p.compliances()
    rows = [np.ascontiguousarray(np.asarray(a, dtype=float).T) for a in (p.DC, p.DB, p.U, p.P)]
    flat = [np.ascontiguousarray(a, dtype=float) for a in (p.r, p.l, p.half_width)]
    return (*rows, *flat, np.array(LEG_LATERAL, dtype=np.int64),
            np.asarray(cc["control"] + cc["bending"], dtype=float),
            np.repeat(np.asarray(cc["torsion"], dtype=float), 2), np.asarray(cc["tension"], dtype=float))


@njit(cache=True)
def independent_compliance(pose, DC, DB, U, P, r, l, hw, lat, c_qb, c_tors, c_tens):  # noqa: E741
    """K (8, 8) of eq. 30 at ``pose`` (4,); the arguments after it from :func:`constants`."""
    x, y, z, th = pose[0], pose[1], pose[2], pose[3]
    d = np.array([x, y, z])
    rz = np.array([[np.cos(th), -np.sin(th), 0.0], [np.sin(th), np.cos(th), 0.0], [0.0, 0.0, 1.0]])
    zz = np.array([0.0, 0.0, 1.0])
    c = np.empty((2, 3))
    for k in range(2):
        c[k] = d + rz @ DC[k]
    q = np.zeros(4)
    A, B = np.empty((4, 3)), np.empty((4, 3))
    Aij, Bij = np.empty((8, 3)), np.empty((8, 3))
    for i in range(4):
        k = lat[i]
        u = U[i]
        a = np.cross(u, zz)
        b = c[k] + DB[i] - DC[k]
        e = b - P[i]
        rhs = (e @ e + r[i] ** 2 - l[2 * i] ** 2) / (2 * r[i])
        phi = np.arctan2(-e[2], e @ a)
        ai = np.empty(3)
        for sign in (1.0, -1.0):
            q[i] = phi + sign * np.arccos(rhs / np.hypot(e @ a, e[2]))
            ai = P[i] + r[i] * (a * np.cos(q[i]) - zz * np.sin(q[i]))
            if u @ np.cross(ai - P[i], b - ai) > 0:
                break
        A[i] = ai
        B[i] = b
        for j, s in enumerate((1.0, -1.0)):
            Aij[2 * i + j] = ai + s * hw[i] * u
            Bij[2 * i + j] = b + s * hw[i] * u
    m1, m2, m3, m4 = np.zeros((8, 8)), np.zeros((8, 32)), np.zeros((32, 4)), np.zeros((32, 8))
    jx, jq = np.zeros((4, 4)), np.zeros((4, 4))
    lengths = np.zeros(8)
    for i in range(4):
        k = lat[i]
        w = B[i] - A[i]
        jx[i, :3] = w
        jx[i, 3] = w @ np.cross(zz, c[k] - d)
        jq[i, i] = w @ np.cross(U[i], A[i] - P[i])
        ri = (P[i] - A[i]) / np.linalg.norm(P[i] - A[i])
        wi = w / np.linalg.norm(w)
        for j in range(2):
            n = 2 * i + j
            wij = Bij[n] - Aij[n]
            lengths[n] = np.linalg.norm(wij)
            t = c[k] - Bij[n]
            m1[n, :3] = wij
            m1[n, 3:6] = np.cross(wij, d - c[k] + t)
            m1[n, 6 + k] = np.cross(wij, t)[2]
            m2[n, 3 * n:3 * n + 3] = wij
            m2[n, 24 + n] = lengths[n]
            pij = P[i] - Aij[n]
            m3[3 * n:3 * n + 3, i] = np.cross(pij, U[i])
            for j2 in range(2):
                pij2 = P[i] - Aij[2 * i + j2]
                m4[3 * n:3 * n + 3, 2 * i + j2] = np.cross(pij, ri) * (np.cross(pij2, ri) @ wi)
    m5 = np.zeros((32, 8))
    m5[24:] = np.eye(8)
    rr = np.zeros((4, 8))
    rr[0, 0] = rr[1, 1] = rr[2, 2] = rr[3, 5] = 1.0
    jj = np.linalg.inv(jx) @ jq
    jb_inv = np.linalg.inv(m1.T @ np.diag(1 / lengths))
    inner = (m3 @ np.diag(c_qb) @ np.ascontiguousarray(jj.T) @ rr + m4 @ np.diag(c_tors) @ jb_inv
             + m5 @ np.diag(c_tens) @ jb_inv)
    return np.linalg.inv(m1) @ m2 @ inner
