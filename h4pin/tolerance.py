# SPDX-License-Identifier: Apache-2.0
"""Tolerance study: Monte Carlo over manufacturing errors of an H4 (issue 9).

Each of N robots is the nominal :class:`h4pin.model.H4Geometry` with its arrays perturbed
(Gaussian, one sigma per kind of error, SI):

* ``forearm``: forearm length per leg: both forearm-side ball joints A0_ij of leg i moved by
  the same draw along the unit forearm direction m_i;
* ``A0``, ``b``, ``P``, ``C0``: joint positions, 3-D offsets per forearm-side ball joint (8),
  per plate-side ball joint (8, offsets b_ij), per actuator axis point (4), per lateral
  revolute C_k (2);
* ``l``: bar length, per bar (8);
* ``mismatch``: bar-length mismatch inside a parallelogram, +delta/2 and -delta/2 on the two
  bars of leg i (4 draws).

For every robot and pose the study gives

* the compliance of eq. 30 (translational 3x3 block, m/N) of the perturbed robot at the pose
  (its inverse geometry, by Newton since a toleranced parallelogram tilts the plate);
* the static pose error: the controller commands the nominal inverse geometry q of the pose,
  the perturbed robot sits at its forward geometry for that q (Newton, q fixed). The error is
  [dx, dy, dz, dtheta] (m, rad; theta of R = exp(tilt) Rz(theta), as
  :func:`h4pin.geometry.forward_geometry`) and the plate tilt (rad, norm of the x, y rotation
  vector).

Everything is vectorised over robots and poses at once: the geometry arrays get a leading robot
axis and broadcast against a pose axis (:class:`BatchGeometry`). The functions here are batched
copies of :mod:`h4pin.geometry` and :mod:`h4pin.matrices` / :func:`h4pin.stiffness.eq30_terms`
(whose closed forms assume one robot); ``tests/test_tolerance.py`` checks single robots against
:func:`h4pin.stiffness.compliance` and :func:`h4pin.geometry.forward_geometry`.
"""

from __future__ import annotations

import dataclasses
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from h4pin import geometry
from h4pin.errors import ParameterError
from h4pin.files import save_figure
from h4pin.geometry import cross, exp_so3, rot_z, rotate
from h4pin.matrices import R_PAPER
from h4pin.model import H4Geometry
from h4pin.params import TOLERANCES

#: Kinds of manufacturing error, in the order they are drawn.
KINDS = ("forearm", "A0", "b", "P", "C0", "l", "mismatch")
#: Default sigmas (m), from :data:`h4pin.params.TOLERANCES`: forearm length as ``r``, ball
#: joints on the forearm as ``half_width`` (their position along the forearm's end), plate
#: points as ``DB``, actuator axes as ``P``, lateral revolutes as ``DC``, bar lengths and their
#: mismatch in a parallelogram as ``l``.
DEFAULT_SIGMAS = {"forearm": TOLERANCES["r"], "A0": TOLERANCES["half_width"], "b": TOLERANCES["DB"],
                  "P": TOLERANCES["P"], "C0": TOLERANCES["DC"], "l": TOLERANCES["l"],
                  "mismatch": TOLERANCES["l"]}
#: Outputs of the study: name, unit factor for display, unit.
OUTPUTS = (("xx", 1e6, "um/N"), ("yy", 1e6, "um/N"), ("zz", 1e6, "um/N"), ("xz", 1e6, "um/N"),
           ("lambda_max", 1e6, "um/N"), ("dx", 1e6, "um"), ("dy", 1e6, "um"), ("dz", 1e6, "um"),
           ("dtheta", 1e6, "urad"), ("tilt", 1e6, "urad"))
_Z = np.array([0.0, 0.0, 1.0])
_CHUNK = 4096  # robot x pose pairs per vectorised block


