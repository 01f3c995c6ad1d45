# SPDX-License-Identifier: Apache-2.0
"""Closed-form geometry of the H4 at rigid poses: points, inverse/forward geometry, eq. 8.

Pure numpy, vectorised over any leading batch shape. This is the fast path used for batches
and the independent reference against which the Pinocchio route (:class:`h4pin.H4`) is tested.

A pose is ``x = [x, y, z, theta]`` (m, rad): the position of D and the rotation of the central
bar about z. At a rigid pose the lateral bars only translate, so
``B_i = D + Rz(theta) DC_k + (DB_i - DC_k)`` with k the lateral bar of leg i.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from h4pin.errors import ConvergenceError, PoseError, SingularPoseError, UnreachablePoseError
from h4pin.params import LEG_LATERAL, H4Params

_Z = np.array([0.0, 0.0, 1.0])
_SIGNS = np.array([1.0, -1.0])  # j = 1 is +h u_i, j = 2 is -h u_i


class Points(NamedTuple):
    """Characteristic points of a rigid pose, in m, world frame; ``...`` is the batch shape."""

    D: np.ndarray  #: (..., 3)
    C: np.ndarray  #: (..., 2, 3) revolute joint centres C_k
    B: np.ndarray  #: (..., 4, 3) B_i
    Bij: np.ndarray  #: (..., 4, 2, 3) plate-side ball joints
    P: np.ndarray  #: (4, 3) actuator axis points
    A: np.ndarray  #: (..., 4, 3) forearm ends A_i
    Aij: np.ndarray  #: (..., 4, 2, 3) forearm-side ball joints


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` over the last axis (3), broadcast; several times faster than ``np.cross`` on
    the small arrays of this package."""
    a, b = np.asarray(a), np.asarray(b)
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def as_poses(pose: np.ndarray | list | tuple) -> np.ndarray:
    """Check and convert a pose (4,) or a batch (N, 4) to float64; clear error otherwise."""
    try:
        x = np.asarray(pose, dtype=float)
    except (TypeError, ValueError):
        raise PoseError(f"a pose must be numbers [x, y, z, theta], got {pose!r}") from None
    if x.ndim not in (1, 2) or x.shape[-1] != 4:
        raise PoseError(f"a pose must have shape (4,) or (N, 4) as [x, y, z, theta], got shape {x.shape}")
    bad = ~np.all(np.isfinite(x), axis=-1)
    if np.any(bad):
        index = int(np.argmax(bad)) if x.ndim == 2 else None
        raise PoseError(f"pose has non-finite entries: {x[index] if index is not None else x}", index)
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


def plate_points(params: H4Params, pose: np.ndarray) -> tuple[np.ndarray, ...]:
    """D, C_k, B_i, B_ij of a rigid pose: shapes (..., 3), (..., 2, 3), (..., 4, 3), (..., 4, 2, 3)."""
    D = pose[..., :3]
    rot = rot_z(pose[..., 3])
    C = D[..., None, :] + np.swapaxes(rot @ params.DC, -1, -2)
    B = C[..., LEG_LATERAL, :] + (params.DB - params.DC[:, LEG_LATERAL]).T
    Bij = B[..., :, None, :] + _SIGNS[:, None] * params.half_width * params.U.T[:, None, :]
    return D, C, B, Bij


