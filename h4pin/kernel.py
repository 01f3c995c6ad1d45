# SPDX-License-Identifier: Apache-2.0
"""Compiled compliance kernel: eq. 30 of Company, Pierrot and Fauroux (ICRA 2005), per pose, in numba.

One compiled function does a whole pose: the inverse geometry (closed form, elbow out), the
points, M1 (eq. 6), J (eq. 8), the compliance K of eq. 30 with the sparsity of M2-M5 used, and a
verdict. The numpy path (:func:`h4pin.stiffness.compliance`) stays the reference it is tested
against.

With ``Y = M1^-1`` (eq. 6) and, per bar n = 2(i-1) + (j-1) of leg i,

* ``g_n = w_n . (p_n x u_i)`` (row n of M2 M3, eqs. 6 and 11; p_n = P_i - A_ij),
* ``d_n = w_n . (p_n x r_i)`` and ``e_n = (p_n x r_i) . w_i`` (M2 M4 = d e^T per leg, eq. 23),

the four terms of eq. 30 are sums of outer products of columns of Y:

* control / bending (eqs. 12, 15): ``sum_i c_i G_i L_i^T`` with ``G_i = sum_j Y[:, n] g_n`` (column
  i of M1^-1 M2 M3), ``L_i = R^T J^T e_i`` (``"paper"``: G_i's x, y, z, theta entries in columns
  0, 1, 2, 5) or ``L_i = G_i`` (``"consistent"``, erratum 4 fixed);
* torsion (eq. 23): ``sum_i c_i (sum_j d_n Y[:, n]) (sum_j e_n l_n Y[:, n])^T``;
* tension (eq. 27): ``sum_n c_n l_n^2 Y[:, n] Y[:, n]^T``,

since ``Jb^-1 = diag(l) M1^-T`` (eq. 16) and ``M2 M5 = diag(l)``. Each spring has its own
compliance (per leg for the forearm and actuator springs, per bar for the bars).

The robot comes as a geometry object with the attributes listed in :func:`prepare` (one value per
leg and per bar, as read from a URDF); ``h4.geometry`` or an
:class:`h4pin.H4Params` is converted.

Verdict per pose (``status``, int8): :data:`OK` 0; :data:`UNREACHABLE` 1 (a leg cannot reach B_i);
:data:`LIMITS` 2 (an actuator angle or a lateral revolute angle omega_k = -theta outside its
limits); :data:`BARS` 3 (the axes of two bars of different legs come closer than
``bar_clearance``); :data:`SINGULAR` 4 (the 1-norm condition number of the scaled M1 -- rows over
l_ij, rotation columns over the mean bar length -- is not below :data:`SINGULAR_CONDITION`). The
first that applies is reported; K is NaN unless the status is 0.
"""

from __future__ import annotations

import types
from collections.abc import Iterable, Iterator
from typing import Any, NamedTuple

import numba
import numpy as np
from numba import njit, prange

from h4pin import geometry
from h4pin.errors import ParameterError, PoseError
from h4pin.model import H4Geometry, geometry_from_params
from h4pin.params import H4Params

OK, UNREACHABLE, LIMITS, BARS, SINGULAR = 0, 1, 2, 3, 4
#: Names of the status codes, indexed by code.
STATUS_NAMES = ("ok", "unreachable", "outside joint limits", "bars interpenetrate", "singular")
#: A pose is singular unless the scaled 1-norm condition number of M1 is below this.
SINGULAR_CONDITION = 1e9
MODELS = ("paper", "consistent")
TERMS = ("control", "bending", "torsion", "tension")
#: Poses per parallel block (scratch arrays are allocated once per block).
_BLOCK = 256
#: Default chunk of :func:`iter_compliance` (about 36 MB of output without terms).
CHUNK = 65_536

# Layout of the packed geometry vector (offsets into one float64 array).
_P = 0  # (4, 3) P_i
_U = 12  # (4, 3) u_i
_V = 24  # (8, 3) A0_ij - P_i
_UV = 48  # (8, 3) u_i x (A0_ij - P_i)
_UVU = 72  # (8, 3) (u_i . (A0_ij - P_i)) u_i
_M = 96  # (4, 3) m_i
_UM = 108  # (4, 3) u_i x m_i
_R2 = 120  # (4,) r_i^2
_LL = 124  # (4,) bar length of leg i (mean of its two bars)
_C0 = 128  # (2, 3)
_BB = 134  # (8, 3) B_ij - C_k
_BM = 158  # (4, 3) B_i - C_k
_LAT = 170  # (8,) lateral bar of each bar (as float)
_CCTRL = 178  # (4,)
_CBEND = 182  # (4,)
_CTORS = 186  # (4,)
_CTENS = 190  # (8,)
_QLO = 198  # (4,)
_QHI = 202  # (4,)
_WLO = 206  # (2,)
_WHI = 208  # (2,)
_CLEAR = 210
_LMEAN = 211
_SIZE = 212