def check_sigmas(sigmas: dict[str, float] | None) -> dict[str, float]:
    """All sigmas (m) with the defaults filled in; unknown names, negative or non-finite values
    are a :class:`ParameterError` naming the sigma."""
    out = dict(DEFAULT_SIGMAS)
    for name, value in (sigmas or {}).items():
        if name not in KINDS:
            raise ParameterError(f"sigmas: unknown tolerance {name!r}; known: {', '.join(KINDS)}")
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ParameterError(f"sigma {name!r} must be a number in m, got {value!r}") from None
        if not np.isfinite(v) or v < 0:
            raise ParameterError(f"sigma {name!r} must be finite and >= 0 (m), got {value!r}")
        out[name] = v
    return out


class BatchGeometry(NamedTuple):
    """The arrays of N robots with a leading robot axis (``...``), others as the nominal robot.

    P (..., 4, 3), A0 (..., 8, 3), l (..., 8), C0 (..., 2, 3), b (..., 8, 3); u (4, 3), v (2, 3),
    lat (8,), leg_lat (4,) are shared; springs is the nominal spring data.
    """

    P: np.ndarray
    A0: np.ndarray
    l: np.ndarray
    C0: np.ndarray
    b: np.ndarray
    u: np.ndarray
    v: np.ndarray
    lat: np.ndarray
    leg_lat: np.ndarray
    springs: dict[str, np.ndarray]

    def take(self, idx: Any, pose_axis: bool = True) -> BatchGeometry:
        """Robots ``idx``, with a pose axis of size 1 after the robot axis if ``pose_axis``."""
        def sel(a: np.ndarray) -> np.ndarray:
            a = a[idx]
            return a[:, None] if pose_axis else a
        return self._replace(P=sel(self.P), A0=sel(self.A0), l=sel(self.l), C0=sel(self.C0), b=sel(self.b))


def sample(g: H4Geometry, n: int, sigmas: dict[str, float] | None = None, seed: int = 0) -> BatchGeometry:
    """N robots: ``g`` with Gaussian manufacturing errors of the given sigmas (m), seeded.

    The standard normal draws do not depend on the sigmas (all kinds are always drawn, in the
    order of :data:`KINDS`), so one seed gives the same robots' errors, scaled, whatever the
    sigmas: the one-at-a-time sensitivity compares like with like.
    """
    s = check_sigmas(sigmas)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"n_robots must be an integer >= 1, got {n!r}")
    rng = np.random.default_rng(seed)
    z = {"forearm": rng.standard_normal((n, 4)), "A0": rng.standard_normal((n, 8, 3)),
         "b": rng.standard_normal((n, 8, 3)), "P": rng.standard_normal((n, 4, 3)),
         "C0": rng.standard_normal((n, 2, 3)), "l": rng.standard_normal((n, 8)),
         "mismatch": rng.standard_normal((n, 4))}
    mhat = g.m / np.linalg.norm(g.m, axis=1, keepdims=True)
    dr = s["forearm"] * z["forearm"]  # (n, 4)
    A0 = g.A0 + np.repeat(dr[..., None] * mhat, 2, axis=1) + s["A0"] * z["A0"]
    half = 0.5 * s["mismatch"] * z["mismatch"]
    l = g.l + s["l"] * z["l"] + np.stack([half, -half], axis=-1).reshape(n, 8)
    return BatchGeometry(P=g.P + s["P"] * z["P"], A0=A0, l=l, C0=g.C0 + s["C0"] * z["C0"], b=g.b + s["b"] * z["b"],
                         u=g.u, v=g.v, lat=g.lat, leg_lat=g.leg_lat, springs=dict(g.springs))


def robot_geometry(g: H4Geometry, batch: BatchGeometry, k: int) -> H4Geometry:
    """Robot ``k`` of a batch drawn from ``g`` as an :class:`H4Geometry`."""
    return g.replace(P=batch.P[k], A0=batch.A0[k], l=batch.l[k], C0=batch.C0[k], b=batch.b[k])


# --- batched geometry (copies of h4pin.geometry with a robot axis on every constant) ---------

