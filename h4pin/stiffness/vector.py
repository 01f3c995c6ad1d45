# SPDX-License-Identifier: Apache-2.0
"""The compiled kernel with poses in lanes: the same pose as :mod:`h4pin.stiffness.kernel`
(inverse geometry, every verdict, M1, eq. 30), written so that LLVM's loop vectoriser emits packed
code (AVX2 / AVX-512 FMA).

Layout: the poses are cut into blocks of at most :data:`LANES` poses. Every intermediate of a
block is one row of a block-local array (rows x lanes, structure of arrays): S (the pose, the
legs, the bars, the masks), M and Y (M1 and its inverse, 8 x 8 x lanes), R (the inversion's
scratch), F and U (the factors of eq. 30 and the upper triangles of its terms). Every innermost
loop runs over the lanes with no branch: the verdicts are masks (0.0 / 1.0 rows), the pivot
choice and the row swaps of the Gauss-Jordan inversion are lane selects, and the status is set at
the end from the masks in the kernel's order (unreachable, limits, interfering bars, singular).
Loops over bars, legs and matrix entries sit outside the lane loop or have a constant trip count
(LLVM unrolls them before vectorising).

What keeps a lane loop vectorised: it writes rows of one array and reads rows of others (at most
one runtime alias check per pair of arrays), or reads and writes rows of one array at distances
LLVM can see. A loop that wrote a row of S while reading 17 others at row indices that are
runtime loop variables stayed scalar (the bar check: 140 -> 25 ns a pose once its mask moved to
an array of its own; the inversion: 300 -> 220 ns once its pivot rows did).

Why runtime-length lane loops and not 4 or 8 fixed lanes: numba compiles with LLVM's SLP
vectoriser off (``NUMBA_SLP_VECTORIZE=0``, a process-wide setting), and LLVM unrolls a loop of 4
or 8 constant trips completely before the loop vectoriser runs, so fixed tiny lane loops come out
scalar. A lane loop whose trip count is known only at run time (``nl <= LANES``) is vectorised by
the loop vectoriser (8 doubles per zmm register on AVX-512, interleaved).

cos and sin of theta stay scalar libm calls, in a lane loop of their own; atan2 for q is
:func:`h4pin.stiffness.core.atan2`, a branch-free polynomial that vectorises.
``fastmath`` is limited to flags that keep NaN and infinity semantics (:data:`FASTMATH`): the
verdicts are comparisons that must see NaN.

Same packed geometry as the kernel (:func:`h4pin.stiffness.kernel.prepare`), same outputs
(:class:`h4pin.stiffness.packed.KernelResult`); robots whose parallelograms are exact.
"""

from __future__ import annotations

import concurrent.futures
import os
from typing import Any

import numba
import numpy as np
from numba import njit

from h4pin import _jit
from h4pin.stiffness import core
from h4pin.stiffness.packed import (
    _BB,
    _BM,
    _C0,
    _CBEND,
    _CCTRL,
    _CLEAR,
    _CTENS,
    _CTORS,
    _LAT,
    _LL,
    _M,
    _P,
    _QHI,
    _QLO,
    _R2,
    _U,
    _UM,
    _UV,
    _UVU,
    _V,
    _WHI,
    _WLO,
    NO_J_N,
    NO_TERMS_N,
    KernelResult,
)
from h4pin.verdicts import INTERFERENCE, LIMITS, OK, SINGULAR, SINGULAR_COND, UNREACHABLE

#: Poses per block (lanes of the scratch rows): of 16, 32, 64 and 128 lanes, 64 was the fastest
#: on one core (435, 426, 390, 449 ns a pose); a block's arrays (about 400 KB) stay in L2.
LANES = 64
#: fastmath flags (:data:`h4pin.stiffness.core.FASTMATH`): never ``nnan`` / ``ninf``.
FASTMATH = core.FASTMATH

_SING = SINGULAR_COND
_CONSISTENT = core.CONSISTENT
_ST_OK, _ST_UNR, _ST_LIM, _ST_BAR, _ST_SING = OK, UNREACHABLE, LIMITS, INTERFERENCE, SINGULAR