# ----------------------------------------------------------------------------------------------
# Geometry object


def _namespace(g: H4Geometry) -> types.SimpleNamespace:
    """The geometry object of :func:`prepare` for an :class:`h4pin.model.H4Geometry` (a loaded
    robot's ``h4.geometry``): its arrays, with the spring compliances per element."""
    if not g.ideal:
        raise ParameterError("the compiled kernel handles robots whose parallelograms are exact (H4Geometry.ideal); "
                             "use the numpy path (method='closed_form') for a toleranced robot")
    c = g.compliances()
    return types.SimpleNamespace(P=g.P, u=g.u, A0=g.A0, l=g.l, lat=g.lat, C0=g.C0, b=g.b, c_ctrl=c["control"],
                                 c_bend=c["bending"], c_tors=c["torsion"], c_tens=c["tension"], q_lo=g.q_lo,
                                 q_hi=g.q_hi, omega_lo=g.omega_lo, omega_hi=g.omega_hi,
                                 bar_clearance=g.bar_clearance)


_SHAPES = {"P": (4, 3), "u": (4, 3), "A0": (8, 3), "l": (8,), "lat": (8,), "C0": (2, 3), "b": (8, 3),
           "c_ctrl": (4,), "c_bend": (4,), "c_tors": (4,), "c_tens": (8,), "q_lo": (4,), "q_hi": (4,),
           "omega_lo": (2,), "omega_hi": (2,)}


def _array(g: Any, name: str) -> np.ndarray:
    try:
        value = np.asarray(getattr(g, name), dtype=float)
    except AttributeError:
        raise ParameterError(f"geometry object has no attribute {name!r}") from None
    if value.shape != _SHAPES[name]:
        raise ParameterError(f"geometry.{name} must have shape {_SHAPES[name]}, got {value.shape}")
    if not np.all(np.isfinite(value)):
        raise ParameterError(f"geometry.{name} has non-finite entries")
    return value