def _forearm_points(bg: BatchGeometry, q: np.ndarray) -> np.ndarray:
    pb = np.repeat(bg.P, 2, axis=-2)
    return pb + rotate(bg.A0 - pb, np.repeat(bg.u, 2, axis=0), np.repeat(q, 2, axis=-1))


class _Pts(NamedTuple):
    D: np.ndarray
    C: np.ndarray
    Bij: np.ndarray  # (..., 8, 3)
    Aij: np.ndarray  # (..., 8, 3)
    v: np.ndarray


def _rot(R: np.ndarray, x: np.ndarray) -> np.ndarray:
    """R (..., 3, 3) applied to points x (..., k, 3), elementwise (faster than tiny matmuls)."""
    return (R[..., None, :, 0] * x[..., 0:1] + R[..., None, :, 1] * x[..., 1:2]
            + R[..., None, :, 2] * x[..., 2:3])


def _points(bg: BatchGeometry, q: np.ndarray, D: np.ndarray, R: np.ndarray, omega: np.ndarray,
            aij: np.ndarray | None = None) -> _Pts:
    C = D[..., None, :] + _rot(R, bg.C0)
    if np.array_equal(bg.v, np.tile(_Z, (2, 1))):  # vertical lateral axes: turn b about z
        c, s = np.cos(omega)[..., bg.lat], np.sin(omega)[..., bg.lat]
        bx, by = bg.b[..., 0], bg.b[..., 1]
        bl = np.stack([c * bx - s * by, s * bx + c * by, np.broadcast_to(bg.b[..., 2], c.shape)], axis=-1)
        B = C[..., bg.lat, :] + _rot(R, bl)
    else:
        lat_rot = R[..., None, :, :] @ exp_so3(bg.v * omega[..., :, None])  # (..., 2, 3, 3)
        B = C[..., bg.lat, :] + (lat_rot[..., bg.lat, :, :] @ bg.b[..., None])[..., 0]
    return _Pts(D, C, B, _forearm_points(bg, q) if aij is None else aij, bg.v @ np.swapaxes(R, -1, -2))


