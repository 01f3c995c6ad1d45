# SPDX-License-Identifier: Apache-2.0
"""An independent route to the compliance: Newton-Euler statics of the plate and unit loads.

This module shares nothing with :mod:`h4pin.stiffness.api` but the points of the pose: it does not
use M1, J, Jb or R. It serves to check the ``consistent`` model (and each of its four terms).

1. Equilibrium of the three plate bodies (central bar, lateral bars 1 and 2) under
   ``Gamma_ext = [F, T, t_1, t_2]``: 18 equations (6 per body) for 18 unknowns, the 8 bar
   tensions and the reactions of the two revolute joints (force, 3, and the moment about x and
   y, 2, each; the moment about z is the applied joint torque t_k).
2. Each spring's load follows from the bar forces acting on the forearms: the moment about the
   actuator axis (control spring and forearm bending, eqs. 10 and 14), the moment about the
   forearm axis (torsion, eq. 20), the bar tension (eq. 25).
3. Unit-load method (virtual work): ``C = sum_s c_s g_s g_s^T`` where ``g_s`` (8,) is the load of
   spring s per unit Gamma_ext and ``c_s`` its compliance.
"""

from __future__ import annotations

import numpy as np

from h4pin.description.geometry import H4Geometry
from h4pin.kinematics import closed_form as geometry

_Z = np.array([0.0, 0.0, 1.0])


def _unit_bars(pts: geometry.Points) -> np.ndarray:
    """Unit vectors A_ij -> B_ij, (8, 3)."""
    w = (pts.Bij - pts.Aij).reshape(8, 3)
    return w / np.linalg.norm(w, axis=1, keepdims=True)


def bar_forces(g: H4Geometry, pose: np.ndarray) -> np.ndarray:
    """Bar tensions per unit external load, (8, 8): ``f_b = Lambda Gamma_ext`` (N per N or N.m).

    Solved from the equilibrium of the central bar and the two lateral bars (moments about the
    world origin). Bar ij (n = 2(i-1) + j-1), in tension f, pulls its plate end B_ij towards A_ij.
    """
    return _bar_forces(g, geometry.assembled_points(g, pose))


def _bar_forces(g: H4Geometry, pts: geometry.Points) -> np.ndarray:
    w = _unit_bars(pts)
    bij = pts.Bij.reshape(8, 3)
    # Unknowns: f (8) | F_1 (3), M_1 normal to v_1 (2) | F_2 (3), M_2 normal to v_2 (2).  F_k, M_k act on lateral bar k,
    # minus them on the central bar. Rows: central force, central moment, lateral 1 (6), lateral 2 (6).
    a = np.zeros((18, 18))
    rhs = np.zeros((18, 8))
    for k in range(2):
        vk = pts.v[k]
        e_xy = geometry.normal_pair(vk)
        col_f, col_m = 8 + 5 * k, 11 + 5 * k
        ck = pts.C[k]
        a[0:3, col_f:col_f + 3] = -np.eye(3)  # central: sum of forces
        a[3:6, col_f:col_f + 3] = -geometry.skew(ck)  # central: sum of moments about O
        a[3:6, col_m:col_m + 2] = -e_xy
        rows = slice(6 + 6 * k, 12 + 6 * k)
        a[rows.start:rows.start + 3, col_f:col_f + 3] = np.eye(3)
        a[rows.start + 3:rows.stop, col_f:col_f + 3] = geometry.skew(ck)
        a[rows.start + 3:rows.stop, col_m:col_m + 2] = e_xy
        for n in np.flatnonzero(g.lat == k):
            a[rows.start:rows.start + 3, n] = -w[n]  # bar pulls B towards A
            a[rows.start + 3:rows.stop, n] = -np.cross(bij[n], w[n])
        # Joint torque t_k: +t_k v_k on lateral bar k, -t_k v_k on the central bar.
        rhs[rows.start + 3:rows.stop, 6 + k] = -vk
        rhs[3:6, 6 + k] = vk
    # External F, T at D on the central bar: F + ..., T + D x F + ... = 0.
    rhs[0:3, 0:3] = -np.eye(3)
    rhs[3:6, 0:3] = -geometry.skew(pts.D)
    rhs[3:6, 3:6] = -np.eye(3)
    return np.linalg.solve(a, rhs)[:8]


def spring_loads(g: H4Geometry, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Load of every spring per unit Gamma_ext: ``{"control", "bending", "torsion"}`` (4, 8) in
    N.m per unit load, ``"tension"`` (8, 8) in N per unit load.

    The bars pull forearm i at A_ij with ``f_ij w_ij`` (unit w_ij towards B_ij). The actuator and
    bending springs carry the moment of these forces about the actuator axis (u_i through P_i),
    the torsion spring their moment about the forearm axis (through A_i, along P_i -> A_i).
    """
    pts = geometry.assembled_points(g, pose)
    f = _bar_forces(g, pts)
    w = _unit_bars(pts)
    aij = pts.Aij.reshape(8, 3)
    axis_moment = np.zeros((4, 8))
    twist = np.zeros((4, 8))
    for n in range(8):
        i = n // 2
        force = np.outer(w[n], f[n])  # (3, 8): force on the forearm per unit load
        e = (pts.A[i] - pts.P[i]) / np.linalg.norm(pts.A[i] - pts.P[i])
        axis_moment[i] += g.u[i] @ np.cross(aij[n] - pts.P[i], force.T).T
        twist[i] += e @ np.cross(aij[n] - pts.A[i], force.T).T
    return {"control": axis_moment, "bending": axis_moment, "torsion": twist, "tension": f}


def compliance_terms(g: H4Geometry, pose: np.ndarray) -> dict[str, np.ndarray]:
    """The four terms of the compliance by unit loads, ``sum_s c_s g_s g_s^T`` over the springs
    of each family (each with its own compliance), each (8, 8), SI."""
    c = g.compliances()
    return {t: (load.T * c[t]) @ load for t, load in spring_loads(g, pose).items()}


def compliance_matrix(g: H4Geometry, pose: np.ndarray) -> np.ndarray:
    """Compliance (8, 8) by the statics route; equals the ``consistent`` model of eq. 30."""
    return sum(compliance_terms(g, pose).values())
