# SPDX-License-Identifier: Apache-2.0
"""The compiled kernel with poses in lanes: the same pose as :mod:`h4pin.stiffness.kernel`
(inverse geometry, every verdict, M1, eq. 30), written so that LLVM's loop vectoriser emits packed
code (AVX2 / AVX-512 FMA).

Layout: the poses are cut into blocks of at most :data:`LANES` poses. Every intermediate of a
block is one row of a block-local scratch array ``S`` (rows x lanes, structure of arrays), and
every innermost loop runs over the lanes with no branch: the verdicts are masks (0.0 / 1.0 rows),
the pivot choice and the row swaps of the Gauss-Jordan inversion are lane selects, and the
status is set at the end from the masks in the kernel's order (unreachable, limits, interfering
bars, singular). Loops over bars, legs and matrix entries sit outside the lane loop or have a
constant trip count (LLVM unrolls them before vectorising).

Why runtime-length lane loops and not 4 or 8 fixed lanes: numba compiles with LLVM's SLP
vectoriser off (``NUMBA_SLP_VECTORIZE=0``, a process-wide setting), and LLVM unrolls a loop of 4
or 8 constant trips completely before the loop vectoriser runs, so fixed tiny lane loops come out
scalar. A lane loop whose trip count is known only at run time (``nl <= LANES``) is vectorised by
the loop vectoriser (8 doubles per zmm register on AVX-512, interleaved).

The transcendental calls (cos, sin of theta; atan2 for q) stay scalar, in their own lane loops.
``fastmath`` is limited to flags that keep NaN and infinity semantics (:data:`FASTMATH`): the
verdicts are comparisons that must see NaN.

Same packed geometry as the kernel (:func:`h4pin.stiffness.kernel.prepare`), same outputs
(:class:`h4pin.stiffness.kernel.KernelResult`); robots whose parallelograms are exact.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from h4pin import _jit
from h4pin.kinematics.closed_form import as_poses
from h4pin.stiffness import core, kernel
from h4pin.stiffness.kernel import (
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
    KernelResult,
    _empty,
    _model_code,
    prepare,
)
from h4pin.verdicts import INTERFERENCE, LIMITS, OK, SINGULAR, SINGULAR_COND, UNREACHABLE

#: Poses per block (lanes of the scratch rows).
LANES = 32
#: Poses per parallel task (one scratch allocation per task).
TASK = 1024
#: fastmath flags: contraction to FMA, reciprocal, reassociation, no signed zeros; never
#: ``nnan`` / ``ninf`` (the verdicts compare NaN).
FASTMATH = {"contract", "arcp", "nsz", "reassoc"}

_SING = SINGULAR_COND
_CONSISTENT = core.CONSISTENT
_ST_OK, _ST_UNR, _ST_LIM, _ST_BAR, _ST_SING = OK, UNREACHABLE, LIMITS, INTERFERENCE, SINGULAR

# Rows of the block scratch S (rows x LANES).
_X, _Y, _Z, _TH, _CT, _SN = 0, 1, 2, 3, 4, 5
_CQ = 6  # (4,) cos q_i
_SQ = 10  # (4,) sin q_i
_A = 14  # (8, 3) A_n
_B = 38  # (8, 3) B_n
_W = 62  # (8, 3) w_n = B_n - A_n
_AA = 86  # (8,) |w_n|^2
_LW = 94  # (8,) |w_n|
_MM = 102  # (8, 8) M1, overwritten by the inversion
_YY = 166  # (8, 8) M1^-1
_GG = 230  # (8,) g_n
_DD = 238  # (8,) d_n
_EE = 246  # (8,) e_n
_GC = 254  # (8, 4) Gc[a, i] = M1^-1 M2 M3
_GS = 286  # (8, 4) (c_ctrl + c_bend)_i Gc[a, i]
_TU = 318  # (8, 4) c_tors_i sum_j d_n Y[a, n]
_TV = 350  # (8, 4) sum_j e_n l_n Y[a, n]
_YS = 382  # (8, 8) c_tens_n l_n^2 Y[a, n]
_KK = 446  # (8, 8) K
_UNR = 510  # masks (0.0 / 1.0): a leg cannot reach
_LIM = 511  # outside the joint limits
_HIT = 512  # two bars interfere
_ZERO = 513  # a zero pivot (exactly singular M1)
_BIG = 514  # pivot search
_PIV = 515
_NRM = 516  # 1-norm of the scaled M1
_LM = 517  # mean bar length
_CND = 518  # condition number
_PR = 520  # (16,) pivot row of M, Y
_OR = 536  # (16,) row c of M, Y before the swap
_IA = 552  # (8,) 1 / |w_n|^2
_Q = 560  # (4,) q_i
_ROWS = 564


@njit(cache=True, nogil=True, inline="always")
def _max(a, b):
    """numba's ``max(a, b)`` for floats (``b if b > a else a``) as a select the vectoriser takes."""
    return b if b > a else a


