# SPDX-License-Identifier: Apache-2.0
"""The compiled pipeline: eq. 30 of Company, Pierrot and Fauroux (ICRA 2005) and the robot's
compliant elements, from a pose to K, written once (numba) for every compiled call.

One pose and a batch run the same functions: :func:`run` takes poses ``start .. stop - 1`` of an
(N, 4) array in blocks of at most :data:`LANES` poses (one pose is a block of one lane). The
stages, in order (each a compiled function of its own, called by :func:`run`):

1. :func:`_legs`, :func:`_angles`: the closed-form inverse geometry (elbow out) and the
   unreachable and joint-limit masks;
2. :func:`_bars`: the bar vectors w_n and the interfering-bars mask;
3. :func:`_matrix`: M1 of eq. 6, g_n (row n of M2 M3, eq. 11), d_n (eq. 23) and the two 4 x 4
   blocks M1 reduces to for exact parallelograms (:func:`_invert`);
4. :func:`_invert`: M1^-1 and the scaled condition number (the singular verdict);
5. :func:`_factors`, :func:`_elements`, :func:`_assemble`: eq. 30 and the element terms;
6. :func:`_store`: the verdict per pose in the order of :mod:`h4pin.verdicts`, K, the terms, q, J.

Layout: every intermediate of a block is a row of a block-local array (rows x lanes). Every
innermost loop runs over the lanes with no branch (the verdicts are masks, pivoting is by lane
selects) and every loop inside a lane loop has a constant trip count, so that LLVM's loop
vectoriser emits packed code (AVX2 / AVX-512 FMA) for each. ``fastmath`` keeps NaN and infinity
semantics (:data:`FASTMATH`): the verdicts are comparisons that must see NaN.

**M1^-1 by two 4 x 4 solves.** For exact parallelograms (the robots this pipeline takes) both
bars of leg i have the same vector w_i and B_i1 - B_i2 = 2 o_i. With the half-sum and half-difference
of the two rows of each leg, M1 x = b becomes block-triangular in
``z = [dD, dOmega_z | dOmega_x, dOmega_y, rho_1z, rho_2z]`` (rho_k = dOmega + domega_k z, the
rotation of lateral bar k):

* the differences: ``-n_i . rho_k = bd_i`` with ``n_i = w_i x o_i`` (a 4 x 4 system ``Rm``);
* the sums: ``w_i . dD + (w_i . (z x c_k)) dOmega_z + G_i . (lower z) = bs_i`` (``Jx``, eq. 8's
  4 x 4 Jacobian, and a coupling G), with c_k = C_k - D and m_i = w_i x (C_k - B_i):
  ``G_i = [w_i . (x x c_k) + m_ix, w_i . (y x c_k) + m_iy, m_iz (k = 1), m_iz (k = 2)]``.

Hence ``z_lower = -Rm^-1 bd`` and ``z_upper = Jx^-1 bs + Jx^-1 G Rm^-1 bd``: two 4 x 4
inversions (adjugate over determinant, branch-free, one lane loop each) and two products, where
a general 8 x 8 Gauss-Jordan inversion with pivoting by lane selects took about 300 small lane
loops (2 us of fixed cost for one pose, 0.25 us a pose in a block). M1 itself is kept for the
scaled condition number of :func:`h4pin.stiffness.eq30.condition`.

**Elements.** Every load an element carries is a combination of the bars' pulls ``Y[:, n] w_n``
per unit Gamma_ext (Y = M1^-1; ``Jb^-1 = diag(l) M1^-T``, eq. 16), so each element kind is an
8 x 8 bar-space compliance E and its term is ``Y E Y^T``. E is read from a table built from the
element schema (:data:`h4pin.description.elements.KINDS`: the site whose wrench the element
carries, the form of its compliance and its axis), so a new kind that combines existing sites,
forms and axes is a row of the schema, not new compiled code (:func:`_element_kind`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from h4pin import _jit
from h4pin.description.elements import (
    AXIS_ACTUATOR,
    AXIS_ARM,
    AXIS_BAR,
    AXIS_CENTRAL,
    AXIS_FOREARM,
    FORM_BEAM_BENDING,
    FORM_BEAM_BENDING_OUT,
    FORM_BEAM_TORSION,
    FORM_COUPLE,
    FORM_COUPLE_AXIAL,
    FORM_COUPLE_NORMAL,
    FORM_FORCE,
    FORM_FORCE_AXIAL,
    FORM_FORCE_NORMAL,
    SITE_ARM,
    SITE_BAR,
    SITE_JOINT,
    SITE_MOUNT,
    SITE_TIP,
)
from h4pin.stiffness.packed import (
    EL_HEADER,
    EL_ROW,
    G_BB,
    G_BM,
    G_C0,
    G_CBEND,
    G_CCTRL,
    G_CLEAR,
    G_CTENS,
    G_CTORS,
    G_LAT,
    G_LL,
    G_M,
    G_P,
    G_QHI,
    G_QLO,
    G_R2,
    G_U,
    G_UM,
    G_UV,
    G_UVU,
    G_V,
    G_WHI,
    G_WLO,
)
from h4pin.verdicts import INTERFERENCE, LIMITS, OK, SINGULAR, SINGULAR_COND, UNREACHABLE

#: numba ``fastmath`` flags: contraction to FMA, reciprocal, no signed zeros. Never ``nnan`` /
#: ``ninf`` (the verdicts compare NaN), nor ``reassoc``: K with its terms is their sum, in the
#: order of :data:`h4pin.stiffness.eq30.TERMS`, to the bit.
FASTMATH = {"contract", "arcp", "nsz"}
#: Model codes of the compiled functions (:data:`h4pin.stiffness.eq30.MODELS` order).
PAPER, CONSISTENT = 0, 1
#: Poses per block (the lanes of the scratch rows): 64 was the fastest of 16 to 128 on one core;
#: a block's arrays (about 300 KB) stay in L2.
LANES = 64

_STAGE = dict(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH)
_SING = SINGULAR_COND

# Rows of the block scratch S (rows x LANES).
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
_CK = 134  # (2, 3) c_k = C_k - D
_ROWS = 140
#: Rows of the lane scratch that the natural frequencies read in a pose's intermediates (:data:`X_S`).
S_A, S_B, S_LW, S_ROWS = _A, _B, _LW, _ROWS

# Rows of the factors F of eq. 30 (rows x LANES; :func:`_factors`).
_GC = 0  # (8, 4) Gc[a, i] = M1^-1 M2 M3
_GS = 32  # (8, 4) (c_ctrl + c_bend)_i Gc[a, i]
_TV = 64  # (8, 4) v[a, i] = sum_j d_n Y[a, n]
_TU = 96  # (8, 4) c_tors_i v[a, i]
_YS = 128  # (8, 8) c_tens_n l_n^2 Y[a, n]
_FROWS = 192
#: Rows of the factors that the natural frequencies read (:data:`X_F`).
F_GC, F_TV = _GC, _TV

# Rows of the inversion's scratch R (rows x LANES).
_ZERO = 0  # a zero or non-finite determinant (exactly singular M1)
_NRM = 1  # 1-norm of the scaled M1
_LM = 2  # mean bar length
_RROWS = 3

# The 4 x 4 blocks of the inversion (block index, 4, 4, LANES).
_JX, _GB, _RM, _AI, _QI, _HB = 0, 1, 2, 3, 4, 5

# Rows of the element scratch X (rows x LANES; :func:`_element_kind`).
_EF = 0  # (4, 3) the force each bar of the site puts on it (w_m)
_EM = 12  # (4, 3) its moment about the site's point
_EA = 24  # (3,) the element's axis (first the site's point)
_EN = 27  # (3,) its second axis
_EU = 30  # (6,) the part u_t of its form
_EB = 36  # (3,) its frame's second normal b
_EG = 39  # (4,) u_t . w_a per bar a of the site
#: Rows of the element scratch (:func:`element_axis`, :func:`site_point` write into them).
EA, XROWS = _EA, 43


@njit(cache=True, nogil=True, inline="always")
def _max(a, b):
    """numba's ``max(a, b)`` for floats (``b if b > a else a``) as a select the vectoriser takes."""
    return b if b > a else a


