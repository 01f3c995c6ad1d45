# SPDX-License-Identifier: Apache-2.0
"""Closed-loop geometry of an H4 from its per-leg and per-bar constants (:class:`H4Geometry`).

Pure numpy, vectorised over any leading batch shape. This is the fast path for batches and the
reference against which the Pinocchio route (:class:`h4pin.H4`) is tested.

A pose is ``x = [x, y, z, theta]`` (m, rad): the position of D and the rotation of the central
bar about z. The plate's full state is :class:`PlateState`: D, the central bar's orientation R
and the relative angles omega_k of the lateral bars (about their axes v_k). For a robot whose
parallelograms are true parallelograms (``g.ideal``) the pose fixes the state in closed form
(R = Rz(theta), omega_k = -theta: the lateral bars only translate). A toleranced robot (unequal
bars, offsets that do not match) tilts its plate slightly: the state is then solved by Newton's
method on the eight bar closures, started from the closed form.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from h4pin.description.geometry import H4Geometry
from h4pin.errors import ConvergenceError, PoseError
from h4pin.verdicts import INTERFERENCE, LIMITS, OK, UNREACHABLE, raise_for_status

_Z = np.array([0.0, 0.0, 1.0])



class Points(NamedTuple):
    """Characteristic points of an assembled H4, in m, world frame; ``...`` is the batch shape."""

    D: np.ndarray  #: (..., 3)
    C: np.ndarray  #: (..., 2, 3) revolute joint centres C_k
    B: np.ndarray  #: (..., 4, 3) B_i, middle of B_i1, B_i2
    Bij: np.ndarray  #: (..., 4, 2, 3) plate-side ball joints
    P: np.ndarray  #: (4, 3) actuator axis points
    A: np.ndarray  #: (..., 4, 3) forearm ends A_i, middle of A_i1, A_i2
    Aij: np.ndarray  #: (..., 4, 2, 3) forearm-side ball joints
    v: np.ndarray  #: (..., 2, 3) world axes of the lateral revolutes


class PlateState(NamedTuple):
    """Assembled state: actuator angles and plate placement (``...`` is the batch shape)."""

    q: np.ndarray  #: (..., 4) rad
    D: np.ndarray  #: (..., 3) m
    R: np.ndarray  #: (..., 3, 3) orientation of the central bar (w.r.t. its reference)
    omega: np.ndarray  #: (..., 2) rad, relative angles of the lateral bars about v_k


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` over the last axis (3), broadcast; several times faster than ``np.cross`` on
    the small arrays of this package."""
    a, b = np.asarray(a), np.asarray(b)
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def as_poses(pose: np.ndarray | list | tuple, name: str = "pose") -> np.ndarray:
    """Check and convert a pose (4,) or a batch (N, 4) to float64; clear error otherwise."""
    try:
        complex_input = np.iscomplexobj(pose)  # lists too (it reads their dtype)
    except (TypeError, ValueError):  # ragged: refused below
        complex_input = False
    if complex_input:
        raise PoseError(f"{name} must be real numbers [x, y, z, theta], got {pose!r}")
    try:
        x = np.asarray(pose, dtype=float)
    except (TypeError, ValueError):
        raise PoseError(f"{name} must be numbers [x, y, z, theta], got {pose!r}") from None
    if x.ndim not in (1, 2) or x.shape[-1] != 4:
        raise PoseError(f"{name} must have shape (4,) or (N, 4) as [x, y, z, theta], got shape {x.shape}")
    if not np.isfinite(x).all():
        bad = ~np.all(np.isfinite(x), axis=-1)
        index = int(np.argmax(bad)) if x.ndim == 2 else None
        raise PoseError(f"{name} has non-finite entries: {x[index] if index is not None else x}", index)
    return x


def as_pose(pose: np.ndarray | list | tuple, name: str = "pose") -> np.ndarray:
    """One pose (4,) as float64; a batch or a wrong shape is a :class:`PoseError` naming ``name``."""
    if type(pose) is np.ndarray and pose.shape == (4,) and pose.dtype == np.float64 and math.isfinite(pose.sum()):
        return pose
    x = as_poses(pose, name)
    if x.ndim != 1:
        raise PoseError(f"{name} must be one pose of shape (4,), got shape {x.shape}")
    return x


