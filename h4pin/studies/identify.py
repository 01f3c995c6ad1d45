# SPDX-License-Identifier: Apache-2.0
"""Identification of the unstated quantities against Table II, by bounded least squares.

Eq. 30 with the stated data does not reproduce Table II (:mod:`h4pin.studies.gap`). This module fits the
quantities the paper does not give or may not know well, within physically plausible bounds
(:data:`PARAMETERS`), to the measured table (or to the computed one), with
h4pin's one fitting engine (:mod:`h4pin.mechanism.fitting`: :func:`scipy.optimize.least_squares`,
``trf``, bounds, several starts; the calibration of any mechanism uses it too), and reports what
the data can tell:

* residual per entry against the noise (``sigma``) estimated from the table's asymmetry
  (:func:`h4pin.studies.gap.noise_from_asymmetry`; for the computed table, its rounding: 1/sqrt(12));
* identifiability: SVD of the Jacobian of the residuals (in units of sigma) with respect to the
  parameters scaled by their plausible range; condition number; the combinations (right singular
  vectors) and the standard deviation of each, ``1 / s_k`` in scaled units.

The model of a measurement: the compliance at the point p where the dial indicators touch, for a
force at the point p' where it is applied (both fixed to the central bar,
:meth:`h4pin.stiffness.api.Compliance.at`), of the robot built with ``load(H4Params(...))``
where the revolute joints C_k are moved, the half-width changed, the tilt (torsion) compliance
scaled by ``tilt`` (I0 / tilt) and the axial compliance (actuators and forearm bending) by
``axial`` (kc / axial, E / axial). The terms of eq. 30 are linear in these two scales, so the
robot is rebuilt only when the geometry changes.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import numpy as np

from h4pin.description.params import H4Params
from h4pin.errors import ConvergenceError
from h4pin.kinematics.closed_form import CENTRE_Q
from h4pin.mechanism import fitting
from h4pin.robot import load
from h4pin.stiffness.api import Compliance, compliance
from h4pin.studies import gap


class Parameter(NamedTuple):
    """An identified quantity: its default (the stated or documented value), bounds and why."""

    unit: str
    default: float
    lower: float
    upper: float
    why: str


_MM = 1e-3
#: The quantities fitted, SI, with their plausible bounds.
PARAMETERS: dict[str, Parameter] = {
    "p_x": Parameter("m", 0.0, -0.1, 0.1, "dial indicator point p, central-bar frame: within 0.1 m of D "
                                          "(the plate is 120 mm x 120 mm; a fixture can reach a bit beyond)"),
    "p_y": Parameter("m", 0.0, -0.1, 0.1, "as p_x"),
    "p_z": Parameter("m", 0.0, -0.1, 0.1, "as p_x (a tool or a measuring block below or above D)"),
    "f_x": Parameter("m", 0.0, -0.1, 0.1, "point p' where the force is applied, same bounds as p"),
    "f_y": Parameter("m", 0.0, -0.1, 0.1, "as f_x"),
    "f_z": Parameter("m", 0.0, -0.1, 0.1, "as f_x"),
    "ck_dx": Parameter("m", 0.0, -50 * _MM, 50 * _MM, "revolute joints C_k along the lateral bars: the joint is "
                                                    "on the bar, between its ball joints (x = +-60 mm)"),
    "ck_dy": Parameter("m", 0.0, -20 * _MM, 20 * _MM, "C_k across the lateral bars (|y| grows): a bearing "
                                                    "housing offset, not more than the bar's own size"),
    "half_width": Parameter("m", 40 * _MM, 15 * _MM, 54 * _MM, "parallelogram half-width h: above 55 mm the ball "
                                                             "joints of legs 1 and 4 collide (5 mm balls)"),
    "tilt": Parameter("", 1.0, 0.5, 10.0, "factor on the forearm torsion compliance (parallelogram tilt): I0 = 2 I "
                                          "is a solid round section; an open or slotted section, the clamps and the "
                                          "ball-joint pins can make the tilt several times softer"),
    "axial": Parameter("", 1.0, 0.5, 2.0, "factor on the actuator and forearm-bending compliances (kc, E): the "
                                          "stressed fraction 2/3 gives ~0.7, gearbox/coupling play up to ~2"),
}
#: Parameters of each fit: the measured table (where the force is applied and the dial
#: indicators touch is not stated) and the computed one (the paper computes at D).
MEASURED_FIT = tuple(PARAMETERS)
COMPUTED_FIT = ("ck_dx", "ck_dy", "half_width", "tilt", "axial")
ONE_POINT_FIT = ("p_x", "p_y", "p_z", *COMPUTED_FIT)
#: Noise of the computed table: uniform rounding to 1 um/N.
ROUNDING_SIGMA = 1e-6 / np.sqrt(12.0)


def robot_params(values: dict[str, float], base: H4Params | None = None) -> H4Params:
    """H4Params with the identified robot quantities (C_k, half-width, tilt, axial) applied to
    ``base`` (default: the prototype); the measurement points are not robot data."""
    base = base or H4Params()
    v = {k: p.default for k, p in PARAMETERS.items()} | dict(values)
    dc = gap.moved_joints(base, v["ck_dx"], v["ck_dy"]).DC
    return base.replace(DC=dc, half_width=v["half_width"], I0=base.I0 / v["tilt"], kc=base.kc / v["axial"],
                        E=base.E / v["axial"])


@functools.lru_cache(maxsize=256)
def _terms(ck_dx: float, ck_dy: float, half_width: float) -> tuple[Compliance, dict[str, np.ndarray]]:
    base = H4Params()
    h4 = load(base.replace(DC=gap.moved_joints(base, ck_dx, ck_dy).DC, half_width=half_width))
    res = compliance(h4, h4.forward_geometry(CENTRE_Q), "consistent")
    return res, res.terms


def table(values: dict[str, float]) -> np.ndarray:
    """The modelled Table II (3, 3), m/N (rows: displacement x, y, z at p; columns: force along
    x, y, z at p') for the quantities ``values`` (missing ones at their defaults)."""
    v = {k: p.default for k, p in PARAMETERS.items()} | dict(values)
    res, terms = _terms(float(v["ck_dx"]), float(v["ck_dy"]), float(v["half_width"]))
    matrix = v["axial"] * (terms["control"] + terms["bending"]) + v["tilt"] * terms["torsion"] + terms["tension"]
    scaled = dataclasses.replace(res, matrix=matrix)
    return scaled.at([v["p_x"], v["p_y"], v["p_z"]], [v["f_x"], v["f_y"], v["f_z"]])


class Combination(NamedTuple):
    """A direction in the scaled parameter space and how well the data fixes it."""

    singular_value: float  #: s_k of the scaled Jacobian
    vector: dict[str, float]  #: unit vector over the scaled parameters (value / plausible range)
    std_scaled: float  #: 1 / s_k: standard deviation along ``vector``, in units of the ranges


@dataclasses.dataclass(frozen=True)
class Fit:
    """Result of :func:`fit` (SI; tables are 3x3, rows displacement, columns force).

    Attributes:
        names: the fitted parameters, in order.
        values: all parameters (fitted and fixed), SI.
        target, model: the table fitted and the modelled one, m/N.
        sigma: noise per entry assumed, m/N.
        residual: (3, 3) (model - target) / sigma.
        at_bound: names of the parameters that ended on a bound.
        singular_values: of the scaled Jacobian (descending); condition = s_max / s_min.
        combinations: right singular vectors with their standard deviation.
        std: per-parameter standard deviation (SI) from the pseudo-inverse restricted to the
            identifiable combinations (``std_scaled < identifiable``); NaN if a parameter is
            mostly in unidentifiable directions.
        cost: 0.5 * sum(residual^2).
        bounds: (lower, upper) of each fitted parameter, SI.
    """

    names: tuple[str, ...]
    values: dict[str, float]
    target: np.ndarray
    model: np.ndarray
    sigma: float
    residual: np.ndarray
    at_bound: tuple[str, ...]
    singular_values: np.ndarray
    combinations: list[Combination]
    std: dict[str, float]
    cost: float
    bounds: dict[str, tuple[float, float]]

    @property
    def condition(self) -> float:
        """Condition number of the scaled Jacobian (inf if rank-deficient)."""
        s = self.singular_values
        return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def _ranges(names: tuple[str, ...]) -> np.ndarray:
    return np.array([PARAMETERS[n].upper - PARAMETERS[n].lower for n in names])


def _values(names: tuple[str, ...], x: np.ndarray, fixed: dict[str, float], same_point: bool) -> dict[str, float]:
    v = {k: p.default for k, p in PARAMETERS.items()} | fixed | dict(zip(names, map(float, x), strict=True))
    if same_point:
        v |= {"f_x": v["p_x"], "f_y": v["p_y"], "f_z": v["p_z"]}
    return v


def _residual_fn(names: tuple[str, ...], target: np.ndarray, sigma: float, fixed: dict[str, float],
                 same_point: bool = False):
    def fn(x: np.ndarray) -> np.ndarray:
        return ((table(_values(names, x, fixed, same_point)) - target) / sigma).ravel()
    return fn


def fit(target: np.ndarray = gap.MEASURED, names: tuple[str, ...] = MEASURED_FIT, sigma: float | None = None,
        starts: int = 6, seed: int = 0, identifiable: float = 0.25, fixed: dict[str, float] | None = None,
        same_point: bool = False, bounds: dict[str, tuple[float, float]] | None = None,
        start: dict[str, float] | None = None) -> Fit:
    """Bounded least squares of ``names`` to ``target`` (3, 3) m/N.

    Args:
        target: the table to fit, m/N (default: the paper's measured Table II).
        names: the parameters fitted (others at their defaults or ``fixed``).
        sigma: noise per entry, m/N (default: :func:`h4pin.studies.gap.noise_from_asymmetry` of target,
            or :data:`ROUNDING_SIGMA` when the target has no asymmetry).
        starts: ``start`` (default: the defaults) plus ``starts - 1`` seeded random points within
            the bounds; the best local solution is kept (the offsets make the problem non-convex).
        identifiable: a combination is called identifiable when its standard deviation is below
            this fraction of the parameters' plausible ranges.
        fixed: values of parameters not fitted (default: :data:`PARAMETERS` defaults).
        same_point: the force is applied where the displacement is measured (p' = p; give only
            p_x, p_y, p_z in ``names``).
        bounds: (lower, upper) replacing the plausible bounds of some parameters, to see what the
            data asks for beyond them.
        start: the first starting point (missing parameters at their defaults).

    Raises:
        ConvergenceError: every start failed (a start that hits ``max_nfev`` still counts: the
            best cost is kept).
    """
    fixed = dict(fixed or {})
    if sigma is None:
        sigma, _ = gap.noise_from_asymmetry(target)
        sigma = sigma if sigma > 0 else ROUNDING_SIGMA
    limits = {n: (p.lower, p.upper) for n, p in PARAMETERS.items()} | dict(bounds or {})
    lower = np.array([limits[n][0] for n in names])
    upper = np.array([limits[n][1] for n in names])
    first = {n: p.default for n, p in PARAMETERS.items()} | fixed | dict(start or {})
    x0 = np.clip([first[n] for n in names], lower, upper)
    rng = np.random.default_rng(seed)
    guesses = [x0] + [lower + rng.uniform(0.05, 0.95, len(names)) * (upper - lower) for _ in range(starts - 1)]
    fn = _residual_fn(names, target, sigma, fixed, same_point)
    try:
        best = fitting.solve(fn, guesses, lower=lower, upper=upper, scale=upper - lower, diff_step=1e-6, max_nfev=300)
    except ConvergenceError as exc:
        raise ConvergenceError(f"identification: {exc}") from None
    return _report(best.x, names, target, sigma, fixed, lower, upper, identifiable, same_point)


def _report(x: np.ndarray, names: tuple[str, ...], target: np.ndarray, sigma: float, fixed: dict[str, float],
            lower: np.ndarray, upper: np.ndarray, identifiable: float, same_point: bool) -> Fit:
    fn = _residual_fn(names, target, sigma, fixed, same_point)
    ranges = _ranges(names)
    h = 1e-6 * ranges
    jac = np.column_stack([(fn(x + hi * e) - fn(x - hi * e)) / (2 * hi) for hi, e in zip(h, np.eye(len(x)),
                                                                                          strict=True)])
    s, vt = fitting.combinations(jac, ranges)  # d residual / d (x / range)
    combos = [Combination(float(sk), dict(zip(names, map(float, v), strict=True)),
                          float(1 / sk) if sk > 0 else float("inf")) for sk, v in zip(s, vt, strict=True)]
    keep = np.array([c.std_scaled < identifiable for c in combos])
    std = {}
    for n_i, name in enumerate(names):
        weight_lost = float(np.sum(vt[~keep, n_i] ** 2))
        var = float(np.sum((vt[keep, n_i] ** 2) / s[keep] ** 2))
        std[name] = float(np.sqrt(var) * ranges[n_i]) if weight_lost < 0.1 else float("nan")
    values = _values(names, x, fixed, same_point)
    model = table(values)
    res = (model - target) / sigma
    tol = 1e-6 * (upper - lower)
    bound = tuple(n for n, xi, lo, hi, t in zip(names, x, lower, upper, tol, strict=True) if xi - lo < t or hi - xi < t)
    return Fit(tuple(names), values, np.asarray(target), model, float(sigma), res, bound, s, combos, std,
               0.5 * float(np.sum(res**2)), {n: (float(a), float(b)) for n, a, b in zip(names, lower, upper,
                                                                                         strict=True)})


#: Candidate parameter sets for the measured table's symmetric part, by number of parameters: the
#: measuring point alone, with one or both spring-shape factors (the tilt and axial factors act
#: linearly on the two shapes of eq. 30), and the saturated set behind the ``measured_match``
#: variant (8 parameters for 6 numbers).
CANDIDATES: dict[str, tuple[str, ...]] = {
    "point": ("p_x", "p_y", "p_z"),
    "point+tilt": ("p_x", "p_y", "p_z", "tilt"),
    "point+axial": ("p_x", "p_y", "p_z", "axial"),
    "point_xz+tilt+axial": ("p_x", "p_z", "tilt", "axial"),
    "point+tilt+axial": ("p_x", "p_y", "p_z", "tilt", "axial"),
    "saturated": ONE_POINT_FIT,
}
#: The six numbers of a symmetric table: xx, yy, zz, xy, xz, yz.
SYMMETRIC_ENTRIES = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def noise_from_antisymmetry(table: np.ndarray = gap.MEASURED) -> tuple[float, int]:
    """Noise per entry (m/N) and its degrees of freedom from the antisymmetric part alone: with
    a symmetric truth (Maxwell-Betti, a one-point model) and independent noise sigma per entry,
    ``a_ij - a_ji ~ N(0, 2 sigma^2)``, so ``sigma^2 = sum_{i<j} (a_ij - a_ji)^2 / (2 * 3)`` with 3
    degrees of freedom. It uses none of the numbers the fit of the symmetric part uses."""
    t = np.asarray(table, dtype=float)
    d = np.array([t[i, j] - t[j, i] for i, j in ((0, 1), (0, 2), (1, 2))])
    return float(np.sqrt(np.sum(d**2) / 6.0)), 3


def symmetric_data(table: np.ndarray = gap.MEASURED) -> tuple[np.ndarray, np.ndarray]:
    """The six numbers of the symmetric part of ``table`` (:data:`SYMMETRIC_ENTRIES`) and their
    noise (m/N): sigma on the diagonal, sigma / sqrt(2) off it (the mean of two entries)."""
    t = np.asarray(table, dtype=float)
    sym = 0.5 * (t + t.T)
    sigma, _ = noise_from_antisymmetry(t)
    return (np.array([sym[i, j] for i, j in SYMMETRIC_ENTRIES]),
            np.array([sigma] * 3 + [sigma / np.sqrt(2.0)] * 3))


class Selection(NamedTuple):
    """One candidate of :func:`select`: a fit of the six symmetric numbers of the measured table.

    ``k`` parameters, ``dof = 6 - k`` (negative: saturated, no test possible), ``chi2`` (sum of
    squared residuals in their noise), ``aic = chi2 + 2 k`` (Akaike; Gaussian noise of known
    sigma), ``loo`` (6,): each entry predicted by the fit of the other five, as
    (prediction - measured) / noise, ``values`` the fitted parameters (SI) and ``at_bound`` those
    that ended on a plausible bound."""

    name: str
    names: tuple[str, ...]
    k: int
    dof: int
    chi2: float
    aic: float
    loo: np.ndarray
    values: dict[str, float]
    at_bound: tuple[str, ...]


def _symmetric_fit(names: tuple[str, ...], data: np.ndarray, noise: np.ndarray, mask: np.ndarray, starts: int,
                   seed: int) -> tuple[np.ndarray, float]:
    lower = np.array([PARAMETERS[n].lower for n in names])
    upper = np.array([PARAMETERS[n].upper for n in names])

    def fn(x: np.ndarray) -> np.ndarray:
        t = table(_values(names, x, {}, True))
        sym = np.array([0.5 * (t[i, j] + t[j, i]) for i, j in SYMMETRIC_ENTRIES])
        return ((sym - data) / noise)[mask]

    rng = np.random.default_rng(seed)
    x0 = np.clip([PARAMETERS[n].default for n in names], lower, upper)
    guesses = [x0] + [lower + rng.uniform(0.05, 0.95, len(names)) * (upper - lower) for _ in range(starts - 1)]
    best = fitting.solve(fn, guesses, lower=lower, upper=upper, scale=upper - lower, diff_step=1e-6, max_nfev=300)
    return best.x, 2.0 * best.cost


def select(candidates: dict[str, tuple[str, ...]] | None = None, target: np.ndarray = gap.MEASURED,
           starts: int = 6, loo_starts: int = 3, seed: int = 0) -> list[Selection]:
    """Fit each candidate parameter set to the six symmetric numbers of ``target`` with the noise
    of its antisymmetric part (:func:`noise_from_antisymmetry`), and report degrees of freedom,
    chi^2, AIC and leave-one-out predictions (:class:`Selection`), sorted by AIC."""
    data, noise = symmetric_data(target)
    full = np.ones(6, dtype=bool)
    out = []
    for name, names in (candidates or CANDIDATES).items():
        x, chi2 = _symmetric_fit(names, data, noise, full, starts, seed)
        loo = np.empty(6)
        for e in range(6):
            mask = full.copy()
            mask[e] = False
            xe, _ = _symmetric_fit(names, data, noise, mask, loo_starts, seed)
            t = table(_values(names, xe, {}, True))
            i, j = SYMMETRIC_ENTRIES[e]
            loo[e] = (0.5 * (t[i, j] + t[j, i]) - data[e]) / noise[e]
        lower = np.array([PARAMETERS[n].lower for n in names])
        upper = np.array([PARAMETERS[n].upper for n in names])
        tol = 1e-6 * (upper - lower)
        bound = tuple(n for n, xi, lo, hi, t_ in zip(names, x, lower, upper, tol, strict=True)
                      if xi - lo < t_ or hi - xi < t_)
        k = len(names)
        out.append(Selection(name, names, k, 6 - k, chi2, chi2 + 2 * k, loo,
                             dict(zip(names, map(float, x), strict=True)), bound))
    return sorted(out, key=lambda s: s.aic)


def fit_measured_one_point(starts: int = 6) -> Fit:
    """The fit behind the ``measured_match`` variant: the measured Table II, force applied where
    the displacement is measured (p' = p), robot quantities C_k, h, tilt, axial
    (:data:`ONE_POINT_FIT`). Saturated: 8 parameters for the 6 numbers a one-point model can
    explain (the table's symmetric part), so it matches them whatever the noise; it identifies
    nothing by itself (:func:`select` compares it with the smaller sets)."""
    return fit(gap.MEASURED, ONE_POINT_FIT, starts=starts, same_point=True)


#: Result of :func:`fit_measured_one_point` (run by ``scripts/identify.py``), rounded to 0.1 mm
#: and 0.01; ``tests/test_identify.py`` checks that the fit still lands here. Two of them sit on
#: a bound (ck_dy, axial): the measured table asks for more than the plausible ranges give.
FITTED = {"p_x": 24.7 * _MM, "p_y": 5.9 * _MM, "p_z": 30.7 * _MM, "ck_dx": 15.6 * _MM, "ck_dy": -20.0 * _MM,
          "half_width": 43.8 * _MM, "tilt": 6.51, "axial": 0.50}
#: Rounding of :data:`FITTED`, per parameter.
FITTED_ROUNDING = {k: (0.05 * _MM if PARAMETERS[k].unit == "m" else 0.005) for k in FITTED}


def fitted_values() -> dict[str, float]:
    """All quantities of the ``measured_match`` variant (:data:`FITTED`, the load point p' = p)."""
    v = {k: p.default for k, p in PARAMETERS.items()} | FITTED
    return v | {"f_x": v["p_x"], "f_y": v["p_y"], "f_z": v["p_z"]}


def fitted_params(base: H4Params | None = None) -> H4Params:
    """The ``measured_match`` variant: the prototype with C_k, half-width, tilt (I0) and axial (kc, E)
    from the saturated fit of the measured Table II (:data:`FITTED`; 8 parameters for 6 numbers, so
    one robot of a family that matches it, not an identification). Never the default robot."""
    return robot_params(FITTED, base)


def fitted_point() -> np.ndarray:
    """Where the ``measured_match`` variant's Table II is taken (force and dial indicators), offset
    from D in the central-bar frame, m (3,)."""
    return np.array([FITTED["p_x"], FITTED["p_y"], FITTED["p_z"]])