@njit(cache=True, nogil=True, inline="always")
def _cross_t(ax, ay, az, bx, by, bz):
    """(a x b) as a tuple."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True, nogil=True, inline="always")
def _min(a, b):
    """numba's ``min(a, b)`` for floats (``b if b < a else a``) as a select."""
    return b if b < a else a


# Cephes' atan (Moshier): a rational approximation on |u| <= 0.66 after one range reduction,
# relative error below 2e-16 (tests/test_pipeline.py: at most 2 ulp against numpy's arctan2).
_AP = (-8.750608600031904122785e-01, -1.615753718733365076637e+01, -7.500855792314704667340e+01,
       -1.228866684490136173410e+02, -6.485021904942025371773e+01)
_AQ = (2.485846490142306297962e+01, 1.650270098316988542046e+02, 4.328810604912902668951e+02,
       4.853903996359136964868e+02, 1.945506571482613964425e+02)
_MOREBITS = 6.123233995736765886130e-17  # pi/2 - float(pi/2)


@njit(**_STAGE)
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


@njit(**_STAGE)
def _load(poses, p0, nl, lanes, G, S):
    """Poses p0 .. p0 + nl - 1 into the first nl of ``lanes`` lanes, the last one repeated in the
    others (every stage then runs a constant number of lanes, and a lane's results are its own);
    cos and sin of theta, and c_k = C_k - D = Rz(theta) C0_k."""
    c00, c01, c02 = G[G_C0], G[G_C0 + 1], G[G_C0 + 2]
    c10, c11, c12 = G[G_C0 + 3], G[G_C0 + 4], G[G_C0 + 5]
    for l in range(lanes):  # scalar libm calls: this loop is not vectorised
        p = p0 + min(l, nl - 1)
        th = poses[p, 3]
        ct, st = np.cos(th), np.sin(th)
        S[_X, l], S[_Y, l], S[_Z, l], S[_TH, l] = poses[p, 0], poses[p, 1], poses[p, 2], th
        S[_CT, l], S[_SN, l] = ct, st
        S[_CK, l], S[_CK + 1, l], S[_CK + 2, l] = ct * c00 - st * c01, st * c00 + ct * c01, c02
        S[_CK + 3, l], S[_CK + 4, l], S[_CK + 5, l] = ct * c10 - st * c11, st * c10 + ct * c11, c12


@njit(**_STAGE)
def _legs(G, nl, S):
    """Inverse geometry of the four legs on the leg mid-points (``alpha cos q + beta sin q =
    rhs``, elbow out, branch-free): cos q, sin q, A, B and the unreachable mask."""
    for l in range(nl):
        S[_UNR, l] = 0.0
    for i in range(4):
        k = int(G[G_LAT + 2 * i])
        ck = _CK + 3 * k
        ox = G[G_BM + 3 * i] - G[G_P + 3 * i]
        oy = G[G_BM + 3 * i + 1] - G[G_P + 3 * i + 1]
        oz = G[G_BM + 3 * i + 2] - G[G_P + 3 * i + 2]
        mx, my, mz = G[G_M + 3 * i], G[G_M + 3 * i + 1], G[G_M + 3 * i + 2]
        nx, ny, nz = G[G_UM + 3 * i], G[G_UM + 3 * i + 1], G[G_UM + 3 * i + 2]
        r2l2 = G[G_R2 + i] - G[G_LL + i] * G[G_LL + i]
        for l in range(nl):
            ex = S[_X, l] + S[ck, l] + ox
            ey = S[_Y, l] + S[ck + 1, l] + oy
            ez = S[_Z, l] + S[ck + 2, l] + oz
            alpha = ex * mx + ey * my + ez * mz
            beta = ex * nx + ey * ny + ez * nz
            rhs = 0.5 * (ex * ex + ey * ey + ez * ez + r2l2)
            rho = np.sqrt(alpha * alpha + beta * beta)
            bad = (not (rho > 0.0)) | (abs(rhs) > rho)
            S[_UNR, l] = 1.0 if bad else S[_UNR, l]
            cd = rhs / rho
            sd = np.sqrt(_max(1.0 - cd * cd, 0.0))
            cphi, sphi = alpha / rho, beta / rho
            S[_CQ + i, l] = cphi * cd + sphi * sd  # q = phi - delta
            S[_SQ + i, l] = sphi * cd - cphi * sd
        for j in range(2):
            n = 2 * i + j
            for a in range(3):
                pa, va, wa, ua = G[G_P + 3 * i + a], G[G_V + 3 * n + a], G[G_UV + 3 * n + a], G[G_UVU + 3 * n + a]
                ba = G[G_BB + 3 * n + a]
                for l in range(nl):
                    cq, sq = S[_CQ + i, l], S[_SQ + i, l]
                    S[_A + 3 * n + a, l] = pa + cq * va + sq * wa + (1.0 - cq) * ua
                    S[_B + 3 * n + a, l] = S[_X + a, l] + S[ck + a, l] + ba


