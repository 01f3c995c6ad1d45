# SPDX-License-Identifier: Apache-2.0
"""Closing the loops of a :class:`~h4pin.mechanism.Mechanism`: :meth:`Mechanism.assemble
<h4pin.mechanism.Mechanism.assemble>`'s solver, the closures' residuals and Jacobians, and
assembly over a list of motor positions by continuation.

A closure's residual is the world position gap of its two points (3-D) or ``log6`` of the
relative placement of its two frames (6-D); its Jacobian is Pinocchio's frame Jacobians' difference
(:func:`closure_step`). The solver (:func:`close`) is a bounded trust-region least-squares on the
residuals (scipy's ``least_squares``), then Gauss-Newton to the tolerance.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin import limits
from h4pin.errors import H4Error, MechanismWarning, ParameterError, located
from h4pin.inputs import real_array
from h4pin.mechanism import engine
from h4pin.mechanism.arguments import joint_names
from h4pin.mechanism.engine import UnassembledError

#: Closure error (m, and rad for 6-D closures) within which :meth:`Mechanism.assemble` stops.
ASSEMBLY_TOL = 1e-10


def assemble(mech: Any, q: Any, motors: Any, fixed: Iterable[Any] | None, tol: float,
             iterations: int) -> np.ndarray:
    """:meth:`Mechanism.assemble <h4pin.mechanism.Mechanism.assemble>`."""
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.floating)) or not (0 < tol < 1e300):
        raise ParameterError(f"tol: a finite tolerance > 0 (m, rad), got {tol!r:.60}")
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 1:
        raise ParameterError(f"iterations: an integer >= 1, got {iterations!r}")
    model = mech.model
    start = np.array(mech.reference) if q is None else mech.configuration(q)
    if motors is not None and fixed is not None:
        raise ParameterError("give motors= or fixed=, not both (motors holds the actuated joints)")
    held = joint_names(model, mech.actuated if fixed is None else fixed, "fixed")
    held = held + tuple(n for n in mech.beam_springs if n not in held)  # a beam's joints: rigid assembly
    if motors is not None:
        def from_neighbour(s: np.ndarray) -> np.ndarray:
            check_ranges(mech, s, held, "held")
            return close(mech, s, held, float(tol), int(iterations), newton_first=True)

        out, one = assemble_motors(mech, start, motors, from_neighbour)
        return out[0] if one else out
    check_ranges(mech, start, held, "held")
    try:
        return close(mech, start, held, float(tol), int(iterations))
    except UnassembledError:
        if fixed is not None or not held:
            raise
    out = close(mech, start, (), float(tol), int(iterations))
    moved = []
    for n in held:
        j = model.joints[model.getJointId(n)]
        moved.append(f"{n} {float(np.linalg.norm(pin.difference(model, start, out)[j.idx_v:j.idx_v + j.nv])):.3g}")
    warnings.warn(f"{mech.name}: the loops do not close with the motors where the start holds them; assembled "
                  f"with the motors free (moved by, rad or m: {', '.join(moved)})", MechanismWarning, stacklevel=3)
    return out


def check_ranges(mech: Any, q: np.ndarray, joints: Iterable[str], what: str) -> None:
    lo, hi = mech.ranges
    for n in joints:
        j = mech.model.joints[mech.model.getJointId(n)]
        sl = slice(j.idx_q, j.idx_q + j.nq)
        bad = (q[sl] < lo[sl] - 1e-12) | (q[sl] > hi[sl] + 1e-12)
        if np.any(bad):
            raise UnassembledError(f"{mech.name}: {what} joint {n!r} is at {q[sl][bad][0]:.6g}, outside its range "
                                   f"[{lo[sl][bad][0]:.6g}, {hi[sl][bad][0]:.6g}]")


def close(mech: Any, start: np.ndarray, held: Sequence[str], tol: float, iterations: int,
           newton_first: bool = False) -> np.ndarray:
    """Trust-region then Gauss-Newton with ``held`` fixed (:meth:`assemble`); ``newton_first``:
    Gauss-Newton's least-norm steps alone first (continuation from a neighbour: the nearest
    closed configuration, not the trust region's), the trust region only if they fail."""
    from scipy.optimize import least_squares

    model, d = mech.model, mech.data
    free = np.ones(model.nv, dtype=bool)
    for n in held:
        j = model.joints[model.getJointId(n)]
        free[j.idx_v:j.idx_v + j.nv] = False
    lo, hi = mech.ranges
    q0 = np.array(start)
    lower, upper = np.full(model.nv, -np.inf), np.full(model.nv, np.inf)
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nq == 1 and jm.nv == 1 and free[jm.idx_v] and np.isfinite(lo[jm.idx_q]):
            q0[jm.idx_q] = min(max(q0[jm.idx_q], lo[jm.idx_q]), hi[jm.idx_q])
            lower[jm.idx_v], upper[jm.idx_v] = lo[jm.idx_q] - q0[jm.idx_q], hi[jm.idx_q] - q0[jm.idx_q]
    pin.forwardKinematics(model, d, q0)
    scale = engine.length_scale(model, d)
    embed = np.eye(model.nv)[:, free]

    def at(x: np.ndarray) -> np.ndarray:
        return pin.integrate(model, q0, embed @ x)

    def residual(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[float, str]]:
        pin.computeJointJacobians(model, d, q)
        rows, res, worst = [], [], (0.0, "")
        for cm in mech.constraint_models:
            r, jac, err = closure_step(model, d, cm)
            w = np.ones(len(r))
            w[:3] = 1.0 / scale
            rows.append(jac * w[:, None])
            res.append(r * w)
            worst = max(worst, (err, cm.name))
        for c in mech.couplings:
            r, row = c.residual_row(model, q)
            rows.append(row[None])
            res.append(np.array([r]))
            worst = max(worst, (abs(r), f"coupling {c.joint1}"))
        return np.concatenate(res), np.vstack(rows), worst

    if not mech.constraint_models and not mech.couplings:
        return q0
    def newton_step(r: np.ndarray, jc: np.ndarray) -> np.ndarray:  # least-norm, the held joints fixed
        step = np.zeros(model.nv)
        step[free] = -np.linalg.lstsq(jc[:, free], r, rcond=None)[0]
        return step

    joints = [model.names[j] for j in range(1, model.njoints)]
    if newton_first and free.any():
        q = q0
        for _ in range(iterations):
            r, jc, worst = residual(q)
            if worst[0] <= 1e-3 * tol:  # Newton converges quadratically: a step more is all but free
                try:
                    check_ranges(mech, q, joints, "assembled:")
                    return q
                except UnassembledError:
                    break
            step = newton_step(r, jc)
            if not np.all(np.isfinite(step)) or np.linalg.norm(step) > 1.0:
                break
            q = pin.integrate(model, q, step)
    if free.any():
        last: dict[bytes, Any] = {}

        def both(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # least_squares asks fun, then jac, at one x
            key = x.tobytes()
            if key not in last:
                last.clear()
                r, jc, _ = residual(at(x))
                last[key] = (r, jc @ pin.dIntegrate(model, q0, embed @ x, pin.ARG1) @ embed)
            return last[key]

        def fun(x: np.ndarray) -> np.ndarray:
            return both(x)[0]

        def jac(x: np.ndarray) -> np.ndarray:
            return both(x)[1]

        x0 = np.zeros(int(free.sum()))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sol = least_squares(fun, x0, jac=jac, bounds=(lower[free], upper[free]), method="trf",
                                xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=max(iterations, 20) * 5)
        q = at(sol.x)
    else:
        q = q0
    worst = (math.inf, "")
    for _ in range(iterations):
        r, jc, worst = residual(q)
        if worst[0] <= tol:
            break
        if not free.any():
            break
        q = pin.integrate(model, q, newton_step(r, jc))
    else:
        worst = residual(q)[2]
    if not worst[0] <= tol:
        raise UnassembledError(f"{mech.name}: the loops do not close from this start: closure {worst[1]!r} is off "
                               f"by {worst[0]:.3e} (tolerance {tol:g}); start nearer, or hold other joints "
                               "(fixed=...)")
    check_ranges(mech, q, joints, "assembled:")
    return q


def closure_rows(mech: Any, model: Any, data: Any, q: np.ndarray, length: float = 1.0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(c (m,), A (m, nv))``: the closures' residuals (translations over ``length``) and the
    couplings', and their Jacobian, at q (Pinocchio's joint Jacobians computed in ``data`` at q)."""
    res, rows = [np.zeros(0)], [np.zeros((0, model.nv))]
    for cm in mech.constraint_models:
        r, jac, _ = closure_step(model, data, cm)
        w = np.ones(len(r))
        w[:3] = 1.0 / length
        res.append(r * w)
        rows.append(jac * w[:, None])
    for c in mech.couplings:
        r, row = c.residual_row(model, q)
        res.append(np.array([r]))
        rows.append(row[None])
    return np.concatenate(res), np.vstack(rows)


def closure_step(model: pin.Model, d: pin.Data, cm: Any) -> tuple[np.ndarray, np.ndarray, float]:
    """A closure's residual, its Jacobian (rows, nv) and its error: world position gap for a
    3-D closure; ``log6`` of the relative placement (frame 1's axes) for a 6-D one."""
    o1 = d.oMi[cm.joint1_id] * cm.joint1_placement
    o2 = d.oMi[cm.joint2_id] * cm.joint2_placement
    lwa = pin.LOCAL_WORLD_ALIGNED
    if cm.type == pin.ContactType.CONTACT_3D:
        j1 = np.reshape(pin.getFrameJacobian(model, d, cm.joint1_id, cm.joint1_placement, lwa), (6, model.nv))[:3]
        j2 = np.reshape(pin.getFrameJacobian(model, d, cm.joint2_id, cm.joint2_placement, lwa), (6, model.nv))[:3]
        r = o2.translation - o1.translation
        return r, j2 - j1, float(np.linalg.norm(r))
    rel = o1.inverse() * o2
    j1 = np.reshape(pin.getFrameJacobian(model, d, cm.joint1_id, cm.joint1_placement, pin.LOCAL), (6, model.nv))
    j2 = np.reshape(pin.getFrameJacobian(model, d, cm.joint2_id, cm.joint2_placement, pin.LOCAL), (6, model.nv))
    r = pin.log6(rel).vector
    jac = pin.Jlog6(rel) @ (j2 - rel.inverse().toActionMatrix() @ j1)
    return r, jac, float(max(np.linalg.norm(r[:3]), np.linalg.norm(r[3:])))






def motor_range(model: pin.Model, name: str) -> str:
    """The plausible range (:data:`h4pin.limits.RANGES`) of the position of the one-coordinate
    motor ``name``: ``"motor travel"`` (m) for a prismatic joint, ``"motor angle"`` (rad) else."""
    kind = model.joints[model.getJointId(name)].shortname()
    return "motor travel" if "Prismatic" in kind or kind.startswith("JointModelP") else "motor angle"


def assemble_motors(mech: Any, start: np.ndarray, motors: Any, close: Any) -> tuple[np.ndarray, bool]:
    """Configurations with the motors at ``motors`` ((n_act,) or (N, n_act), in
    ``mech.actuated`` order), each closed from the one before (continuation; the first from
    ``start``) by ``close(start)``; and whether one row was given."""
    model = mech.model
    idx = []
    for name in mech.actuated:
        j = model.joints[model.getJointId(name)]
        if j.nq != 1 or j.nv != 1:
            raise ParameterError(f"motors: motor joint {name!r} has {j.nq} coordinates; only one-coordinate motors "
                                 "can be set by value (use assemble(q, fixed=...))")
        idx.append(j.idx_q)
    rows = len(motors) if np.ndim(motors) == 2 else 1  # from the shape: nothing is copied before the estimate
    limits.check_size(f"{mech.name}: assembly at {limits.fmt_count(rows)} motor positions",
                      rows * 8 * (model.nq + 2 * len(idx)), rows / 200.0)
    m = real_array(motors, "motors", ParameterError, f"motor positions, real numbers of shape ({len(idx)},) or "
                   f"(N, {len(idx)})")
    one = m.ndim == 1
    m = np.atleast_2d(m)
    if m.ndim != 2 or m.shape[1] != len(idx) or len(m) == 0:
        raise ParameterError(f"motors: shape ({len(idx)},) or (N, {len(idx)}) (the motors {list(mech.actuated)}), "
                             f"got {np.shape(motors)}")
    bad = np.flatnonzero(~np.all(np.isfinite(m), axis=1))
    if bad.size:
        raise ParameterError(f"motors[{bad[0]}]: not finite ({m[bad[0]].tolist()})")
    for k, name in enumerate(mech.actuated):
        limits.check_range(f"motors: {name!r}", m[:, k], motor_range(model, name))
    out = np.zeros((len(m), model.nq))
    q = np.array(start)
    for i, row in enumerate(m):
        q[idx] = row
        try:
            q = close(q)
        except H4Error as exc:
            raise located(exc, None if one else f"motors[{i}] = {row.tolist()}") from None
        out[i] = q
    return out, one