def rot_z(theta: np.ndarray) -> np.ndarray:
    """Rz(theta), shape (..., 3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    out = np.zeros((*np.shape(theta), 3, 3))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    out[..., 2, 2] = 1.0
    return out


def rotate(x: np.ndarray, axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: ``x`` (..., 3) turned by ``angle`` (...) about the unit ``axis`` (..., 3)."""
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    return x * c + cross(axis, x) * s + axis * np.sum(axis * x, axis=-1, keepdims=True) * (1.0 - c)


def exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors ``w`` (..., 3)."""
    angle = np.linalg.norm(w, axis=-1)
    safe = np.where(angle > 0, angle, 1.0)
    k = w / safe[..., None]
    kx = np.zeros((*w.shape[:-1], 3, 3))
    kx[..., 0, 1], kx[..., 0, 2], kx[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    kx = kx - np.swapaxes(kx, -1, -2)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * kx + (1.0 - c) * (kx @ kx)


def skew(v: np.ndarray) -> np.ndarray:
    """The cross-product matrix [v]x (3, 3) of a vector v (3,): ``skew(v) @ w = v x w``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def normal_pair(axis: np.ndarray) -> np.ndarray:
    """(3, 2): two orthonormal vectors normal to the unit ``axis``, as columns."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(axis, e1)])


def rigid_state(pose: np.ndarray, q: np.ndarray) -> PlateState:
    """The state of a rigid pose: R = Rz(theta), omega_k = -theta (lateral bars translate)."""
    theta = pose[..., 3]
    return PlateState(q, pose[..., :3], rot_z(theta), np.stack([-theta, -theta], axis=-1))


def forearm_points(g: H4Geometry, q: np.ndarray) -> np.ndarray:
    """A_ij (..., 8, 3) for actuator angles q (..., 4): A0_ij turned by q_i about axis i."""
    pb = np.repeat(g.P, 2, axis=-2)
    return pb + rotate(g.A0 - pb, np.repeat(g.u, 2, axis=0), np.repeat(q, 2, axis=-1))


def _apply(R: np.ndarray, x: np.ndarray) -> np.ndarray:
    """R (..., 3, 3) applied to points x (..., k, 3), elementwise (faster than tiny matmuls)."""
    return (R[..., None, :, 0] * x[..., 0:1] + R[..., None, :, 1] * x[..., 1:2]
            + R[..., None, :, 2] * x[..., 2:3])


def plate_points(g: H4Geometry, D: np.ndarray, R: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, ...]:
    """C_k (..., 2, 3), B_ij (..., 8, 3) and the world lateral axes (..., 2, 3) of a plate state."""
    C = D[..., None, :] + _apply(R, g.C0)
    if np.array_equal(g.v, np.tile(_Z, (2, 1))):  # vertical lateral axes: turn b about z
        c, s = np.cos(omega)[..., g.lat], np.sin(omega)[..., g.lat]
        bx, by = g.b[..., 0], g.b[..., 1]
        local = np.stack([c * bx - s * by, s * bx + c * by, np.broadcast_to(g.b[..., 2], c.shape)], axis=-1)
        B = C[..., g.lat, :] + _apply(R, local)
    else:
        lat_rot = R[..., None, :, :] @ exp_so3(g.v * omega[..., :, None])  # (..., 2, 3, 3)
        B = C[..., g.lat, :] + (lat_rot[..., g.lat, :, :] @ g.b[..., None])[..., 0]
    return C, B, g.v @ np.swapaxes(R, -1, -2)


def points(g: H4Geometry, state: PlateState) -> Points:
    """All characteristic points of an assembled state."""
    C, Bij, v = plate_points(g, state.D, state.R, state.omega)
    Aij = forearm_points(g, state.q)
    shape = Aij.shape[:-2]
    Bij, Aij = Bij.reshape(*shape, 4, 2, 3), Aij.reshape(*shape, 4, 2, 3)
    return Points(state.D, C, Bij.mean(axis=-2), Bij, g.P, Aij.mean(axis=-2), Aij, v)


def _closed_form(g: H4Geometry, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Elbow-out q (..., 4) of each leg's midpoints, and the ratio cos(q - phi) (..., 4)
    (|ratio| > 1: the leg cannot reach) with the leg's e = B_i - P_i.

    Leg i closes when ``|B_i - A_i(q)| = l_i``. With ``e = B_i - P_i`` and
    ``A_i(q) - P_i = m_i cos q + (u_i x m_i) sin q`` (m_i = A_i(0) - P_i, normal to u_i):
    ``(e.m) cos q + (e.(u x m)) sin q = (|e|^2 + r^2 - l^2) / 2``. Writing
    ``alpha = e.m, beta = e.(u x m) = rho sin(phi), alpha = rho cos(phi)``: the elbow-out test
    ``u.((A - P) x (B - A)) = beta cos q - alpha sin q = rho sin(phi - q) > 0`` picks
    ``q = phi - acos(c / rho)``.
    """
    theta = pose[..., 3]
    C = pose[..., None, :3] + np.einsum("...ab,kb->...ka", rot_z(theta), g.C0)
    B = C[..., g.leg_lat, :] + g.b_leg
    e = B - g.P
    alpha = np.sum(e * g.m, axis=-1)
    beta = np.sum(e * g.um, axis=-1)
    c = 0.5 * (np.sum(e * e, axis=-1) + g.r**2 - g.l_leg**2)
    rho = np.hypot(alpha, beta)
    ratio = np.divide(c, rho, out=np.full_like(c, np.inf), where=rho > 0)
    q = np.arctan2(beta, alpha) - np.arccos(np.clip(ratio, -1.0, 1.0))
    return (q + np.pi) % (2 * np.pi) - np.pi, ratio, e