def _bar_jacobians(bg: BatchGeometry, pts: _Pts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """As :func:`h4pin.geometry._bar_jacobians`: w (..., 8, 3), M1 (..., 8, 8), d/dq (..., 8, 4)."""
    bij, aij = pts.Bij, pts.Aij
    shape = bij.shape[:-2]
    w = bij - aij
    m1 = np.zeros((*shape, 8, 8))
    m1[..., :3] = w
    m1[..., 3:6] = cross(bij - pts.D[..., None, :], w)
    lever = cross(pts.v[..., bg.lat, :], bij - pts.C[..., bg.lat, :])
    m1[..., np.arange(8), 6 + bg.lat] = np.sum(w * lever, axis=-1)
    dq = np.zeros((*shape, 8, 4))
    arm = cross(np.repeat(bg.u, 2, axis=0), aij - np.repeat(bg.P, 2, axis=-2))
    dq[..., np.arange(8), np.arange(8) // 2] = -np.sum(w * arm, axis=-1)
    return w, m1, dq


class _State(NamedTuple):
    q: np.ndarray
    D: np.ndarray
    R: np.ndarray
    omega: np.ndarray
    theta: np.ndarray
    tilt: np.ndarray


def _newton(bg: BatchGeometry, q: np.ndarray, D: np.ndarray, theta: np.ndarray, free_q: bool,
            jac0_inv: np.ndarray | None = None, tol: float = 1e-13,
            max_iter: int = 30) -> tuple[_State, _Pts, np.ndarray]:
    """As :func:`h4pin.geometry._newton`, started from the rigid state (q, D, theta) (..., pairs).

    With ``jac0_inv`` (the inverse Jacobian of the nominal robot at each pair's pose), the chord
    method: that fixed Jacobian for every step (the errors are small, so it converges almost as
    fast, at the cost of residuals only); pairs it leaves unconverged finish with full Newton.
    """
    shape = theta.shape
    q = np.broadcast_to(q, (*shape, 4)).copy()
    D = np.broadcast_to(D, (*shape, 3)).copy()
    theta = np.broadcast_to(theta, shape).copy()
    tilt = np.zeros((*shape, 3))
    psi = np.zeros((*shape, 2))  # omega + theta
    scale = tol * float(np.max(bg.l))
    lat0 = (bg.lat == 0)[:, None]
    lat1 = (bg.lat == 1)[:, None]
    chord = jac0_inv is not None
    aij = None if free_q else _forearm_points(bg, q)
    for it in range(max_iter + 1):
        R = exp_so3(tilt) @ rot_z(theta)
        pts = _points(bg, q, D, R, psi - theta[..., None], aij)
        if chord:
            w = pts.Bij - pts.Aij
        else:
            w, m1, dq = _bar_jacobians(bg, pts)
        res = 0.5 * (np.sum(w * w, axis=-1) - bg.l**2)
        done = np.max(np.abs(res), axis=-1) < scale
        if np.all(done) or it == max_iter:
            break
        if chord:
            step = -(jac0_inv @ res[..., None])[..., 0]
        else:
            if free_q:
                jac = np.concatenate([dq, m1[..., 3:5], m1[..., 6:8]], axis=-1)
            else:
                dtheta = m1[..., 5:6] - m1[..., 6:7] * lat0 - m1[..., 7:8] * lat1
                jac = np.concatenate([m1[..., :3], dtheta, m1[..., 3:5], m1[..., 6:8]], axis=-1)
            with np.errstate(all="ignore"):
                try:
                    step = np.linalg.solve(jac, -res[..., None])[..., 0]
                except np.linalg.LinAlgError:
                    step = np.full(res.shape, np.nan)
        step = np.where(done[..., None], 0.0, step)
        if free_q:
            q += step[..., :4]
        else:
            D += step[..., :3]
            theta += step[..., 3]
        tilt[..., :2] += step[..., 4:6]
        psi += step[..., 6:8]
        if not np.all(np.isfinite(step)):
            break
    return _State(q, D, R, psi - theta[..., None], theta, tilt), pts, done


def _jacobian(bg: BatchGeometry, pts: _Pts, free_q: bool) -> np.ndarray:
    """The Newton Jacobian of :func:`_newton` (..., 8, 8) at points ``pts``."""
    _, m1, dq = _bar_jacobians(bg, pts)
    if free_q:
        return np.concatenate([dq, m1[..., 3:5], m1[..., 6:8]], axis=-1)
    lat0, lat1 = (bg.lat == 0)[:, None], (bg.lat == 1)[:, None]
    dtheta = m1[..., 5:6] - m1[..., 6:7] * lat0 - m1[..., 7:8] * lat1
    return np.concatenate([m1[..., :3], dtheta, m1[..., 3:5], m1[..., 6:8]], axis=-1)


def _solve_pairs(bg: BatchGeometry, q: np.ndarray, x: np.ndarray, free_q: bool,
                 jac0_inv: np.ndarray) -> tuple[_State, _Pts, np.ndarray]:
    """Chord method on flat pairs, then full Newton on the pairs it left unconverged."""
    st, pts, done = _newton(bg, q, x[:, :3], x[:, 3], free_q, jac0_inv, max_iter=8)
    bad = np.flatnonzero(~done)
    if bad.size:
        sub = bg._replace(P=bg.P[bad], A0=bg.A0[bad], l=bg.l[bad], C0=bg.C0[bad], b=bg.b[bad])
        st2, pts2, done2 = _newton(sub, q[bad], x[bad, :3], x[bad, 3], free_q)
        for a, a2 in zip((*st, *pts), (*st2, *pts2), strict=True):
            a[bad] = a2
        done[bad] = done2
    return st, pts, done


def _compliance_tt(bg: BatchGeometry, pts: _Pts, model: str) -> np.ndarray:
    """Eq. 30 (as :func:`h4pin.stiffness.eq30_terms`, summed), full K (..., 8, 8), from the
    closed forms of :mod:`h4pin.matrices` with the sparsity of M2, M3, M4, M5 used:
    M2 M3 = -d/dq of the closures, M2 M4 is 2x2 block-diagonal per leg, M2 M5 = diag(l)."""
    w, m1, dq = _bar_jacobians(bg, pts)
    shape = w.shape[:-2]
    l = np.linalg.norm(w, axis=-1)
    inv = np.linalg.inv(m1)
    g3 = inv @ -dq  # M1^-1 M2 M3, (..., 8, 4)
    # Spring compliances of each robot (h4pin.model.H4Geometry.compliances), r from its joints.
    s = bg.springs
    r = np.linalg.norm(bg.A0.reshape(*bg.A0.shape[:-2], 4, 2, 3).mean(axis=-2) - bg.P, axis=-1)
    phi = s["forearm_stressed_fraction"]
    c_q = 1.0 / s["kc"] + phi**3 * r / (3.0 * s["E"] * s["I"])  # control + bending
    c_t = phi * r / (s["G"] * s["I0"])
    c_l = bg.l / (s["Sb"] * s["Eb"])
    if model == "paper":
        load = np.swapaxes(g3[..., [0, 1, 2, 5], :], -1, -2) @ R_PAPER
    else:
        load = np.swapaxes(g3, -1, -2)
    # M2 M4 (matrices.n_matrix): entry (2i+j, 2i+j') = (w_ij . (p_ij x r_i)) c_ij', with
    # p_ij = P_i - A_ij, r_i unit A_i -> P_i, c_ij = (p_ij x r_i) . unit(B_ij - A_ij).
    aij = pts.Aij.reshape(*shape, 4, 2, 3)
    ai = aij.mean(axis=-2)
    p = bg.P[..., None, :] - aij
    ri = bg.P - ai
    ri = ri / np.linalg.norm(ri, axis=-1, keepdims=True)
    wl = w.reshape(*shape, 4, 2, 3)
    wl = wl / np.linalg.norm(wl, axis=-1, keepdims=True)
    pr = cross(p, ri[..., None, :])
    c = np.sum(pr * wl, axis=-1)  # (..., 4, 2)
    a = np.sum(w.reshape(*shape, 4, 2, 3) * pr, axis=-1)  # (..., 4, 2)
    blocks = a[..., :, None] * c[..., None, :] * c_t[..., :, None, None]  # (..., 4, 2, 2)
    hc = np.zeros((*shape, 8, 8))
    for i in range(4):
        hc[..., 2 * i:2 * i + 2, 2 * i:2 * i + 2] = blocks[..., i, :, :]
    n = np.arange(8)
    hc[..., n, n] += l * c_l
    jb_inv = l[..., :, None] * np.swapaxes(inv, -1, -2)
    return (g3 * c_q[..., None, :]) @ load + inv @ (hc @ jb_inv)


# --- the study --------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class ToleranceResult:
    """Outcome of :func:`study`, SI. R robots, M poses.

    Attributes:
        poses: (M, 4) poses [x, y, z, theta] (m, rad).
        q: (M, 4) the nominal inverse geometry (rad), commanded to every robot.
        sigmas: the sigmas used (m).
        compliance: (R, M, 3, 3) translational block of K (m/N) of each robot at each pose.
        nominal: (M, 3, 3) the nominal robot's block (m/N).
        pose_error: (R, M, 4) [dx, dy, dz, dtheta] (m, rad) at the commanded q.
        tilt: (R, M) plate tilt (rad) at the commanded q.
        converged: (R, M) both Newton solves converged (other rows are NaN).
    """

    poses: np.ndarray
    q: np.ndarray
    sigmas: dict[str, float]
    compliance: np.ndarray
    nominal: np.ndarray
    pose_error: np.ndarray
    tilt: np.ndarray
    converged: np.ndarray

    def outputs(self) -> dict[str, np.ndarray]:
        """The scalar outputs (R, M) by name (:data:`OUTPUTS`), SI."""
        k = self.compliance
        sym = 0.5 * (k + np.swapaxes(k, -1, -2))
        lam = np.full(k.shape[:-2], np.nan)
        ok = np.all(np.isfinite(sym), axis=(-1, -2))
        lam[ok] = np.linalg.eigvalsh(sym[ok])[..., -1]
        e = self.pose_error
        return {"xx": k[..., 0, 0], "yy": k[..., 1, 1], "zz": k[..., 2, 2], "xz": k[..., 0, 2], "lambda_max": lam,
                "dx": e[..., 0], "dy": e[..., 1], "dz": e[..., 2], "dtheta": e[..., 3], "tilt": self.tilt}

    def percentiles(self, pcts: tuple[float, ...] = (5, 50, 95)) -> dict[str, np.ndarray]:
        """Percentiles over robots and poses of every output, SI: name -> (len(pcts),)."""
        return {name: np.nanpercentile(v, pcts) for name, v in self.outputs().items()}


def default_poses(h4) -> np.ndarray:
    """The centre pose (all actuators at 45 deg) and six around it: +-30 mm in x, y, z, and
    two turned by +-0.2 rad (8 poses)."""
    from h4pin.table2 import centre_pose

    c = centre_pose(h4)
    steps = np.array([[0.03, 0, 0, 0], [-0.03, 0, 0, 0], [0, 0.03, 0, 0], [0, -0.03, 0, 0], [0, 0, 0.03, 0],
                      [0, 0, -0.03, 0], [0, 0, 0, 0.2]])
    return np.vstack([c, c + steps])


def study(h4, poses: np.ndarray | None = None, n_robots: int = 1000, sigmas: dict[str, float] | None = None,
          seed: int = 0, model: str = "paper", progress: bool = False, workers: int | None = None) -> ToleranceResult:
    """Monte Carlo over manufacturing errors of ``h4`` (see the module docstring).

    Args:
        h4: The nominal robot (:func:`h4pin.load`); must be an ideal one (true parallelograms).
        poses: (M, 4) or (4,) poses [x, y, z, theta] (m, rad); default :func:`default_poses`.
        n_robots: Robots drawn.
        sigmas: Sigma per kind of error (m), :data:`KINDS`; missing ones take
            :data:`DEFAULT_SIGMAS`.
        seed: Seed of the draws.
        model: ``"paper"`` or ``"consistent"`` (:mod:`h4pin.stiffness`).
        progress: Show a tqdm progress bar.
        workers: Threads over chunks of robot-pose pairs (default: one per core); the result does
            not depend on it.

    Raises:
        ParameterError: a bad sigma, n_robots or model.
        PoseError (and subclasses): a pose the nominal robot cannot take.
    """
    from h4pin.stiffness import MODELS, compliance

    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}, got {model!r}")
    g: H4Geometry = h4.geometry
    x = default_poses(h4) if poses is None else geometry.as_poses(poses, "poses")
    x = np.atleast_2d(x)
    nom = compliance(h4, x, model)  # raises the typed error of a bad pose
    if not g.ideal:
        raise ParameterError("the nominal robot must have true parallelograms (an ideal H4)")
    batch = sample(g, n_robots, sigmas, seed)
    m = len(x)
    q_nom = nom.q
    comp = np.full((n_robots, m, 3, 3), np.nan)
    err = np.full((n_robots, m, 4), np.nan)
    tilt = np.full((n_robots, m), np.nan)
    conv = np.zeros((n_robots, m), dtype=bool)
    # Nominal Newton Jacobians per pose (chord method for the small perturbations).
    nb = batch._replace(P=g.P[None], A0=g.A0[None], l=g.l[None], C0=g.C0[None], b=g.b[None])
    st0 = geometry.rigid_state(x, q_nom)
    pts0 = _points(nb, q_nom, x[:, :3], st0.R, st0.omega)
    inv_free = np.linalg.inv(_jacobian(nb, pts0, True))
    inv_fwd = np.linalg.inv(_jacobian(nb, pts0, False))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_robots * m, unit="pair", desc="tolerance study", leave=False)
    total = n_robots * m

    def run(s0: int) -> int:
        flat = np.arange(s0, min(s0 + _CHUNK, total))
        ri, pi = flat // m, flat % m
        bg = batch.take(ri, pose_axis=False)
        xp, qp = x[pi], q_nom[pi]
        # Compliance at the pose: the robot's own inverse geometry (q and the tilt free).
        _, pts, ok1 = _solve_pairs(bg, qp, xp, True, inv_free[pi])
        with np.errstate(all="ignore"):
            try:
                kk = _compliance_tt(bg, pts, model)
            except np.linalg.LinAlgError:
                kk = np.full((len(flat), 8, 8), np.nan)
        # Pose error at the commanded nominal q (forward geometry).
        fw, _, ok2 = _solve_pairs(bg, qp, xp, False, inv_fwd[pi])
        ok = ok1 & ok2
        e = np.concatenate([fw.D - xp[:, :3], (fw.theta - xp[:, 3])[..., None]], axis=-1)
        comp[ri, pi] = np.where(ok[..., None, None], kk[..., :3, :3], np.nan)
        err[ri, pi] = np.where(ok[..., None], e, np.nan)
        tilt[ri, pi] = np.where(ok, np.linalg.norm(fw.tilt[..., :2], axis=-1), np.nan)
        conv[ri, pi] = ok
        return len(flat)

    # Chunks are independent and write disjoint rows; numpy releases the GIL in its array
    # work, so threads use the cores without copying the robots to other processes.
    with ThreadPoolExecutor(max_workers=workers or os.cpu_count() or 1) as pool:
        for done in pool.map(run, range(0, total, _CHUNK)):
            if bar is not None:
                bar.update(done)
    if bar is not None:
        bar.close()
    return ToleranceResult(x, q_nom, check_sigmas(sigmas), comp, nom.translational, err, tilt, conv)