@njit(**_STAGE)
def _angles(G, nl, S):
    """q by :func:`atan2` (vectorised) and the joint-limit mask."""
    for i in range(4):
        for l in range(nl):
            S[_Q + i, l] = atan2(S[_SQ + i, l], S[_CQ + i, l])
    lo0, lo1, lo2, lo3 = G[G_QLO], G[G_QLO + 1], G[G_QLO + 2], G[G_QLO + 3]
    hi0, hi1, hi2, hi3 = G[G_QHI], G[G_QHI + 1], G[G_QHI + 2], G[G_QHI + 3]
    w0, w1, v0, v1 = G[G_WLO], G[G_WLO + 1], G[G_WHI], G[G_WHI + 1]
    for l in range(nl):
        q0, q1, q2, q3 = S[_Q, l], S[_Q + 1, l], S[_Q + 2, l], S[_Q + 3, l]
        w = -S[_TH, l]
        inside = ((lo0 <= q0) & (q0 <= hi0) & (lo1 <= q1) & (q1 <= hi1) & (lo2 <= q2) & (q2 <= hi2)
                  & (lo3 <= q3) & (q3 <= hi3) & (w0 <= w) & (w <= v0) & (w1 <= w) & (w <= v1))
        S[_LIM, l] = 0.0 if inside else 1.0


@njit(**_STAGE)
def _bars(G, nl, S, H):
    """Bar vectors w_n, |w_n|^2, |w_n|, and the interference mask: the least distance between the
    axes of two bars of different legs below the clearance (Ericson, Real-Time Collision
    Detection 5.1.9, branch-free). The mask builds up in H (LANES,), an array apart from S (a
    read-modify-write of a row of S in the pair loop, with its 17 other rows read, kept LLVM from
    vectorising it)."""
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
    c2 = G[G_CLEAR] * G[G_CLEAR]
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


@njit(**_STAGE)
def _matrix(G, nl, S, M, Bk):
    """M1 (eq. 6, row n = [w_n, w_n x (D - B_n), (w_n x (C_k - B_n)).z in column 6 + k]) into M
    (8, 8, LANES), g_n = w_n . (p_n x u_i) (row n of M2 M3), d_n = w_n . (p_n x r_i) (eq. 23,
    p_n = P_i - A_n, r_i the unit vector A_i -> P_i), and the blocks Jx, G, Rm of the module
    docstring into Bk."""
    for i in range(4):
        px, py, pz = G[G_P + 3 * i], G[G_P + 3 * i + 1], G[G_P + 3 * i + 2]
        ux, uy, uz = G[G_U + 3 * i], G[G_U + 3 * i + 1], G[G_U + 3 * i + 2]
        k = int(G[G_LAT + 2 * i])
        ck = _CK + 3 * k
        for j in range(2):
            n = 2 * i + j
            for l in range(nl):
                wx, wy, wz = S[_W + 3 * n, l], S[_W + 3 * n + 1, l], S[_W + 3 * n + 2, l]
                sx = S[_X, l] - S[_B + 3 * n, l]
                sy = S[_Y, l] - S[_B + 3 * n + 1, l]
                sz = S[_Z, l] - S[_B + 3 * n + 2, l]
                M[n, 0, l], M[n, 1, l], M[n, 2, l] = wx, wy, wz
                M[n, 3, l] = wy * sz - wz * sy
                M[n, 4, l] = wz * sx - wx * sz
                M[n, 5, l] = wx * sy - wy * sx
                mk = wx * (sy + S[ck + 1, l]) - wy * (sx + S[ck, l])
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
                S[_DD + n, l] = (S[_W + 3 * n, l] * (qy * rz - qz * ry) + S[_W + 3 * n + 1, l] * (qz * rx - qx * rz)
                                 + S[_W + 3 * n + 2, l] * (qx * ry - qy * rx))
        bmx, bmy, bmz = G[G_BM + 3 * i], G[G_BM + 3 * i + 1], G[G_BM + 3 * i + 2]
        for l in range(nl):
            n0, n1 = 6 * i, 6 * i + 3
            wx = 0.5 * (S[_W + n0, l] + S[_W + n1, l])
            wy = 0.5 * (S[_W + n0 + 1, l] + S[_W + n1 + 1, l])
            wz = 0.5 * (S[_W + n0 + 2, l] + S[_W + n1 + 2, l])
            ox = 0.5 * (S[_B + n0, l] - S[_B + n1, l])
            oy = 0.5 * (S[_B + n0 + 1, l] - S[_B + n1 + 1, l])
            oz = 0.5 * (S[_B + n0 + 2, l] - S[_B + n1 + 2, l])
            cx, cy, cz = S[ck, l], S[ck + 1, l], S[ck + 2, l]
            mx, my, mz = wz * bmy - wy * bmz, wx * bmz - wz * bmx, wy * bmx - wx * bmy  # w x (C_k - B_i)
            Bk[_JX, i, 0, l], Bk[_JX, i, 1, l], Bk[_JX, i, 2, l] = wx, wy, wz
            Bk[_JX, i, 3, l] = wy * cx - wx * cy
            Bk[_GB, i, 0, l] = wz * cy - wy * cz + mx
            Bk[_GB, i, 1, l] = wx * cz - wz * cx + my
            Bk[_GB, i, 2, l] = mz if k == 0 else 0.0
            Bk[_GB, i, 3, l] = mz if k == 1 else 0.0
            nz = wx * oy - wy * ox
            Bk[_RM, i, 0, l] = wy * oz - wz * oy
            Bk[_RM, i, 1, l] = wz * ox - wx * oz
            Bk[_RM, i, 2, l] = nz if k == 0 else 0.0
            Bk[_RM, i, 3, l] = nz if k == 1 else 0.0


@njit(cache=True, nogil=True, inline="always")
def _c3(i, x, p, y, q, z, r):
    """(x p - y q + z r) i: an entry of :func:`_inv4`, a 3 x 3 cofactor (a row's entries and 2 x 2
    minors) over the determinant (i its signed inverse)."""
    return (x * p - y * q + z * r) * i


@njit(cache=True, nogil=True, inline="always")
def _column(Z, c, l, z0, z1, z2, z3):
    """Column c of lane l of Z (4, 4, LANES) = (z0, z1, z2, z3)."""
    Z[0, c, l], Z[1, c, l], Z[2, c, l], Z[3, c, l] = z0, z1, z2, z3


