# SPDX-License-Identifier: Apache-2.0
"""Eq. 30 of Company, Pierrot and Fauroux (ICRA 2005): the numpy reference, with its four terms.

``K = M1^-1 M2 (M3 C_c J^T R + M3 C_b J^T R + M4 C_t Jb^-1 + M5 C_l Jb^-1)`` (eq. 30), written
on the products the paper's sparse matrices reduce to (:func:`h4pin.stiffness.matrices.products`):
``H = M2 M3`` (8, 4), ``N = M2 M4`` (8, 8, block-diagonal per leg) and ``M2 M5 = diag(l)``, with
``Jb^-1 = diag(l) M1^-T`` (eq. 16) and, per spring family, the diagonal compliances C (one per
actuator, forearm and bar; the print has one scalar each).

* ``model="paper"``: eq. 30 as printed (errata 1-3 fixed): ``J^T R`` with J the rows x, y, z,
  theta of ``M1^-1 M2 M3`` (eq. 8) and R of eq. 30.
* ``model="consistent"``: erratum 4 fixed too, ``J^T R`` replaced by ``(M1^-1 M2 M3)^T``: K is
  then symmetric and equals the Newton-Euler statics route (:mod:`h4pin.checks.statics`).

Every array may carry leading batch axes (poses, or robots x poses): the same function serves a
batch of poses of one robot and the tolerance study's robots x poses. The compiled pipeline
(:mod:`h4pin.stiffness.pipeline`) computes the same sums per pose; tests keep every backend equal
to this reference.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

TERMS = ("control", "bending", "torsion", "tension")
MODELS = ("paper", "consistent")
#: Rows of M1^-1 M2 M3 that make J of eq. 8 (x, y, z, theta): R of eq. 30 selects them.
J_ROWS = (0, 1, 2, 5)


class Raw(NamedTuple):
    """What a backend returns for N finite poses (eq. 30 only, SI): ``matrix`` (N, 8, 8),
    ``terms`` (N, 4, 8, 8) in :data:`TERMS` order or None, ``q`` (N, 4), ``condition`` (N,),
    ``status`` (N,) int8; rows whose status is not 0 are NaN."""

    matrix: np.ndarray
    terms: np.ndarray | None
    q: np.ndarray
    condition: np.ndarray
    status: np.ndarray


def inverse(m1: np.ndarray) -> np.ndarray:
    """M1^-1 (..., 8, 8); a singular M1 gives NaN (never an exception)."""
    with np.errstate(all="ignore"):
        try:
            return np.linalg.inv(m1)
        except np.linalg.LinAlgError:
            out = np.full_like(m1, np.nan)
            flat, dest = m1.reshape(-1, 8, 8), out.reshape(-1, 8, 8)
            for n, m in enumerate(flat):
                try:
                    dest[n] = np.linalg.inv(m)
                except np.linalg.LinAlgError:
                    pass
            return out


def condition(m1: np.ndarray, inv: np.ndarray, l: np.ndarray) -> np.ndarray:
    """1-norm condition number of the scaled M1 (..., batched): rows over the bar lengths l
    (unit w_ij), the five rotation columns over the mean bar length, so that it does not depend
    on units. Non-finite results are ``inf`` (:data:`h4pin.verdicts.SINGULAR_COND`)."""
    with np.errstate(all="ignore"):
        L = np.mean(l, axis=-1)[..., None]
        col = np.concatenate([np.ones((*L.shape[:-1], 3)), np.repeat(1 / L, 5, axis=-1)], axis=-1)
        ms = m1 / l[..., :, None] * col[..., None, :]
        ims = inv / col[..., :, None] * l[..., None, :]
        cond = np.abs(ms).sum(-2).max(-1) * np.abs(ims).sum(-2).max(-1)
    return np.where(np.isfinite(cond), cond, np.inf)


def terms(inv: np.ndarray, H: np.ndarray, N: np.ndarray, l: np.ndarray, comp: dict[str, np.ndarray],
          model: str) -> dict[str, np.ndarray]:
    """The four terms of eq. 30, each (..., 8, 8), SI.

    Args:
        inv: M1^-1 (..., 8, 8).
        H: M2 M3 (..., 8, 4); N: M2 M4 (..., 8, 8); l: bar lengths (..., 8) (M2 M5 = diag(l)).
        comp: spring compliances (:meth:`h4pin.H4Geometry.compliances`): ``control``,
            ``bending``, ``torsion`` (..., 4) and ``tension`` (..., 8); leading axes broadcast
            (one robot for all poses, or one per robot).
        model: ``"paper"`` or ``"consistent"`` (module docstring).
    """
    g3 = inv @ H  # M1^-1 M2 M3 (..., 8, 4)
    if model == "paper":
        load = np.zeros((*g3.shape[:-2], 4, 8))
        load[..., list(J_ROWS)] = np.swapaxes(g3[..., list(J_ROWS), :], -1, -2)
    else:
        load = np.swapaxes(g3, -1, -2)
    jb_inv = l[..., :, None] * np.swapaxes(inv, -1, -2)
    c_tors = np.repeat(np.asarray(comp["torsion"]), 2, axis=-1)
    return {
        "control": (g3 * np.asarray(comp["control"])[..., None, :]) @ load,
        "bending": (g3 * np.asarray(comp["bending"])[..., None, :]) @ load,
        "torsion": (inv @ (N * c_tors[..., None, :])) @ jb_inv,
        "tension": (inv * (l * np.asarray(comp["tension"]))[..., None, :]) @ jb_inv,
    }


def jacobian(inv: np.ndarray, H: np.ndarray) -> np.ndarray:
    """J of eq. 8 (..., 4, 4): the plate motion x, y, z, theta per actuator rotation,
    ``(M1^-1 M2 M3)[[0, 1, 2, 5]]`` (equals ``Jx^-1 Jq`` for an ideal robot)."""
    return (inv @ H)[..., list(J_ROWS), :]


__all__ = ["J_ROWS", "MODELS", "TERMS", "Raw", "condition", "inverse", "jacobian", "terms"]