# Rows of the block scratch S (rows x LANES). M1 and its inverse live in arrays of their own (M, Y:
# 8 x 8 x LANES) and the inversion's per-lane scratch in R (below): a lane loop that writes one
# array while it reads another vectorises with at most a runtime check per pair of arrays, while
# a loop that writes rows of S that it also reads at a distance LLVM cannot see (a row index that
# is a runtime loop variable) stays scalar.
_X, _Y, _Z, _TH, _CT, _SN = 0, 1, 2, 3, 4, 5
_CQ = 6  # (4,) cos q_i
_SQ = 10  # (4,) sin q_i
_A = 14  # (8, 3) A_n
_B = 38  # (8, 3) B_n
_W = 62  # (8, 3) w_n = B_n - A_n
_AA = 86  # (8,) |w_n|^2
_LW = 94  # (8,) |w_n|
_GG = 102  # (8,) g_n
_DD = 110  # (8,) d_n
_UNR = 118  # masks (0.0 / 1.0): a leg cannot reach
_LIM = 119  # outside the joint limits
_HIT = 120  # two bars interfere
_CND = 121  # condition number
_IA = 122  # (8,) 1 / |w_n|^2
_Q = 130  # (4,) q_i
_ROWS = 134

# Rows of the factors F of eq. 30 (rows x LANES; :func:`_eq30`).
_GC = 0  # (8, 4) Gc[a, i] = M1^-1 M2 M3
_GS = 32  # (8, 4) (c_ctrl + c_bend)_i Gc[a, i]
_TV = 64  # (8, 4) v[a, i] = sum_j d_n Y[a, n]
_TU = 96  # (8, 4) c_tors_i v[a, i]
_YS = 128  # (8, 8) c_tens_n l_n^2 Y[a, n]
_FROWS = 192

# Rows of the inversion's scratch R (rows x LANES).
_PIV = 0  # pivot row of the current column
_ZERO = 1  # a zero pivot (exactly singular M1)
_INV = 2  # 1 / pivot
_NRM = 3  # 1-norm of the scaled M1
_NRI = 4  # 1-norm of the scaled M1^-1
_LM = 5  # mean bar length
_ILM = 6  # 1 / mean bar length
_PM = 8  # (8,) the pivot row of M, scaled
_PY = 16  # (8,) the pivot row of Y, scaled
_OM = 24  # (8,) row c of M before the swap
_OY = 32  # (8,) row c of Y before the swap
_IL = 40  # (8,) 1 / |w_n|
_RROWS = 48


@njit(cache=True, nogil=True, inline="always")
def _max(a, b):
    """numba's ``max(a, b)`` for floats (``b if b > a else a``) as a select the vectoriser takes."""
    return b if b > a else a


