# SPDX-License-Identifier: Apache-2.0
"""The default compiled path: eq. 30 of Company, Pierrot and Fauroux (ICRA 2005) per pose, in numba.

One compiled call does a whole pose: the inverse geometry (closed form, elbow out), the verdict
(:mod:`h4pin.verdicts`), M1 (eq. 6) and the products of M2, M3, M4, M5 from the points, then the
shared compiled core of eq. 30 (:mod:`h4pin.stiffness.core`). Robots whose parallelograms are
exact (:attr:`H4Geometry.ideal <h4pin.H4Geometry>`); the numpy reference (:mod:`h4pin.stiffness.eq30`) covers
every robot and a parametrised test keeps them equal.

The robot comes as an :class:`h4pin.H4Geometry` (``h4.geometry``) or any object with the
attributes listed in :func:`prepare`, packed once into one float vector.

K is NaN unless the status is 0 (:data:`h4pin.verdicts.OK`).
"""

from __future__ import annotations

import functools
import math
import types
import weakref
from collections.abc import Iterable, Iterator
from typing import Any

import numba
import numpy as np
from numba import njit, prange

from h4pin import _jit
from h4pin.description.geometry import H4Geometry, forearms, spring_compliances
from h4pin.errors import ParameterError, PoseError
from h4pin.kinematics.closed_form import as_poses
from h4pin.stiffness import core
from h4pin.stiffness import vector as lanes
from h4pin.stiffness.eq30 import MODELS
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
    _SIZE,
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

#: Poses per parallel block (scratch arrays are allocated once per block).
_BLOCK = 256
#: Default chunk of :func:`iter_compliance` (about 36 MB of output without terms).
CHUNK = 65_536


# ----------------------------------------------------------------------------------------------
# Geometry object


def _inputs(f: Any, c: dict[str, np.ndarray]) -> dict[str, Any]:
    """The arguments of :func:`pack` from the fields ``f`` of :class:`H4Geometry` (the object,
    or a mapping as :func:`h4pin.description.geometry.geometry_arrays` gives) and their spring
    compliances ``c``."""
    get = f.__getitem__ if isinstance(f, dict) else functools.partial(getattr, f)
    return dict(P=get("P"), u=get("u"), A0=get("A0"), l=get("l"), lat=get("lat"), C0=get("C0"), b=get("b"),
                c_ctrl=c["control"], c_bend=c["bending"], c_tors=c["torsion"], c_tens=c["tension"], q_lo=get("q_lo"),
                q_hi=get("q_hi"), omega_lo=get("omega_lo"), omega_hi=get("omega_hi"),
                bar_clearance=get("bar_clearance"))


def _namespace(g: H4Geometry) -> types.SimpleNamespace:
    """The geometry object of :func:`prepare` for an :class:`h4pin.description.geometry.H4Geometry` (a loaded
    robot's ``h4.geometry``): its arrays, with the spring compliances per element."""
    if not g.ideal:
        raise ParameterError("the compiled kernel handles robots whose parallelograms are exact (H4Geometry.ideal); "
                             "use the numpy path (method='closed_form') for a toleranced robot")
    return types.SimpleNamespace(**_inputs(g, g.compliances()))


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


def _check(a: dict[str, Any]) -> None:
    """The checks of :func:`prepare` on the arguments of :func:`pack` (leading robot axes allowed),
    before packing."""
    lat = a["lat"]
    if not np.all((lat == 0) | (lat == 1)) or np.any(lat[..., 0::2] != lat[..., 1::2]):
        raise ParameterError(f"geometry.lat must be 0 or 1, the same for both bars of a leg, got {lat.tolist()}")
    if np.any(np.abs(np.linalg.norm(a["u"], axis=-1) - 1.0) > 1e-9):
        raise ParameterError("geometry.u must hold unit vectors")
    for name in ("l", "c_ctrl", "c_bend", "c_tors", "c_tens"):
        if np.any(a[name] <= 0):
            raise ParameterError(f"geometry.{name} must be > 0, got {a[name].tolist()}")
    clearance = a["bar_clearance"]
    if not np.all(np.isfinite(clearance)) or np.any(clearance < 0):
        raise ParameterError(f"geometry.bar_clearance must be finite and >= 0, got {clearance!r}")


