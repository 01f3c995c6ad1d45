# SPDX-License-Identifier: Apache-2.0
"""Why eq. 30 cannot reproduce Table II at the stated geometry: the two-shape analysis.

At q_i = 45 deg the translational block of K (Table II) is the sum of four terms (control,
bending, torsion, tension). Each term is a fixed 3x3 *shape* times its spring compliance:

* control and bending have the same shape (both load the forearm rotation about u_i: the legs'
  "axial" compliance, ``J J^T``), so kc and E I cannot be told apart;
* torsion (the parallelogram tilt) has another shape, and tension lies in the span of these two.

So, with the geometry fixed, every choice of spring constants gives a non-negative combination of
two shapes. This module computes the shapes, their span, the best non-negative combinations
against a target table (least squares with :func:`scipy.optimize.nnls`, and min-max misfit with
:func:`scipy.optimize.linprog`), the region of (C_k offset, tilt factor) in which the paper's
computed table is met within its rounding, the range of ratios the family can reach, and the
measurement noise implied by the asymmetry of the measured table. Everything is SI (m/N); the
printing script is ``scripts/gap_analysis.py`` and the write-up ``docs/gap.md``.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
from scipy.optimize import linprog, nnls
from tqdm import tqdm

from h4pin.description.params import H4Params
from h4pin.errors import ConvergenceError, H4Error
from h4pin.kinematics.closed_form import centre_pose
from h4pin.robot import H4, load
from h4pin.stiffness.api import TERMS, compliance
from h4pin.studies.paper import PAPER_COMPUTED, PAPER_MEASURED

#: The four non-zero entries of Table II at the centre (mirror symmetry zeroes the y couplings).
ENTRIES = {"xx": (0, 0), "yy": (1, 1), "zz": (2, 2), "xz": (0, 2)}
#: Table II is printed to 1 um/N: an entry within +-0.5 um/N of it is "within rounding".
ROUNDING = 0.5e-6
#: The paper's tables in SI (m/N); rows: displacement x, y, z, columns: force along x, y, z.
COMPUTED = PAPER_COMPUTED * 1e-6
MEASURED = PAPER_MEASURED * 1e-6
_US = 1e6  # internal scaling of the solvers (um/N), results are returned in SI


def entries(block: np.ndarray) -> np.ndarray:
    """The entries xx, yy, zz, xz (..., 4) of 3x3 blocks (..., 3, 3)."""
    return np.stack([block[..., a, b] for a, b in ENTRIES.values()], axis=-1)


def term_blocks(robot: H4 | H4Params | None = None, q: float = np.pi / 4) -> dict[str, np.ndarray]:
    """The translational block (3, 3) of each term of eq. 30 with every actuator at ``q`` (rad,
    default 45 deg, the paper's pose), m/N.

    ``robot``: a loaded robot, or parameters (built with ``load(params)``; default the
    prototype's). The translational block is the same in the ``paper`` and ``consistent`` models;
    the robot's optional elements are left out (eq. 30 alone).
    """
    h4 = robot if isinstance(robot, H4) else load(robot or H4Params())
    pose = centre_pose(h4) if q == np.pi / 4 else h4.forward_geometry(np.full(4, q))
    res = compliance(h4, pose, elements=False)
    return {t: res.terms[t][:3, :3].copy() for t in TERMS}


class Robustness(NamedTuple):
    """The gap's conclusions for one perturbed robot or pose (:func:`robustness`), SI."""

    name: str  #: what was changed
    yy_xx: tuple[float, float]  #: range of yy/xx any spring constants reach (paper computed: 0.525)
    zz_xx: tuple[float, float]  #: range of zz/xx (paper measured: 0.176)
    least_miss: float  #: least largest miss against the computed table over all springs, m/N
    meets: bool  #: least_miss within the table's rounding (the springs alone would close the gap)


#: The perturbations of :func:`robustness`: actuator zero offsets and each unstated length.
PERTURBATIONS = ("nominal", "q -3 deg", "q +3 deg", "half-width -5 %", "half-width +5 %", "C_k |y| -5 %",
                 "C_k |y| +5 %", "C_k z -5 %", "C_k z +5 %")


def _perturbed(name: str, base: H4Params) -> tuple[H4Params, float]:
    q = np.pi / 4
    if name.startswith("q "):
        q += np.deg2rad(float(name.split()[1]))
    elif name.startswith("half-width"):
        base = base.replace(half_width=base.half_width * (1 + float(name.split()[1]) / 100))
    elif name.startswith("C_k"):
        axis = 1 if "|y|" in name else 2
        dc = base.DC.copy()
        dc[axis] *= 1 + float(name.split()[2]) / 100
        base = base.replace(DC=dc)
    return base, q


def robustness(names: tuple[str, ...] = PERTURBATIONS, base: H4Params | None = None) -> list[Robustness]:
    """The conclusions of sections 1-2 of ``docs/gap.md`` under each perturbation: an actuator zero
    offset of +-3 deg (every actuator at 45 +- 3 deg instead of 45) and +-5 % on each length the
    paper does not state (the parallelogram half-width; the revolute joints C_k's abs(y) and z)."""
    base = base or H4Params()
    out = []
    for name in names:
        params, q = _perturbed(name, base)
        blocks = term_blocks(params, q)
        miss = minimax_combination(blocks).max_abs
        out.append(Robustness(name, ratio_range(blocks, "yy", "xx"), ratio_range(blocks, "zz", "xx"), miss,
                              miss <= ROUNDING))
    return out


def two_shapes(blocks: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The two shapes as blocks: ``axial`` = control + bending, ``tilt`` = torsion (m/N). Tension
    is left out: it is a non-negative combination of them (:func:`in_span`), so any combination
    of the four terms is one of these two."""
    return {"axial": blocks["control"] + blocks["bending"], "tilt": blocks["torsion"]}


def shapes(blocks: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each term's shape: its block divided by its xx entry (dimensionless)."""
    return {t: b / b[0, 0] for t, b in blocks.items()}


def span_singular_values(blocks: dict[str, np.ndarray]) -> np.ndarray:
    """Singular values of the stacked term blocks, each flattened and normalised to unit norm
    (4 values, descending). Two non-zero values: the terms span a plane of 3x3 tables."""
    m = np.stack([b.ravel() / np.linalg.norm(b) for b in blocks.values()])
    return np.linalg.svd(m, compute_uv=False)


def in_span(blocks: dict[str, np.ndarray], term: str = "tension", basis: tuple[str, str] = ("control", "torsion")
            ) -> tuple[np.ndarray, float]:
    """Coefficients (2,) expressing ``term`` in the ``basis`` terms (least squares), and the
    relative residual (0 when it lies in their span)."""
    a = np.stack([blocks[b].ravel() for b in basis], axis=1)
    y = blocks[term].ravel()
    coef = np.linalg.lstsq(a, y, rcond=None)[0]
    return coef, float(np.linalg.norm(a @ coef - y) / np.linalg.norm(y))


class Combination(NamedTuple):
    """A non-negative combination of the terms against a target (SI)."""

    factors: dict[str, float]  #: factor on each term's compliance (1 = the stated spring)
    fitted: np.ndarray  #: (4,) xx, yy, zz, xz of the combination, m/N
    misfit: np.ndarray  #: (4,) fitted - target, m/N
    rms: float  #: root mean square of misfit, m/N
    max_abs: float  #: largest abs(misfit), m/N


def _combination(blocks: dict[str, np.ndarray], factors: np.ndarray, target: np.ndarray) -> Combination:
    a = np.stack([entries(blocks[t]) for t in blocks], axis=1)
    fitted = a @ factors
    misfit = fitted - entries(target)
    return Combination(dict(zip(blocks, map(float, factors), strict=True)), fitted, misfit,
                       float(np.sqrt(np.mean(misfit**2))), float(np.max(np.abs(misfit))))


def best_combination(blocks: dict[str, np.ndarray], target: np.ndarray = COMPUTED) -> Combination:
    """Least-squares non-negative factors on the terms (``scipy.optimize.nnls``) for the four
    entries xx, yy, zz, xz of ``target`` (3, 3), m/N."""
    a = np.stack([entries(blocks[t]) for t in blocks], axis=1) * _US
    factors, _ = nnls(a, entries(target) * _US)
    return _combination(blocks, factors, target)


def minimax_combination(blocks: dict[str, np.ndarray], target: np.ndarray = COMPUTED) -> Combination:
    """Non-negative factors on the terms that minimise the largest abs(misfit) over xx, yy, zz, xz
    (a linear programme, ``scipy.optimize.linprog``). Its ``max_abs`` is the least misfit any
    choice of spring constants can reach at this geometry."""
    a = np.stack([entries(blocks[t]) for t in blocks], axis=1) * _US
    b = entries(target) * _US
    n = a.shape[1]
    ones = np.ones((len(b), 1))
    res = linprog(np.r_[np.zeros(n), 1.0], A_ub=np.block([[a, -ones], [-a, -ones]]), b_ub=np.r_[b, -b],
                  bounds=[(0, None)] * (n + 1), method="highs")
    if not res.success:
        raise ConvergenceError(f"min-max combination: linprog failed ({res.message})")
    return _combination(blocks, res.x[:n], target)


def ratio_range(blocks: dict[str, np.ndarray], num: str = "zz", den: str = "xx") -> tuple[float, float]:
    """Range (min, max) of the ratio of two entries over all non-negative combinations of the
    terms: a ratio of sums of positive-denominator terms lies between the terms' own ratios."""
    r = [entries(b)[list(ENTRIES).index(num)] / entries(b)[list(ENTRIES).index(den)] for b in blocks.values()]
    return float(min(r)), float(max(r))


def model_projection(table: np.ndarray) -> np.ndarray:
    """The table (3, 3) the model at D can produce closest to ``table`` (least squares): its
    symmetric part with the y couplings zeroed (Maxwell-Betti and the mirror symmetry about y = 0)."""
    t = np.asarray(table, dtype=float)
    proj = (t + t.T) / 2
    proj[[0, 1, 1, 2], [1, 0, 2, 1]] = 0.0
    return proj


def noise_from_asymmetry(table: np.ndarray = MEASURED) -> tuple[float, int]:
    """Measurement noise (standard deviation per entry, same unit as ``table``) and its degrees of
    freedom, from what the model at D cannot produce.

    At D the compliance of the mirror-symmetric robot is symmetric (Maxwell-Betti) with zero y
    couplings: a 4-parameter family (xx, yy, zz, xz). The residual of the least-squares
    projection of the 9 measured entries onto that family has 5 degrees of freedom, so
    ``sigma^2 = |residual|^2 / 5`` (independent errors of equal variance assumed). A tool or dial
    offset from D would also make the table asymmetric: then this over-estimates the noise.
    """
    t = np.asarray(table, dtype=float)
    dof = 9 - len(ENTRIES)
    return float(np.sqrt(np.sum((t - model_projection(t)) ** 2) / dof)), dof


def _dc(base: H4Params, dx: float, dy: float) -> np.ndarray:
    dc = base.DC.copy()
    dc[0] += dx
    dc[1] += np.array([-dy, dy])
    return dc


def moved_joints(base: H4Params, dx: float, dy: float) -> H4Params:
    """``base`` with both revolute joints C_k moved by dx along x (along the lateral bars) and
    outwards by dy (abs(y) of C_k grows by dy); mirror symmetry about y = 0 is kept."""
    return base.replace(DC=_dc(base, dx, dy))


def smallest_joint_offset(q: float = np.pi / 4, step: float = 2e-3, limit: float = 60e-3,
                          base: H4Params | None = None) -> tuple[float, float, float] | None:
    """The smallest move (dx, dy) of the revolute joints C_k (:func:`moved_joints`, on a grid of
    ``step``, nearest first, up to ``limit``) at which some non-negative spring factors meet the
    computed table within rounding, with every actuator at ``q``: (dx, dy, least miss) in m, m,
    m/N, or None. A lower bound of the offset the gap needs (every spring free)."""
    base = base or H4Params()
    n = int(round(limit / step))
    grid = [(i * step, j * step) for i in range(-n, n + 1) for j in range(-n, n + 1)
            if np.hypot(i, j) * step <= limit]
    for dx, dy in sorted(grid, key=lambda c: (np.hypot(*c), c)):
        try:
            miss = minimax_combination(term_blocks(moved_joints(base, dx, dy), q)).max_abs
        except H4Error:  # a move the robot cannot take (unreachable centre, interfering bars)
            continue
        if miss <= ROUNDING:
            return dx, dy, miss
    return None


@dataclasses.dataclass(frozen=True)
class FitRegion:
    """Where the paper's computed table is met within rounding (all four entries within
    :data:`ROUNDING`) by the stated control, bending and tension springs times a common axial
    factor ``a`` (kc and E I together), a tilt factor ``tau`` on torsion, and C_k moved by (dx, dy).

    Attributes:
        dx, dy: (nx,), (ny,) the C_k offsets swept, m.
        taus: (nt,) the tilt factors swept.
        feasible: (nx, ny, nt) bool, some axial factor meets the table within rounding.
        axial: (nx, ny, nt, 2) the interval [a_min, a_max] of such axial factors (NaN if none).
        stated_axial: (nx, ny, nt) bool, the stated springs (a = 1) meet it.
        zz_xx_min: (nx, ny) the least zz/xx any non-negative combination of the terms reaches.
    """

    dx: np.ndarray
    dy: np.ndarray
    taus: np.ndarray
    feasible: np.ndarray
    axial: np.ndarray
    stated_axial: np.ndarray
    zz_xx_min: np.ndarray


def axial_interval(blocks: dict[str, np.ndarray], tau: np.ndarray, target: np.ndarray = COMPUTED,
                   tol: float = ROUNDING) -> np.ndarray:
    """Interval (..., 2) of axial factors a >= 0 with ``|a (control + bending) + tau torsion +
    tension - target| <= tol`` in xx, yy, zz, xz (each entry is linear in a), NaN where empty."""
    x = entries(blocks["control"] + blocks["bending"])
    c = np.asarray(tau, dtype=float)[..., None] * entries(blocks["torsion"]) + entries(blocks["tension"])
    b = entries(target)
    lo = np.maximum(np.max((b - c - tol) / x, axis=-1), 0.0)
    hi = np.min((b - c + tol) / x, axis=-1)
    out = np.stack([lo, hi], axis=-1)
    out[lo > hi] = np.nan
    return out


def fit_region(dx: np.ndarray, dy: np.ndarray, taus: np.ndarray, base: H4Params | None = None,
               target: np.ndarray = COMPUTED, tol: float = ROUNDING, progress: bool = False) -> FitRegion:
    """Sweep C_k offsets ``dx`` x ``dy`` (m) and tilt factors ``taus`` (see :class:`FitRegion`);
    ``progress`` shows a tqdm bar over the robots built."""
    base = base or H4Params()
    dx, dy, taus = (np.asarray(v, dtype=float) for v in (dx, dy, taus))
    axial = np.full((len(dx), len(dy), len(taus), 2), np.nan)
    stated = np.zeros((len(dx), len(dy), len(taus)), dtype=bool)
    zz_xx = np.empty((len(dx), len(dy)))
    cells = [(i, j) for i in range(len(dx)) for j in range(len(dy))]
    for i, j in tqdm(cells, desc="C_k sweep", unit="robot", disable=not progress):
        blocks = term_blocks(moved_joints(base, dx[i], dy[j]))
        axial[i, j] = axial_interval(blocks, taus, target, tol)
        stated[i, j] = (axial[i, j, :, 0] <= 1.0) & (axial[i, j, :, 1] >= 1.0)
        zz_xx[i, j] = ratio_range(blocks)[0]
    return FitRegion(dx, dy, taus, np.isfinite(axial[..., 0]), axial, stated, zz_xx)