class Kernel:
    """A geometry packed for the compiled kernel (see :func:`prepare`). Calling it on one pose is
    the fast single-pose path: ``K, q, condition, status = kernel(pose)``."""

    def __init__(self, g: Any):
        self.geometry = g
        a = {name: _array(g, name) for name in _SHAPES}
        lat = a["lat"]
        if not np.all((lat == 0) | (lat == 1)) or np.any(lat[0::2] != lat[1::2]):
            raise ParameterError(f"geometry.lat must be 0 or 1, the same for both bars of a leg, got {lat.tolist()}")
        u = a["u"]
        if np.any(np.abs(np.linalg.norm(u, axis=1) - 1.0) > 1e-9):
            raise ParameterError("geometry.u must hold unit vectors")
        for name in ("l", "c_ctrl", "c_bend", "c_tors", "c_tens"):
            if np.any(a[name] <= 0):
                raise ParameterError(f"geometry.{name} must be > 0, got {a[name].tolist()}")
        clearance = float(getattr(g, "bar_clearance", np.nan))
        if not np.isfinite(clearance) or clearance < 0:
            raise ParameterError(f"geometry.bar_clearance must be finite and >= 0, got {clearance!r}")
        leg = np.repeat(np.arange(4), 2)
        P = a["P"]
        v = a["A0"] - P[leg]
        m = 0.5 * (v[0::2] + v[1::2])
        um = np.cross(u, m)
        if np.any(np.abs(np.einsum("ia,ia->i", m, u)) > 1e-9 * np.linalg.norm(m, axis=1)):
            raise ParameterError("geometry.P must be the foot of the perpendicular from the forearm end A_i "
                                 "on the actuator axis (m_i . u_i = 0)")
        G = np.zeros(_SIZE)
        G[_P:_P + 12] = P.ravel()
        G[_U:_U + 12] = u.ravel()
        G[_V:_V + 24] = v.ravel()
        G[_UV:_UV + 24] = np.cross(u[leg], v).ravel()
        G[_UVU:_UVU + 24] = (np.einsum("na,na->n", u[leg], v)[:, None] * u[leg]).ravel()
        G[_M:_M + 12] = m.ravel()
        G[_UM:_UM + 12] = um.ravel()
        G[_R2:_R2 + 4] = np.einsum("ia,ia->i", m, m)
        G[_LL:_LL + 4] = 0.5 * (a["l"][0::2] + a["l"][1::2])
        G[_C0:_C0 + 6] = a["C0"].ravel()
        G[_BB:_BB + 24] = a["b"].ravel()
        G[_BM:_BM + 12] = (0.5 * (a["b"][0::2] + a["b"][1::2])).ravel()
        G[_LAT:_LAT + 8] = lat
        G[_CCTRL:_CCTRL + 4] = a["c_ctrl"]
        G[_CBEND:_CBEND + 4] = a["c_bend"]
        G[_CTORS:_CTORS + 4] = a["c_tors"]
        G[_CTENS:_CTENS + 8] = a["c_tens"]
        G[_QLO:_QLO + 4] = a["q_lo"]
        G[_QHI:_QHI + 4] = a["q_hi"]
        G[_WLO:_WLO + 2] = a["omega_lo"]
        G[_WHI:_WHI + 2] = a["omega_hi"]
        G[_CLEAR] = clearance
        G[_LMEAN] = float(np.mean(a["l"]))
        G.setflags(write=False)
        self.packed = G

    def __call__(self, pose: np.ndarray, model: str = "paper") -> tuple[np.ndarray, np.ndarray, float, int]:
        """K (8, 8), q (4,), condition, status at one pose [x, y, z, theta] (m, rad)."""
        x = np.asarray(pose, dtype=np.float64)
        if x.shape != (4,):
            x = geometry.as_poses(pose)
            if x.ndim != 1:
                raise PoseError(f"a Kernel call takes one pose (4,), got shape {x.shape}; use compliance_batch")
        return _one(x, self.packed, 1 if model == "consistent" else _model_code(model))


def prepare(g: Any) -> Kernel:
    """Check and pack a geometry object once, for many calls of the kernel.

    ``g`` has the attributes (SI, world frame, legs i = 0..3, bars n = 2 i + j):

    * ``P`` (4, 3): a point of actuator axis i, the foot of the perpendicular from A_i;
      ``u`` (4, 3): unit actuator axis (q right-handed about u_i);
    * ``A0`` (8, 3): ball-joint centres A_ij at q_i = 0; ``l`` (8,): bar lengths;
    * ``lat`` (8,): lateral bar (0/1) of each bar; ``C0`` (2, 3): C_k - D at theta = 0 in the
      central bar's frame; ``b`` (8, 3): B_ij - C_k (the lateral bars only translate);
    * springs: ``c_ctrl`` (4,) 1/kc_i, ``c_bend`` (4,) phi^3 r_i/(3 E I), ``c_tors`` (4,)
      phi r_i/(G I0) (rad/(N.m)), ``c_tens`` (8,) l/(Sb Eb) (m/N);
    * limits: ``q_lo``, ``q_hi`` (4,) actuator angles, ``omega_lo``, ``omega_hi`` (2,) lateral
      revolutes (rad); ``bar_clearance`` (m): least distance between the axes of two bars of
      different legs.

    An :class:`h4pin.model.H4Geometry` (``h4.geometry``, ideal parallelograms) or an
    :class:`h4pin.H4Params` is accepted too.

    Raises:
        ParameterError: an attribute is missing or has the wrong shape (the message names it).
    """
    if isinstance(g, Kernel):
        return g
    if isinstance(g, H4Params):
        g = geometry_from_params(g)
    if isinstance(g, H4Geometry):
        g = _namespace(g)
    return Kernel(g)


def _model_code(model: str) -> int:
    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}, got {model!r}")
    return MODELS.index(model)


# ----------------------------------------------------------------------------------------------
# The compiled pose


@njit(cache=True, nogil=True, inline="always")
def _seg_dist2(A, B, n1, n2):
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
def _rank1(M, s, u, v):
    """M += s u v^T (8 x 8)."""
    for a in range(8):
        sa = s * u[a]
        for c in range(8):
            M[a, c] += sa * v[c]