def _check_packed(G: np.ndarray) -> None:
    """The check of :func:`prepare` on packed vectors (..., _SIZE): P_i is the foot of the
    perpendicular from A_i (m_i . u_i = 0)."""
    m = G[..., _M:_M + 12].reshape(G.shape[:-1] + (4, 3))
    u = G[..., _U:_U + 12].reshape(G.shape[:-1] + (4, 3))
    if np.any(np.abs(np.einsum("...ia,...ia->...i", m, u)) > 1e-9 * np.linalg.norm(m, axis=-1)):
        raise ParameterError("geometry.P must be the foot of the perpendicular from the forearm end A_i "
                             "on the actuator axis (m_i . u_i = 0)")


def pack(P: np.ndarray, u: np.ndarray, A0: np.ndarray, l: np.ndarray, lat: np.ndarray, C0: np.ndarray,
         b: np.ndarray, c_ctrl: np.ndarray, c_bend: np.ndarray, c_tors: np.ndarray, c_tens: np.ndarray,
         q_lo: np.ndarray, q_hi: np.ndarray, omega_lo: np.ndarray, omega_hi: np.ndarray,
         bar_clearance: float | np.ndarray) -> np.ndarray:
    """The packed vectors G (..., _SIZE) of the kernel from the attributes of :func:`prepare`
    (shapes there), each with any leading robot axes (broadcast). No checks: :func:`prepare`
    and :func:`pack_fields` check before packing."""
    P, u, A0, l, C0, b = (np.asarray(x, dtype=float) for x in (P, u, A0, l, C0, b))
    lat = np.asarray(lat, dtype=float)
    rest = {"c_ctrl": c_ctrl, "c_bend": c_bend, "c_tors": c_tors, "c_tens": c_tens, "q_lo": q_lo, "q_hi": q_hi,
            "omega_lo": omega_lo, "omega_hi": omega_hi}
    batch = np.broadcast_shapes(*(np.shape(x)[:np.ndim(x) - len(_SHAPES[k])] for k, x in
                                  {"P": P, "u": u, "A0": A0, "l": l, "lat": lat, "C0": C0, "b": b, **rest}.items()),
                                np.shape(bar_clearance))
    leg = np.repeat(np.arange(4), 2)
    ul = u[..., leg, :]
    v = A0 - P[..., leg, :]
    m = 0.5 * (v[..., 0::2, :] + v[..., 1::2, :])
    G = np.zeros(batch + (_SIZE,))

    def put(offset: int, x: np.ndarray, trailing: int = 1) -> None:
        x = np.asarray(x, dtype=float)
        x = x.reshape(x.shape[:x.ndim - trailing] + (int(np.prod(x.shape[x.ndim - trailing:])),))
        G[..., offset:offset + x.shape[-1]] = x

    put(_P, P, 2)
    put(_U, u, 2)
    put(_V, v, 2)
    put(_UV, np.cross(ul, v), 2)
    put(_UVU, np.einsum("...na,...na->...n", ul, v)[..., None] * ul, 2)
    put(_M, m, 2)
    put(_UM, np.cross(u, m), 2)
    put(_R2, np.einsum("...ia,...ia->...i", m, m))
    put(_LL, 0.5 * (l[..., 0::2] + l[..., 1::2]))
    put(_C0, C0, 2)
    put(_BB, b, 2)
    put(_BM, 0.5 * (b[..., 0::2, :] + b[..., 1::2, :]), 2)
    put(_LAT, lat)
    put(_CCTRL, c_ctrl)
    put(_CBEND, c_bend)
    put(_CTORS, c_tors)
    put(_CTENS, c_tens)
    put(_QLO, q_lo)
    put(_QHI, q_hi)
    put(_WLO, omega_lo)
    put(_WHI, omega_hi)
    G[..., _CLEAR] = bar_clearance
    return G


def pack_fields(fields: dict[str, Any]) -> np.ndarray:
    """The packed vectors (..., _SIZE) of many robots at once, checked as :func:`prepare` checks
    one: ``fields`` are those of :class:`H4Geometry` with leading robot axes, as
    :func:`h4pin.description.geometry.geometry_arrays` gives them (robots with exact
    parallelograms, as H4Params makes them). ``Kernel.from_packed(G[k])`` is then robot k's kernel."""
    r = forearms(np.asarray(fields["A0"], dtype=float), np.asarray(fields["P"], dtype=float))[2]
    a = _inputs(fields, spring_compliances(fields["springs"], r, fields["l"]))
    _check(a)
    G = pack(**a)
    _check_packed(G)
    return G