@njit(cache=True, nogil=True, inline="always")
def _min(a, b):
    """numba's ``min(a, b)`` for floats (``b if b < a else a``) as a select."""
    return b if b < a else a


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
    """q by :func:`atan2` (vectorised) and the joint-limit mask."""
    for i in range(4):
        for l in range(nl):
            S[_Q + i, l] = atan2(S[_SQ + i, l], S[_CQ + i, l])
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
def _bars(G, nl, S):
    """Bar vectors w_n, |w_n|^2, |w_n|, and the interference mask: the least distance between the
    axes of two bars of different legs below the clearance (:func:`core.seg_dist2`, branch-free)."""
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
        S[_HIT, l] = 0.0
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
                S[_HIT, l] = 1.0 if x * x + y * y + z * z < c2 else S[_HIT, l]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _matrix(G, nl, S):
    """M1 (eq. 6), g_n, and the torsion factors d_n, e_n (:func:`core.torsion_factors`)."""
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
                r = _MM + 8 * n
                S[r, l], S[r + 1, l], S[r + 2, l] = wx, wy, wz
                S[r + 3, l] = wy * sz - wz * sy
                S[r + 4, l] = wz * sx - wx * sz
                S[r + 5, l] = wx * sy - wy * sx
                tx = sx + ct * c0x - st * c0y
                ty = sy + st * c0x + ct * c0y
                mk = wx * ty - wy * tx
                S[r + 6, l] = mk if k == 0 else 0.0
                S[r + 7, l] = mk if k == 1 else 0.0
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
                S[_EE + n, l] = dn / S[_LW + n, l]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _swap(nl, S, X, c, need, e0):
    """Swap rows c and PIV of X (8, 8, lanes), columns e0..7, by lane selects: the new row c
    gathers in _PR + 1..8, the old one waits in _OR; each loop writes one side only (few runtime
    alias checks)."""
    for l in range(nl):
        for e in range(e0, 8):
            S[_OR + e, l] = X[c, e, l]
    for l in range(nl):
        for e in range(e0, 8):
            S[_PR + 1 + e, l] = S[_OR + e, l]
    for a in range(c + 1, 8):
        if not (need >> a) & 1:
            continue
        for l in range(nl):
            swap = S[_PIV, l] == a
            for e in range(e0, 8):
                S[_PR + 1 + e, l] = X[a, e, l] if swap else S[_PR + 1 + e, l]
        for l in range(nl):
            swap = S[_PIV, l] == a
            for e in range(e0, 8):
                X[a, e, l] = S[_OR + e, l] if swap else X[a, e, l]
    for l in range(nl):
        for e in range(e0, 8):
            X[c, e, l] = S[_PR + 1 + e, l]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _column(nl, S, M, Y, c):
    """Step c of the Gauss-Jordan inversion of M into Y (8, 8, lanes each): the pivot choice and
    the row swap are lane selects (:func:`core.invert_scaled`)."""
    for l in range(nl):  # pivot search: the first largest |M[a, c]|, a >= c
        S[_BIG, l] = abs(M[c, c, l])
        S[_PIV, l] = c
    for a in range(c + 1, 8):
        for l in range(nl):
            v = abs(M[a, c, l])
            better = v > S[_BIG, l]
            S[_BIG, l] = v if better else S[_BIG, l]
            S[_PIV, l] = a if better else S[_PIV, l]
    for l in range(nl):
        S[_ZERO, l] = 1.0 if S[_BIG, l] == 0.0 else S[_ZERO, l]
    need = 0  # bit a: some lane pivots on row a (a uniform branch: no lane work when unused)
    for l in range(nl):
        need |= 1 << int(S[_PIV, l])
    if need != 1 << c:
        _swap(nl, S, M, c, need, c)  # M's columns before c are zero below the diagonal
        _swap(nl, S, Y, c, need, 0)
    for l in range(nl):
        S[_PR, l] = 1.0 / M[c, c, l]
    for l in range(nl):  # M's column c is not read again: only its trailing columns
        inv = S[_PR, l]
        for e in range(c + 1, 8):
            M[c, e, l] *= inv
    for l in range(nl):
        inv = S[_PR, l]
        for e in range(8):
            Y[c, e, l] *= inv
    for a in range(8):
        if a != c:
            for l in range(nl):
                f = M[a, c, l]
                for e in range(8):
                    Y[a, e, l] -= f * Y[c, e, l]
            for l in range(nl):
                f = M[a, c, l]
                for e in range(c + 1, 8):
                    M[a, e, l] -= f * M[c, e, l]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _invert(nl, S, M, Y):
    """Y = M1^-1 by Gauss-Jordan with partial pivoting, per lane (:func:`core.invert_scaled`):
    pivot choice and row swaps are lane selects. Fills the condition row (inf when singular)."""
    for l in range(nl):
        lm = 0.0
        for n in range(8):
            lm += S[_LW + n, l]
        S[_LM, l] = lm / 8.0
        S[_NRM, l] = 0.0
        S[_ZERO, l] = 0.0
    for c in range(8):
        for l in range(nl):
            s = 0.0
            for n in range(8):
                s += abs(S[_MM + 8 * n + c, l]) / S[_LW + n, l]
            s = s / S[_LM, l] if c >= 3 else s
            S[_NRM, l] = _max(S[_NRM, l], s)
    for a in range(8):
        for e in range(8):
            for l in range(nl):
                M[a, e, l] = S[_MM + 8 * a + e, l]
                Y[a, e, l] = 1.0 if a == e else 0.0
    _column(nl, S, M, Y, 0)
    _column(nl, S, M, Y, 1)
    _column(nl, S, M, Y, 2)
    _column(nl, S, M, Y, 3)
    _column(nl, S, M, Y, 4)
    _column(nl, S, M, Y, 5)
    _column(nl, S, M, Y, 6)
    _column(nl, S, M, Y, 7)
    for a in range(8):
        for e in range(8):
            for l in range(nl):
                S[_YY + 8 * a + e, l] = Y[a, e, l]
    for l in range(nl):
        S[_BIG, l] = 0.0  # the 1-norm of the scaled M1^-1
    for n in range(8):
        for l in range(nl):
            lm = S[_LM, l]
            s = 0.0
            for a in range(8):
                s += abs(S[_YY + 8 * a + n, l]) * (lm if a >= 3 else 1.0)
            S[_BIG, l] = _max(S[_BIG, l], s * S[_LW + n, l])
    for l in range(nl):
        cond = S[_NRM, l] * S[_BIG, l]
        cond = cond if cond == cond else np.inf
        S[_CND, l] = np.inf if S[_ZERO, l] != 0.0 else cond


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _eq30(G, model, nl, S):
    """K of eq. 30 (:func:`core.eq30`): the 16 rank-one terms, entry by entry over the lanes."""
    for a in range(8):
        for i in range(4):
            cs = G[_CCTRL + i] + G[_CBEND + i]
            ct = G[_CTORS + i]
            n0, n1 = 2 * i, 2 * i + 1
            for l in range(nl):
                y0, y1 = S[_YY + 8 * a + n0, l], S[_YY + 8 * a + n1, l]
                gc = y0 * S[_GG + n0, l] + y1 * S[_GG + n1, l]
                S[_GC + 4 * a + i, l] = gc
                S[_GS + 4 * a + i, l] = cs * gc
                S[_TU + 4 * a + i, l] = ct * (y0 * S[_DD + n0, l] + y1 * S[_DD + n1, l])
                S[_TV + 4 * a + i, l] = (y0 * S[_EE + n0, l] * S[_LW + n0, l] + y1 * S[_EE + n1, l] * S[_LW + n1, l])
        for n in range(8):
            cn = G[_CTENS + n]
            for l in range(nl):
                S[_YS + 8 * a + n, l] = cn * S[_LW + n, l] * S[_LW + n, l] * S[_YY + 8 * a + n, l]
    for a in range(8):
        for c in range(8):
            load = 1.0 if (model == _CONSISTENT or c < 3 or c == 5) else 0.0
            for l in range(nl):
                k = 0.0
                for i in range(4):
                    k += S[_GS + 4 * a + i, l] * S[_GC + 4 * c + i, l] * load
                    k += S[_TU + 4 * a + i, l] * S[_TV + 4 * c + i, l]
                for n in range(8):
                    k += S[_YS + 8 * a + n, l] * S[_YY + 8 * c + n, l]
                S[_KK + 8 * a + c, l] = k


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _store(p0, nl, S, K, qo, cond, status):
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
        if st == _ST_OK:
            for a in range(8):
                for c in range(8):
                    K[p, a, c] = S[_KK + 8 * a + c, l]
        else:
            for a in range(8):
                for c in range(8):
                    K[p, a, c] = np.nan


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH)
def _run(poses, start, stop, G, model, K, qo, cond, status):
    """Poses start .. stop - 1, in blocks of at most LANES lanes of one scratch S (allocated here,
    so that its shape is a compile-time constant in every lane loop)."""
    S = np.empty((_ROWS, LANES))
    M = np.empty((8, 8, LANES))
    Y = np.empty((8, 8, LANES))
    for p0 in range(start, stop, LANES):
        nl = min(LANES, stop - p0)
        _load(poses, p0, nl, S)
        _legs(G, nl, S)
        _angles(G, nl, S)
        _bars(G, nl, S)
        _matrix(G, nl, S)
        _invert(nl, S, M, Y)
        _eq30(G, model, nl, S)
        _store(p0, nl, S, K, qo, cond, status)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH, parallel=True)
