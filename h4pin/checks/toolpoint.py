# SPDX-License-Identifier: Apache-2.0
"""Compliance at a tool point: an independent route for :meth:`h4pin.stiffness.api.Compliance.at`.

A real tool or dial indicator is never exactly at D. For a point p fixed to the central bar
(offset o in the central-bar frame, ``p - D = Rz(theta) o``) and a force F applied at another
such point p', the compliance ``C_pp'`` (3x3, ``dp = C_pp' F``) is computed here without the
paper's matrices and without K:

1. :func:`bar_forces_at`: Newton-Euler equilibrium of the three plate bodies with F acting at p'
   (its moment about D is ``(p' - D) x F``), solved for the 8 bar tensions and the reactions of
   the two revolute joints (moments taken about D, not about the world origin as in
   :mod:`h4pin.checks.statics`).
2. :func:`spring_loads_at`: the load of each of the 16 springs of :mod:`h4pin.checks.deformed` (forearm
   rotation about u_i, forearm twist, bar tension) per unit force at p'.
3. :func:`point_sensitivities`: ``dp / d eps_s`` by central differences of the non-linear deformed
   robot (:class:`h4pin.checks.deformed.DeformedH4`): solve the deformed plate, move p rigidly with the
   central bar.
4. Virtual work: ``C_pp' = sum_s c_s (dp/d eps_s) g_s(p')^T`` (:func:`point_compliance`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from h4pin.checks.deformed import DeformedH4
from h4pin.description.geometry import H4Geometry
from h4pin.kinematics import closed_form as geometry


def world_offset(pose: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """p - D (3,) in m for an offset o (3,) given in the central-bar frame: Rz(theta) o."""
    return geometry.rot_z(float(np.asarray(pose)[3])) @ np.asarray(offset, dtype=float)


def _pose_points(g: H4Geometry, pose: np.ndarray) -> tuple[np.ndarray, geometry.Points]:
    x = geometry.as_pose(pose)
    return x, geometry.assembled_points(g, x)


def bar_forces_at(g: H4Geometry, pose: np.ndarray, load_at: np.ndarray) -> np.ndarray:
    """Bar tensions (8, 3) per unit force at p' (offset ``load_at`` (3,) m, central-bar frame).

    Unknowns: tensions f (8), then for each lateral bar k the joint force F_k (3) and the joint
    moment M_k normal to the joint axis v_k (2), acting on lateral bar k (minus them on the
    central bar); the joint carries no moment about its axis (no torque is applied). Equations: force and moment
    (about D) balance of the central bar and of each lateral bar. Bar ij in tension pulls B_ij
    towards A_ij.
    """
    x, pts = _pose_points(g, pose)
    w = (pts.Bij - pts.Aij).reshape(8, 3)
    w = w / np.linalg.norm(w, axis=1, keepdims=True)
    b = pts.Bij.reshape(8, 3) - pts.D  # lever arms about D
    a = np.zeros((18, 18))
    for k in range(2):
        cf, cm = 8 + 5 * k, 11 + 5 * k
        ck = pts.C[k] - pts.D
        normal = geometry.normal_pair(pts.v[k])
        # central bar: -F_k at C_k, -M_k
        a[0:3, cf:cf + 3] -= np.eye(3)
        a[3:6, cf:cf + 3] -= geometry.skew(ck)
        a[3:6, cm:cm + 2] -= normal
        # lateral bar k: +F_k at C_k, +M_k, and its bars
        r0 = 6 + 6 * k
        a[r0:r0 + 3, cf:cf + 3] += np.eye(3)
        a[r0 + 3:r0 + 6, cf:cf + 3] += geometry.skew(ck)
        a[r0 + 3:r0 + 6, cm:cm + 2] += normal
        for n in np.flatnonzero(g.lat == k):
            a[r0:r0 + 3, n] = -w[n]
            a[r0 + 3:r0 + 6, n] = -np.cross(b[n], w[n])
    arm = world_offset(x, load_at)
    rhs = np.zeros((18, 3))
    rhs[0:3] = -np.eye(3)  # F + (joint forces) = 0 on the central bar
    rhs[3:6] = -geometry.skew(arm)  # (p' - D) x F + ... = 0
    return np.linalg.solve(a, rhs)[:8]


def spring_loads_at(g: H4Geometry, pose: np.ndarray, load_at: np.ndarray) -> np.ndarray:
    """Load of each spring (16, 3) per unit force at p', ordered as ``eps`` in
    :meth:`h4pin.checks.deformed.DeformedH4.anchors`: moment about u_i on forearm i (4, N.m/N), moment
    about the forearm axis (4, N.m/N), bar tension (8, N/N)."""
    x, pts = _pose_points(g, pose)
    f = bar_forces_at(g, x, load_at)
    w = (pts.Bij - pts.Aij).reshape(8, 3)
    w = w / np.linalg.norm(w, axis=1, keepdims=True)
    aij = pts.Aij.reshape(8, 3)
    out = np.zeros((16, 3))
    for n in range(8):
        i = n // 2
        e = (pts.A[i] - pts.P[i]) / np.linalg.norm(pts.A[i] - pts.P[i])
        out[i] += g.u[i] @ np.cross(aij[n] - pts.P[i], w[n]) * f[n]
        out[4 + i] += e @ np.cross(aij[n] - pts.A[i], w[n]) * f[n]
    out[8:] = f
    return out


def point_sensitivities(g: H4Geometry, pose: np.ndarray, offset: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """``dp / d eps`` (3, 16) of the point p (offset (3,) m, central-bar frame) by central
    differences of the deformed robot: the plate is solved non-linearly and p moves rigidly
    with the central bar (``p = D + exp(Omega) Rz(theta) o``)."""
    robot = DeformedH4(g, pose)
    o = np.asarray(offset, dtype=float)
    rot = geometry.rot_z(float(robot.pose[3]))

    def point(tp: np.ndarray) -> np.ndarray:
        return robot.state.D + tp[:3] + pin.exp3(tp[3:6]) @ rot @ o

    out = np.empty((3, 16))
    for s in range(16):
        e = np.zeros(16)
        e[s] = step
        out[:, s] = (point(robot.solve_plate(e)) - point(robot.solve_plate(-e))) / (2 * step)
    return out


def spring_compliances(g: H4Geometry) -> np.ndarray:
    """Compliance of each of the 16 springs (16,): actuator + bending per forearm rotation
    (rad/(N.m)), torsion (rad/(N.m)), bar tension (m/N), each element its own."""
    c = g.compliances()
    return np.r_[c["control"] + c["bending"], c["torsion"], c["tension"]]


def point_compliance(g: H4Geometry, pose: np.ndarray, offset: np.ndarray, load_at: np.ndarray | None = None,
                     step: float = 1e-6) -> np.ndarray:
    """``C_pp'`` (3, 3) in m/N by statics (spring loads for a force at p') and finite differences
    of the deformed robot (motion of p per spring deformation); ``load_at`` defaults to ``offset``."""
    load_at = offset if load_at is None else load_at
    g_load = spring_loads_at(g, pose, load_at)
    g_move = point_sensitivities(g, pose, offset, step)
    return (g_move * spring_compliances(g)) @ g_load