def sensitivity(h4, poses: np.ndarray | None = None, n_robots: int = 1000, sigmas: dict[str, float] | None = None,
                seed: int = 0, model: str = "paper") -> dict[str, dict[str, float]]:
    """One tolerance at a time: for each kind with a non-zero sigma, the study with only that
    sigma; returns kind -> output -> spread (95th minus 5th percentile over robots and poses
    of the deviation from the nominal robot), SI."""
    s = check_sigmas(sigmas)
    out: dict[str, dict[str, float]] = {}
    for kind in KINDS:
        if s[kind] == 0.0:
            continue
        only = {k: (s[k] if k == kind else 0.0) for k in KINDS}
        res = study(h4, poses, n_robots, only, seed, model)
        out[kind] = {name: float(np.subtract(*np.nanpercentile(v - _nominal_of(res, name), [95, 5])))
                     for name, v in res.outputs().items()}
    return out


def _nominal_of(res: ToleranceResult, name: str) -> np.ndarray:
    """The nominal value (M,) of an output (0 for the pose errors and the tilt)."""
    k = res.nominal
    table = {"xx": k[:, 0, 0], "yy": k[:, 1, 1], "zz": k[:, 2, 2], "xz": k[:, 0, 2],
             "lambda_max": np.linalg.eigvalsh(0.5 * (k + np.swapaxes(k, -1, -2)))[:, -1]}
    return table.get(name, np.zeros(len(k)))


