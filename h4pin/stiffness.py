# SPDX-License-Identifier: Apache-2.0
"""The stiffness model of Company, Pierrot and Fauroux (ICRA 2005), section IV, on Pinocchio.

:func:`compliance` gives the 8x8 compliance matrix ``K`` of eq. 30, ``dtp = K Gamma_ext``, with

* ``dtp = [dD, dOmega, domega_1, domega_2]`` (eq. 3): small translation and rotation of the
  central bar (world-aligned, at D) and the relative rotations of the lateral bars on their
  revolute joints (m, rad);
* ``Gamma_ext = [F, T, t_1, t_2]`` (eq. 16): force and torque on the central bar at D and the
  torques on the two revolute joints (N, N.m).

``K`` is the sum of four terms kept apart: ``control`` (actuators, eq. 12), ``bending``
(forearms, eq. 15), ``torsion`` (forearms, eq. 23) and ``tension`` (bars, eq. 27).

Two models, side by side:

* ``"paper"``: eq. 30 as printed, with errata 1-3 of H4-NOTES fixed (dim of d_epsilon is 32, not
  34; M1 uses t_ij per bar; eq. 16's displacement set is eq. 3's).
* ``"consistent"``: erratum 4 fixed too. As printed, ``R`` keeps only F and T_z and drops the
  load that t_1, t_2 put on the actuators (at a rigid pose d_omega_k = -d_theta). Here
  ``J^T R`` is replaced by ``(M1^-1 M2 M3)^T``, i.e. R[3, 6] = R[3, 7] = -1 (0-based). K is then
  exactly symmetric and equals an independent Newton-Euler statics route
  (:mod:`h4pin.statics`). Both models agree on the translational block and on the F, T columns.

Two paths share the matrix formulas (:func:`terms_from_matrices`): a single pose goes through
Pinocchio (M1 rows are ``w_ij^T`` times the Pinocchio Jacobian of B_ij in plate coordinates, J
from the closure Jacobians, M3 from the Jacobians of A_ij); a batch of poses uses the
vectorised closed forms of eqs. 6, 8 and 11. A test keeps them equal.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from h4pin import geometry
from h4pin.errors import PoseError, SingularPoseError, UnreachablePoseError
from h4pin.geometry import Points
from h4pin.params import LEG_LATERAL, H4Params
from h4pin.robot import H4

TERMS = ("control", "bending", "torsion", "tension")
MODELS = ("paper", "consistent")
#: cond(M1) above which a pose is reported singular (K would have lost > 6 of its 16 digits).
SINGULAR_COND = 1e10
_Z = np.array([0.0, 0.0, 1.0])
_BATCH_CHUNK = 8192

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


def _bars(pts: Points) -> tuple[np.ndarray, np.ndarray]:
    """w_ij = B_ij - A_ij (..., 8, 3) and l_ij = |w_ij| (..., 8)."""
    shape = pts.Bij.shape[:-3]
    w = (pts.Bij - pts.Aij).reshape(*shape, 8, 3)
    return w, np.linalg.norm(w, axis=-1)


def m1_closed_form(pts: Points) -> np.ndarray:
    """M1 of eq. 6 from cross products, (..., 8, 8).

    Row n = (i, j): ``[w_ij^T, (w_ij x (s_k + t_ij))^T, (w_ij x t_ij).z in column 6 + k]`` with
    s_k = D - C_k and t_ij = C_k - B_ij. Erratum 2: the print uses t_i per leg, which gives M1
    rank 6; the bars of one leg need their own t_ij.
    """
    w, _ = _bars(pts)
    shape = w.shape[:-2]
    bij = pts.Bij.reshape(*shape, 8, 3)
    ck = np.repeat(pts.C[..., LEG_LATERAL, :], 2, axis=-2)
    t = ck - bij
    s_plus_t = pts.D[..., None, :] - bij
    m1 = np.zeros((*shape, 8, 8))
    m1[..., :3] = w
    m1[..., 3:6] = geometry.cross(w, s_plus_t)
    lat = np.repeat(LEG_LATERAL, 2)
    m1[..., np.arange(8), 6 + lat] = geometry.cross(w, t)[..., 2]
    return m1


def m2(pts: Points) -> np.ndarray:
    """M2 = [spar(w_ij^T), diag(l_ij)] of eq. 6, (..., 8, 32); d_epsilon = [da_11..da_42, dl_11..dl_42]."""
    w, l = _bars(pts)
    shape = w.shape[:-2]
    out = np.zeros((*shape, 8, 32))
    n = np.arange(8)
    for c in range(3):
        out[..., n, 3 * n + c] = w[..., c]
    out[..., n, 24 + n] = l
    return out


def _per_bar_leg(array: np.ndarray) -> np.ndarray:
    """(..., 4, 3) per leg -> (..., 8, 3) per bar."""
    return np.repeat(array, 2, axis=-2)


def m3_closed_form(pts: Points, params: H4Params) -> np.ndarray:
    """M3 = [spar([(p_i1 x u_i)^T (p_i2 x u_i)^T]^T); 0] of eq. 11, (..., 32, 4).

    p_ij = P_i - A_ij; a rotation dq_i of actuator i moves A_ij by (p_ij x u_i) dq_i.
    """
    shape = pts.Aij.shape[:-3]
    p = (pts.P[:, None, :] - pts.Aij).reshape(*shape, 8, 3)
    col = geometry.cross(p, _per_bar_leg(np.broadcast_to(params.U.T, (*shape, 4, 3))))
    out = np.zeros((*shape, 32, 4))
    for n in range(8):
        out[..., 3 * n:3 * n + 3, n // 2] = col[..., n, :]
    return out


def n_matrix(pts: Points) -> np.ndarray:
    """N of eq. 23, one 6x2 block per leg, (..., 4, 6, 2).

    The printed N is garbled. Per leg, the reading that makes eqs. 22 and 23 agree in sign
    (H4-NOTES) is ``N_i = [p_i1 x r_i; p_i2 x r_i] [(p_i1 x r_i).w_i, (p_i2 x r_i).w_i]``, with
    p_ij = P_i - A_ij, r_i the unit vector A_i -> P_i and w_i the unit vector A_i -> B_i. A twist
    of forearm i under bar forces f_i1, f_i2 moves A_i1, A_i2 by ``(r / (G I0)) N_i [f_i1, f_i2]``.
    """
    shape = pts.Aij.shape[:-3]
    p = pts.P[:, None, :] - pts.Aij  # (..., 4, 2, 3)
    r = pts.P - pts.A
    r = r / np.linalg.norm(r, axis=-1, keepdims=True)
    wl = pts.B - pts.A
    wl = wl / np.linalg.norm(wl, axis=-1, keepdims=True)
    pr = geometry.cross(p, r[..., None, :])  # (..., 4, 2, 3): p_ij x r_i
    c = np.einsum("...ija,...ia->...ij", pr, wl)  # (..., 4, 2): (p_ij x r_i) . w_i
    return (pr.reshape(*shape, 4, 6)[..., :, None] * c[..., None, :])


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
    (Erratum 3: eq. 16 refers to eq. 8 for the displacement set; it means eq. 3.)
    """
    return np.swapaxes(m1, -1, -2) / l[..., None, :]