@njit(cache=True, nogil=True, inline="always")
def _min(a, b):
    """numba's ``min(a, b)`` for floats (``b if b < a else a``) as a select."""
    return b if b < a else a


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _load(poses, p0, nl, S):
    for l in range(nl):
        S[_X, l] = poses[p0 + l, 0]
        S[_Y, l] = poses[p0 + l, 1]
        S[_Z, l] = poses[p0 + l, 2]
        S[_TH, l] = poses[p0 + l, 3]
    for l in range(nl):  # scalar libm calls, kept out of the vector loops
        S[_CT, l] = np.cos(S[_TH, l])
        S[_SN, l] = np.sin(S[_TH, l])


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _legs(G, nl, S):
    """Inverse geometry of the four legs (the kernel's ``_inverse_geometry``, branch-free):
    cos q, sin q, A, B and the unreachable mask."""
    for l in range(nl):
        S[_UNR, l] = 0.0
    for i in range(4):
        k = int(G[_LAT + 2 * i])
        c0x, c0y, c0z = G[_C0 + 3 * k], G[_C0 + 3 * k + 1], G[_C0 + 3 * k + 2]
        ox = G[_BM + 3 * i] - G[_P + 3 * i]
        oy = G[_BM + 3 * i + 1] - G[_P + 3 * i + 1]
        oz = G[_BM + 3 * i + 2] - G[_P + 3 * i + 2]
        mx, my, mz = G[_M + 3 * i], G[_M + 3 * i + 1], G[_M + 3 * i + 2]
        nx, ny, nz = G[_UM + 3 * i], G[_UM + 3 * i + 1], G[_UM + 3 * i + 2]
        r2l2 = G[_R2 + i] - G[_LL + i] * G[_LL + i]
        for l in range(nl):
            ct, st = S[_CT, l], S[_SN, l]
            cx = S[_X, l] + ct * c0x - st * c0y
            cy = S[_Y, l] + st * c0x + ct * c0y
            cz = S[_Z, l] + c0z
            ex, ey, ez = cx + ox, cy + oy, cz + oz
            alpha = ex * mx + ey * my + ez * mz
            beta = ex * nx + ey * ny + ez * nz
            rhs = 0.5 * (ex * ex + ey * ey + ez * ez + r2l2)
            rho = np.sqrt(alpha * alpha + beta * beta)
            bad = (not (rho > 0.0)) | (abs(rhs) > rho)
            S[_UNR, l] = 1.0 if bad else S[_UNR, l]
            cd = rhs / rho
            sd = np.sqrt(_max(1.0 - cd * cd, 0.0))
            cphi, sphi = alpha / rho, beta / rho
            S[_CQ + i, l] = cphi * cd + sphi * sd
            S[_SQ + i, l] = sphi * cd - cphi * sd
        for j in range(2):
            n = 2 * i + j
            for a in range(3):
                pa, va, wa, ua = G[_P + 3 * i + a], G[_V + 3 * n + a], G[_UV + 3 * n + a], G[_UVU + 3 * n + a]
                ca = c0x if a == 0 else (c0y if a == 1 else c0z)
                cb = -c0y if a == 0 else (c0x if a == 1 else 0.0)
                ba = G[_BB + 3 * n + a]
                for l in range(nl):
                    cq, sq = S[_CQ + i, l], S[_SQ + i, l]
                    S[_A + 3 * n + a, l] = pa + cq * va + sq * wa + (1.0 - cq) * ua
                    # c_a + b_na with c = D + R(theta) C0_k (z: no rotation)
                    rot = (S[_CT, l] * ca + S[_SN, l] * cb) if a < 2 else c0z
                    S[_B + 3 * n + a, l] = S[_X + a, l] + rot + ba


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _angles(G, nl, S):
    """q by :func:`core.atan2` (vectorised) and the joint-limit mask."""
    for i in range(4):
        for l in range(nl):
            S[_Q + i, l] = core.atan2(S[_SQ + i, l], S[_CQ + i, l])
    lo0, lo1, lo2, lo3 = G[_QLO], G[_QLO + 1], G[_QLO + 2], G[_QLO + 3]
    hi0, hi1, hi2, hi3 = G[_QHI], G[_QHI + 1], G[_QHI + 2], G[_QHI + 3]
    w0, w1, v0, v1 = G[_WLO], G[_WLO + 1], G[_WHI], G[_WHI + 1]
    for l in range(nl):
        q0, q1, q2, q3 = S[_Q, l], S[_Q + 1, l], S[_Q + 2, l], S[_Q + 3, l]
        w = -S[_TH, l]
        inside = ((lo0 <= q0) & (q0 <= hi0) & (lo1 <= q1) & (q1 <= hi1) & (lo2 <= q2) & (q2 <= hi2)
                  & (lo3 <= q3) & (q3 <= hi3) & (w0 <= w) & (w <= v0) & (w1 <= w) & (w <= v1))
        S[_LIM, l] = 0.0 if inside else 1.0


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _bars(G, nl, S, H):
    """Bar vectors w_n, |w_n|^2, |w_n|, and the interference mask: the least distance between the
    axes of two bars of different legs below the clearance (:func:`core.seg_dist2`, branch-free).
    The mask builds up in H (LANES,), an array apart from S: read-modify-write of a row of S in
    the pair loop, with its 17 other rows read, kept LLVM from vectorising it (138 -> 23 ns a pose)."""
    for n in range(8):
        for l in range(nl):
            wx = S[_B + 3 * n, l] - S[_A + 3 * n, l]
            wy = S[_B + 3 * n + 1, l] - S[_A + 3 * n + 1, l]
            wz = S[_B + 3 * n + 2, l] - S[_A + 3 * n + 2, l]
            S[_W + 3 * n, l], S[_W + 3 * n + 1, l], S[_W + 3 * n + 2, l] = wx, wy, wz
            aa = wx * wx + wy * wy + wz * wz
            S[_AA + n, l] = aa
            S[_IA + n, l] = 1.0 / aa
            S[_LW + n, l] = np.sqrt(aa)
    c2 = G[_CLEAR] * G[_CLEAR]
    for l in range(nl):
        H[l] = 0.0
    for n1 in range(6):
        for n2 in range(2 * (n1 // 2) + 2, 8):
            for l in range(nl):
                d1x, d1y, d1z = S[_W + 3 * n1, l], S[_W + 3 * n1 + 1, l], S[_W + 3 * n1 + 2, l]
                d2x, d2y, d2z = S[_W + 3 * n2, l], S[_W + 3 * n2 + 1, l], S[_W + 3 * n2 + 2, l]
                rx = S[_A + 3 * n1, l] - S[_A + 3 * n2, l]
                ry = S[_A + 3 * n1 + 1, l] - S[_A + 3 * n2 + 1, l]
                rz = S[_A + 3 * n1 + 2, l] - S[_A + 3 * n2 + 2, l]
                a = S[_AA + n1, l]
                e = S[_AA + n2, l]
                ia = S[_IA + n1, l]
                f = d2x * rx + d2y * ry + d2z * rz
                c = d1x * rx + d1y * ry + d1z * rz
                b = d1x * d2x + d1y * d2y + d1z * d2z
                den = a * e - b * b
                s0 = _min(_max((b * f - c * e) / den, 0.0), 1.0)
                s = s0 if den > 1e-14 * a * e else 0.0
                t0 = (b * s + f) * S[_IA + n2, l]
                lo = t0 < 0.0
                hi = t0 > 1.0
                s_lo = _min(_max(-c * ia, 0.0), 1.0)
                s_hi = _min(_max((b - c) * ia, 0.0), 1.0)
                t = 0.0 if lo else (1.0 if hi else t0)
                s = s_lo if lo else (s_hi if hi else s)
                x = rx + d1x * s - d2x * t
                y = ry + d1y * s - d2y * t
                z = rz + d1z * s - d2z * t
                H[l] = 1.0 if x * x + y * y + z * z < c2 else H[l]
    for l in range(nl):
        S[_HIT, l] = H[l]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _matrix(G, nl, S, M):
    """M1 (eq. 6) into M (8, 8, LANES), g_n, and the torsion factors d_n
    (:func:`core.torsion_factors`; e_n l_n = d_n)."""
    for i in range(4):
        px, py, pz = G[_P + 3 * i], G[_P + 3 * i + 1], G[_P + 3 * i + 2]
        ux, uy, uz = G[_U + 3 * i], G[_U + 3 * i + 1], G[_U + 3 * i + 2]
        for j in range(2):
            n = 2 * i + j
            k = int(G[_LAT + n])
            c0x, c0y = G[_C0 + 3 * k], G[_C0 + 3 * k + 1]
            for l in range(nl):
                wx, wy, wz = S[_W + 3 * n, l], S[_W + 3 * n + 1, l], S[_W + 3 * n + 2, l]
                bx, by, bz = S[_B + 3 * n, l], S[_B + 3 * n + 1, l], S[_B + 3 * n + 2, l]
                sx, sy, sz = S[_X, l] - bx, S[_Y, l] - by, S[_Z, l] - bz
                ct, st = S[_CT, l], S[_SN, l]
                M[n, 0, l], M[n, 1, l], M[n, 2, l] = wx, wy, wz
                M[n, 3, l] = wy * sz - wz * sy
                M[n, 4, l] = wz * sx - wx * sz
                M[n, 5, l] = wx * sy - wy * sx
                tx = sx + ct * c0x - st * c0y
                ty = sy + st * c0x + ct * c0y
                mk = wx * ty - wy * tx
                M[n, 6, l] = mk if k == 0 else 0.0
                M[n, 7, l] = mk if k == 1 else 0.0
            for l in range(nl):  # a loop of its own: fewer runtime alias checks
                wx, wy, wz = S[_W + 3 * n, l], S[_W + 3 * n + 1, l], S[_W + 3 * n + 2, l]
                qx = px - S[_A + 3 * n, l]
                qy = py - S[_A + 3 * n + 1, l]
                qz = pz - S[_A + 3 * n + 2, l]
                S[_GG + n, l] = wx * (qy * uz - qz * uy) + wy * (qz * ux - qx * uz) + wz * (qx * uy - qy * ux)
        for l in range(nl):
            rx = px - 0.5 * (S[_A + 6 * i, l] + S[_A + 6 * i + 3, l])
            ry = py - 0.5 * (S[_A + 6 * i + 1, l] + S[_A + 6 * i + 4, l])
            rz = pz - 0.5 * (S[_A + 6 * i + 2, l] + S[_A + 6 * i + 5, l])
            rn = np.sqrt(rx * rx + ry * ry + rz * rz)
            rx, ry, rz = rx / rn, ry / rn, rz / rn
            for j in range(2):
                n = 2 * i + j
                qx = px - S[_A + 3 * n, l]
                qy = py - S[_A + 3 * n + 1, l]
                qz = pz - S[_A + 3 * n + 2, l]
                dn = (S[_W + 3 * n, l] * (qy * rz - qz * ry) + S[_W + 3 * n + 1, l] * (qz * rx - qx * rz)
                      + S[_W + 3 * n + 2, l] * (qx * ry - qy * rx))
                S[_DD + n, l] = dn


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _gather(nl, R, X, c, e0, old, piv):
    """Columns e0..7 of X's row c as it was into rows ``old + e`` of R, and of each lane's pivot
    row (row R[_PIV] of X, by lane selects over the rows below c) into rows ``piv + e``."""
    for e in range(e0, 8):
        for l in range(nl):
            x = X[c, e, l]
            v = x
            p = R[_PIV, l]
            for a in range(c + 1, 8):
                v = X[a, e, l] if p == a else v
            R[old + e, l] = x
            R[piv + e, l] = v


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _column(nl, R, M, Y, c):
    """Step c of the Gauss-Jordan inversion of M into Y (8, 8, lanes each), partial pivoting per
    lane (:func:`core.invert_scaled`): the pivot row is gathered by lane selects into R (scaled
    there), the row it leaves takes row c as it was inside the elimination (a select per entry),
    so that every lane loop reads the rows it does not write from R. M's columns before c are zero
    below the diagonal and its column c is not read again: only its trailing columns are kept."""
    for l in range(nl):  # pivot search: the first largest |M[a, c]|, a >= c
        big = abs(M[c, c, l])
        p = float(c)
        for a in range(c + 1, 8):
            v = abs(M[a, c, l])
            better = v > big
            big = v if better else big
            p = a if better else p
        R[_PIV, l] = p
        R[_ZERO, l] = 1.0 if big == 0.0 else R[_ZERO, l]
    _gather(nl, R, M, c, c, _OM, _PM)
    _gather(nl, R, Y, c, 0, _OY, _PY)
    for l in range(nl):
        R[_INV, l] = 1.0 / R[_PM + c, l]
    for e in range(c + 1, 8):
        for l in range(nl):
            m = R[_PM + e, l] * R[_INV, l]
            R[_PM + e, l] = m
            M[c, e, l] = m
    for e in range(8):
        for l in range(nl):
            y = R[_PY + e, l] * R[_INV, l]
            R[_PY + e, l] = y
            Y[c, e, l] = y
    for a in range(c):  # rows above c: never the pivot
        for l in range(nl):
            f = M[a, c, l]
            for e in range(c + 1, 8):
                M[a, e, l] -= f * R[_PM + e, l]
        for l in range(nl):
            f = M[a, c, l]
            for e in range(8):
                Y[a, e, l] -= f * R[_PY + e, l]
    for a in range(c + 1, 8):  # rows below: the pivot's old place takes row c as it was
        for l in range(nl):
            sw = R[_PIV, l] == a
            f = R[_OM + c, l] if sw else M[a, c, l]
            for e in range(8):
                Y[a, e, l] = (R[_OY + e, l] if sw else Y[a, e, l]) - f * R[_PY + e, l]
        for l in range(nl):
            sw = R[_PIV, l] == a
            f = R[_OM + c, l] if sw else M[a, c, l]
            for e in range(c + 1, 8):
                M[a, e, l] = (R[_OM + e, l] if sw else M[a, e, l]) - f * R[_PM + e, l]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _invert(nl, S, M, Y, R):
    """Y = M1^-1 (M is overwritten) by Gauss-Jordan with partial pivoting, per lane
    (:func:`core.invert_scaled`). Fills the condition row of S (inf when singular)."""
    for l in range(nl):
        lm = 0.0
        for n in range(8):
            lm += S[_LW + n, l]
        R[_LM, l] = lm / 8.0
        R[_ILM, l] = 8.0 / lm
        R[_NRM, l] = 0.0
        R[_NRI, l] = 0.0
        R[_ZERO, l] = 0.0
    for n in range(8):
        for l in range(nl):
            R[_IL + n, l] = 1.0 / S[_LW + n, l]
    for c in range(8):  # the 1-norm of the scaled M1 (rows over l_n, columns 3.. over the mean)
        for l in range(nl):
            s = 0.0
            for n in range(8):
                s += abs(M[n, c, l]) * R[_IL + n, l]
            s = s * R[_ILM, l] if c >= 3 else s
            R[_NRM, l] = _max(R[_NRM, l], s)
    for a in range(8):
        for e in range(8):
            for l in range(nl):
                Y[a, e, l] = 1.0 if a == e else 0.0
    _column(nl, R, M, Y, 0)
    _column(nl, R, M, Y, 1)
    _column(nl, R, M, Y, 2)
    _column(nl, R, M, Y, 3)
    _column(nl, R, M, Y, 4)
    _column(nl, R, M, Y, 5)
    _column(nl, R, M, Y, 6)
    _column(nl, R, M, Y, 7)
    for n in range(8):  # the 1-norm of the scaled M1^-1
        for l in range(nl):
            lm = R[_LM, l]
            s = 0.0
            for a in range(8):
                s += abs(Y[a, n, l]) * (lm if a >= 3 else 1.0)
            R[_NRI, l] = _max(R[_NRI, l], s * S[_LW + n, l])
    for l in range(nl):
        cond = R[_NRM, l] * R[_NRI, l]
        cond = cond if cond == cond else np.inf
        S[_CND, l] = np.inf if R[_ZERO, l] != 0.0 else cond


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _eq30(G, model, nl, S, Y, F, U, KB, TB, want_terms):
    """K of eq. 30 (:func:`core.eq30`) into KB (8, 8, LANES), with ``want_terms`` the four terms
    into TB (4, 8, 8, LANES) (K their sum). Each term is a symmetric matrix times the load mask of
    its column (``"paper"``: 1 in columns 0, 1, 2, 5 of the actuator terms): the upper triangles go
    to U (4, 8, 8, LANES), then every entry is assembled from them (36 entries of sums instead of
    64; a loop that wrote K[a, c] and K[c, a] together would not vectorise)."""
    for a in range(8):
        for i in range(4):
            cs = G[_CCTRL + i] + G[_CBEND + i]
            ct = G[_CTORS + i]
            n0, n1 = 2 * i, 2 * i + 1
            for l in range(nl):
                y0, y1 = Y[a, n0, l], Y[a, n1, l]
                gc = y0 * S[_GG + n0, l] + y1 * S[_GG + n1, l]
                v = y0 * S[_DD + n0, l] + y1 * S[_DD + n1, l]
                F[_GC + 4 * a + i, l] = gc
                F[_GS + 4 * a + i, l] = cs * gc
                F[_TV + 4 * a + i, l] = v
                F[_TU + 4 * a + i, l] = ct * v
        for n in range(8):
            cn = G[_CTENS + n]
            for l in range(nl):
                F[_YS + 8 * a + n, l] = cn * S[_LW + n, l] * S[_LW + n, l] * Y[a, n, l]
    if want_terms:
        cc0, cc1, cc2, cc3 = G[_CCTRL], G[_CCTRL + 1], G[_CCTRL + 2], G[_CCTRL + 3]
        cb0, cb1, cb2, cb3 = G[_CBEND], G[_CBEND + 1], G[_CBEND + 2], G[_CBEND + 3]
        for a in range(8):
            for c in range(a, 8):
                for l in range(nl):
                    g0 = F[_GC + 4 * a, l] * F[_GC + 4 * c, l]
                    g1 = F[_GC + 4 * a + 1, l] * F[_GC + 4 * c + 1, l]
                    g2 = F[_GC + 4 * a + 2, l] * F[_GC + 4 * c + 2, l]
                    g3 = F[_GC + 4 * a + 3, l] * F[_GC + 4 * c + 3, l]
                    t2 = 0.0
                    for i in range(4):
                        t2 += F[_TU + 4 * a + i, l] * F[_TV + 4 * c + i, l]
                    t3 = 0.0
                    for n in range(8):
                        t3 += F[_YS + 8 * a + n, l] * Y[c, n, l]
                    U[0, a, c, l] = cc0 * g0 + cc1 * g1 + cc2 * g2 + cc3 * g3
                    U[1, a, c, l] = cb0 * g0 + cb1 * g1 + cb2 * g2 + cb3 * g3
                    U[2, a, c, l] = t2
                    U[3, a, c, l] = t3
        for a in range(8):
            for c in range(8):
                load = 1.0 if (model == _CONSISTENT or c < 3 or c == 5) else 0.0
                i, j = (a, c) if a <= c else (c, a)
                for l in range(nl):
                    t0 = load * U[0, i, j, l]
                    t1 = load * U[1, i, j, l]
                    t2 = U[2, i, j, l]
                    t3 = U[3, i, j, l]
                    TB[0, a, c, l] = t0
                    TB[1, a, c, l] = t1
                    TB[2, a, c, l] = t2
                    TB[3, a, c, l] = t3
                    KB[a, c, l] = t0 + t1 + t2 + t3
        return
    for a in range(8):
        for c in range(a, 8):
            for l in range(nl):
                act = 0.0
                rest = 0.0
                for i in range(4):
                    act += F[_GS + 4 * a + i, l] * F[_GC + 4 * c + i, l]
                    rest += F[_TU + 4 * a + i, l] * F[_TV + 4 * c + i, l]
                for n in range(8):
                    rest += F[_YS + 8 * a + n, l] * Y[c, n, l]
                U[0, a, c, l] = act
                U[1, a, c, l] = rest
    for a in range(8):
        for c in range(8):
            load = 1.0 if (model == _CONSISTENT or c < 3 or c == 5) else 0.0
            i, j = (a, c) if a <= c else (c, a)
            for l in range(nl):
                KB[a, c, l] = load * U[0, i, j, l] + U[1, i, j, l]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _transpose(p0, nl, B, X):
    """X[p0 + l] = B[:, :, l] (X: (N, 8, 8) pose-major, B (8, 8, LANES) lane-major), in tiles of 8
    lanes x 8 entries that stay in L1 (a lane at a time over the 64 entries: 1.5x slower)."""
    for l0 in range(0, nl, 8):
        for a in range(8):
            for l in range(l0, min(l0 + 8, nl)):
                for c in range(8):
                    X[p0 + l, a, c] = B[a, c, l]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _store(p0, nl, S, KB, TB, K, qo, cond, status, T, want_terms):
    """The verdicts (in the kernel's order: unreachable, limits, interfering bars, singular), q,
    the condition, K (and the terms), NaN where the verdict is not 0."""
    _transpose(p0, nl, KB, K)
    if want_terms:
        for t in range(4):
            _transpose(p0, nl, TB[t], T[:, t])
    for l in range(nl):
        p = p0 + l
        if S[_UNR, l] != 0.0:
            st = _ST_UNR
        elif S[_LIM, l] != 0.0:
            st = _ST_LIM
        elif S[_HIT, l] != 0.0:
            st = _ST_BAR
        elif not (S[_CND, l] < _SING):
            st = _ST_SING
        else:
            st = _ST_OK
        status[p] = st
        if st == _ST_UNR:
            cond[p] = np.nan
            for i in range(4):
                qo[p, i] = np.nan
        else:
            cond[p] = S[_CND, l]
            for i in range(4):
                qo[p, i] = S[_Q + i, l]
        if st != _ST_OK:
            K[p] = np.nan
            if want_terms:
                T[p] = np.nan


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH)
def _run(poses, start, stop, G, model, K, qo, cond, status, T, want_terms, J, want_jac):
    """Poses start .. stop - 1, in blocks of at most LANES lanes of one scratch S (allocated here,
    so that its shape is a compile-time constant in every lane loop); with ``want_jac`` J of eq. 8
    (rows 0, 1, 2, 5 of M1^-1 M2 M3) into J (N, 4, 4), NaN where the verdict is not 0."""
    S = np.empty((_ROWS, LANES))
    M = np.empty((8, 8, LANES))
    Y = np.empty((8, 8, LANES))
    R = np.empty((_RROWS, LANES))
    H = np.empty(LANES)
    F = np.empty((_FROWS, LANES))
    U = np.empty((4, 8, 8, LANES))
    TB = np.empty((4 if want_terms else 1, 8, 8, LANES))
    for p0 in range(start, stop, LANES):
        nl = min(LANES, stop - p0)
        _load(poses, p0, nl, S)
        _legs(G, nl, S)
        _angles(G, nl, S)
        _bars(G, nl, S, H)
        _matrix(G, nl, S, M)
        _invert(nl, S, M, Y, R)
        _eq30(G, model, nl, S, Y, F, U, M, TB, want_terms)  # M1 is spent: M takes K
        _store(p0, nl, S, M, TB, K, qo, cond, status, T, want_terms)
        if want_jac:
            for l in range(nl):
                ok = status[p0 + l] == _ST_OK
                for r in range(4):
                    a = 5 if r == 3 else r
                    for i in range(4):
                        J[p0 + l, r, i] = F[_GC + 4 * a + i, l] if ok else np.nan


#: Batches from this many poses are cut in one contiguous run of blocks a thread (numba's number
#: of threads, ``numba.set_num_threads``); smaller ones run in the calling thread (handing a run
#: to a pool thread costs about 20 us: 45 poses).
PARALLEL_FROM = 256

_POOL: list[concurrent.futures.ThreadPoolExecutor] = []


def _pool() -> concurrent.futures.ThreadPoolExecutor:
    """The threads that run :func:`_run` beside the calling one (made at first need; a forked
    child makes its own)."""
    if not _POOL:
        _POOL.append(concurrent.futures.ThreadPoolExecutor(max(1, numba.config.NUMBA_NUM_THREADS - 1),
                                                           thread_name_prefix="h4pin-vector"))
    return _POOL[0]


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_POOL.clear)


