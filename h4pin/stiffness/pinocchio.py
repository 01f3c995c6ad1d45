# SPDX-License-Identifier: Apache-2.0
"""The Pinocchio path of eq. 30, the independent route of the compiled pipeline: M1 (eq. 6) and
the products of M2, M3, M4, M5 from Pinocchio's joint Jacobians at the assembled configuration
(:func:`h4pin.stiffness.matrices.from_kinematics`), then the numpy reference of eq. 30
(:mod:`h4pin.stiffness.eq30`).

Per pose: the verdict before M1 (the compiled pipeline's for an exact robot, else
:func:`h4pin.kinematics.closed_form.solve`: one verdict per pose on every path), the
configuration (:func:`h4pin.kinematics.pinocchio.assemble`), ``computeJointJacobians`` in the
calling thread's own ``pin.Data``, the paper's matrices, and the singular verdict from
Pinocchio's own M1. Nothing of the closed forms enters M1 or eq. 30 here.
"""

from __future__ import annotations

import math

import numpy as np

from h4pin.kinematics import closed_form as cf
from h4pin.kinematics import pinocchio as kin
from h4pin.stiffness import eq30
from h4pin.stiffness.elements import add_terms
from h4pin.stiffness.matrices import from_kinematics, products_of
from h4pin.verdicts import OK, SINGULAR, SINGULAR_COND, UNREACHABLE


def _verdicts(h4, x: np.ndarray, model: str) -> tuple[np.ndarray, np.ndarray, list[cf.PlateState] | cf.PlateState]:
    """Status (N,) (singular left to Pinocchio's M1), q (N, 4) and the assembled states of the poses."""
    g = h4.geometry
    from h4pin.stiffness import kernel

    if g.ideal and kernel.BATCH.ready:
        res = kernel.compliance_batch(kernel.for_geometry(g), x, model)
        status = np.where(res.status == SINGULAR, OK, res.status).astype(np.int8)
        return status, res.q, _rigid_states(x, res.q)
    sol = cf.solve(g, x)
    status = np.asarray(sol.status, dtype=np.int8).copy()
    return status, np.where((status == UNREACHABLE)[:, None], np.nan, sol.state.q), sol.state


def backend(h4, x: np.ndarray, model: str, terms: bool, elements=None):
    """The Pinocchio path as a backend of :func:`h4pin.compliance`, one pose at a time in the
    calling thread's ``pin.Data`` (:class:`h4pin.stiffness.eq30.Raw`), with the terms of
    ``elements`` by the statics route (:func:`h4pin.stiffness.elements.add_terms`)."""
    n = len(x)
    status, q, states = _verdicts(h4, x, model)
    cond, matrix = np.full(n, np.nan), np.full((n, 8, 8), np.nan)
    out = np.full((n, 4, 8, 8), np.nan) if terms else None
    comp, d = h4.geometry.compliances(), h4.data
    for k in np.flatnonzero(status == OK):
        st = states[k] if isinstance(states, list) else cf.PlateState(*(a[k] for a in states))
        m1, H, N, l = products_of(from_kinematics(kin.kinematics(h4, x[k], d, st)))
        inv = eq30.inverse(m1)
        cond[k] = eq30.condition(m1, inv, l)
        if not cond[k] < SINGULAR_COND:
            status[k] = SINGULAR
            continue
        part = eq30.terms(inv, H, N, l, comp, model)
        matrix[k] = sum(part.values())
        if out is not None:
            out[k] = [part[t] for t in eq30.TERMS]
    return add_terms(h4.geometry, x, eq30.Raw(matrix, out, q, cond, status), elements)


def _rigid_states(x: np.ndarray, q: np.ndarray) -> list[cf.PlateState]:
    """:func:`h4pin.kinematics.closed_form.rigid_state` pose by pose (cheaper for a few poses)."""
    out = []
    for xk, qk in zip(x, q, strict=True):
        c, s = math.cos(xk[3]), math.sin(xk[3])
        out.append(cf.PlateState(qk, xk[:3], np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]),
                                 np.array([-xk[3], -xk[3]])))
    return out


__all__ = ["backend"]