def bar_jacobians(g: H4Geometry, pts: Points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """w_ij (..., 8, 3) and the derivatives of (‖B - A‖^2 - l^2)/2 w.r.t. the plate
    coordinates [dD, dOmega, domega_1, domega_2] (..., 8, 8, i.e. M1 of eq. 6) and the
    actuator angles (..., 8, 4)."""
    shape = pts.Aij.shape[:-3]
    bij, aij = pts.Bij.reshape(*shape, 8, 3), pts.Aij.reshape(*shape, 8, 3)
    w = bij - aij
    m1 = np.zeros((*shape, 8, 8))
    m1[..., :3] = w
    m1[..., 3:6] = cross(bij - pts.D[..., None, :], w)
    lever = cross(pts.v[..., g.lat, :], bij - pts.C[..., g.lat, :])
    m1[..., np.arange(8), 6 + g.lat] = np.sum(w * lever, axis=-1)
    dq = np.zeros((*shape, 8, 4))
    arm = cross(np.repeat(g.u, 2, axis=0), aij - np.repeat(g.P, 2, axis=-2))
    dq[..., np.arange(8), np.arange(8) // 2] = -np.sum(w * arm, axis=-1)
    return w, m1, dq


def newton_jacobian(g: H4Geometry, pts: Points, free_q: bool) -> np.ndarray:
    """The Jacobian (..., 8, 8) of the closures w.r.t. the unknowns of :func:`newton`: q (4), tilt
    x, y, lateral 1, 2 (``free_q``); or D (3), theta (a rotation about z with the lateral bars
    kept), tilt x, y, lateral 1, 2."""
    _, m1, dq = bar_jacobians(g, pts)
    if free_q:
        return np.concatenate([dq, m1[..., 3:5], m1[..., 6:8]], axis=-1)
    dtheta = m1[..., 5:6] - m1[..., 6:7] * (g.lat == 0)[:, None] - m1[..., 7:8] * (g.lat == 1)[:, None]
    return np.concatenate([m1[..., :3], dtheta, m1[..., 3:5], m1[..., 6:8]], axis=-1)


def newton(g: H4Geometry, pose: np.ndarray, state: PlateState, free_q: bool, *, jac0_inv: np.ndarray | None = None,
           tol: float = 1e-13, max_iter: int = 30,
           rcond: float | None = None) -> tuple[PlateState, np.ndarray, np.ndarray, np.ndarray]:
    """Solve the eight closures ``(|B_ij - A_ij|^2 - l_ij^2) / 2 = 0`` by Newton's method.

    ``free_q``: unknowns are q, the tilt of the central bar and the lateral angles (inverse
    geometry: D and theta fixed); otherwise D, theta, tilt and the lateral angles (forward
    geometry: q fixed). ``g`` may carry leading robot axes that broadcast with the poses'
    (robots x poses, the tolerance study). With ``jac0_inv`` (the inverse Jacobian at a nearby
    solution, e.g. the nominal robot's), the chord method: that fixed Jacobian for every step
    (residuals only). With ``rcond``, each step is the least-norm one, the Jacobian's singular
    values under ``rcond`` times its largest dropped (``np.linalg.pinv``): at an exactly singular
    assembly the unknowns do not move along the direction the closures cannot resolve, where a
    plain solve moves them by round-off amplified by the condition number (1e-9 m, and not the
    same on two CPUs). Returns the state, a converged flag per pose, theta and the tilt (the
    pose's rotation: R = exp(tilt) Rz(theta), tilt normal to z).
    """
    q, D, theta = state.q.copy(), state.D.copy(), pose[..., 3].copy()
    shape = np.broadcast_shapes(theta.shape, np.shape(g.l)[:-1])
    q, D, theta = (np.broadcast_to(a, (*shape, *a.shape[theta.ndim:])).copy() for a in (q, D, theta))
    tilt = np.zeros((*shape, 3))
    psi = np.broadcast_to(state.omega + pose[..., 3, None], (*shape, 2)).copy()
    done = np.zeros(shape, dtype=bool)
    scale = tol * float(np.max(g.l))
    for _ in range(max_iter):
        R = exp_so3(tilt) @ rot_z(theta)
        st = PlateState(q, D, R, psi - theta[..., None])
        pts = points(g, st)
        w = (pts.Bij - pts.Aij).reshape(*shape, 8, 3)
        res = 0.5 * (np.sum(w * w, axis=-1) - g.l**2)
        done = np.max(np.abs(res), axis=-1) < scale
        if np.all(done):
            return st, done, theta, tilt
        if jac0_inv is not None:
            step = -(jac0_inv @ res[..., None])[..., 0]
        elif rcond is not None:
            step = -(np.linalg.pinv(newton_jacobian(g, pts, free_q), rcond=rcond) @ res[..., None])[..., 0]
        else:
            step = _solve_rows(newton_jacobian(g, pts, free_q), -res)
        step = np.where(done[..., None], 0.0, step)
        if free_q:
            q = q + step[..., :4]
        else:
            D = D + step[..., :3]
            theta = theta + step[..., 3]
        tilt[..., :2] += step[..., 4:6]
        psi = psi + step[..., 6:8]
        if not np.all(np.isfinite(step)):
            break
    R = exp_so3(tilt) @ rot_z(theta)
    st = PlateState(q, D, R, psi - theta[..., None])
    pts = points(g, st)
    w = (pts.Bij - pts.Aij).reshape(*shape, 8, 3)
    res = 0.5 * (np.sum(w * w, axis=-1) - g.l**2)
    return st, np.max(np.abs(res), axis=-1) < scale, theta, tilt


def _solve_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 b`` for a batch of square systems; a singular one gives NaN, not an exception."""
    with np.errstate(all="ignore"):
        try:
            return np.linalg.solve(a, b[..., None])[..., 0]
        except np.linalg.LinAlgError:
            out = np.full(b.shape, np.nan)
            flat_a, flat_b = a.reshape(-1, *a.shape[-2:]), b.reshape(-1, b.shape[-1])
            flat = out.reshape(-1, b.shape[-1])
            for n in range(len(flat_a)):
                try:
                    flat[n] = np.linalg.solve(flat_a[n], flat_b[n])
                except np.linalg.LinAlgError:
                    pass
            return out


def segment_distances(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Shortest distances between segments a0-a1 and b0-b1 (..., 3) -> (...)."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e, f = np.sum(d1 * d1, -1), np.sum(d2 * d2, -1), np.sum(d2 * r, -1)
    c, b = np.sum(d1 * r, -1), np.sum(d1 * d2, -1)
    denom = a * e - b * b
    with np.errstate(all="ignore"):
        s = np.where(denom > 1e-18 * a * e, np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        t = (b * s + f) / e
        t_c = np.clip(t, 0.0, 1.0)
        s = np.where(t != t_c, np.clip((b * t_c - c) / a, 0.0, 1.0), s)
    return np.linalg.norm(a0 + s[..., None] * d1 - b0 - t_c[..., None] * d2, axis=-1)


#: Pairs of bars of different legs (24 of the 28 pairs), checked for interference.
_PAIRS = np.array([(m, n) for m in range(8) for n in range(m + 1, 8) if m // 2 != n // 2])


class Solution(NamedTuple):
    """Inverse geometry of a batch of poses: the states, a verdict per pose and its reason."""

    state: PlateState
    status: np.ndarray  #: (...,) int8, :data:`h4pin.verdicts.STATUS_NAMES`
    detail: list[str | None]  #: a message per pose (None when ok)


#: A pose coordinate (m) beyond which D is out of reach of any robot h4pin models: such poses are
#: computed without numpy's overflow warnings (their squares overflow near 1e154 m), unreachable.
FAR = 1e6


def solve(g: H4Geometry, pose: np.ndarray, *, check: bool = True) -> Solution:
    """Inverse geometry with a verdict per pose: unreachable, outside the joint limits, bars
    interpenetrating (``check``), or ok (status 0). Never raises on a bad pose, and never warns
    on one: a pose more than :data:`FAR` from the base is unreachable, told without numpy's
    overflow warnings."""
    x = as_poses(pose)
    if x.size and np.abs(x[..., :3]).max() > FAR:
        with np.errstate(over="ignore", invalid="ignore"):
            return _solve(g, x, check)
    return _solve(g, x, check)


def _solve(g: H4Geometry, x: np.ndarray, check: bool) -> Solution:
    single = x.ndim == 1
    xb = x[None] if single else x
    n = len(xb)
    q, ratio, e = _closed_form(g, xb)
    status = np.zeros(n, dtype=np.int8)
    detail: list[str | None] = [None] * n
    reach = np.abs(ratio) <= 1.0
    for k in np.flatnonzero(~reach.all(axis=1)):
        leg = int(np.argmax(~reach[k]))
        status[k] = UNREACHABLE
        detail[k] = _unreachable_message(g, e[k, leg], leg)
    state = rigid_state(xb, q)
    if not g.ideal:
        idx = np.flatnonzero(status == OK)
        sub, converged, _, _ = newton(g, xb[idx], PlateState(*(a[idx] for a in state)), free_q=True)
        state = PlateState(*(np.array(a) for a in state))
        for full, part in zip(state, sub, strict=True):
            full[idx] = part
        q = state.q
        converged_all = np.ones(n, dtype=bool)
        converged_all[idx] = converged
        for k in np.flatnonzero(~converged_all & (status == OK)):
            status[k] = UNREACHABLE
            detail[k] = "the closures of the toleranced robot have no solution near the nominal assembly"
    if check:
        ok = status == OK
        lo, hi = q < g.q_lo, q > g.q_hi
        omega = state.omega
        olo, ohi = omega < g.omega_lo, omega > g.omega_hi
        for k in np.flatnonzero(ok & (lo | hi).any(axis=1)):
            i = int(np.argmax((lo | hi)[k]))
            status[k] = LIMITS
            detail[k] = (f"actuator {i + 1} would be at {_rad(q[k, i])} rad, outside its joint limits "
                         f"[{g.q_lo[i]:.3f}, {g.q_hi[i]:.3f}] rad")
        ok = status == OK
        for k in np.flatnonzero(ok & (olo | ohi).any(axis=1)):
            j = int(np.argmax((olo | ohi)[k]))
            status[k] = LIMITS
            detail[k] = (f"lateral bar {j + 1} would turn by {_rad(omega[k, j])} rad on its revolute joint, outside "
                         f"its limits [{g.omega_lo[j]:.3f}, {g.omega_hi[j]:.3f}] rad (theta = {_rad(xb[k, 3])} rad)")
        ok = np.flatnonzero(status == OK)
        if ok.size:
            pts = points(g, PlateState(*(np.asarray(a)[ok] for a in state)))
            bij, aij = pts.Bij.reshape(-1, 8, 3), pts.Aij.reshape(-1, 8, 3)
            dist = segment_distances(aij[:, _PAIRS[:, 0]], bij[:, _PAIRS[:, 0]], aij[:, _PAIRS[:, 1]],
                                     bij[:, _PAIRS[:, 1]])
            for row in np.flatnonzero(dist.min(axis=1) < g.bar_clearance):
                pair = _PAIRS[int(np.argmin(dist[row]))]
                k = ok[row]
                status[k] = INTERFERENCE
                detail[k] = (f"bars {pair[0] // 2 + 1}{pair[0] % 2 + 1} and {pair[1] // 2 + 1}{pair[1] % 2 + 1} "
                             f"interpenetrate (axes {dist[row].min() * 1e3:.1f} mm apart, clearance "
                             f"{g.bar_clearance * 1e3:.1f} mm)")
    if single:
        return Solution(PlateState(*(a[0] for a in state)), status[0], detail[:1])
    return Solution(state, status, detail)


def _rad(angle: float) -> str:
    """An angle (rad) for a message: 3 decimals, or 3 digits once it is huge (theta = 1e300)."""
    return f"{angle:.3f}" if abs(angle) < 1e6 else f"{angle:.3g}"


def _unreachable_message(g: H4Geometry, e: np.ndarray, leg: int) -> str:
    if not np.abs(e).max() < FAR:
        return (f"leg {leg + 1} cannot reach B_{leg + 1}: it is {np.max(np.abs(e)):.3g} m from the actuator "
                f"(the bars are {g.l_leg[leg] * 1e3:.1f} mm long)")
    # |B - A(q)|^2 = |e|^2 + r^2 - 2 (alpha cos q + beta sin q) spans |e|^2 + r^2 -+ 2 rho.
    rho = np.hypot(e @ g.m[leg], e @ g.um[leg])
    e2, r = float(e @ e), float(g.r[leg])
    lo, hi = (np.sqrt(max(e2 + r * r + s * 2 * rho, 0.0)) for s in (-1, 1))
    return (f"leg {leg + 1} cannot reach B_{leg + 1}: over all actuator angles |B_{leg + 1} - A_{leg + 1}| spans "
            f"{lo * 1e3:.1f} to {hi * 1e3:.1f} mm, the bars are {g.l_leg[leg] * 1e3:.1f} mm long")


def assembled_points(g: H4Geometry, pose: np.ndarray) -> Points:
    """The points of one pose assembled without the joint-limit and interference checks (the
    validation routes work on any pose the legs reach); raises if a leg cannot reach."""
    sol = solve(g, as_pose(pose), check=False)
    raise_for_status(sol.status, sol.detail, batch=False)
    return points(g, sol.state)


def inverse_geometry(g: H4Geometry, pose: np.ndarray, *, on_error: str = "raise", check: bool = True) -> np.ndarray:
    """Actuator angles q (rad) of a pose, elbow-out branch; (4,) -> (4,), (N, 4) -> (N, 4).

    Closed form for ideal parallelograms, Newton otherwise (:func:`solve`).

    Args:
        g: The robot's geometry.
        pose: (4,) or (N, 4) poses [x, y, z, theta] (m, rad).
        on_error: ``"raise"`` raises the typed error of the first bad pose (its index for a
            batch); ``"nan"`` returns NaN rows for bad poses instead.
        check: Also refuse poses outside the joint limits or with interpenetrating bars.
    """
    if on_error not in ("raise", "nan"):
        raise PoseError(f"on_error must be 'raise' or 'nan', got {on_error!r}")
    sol = solve(g, pose, check=check)
    if on_error == "raise":
        raise_for_status(sol.status, sol.detail, np.ndim(sol.status) == 1)
    bad = np.asarray(sol.status) != OK
    return np.where(bad[..., None], np.nan, sol.state.q)


def closure_residual(g: H4Geometry, state: PlateState) -> np.ndarray:
    """``(|B_ij - A_ij|^2 - l_ij^2) / 2`` per bar, shape (..., 8), in m^2 (zero when closed)."""
    pts = points(g, state)
    w = pts.Bij - pts.Aij
    return 0.5 * (np.sum(w * w, axis=-1).reshape(*w.shape[:-3], 8) - g.l**2)


def jx_jq(g: H4Geometry, pose: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's Jx (..., 4, 4) and Jq (..., 4, 4) of eq. 8: ``Jx x_dot = Jq q_dot``.

    Derivative of each leg's closure ``(|B_i - A_i|^2 - l_i^2)/2 = 0`` at a rigid pose, with
    ``w_i = B_i - A_i``: row i of Jx is ``[w_i^T, w_i . (z x (C_k - D))]`` and
    ``Jq = diag(w_i . (u_i x (A_i - P_i)))``. Exact for ideal parallelograms (``g.ideal``).
    """
    pts = points(g, rigid_state(pose, q))
    w = pts.B - pts.A
    lever = cross(_Z, (pts.C - pts.D[..., None, :])[..., g.leg_lat, :])
    jx = np.concatenate([w, np.sum(w * lever, axis=-1)[..., None]], axis=-1)
    jq_diag = np.sum(w * cross(g.u, pts.A - g.P), axis=-1)
    return jx, jq_diag[..., :, None] * np.eye(4)


def forward_geometry(g: H4Geometry, q: np.ndarray, guess: np.ndarray | None = None, *, tol: float = 1e-13,
                     max_iter: int = 50) -> np.ndarray:
    """Pose [x, y, z, theta] of actuator angles q (4,), by Newton on the eight bar closures.

    Args:
        g: The robot's geometry.
        q: (4,) actuator angles, rad.
        guess: Starting pose. Default: theta = 0, D under the mean of the A_i (shifted by the mean
            plate offset) at the depth that gives the bars their length on average.

    Raises:
        ConvergenceError: Newton did not converge (the legs cannot assemble, or a bad guess),
            or converged to an assembly that is not on the elbow-out branch of q.
    """
    qv = np.asarray(q, dtype=float)
    if qv.shape != (4,) or not np.all(np.isfinite(qv)):
        raise PoseError(f"q must be 4 finite actuator angles (rad), got {q!r}")
    return forward_state(g, qv, guess, tol=tol, max_iter=max_iter)[0]


#: Relative singular value of the forward geometry's Newton Jacobian under which a direction is
#: dropped from the step (:func:`newton`'s ``rcond``): far below any pose the verdicts accept
#: (condition 1e9), so only exactly singular assemblies are affected.
_FORWARD_RCOND = 1e-13


def forward_state(g: H4Geometry, q: np.ndarray, guess: np.ndarray | None = None, *, tol: float = 1e-13,
                  max_iter: int = 50) -> tuple[np.ndarray, PlateState]:
    """Pose and full :class:`PlateState` of actuator angles q (4,) (see :func:`forward_geometry`)."""
    A = forearm_points(g, q).reshape(4, 2, 3).mean(axis=1)
    if guess is None:
        offset = (g.C0[g.leg_lat] + g.b_leg).mean(axis=0)
        centre = A.mean(axis=0) - offset
        spread = np.mean(np.sum((A - A.mean(0)) ** 2, -1))
        depth = np.sqrt(max(float(np.mean(g.l_leg)) ** 2 - spread, 0.25 * float(np.mean(g.l_leg)) ** 2))
        x = np.array([centre[0], centre[1], centre[2] - depth, 0.0])
    else:
        x = as_pose(guess, "guess").copy()
    start = rigid_state(x, q)
    # Least-norm steps (rcond): regular assemblies are solved as by a plain solve; at an exactly
    # singular one (the symmetric variant's centre) the pose stays where the guess put it along
    # the motion the closures do not fix, instead of drifting by 1e-9 m with the CPU's round-off.
    state, converged, theta, _ = newton(g, x, start, free_q=False, tol=tol, max_iter=max_iter, rcond=_FORWARD_RCOND)
    if not converged:
        raise ConvergenceError(f"forward geometry did not converge for q = {q} rad: the legs may not assemble")
    # Polish to round-off: at a singular assembly the pose is only as good as the square root of
    # the residual, and a verdict there must not depend on where Newton happened to stop.
    polished, fine, theta_p, _ = newton(g, np.r_[state.D, theta], state, free_q=False, tol=1e-16, max_iter=8,
                                        rcond=_FORWARD_RCOND)
    if fine:
        state, theta = polished, theta_p
    pose = np.r_[state.D, theta]
    q_back = inverse_geometry(g, pose, on_error="nan", check=False)
    if not np.allclose(q_back, q, atol=1e-8):
        raise ConvergenceError(f"forward geometry for q = {q} converged to pose {pose}, which is not on the "
                               "elbow-out branch")
    return pose, state


#: The paper's measurement pose: all actuators at 45 deg (Table II).
CENTRE_Q = np.full(4, np.pi / 4)


def centre_pose(robot) -> np.ndarray:
    """The pose (4,) with all actuators at 45 deg (the paper's measurement pose) of a robot
    (:class:`h4pin.H4`) or its :class:`H4Geometry`, by :func:`forward_geometry`."""
    return forward_geometry(getattr(robot, "geometry", robot), CENTRE_Q)
