# SPDX-License-Identifier: Apache-2.0
"""What the compiled pipeline and its Python front end share: the layouts of the packed geometry
vector and of the element table (offsets into float64 arrays, filled by
:func:`h4pin.stiffness.kernel.pack` and :func:`h4pin.stiffness.kernel.pack_elements`), the result,
:class:`KernelResult`, and the placeholders of the outputs a run does not write.

:mod:`h4pin.stiffness.pipeline` (compiled) and :mod:`h4pin.stiffness.kernel` (Python) both import
it. numba freezes these offsets into the compiled code (the cache stamps follow the import:
:mod:`h4pin._numba_cache`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

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
_SIZE = 211

# Layout of the element table (one float64 array, :func:`h4pin.stiffness.kernel.pack_elements`):
# [number of kinds on | one row per kind on: site, form, axis, count, offset of its values |
# per element of the kind: compliance (its value, or 1 / rigidity, times ``series``), length (m)].
EL_HEADER = 1
EL_ROW = 5


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


__all__ = ["EL_HEADER", "EL_ROW", "NO_ELEMENTS", "NO_J_N", "NO_TERMS_N", "NO_X_N", "KernelResult"]