def _vbatch(poses, G, model, K, qo, cond, status, T, want_terms, J, want_jac) -> None:
    """:func:`_run` over all the poses, on numba's number of threads: one contiguous run of whole
    blocks a thread, the calling thread taking the first (``_run`` releases the GIL). Python threads
    and not a ``prange``: a parallel numba function recompiles ``_run`` under its own options, which
    quadrupled the kernel's compile time (65 s -> 220 s more) for the same speed."""
    n = len(poses)
    threads = min(numba.get_num_threads(), -(-n // LANES)) if n >= PARALLEL_FROM else 1
    if threads <= 1:
        _run(poses, 0, n, G, model, K, qo, cond, status, T, want_terms, J, want_jac)
        return
    step = LANES * -(-n // (LANES * threads))
    bounds = [(lo, min(n, lo + step)) for lo in range(0, n, step)]
    pool = _pool()
    futures = [pool.submit(_run, poses, lo, hi, G, model, K, qo, cond, status, T, want_terms, J, want_jac)
               for lo, hi in bounds[1:]]
    _run(poses, bounds[0][0], bounds[0][1], G, model, K, qo, cond, status, T, want_terms, J, want_jac)
    for f in futures:
        f.result()


def run(kern: Any, x: np.ndarray, code: int, res: KernelResult, terms: bool, jacobian: bool) -> None:
    """The batch into ``res`` on checked input (x (N, 4) C-contiguous float64, N >= 1)."""
    _vbatch(x, kern.packed, code, res.K, res.q, res.condition, res.status, res.terms if terms else NO_TERMS_N,
            terms, res.J if jacobian else NO_J_N, jacobian)


#: Whether :func:`_run` is compiled (:mod:`h4pin._jit`); until then the scalar kernel runs.
VECTOR = _jit.Gate("vector kernel", _run)
#: Batches from this many poses take the vector kernel in :func:`h4pin.stiffness.kernel.compliance_batch`
#: and :func:`h4pin.compliance` (below it, the scalar kernel's serial loop: a block of lanes costs
#: more than a few poses one by one; 7.9 against 10.4 us at 8 poses, 7.9 against 6.1 at 4).
VECTOR_FROM = 8


__all__ = ["FASTMATH", "LANES", "PARALLEL_FROM", "VECTOR_FROM"]