def _vbatch(poses, G, model, K, qo, cond, status, task):
    n = poses.shape[0]
    ntasks = (n + task - 1) // task
    for t in prange(ntasks):
        _run(poses, t * task, min(n, (t + 1) * task), G, model, K, qo, cond, status)


def compliance_batch(g: Any, poses: np.ndarray, model: str = "paper", out: KernelResult | None = None) -> KernelResult:
    """K of eq. 30, q, the condition and the verdict at N poses, poses in lanes (the same fields
    and numbers as :func:`h4pin.stiffness.kernel.compliance_batch` without terms or J).

    Args:
        g: A geometry (see :func:`h4pin.stiffness.kernel.prepare`) or a prepared kernel.
        poses: (N, 4) or (4,) poses [x, y, z, theta] (m, rad).
        model: ``"paper"`` or ``"consistent"``.
        out: Arrays to fill (a :class:`KernelResult`); allocated if None.

    The number of threads is numba's (``numba.set_num_threads``).
    """
    kern = prepare(g)
    code = _model_code(model)
    x = as_poses(poses)
    x = np.ascontiguousarray(x[None] if x.ndim == 1 else x, dtype=np.float64)
    n = len(x)
    res = _empty(n, False, False) if out is None else out
    if n:
        _vbatch(x, kern.packed, code, res.K, res.q, res.condition, res.status, TASK)
    return res


