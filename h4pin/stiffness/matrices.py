# SPDX-License-Identifier: Apache-2.0
"""The matrices of Company, Pierrot and Fauroux (ICRA 2005), section IV, at one or many poses.

:class:`Matrices` holds M1, M2, J, M3, M4, M5, Jb, R (and the bar lengths l_ij) of eqs. 6-30.
Two routes build them and a test keeps them equal:

* :func:`from_kinematics`, through Pinocchio: M1 rows are ``w_ij^T JB_ij`` with JB_ij the
  Pinocchio Jacobian of frame B_ij in plate coordinates, M3 the Jacobians of frames A_ij
  w.r.t. the actuators (:meth:`h4pin.H4.kinematics`);
* :func:`from_points`, closed forms of the same derivatives (cross products), vectorised over
  any batch of poses.

Where the code departs from the print (see ``docs/errata.md``): d_epsilon has 32 entries, not 34
(erratum 1); M1 uses t_ij per bar (erratum 2); eq. 16's displacement set is eq. 3's (erratum 3);
Jb, not given, is ``M1^T diag(1/l_ij)``; N of eq. 23 is read as documented at :func:`n_matrix`.
J of eq. 8 is taken from the same model as M1: ``J = (M1^-1 M2 M3)[[0, 1, 2, 5]]`` (the plate
motion per actuator rotation), which equals ``Jx^-1 Jq`` for an ideal robot and stays right for a
toleranced one.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from h4pin.description.geometry import H4Geometry
from h4pin.kinematics import closed_form as geometry
from h4pin.kinematics.closed_form import Points
from h4pin.stiffness.eq30 import inverse, jacobian

#: The selection matrix R of eq. 30 (4x8): Gamma_d = [F, T_z] = R Gamma_ext.
R_PAPER = np.zeros((4, 8))
R_PAPER[[0, 1, 2, 3], [0, 1, 2, 5]] = 1.0
#: R with erratum 4 fixed: t_1, t_2 load the actuators like -T_z (d_omega_k = -d_theta).
R_CONSISTENT = R_PAPER.copy()
R_CONSISTENT[3, 6:8] = -1.0
#: M5 of eq. 27 (32x8): d_epsilon_tens = [0; dl].
M5 = np.vstack([np.zeros((24, 8)), np.eye(8)])


class Matrices(NamedTuple):
    """The paper's matrices at one pose (or a batch: leading shape ``...``), SI units.

    M1 (..., 8, 8) eq. 6; M2 (..., 8, 32) eq. 6; J (..., 4, 4) eq. 8; M3 (..., 32, 4) eq. 11;
    M4 (..., 32, 8) eq. 23; M5 (32, 8) eq. 27; Jb (..., 8, 8) eq. 16; R (4, 8) eq. 30;
    l (..., 8) the bar lengths l_ij.
    """

    M1: np.ndarray
    M2: np.ndarray
    J: np.ndarray
    M3: np.ndarray
    M4: np.ndarray
    M5: np.ndarray
    Jb: np.ndarray
    R: np.ndarray
    l: np.ndarray


def bars(pts: Points) -> tuple[np.ndarray, np.ndarray]:
    """w_ij = B_ij - A_ij (..., 8, 3) and l_ij = ‖w_ij‖ (..., 8)."""
    shape = pts.Bij.shape[:-3]
    w = (pts.Bij - pts.Aij).reshape(*shape, 8, 3)
    return w, np.linalg.norm(w, axis=-1)


def m1_closed_form(g: H4Geometry, pts: Points) -> np.ndarray:
    """M1 of eq. 6 from cross products, (..., 8, 8).

    Row n = (i, j): ``[w_ij^T, (w_ij x (s_k + t_ij))^T, (w_ij x t_ij).v_k in column 6 + k]`` with
    s_k = D - C_k, t_ij = C_k - B_ij and v_k the lateral axis (z for the paper's plate).
    Erratum 2: the print uses t_i per leg, which gives M1 rank 6.
    """
    return geometry.bar_jacobians(g, pts)[1]


def m2(pts: Points) -> np.ndarray:
    """M2 = [spar(w_ij^T), diag(l_ij)] of eq. 6, (..., 8, 32); d_epsilon = [da_11..da_42, dl_11..dl_42]."""
    w, l = bars(pts)
    out = np.zeros((*w.shape[:-2], 8, 32))
    n = np.arange(8)
    for c in range(3):
        out[..., n, 3 * n + c] = w[..., c]
    out[..., n, 24 + n] = l
    return out


def m3_closed_form(g: H4Geometry, pts: Points) -> np.ndarray:
    """M3 = [spar([(p_i1 x u_i)^T (p_i2 x u_i)^T]^T); 0] of eq. 11, (..., 32, 4).

    p_ij = P_i - A_ij; a rotation dq_i of actuator i moves A_ij by (p_ij x u_i) dq_i.
    """
    shape = pts.Aij.shape[:-3]
    p = (pts.P[:, None, :] - pts.Aij).reshape(*shape, 8, 3)
    col = geometry.cross(p, np.repeat(g.u, 2, axis=0))
    out = np.zeros((*shape, 32, 4))
    for n in range(8):
        out[..., 3 * n:3 * n + 3, n // 2] = col[..., n, :]
    return out


def n_matrix(pts: Points) -> np.ndarray:
    """N of eq. 23, one 6x2 block per leg, (..., 4, 6, 2).

    The printed N is garbled. Per leg, the reading that makes eqs. 22 and 23 agree in sign is
    ``N_i = [p_i1 x r_i; p_i2 x r_i] [(p_i1 x r_i).w_i1, (p_i2 x r_i).w_i2]``, with
    p_ij = P_i - A_ij, r_i the unit vector A_i -> P_i and w_ij the unit vector A_ij -> B_ij. A
    twist of forearm i under bar forces f_i1, f_i2 moves A_i1, A_i2 by
    ``c_torsion N_i [f_i1, f_i2]``. The paper writes w_i (A_i -> B_i) in eq. 18: the same vector
    for a true parallelogram; for a toleranced robot each bar pulls along its own w_ij, and only
    that keeps K symmetric (the statics route, :mod:`h4pin.checks.statics`, agrees).
    """
    shape = pts.Aij.shape[:-3]
    p = pts.P[:, None, :] - pts.Aij  # (..., 4, 2, 3)
    r = pts.P - pts.A
    r = r / np.linalg.norm(r, axis=-1, keepdims=True)
    wl = pts.Bij - pts.Aij
    wl = wl / np.linalg.norm(wl, axis=-1, keepdims=True)
    pr = geometry.cross(p, r[..., None, :])  # p_ij x r_i
    c = np.sum(pr * wl, axis=-1)  # (p_ij x r_i) . w_ij
    return pr.reshape(*shape, 4, 6)[..., :, None] * c[..., None, :]


def m4(pts: Points) -> np.ndarray:
    """M4 = [spar(N); 0] of eq. 23, (..., 32, 8), with N from :func:`n_matrix`."""
    n = n_matrix(pts)
    out = np.zeros((*n.shape[:-3], 32, 8))
    for i in range(4):
        out[..., 6 * i:6 * i + 6, 2 * i:2 * i + 2] = n[..., i, :, :]
    return out


def jb_from_m1(m1: np.ndarray, l: np.ndarray) -> np.ndarray:
    """Jb of eq. 16 (not given in the paper): by virtual work, ``Jb = M1^T diag(1/l_ij)``.

    With f_b tension-positive, bar ij pulls the plate at B_ij towards A_ij; the plate's
    equilibrium ``Gamma_ext = Jb f_b`` then follows from ``w_ij . db_ij = (M1 dtp)_ij``.
    """
    return np.swapaxes(m1, -1, -2) / l[..., None, :]


def _assemble(M1: np.ndarray, pts: Points, M3: np.ndarray) -> Matrices:
    _, l = bars(pts)
    M2 = m2(pts)
    return Matrices(M1, M2, jacobian(inverse(M1), M2 @ M3), M3, m4(pts), M5, jb_from_m1(M1, l), R_PAPER, l)


def products(g: H4Geometry, pts: Points) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """M1 (..., 8, 8) and the products eq. 30 needs, from the closed forms (vectorised, sparse):
    ``H = M2 M3`` (..., 8, 4), ``N = M2 M4`` (..., 8, 8) and the bar lengths l (..., 8)
    (``M2 M5 = diag(l)``). Equal to the dense products of :func:`from_points` (tested).

    ``g`` may carry a leading robot axis on its per-leg and per-bar arrays (the tolerance study).
    """
    w, m1, dq = geometry.bar_jacobians(g, pts)
    shape = w.shape[:-2]
    l = np.linalg.norm(w, axis=-1)
    # N: entry (2i+j, 2i+j') = (w_ij . (p_ij x r_i)) c_ij', c_ij = (p_ij x r_i) . unit(w_ij) (n_matrix).
    p = pts.P[..., None, :] - pts.Aij
    r = pts.P - pts.A
    r = r / np.linalg.norm(r, axis=-1, keepdims=True)
    pr = geometry.cross(p, r[..., None, :]).reshape(*shape, 8, 3)
    a = np.sum(w * pr, axis=-1)
    c = a / l
    N = np.zeros((*shape, 8, 8))
    for i in range(4):
        s = slice(2 * i, 2 * i + 2)
        N[..., s, s] = a[..., s, None] * c[..., None, s]
    return m1, -dq, N, l


def products_of(mats: Matrices) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """M1, ``M2 M3``, ``M2 M4`` and l from the dense matrices (e.g. Pinocchio's, :func:`from_kinematics`)."""
    return mats.M1, mats.M2 @ mats.M3, mats.M2 @ mats.M4, mats.l


def from_points(g: H4Geometry, pts: Points) -> Matrices:
    """All the paper's matrices from the closed forms (vectorised over a batch of poses)."""
    return _assemble(m1_closed_form(g, pts), pts, m3_closed_form(g, pts))


def from_kinematics(kin) -> Matrices:
    """All the paper's matrices at one pose from Pinocchio (:meth:`h4pin.H4.kinematics`):
    M1 rows ``w_ij^T JB_ij`` (eq. 6), M3 rows of leg i the Jacobians of A_i1, A_i2 w.r.t.
    actuator i (eq. 11), M2, M4 from Pinocchio's frame positions."""
    w, _ = bars(kin.points)
    M1 = np.einsum("na,nab->nb", w, kin.JB)
    M3 = np.zeros((32, 4))
    M3[:24] = kin.JA.reshape(24, 4)
    return _assemble(M1, kin.points, M3)