def matrices_closed_form(params: H4Params, pose: np.ndarray, q: np.ndarray) -> Matrices:
    """All the paper's matrices from the closed forms (vectorised over a batch of poses)."""
    pts = geometry.points(params, pose, q)
    M1 = m1_closed_form(pts)
    _, l = _bars(pts)
    return Matrices(M1, m2(pts), geometry.jacobian(params, pose, q), m3_closed_form(pts, params), m4(pts), M5,
                    jb_from_m1(M1, l), R_PAPER, l)


def points_from_pinocchio(h4: H4, xyz: np.ndarray | None = None) -> Points:
    """The characteristic points from Pinocchio's frame placements (after ``h4.compute(q)``);
    ``xyz``: :meth:`h4pin.H4.frame_points`, if already computed."""
    xyz = h4.frame_points() if xyz is None else xyz
    return Points(D=xyz[0], C=xyz[1:3], B=xyz[3:7], Bij=xyz[7:15].reshape(4, 2, 3), P=xyz[15:19], A=xyz[19:23],
                  Aij=xyz[23:31].reshape(4, 2, 3))


def matrices(h4: H4, pose: np.ndarray, q: np.ndarray | None = None) -> Matrices:
    """All the paper's matrices at one pose, through Pinocchio.

    * M1 (eq. 6): row n is ``w_ij^T JB_ij`` with JB_ij the Pinocchio Jacobian of frame B_ij in
      plate coordinates dtp (:meth:`h4pin.H4.plate_jacobians`);
    * J (eq. 8): from the closure Jacobians and the frame Jacobian of D (:meth:`h4pin.H4.jacobian`);
    * M3 (eq. 11): rows of leg i are the Jacobians of frames A_i1, A_i2 w.r.t. actuator i;
    * M2, M4, M5, Jb, R: formulas of eqs. 6, 23, 27, 16, 30 on the Pinocchio frame positions.

    ``q`` (4,), the actuator angles of ``pose``, saves an inverse geometry when already known.

    Raises:
        UnreachablePoseError, SingularPoseError: as :func:`compliance`.
    """
    x = geometry.as_poses(pose)
    if x.ndim != 1:
        raise PoseError(f"matrices takes one pose (4,), got shape {x.shape}; use matrices_closed_form for a batch")
    h4.compute(h4.configuration(x, q))
    xyz = h4.frame_points()
    pts = points_from_pinocchio(h4, xyz)
    w, l = _bars(pts)
    jb, ja = h4.plate_jacobians(xyz)
    M1 = np.einsum("na,nab->nb", w, jb)
    M3 = np.zeros((32, 4))
    M3[:24] = ja.reshape(24, 4)
    J = h4.plate_velocity_jacobian()
    return Matrices(M1, m2(pts), J, M3, m4(pts), M5, jb_from_m1(M1, l), R_PAPER, l)


