# SPDX-License-Identifier: Apache-2.0
"""The compiled core of eq. 30 (numba): written once, shared by every compiled front end.

Two front ends build M1 (eq. 6) and the products of the paper's sparse matrices at one pose, then
call this core: the closed-form kernel (:mod:`h4pin.stiffness.kernel`, the default path) and the
Pinocchio path (:mod:`h4pin.stiffness.pinocchio`, M1 from Pinocchio's joint Jacobians). The numpy
reference (:mod:`h4pin.stiffness.eq30`) computes the same quantities with dense arrays; one
parametrised test keeps every backend equal to it.

With ``Y = M1^-1`` and, per bar n = 2 i + j of leg i (0-based),

* ``g_n`` = row n of M2 M3 (eqs. 6, 11): ``w_n . (p_n x u_i)``, ``p_n = P_i - A_n``;
* ``d_n = w_n . (p_n x r_i)`` and ``e_n = (p_n x r_i) . w_n / |w_n|`` (M2 M4 = d e^T per leg,
  eq. 23; r_i the unit vector A_i -> P_i);

the four terms of eq. 30 are sums of outer products of columns of Y:

* control / bending (eqs. 12, 15): ``sum_i c_i G_i L_i^T`` with ``G_i = sum_j Y[:, n] g_n`` (column
  i of M1^-1 M2 M3), ``L_i = R^T J^T e_i`` (``"paper"``: G_i's x, y, z, theta entries in columns
  0, 1, 2, 5) or ``L_i = G_i`` (``"consistent"``, erratum 4 fixed);
* torsion (eq. 23): ``sum_i c_i (sum_j d_n Y[:, n]) (sum_j e_n l_n Y[:, n])^T``;
* tension (eq. 27): ``sum_n c_n l_n^2 Y[:, n] Y[:, n]^T``,

since ``Jb^-1 = diag(l) M1^-T`` (eq. 16) and ``M2 M5 = diag(l)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from h4pin.verdicts import SINGULAR_COND

#: Model codes of the compiled functions.
PAPER, CONSISTENT = 0, 1
#: A pose is refused as singular unless its condition number is below this (one home:
#: :data:`h4pin.verdicts.SINGULAR_COND`; numba freezes it at compile time).
_SINGULAR = SINGULAR_COND

#: numba ``fastmath`` flags of the compiled kernels: contraction to FMA, reciprocal, no signed
#: zeros. Never ``nnan`` / ``ninf`` (the verdicts compare NaN), nor ``reassoc``: K with its terms
#: is their sum in the order of :data:`h4pin.stiffness.eq30.TERMS`, to the bit (measured: no
#: speed lost without it).
FASTMATH = {"contract", "arcp", "nsz"}


# Cephes' atan (Moshier): a rational approximation on |u| <= 0.66 after one range reduction,
# relative error below 2e-16 (tests/test_vector.py: at most 2 ulp against numpy's arctan2).
_AP = (-8.750608600031904122785e-01, -1.615753718733365076637e+01, -7.500855792314704667340e+01,
       -1.228866684490136173410e+02, -6.485021904942025371773e+01)
_AQ = (2.485846490142306297962e+01, 1.650270098316988542046e+02, 4.328810604912902668951e+02,
       4.853903996359136964868e+02, 1.945506571482613964425e+02)
_MOREBITS = 6.123233995736765886130e-17  # pi/2 - float(pi/2)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def atan2(y, x):
    """``np.arctan2(y, x)`` for finite or NaN floats, branch-free (selects and one rational
    polynomial, so that a lane loop of it vectorises; libm's atan2 is a scalar call). Within 2
    ulp of numpy's; signed zeros as numpy's; ``atan2(0, 0) = 0``."""
    ax, ay = abs(x), abs(y)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax
    t = num / den if den != 0.0 else 0.0  # den = max(|x|, |y|): 0 only at the origin
    big = t > 0.66
    u = (t - 1.0) / (t + 1.0) if big else t
    z = u * u
    p = (((_AP[0] * z + _AP[1]) * z + _AP[2]) * z + _AP[3]) * z + _AP[4]
    q = ((((z + _AQ[0]) * z + _AQ[1]) * z + _AQ[2]) * z + _AQ[3]) * z + _AQ[4]
    r = u + u * (z * p / q)
    r = (0.25 * np.pi + (r + 0.5 * _MOREBITS)) if big else r
    r = (0.5 * np.pi + _MOREBITS) - r if swap else r
    r = (np.pi + 2.0 * _MOREBITS) - r if (x < 0.0 or (x == 0.0 and math.copysign(1.0, x) < 0.0)) else r
    return math.copysign(r, y)


@njit(cache=True, nogil=True, inline="always")
def lines_apart(A, B, n1, n2, c2):
    """Whether the axes of bars n1 and n2 (the lines through A[n] and B[n]) are farther apart than
    sqrt(c2), with a relative margin of 1e-9: then so are the bars (the distance between two
    segments is at least that between their lines), and :func:`seg_dist2` need not run. No
    division; it clears about 93 % of the pairs over the prototype's workspace (parallel bars
    never: their cross product vanishes)."""
    d1x, d1y, d1z = B[n1, 0] - A[n1, 0], B[n1, 1] - A[n1, 1], B[n1, 2] - A[n1, 2]
    d2x, d2y, d2z = B[n2, 0] - A[n2, 0], B[n2, 1] - A[n2, 1], B[n2, 2] - A[n2, 2]
    nx, ny, nz = d1y * d2z - d1z * d2y, d1z * d2x - d1x * d2z, d1x * d2y - d1y * d2x
    rn = (A[n1, 0] - A[n2, 0]) * nx + (A[n1, 1] - A[n2, 1]) * ny + (A[n1, 2] - A[n2, 2]) * nz
    return rn * rn > c2 * (1.0 + 1e-9) * (nx * nx + ny * ny + nz * nz)


@njit(cache=True, nogil=True, inline="always")
def seg_dist2(A, B, n1, n2):
    """Squared distance between segments A[n1]-B[n1] and A[n2]-B[n2] (Ericson, RTCD 5.1.9)."""
    d1x, d1y, d1z = B[n1, 0] - A[n1, 0], B[n1, 1] - A[n1, 1], B[n1, 2] - A[n1, 2]
    d2x, d2y, d2z = B[n2, 0] - A[n2, 0], B[n2, 1] - A[n2, 1], B[n2, 2] - A[n2, 2]
    rx, ry, rz = A[n1, 0] - A[n2, 0], A[n1, 1] - A[n2, 1], A[n1, 2] - A[n2, 2]
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    c = d1x * rx + d1y * ry + d1z * rz
    b = d1x * d2x + d1y * d2y + d1z * d2z
    den = a * e - b * b
    s = 0.0
    if den > 1e-14 * a * e:
        s = min(max((b * f - c * e) / den, 0.0), 1.0)
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t = 1.0
        s = min(max((b - c) / a, 0.0), 1.0)
    x = rx + d1x * s - d2x * t
    y = ry + d1y * s - d2y * t
    z = rz + d1z * s - d2z * t
    return x * x + y * y + z * z


@njit(cache=True, nogil=True, inline="always")
def invert_scaled(M, lw, Y):
    """Y = M1^-1 by Gauss-Jordan with partial pivoting, in place (M is overwritten: garbage after); returns the 1-norm
    condition number of the scaled M1 (rows over l_n, columns 3..7 over the mean bar length),
    ``inf`` for an exactly singular M1 (Y is then garbage)."""
    lmean = 0.0
    for n in range(8):
        lmean += lw[n]
        Y[0, n] = 1.0 / lw[n]  # Y as scratch until it is set below
    lmean /= 8.0
    ilm = 1.0 / lmean
    norm1 = 0.0
    for c in range(8):
        s = 0.0
        for n in range(8):
            s += abs(M[n, c]) * Y[0, n]
        if c >= 3:
            s *= ilm
        norm1 = max(norm1, s)
    # Gauss-Jordan in place on Y (a copy of M1): a column's pivot row becomes, scaled, that row of
    # the inverse, the pivot column the inverse's column (448 multiply-adds instead of 644 with a
    # separate identity), and the row swaps come back as column swaps in reverse order at the end.
    # M keeps the pivot rows.
    for a in range(8):
        for c in range(8):
            Y[a, c] = M[a, c]
    for c in range(8):
        p = c
        big = abs(Y[c, c])
        for a in range(c + 1, 8):
            v = abs(Y[a, c])
            if v > big:
                big = v
                p = a
        if big == 0.0:
            return np.inf
        M[0, c] = p
        if p != c:
            for e in range(8):
                Y[c, e], Y[p, e] = Y[p, e], Y[c, e]
        inv = 1.0 / Y[c, c]
        Y[c, c] = 1.0
        for e in range(8):
            Y[c, e] *= inv
        for a in range(8):
            if a != c:
                f = Y[a, c]
                Y[a, c] = 0.0
                for e in range(8):
                    Y[a, e] -= f * Y[c, e]
    for c in range(7, -1, -1):
        p = int(M[0, c])
        if p != c:
            for a in range(8):
                Y[a, c], Y[a, p] = Y[a, p], Y[a, c]
    ninv = 0.0
    for n in range(8):
        s = 0.0
        for a in range(8):
            s += abs(Y[a, n]) * (lmean if a >= 3 else 1.0)
        ninv = max(ninv, s * lw[n])
    cond = norm1 * ninv
    return cond if cond == cond else np.inf


@njit(cache=True, nogil=True, inline="always")
def torsion_factors(A, W, P, d):
    """d_n of the module docstring (eq. 23) from the forearm-side points A (8, 3), the bar vectors
    W (8, 3) = B_n - A_n and the actuator points P (4, 3) (e_n l_n = d_n: :func:`eq30` needs d
    alone)."""
    for i in range(4):
        rx = P[i, 0] - 0.5 * (A[2 * i, 0] + A[2 * i + 1, 0])
        ry = P[i, 1] - 0.5 * (A[2 * i, 1] + A[2 * i + 1, 1])
        rz = P[i, 2] - 0.5 * (A[2 * i, 2] + A[2 * i + 1, 2])
        rn = np.sqrt(rx * rx + ry * ry + rz * rz)
        rx, ry, rz = rx / rn, ry / rn, rz / rn
        for j in range(2):
            n = 2 * i + j
            qx, qy, qz = P[i, 0] - A[n, 0], P[i, 1] - A[n, 1], P[i, 2] - A[n, 2]
            prx, pry, prz = qy * rz - qz * ry, qz * rx - qx * rz, qx * ry - qy * rx
            d[n] = W[n, 0] * prx + W[n, 1] * pry + W[n, 2] * prz


@njit(cache=True, nogil=True, inline="always")
def eq30(Y, g, d, lw, c_ctrl, c_bend, c_tors, c_tens, model, K, T, want_terms, Gc, ws):
    """K (8, 8) of eq. 30 (and with ``want_terms`` its four terms T (4, 8, 8), K their sum) from
    Y = M1^-1 and the per-bar g, d, l (module docstring). Gc (8, 4) receives M1^-1 M2 M3 (its
    rows 0, 1, 2, 5 are J of eq. 8); ws (24, 8) is scratch.

    Each term is a symmetric matrix (sum over legs or bars of c v v^T) times, for the actuator
    terms of the ``"paper"`` model, the load mask of its column: entry (a, c) for c >= a is one
    dot product per term, with the spring compliance folded into its left factor beforehand, and
    gives (c, a) too (a third of the operations of the 16 rank-one updates of K in memory that this
    replaced: 390 -> 150 ns a pose)."""
    for i in range(4):
        n0, n1 = 2 * i, 2 * i + 1
        cs = c_ctrl[i] if want_terms else c_ctrl[i] + c_bend[i]
        for a in range(8):
            gc = Y[a, n0] * g[n0] + Y[a, n1] * g[n1]
            v = Y[a, n0] * d[n0] + Y[a, n1] * d[n1]  # torsion: sum_j d_n Y[:, n] (e_n l_n = d_n)
            Gc[a, i] = gc
            ws[i, a] = v
            ws[4 + i, a] = c_tors[i] * v
            ws[8 + i, a] = cs * gc
            ws[12 + i, a] = c_bend[i] * gc
    for n in range(8):
        w = c_tens[n] * lw[n] * lw[n]
        for a in range(8):
            ws[16 + n, a] = w * Y[a, n]
    for a in range(8):
        la = 1.0 if (model == CONSISTENT or a < 3 or a == 5) else 0.0
        for c in range(a, 8):
            lc = 1.0 if (model == CONSISTENT or c < 3 or c == 5) else 0.0
            ctrl = ws[8, a] * Gc[c, 0] + ws[9, a] * Gc[c, 1] + ws[10, a] * Gc[c, 2] + ws[11, a] * Gc[c, 3]
            tors = ws[4, a] * ws[0, c] + ws[5, a] * ws[1, c] + ws[6, a] * ws[2, c] + ws[7, a] * ws[3, c]
            ten = ((ws[16, a] * Y[c, 0] + ws[17, a] * Y[c, 1]) + (ws[18, a] * Y[c, 2] + ws[19, a] * Y[c, 3])
                   + ((ws[20, a] * Y[c, 4] + ws[21, a] * Y[c, 5]) + (ws[22, a] * Y[c, 6] + ws[23, a] * Y[c, 7])))
            if want_terms:
                bend = ws[12, a] * Gc[c, 0] + ws[13, a] * Gc[c, 1] + ws[14, a] * Gc[c, 2] + ws[15, a] * Gc[c, 3]
                T[0, a, c], T[0, c, a] = lc * ctrl, la * ctrl
                T[1, a, c], T[1, c, a] = lc * bend, la * bend
                T[2, a, c], T[2, c, a] = tors, tors
                T[3, a, c], T[3, c, a] = ten, ten
                ctrl += bend
            K[a, c] = lc * ctrl + tors + ten
            K[c, a] = la * ctrl + tors + ten


@njit(cache=True, nogil=True, inline="always")
def refuse(K, T, want_terms, Jo, want_jac):
    """NaN outputs of a pose that gets no K (status not 0)."""
    K[:, :] = np.nan
    if want_terms:
        T[:] = np.nan
    if want_jac:
        Jo[:] = np.nan


@njit(cache=True, nogil=True, inline="always")
def finish(M, W, lw, A, P, g, c_ctrl, c_bend, c_tors, c_tens, model, status, K, T, want_terms, Jo, want_jac,
           Y, Gc, ws, d):
    """From M1 (overwritten) to the verdict and K: inverts M1 (:func:`invert_scaled`), refuses a
    singular pose (status 4 unless an earlier verdict holds), else fills K (and T, J of eq. 8).
    Returns (condition, status)."""
    cond = invert_scaled(M, lw, Y)
    if status == 0 and not (cond < _SINGULAR):
        status = 4
    if status != 0:
        refuse(K, T, want_terms, Jo, want_jac)
        return cond, status
    torsion_factors(A, W, P, d)
    eq30(Y, g, d, lw, c_ctrl, c_bend, c_tors, c_tens, model, K, T, want_terms, Gc, ws)
    if want_jac:
        for i in range(4):
            Jo[0, i], Jo[1, i], Jo[2, i], Jo[3, i] = Gc[0, i], Gc[1, i], Gc[2, i], Gc[5, i]
    return cond, 0


@njit(cache=True, nogil=True)
def scratch():
    """Scratch arrays of one thread: A, B, W (8, 3), lw (8,), M, Y (8, 8), Gc (8, 4), ws (24, 8),
    g, d (8,) (:func:`scratch_in` of one new buffer)."""
    return scratch_in(np.empty(SCRATCH))


#: Size of the buffer :func:`scratch_in` cuts into the scratch arrays (float64).
SCRATCH = 448


@njit(cache=True, nogil=True, inline="always")
def scratch_in(b):
    """The scratch arrays of :func:`scratch` as views of ``b`` (:data:`SCRATCH`,): one allocation."""
    return (b[0:24].reshape(8, 3), b[24:48].reshape(8, 3), b[48:72].reshape(8, 3), b[72:80],
            b[80:144].reshape(8, 8), b[144:208].reshape(8, 8), b[208:240].reshape(8, 4), b[240:432].reshape(24, 8),
            b[432:440], b[440:448])