@njit(**_STAGE)
def _inv4(nl, Bk, src, dst, R):
    """Bk[dst] = Bk[src]^-1 (4 x 4 per lane) by the adjugate over the determinant, from the 2 x 2
    minors of the first two and the last two rows (Laplace); a zero or non-finite determinant
    sets R[_ZERO] (an exactly singular M1)."""
    X, Z = Bk[src], Bk[dst]
    for l in range(nl):
        a00, a01, a02, a03 = X[0, 0, l], X[0, 1, l], X[0, 2, l], X[0, 3, l]
        a10, a11, a12, a13 = X[1, 0, l], X[1, 1, l], X[1, 2, l], X[1, 3, l]
        a20, a21, a22, a23 = X[2, 0, l], X[2, 1, l], X[2, 2, l], X[2, 3, l]
        a30, a31, a32, a33 = X[3, 0, l], X[3, 1, l], X[3, 2, l], X[3, 3, l]
        s0, s1, s2 = a00 * a11 - a10 * a01, a00 * a12 - a10 * a02, a00 * a13 - a10 * a03
        s3, s4, s5 = a01 * a12 - a11 * a02, a01 * a13 - a11 * a03, a02 * a13 - a12 * a03
        c5, c4, c3 = a22 * a33 - a32 * a23, a21 * a33 - a31 * a23, a21 * a32 - a31 * a22
        c2, c1, c0 = a20 * a33 - a30 * a23, a20 * a32 - a30 * a22, a20 * a31 - a30 * a21
        det = s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0
        bad = not (det != 0.0 and abs(det) < np.inf)
        R[_ZERO, l] = 1.0 if bad else R[_ZERO, l]
        i = 1.0 / det
        _column(Z, 0, l, _c3(i, a11, c5, a12, c4, a13, c3), _c3(-i, a10, c5, a12, c2, a13, c1),
                _c3(i, a10, c4, a11, c2, a13, c0), _c3(-i, a10, c3, a11, c1, a12, c0))
        _column(Z, 1, l, _c3(-i, a01, c5, a02, c4, a03, c3), _c3(i, a00, c5, a02, c2, a03, c1),
                _c3(-i, a00, c4, a01, c2, a03, c0), _c3(i, a00, c3, a01, c1, a02, c0))
        _column(Z, 2, l, _c3(i, a31, s5, a32, s4, a33, s3), _c3(-i, a30, s5, a32, s2, a33, s1),
                _c3(i, a30, s4, a31, s2, a33, s0), _c3(-i, a30, s3, a31, s1, a32, s0))
        _column(Z, 3, l, _c3(-i, a21, s5, a22, s4, a23, s3), _c3(i, a20, s5, a22, s2, a23, s1),
                _c3(-i, a20, s4, a21, s2, a23, s0), _c3(i, a20, s3, a21, s1, a22, s0))


@njit(**_STAGE)
def _invert(nl, S, M, Y, Bk, R):
    """Y = M1^-1 (8, 8, LANES) from the blocks of :func:`_matrix` (module docstring) and the
    1-norm condition number of the scaled M1 (rows over l_n, columns 3..7 over the mean bar
    length, as :func:`h4pin.stiffness.eq30.condition`) into S; ``inf`` for an exactly singular M1."""
    for l in range(nl):  # the 1-norm of the scaled M1
        lm = 0.0
        for n in range(8):
            lm += S[_LW + n, l]
        R[_LM, l] = lm / 8.0
        ilm = 8.0 / lm
        norm = 0.0
        for c in range(8):
            t = 0.0
            for n in range(8):
                t += abs(M[n, c, l]) / S[_LW + n, l]
            norm = _max(norm, t * ilm if c >= 3 else t)
        R[_NRM, l] = norm
        R[_ZERO, l] = 0.0
    for b in range(2):  # Jx^-1 and Rm^-1 (one copy of the code: a loop, not two calls)
        _inv4(nl, Bk, _JX if b == 0 else _RM, _AI if b == 0 else _QI, R)
    for l in range(nl):  # T = G Rm^-1, kept in Bk[_JX] (spent)
        for a in range(4):
            for e in range(4):
                Bk[_JX, a, e, l] = (Bk[_GB, a, 0, l] * Bk[_QI, 0, e, l] + Bk[_GB, a, 1, l] * Bk[_QI, 1, e, l]
                                    + Bk[_GB, a, 2, l] * Bk[_QI, 2, e, l] + Bk[_GB, a, 3, l] * Bk[_QI, 3, e, l])
    for l in range(nl):  # H = Jx^-1 T
        for a in range(4):
            for e in range(4):
                Bk[_HB, a, e, l] = (Bk[_AI, a, 0, l] * Bk[_JX, 0, e, l] + Bk[_AI, a, 1, l] * Bk[_JX, 1, e, l]
                                    + Bk[_AI, a, 2, l] * Bk[_JX, 2, e, l] + Bk[_AI, a, 3, l] * Bk[_JX, 3, e, l])
    for l in range(nl):  # column n = 2 i + j: z_upper = (A + s H)[:, i] / 2, z_lower = -s Q[:, i] / 2
        for i in range(4):
            for j in range(2):
                n = 2 * i + j
                s = 0.5 if j == 0 else -0.5
                up3 = 0.5 * Bk[_AI, 3, i, l] + s * Bk[_HB, 3, i, l]
                Y[0, n, l] = 0.5 * Bk[_AI, 0, i, l] + s * Bk[_HB, 0, i, l]
                Y[1, n, l] = 0.5 * Bk[_AI, 1, i, l] + s * Bk[_HB, 1, i, l]
                Y[2, n, l] = 0.5 * Bk[_AI, 2, i, l] + s * Bk[_HB, 2, i, l]
                Y[5, n, l] = up3
                Y[3, n, l] = -s * Bk[_QI, 0, i, l]
                Y[4, n, l] = -s * Bk[_QI, 1, i, l]
                Y[6, n, l] = -s * Bk[_QI, 2, i, l] - up3
                Y[7, n, l] = -s * Bk[_QI, 3, i, l] - up3
    for l in range(nl):  # the 1-norm of the scaled M1^-1, the condition
        lm = R[_LM, l]
        norm = 0.0
        for n in range(8):
            t = abs(Y[0, n, l]) + abs(Y[1, n, l]) + abs(Y[2, n, l])
            t += lm * (abs(Y[3, n, l]) + abs(Y[4, n, l]) + abs(Y[5, n, l]) + abs(Y[6, n, l]) + abs(Y[7, n, l]))
            norm = _max(norm, t * S[_LW + n, l])
        cond = R[_NRM, l] * norm
        cond = cond if cond == cond else np.inf
        S[_CND, l] = np.inf if R[_ZERO, l] != 0.0 else cond


