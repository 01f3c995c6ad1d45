# SPDX-License-Identifier: Apache-2.0
"""The numpy backend of :func:`h4pin.compliance` (``method="closed_form"``): the reference.

Vectorised over the poses: the closed-form geometry (:func:`h4pin.kinematics.closed_form.solve`,
Newton for a robot whose parallelograms are not exact), the products of the paper's matrices
(:func:`h4pin.stiffness.matrices.products`) and eq. 30 (:func:`h4pin.stiffness.eq30.terms`).
Every other backend is tested against it.
"""

from __future__ import annotations

import numpy as np

from h4pin.kinematics import closed_form as cf
from h4pin.stiffness import eq30
from h4pin.stiffness.elements import add_terms
from h4pin.stiffness.eq30 import Raw
from h4pin.stiffness.matrices import products
from h4pin.verdicts import OK, SINGULAR, SINGULAR_COND, UNREACHABLE


def backend(h4, x: np.ndarray, model: str, terms: bool, elements=None) -> Raw:
    """Eq. 30 at poses x (N, 4) (finite) of robot ``h4`` (:class:`h4pin.stiffness.eq30.Raw`),
    with the terms of ``elements`` (:class:`h4pin.Elements` or None) by the statics route of
    :mod:`h4pin.stiffness.elements`."""
    g = h4.geometry
    n = len(x)
    sol = cf.solve(g, x)
    status = np.asarray(sol.status, dtype=np.int8).copy()
    q = np.where((status == UNREACHABLE)[:, None], np.nan, sol.state.q)
    cond = np.full(n, np.nan)
    matrix = np.full((n, 8, 8), np.nan)
    out = np.full((n, 4, 8, 8), np.nan) if terms else None
    ok = np.flatnonzero(status == OK)
    if ok.size:
        state = cf.PlateState(*(a[ok] for a in sol.state))
        m1, H, N, l = products(g, cf.points(g, state))
        inv = eq30.inverse(m1)
        c = eq30.condition(m1, inv, l)
        cond[ok] = c
        regular = c < SINGULAR_COND
        status[ok[~regular]] = SINGULAR
        sel = ok[regular]
        if sel.size:
            part = eq30.terms(inv[regular], H[regular], N[regular], l[regular], g.compliances(), model)
            matrix[sel] = sum(part.values())
            if out is not None:
                out[sel] = np.stack([part[t] for t in eq30.TERMS], axis=1)
    return add_terms(g, x, Raw(matrix, out, q, cond, status), elements)


__all__ = ["backend"]
