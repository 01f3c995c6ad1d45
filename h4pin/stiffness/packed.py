# SPDX-License-Identifier: Apache-2.0
"""What the compiled pipeline and its Python front end share: the layouts of the packed geometry
vector and of the element table (offsets into float64 arrays, filled by
:func:`pack` and :func:`h4pin.stiffness.kernel.pack_elements`), the result,
:class:`KernelResult`, and the placeholders of the outputs a run does not write.

:mod:`h4pin.stiffness.pipeline` (compiled) and :mod:`h4pin.stiffness.kernel` (Python) both import
it. numba freezes these offsets into the compiled code (the cache stamps follow the import:
:mod:`h4pin._numba_cache`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from h4pin.errors import ParameterError

# Layout of the packed geometry vector (offsets into one float64 array; public: the compiled
# pipeline and the natural frequencies read it).
G_P = 0  # (4, 3) P_i
G_U = 12  # (4, 3) u_i
G_V = 24  # (8, 3) A0_ij - P_i
G_UV = 48  # (8, 3) u_i x (A0_ij - P_i)
G_UVU = 72  # (8, 3) (u_i . (A0_ij - P_i)) u_i
G_M = 96  # (4, 3) m_i
G_UM = 108  # (4, 3) u_i x m_i
G_R2 = 120  # (4,) r_i^2
G_LL = 124  # (4,) bar length of leg i (mean of its two bars)
G_C0 = 128  # (2, 3)
G_BB = 134  # (8, 3) B_ij - C_k
G_BM = 158  # (4, 3) B_i - C_k
G_LAT = 170  # (8,) lateral bar of each bar (as float)
G_CCTRL = 178  # (4,)
G_CBEND = 182  # (4,)
G_CTORS = 186  # (4,)
G_CTENS = 190  # (8,)
G_QLO = 198  # (4,)
G_QHI = 202  # (4,)
G_WLO = 206  # (2,)
G_WHI = 208  # (2,)
G_CLEAR = 210
G_SIZE = 211

# Layout of the element table (one float64 array, :func:`h4pin.stiffness.kernel.pack_elements`):
# [number of kinds on | one row per kind on: site, form, axis, count, offset of its values, second
# axis (normal) | per element of the kind: compliance (its value, or 1 / rigidity, times
# ``series``), length (m)].
EL_HEADER = 1
EL_ROW = 6


class KernelResult(NamedTuple):
    """Output of the kernel for N poses (SI).

    K (N, 8, 8) of eq. 30 and the elements (NaN unless status is 0); q (N, 4) actuator angles,
    rad (NaN if unreachable); condition (N,) scaled 1-norm condition number of M1; status (N,)
    int8 (:mod:`h4pin.verdicts`); terms (N, 4 + kinds on, 8, 8): control, bending, torsion,
    tension, then one per element kind that is on (or None); J (N, 4, 4) = Jx^-1 Jq of eq. 8 (or
    None).
    """

    K: np.ndarray
    q: np.ndarray
    condition: np.ndarray
    status: np.ndarray
    terms: np.ndarray | None = None
    J: np.ndarray | None = None


#: The T and J arguments of a run without terms or without J (never written: the pipeline writes
#: them only when asked for them).
NO_TERMS_N = np.empty((1, 4, 8, 8))
NO_J_N = np.empty((1, 4, 4))
NO_X_N = np.empty((1, 1))
#: The element table of a robot with every element off.
NO_ELEMENTS = np.zeros(EL_HEADER)
NO_ELEMENTS.setflags(write=False)

#: The geometry attributes the pipeline packs, and their shapes (legs i, bars n = 2 i + j).
SHAPES = {"P": (4, 3), "u": (4, 3), "A0": (8, 3), "l": (8,), "lat": (8,), "C0": (2, 3), "b": (8, 3),
           "c_ctrl": (4,), "c_bend": (4,), "c_tors": (4,), "c_tens": (8,), "q_lo": (4,), "q_hi": (4,),
           "omega_lo": (2,), "omega_hi": (2,)}


def pack(P: np.ndarray, u: np.ndarray, A0: np.ndarray, l: np.ndarray, lat: np.ndarray, C0: np.ndarray,
         b: np.ndarray, c_ctrl: np.ndarray, c_bend: np.ndarray, c_tors: np.ndarray, c_tens: np.ndarray,
         q_lo: np.ndarray, q_hi: np.ndarray, omega_lo: np.ndarray, omega_hi: np.ndarray,
         bar_clearance: float | np.ndarray) -> np.ndarray:
    """The packed vectors G (..., G_SIZE) of the kernel from the attributes of :func:`prepare`
    (shapes there), each with any leading robot axes (broadcast). No checks: :func:`prepare`
    and :func:`pack_fields` check before packing."""
    P, u, A0, l, C0, b = (np.asarray(x, dtype=float) for x in (P, u, A0, l, C0, b))
    lat = np.asarray(lat, dtype=float)
    rest = {"c_ctrl": c_ctrl, "c_bend": c_bend, "c_tors": c_tors, "c_tens": c_tens, "q_lo": q_lo, "q_hi": q_hi,
            "omega_lo": omega_lo, "omega_hi": omega_hi}
    batch = np.broadcast_shapes(*(np.shape(x)[:np.ndim(x) - len(SHAPES[k])] for k, x in
                                  {"P": P, "u": u, "A0": A0, "l": l, "lat": lat, "C0": C0, "b": b, **rest}.items()),
                                np.shape(bar_clearance))
    leg = np.repeat(np.arange(4), 2)
    ul = u[..., leg, :]
    v = A0 - P[..., leg, :]
    m = 0.5 * (v[..., 0::2, :] + v[..., 1::2, :])
    G = np.zeros(batch + (G_SIZE,))

    def put(offset: int, x: np.ndarray, trailing: int = 1) -> None:
        x = np.asarray(x, dtype=float)
        x = x.reshape(x.shape[:x.ndim - trailing] + (int(np.prod(x.shape[x.ndim - trailing:])),))
        G[..., offset:offset + x.shape[-1]] = x

    put(G_P, P, 2)
    put(G_U, u, 2)
    put(G_V, v, 2)
    put(G_UV, np.cross(ul, v), 2)
    put(G_UVU, np.einsum("...na,...na->...n", ul, v)[..., None] * ul, 2)
    put(G_M, m, 2)
    put(G_UM, np.cross(u, m), 2)
    put(G_R2, np.einsum("...ia,...ia->...i", m, m))
    put(G_LL, 0.5 * (l[..., 0::2] + l[..., 1::2]))
    put(G_C0, C0, 2)
    put(G_BB, b, 2)
    put(G_BM, 0.5 * (b[..., 0::2, :] + b[..., 1::2, :]), 2)
    put(G_LAT, lat)
    put(G_CCTRL, c_ctrl)
    put(G_CBEND, c_bend)
    put(G_CTORS, c_tors)
    put(G_CTENS, c_tens)
    put(G_QLO, q_lo)
    put(G_QHI, q_hi)
    put(G_WLO, omega_lo)
    put(G_WHI, omega_hi)
    G[..., G_CLEAR] = bar_clearance
    return G


def beam_lengths(packed: np.ndarray) -> dict[str, np.ndarray]:
    """Lengths of the beams a geometry holds (m): the central-bar segments |C_k - D| (2,), the
    lateral arms |B_i - C_k| (4,) and the forearms |A_i - P_i| (4,)."""
    return {"central": np.linalg.norm(packed[G_C0:G_C0 + 6].reshape(2, 3), axis=1),
            "arm": np.linalg.norm(packed[G_BM:G_BM + 12].reshape(4, 3), axis=1),
            "forearm": np.linalg.norm(packed[G_M:G_M + 12].reshape(4, 3), axis=1)}



def check_packed(G: np.ndarray) -> None:
    """The check of :func:`h4pin.stiffness.kernel.prepare` on packed vectors (..., G_SIZE): P_i is the foot of the
    perpendicular from A_i (m_i . u_i = 0)."""
    m = G[..., G_M:G_M + 12].reshape(G.shape[:-1] + (4, 3))
    u = G[..., G_U:G_U + 12].reshape(G.shape[:-1] + (4, 3))
    if np.any(np.abs(np.einsum("...ia,...ia->...i", m, u)) > 1e-9 * np.linalg.norm(m, axis=-1)):
        raise ParameterError("geometry.P must be the foot of the perpendicular from the forearm end A_i "
                             "on the actuator axis (m_i . u_i = 0)")


__all__ = ["EL_HEADER", "EL_ROW", "G_BB", "G_BM", "G_C0", "G_CBEND", "G_CCTRL", "G_CLEAR", "G_CTENS", "G_CTORS",
           "G_LAT", "G_LL", "G_M", "G_P", "G_QHI", "G_QLO", "G_R2", "G_SIZE", "G_U", "G_UM", "G_UV", "G_UVU", "G_V",
           "G_WHI", "G_WLO", "NO_ELEMENTS", "NO_J_N", "NO_TERMS_N", "NO_X_N", "SHAPES", "KernelResult", "beam_lengths",
           "check_packed", "pack"]