#: Whether :func:`_vbatch` is compiled (:mod:`h4pin._jit`); until then the scalar kernel runs.
VECTOR = _jit.Gate("vector kernel", _vbatch)
#: Batches from this many poses without terms take the vector kernel (below it, the scalar
#: kernel's serial loop: a block of lanes costs more than a few poses one by one).
VECTOR_FROM = 64


def backend(h4, x: np.ndarray, model: str, terms: bool):
    """The kernel backend of :func:`h4pin.compliance` (``method="kernel"``, and ``"auto"`` on a
    robot with exact parallelograms): the vector kernel for batches of :data:`VECTOR_FROM` poses
    or more without terms, else the scalar kernel (:func:`h4pin.stiffness.kernel.backend`), which
    also gives the terms. ``x``: checked (N, 4) finite poses."""
    if terms or len(x) < VECTOR_FROM or not VECTOR.ready:
        return kernel.backend(h4, x, model, terms)
    from h4pin.stiffness.eq30 import MODELS, Raw

    res = _empty(len(x), False, False)
    _vbatch(np.ascontiguousarray(x, dtype=np.float64), kernel.for_geometry(h4.geometry).packed, MODELS.index(model),
            res.K, res.q, res.condition, res.status, TASK)
    return Raw(res.K, None, res.q, res.condition, res.status)


__all__ = ["FASTMATH", "LANES", "TASK", "VECTOR_FROM", "backend", "compliance_batch"]