class Kernel:
    """A geometry packed for the compiled kernel (see :func:`prepare`). Calling it on one pose is
    the fast single-pose path: ``K, q, condition, status = kernel(pose)``."""

    geometry: Any
    packed: np.ndarray

    def __init__(self, g: Any):
        self.geometry = g
        a: dict[str, Any] = {name: _array(g, name) for name in _SHAPES}
        a["bar_clearance"] = float(getattr(g, "bar_clearance", np.nan))
        _check(a)
        G = pack(**a)
        _check_packed(G)
        G.setflags(write=False)
        self.packed = G

    @classmethod
    def from_packed(cls, G: np.ndarray) -> Kernel:
        """The kernel of a vector packed by :func:`pack_fields` (a read-only copy; ``geometry``
        is None)."""
        packed = np.array(G, dtype=np.float64)
        if packed.shape != (_SIZE,):
            raise ParameterError(f"a packed kernel vector has shape ({_SIZE},), got {packed.shape}")
        packed.setflags(write=False)
        kern = cls.__new__(cls)
        kern.geometry, kern.packed = None, packed
        return kern

    def __call__(self, pose: np.ndarray, model: str = "paper") -> tuple[np.ndarray, np.ndarray, float, int]:
        """K (8, 8), q (4,), condition, status at one pose [x, y, z, theta] (m, rad)."""
        x = np.asarray(pose, dtype=np.float64)
        if x.shape != (4,):
            x = as_poses(pose)
            if x.ndim != 1:
                raise PoseError(f"a Kernel call takes one pose (4,), got shape {x.shape}; use compliance_batch")
        K, q, cond, status, _ = one(self, x, 1 if model == "consistent" else _model_code(model))
        return K, q, cond, status