@njit(cache=True, nogil=True, inline="always")
def _refuse(K, T, want_terms, Jo, want_jac):
    """NaN outputs of a pose that gets no K (status not 0)."""
    K[:, :] = np.nan
    if want_terms:
        T[:] = np.nan
    if want_jac:
        Jo[:] = np.nan


@njit(cache=True, nogil=True)
def _pose(px, py, pz, th, G, model, K, qo, T, want_terms, Jo, want_jac, A, B, W, lw, M, Y, Gc, ws):
    """One pose: fills K (8, 8), qo (4,), optionally T (4, 8, 8) and Jo (4, 4); returns
    (condition, status). A, B, W (8, 3), lw (8,), M, Y (8, 8), Gc (8, 4), ws (8, 8) are scratch."""
    nan = np.nan
    ct, st = np.cos(th), np.sin(th)
    status = 0
    # Inverse geometry on the leg midpoints: alpha cos q + beta sin q = rhs, elbow out.
    for i in range(4):
        k = int(G[_LAT + 2 * i])
        cx = px + ct * G[_C0 + 3 * k] - st * G[_C0 + 3 * k + 1]
        cy = py + st * G[_C0 + 3 * k] + ct * G[_C0 + 3 * k + 1]
        cz = pz + G[_C0 + 3 * k + 2]
        ex = cx + G[_BM + 3 * i] - G[_P + 3 * i]
        ey = cy + G[_BM + 3 * i + 1] - G[_P + 3 * i + 1]
        ez = cz + G[_BM + 3 * i + 2] - G[_P + 3 * i + 2]
        alpha = ex * G[_M + 3 * i] + ey * G[_M + 3 * i + 1] + ez * G[_M + 3 * i + 2]
        beta = ex * G[_UM + 3 * i] + ey * G[_UM + 3 * i + 1] + ez * G[_UM + 3 * i + 2]
        rhs = 0.5 * (ex * ex + ey * ey + ez * ez + G[_R2 + i] - G[_LL + i] * G[_LL + i])
        rho = np.sqrt(alpha * alpha + beta * beta)
        if not (rho > 0.0) or abs(rhs) > rho:
            for a in range(4):
                qo[a] = nan
            _refuse(K, T, want_terms, Jo, want_jac)
            return nan, 1
        cd = rhs / rho
        sd = np.sqrt(max(1.0 - cd * cd, 0.0))
        cphi, sphi = alpha / rho, beta / rho
        cq = cphi * cd + sphi * sd  # q = phi - delta
        sq = sphi * cd - cphi * sd
        qo[i] = np.arctan2(sq, cq)
        for j in range(2):
            n = 2 * i + j
            for a in range(3):
                A[n, a] = (G[_P + 3 * i + a] + cq * G[_V + 3 * n + a] + sq * G[_UV + 3 * n + a]
                           + (1.0 - cq) * G[_UVU + 3 * n + a])
            B[n, 0] = cx + G[_BB + 3 * n]
            B[n, 1] = cy + G[_BB + 3 * n + 1]
            B[n, 2] = cz + G[_BB + 3 * n + 2]
    # Joint limits.
    for i in range(4):
        if not (G[_QLO + i] <= qo[i] <= G[_QHI + i]):
            status = 2
    for k in range(2):
        if not (G[_WLO + k] <= -th <= G[_WHI + k]):
            status = 2
    # Bar axes of different legs.
    if status == 0:
        c2 = G[_CLEAR] * G[_CLEAR]
        for n1 in range(6):
            for n2 in range(2 * (n1 // 2) + 2, 8):
                if _seg_dist2(A, B, n1, n2) < c2:
                    status = 3
    # M1 of eq. 6, row n = [w, w x (D - B_n), (w x (C_k - B_n)).z in column 6 + k].
    for n in range(8):
        k = int(G[_LAT + n])
        wx, wy, wz = B[n, 0] - A[n, 0], B[n, 1] - A[n, 1], B[n, 2] - A[n, 2]
        W[n, 0], W[n, 1], W[n, 2] = wx, wy, wz
        lw[n] = np.sqrt(wx * wx + wy * wy + wz * wz)
        sx, sy, sz = px - B[n, 0], py - B[n, 1], pz - B[n, 2]
        M[n, 0], M[n, 1], M[n, 2] = wx, wy, wz
        M[n, 3] = wy * sz - wz * sy
        M[n, 4] = wz * sx - wx * sz
        M[n, 5] = wx * sy - wy * sx
        M[n, 6] = 0.0
        M[n, 7] = 0.0
        tx = px + ct * G[_C0 + 3 * k] - st * G[_C0 + 3 * k + 1] - B[n, 0]
        ty = py + st * G[_C0 + 3 * k] + ct * G[_C0 + 3 * k + 1] - B[n, 1]
        M[n, 6 + k] = wx * ty - wy * tx
    # 1-norm of the scaled M1 (rows / l_n, columns 3..7 / L).
    lmean = G[_LMEAN]
    norm1 = 0.0
    for c in range(8):
        s = 0.0
        for n in range(8):
            s += abs(M[n, c]) / lw[n]
        if c >= 3:
            s /= lmean
        norm1 = max(norm1, s)
    # Y = M1^-1 by Gauss-Jordan with partial pivoting (M is overwritten).
    for a in range(8):
        for c in range(8):
            Y[a, c] = 1.0 if a == c else 0.0
    singular = False
    for c in range(8):
        p = c
        big = abs(M[c, c])
        for a in range(c + 1, 8):
            if abs(M[a, c]) > big:
                big = abs(M[a, c])
                p = a
        if big == 0.0:
            singular = True
            break
        if p != c:
            for e in range(8):
                M[c, e], M[p, e] = M[p, e], M[c, e]
                Y[c, e], Y[p, e] = Y[p, e], Y[c, e]
        inv = 1.0 / M[c, c]
        for e in range(8):
            M[c, e] *= inv
            Y[c, e] *= inv
        for a in range(8):
            if a != c:
                f = M[a, c]
                if f != 0.0:
                    for e in range(8):
                        M[a, e] -= f * M[c, e]
                        Y[a, e] -= f * Y[c, e]
    cond = np.inf
    if not singular:
        ninv = 0.0
        for n in range(8):
            s = 0.0
            for a in range(8):
                s += abs(Y[a, n]) * (lmean if a >= 3 else 1.0)
            ninv = max(ninv, s * lw[n])
        cond = norm1 * ninv
    if status == 0 and not (cond < SINGULAR_CONDITION):
        status = 4
    if status != 0:
        _refuse(K, T, want_terms, Jo, want_jac)
        return cond, status
    # Columns of M1^-1 M2 M3 (eq. 11): Gc[:, i] = sum_j Y[:, n] g_n, g_n = w_n . (p_n x u_i).
    for i in range(4):
        for a in range(8):
            Gc[a, i] = 0.0
        for j in range(2):
            n = 2 * i + j
            ux, uy, uz = G[_U + 3 * i], G[_U + 3 * i + 1], G[_U + 3 * i + 2]
            qx, qy, qz = G[_P + 3 * i] - A[n, 0], G[_P + 3 * i + 1] - A[n, 1], G[_P + 3 * i + 2] - A[n, 2]
            g = W[n, 0] * (qy * uz - qz * uy) + W[n, 1] * (qz * ux - qx * uz) + W[n, 2] * (qx * uy - qy * ux)
            for a in range(8):
                Gc[a, i] += Y[a, n] * g
    if want_jac:
        for i in range(4):
            Jo[0, i], Jo[1, i], Jo[2, i], Jo[3, i] = Gc[0, i], Gc[1, i], Gc[2, i], Gc[5, i]
    # Rank-one updates of eq. 30 into K, or with the terms into T[term] (then K = their sum).
    if want_terms:
        T[:] = 0.0
    for a in range(8):
        for c in range(8):
            K[a, c] = 0.0
    # Actuator springs: control and bending (eqs. 12, 15), column G_i, load row L_i.
    for i in range(4):
        cc, cb = G[_CCTRL + i], G[_CBEND + i]
        for c in range(8):
            ws[2, c] = Gc[c, i]
            ws[3, c] = Gc[c, i] if (model == 1 or c < 3 or c == 5) else 0.0
        if want_terms:
            _rank1(T[0], cc, ws[2], ws[3])
            _rank1(T[1], cb, ws[2], ws[3])
        else:
            _rank1(K, cc + cb, ws[2], ws[3])
    # Forearm torsion (eq. 23): per leg c_i (sum_j d_n Y[:, n]) (sum_j e_n l_n Y[:, n])^T.
    for i in range(4):
        amx = 0.5 * (A[2 * i, 0] + A[2 * i + 1, 0])
        amy = 0.5 * (A[2 * i, 1] + A[2 * i + 1, 1])
        amz = 0.5 * (A[2 * i, 2] + A[2 * i + 1, 2])
        rx, ry, rz = G[_P + 3 * i] - amx, G[_P + 3 * i + 1] - amy, G[_P + 3 * i + 2] - amz
        rn = np.sqrt(rx * rx + ry * ry + rz * rz)
        rx, ry, rz = rx / rn, ry / rn, rz / rn
        wx = 0.5 * (B[2 * i, 0] + B[2 * i + 1, 0]) - amx
        wy = 0.5 * (B[2 * i, 1] + B[2 * i + 1, 1]) - amy
        wz = 0.5 * (B[2 * i, 2] + B[2 * i + 1, 2]) - amz
        wn = np.sqrt(wx * wx + wy * wy + wz * wz)
        wx, wy, wz = wx / wn, wy / wn, wz / wn
        for a in range(8):
            ws[0, a] = 0.0
            ws[1, a] = 0.0
        for j in range(2):
            n = 2 * i + j
            qx, qy, qz = G[_P + 3 * i] - A[n, 0], G[_P + 3 * i + 1] - A[n, 1], G[_P + 3 * i + 2] - A[n, 2]
            prx, pry, prz = qy * rz - qz * ry, qz * rx - qx * rz, qx * ry - qy * rx
            d = W[n, 0] * prx + W[n, 1] * pry + W[n, 2] * prz
            e = (prx * wx + pry * wy + prz * wz) * lw[n]
            for a in range(8):
                ws[0, a] += Y[a, n] * d
                ws[1, a] += Y[a, n] * e
        _rank1(T[2] if want_terms else K, G[_CTORS + i], ws[0], ws[1])
    # Bar tension (eq. 27): sum_n c_n l_n^2 Y[:, n] Y[:, n]^T.
    for n in range(8):
        for a in range(8):
            ws[4, a] = Y[a, n]
        _rank1(T[3] if want_terms else K, G[_CTENS + n] * lw[n] * lw[n], ws[4], ws[4])
    if want_terms:
        for a in range(8):
            for c in range(8):
                K[a, c] = T[0, a, c] + T[1, a, c] + T[2, a, c] + T[3, a, c]
    return cond, 0


@njit(cache=True, nogil=True)
def _scratch():
    return (np.empty((8, 3)), np.empty((8, 3)), np.empty((8, 3)), np.empty(8), np.empty((8, 8)), np.empty((8, 8)),
            np.empty((8, 4)), np.empty((8, 8)))


@njit(cache=True, nogil=True)
def _one(x, G, model):
    K = np.empty((8, 8))
    q = np.empty(4)
    T = np.empty((1, 4, 8, 8))
    J = np.empty((1, 4, 4))
    A, B, W, lw, M, Y, Gc, ws = _scratch()
    cond, status = _pose(x[0], x[1], x[2], x[3], G, model, K, q, T[0], False, J[0], False, A, B, W, lw, M, Y,
                         Gc, ws)
    return K, q, cond, status


@njit(cache=True, nogil=True, parallel=True)
def _batch(poses, G, model, K, q, cond, status, T, want_terms, J, want_jac, block):
    n = poses.shape[0]
    nblocks = (n + block - 1) // block
    for bi in prange(nblocks):
        A, B, W, lw, M, Y, Gc, ws = _scratch()
        for p in range(bi * block, min(n, (bi + 1) * block)):
            tp = T[p] if want_terms else T[0]
            jp = J[p] if want_jac else J[0]
            c, s = _pose(poses[p, 0], poses[p, 1], poses[p, 2], poses[p, 3], G, model, K[p], q[p], tp, want_terms,
                         jp, want_jac, A, B, W, lw, M, Y, Gc, ws)
            cond[p] = c
            status[p] = s


# ----------------------------------------------------------------------------------------------
# Python API


class KernelResult(NamedTuple):
    """Output of the kernel for N poses (SI).

    K (N, 8, 8) of eq. 30 (NaN unless status is 0); q (N, 4) actuator angles, rad (NaN if
    unreachable); condition (N,) scaled 1-norm condition number of M1; status (N,) int8 (see the
    module docstring); terms (N, 4, 8, 8) control, bending, torsion, tension (or None);
    J (N, 4, 4) = Jx^-1 Jq of eq. 8 (or None).
    """

    K: np.ndarray
    q: np.ndarray
    condition: np.ndarray
    status: np.ndarray
    terms: np.ndarray | None = None
    J: np.ndarray | None = None


def _empty(n: int, terms: bool, jacobian: bool) -> KernelResult:
    return KernelResult(np.empty((n, 8, 8)), np.empty((n, 4)), np.empty(n), np.empty(n, dtype=np.int8),
                        np.empty((n, 4, 8, 8)) if terms else None, np.empty((n, 4, 4)) if jacobian else None)


def _check_out(out: KernelResult, n: int, terms: bool, jacobian: bool) -> KernelResult:
    shapes = {"K": (n, 8, 8), "q": (n, 4), "condition": (n,), "status": (n,)}
    if terms:
        shapes["terms"] = (n, 4, 8, 8)
    if jacobian:
        shapes["J"] = (n, 4, 4)
    for name, shape in shapes.items():
        arr = getattr(out, name)
        want = np.int8 if name == "status" else np.float64
        if arr is None or arr.shape != shape or arr.dtype != want:
            raise ParameterError(f"out.{name} must be a {np.dtype(want).name} array of shape {shape}")
    return out


def compliance_batch(g: Any, poses: np.ndarray, model: str = "paper", out: KernelResult | None = None, *,
                     terms: bool = False, jacobian: bool = False) -> KernelResult:
    """K of eq. 30, q, the condition and the verdict at N poses, in parallel over the poses.

    Args:
        g: A geometry object (see :func:`prepare`), a :class:`Kernel`, or an :class:`h4pin.H4Params`.
        poses: (N, 4) or (4,) poses [x, y, z, theta] (m, rad).
        model: ``"paper"`` or ``"consistent"`` (see :mod:`h4pin.stiffness`).
        out: Arrays to fill (a :class:`KernelResult` of the right shapes, e.g. memory-mapped
            files); allocated if None.
        terms: Also return the four terms (4 x 512 bytes a pose more).
        jacobian: Also return J = Jx^-1 Jq (eq. 8).

    The number of threads is numba's (``numba.set_num_threads``).
    """
    kern = prepare(g)
    code = _model_code(model)
    x = geometry.as_poses(poses)
    x = np.ascontiguousarray(x[None] if x.ndim == 1 else x)
    n = len(x)
    res = _empty(n, terms, jacobian) if out is None else _check_out(out, n, terms, jacobian)
    T = res.terms if terms else np.empty((1, 4, 8, 8))
    J = res.J if jacobian else np.empty((1, 4, 4))
    if n:
        _batch(x, kern.packed, code, res.K, res.q, res.condition, res.status, T, terms, J, jacobian, _BLOCK)
    return res


def compliance_one(g: Any, pose: np.ndarray, model: str = "paper") -> tuple[np.ndarray, np.ndarray, float, int]:
    """K (8, 8), q (4,), condition, status at one pose. Pass a :class:`Kernel` (:func:`prepare`)
    for the fast path; a geometry object is packed at every call."""
    return prepare(g)(pose, model)


def iter_compliance(g: Any, poses: np.ndarray | Iterable[np.ndarray], model: str = "paper", *, chunk: int = CHUNK,
                    terms: bool = False, jacobian: bool = False) -> Iterator[tuple[int, KernelResult]]:
    """Stream the kernel over many poses in chunks: yields ``(start, result)`` per chunk.

    ``poses`` is an (N, 4) array (cut into ``chunk`` rows) or an iterable of (n, 4) arrays (each
    one a chunk, e.g. generated on the fly). The result's arrays are reused from one chunk to
    the next: reduce or copy them before asking for the next one. Memory stays at one chunk.
    """
    kern = prepare(g)
    if chunk < 1:
        raise ParameterError(f"chunk must be >= 1, got {chunk!r}")
    if isinstance(poses, np.ndarray):
        x = geometry.as_poses(poses)
        x = x[None] if x.ndim == 1 else x
        parts: Iterable[np.ndarray] = (x[s:s + chunk] for s in range(0, len(x), chunk))
    else:
        parts = poses
    buf: KernelResult | None = None
    start = 0
    for part in parts:
        n = len(part)
        if buf is None or len(buf.K) < n:
            buf = _empty(max(n, chunk), terms, jacobian)
        view = KernelResult(*(None if a is None else a[:n] for a in buf))
        yield start, compliance_batch(kern, part, model, view, terms=terms, jacobian=jacobian)
        start += n


def threads() -> int:
    """numba's current number of threads for the batch kernel."""
    return numba.get_num_threads()
