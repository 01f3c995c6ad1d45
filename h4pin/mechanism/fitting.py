# SPDX-License-Identifier: Apache-2.0
"""h4pin's one fitting engine: bounded, robust least squares from several starts, and what the
data can tell of the parameters (identifiability, covariance).

Every fit of the package goes through it: the calibration of any mechanism from measured tool
positions (:mod:`h4pin.mechanism.calibration`) and the H4's identification from its compliance
table (:mod:`h4pin.studies.identify`).

* :func:`solve`: :func:`scipy.optimize.least_squares` (trust region reflective, bounds, a robust
  ``loss`` as SciPy's) from each start, the best kept; a typed error when every start fails.
* :func:`combinations`: the SVD of a Jacobian in scaled units (each parameter over its scale: a
  prior sigma, a plausible range): singular values ``s_k`` and the parameter combinations ``v_k``
  (unit vectors). A combination's standard deviation, in scaled units, is ``1 / s_k`` (for
  residuals in units of their noise).
* :func:`split`: the identifiable combinations (``s_k >= tol * s_max`` and ``1/s_k`` below a
  fraction of the scale) and the others, which a fit holds at the prior.
* :func:`covariance`: ``(Jᵀ J)⁻¹`` on the identifiable subspace, back in the parameters' units.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from h4pin.errors import ConvergenceError

#: SciPy's robust losses.
LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")


@dataclasses.dataclass(frozen=True)
class Solution:
    """The best local solution of :func:`solve`: ``x``, ``cost`` (``0.5 Σ ρ(r²)``), the residuals
    ``fun`` and Jacobian ``jac`` there, SciPy's ``status`` and ``nfev`` summed over the starts."""

    x: np.ndarray
    cost: float
    fun: np.ndarray
    jac: np.ndarray
    status: int
    nfev: int
    message: str


def solve(fun: Callable[[np.ndarray], np.ndarray], starts: Sequence[np.ndarray], *,
          jac: Callable[[np.ndarray], np.ndarray] | str = "2-point", lower: Any = -np.inf, upper: Any = np.inf,
          scale: Any = 1.0, loss: str = "linear", f_scale: float = 1.0, diff_step: float | None = None,
          tol: float = 1e-10, max_nfev: int | None = None) -> Solution:
    """The best of :func:`scipy.optimize.least_squares` (``trf``) from each start.

    Raises:
        ParameterError: an unknown ``loss``. ConvergenceError: every start failed.
    """
    from h4pin.errors import ParameterError

    if loss not in LOSSES:
        raise ParameterError(f"loss: one of {', '.join(LOSSES)} (SciPy's), got {loss!r}")
    best, nfev, last = None, 0, ""
    for x0 in starts:
        try:
            sol = least_squares(fun, np.asarray(x0, float), jac=jac, bounds=(lower, upper), x_scale=scale,
                                method="trf", loss=loss, f_scale=f_scale, diff_step=diff_step, xtol=tol, ftol=tol,
                                gtol=tol, max_nfev=max_nfev)
        except (ValueError, np.linalg.LinAlgError) as exc:
            last = str(exc)
            continue
        nfev += sol.nfev
        last = sol.message
        if sol.status >= 0 and np.all(np.isfinite(sol.fun)) and (best is None or sol.cost < best.cost):
            best = sol
    if best is None:
        raise ConvergenceError(f"the fit failed from every start ({last})")
    return Solution(best.x, float(best.cost), best.fun, np.asarray(best.jac), int(best.status), nfev, best.message)


def combinations(jac: np.ndarray, scale: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(s (p,), vt (p, p))``: the singular values of ``jac * scale`` (columns: each parameter
    over its scale), padded with zeros to one per parameter, and the combinations (rows of vt)."""
    scaled = np.asarray(jac, float) * np.asarray(scale, float)
    p = scaled.shape[1]
    _, s, vt = np.linalg.svd(scaled, full_matrices=True)
    return np.r_[s, np.zeros(p - len(s))], vt


def split(s: np.ndarray, tol: float = 1e-8, std: float = np.inf) -> np.ndarray:
    """Which combinations the data identify: ``s_k > tol * s_max`` and a scaled standard
    deviation ``1 / s_k`` below ``std``."""
    top = float(s.max()) if s.size else 0.0
    return (s > tol * top) & (s > 0) & (1.0 / np.where(s > 0, s, 1.0) < std)


def covariance(s: np.ndarray, vt: np.ndarray, keep: np.ndarray, scale: Any) -> np.ndarray:
    """``(p, p)`` the parameters' covariance (their units) on the identifiable combinations
    ``keep``: ``V_k diag(1/s_k²) V_kᵀ``, scaled back."""
    v = vt[keep].T
    cov = (v / s[keep] ** 2) @ v.T
    sc = np.asarray(scale, float) * np.ones(vt.shape[1])
    return cov * sc[:, None] * sc[None, :]


def describe(v: np.ndarray, names: Sequence[str], top: int = 4) -> str:
    """A combination as text: its largest coefficients, ``0.71 offsets/knee - 0.71 geometry/knee/rz``."""
    order = np.argsort(-np.abs(v))[:top]
    parts = [f"{v[i]:+.2f} {names[i]}" for i in order if abs(v[i]) > 0.05]
    text = " ".join(parts).lstrip("+")
    return text.replace(" +", " + ").replace(" -", " - ")


__all__ = ["LOSSES", "Solution", "combinations", "covariance", "describe", "solve", "split"]