def _inverse_m1(m1: np.ndarray, first_index: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """M1^-1 and the 1-norm condition number of M1, batched; singular M1 give NaN and inf."""
    good = np.ones(m1.shape[:-2], dtype=bool)
    try:
        inv = np.linalg.inv(m1)
    except np.linalg.LinAlgError:
        flat = m1.reshape(-1, 8, 8)
        inv = np.full_like(flat, np.nan)
        for n, m in enumerate(flat):
            try:
                inv[n] = np.linalg.inv(m)
            except np.linalg.LinAlgError:
                good.reshape(-1)[n] = False
        inv = inv.reshape(m1.shape)
    with np.errstate(invalid="ignore"):
        cond = np.abs(m1).sum(-2).max(-1) * np.abs(inv).sum(-2).max(-1)
    cond = np.where(good & np.isfinite(cond), cond, np.inf)
    return inv, cond


def terms_from_matrices(mats: Matrices, params: H4Params, model: str = "paper") -> dict[str, np.ndarray]:
    """The four terms of eq. 30 from the paper's matrices, each (..., 8, 8), SI.

    ``K = M1^-1 M2 ( (1/kc) M3 J^T R + r/(3EI) M3 J^T R + r/(G I0) M4 Jb^-1 + l/(Sb Eb) M5 Jb^-1 )``,
    with ``Jb^-1 = diag(l) M1^-T`` and, for ``model="consistent"``, ``J^T R`` replaced by
    ``(M1^-1 M2 M3)^T`` (erratum 4). The forearm terms carry the stressed fraction phi
    (phi^3 for bending, phi for torsion; phi = 1 is the paper).

    Raises:
        SingularPoseError: cond(M1) > :data:`SINGULAR_COND` (the message gives it).
    """
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    inv, cond = _inverse_m1(mats.M1)
    if np.any(~(cond < SINGULAR_COND)):
        n = int(np.argmax(~(cond < SINGULAR_COND).reshape(-1)))
        raise SingularPoseError(
            f"M1 is singular (cond = {cond.reshape(-1)[n]:.2e} > {SINGULAR_COND:.0e}): the plate has a "
            "motion that no spring resists", n if mats.M1.ndim == 3 else None)
    return _terms(inv, mats, params, model)


def _terms(inv: np.ndarray, mats: Matrices, params: H4Params, model: str) -> dict[str, np.ndarray]:
    c = params.compliances()
    ym2 = inv @ mats.M2
    g3 = ym2 @ mats.M3  # (..., 8, 4) = M1^-1 M2 M3
    if model == "paper":
        load = np.swapaxes(mats.J, -1, -2) @ mats.R
    else:
        load = np.swapaxes(g3, -1, -2)
    actuator = g3 @ load
    jb_inv = mats.l[..., :, None] * np.swapaxes(inv, -1, -2)
    return {
        "control": c["control"] * actuator,
        "bending": c["bending"] * actuator,
        "torsion": c["torsion"] * (ym2 @ mats.M4 @ jb_inv),
        "tension": c["tension"] * (ym2 @ mats.M5 @ jb_inv),
    }


@dataclasses.dataclass(frozen=True)
class Compliance:
    """Compliance of an H4 at one pose (shapes as below) or a batch (a leading N axis).

    Attributes:
        matrix: (8, 8) K of eq. 30, dtp = K Gamma_ext, SI (m/N, rad/N, m/(N.m), rad/(N.m)).
        terms: "control", "bending", "torsion", "tension": (8, 8) each, summing to ``matrix``.
        pose: (4,) [x, y, z, theta] in m, rad.
        q: (4,) actuator angles in rad.
        model: "paper" or "consistent".
        valid: (N,) bool for a batch computed with ``on_error="nan"`` (False rows are NaN);
            ``None`` otherwise.
    """

    matrix: np.ndarray
    terms: dict[str, np.ndarray]
    pose: np.ndarray
    q: np.ndarray
    model: str
    valid: np.ndarray | None = None

    @property
    def translational(self) -> np.ndarray:
        """The 3x3 block dD = K_tt F, in m/N (Table II of the paper, in um/N, is 1e6 times it)."""
        return self.matrix[..., :3, :3]

    def deflection(self, load: np.ndarray) -> np.ndarray:
        """dtp (8,) (or (N, 8)) for a load Gamma_ext (8,) or a force F (3,), SI."""
        g = np.asarray(load, dtype=float)
        if g.shape == (3,):
            g = np.r_[g, np.zeros(5)]
        if g.shape != (8,):
            raise ValueError(f"load must be a force F (3,) or Gamma_ext = [F, T, t1, t2] (8,), got shape {g.shape}")
        return self.matrix @ g

    def at(self, offset: np.ndarray, load_at: np.ndarray | None = None) -> np.ndarray:
        """Translational compliance (3, 3) (or (N, 3, 3)) at a point p fixed to the central bar,
        for a force applied at p' (default p' = p), SI (m/N).

        ``offset`` o and ``load_at`` o' (3,) (or (N, 3)) are the points in the central-bar frame,
        in m: p - D = Rz(theta) o, with theta the pose's (the frame is world-aligned at theta = 0).
        A small plate motion moves p by ``dp = dD + dOmega x (p - D) = T_p [dD; dOmega]`` with
        ``T_p = [I, -[p - D]x]`` (3x6); a force F at p' is ``[F, (p' - D) x F] = T_p'^T F`` at D.
        Hence ``C_pp' = T_p K6 T_p'^T``, K6 the F, T block of :attr:`matrix` (the same in both
        models). With ``offset = load_at = 0`` it is :attr:`translational`; for p != p' it is not
        symmetric (``C_p'p = C_pp'^T``).
        """
        theta = np.asarray(self.pose)[..., 3]
        rot = geometry.rot_z(theta)

        def transform(o: np.ndarray) -> np.ndarray:
            o = np.asarray(o, dtype=float)
            if o.shape[-1:] != (3,):
                raise ValueError(f"a point offset must have shape (3,) or (N, 3), got shape {o.shape}")
            r = np.einsum("...ab,...b->...a", rot, o)
            t = np.zeros((*r.shape[:-1], 3, 6))
            t[..., :, :3] = np.eye(3)
            t[..., :, 3:] = -np.swapaxes(geometry.cross(r[..., None, :], np.eye(3)), -1, -2)  # -[r]x
            return t

        tp = transform(offset)
        tq = tp if load_at is None else transform(load_at)
        return tp @ self.matrix[..., :6, :6] @ np.swapaxes(tq, -1, -2)


def compliance(h4: H4, pose: np.ndarray, model: str = "paper", *, on_error: str = "raise",
               method: str = "auto") -> Compliance:
    """Compliance matrix K of eq. 30 at a pose or a batch of poses.

    Args:
        h4: The robot (:func:`h4pin.load`).
        pose: (4,) or (N, 4) poses [x, y, z, theta] in m, rad.
        model: ``"paper"`` (eq. 30 as printed, errata 1-3 fixed) or ``"consistent"``
            (erratum 4 fixed too, K symmetric). See the module docstring.
        on_error: ``"raise"``: the first unreachable or singular pose raises
            :class:`h4pin.UnreachablePoseError` or :class:`h4pin.SingularPoseError` naming its
            index. ``"nan"``: bad poses give NaN matrices and ``valid`` is False for them.
        method: ``"pinocchio"`` (single pose through Pinocchio's Jacobians), ``"closed_form"``
            (vectorised), or ``"auto"`` (Pinocchio for one pose, closed form for a batch).

    Returns:
        A :class:`Compliance`.
    """
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    if on_error not in ("raise", "nan"):
        raise ValueError(f"on_error must be 'raise' or 'nan', got {on_error!r}")
    if method not in ("auto", "pinocchio", "closed_form"):
        raise ValueError(f"method must be 'auto', 'pinocchio' or 'closed_form', got {method!r}")
    x = geometry.as_poses(pose)
    single = x.ndim == 1
    if method == "auto":
        method = "pinocchio" if single else "closed_form"
    xb = x[None] if single else x
    if method == "pinocchio" and single and on_error == "raise":
        q = h4.inverse_geometry(x)
        terms = terms_from_matrices(matrices(h4, x, q), h4.params, model)
        return Compliance(sum(terms.values()), terms, x, q, model, None)
    if method == "pinocchio":
        return _pinocchio_batch(h4, xb, model, on_error, single)
    return _closed_form_batch(h4.params, xb, model, on_error, single)


def _pack(terms: dict[str, np.ndarray], x: np.ndarray, q: np.ndarray, model: str, valid: np.ndarray | None,
          single: bool) -> Compliance:
    matrix = sum(terms.values())
    if single:
        return Compliance(matrix[0], {k: v[0] for k, v in terms.items()}, x[0], q[0], model, None)
    return Compliance(matrix, terms, x, q, model, valid)


def _pinocchio_batch(h4: H4, x: np.ndarray, model: str, on_error: str, single: bool) -> Compliance:
    terms = {t: np.full((len(x), 8, 8), np.nan) for t in TERMS}
    q = np.full((len(x), 4), np.nan)
    valid = np.zeros(len(x), dtype=bool)
    for n, xn in enumerate(x):
        try:
            q[n] = h4.inverse_geometry(xn)
            one = terms_from_matrices(matrices(h4, xn, q[n]), h4.params, model)
        except (UnreachablePoseError, SingularPoseError) as exc:
            if on_error == "raise":
                raise type(exc)(str(exc), None if single else n) from None
            continue
        for t in TERMS:
            terms[t][n] = one[t]
        valid[n] = True
    return _pack(terms, x, q, model, None if on_error == "raise" else valid, single)


def _closed_form_batch(params: H4Params, x: np.ndarray, model: str, on_error: str, single: bool) -> Compliance:
    q = geometry.inverse_geometry(params, x, on_error="nan")
    reachable = np.all(np.isfinite(q), axis=-1)
    if on_error == "raise" and not np.all(reachable):
        n = int(np.argmax(~reachable))
        try:
            geometry.inverse_geometry(params, x[n])
        except UnreachablePoseError as exc:
            raise UnreachablePoseError(str(exc), None if single else n) from None
    terms = {t: np.full((len(x), 8, 8), np.nan) for t in TERMS}
    valid = reachable.copy()
    for start in range(0, len(x), _BATCH_CHUNK):
        sl = slice(start, start + _BATCH_CHUNK)
        idx = np.flatnonzero(reachable[sl]) + start
        if idx.size == 0:
            continue
        mats = matrices_closed_form(params, x[idx], q[idx])
        inv, cond = _inverse_m1(mats.M1)
        ok = cond < SINGULAR_COND
        if on_error == "raise" and not np.all(ok):
            n = int(idx[np.argmax(~ok)])
            raise SingularPoseError(
                f"M1 is singular (cond = {cond[np.argmax(~ok)]:.2e} > {SINGULAR_COND:.0e}): the plate has a "
                "motion that no spring resists", None if single else n)
        valid[idx[~ok]] = False
        part = _terms(inv, mats, params, model)
        for t in TERMS:
            terms[t][idx[ok]] = part[t][ok]
    return _pack(terms, x, q, model, None if on_error == "raise" else valid, single)