@njit(**_STAGE)
def _factors(G, nl, S, Y, F):
    """The factors of eq. 30 per lane (rows of F): ``Gc = M1^-1 M2 M3`` (8, 4) (its rows 0, 1, 2,
    5 are J of eq. 8), ``(c_ctrl + c_bend) Gc``, the torsion vectors ``v_i = sum_j d_n Y[:, n]``
    and ``c_tors v_i`` (eq. 23; e_n l_n = d_n), and ``c_tens_n l_n^2 Y[:, n]`` (eq. 27)."""
    for a in range(8):
        for i in range(4):
            cs = G[G_CCTRL + i] + G[G_CBEND + i]
            ct = G[G_CTORS + i]
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
            cn = G[G_CTENS + n]
            for l in range(nl):
                F[_YS + 8 * a + n, l] = cn * S[_AA + n, l] * Y[a, n, l]


@njit(**_STAGE)
def site_bars(G, site, s, m):
    """Whether bar m loads element s of a kind whose site is ``site``
    (:data:`h4pin.description.elements.SITES`): the bars of lateral bar s, bar s, or those of leg s."""
    if site == SITE_JOINT:
        return int(G[G_LAT + m]) == s
    if site == SITE_BAR:
        return m == s
    return m // 2 == s


@njit(**_STAGE)
def site_point(G, site, s, m, nl, S, X):
    """The point about which element s's wrench is taken, into rows :data:`EA` of X: C_k of
    lateral bar s (joint), B_i of leg s (arm), P_i (mount), A_i (tip), or bar m's end B_m (bar)."""
    if site == SITE_JOINT:
        for d in range(3):
            for l in range(nl):
                X[_EA + d, l] = S[_X + d, l] + S[_CK + 3 * s + d, l]
    elif site == SITE_MOUNT:
        for d in range(3):
            for l in range(nl):
                X[_EA + d, l] = G[G_P + 3 * s + d]
    elif site == SITE_ARM or site == SITE_TIP:
        pt = _B if site == SITE_ARM else _A
        for d in range(3):
            for l in range(nl):
                X[_EA + d, l] = 0.5 * (S[pt + 6 * s + d, l] + S[pt + 6 * s + 3 + d, l])
    else:
        for d in range(3):
            for l in range(nl):
                X[_EA + d, l] = S[_B + 3 * m + d, l]


@njit(**_STAGE)
def element_axis(G, axis, s, nl, S, X, row):
    """Element s's unit axis (:data:`h4pin.description.elements.AXES`) into rows ``row`` .. row + 2
    of X: z (none, z, and the lateral revolutes of the exact robots this pipeline takes), u_i
    (actuator), C_k - D (central segment), B_i - C_k (lateral arm), A_i - P_i (forearm) or w_n (bar)."""
    for d in range(3):
        if axis == AXIS_ACTUATOR:
            for l in range(nl):
                X[row + d, l] = G[G_U + 3 * s + d]
        elif axis == AXIS_CENTRAL:
            for l in range(nl):
                X[row + d, l] = S[_CK + 3 * s + d, l]
        elif axis == AXIS_ARM:
            for l in range(nl):
                X[row + d, l] = G[G_BM + 3 * s + d]
        elif axis == AXIS_FOREARM:
            for l in range(nl):
                X[row + d, l] = 0.5 * (S[_A + 6 * s + d, l] + S[_A + 6 * s + 3 + d, l]) - G[G_P + 3 * s + d]
        elif axis == AXIS_BAR:
            for l in range(nl):
                X[row + d, l] = S[_W + 3 * s + d, l]
        else:  # AXIS_NONE, AXIS_Z, AXIS_REVOLUTE
            for l in range(nl):
                X[row + d, l] = 1.0 if d == 2 else 0.0
    for l in range(nl):
        ax, ay, az = X[row, l], X[row + 1, l], X[row + 2, l]
        inv = 1.0 / np.sqrt(ax * ax + ay * ay + az * az)
        X[row, l], X[row + 1, l], X[row + 2, l] = ax * inv, ay * inv, az * inv


@njit(**_STAGE)
def form_count(form):
    """How many rank-one parts :func:`form_part` gives an element of this form."""
    if form == FORM_FORCE or form == FORM_COUPLE:
        return 3
    if form == FORM_FORCE_NORMAL or form == FORM_COUPLE_NORMAL or form == FORM_BEAM_BENDING_OUT:
        return 2
    return 4 if form == FORM_BEAM_BENDING else 1


@njit(cache=True, nogil=True)
def form_part(form, t, c, length):
    """Part t of an element's compliance in its form (:data:`h4pin.description.elements.FORMS`):
    ``C = sum_t c_t u_t u_t^T`` over :func:`form_count` parts, u_t (6,) a twist [translation;
    rotation] at the site's point, dual to its wrench [force; couple], given in the element's
    frame (e its unit axis, a and b the unit normals of :func:`form_frame`) and the world's:
    returns ``(c_t, fe, fa, fb, fw, me, ma, mb, mw)`` with ``u_t = [fe e + fa a + fb b + fw x_t;
    me e + ma a + mb b + mw x_t]`` (x_t world axis t), from the element's compliance c (1/EI,
    1/GJ for a beam) and length. A beam's bending in the plane of e and a:
    ``L^3/(3EI) (f.a + 3 m.b / (2L))^2 + L/(4EI) (m.b)^2`` (the cantilever of
    :func:`h4pin.stiffness.elements.beam_compliance`), then in the plane of e and b (with -a);
    out of plane (a along the second axis), the first plane only. The one compiled term of a
    form: the compliance (:func:`_element_kind`) and the natural frequencies
    (:mod:`h4pin.stiffness.frequencies`) both read it; its numbers do not depend on the pose
    (scalars, computed once an element, outside the lane loops)."""
    if form == FORM_FORCE or form == FORM_COUPLE:
        rot = 1.0 if form == FORM_COUPLE else 0.0
        return c, 0.0, 0.0, 0.0, 1.0 - rot, 0.0, 0.0, 0.0, rot
    if form == FORM_FORCE_NORMAL or form == FORM_COUPLE_NORMAL:
        rot = 1.0 if form == FORM_COUPLE_NORMAL else 0.0
        a, b = (1.0, 0.0) if t == 0 else (0.0, 1.0)
        return c, 0.0, (1.0 - rot) * a, (1.0 - rot) * b, 0.0, 0.0, rot * a, rot * b, 0.0
    if form == FORM_FORCE_AXIAL:
        return c, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if form == FORM_COUPLE_AXIAL or form == FORM_BEAM_TORSION:
        return c * length if form == FORM_BEAM_TORSION else c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0
    k = 1.5 / length  # beams bending: t = 0, 1 in the plane of e and a; t = 2, 3 in that of e and b
    f = 1.0 if t % 2 == 0 else 0.0
    m = k if t % 2 == 0 else 1.0
    cube = c * length * length * length / 3.0
    if t < 2:
        return cube if t == 0 else 0.25 * c * length, 0.0, f, 0.0, 0.0, 0.0, 0.0, m, 0.0
    return cube if t == 2 else 0.25 * c * length, 0.0, 0.0, f, 0.0, 0.0, -m, 0.0, 0.0