def report(res: ToleranceResult, sens: dict[str, dict[str, float]] | None = None) -> str:
    """Text: the sigmas, the percentile table (5, 50, 95) and the one-at-a-time sensitivity."""
    r, m = res.converged.shape
    lines = [f"tolerance study: {r} robots x {m} poses ({int(res.converged.sum())} converged)",
             "sigmas: " + ", ".join(f"{k} {v * 1e6:g} um" for k, v in res.sigmas.items()), ""]
    pct = {name: np.nanpercentile(v[:, 0], (5, 50, 95)) for name, v in res.outputs().items()}
    lines.append("percentiles over the robots at pose 0 (the centre pose):")
    nominal_centre = {name: float(_nominal_of(res, name)[0]) for name, _, _ in OUTPUTS}
    lines.append(f"| {'output':<10} | {'unit':<5} | {'nominal@0':>10} | {'p5':>10} | {'p50':>10} | {'p95':>10} |")
    lines.append(f"|{'-' * 12}|{'-' * 7}|{'-' * 12}|{'-' * 12}|{'-' * 12}|{'-' * 12}|")
    for name, f, unit in OUTPUTS:
        p = pct[name] * f
        lines.append(f"| {name:<10} | {unit:<5} | {nominal_centre[name] * f:>10.4g} | {p[0]:>10.4g} | {p[1]:>10.4g} "
                     f"| {p[2]:>10.4g} |")
    if sens:
        names = [n for n, _, _ in OUTPUTS]
        lines += ["", "one at a time: spread p95 - p5 of the deviation from nominal (um/N, um, urad)",
                  "| " + f"{'tolerance':<9} | " + " | ".join(f"{n:>9}" for n in names) + " |",
                  "|" + "-" * 11 + "|" + "|".join("-" * 11 for _ in names) + "|"]
        for kind, row in sens.items():
            lines.append(f"| {kind:<9} | " + " | ".join(f"{row[n] * 1e6:>9.3g}" for n in names) + " |")
        for group, keys in (("compliance", ("xx", "yy", "zz", "xz", "lambda_max")),
                            ("pose error", ("dx", "dy", "dz", "dtheta", "tilt"))):
            worst = {kind: max(row[k] / max(_spread_total(res, k), 1e-300) for k in keys) for kind, row in sens.items()}
            top = max(worst, key=worst.get)
            lines.append(f"matters most for the {group}: {top}")
    return "\n".join(lines)