def forearm_points(params: H4Params, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A_i (..., 4, 3) and A_ij (..., 4, 2, 3) for actuator angles q (..., 4), in m."""
    a = params.forearm_dirs.T  # (4, 3)
    A = params.P.T + params.r * (np.cos(q)[..., None] * a - np.sin(q)[..., None] * _Z)
    Aij = A[..., :, None, :] + _SIGNS[:, None] * params.half_width * params.U.T[:, None, :]
    return A, Aij


def points(params: H4Params, pose: np.ndarray, q: np.ndarray) -> Points:
    """All characteristic points of the rigid pose ``pose`` with actuator angles ``q``."""
    D, C, B, Bij = plate_points(params, pose)
    A, Aij = forearm_points(params, q)
    return Points(D, C, B, Bij, params.P.T.copy(), A, Aij)


def inverse_geometry(params: H4Params, pose: np.ndarray, *, on_error: str = "raise") -> np.ndarray:
    """Actuator angles q (rad) of a pose, elbow-out branch, closed form.

    Leg i closes when ``|B_i - A_i(q_i)| = l``. With ``e = B_i - P_i`` this is
    ``(e.a_i) cos q - (e.z) sin q = (|e|^2 + r^2 - l^2) / (2 r)``, solved for the branch with
    ``u_i . ((A_i - P_i) x (B_i - A_i)) > 0`` (elbow out).

    Args:
        params: Robot parameters.
        pose: (4,) or (N, 4) poses [x, y, z, theta] (m, rad).
        on_error: ``"raise"`` raises :class:`UnreachablePoseError` naming the leg (and the first
            bad index of a batch); ``"nan"`` returns NaN rows for unreachable poses instead.

    Returns:
        q of shape (4,) or (N, 4), in rad.
    """
    x = as_poses(pose)
    _, _, B, _ = plate_points(params, x)
    e = B - params.P.T
    a = params.forearm_dirs.T
    ea = np.einsum("...ia,ia->...i", e, a)
    ez = e[..., 2]
    c = (np.einsum("...ia,...ia->...i", e, e) + params.r**2 - params.l**2) / (2.0 * params.r)
    rho = np.hypot(ea, ez)
    ratio = np.divide(c, rho, out=np.full_like(c, np.inf), where=rho > 0)
    bad = np.abs(ratio) > 1.0
    if np.any(bad) and on_error == "raise":
        flat = bad.reshape(-1, 4)
        n, leg = np.argwhere(flat)[0]
        # |B - A(q)|^2 = |e|^2 + r^2 - 2 r (e.a cos q - e.z sin q) spans |e|^2 + r^2 -+ 2 r rho.
        e2 = float(np.sum(e.reshape(-1, 4, 3)[n, leg] ** 2))
        rh = float(rho.reshape(-1, 4)[n, leg])
        lo, hi = (np.sqrt(max(e2 + params.r**2 + s * 2 * params.r * rh, 0.0)) for s in (-1, 1))
        raise UnreachablePoseError(
            f"leg {leg + 1} cannot reach B_{leg + 1}: over all actuator angles |B_{leg + 1} - A_{leg + 1}| "
            f"spans {lo * 1e3:.1f} to {hi * 1e3:.1f} mm, the bars are {params.l * 1e3:.1f} mm long",
            int(n) if x.ndim == 2 else None,
        )
    # A cos q + Bc sin q = c with A = e.a, Bc = -e.z: q = phi +- delta, phi = atan2(Bc, A).
    # Elbow out: u.((A - P) x (B - A)) = u.((A - P) x e) = -r (e.z cos q + e.a sin q)
    # = -r rho sin(q - phi), positive for q = phi - delta (delta = acos(c / rho) in [0, pi]).
    phi = np.arctan2(-ez, ea)
    q = phi - np.arccos(np.clip(ratio, -1.0, 1.0))
    q = (q + np.pi) % (2 * np.pi) - np.pi
    if on_error == "nan":
        q = np.where(bad.any(axis=-1, keepdims=True), np.nan, q)
    elif on_error != "raise":
        raise ValueError(f"on_error must be 'raise' or 'nan', got {on_error!r}")
    return q


def closure_residual(params: H4Params, pose: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``(|B_i - A_i|^2 - l^2) / 2`` per leg, shape (..., 4), in m^2 (zero when closed)."""
    _, _, B, _ = plate_points(params, pose)
    A, _ = forearm_points(params, q)
    w = B - A
    return 0.5 * (np.einsum("...ia,...ia->...i", w, w) - params.l**2)


def jx_jq(params: H4Params, pose: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's Jx (..., 4, 4) and Jq (..., 4, 4) of eq. 8: ``Jx x_dot = Jq q_dot``.

    Derivative of the closure ``(|B_i - A_i|^2 - l^2)/2 = 0`` with ``w_i = B_i - A_i``:
    row i of Jx is ``[w_i^T, w_i . (z x Rz(theta) DC_k)]`` and
    ``Jq = diag(w_i . (u_i x (A_i - P_i)))``. Units: Jx m (first 3 columns), m^2 (last); Jq m^2.
    """
    D, C, B, _ = plate_points(params, pose)
    A, _ = forearm_points(params, q)
    w = B - A
    lever = cross(_Z, (C - D[..., None, :])[..., LEG_LATERAL, :])
    jx = np.concatenate([w, np.einsum("...ia,...ia->...i", w, lever)[..., None]], axis=-1)
    dA = cross(params.U.T, A - params.P.T)
    jq_diag = np.einsum("...ia,...ia->...i", w, dA)
    jq = jq_diag[..., :, None] * np.eye(4)
    return jx, jq


def jacobian(params: H4Params, pose: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``J = Jx^-1 Jq`` (eq. 8), x_dot = J q_dot, shape (..., 4, 4); units m/rad and rad/rad."""
    jx, jq = jx_jq(params, pose, q)
    return np.linalg.solve(jx, jq)


def forward_geometry(
    params: H4Params,
    q: np.ndarray,
    guess: np.ndarray | None = None,
    *,
    tol: float = 1e-13,
    max_iter: int = 50,
) -> np.ndarray:
    """Pose [x, y, z, theta] of actuator angles q (4,), by Newton on the four leg closures.

    Args:
        params: Robot parameters.
        q: (4,) actuator angles, rad.
        guess: Starting pose. Default: theta = 0, D under the mean of the A_i (shifted by the mean
            of DB) at the depth that gives the bars their length on average.
        tol: Convergence threshold on the closure residual, m^2.
        max_iter: Iteration cap.

    Raises:
        ConvergenceError: Newton did not converge (the legs cannot assemble, or a bad guess).
        SingularPoseError: Jx became singular on the way.
    """
    qv = np.asarray(q, dtype=float)
    if qv.shape != (4,) or not np.all(np.isfinite(qv)):
        raise PoseError(f"q must be 4 finite actuator angles (rad), got {q!r}")
    if guess is None:
        A, _ = forearm_points(params, qv)
        centre = A.mean(axis=0) - params.DB.mean(axis=1)
        depth = np.sqrt(max(params.l**2 - np.mean(np.sum((A - A.mean(0)) ** 2, -1)), 0.25 * params.l**2))
        x = np.array([centre[0], centre[1], centre[2] - depth, 0.0])
    else:
        x = as_poses(guess).copy()
        if x.ndim != 1:
            raise PoseError(f"guess must be a single pose (4,), got shape {x.shape}")
    res = closure_residual(params, x, qv)
    for _ in range(max_iter):
        jx, _ = jx_jq(params, x, qv)
        if np.linalg.cond(jx) > 1e12:
            raise SingularPoseError(
                f"forward geometry met a singular Jx (cond = {np.linalg.cond(jx):.2e}) at pose {x} for q = {qv}"
            )
        x = x - np.linalg.solve(jx, res)
        res = closure_residual(params, x, qv)
        if np.max(np.abs(res)) < tol:
            # The closure is quadratic in |B - A|: make sure the assembly is the elbow-out one of q.
            if np.allclose(inverse_geometry(params, x, on_error="nan"), qv, atol=1e-8):
                return x
            raise ConvergenceError(
                f"forward geometry for q = {qv} converged to pose {x}, which is not on the elbow-out branch"
            )
    raise ConvergenceError(
        f"forward geometry did not converge for q = {qv} rad in {max_iter} iterations "
        f"(closure residual {np.max(np.abs(res)):.2e} m^2): the legs may not assemble"
    )