@njit(cache=True, nogil=True)
def form_plane(form):
    """Whether the form's normal a is the element's second axis made normal to e (a beam bending
    out of its plane), rather than the first of two normals to e (:func:`form_frame`)."""
    return form == FORM_BEAM_BENDING_OUT


@njit(**_STAGE)
def form_frame(plane, ex, ey, ez, nx, ny, nz):
    """The unit normals (a, b) of an element's frame, b = e x a: a = n made normal to e if
    ``plane`` (:func:`form_plane`), else e x h (h the world axis of e's least component)."""
    hx = 1.0 if (abs(ex) <= abs(ey) and abs(ex) <= abs(ez)) else 0.0
    hy = 1.0 if (hx == 0.0 and abs(ey) <= abs(ez)) else 0.0
    cx, cy, cz = _cross_t(ex, ey, ez, hx, hy, 1.0 - hx - hy)
    d = nx * ex + ny * ey + nz * ez
    ax = nx - d * ex if plane else cx
    ay = ny - d * ey if plane else cy
    az = nz - d * ez if plane else cz
    inv = 1.0 / np.sqrt(ax * ax + ay * ay + az * az)
    ax, ay, az = ax * inv, ay * inv, az * inv
    bx, by, bz = _cross_t(ex, ey, ez, ax, ay, az)
    return ax, ay, az, bx, by, bz


@njit(**_STAGE)
def _element_kind(G, EG, row, nl, S, X, E):
    """Add the bar-space compliance of one element kind (row ``row`` of the element table EG,
    :data:`h4pin.stiffness.packed.EL_ROW`) into the upper triangle of E (8, 8, LANES): for each
    element s of the kind, ``E[m, n] += w_m^T C_s w_n`` over the bars m, n that load its site,
    w_m = [f_m, mu_m] bar m's pull (w_m) and its moment about the site's point, C_s the element's
    compliance in the form of the row, ``sum_t c_t u_t u_t^T`` (:func:`form_part`)."""
    base = EL_HEADER + EL_ROW * row
    site, form, axis = int(EG[base]), int(EG[base + 1]), int(EG[base + 2])
    count, off, normal = int(EG[base + 3]), int(EG[base + 4]), int(EG[base + 5])
    for s in range(count):
        c, length = EG[off + 2 * s], EG[off + 2 * s + 1]
        if c == 0.0:
            continue
        slot = 0
        for m in range(8):  # each bar's force and moment about the site's point
            if not site_bars(G, site, s, m):
                continue
            site_point(G, site, s, m, nl, S, X)
            pt = _A if (site == SITE_MOUNT or site == SITE_TIP) else _B
            for l in range(nl):
                rx = S[pt + 3 * m, l] - X[_EA, l]
                ry = S[pt + 3 * m + 1, l] - X[_EA + 1, l]
                rz = S[pt + 3 * m + 2, l] - X[_EA + 2, l]
                fx, fy, fz = S[_W + 3 * m, l], S[_W + 3 * m + 1, l], S[_W + 3 * m + 2, l]
                X[_EF + 3 * slot, l], X[_EF + 3 * slot + 1, l], X[_EF + 3 * slot + 2, l] = fx, fy, fz
                X[_EM + 3 * slot, l] = ry * fz - rz * fy
                X[_EM + 3 * slot + 1, l] = rz * fx - rx * fz
                X[_EM + 3 * slot + 2, l] = rx * fy - ry * fx
            slot += 1
        for k in range(2):  # the axis, then the second axis (one inlined copy of element_axis)
            element_axis(G, axis if k == 0 else normal, s, nl, S, X, _EA if k == 0 else _EN)
        plane = form_plane(form)
        for l in range(nl):  # the element's frame: a into rows _EN (its second axis, spent), b into _EU + 3
            ax, ay, az, bx, by, bz = form_frame(plane, X[_EA, l], X[_EA + 1, l], X[_EA + 2, l], X[_EN, l],
                                                X[_EN + 1, l], X[_EN + 2, l])
            X[_EN, l], X[_EN + 1, l], X[_EN + 2, l], X[_EB, l], X[_EB + 1, l], X[_EB + 2, l] = ax, ay, az, bx, by, bz
        for t in range(form_count(form)):
            ct, fe, fa, fb, fw, me, ma, mb, mw = form_part(form, t, c, length)
            wx, wy, wz = (1.0 if t == 0 else 0.0), (1.0 if t == 1 else 0.0), (1.0 if t == 2 else 0.0)
            for d in range(3):
                w = wx if d == 0 else (wy if d == 1 else wz)
                for l in range(nl):  # u_t in the world
                    ve, va, vb = X[_EA + d, l], X[_EN + d, l], X[_EB + d, l]
                    X[_EU + d, l] = fe * ve + fa * va + fb * vb + fw * w
                    X[_EU + 3 + d, l] = me * ve + ma * va + mb * vb + mw * w
            for a in range(slot):  # g_a = u_t . w_a
                fa, ma = _EF + 3 * a, _EM + 3 * a
                for l in range(nl):
                    X[_EG + a, l] = (X[_EU, l] * X[fa, l] + X[_EU + 1, l] * X[fa + 1, l] + X[_EU + 2, l] * X[fa + 2, l]
                                     + X[_EU + 3, l] * X[ma, l] + X[_EU + 4, l] * X[ma + 1, l]
                                     + X[_EU + 5, l] * X[ma + 2, l])
            ta = 0
            for m in range(8):
                if not site_bars(G, site, s, m):
                    continue
                tb = ta
                for n in range(m, 8):
                    if not site_bars(G, site, s, n):
                        continue
                    for l in range(nl):
                        E[m, n, l] += ct * X[_EG + ta, l] * X[_EG + tb, l]
                    tb += 1
                ta += 1


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH)
def _element_term(G, EG, nl, S, X, E, Y, Z, kind):  # pragma: no cover - compiled
    """The term ``Y E Y^T`` into E (8, 8, LANES) of every element kind that is on (``kind`` < 0)
    or of row ``kind`` of the table alone (Z (8, 8, LANES) scratch). Compiled once and called by
    both entries (not inlined: its code is a fifth of the pipeline's, and it runs only for robots
    with elements), with ``nl`` a run-time count: a compile-time lane count would compile it once
    per entry, the one-lane version unrolled (14 s of compile of its own)."""
    for a in range(8):
        for b in range(8):
            for l in range(nl):
                E[a, b, l] = 0.0
    for row in range(int(EG[0])):
        if kind < 0 or row == kind:
            _element_kind(G, EG, row, nl, S, X, E)
    for a in range(8):
        for b in range(a):
            for l in range(nl):
                E[a, b, l] = E[b, a, l]
    for a in range(8):  # Z = Y E
        for n in range(8):
            for l in range(nl):
                t = 0.0
                for m in range(8):
                    t += Y[a, m, l] * E[m, n, l]
                Z[a, n, l] = t
    for a in range(8):  # E = Z Y^T (symmetric: the upper triangle, then its mirror)
        for c in range(a, 8):
            for l in range(nl):
                t = 0.0
                for n in range(8):
                    t += Z[a, n, l] * Y[c, n, l]
                E[a, c, l] = t
    for a in range(8):
        for c in range(a):
            for l in range(nl):
                E[a, c, l] = E[c, a, l]