def _spread_total(res: ToleranceResult, name: str) -> float:
    v = res.outputs()[name] - _nominal_of(res, name)
    return float(np.subtract(*np.nanpercentile(v, [95, 5])))


def write_figure(res: ToleranceResult, path: str | Path) -> Path:
    """Histograms of every output (deviation from nominal for the compliance), written
    atomically (temporary file, then rename) as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    if not path.parent.is_dir():
        raise ParameterError(f"cannot write {path}: folder {path.parent} does not exist")
    outs = res.outputs()
    fig, axes = plt.subplots(2, 5, figsize=(16, 6.5))
    for ax, (name, f, unit) in zip(axes.ravel(), OUTPUTS, strict=True):
        v = (outs[name] - (_nominal_of(res, name) if name in ("xx", "yy", "zz", "xz", "lambda_max") else 0.0)) * f
        v = v[np.isfinite(v)]
        ax.hist(v, bins=60, color="tab:blue", alpha=0.8)
        for p in np.percentile(v, [5, 50, 95]) if v.size else ():
            ax.axvline(p, color="k", lw=0.8, ls="--")
        label = f"d{name}" if name in ("xx", "yy", "zz", "xz", "lambda_max") else name
        ax.set_xlabel(f"{label} ({unit})")
        ax.set_yticks([])
    r, m = res.converged.shape
    fig.suptitle(f"H4 tolerance study: {r} robots x {m} poses (dashed: 5, 50, 95 %; compliance as deviation "
                 "from nominal)")
    fig.tight_layout()
    return save_figure(fig, path, dpi=90)


__all__ = ["DEFAULT_SIGMAS", "KINDS", "OUTPUTS", "BatchGeometry", "ToleranceResult", "check_sigmas", "default_poses",
           "report", "robot_geometry", "sample", "sensitivity", "study", "write_figure"]
