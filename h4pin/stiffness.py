# SPDX-License-Identifier: Apache-2.0
"""The stiffness model of Company, Pierrot and Fauroux (ICRA 2005): eq. 30, and the compliance API.

:func:`compliance` gives the 8x8 compliance matrix ``K`` of eq. 30, ``dtp = K Gamma_ext``, with

* ``dtp = [dD, dOmega, domega_1, domega_2]`` (eq. 3): small translation and rotation of the
  central bar (world-aligned, at D) and the relative rotations of the lateral bars on their
  revolute joints (m, rad);
* ``Gamma_ext = [F, T, t_1, t_2]`` (eq. 16): force and torque on the central bar at D and the
  torques on the two revolute joints (N, N.m).

``K`` is the sum of four terms, kept apart on request: ``control`` (actuators, eq. 12),
``bending`` (forearms, eq. 15), ``torsion`` (forearms, eq. 23) and ``tension`` (bars, eq. 27).
Every spring has its own compliance (per actuator, forearm and bar, read from the URDF).

Two models, side by side (``docs/errata.md``):

* ``"paper"``: eq. 30 as printed, with errata 1-3 fixed.
* ``"consistent"``: erratum 4 fixed too. As printed, ``R`` keeps only F and T_z and drops the
  load that t_1, t_2 put on the actuators. Here ``J^T R`` is replaced by ``(M1^-1 M2 M3)^T``.
  K is then exactly symmetric and equals an independent Newton-Euler statics route
  (:mod:`h4pin.statics`). Both models agree on the translational block and the F, T columns.

One verdict per pose, on every path: the pose is solved by :func:`h4pin.geometry.solve`
(unreachable, joint limits, interfering bars), then refused as singular when the condition
number of the scaled M1 (:func:`condition_number`) is not below :data:`SINGULAR_COND`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator, Mapping
from typing import Any

import numpy as np

from h4pin import geometry
from h4pin.errors import LoadError, ParameterError, SingularPoseError
from h4pin.geometry import OK, SINGULAR, STATUS_NAMES
from h4pin.matrices import R_CONSISTENT, R_PAPER, Matrices, from_kinematics, from_points, n_matrix
from h4pin.model import H4Geometry

TERMS = ("control", "bending", "torsion", "tension")
MODELS = ("paper", "consistent")
METHODS = ("auto", "kernel", "closed_form", "pinocchio")
#: Status of a pose given as NaN (only with ``on_error="nan"``).
INVALID = 5
#: Singularity threshold on :func:`condition_number`. K's relative error is about
#: cond x 1e-16, so an accepted pose's K is accurate to ~1e-7; tests/test_verdicts.py checks
#: it against the independent statics route at the worst accepted poses.
SINGULAR_COND = 1e9
_BATCH_CHUNK = 8192

__all__ = ["MODELS", "R_CONSISTENT", "R_PAPER", "SINGULAR_COND", "TERMS", "Compliance", "Matrices", "compliance",
           "condition_number", "eq30_terms", "matrices_at", "n_matrix"]


def condition_number(mats: Matrices) -> tuple[np.ndarray, np.ndarray]:
    """M1^-1 and the 1-norm condition number of the scaled M1 (..., batched).

    Scaled so the number does not depend on units: each row divided by its bar length (unit
    w_ij) and the five rotation columns divided by the mean bar length. Singular M1 give NaN
    and inf.
    """
    m1 = mats.M1
    with np.errstate(all="ignore"):
        try:
            inv = np.linalg.inv(m1)
        except np.linalg.LinAlgError:
            inv = np.full_like(m1, np.nan)
            flat, out = m1.reshape(-1, 8, 8), inv.reshape(-1, 8, 8)
            for n, m in enumerate(flat):
                try:
                    out[n] = np.linalg.inv(m)
                except np.linalg.LinAlgError:
                    pass
        L = np.mean(mats.l, axis=-1)[..., None]
        col = np.concatenate([np.ones((*L.shape[:-1], 3)), np.repeat(1 / L, 5, axis=-1)], axis=-1)
        ms = m1 / mats.l[..., :, None] * col[..., None, :]
        ims = inv / col[..., :, None] * mats.l[..., None, :]
        cond = np.abs(ms).sum(-2).max(-1) * np.abs(ims).sum(-2).max(-1)
    return inv, np.where(np.isfinite(cond), cond, np.inf)


def singular_message(cond: float) -> str:
    """The message of a pose refused as singular (:data:`SINGULAR_COND`)."""
    return (f"M1 is singular (cond = {cond:.2e} >= {SINGULAR_COND:.0e}): the plate has a motion that no spring "
            "resists")


def eq30_terms(inv: np.ndarray, mats: Matrices, comp: dict[str, np.ndarray], model: str) -> dict[str, np.ndarray]:
    """The four terms of eq. 30, each (..., 8, 8), SI, from M1^-1 and the matrices.

    ``K = M1^-1 M2 (M3 C_c J^T R + M3 C_b J^T R + M4 C_t Jb^-1 + M5 C_l Jb^-1)`` with the
    diagonal compliance matrices C of each spring family (per actuator, forearm, bar; the
    print has one scalar each), ``Jb^-1 = diag(l) M1^-T`` and, for ``model="consistent"``,
    ``J^T R`` replaced by ``(M1^-1 M2 M3)^T`` (erratum 4).
    """
    ym2 = inv @ mats.M2
    g3 = ym2 @ mats.M3  # (..., 8, 4) = M1^-1 M2 M3
    load = np.swapaxes(mats.J, -1, -2) @ mats.R if model == "paper" else np.swapaxes(g3, -1, -2)
    jb_inv = mats.l[..., :, None] * np.swapaxes(inv, -1, -2)
    return {
        "control": (g3 * comp["control"]) @ load,
        "bending": (g3 * comp["bending"]) @ load,
        "torsion": (ym2 @ mats.M4 * np.repeat(comp["torsion"], 2)) @ jb_inv,
        "tension": (ym2 @ mats.M5 * comp["tension"]) @ jb_inv,
    }


class LazyTerms(Mapping):
    """The four terms of eq. 30, computed on first access (a read-only mapping of name -> array).

    A compliance result carries one, so that a user who does not look at the terms does not pay
    for them (time, and 2 KB a pose)."""

    def __init__(self, compute: Callable[[], Mapping[str, np.ndarray]]):
        self._compute: Callable[[], Mapping[str, np.ndarray]] | None = compute
        self._data: dict[str, np.ndarray] | None = None

    def _get(self) -> dict[str, np.ndarray]:
        if self._data is None:
            self._data = dict(self._compute())  # type: ignore[misc]
            self._compute = None
        return self._data

    @property
    def computed(self) -> bool:
        """Whether the terms have been computed yet."""
        return self._data is not None

    def __getitem__(self, key: str) -> np.ndarray:
        return self._get()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._get())

    def __len__(self) -> int:
        return len(TERMS)

    def __repr__(self) -> str:
        return f"LazyTerms({'computed' if self.computed else 'not computed yet'}: {', '.join(TERMS)})"


@dataclasses.dataclass(frozen=True)
class Compliance:
    """Compliance of an H4 at one pose (shapes as below) or a batch (a leading N axis).

    Attributes:
        matrix: (8, 8) K of eq. 30, dtp = K Gamma_ext, SI (m/N, rad/N, m/(N.m), rad/(N.m)).
        terms: "control", "bending", "torsion", "tension": (8, 8) each, summing to ``matrix``;
            computed on first access (:class:`LazyTerms`) unless ``compliance(..., terms=True)``.
        pose: (4,) [x, y, z, theta] in m, rad.
        q: (4,) actuator angles in rad.
        model: "paper" or "consistent".
        condition: condition number of the scaled M1 (how close to a singularity the pose is;
            poses at or above :data:`SINGULAR_COND` are refused).
        status: verdict code per pose (0 ok; 1 unreachable, 2 joint limits, 3 interfering bars,
            4 singular, 5 not a finite pose; ``h4pin.geometry.STATUS_NAMES``).
        valid: (N,) bool for a batch computed with ``on_error="nan"`` (False rows are NaN);
            ``None`` otherwise.
    """

    matrix: np.ndarray
    terms: Mapping[str, np.ndarray]
    pose: np.ndarray
    q: np.ndarray
    model: str
    condition: np.ndarray | float
    status: np.ndarray | int = 0
    valid: np.ndarray | None = None

    @property
    def translational(self) -> np.ndarray:
        """The 3x3 block dD = K_tt F, in m/N (Table II of the paper, in um/N, is 1e6 times it)."""
        return self.matrix[..., :3, :3]

    def deflection(self, load: np.ndarray) -> np.ndarray:
        """dtp (8,) (or (N, 8)) for a load Gamma_ext (8,) or a force F (3,) at D, SI."""
        return self.matrix @ as_load(load)

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
                raise ParameterError(f"a point offset must have shape (3,) or (N, 3), got shape {o.shape}")
            r = np.einsum("...ab,...b->...a", rot, o)
            t = np.zeros((*r.shape[:-1], 3, 6))
            t[..., :, :3] = np.eye(3)
            t[..., :, 3:] = -np.swapaxes(geometry.cross(r[..., None, :], np.eye(3)), -1, -2)  # -[r]x
            return t

        tp = transform(offset)
        tq = tp if load_at is None else transform(load_at)
        return tp @ self.matrix[..., :6, :6] @ np.swapaxes(tq, -1, -2)


def as_load(load: Any) -> np.ndarray:
    """A force F (3,) or a full Gamma_ext = [F, T, t1, t2] (8,) as Gamma_ext (8,), SI."""
    try:
        g = np.asarray(load, dtype=float)
    except (TypeError, ValueError):
        raise LoadError(f"load must be numbers: a force F (3,) in N or Gamma_ext (8,), got {load!r}") from None
    if g.shape == (3,):
        g = np.r_[g, np.zeros(5)]
    if g.shape != (8,) or not np.all(np.isfinite(g)):
        raise LoadError(f"load must be a finite force F (3,) in N or Gamma_ext = [F, T, t1, t2] (8,), "
                        f"got {load!r}")
    return g


def matrices_at(h4, pose: np.ndarray) -> Matrices:
    """All the paper's matrices at one pose, through Pinocchio (:func:`h4pin.matrices.from_kinematics`).

    Raises:
        UnreachablePoseError (and subclasses): as :func:`compliance`.
    """
    return from_kinematics(h4.kinematics(pose))


def _check_options(model: str, on_error: str, method: str) -> None:
    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}, got {model!r}")
    if on_error not in ("raise", "nan"):
        raise ParameterError(f"on_error must be 'raise' or 'nan', got {on_error!r}")
    if method not in METHODS:
        raise ParameterError(f"method must be one of {METHODS}, got {method!r}")


def compliance(h4, pose: np.ndarray, model: str = "paper", *, on_error: str = "raise", method: str = "auto",
               terms: bool | None = None) -> Compliance:
    """Compliance matrix K of eq. 30 at a pose or a batch of poses.

    Args:
        h4: The robot (:func:`h4pin.load`).
        pose: (4,) or (N, 4) poses [x, y, z, theta] in m, rad.
        model: ``"paper"`` (eq. 30 as printed, errata 1-3 fixed) or ``"consistent"``
            (erratum 4 fixed too, K symmetric).
        on_error: ``"raise"``: the first pose the robot cannot take, or a singular one, raises
            its typed error (:class:`h4pin.UnreachablePoseError` and subclasses,
            :class:`h4pin.SingularPoseError`) naming its index. ``"nan"``: such poses (and NaN
            poses) give NaN matrices, ``valid`` False and their ``status``.
        method: ``"kernel"`` (the compiled kernel, :mod:`h4pin.kernel`; robots with exact
            parallelograms), ``"pinocchio"`` (Pinocchio's frame Jacobians, one pose at a time),
            ``"closed_form"`` (vectorised numpy closed forms, the reference), ``"auto"`` (the
            kernel when it applies, else the closed form). Every method gives the same verdicts.
        terms: Compute the four terms now (``True``); by default they are computed when first
            accessed (:attr:`Compliance.terms`).

    Returns:
        A :class:`Compliance`.
    """
    _check_options(model, on_error, method)
    if (not terms and method == "auto" and on_error == "raise" and type(pose) is np.ndarray and pose.shape == (4,)
            and pose.dtype == np.float64 and math.isfinite(pose.sum()) and h4.geometry.ideal):
        # The fast path of one pose: one compiled call; anything but a regular pose goes the long way.
        K, q, cond, status = _kernel(h4)(pose, model)
        if status == OK:
            x = pose.copy()
            return Compliance(K, LazyTerms(lambda: _compliance(h4, x, model, "nan", method, True).terms), x, q, model,
                              cond, 0, None)
    if not terms and method == "pinocchio" and on_error == "raise" and np.shape(pose) == (4,):
        x = geometry.as_pose(pose).copy()
        K, cond, _, q = h4.pinocchio_compliance(x, model)  # raises the typed error of a pose it cannot take
        if not cond < SINGULAR_COND:
            raise SingularPoseError(singular_message(cond))
        return Compliance(K, LazyTerms(lambda: _compliance(h4, x, model, "nan", method, True).terms), x, q, model,
                          cond, 0, None)
    if not terms:
        res = _compliance(h4, pose, model, on_error, method, False)
        lazy = LazyTerms(lambda: _compliance(h4, pose, model, "nan", method, True).terms)
        return dataclasses.replace(res, terms=lazy)
    return _compliance(h4, pose, model, on_error, method, True)


def _compliance(h4, pose: np.ndarray, model: str, on_error: str, method: str, keep: bool) -> Compliance:
    raw = np.asarray(pose, dtype=float) if on_error == "nan" else None
    if raw is not None and raw.ndim == 2 and raw.shape[-1] == 4:
        finite = np.all(np.isfinite(raw), axis=1)
        x = raw
    else:
        x = geometry.as_poses(pose)
        finite = np.ones(len(x) if x.ndim == 2 else 1, dtype=bool)
    single = x.ndim == 1
    xb = x[None] if single else x
    g: H4Geometry = h4.geometry
    if method == "auto":
        method = "kernel" if g.ideal else "closed_form"
    if method == "kernel":
        return _kernel_path(h4, x, xb, finite, single, model, on_error, keep)
    n = len(xb)
    status = np.full(n, INVALID, dtype=np.int8)
    detail: list[str | None] = [None] * n  # filled for the poses that fail (NaN poses: below)
    q = np.full((n, 4), np.nan)
    cond = np.full(n, np.nan)
    matrix = np.full((n, 8, 8), np.nan)
    out_terms = {t: np.full((n, 8, 8), np.nan) for t in TERMS} if keep else None
    idx_all = np.flatnonzero(finite)
    comp = g.compliances()
    for start in range(0, len(idx_all), _BATCH_CHUNK):
        idx = idx_all[start:start + _BATCH_CHUNK]
        sol = geometry.solve(g, xb[idx])
        status[idx] = sol.status
        for k, msg in zip(idx, sol.detail, strict=True):
            detail[k] = msg
        ok = np.flatnonzero(sol.status == OK)
        if ok.size == 0:
            continue
        sel = idx[ok]
        q[sel] = sol.state.q[ok]
        if method == "pinocchio" and not keep:
            for k in sel:
                K, c, _, _ = h4.pinocchio_compliance(xb[k], model)
                cond[k] = c
                if c < SINGULAR_COND:
                    matrix[k] = K
                else:
                    status[k] = SINGULAR
                    detail[k] = singular_message(c)
            continue
        if method == "pinocchio":
            mats_list = [from_kinematics(h4.kinematics(xb[k])) for k in sel]
            mats = Matrices(*(np.stack([getattr(m, f) for m in mats_list]) if f not in ("M5", "R")
                              else getattr(mats_list[0], f) for f in Matrices._fields))
        else:
            state = geometry.PlateState(*(a[ok] for a in sol.state))
            mats = from_points(g, geometry.points(g, state))
        inv, c = condition_number(mats)
        cond[sel] = c
        regular = c < SINGULAR_COND
        for k, cc in zip(sel[~regular], c[~regular], strict=True):
            status[k] = SINGULAR
            detail[k] = singular_message(cc)
        if not np.any(regular):
            continue
        sub = Matrices(*(getattr(mats, f)[regular] if f not in ("M5", "R") else getattr(mats, f)
                         for f in Matrices._fields))
        part = eq30_terms(inv[regular], sub, comp, model)
        matrix[sel[regular]] = sum(part.values())
        if out_terms is not None:
            for t in TERMS:
                out_terms[t][sel[regular]] = part[t]
    if on_error == "raise":
        for k in np.flatnonzero(status == INVALID)[:1]:
            detail[k] = f"pose #{k} is not finite: {xb[k]}"
        geometry.raise_for_status(status, detail, batch=not single)
    valid = status == OK
    if single:
        if on_error == "raise":
            return Compliance(matrix[0], None if out_terms is None else {t: v[0] for t, v in out_terms.items()},
                              x, q[0], model, float(cond[0]), int(status[0]), None)
        return Compliance(matrix[0], None if out_terms is None else {t: v[0] for t, v in out_terms.items()}, x,
                          q[0], model, float(cond[0]), int(status[0]), np.array(valid[0]))
    return Compliance(matrix, out_terms, x, q, model, cond, status, None if on_error == "raise" else valid)


def _kernel(h4) -> Any:
    """The robot's packed kernel, made once (the robot is immutable once loaded)."""
    from h4pin import kernel

    kern = getattr(h4, "_kernel", None)
    if kern is None:
        kern = kernel.prepare(h4.geometry)
        h4._kernel = kern
    return kern


def _kernel_path(h4, x: np.ndarray, xb: np.ndarray, finite: np.ndarray, single: bool, model: str, on_error: str,
                 keep: bool) -> Compliance:
    from h4pin import kernel

    kern = _kernel(h4)
    if single and not keep and finite[0]:
        K, q, cond, status = kern(xb[0], model)
        matrix, qs, conds, statuses, terms = K[None], q[None], np.array([cond]), np.array([status], np.int8), None
    else:
        n = len(xb)
        matrix, qs = np.full((n, 8, 8), np.nan), np.full((n, 4), np.nan)
        conds, statuses = np.full(n, np.nan), np.full(n, INVALID, dtype=np.int8)
        terms = {t: np.full((n, 8, 8), np.nan) for t in TERMS} if keep else None
        idx = np.flatnonzero(finite)
        if idx.size:
            res = kernel.compliance_batch(kern, np.ascontiguousarray(xb[idx]), model, terms=keep)
            matrix[idx], qs[idx], conds[idx], statuses[idx] = res.K, res.q, res.condition, res.status
            if keep:
                for t, name in enumerate(TERMS):
                    terms[name][idx] = res.terms[:, t]
    if on_error == "raise" and np.any(statuses != OK):
        k = int(np.argmax(statuses != OK))
        details: list[str | None] = [None] * len(statuses)
        if statuses[k] == SINGULAR:
            details[k] = singular_message(conds[k])
        elif statuses[k] == INVALID:
            details[k] = f"pose #{k} is not finite: {xb[k]}"
        else:
            details[k] = geometry.solve(h4.geometry, xb[k]).detail[0]
        geometry.raise_for_status(statuses, details, batch=not single)
    valid = statuses == OK
    if single:
        return Compliance(matrix[0], None if terms is None else {t: v[0] for t, v in terms.items()}, x, qs[0], model,
                          float(conds[0]), int(statuses[0]), None if on_error == "raise" else np.array(valid[0]))
    return Compliance(matrix, terms, x, qs, model, conds, statuses, None if on_error == "raise" else valid)


def describe_status(status: int) -> str:
    """Human name of a verdict code (:attr:`Compliance.status`)."""
    return STATUS_NAMES.get(int(status), "not a finite pose" if int(status) == INVALID else "unknown")