@njit(cache=True, nogil=True, inline="always")
def _loaded(model, a, c):
    """For entry (a, c) of K: the factor of the actuator and bending terms (the paper's model
    loads them with F_x, F_y, F_z and T_z alone, eq. 30; the consistent model with every
    component) and the upper-triangle entry (i, j) that holds it."""
    load = 1.0 if (model == CONSISTENT or c < 3 or c == 5) else 0.0
    return (load, a, c) if a <= c else (load, c, a)


@njit(**_STAGE)
def _assemble(G, model, nl, F, Y, U, KB, TB, want_terms):
    """K of eq. 30 into KB (8, 8, LANES) from the factors F, with ``want_terms`` the four terms
    into TB[0:4] (K their sum). Each term is a symmetric matrix times the load mask of its column
    (``"paper"``: 1 in columns 0, 1, 2, 5 of the actuator terms): the upper triangles go to U,
    then every entry is assembled from them (36 entries of sums instead of 64; a loop that wrote
    K[a, c] and K[c, a] together would not vectorise)."""
    if want_terms:
        cc0, cc1, cc2, cc3 = G[G_CCTRL], G[G_CCTRL + 1], G[G_CCTRL + 2], G[G_CCTRL + 3]
        cb0, cb1, cb2, cb3 = G[G_CBEND], G[G_CBEND + 1], G[G_CBEND + 2], G[G_CBEND + 3]
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
                    U[2, a, c, l], U[3, a, c, l] = t2, t3
        for a in range(8):
            for c in range(8):
                load, i, j = _loaded(model, a, c)
                for l in range(nl):
                    t0 = load * U[0, i, j, l]
                    t1 = load * U[1, i, j, l]
                    t2 = U[2, i, j, l]
                    t3 = U[3, i, j, l]
                    TB[0, a, c, l], TB[1, a, c, l], TB[2, a, c, l], TB[3, a, c, l] = t0, t1, t2, t3
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
                U[0, a, c, l], U[1, a, c, l] = act, rest
    for a in range(8):
        for c in range(8):
            load, i, j = _loaded(model, a, c)
            for l in range(nl):
                KB[a, c, l] = load * U[0, i, j, l] + U[1, i, j, l]


@njit(**_STAGE)
def _transpose(p0, nl, B, X):
    """X[p0 + l] = B[:, :, l] (X: (N, 8, 8) pose-major, B (8, 8, LANES) lane-major), in tiles of 8
    lanes x 8 entries that stay in L1 (a lane at a time over the 64 entries: 1.5x slower)."""
    for l0 in range(0, nl, 8):
        for a in range(8):
            for l in range(l0, min(l0 + 8, nl)):
                for c in range(8):
                    X[p0 + l, a, c] = B[a, c, l]


@njit(**_STAGE)
def _store(p0, nl, S, KB, TB, nt, K, qo, cond, status, T, want_terms):
    """The verdicts (in the order of :mod:`h4pin.verdicts`: unreachable, joint limits, interfering
    bars, singular), q, the condition, K (and the ``nt`` terms), NaN where the verdict is not 0."""
    _transpose(p0, nl, KB, K)
    if want_terms:
        for t in range(nt):
            _transpose(p0, nl, TB[t], T[:, t])
    for l in range(nl):
        p = p0 + l
        if S[_UNR, l] != 0.0:
            st = UNREACHABLE
        elif S[_LIM, l] != 0.0:
            st = LIMITS
        elif S[_HIT, l] != 0.0:
            st = INTERFERENCE
        elif not (S[_CND, l] < _SING):
            st = SINGULAR
        else:
            st = OK
        status[p] = st
        if st == UNREACHABLE:
            cond[p] = np.nan
            for i in range(4):
                qo[p, i] = np.nan
        else:
            cond[p] = S[_CND, l]
            for i in range(4):
                qo[p, i] = S[_Q + i, l]
        if st != OK:
            K[p] = np.nan
            if want_terms:
                T[p] = np.nan


@njit(**_STAGE)
def _scratch(lanes, kinds, want_terms):
    """The scratch arrays of a block of ``lanes`` lanes, cut from one allocation: S, M, Y, R, Bk,
    H, F, U, TB, X, E, Z (the element ones of size 1 when no element is on)."""
    nt = 4 + kinds
    ne = lanes if kinds else 1
    s0, s1, s2, s3 = _ROWS * lanes, 64 * lanes, 64 * lanes, _RROWS * lanes
    s4, s5, s6, s7 = 96 * lanes, lanes, _FROWS * lanes, 256 * lanes
    s8, s9, s10 = (nt if want_terms else 1) * 64 * lanes, (XROWS if kinds else 1) * lanes, 64 * ne
    o1 = s0  # the offsets, summed by hand (no temporary arrays: one allocation a call)
    o2 = o1 + s1
    o3 = o2 + s2
    o4 = o3 + s3
    o5 = o4 + s4
    o6 = o5 + s5
    o7 = o6 + s6
    o8 = o7 + s7
    o9 = o8 + s8
    o10 = o9 + s9
    o11 = o10 + s10
    buf = np.empty(o11 + s10)
    return (buf[:o1].reshape(_ROWS, lanes), buf[o1:o2].reshape(8, 8, lanes), buf[o2:o3].reshape(8, 8, lanes),
            buf[o3:o4].reshape(_RROWS, lanes), buf[o4:o5].reshape(6, 4, 4, lanes), buf[o5:o6],
            buf[o6:o7].reshape(_FROWS, lanes), buf[o7:o8].reshape(4, 8, 8, lanes),
            buf[o8:o9].reshape(nt if want_terms else 1, 8, 8, lanes), buf[o9:o10].reshape(XROWS if kinds else 1, lanes),
            buf[o10:o11].reshape(8, 8, ne), buf[o11:o11 + s10].reshape(8, 8, ne))