def prepare(g: H4Geometry | Kernel | Any) -> Kernel:
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

    An :class:`h4pin.H4Geometry` (``h4.geometry``, ideal parallelograms) is converted.

    Raises:
        ParameterError: an attribute is missing or has the wrong shape (the message names it).
    """
    if isinstance(g, Kernel):
        return g
    if isinstance(g, H4Geometry):
        g = _namespace(g)
    return Kernel(g)


def _model_code(model: str) -> int:
    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}, got {model!r}")
    return MODELS.index(model)


# ----------------------------------------------------------------------------------------------
# The compiled pose: closed-form front end of the shared core (h4pin.stiffness.core)


@njit(cache=True, nogil=True, inline="always")
def _inverse_geometry(px, py, pz, th, G, qo, A, B):
    """Closed-form inverse geometry on the leg midpoints (alpha cos q + beta sin q = rhs, elbow
    out): fills qo (4,), A, B (8, 3); returns False if a leg cannot reach."""
    ct, st = np.cos(th), np.sin(th)
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
                qo[a] = np.nan
            return False
        cd = rhs / rho
        sd = np.sqrt(max(1.0 - cd * cd, 0.0))
        cphi, sphi = alpha / rho, beta / rho
        cq = cphi * cd + sphi * sd  # q = phi - delta
        sq = sphi * cd - cphi * sd
        qo[i] = core.atan2(sq, cq)  # libm's atan2 costs 2-3x more
        for j in range(2):
            n = 2 * i + j
            for a in range(3):
                A[n, a] = (G[_P + 3 * i + a] + cq * G[_V + 3 * n + a] + sq * G[_UV + 3 * n + a]
                           + (1.0 - cq) * G[_UVU + 3 * n + a])
            B[n, 0] = cx + G[_BB + 3 * n]
            B[n, 1] = cy + G[_BB + 3 * n + 1]
            B[n, 2] = cz + G[_BB + 3 * n + 2]
    return True


@njit(cache=True, nogil=True, inline="always")
def _limits_and_bars(th, G, qo, A, B):
    """Verdict of an assembled pose before M1: 2 (joint limits), 3 (interfering bars) or 0."""
    for i in range(4):
        if not (G[_QLO + i] <= qo[i] <= G[_QHI + i]):
            return 2
    for k in range(2):
        if not (G[_WLO + k] <= -th <= G[_WHI + k]):
            return 2
    c2 = G[_CLEAR] * G[_CLEAR]
    for n1 in range(6):
        for n2 in range(2 * (n1 // 2) + 2, 8):
            if not core.lines_apart(A, B, n1, n2, c2) and core.seg_dist2(A, B, n1, n2) < c2:
                return 3
    return 0


@njit(cache=True, nogil=True, inline="always")
def _m1(px, py, pz, th, G, A, B, W, lw, M, g):
    """M1 of eq. 6 (row n = [w, w x (D - B_n), (w x (C_k - B_n)).z in column 6 + k]), the bar
    vectors W, lengths lw and g_n = w_n . (p_n x u_i) (row n of M2 M3)."""
    ct, st = np.cos(th), np.sin(th)
    for n in range(8):
        k = int(G[_LAT + n])
        i = n // 2
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
        ux, uy, uz = G[_U + 3 * i], G[_U + 3 * i + 1], G[_U + 3 * i + 2]
        qx, qy, qz = G[_P + 3 * i] - A[n, 0], G[_P + 3 * i + 1] - A[n, 1], G[_P + 3 * i + 2] - A[n, 2]
        g[n] = wx * (qy * uz - qz * uy) + wy * (qz * ux - qx * uz) + wz * (qx * uy - qy * ux)


@njit(cache=True, nogil=True, inline="always")
def _pose(px, py, pz, th, G, P, C, model, K, qo, T, want_terms, Jo, want_jac, A, B, W, lw, M, Y, Gc, ws, g, d):
    """One pose: fills K (8, 8), qo (4,), optionally T (4, 8, 8) and Jo (4, 4); returns
    (condition, status). P (4, 3) and C (20,) are the actuator points and the spring compliances
    of the packed G (:func:`_views`); the other arrays are scratch
    (:func:`h4pin.stiffness.core.scratch`)."""
    if not _inverse_geometry(px, py, pz, th, G, qo, A, B):
        core.refuse(K, T, want_terms, Jo, want_jac)
        return np.nan, 1
    status = _limits_and_bars(th, G, qo, A, B)
    _m1(px, py, pz, th, G, A, B, W, lw, M, g)
    return core.finish(M, W, lw, A, P, g, C[0:4], C[4:8], C[8:12], C[12:20], model, status, K, T, want_terms, Jo,
                       want_jac, Y, Gc, ws, d)


@njit(cache=True, nogil=True)
def _views(G):
    """The actuator points P (4, 3) and the spring compliances (20,) of the packed G."""
    return G[_P:_P + 12].reshape(4, 3), G[_CCTRL:_CTENS + 8]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=core.FASTMATH)
def _one(x, G, model, want_terms, K, q, T):
    """One pose x (4,) into K (8, 8), q (4,) and, with ``want_terms``, T (4, 8, 8) (else T is not
    touched: :data:`NO_TERMS`), with one scratch allocation; returns (condition, status), status
    5 (K, q NaN) for a pose that is not finite. The caller allocates the outputs: a compiled
    function that returns arrays pays for boxing them (about 0.3 us each)."""
    px, py, pz, th = x[0], x[1], x[2], x[3]
    if not (math.isfinite(px) and math.isfinite(py) and math.isfinite(pz) and math.isfinite(th)):
        K[:, :] = np.nan
        q[:] = np.nan
        return np.nan, 5
    n = core.SCRATCH + 16
    buf = np.empty(n)
    A, B, W, lw, M, Y, Gc, ws, g, d = core.scratch_in(buf)
    J = buf[core.SCRATCH:n].reshape(4, 4)
    P, C = _views(G)
    return _pose(px, py, pz, th, G, P, C, model, K, q, T, want_terms, J, False, A, B, W, lw, M, Y, Gc, ws, g, d)


#: The T argument of :func:`_one` without terms (never written).
NO_TERMS = np.empty((4, 8, 8))

_ONE_ENTRY: list[Any] = []


def one_into(x: np.ndarray, G: np.ndarray, code: int, want_terms: bool, K: np.ndarray, q: np.ndarray,
             T: np.ndarray) -> tuple[float, int]:
    """:func:`_one` for the argument types of :func:`h4pin.compliance`'s one-pose path (x a
    read-only C float64 (4,) copy, the packed G, outputs from ``np.empty``), through the compiled
    entry point of that one overload: it skips the dispatcher's typing of seven arguments (0.14 of
    about 2 us). The first call goes through the dispatcher and looks the overload up by the types
    it was given; a numba without ``entry_point`` keeps the dispatcher."""
    if _ONE_ENTRY:
        return _ONE_ENTRY[0](x, G, code, want_terms, K, q, T)
    out = _one(x, G, code, want_terms, K, q, T)
    sig = tuple(numba.typeof(a) for a in (x, G, code, want_terms, K, q, T))
    overload = _one.overloads.get(sig)
    _ONE_ENTRY.append(getattr(overload, "entry_point", None) or _one)
    return out


@njit(cache=True, nogil=True, inline="always")
def _block(poses, lo, hi, G, P, C, model, K, q, cond, status, T, want_terms, J, want_jac):
    """Poses lo..hi-1 with one set of scratch arrays."""
    A, B, W, lw, M, Y, Gc, ws, g, d = core.scratch()
    for p in range(lo, hi):
        tp = T[p] if want_terms else T[0]
        jp = J[p] if want_jac else J[0]
        c, s = _pose(poses[p, 0], poses[p, 1], poses[p, 2], poses[p, 3], G, P, C, model, K[p], q[p], tp,
                     want_terms, jp, want_jac, A, B, W, lw, M, Y, Gc, ws, g, d)
        cond[p] = c
        status[p] = s


@njit(cache=True, nogil=True, error_model="numpy", fastmath=core.FASTMATH, parallel=True)
def _batch(poses, G, model, K, q, cond, status, T, want_terms, J, want_jac, block):
    n = poses.shape[0]
    nblocks = (n + block - 1) // block
    P, C = _views(G)
    for bi in prange(nblocks):
        _block(poses, bi * block, min(n, (bi + 1) * block), G, P, C, model, K, q, cond, status, T, want_terms, J,
               want_jac)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=core.FASTMATH)
def _batch_serial(poses, G, model, K, q, cond, status, T, want_terms, J, want_jac, block):
    """:func:`_batch` without threads, for small batches (no thread start-up, no wake-up latency)."""
    P, C = _views(G)
    _block(poses, 0, poses.shape[0], G, P, C, model, K, q, cond, status, T, want_terms, J, want_jac)


#: Batches smaller than this run serially (:func:`_batch_serial`): waking the thread pool costs
#: about as much as a few hundred poses (``scripts/bench.py``, small-batch rows).
SERIAL_BELOW = 2 * _BLOCK

#: Whether the one-pose and the batch kernels are compiled (:mod:`h4pin._jit`): until then
#: ``compliance(method="auto")`` takes the numpy reference instead of compiling in the call.
ONE = _jit.Gate("one-pose kernel", _one)
BATCH = _jit.Gate("batch kernel", _batch, _batch_serial)


# ----------------------------------------------------------------------------------------------
# Python API


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
                     terms: bool = False, jacobian: bool = False, vector: bool | None = None) -> KernelResult:
    """K of eq. 30, q, the condition and the verdict at N poses, in parallel over the poses.

    Args:
        g: A geometry (see :func:`prepare`) or a :class:`Kernel`.
        poses: (N, 4) or (4,) poses [x, y, z, theta] (m, rad).
        model: ``"paper"`` or ``"consistent"`` (see :mod:`h4pin.stiffness.api`).
        out: Arrays to fill (a :class:`KernelResult` of the right shapes, e.g. memory-mapped
            files); allocated if None.
        terms: Also return the four terms (4 x 512 bytes a pose more).
        jacobian: Also return J = Jx^-1 Jq (eq. 8).
        vector: Which compiled kernel: ``None`` (default) the vector kernel
            (:mod:`h4pin.stiffness.vector`, poses in lanes) from :data:`h4pin.stiffness.vector.VECTOR_FROM`
            poses once it is compiled, else this module's (one pose at a time); ``True`` /
            ``False`` the one or the other. The same numbers to round-off, the same verdicts.

    The number of threads is numba's (``numba.set_num_threads``).
    """
    kern = prepare(g)
    code = _model_code(model)
    x = as_poses(poses)
    x = np.ascontiguousarray(x[None] if x.ndim == 1 else x)
    res = _empty(len(x), terms, jacobian) if out is None else _check_out(out, len(x), terms, jacobian)
    return _run(kern, x, code, res, terms, jacobian, vector)


def _run(kern: Kernel, x: np.ndarray, code: int, res: KernelResult, terms: bool, jacobian: bool,
         vector: bool | None = None) -> KernelResult:
    """:func:`compliance_batch` on checked input: x (N, 4) C-contiguous float64, res of its size."""
    n = len(x)
    if n and (vector or (vector is None and n >= lanes.VECTOR_FROM and lanes.VECTOR.ready)):
        lanes.run(kern, x, code, res, terms, jacobian)
        return res
    T = res.terms if terms else NO_TERMS_N
    J = res.J if jacobian else NO_J_N
    if n:
        run = _batch if n >= SERIAL_BELOW else _batch_serial
        run(x, kern.packed, code, res.K, res.q, res.condition, res.status, T, terms, J, jacobian, _BLOCK)
    return res


def one(kern: Kernel, x: np.ndarray, code: int, terms: bool = False) -> tuple:
    """:meth:`Kernel.__call__` without its checks, for a caller that has checked them: ``x`` a
    finite float64 pose (4,), ``code`` 0 (paper) or 1 (consistent). Returns K, q, condition,
    status and the terms (4, 8, 8) (None unless ``terms``)."""
    K, q = np.empty((8, 8)), np.empty(4)
    T = np.empty((4, 8, 8)) if terms else NO_TERMS
    cond, status = _one(x, kern.packed, code, terms, K, q, T)
    return K, q, cond, status, T if terms else None


def compliance_one(g: Any, pose: np.ndarray, model: str = "paper") -> tuple[np.ndarray, np.ndarray, float, int]:
    """K (8, 8), q (4,), condition, status at one pose. Pass a :class:`Kernel` (:func:`prepare`)
    for the fast path; a geometry object is packed at every call."""
    return prepare(g)(pose, model)


def iter_compliance(g: Any, poses: np.ndarray | Iterable[np.ndarray], model: str = "paper", *, chunk: int = CHUNK,
                    terms: bool = False, jacobian: bool = False,
                    vector: bool | None = None) -> Iterator[tuple[int, KernelResult]]:
    """Stream the kernel over many poses in chunks: yields ``(start, result)`` per chunk.

    ``poses`` is an (N, 4) array (cut into ``chunk`` rows) or an iterable of (n, 4) arrays (each
    one a chunk, e.g. generated on the fly). The result's arrays are reused from one chunk to
    the next: reduce or copy them before asking for the next one. Memory stays at one chunk.
    ``vector`` as in :func:`compliance_batch`, except that ``None`` chooses once for the whole
    stream (the vector kernel if it is compiled), so that the numbers do not depend on how the
    poses are cut.
    """
    kern = prepare(g)
    if vector is None:
        vector = bool(lanes.VECTOR.ready)
    if chunk < 1:
        raise ParameterError(f"chunk must be >= 1, got {chunk!r}")
    if isinstance(poses, np.ndarray):
        x = as_poses(poses)
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
        yield start, compliance_batch(kern, part, model, view, terms=terms, jacobian=jacobian, vector=vector)
        start += n


def cached() -> bool:
    """Whether the compiled kernels are ready (compiled here, or current in numba's on-disk
    cache); else a call that needs them compiles them, 10 to 30 s once."""
    return ONE.cached() and BATCH.cached()


def threads() -> int:
    """numba's current number of threads for the batch kernel."""
    return numba.get_num_threads()


_KERNELS: dict[int, Kernel] = {}


def for_geometry(g: H4Geometry) -> Kernel:
    """The packed kernel of a loaded robot's geometry, made once per geometry (a read-only cache
    keyed by the immutable :class:`h4pin.H4Geometry`, outside it; threads may share it). Keyed by
    ``id(g)`` and dropped when ``g`` is (a plain dict lookup: a WeakKeyDictionary costs 0.6 us)."""
    kern = _KERNELS.get(id(g))
    if kern is None:
        kern = prepare(g)
        if _KERNELS.setdefault(id(g), kern) is kern:
            weakref.finalize(g, _KERNELS.pop, id(g), None)
    return kern


def backend(h4, x: np.ndarray, model: str, terms: bool):
    """The kernel as a backend of :func:`h4pin.compliance` (:class:`h4pin.stiffness.eq30.Raw`);
    robots whose parallelograms are exact."""
    from h4pin.stiffness.eq30 import Raw

    res = _run(for_geometry(h4.geometry), x, MODELS.index(model), _empty(len(x), terms, False), terms,
               False)  # x: the caller's checked (N, 4) finite poses
    return Raw(res.K, res.terms, res.q, res.condition, res.status)