#: Width of one pose's row of the intermediates (:func:`run`'s ``X``): M1^-1 (64), the factors
#: of eq. 30 (:data:`_XF` rows of F) and every row of the lane scratch S.
_XF = _YS
NX = 64 + _XF + _ROWS
#: Where each part starts in a row of ``X``.
X_Y, X_F, X_S = 0, 64, 64 + _XF


def _entry(lanes: int):
    """The pipeline over poses ``start .. stop - 1`` in blocks of ``lanes`` lanes, ``lanes`` a
    constant of the compiled code (a closure: each entry is compiled on its own). The stages are
    plain calls, each compiled once per lane count (numba types a constant argument as a literal
    and compiles a version for it, so every lane loop keeps its constant trip count). They were
    inlined by numba (``inline="always"``) until this release: numba copies and types an inlined
    body again at every call site, which cost 40 % more compile time and 220 MB more memory for
    0.4 us less at one pose (docs/architecture.md)."""

    def entry(poses, start, stop, G, EG, model, K, qo, cond, status, T, want_terms, J, want_jac, Xo,
              want_x):  # pragma: no cover - compiled
        kinds = int(EG[0])
        S, M, Y, R, Bk, H, F, U, TB, X, E, Z = _scratch(lanes, kinds, want_terms)
        for p0 in range(start, stop, lanes):
            nl = min(lanes, stop - p0)
            _load(poses, p0, nl, lanes, G, S)  # the last pose fills the lanes past nl
            _legs(G, lanes, S)
            _angles(G, lanes, S)
            _bars(G, lanes, S, H)
            _matrix(G, lanes, S, M, Bk)
            _invert(lanes, S, M, Y, Bk, R)
            _factors(G, lanes, S, Y, F)
            _assemble(G, model, lanes, F, Y, U, M, TB, want_terms)  # M1 is spent: M takes K
            for row in range(kinds if want_terms else min(kinds, 1)):  # the element terms, added to K
                _element_term(G, EG, S.shape[1], S, X, E, Y, Z, row if want_terms else -1)  # run-time count
                for a in range(8):
                    for c in range(8):
                        for l in range(lanes):
                            M[a, c, l] += E[a, c, l]
                if want_terms:
                    for a in range(8):
                        for c in range(8):
                            for l in range(lanes):
                                TB[4 + row, a, c, l] = E[a, c, l]
            if want_jac:
                for r in range(4):
                    a = 5 if r == 3 else r
                    for i in range(4):
                        for l in range(nl):
                            J[p0 + l, r, i] = F[_GC + 4 * a + i, l]
            if want_x:
                for l in range(nl):
                    for a in range(8):
                        for n in range(8):
                            Xo[p0 + l, X_Y + 8 * a + n] = Y[a, n, l]
                    for r in range(_XF):
                        Xo[p0 + l, X_F + r] = F[r, l]
                    for r in range(_ROWS):
                        Xo[p0 + l, X_S + r] = S[r, l]
            _store(p0, nl, S, M, TB, 4 + kinds, K, qo, cond, status, T, want_terms)
            if want_jac:
                for l in range(nl):
                    if status[p0 + l] != OK:
                        J[p0 + l] = np.nan

    return entry


#: Width of one pose's row of the intermediates (:func:`run`'s ``Xo``): M1^-1 (64), the factors
#: of eq. 30 (:data:`_XF` rows of F) and every row of the lane scratch S.
_XF = _YS
NX = 64 + _XF + _ROWS
#: Where each part starts in a row of ``Xo``.
X_Y, X_F, X_S = 0, 64, 64 + _XF

_JIT = dict(cache=True, nogil=True, error_model="numpy", fastmath=FASTMATH)
#: The batch entry: ``run(poses, start, stop, G, EG, model, K, qo, cond, status, T, want_terms, J,
#: want_jac, Xo, want_x)``: poses start .. stop - 1 of ``poses`` (N, 4) into K (N, 8, 8), qo (N,
#: 4), cond (N,), status (N,) int8; with ``want_terms`` the terms into T (N, 4 + kinds on, 8, 8)
#: (eq. 30's four, then one per row of the element table EG); with ``want_jac`` J of eq. 8 (rows
#: 0, 1, 2, 5 of M1^-1 M2 M3) into J (N, 4, 4); with ``want_x`` each pose's intermediates into Xo
#: (N, :data:`NX`) (for the natural frequencies, :mod:`h4pin.stiffness.frequencies`); NaN where the verdict
#: is not 0. G is the packed geometry (:mod:`h4pin.stiffness.packed`); model 0 ``"paper"``, 1
#: ``"consistent"``. Blocks of :data:`LANES` lanes, a compile-time constant in every lane loop.
run = _jit.link_as_compiled(njit(**_JIT)(_entry(LANES)))  # its stages optimised once (_jit)
#: The one-lane entry, inlined by numba into :func:`one`, its only caller: its body is a few calls
#: (cheap to copy), and as a function of its own its linked module was optimised by LLVM once
#: more (4 s of the one-pose step's compile).
_run1 = njit(**_JIT, inline="always")(_entry(1))


@_jit.link_as_compiled
@njit(**_JIT)
def one(pose, G, EG, model, K, q, T, want_terms, Xo, want_x):  # pragma: no cover
    """One pose (4,) as :func:`run` does it, into K (8, 8), q (4,), with ``want_terms`` T
    (4 + kinds on, 8, 8) and with ``want_x`` Xo (NX,) (else not touched); returns (condition,
    status). One lane is a compile-time constant here: LLVM turns every lane loop into
    straight-line code (a call of :func:`run` for one pose runs the vectorised loops' set-ups and
    remainders, 4 to 6 us; this, about 1.5 us). The caller allocates the outputs: a compiled
    function that returns arrays pays for boxing them."""
    cond = np.empty(1)
    status = np.empty(1, dtype=np.int8)  # int8 as the batch's: one compiled version of the stages after
    Kr = K.reshape(1, 8, 8)
    _run1(pose.reshape(1, 4), 0, 1, G, EG, model, Kr, q.reshape(1, 4), cond, status,
          T.reshape(1, T.shape[0], 8, 8), want_terms, Kr, False, Xo.reshape(1, Xo.shape[0]), want_x)  # no J: K's
    return cond[0], status[0]


__all__ = ["CONSISTENT", "EA", "FASTMATH", "F_GC", "F_TV", "LANES", "NX", "PAPER", "S_A", "S_B", "S_LW", "S_ROWS",
           "XROWS", "X_F", "X_S", "X_Y", "atan2", "element_axis", "form_count", "form_frame", "form_part",
           "form_plane", "one", "run", "site_bars", "site_point"]
