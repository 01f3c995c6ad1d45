# SPDX-License-Identifier: Apache-2.0
"""Tolerance study: Monte Carlo over manufacturing errors of an H4 (issue 9).

Each of N robots is the nominal :class:`h4pin.description.geometry.H4Geometry` with its arrays perturbed
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
  :func:`h4pin.kinematics.closed_form.forward_geometry`) and the plate tilt (rad, norm of the x, y rotation
  vector).

Everything is vectorised over robots and poses at once: the geometry arrays get a leading robot
axis (:class:`BatchGeometry`) and go through the same closed forms as one robot
(:mod:`h4pin.kinematics.closed_form`, :func:`h4pin.stiffness.matrices.products`,
:func:`h4pin.stiffness.eq30.terms`), which broadcast over it. The robot's optional elements
(:attr:`H4.elements <h4pin.H4>`) are added at their nominal value. ``tests/test_tolerance.py`` checks
single robots against :func:`h4pin.compliance` and :func:`h4pin.kinematics.closed_form.forward_geometry`.
"""

from __future__ import annotations

import dataclasses
import os
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

import numpy as np

from h4pin import limits
from h4pin.description.geometry import H4Geometry, spring_compliances
from h4pin.description.params import TOLERANCES
from h4pin.errors import ConvergenceError, ParameterError
from h4pin.kinematics import closed_form as cf
from h4pin.stiffness import eq30
from h4pin.stiffness.matrices import products

#: Kinds of manufacturing error, in the order they are drawn.
KINDS = ("forearm", "A0", "b", "P", "C0", "l", "mismatch")
#: Default sigmas (m), from :data:`h4pin.description.params.TOLERANCES`: forearm length as ``r``, ball
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
_CHUNK = 4096  # robot x pose pairs per vectorised block
#: Bytes the study holds per robot (its draws and its perturbed arrays, 156 float64, and their
#: temporaries) and per robot-pose pair (the (3, 3) compliance, the pose error, tilt, flag, and
#: the outputs and percentiles of the report): measured 4,065 bytes a robot at 8 poses over 20,000
#: robots, rounded up. Pairs a second: measured 3.65e4 on 2 cores, rounded down.
BYTES_PER_ROBOT, BYTES_PER_PAIR = 1600, 320
PAIRS_PER_S = 3e4
#: Largest sigma accepted (m): a tenth of the prototype's smallest length (its 35 mm half-width is
#: the shortest); machined tolerances are 0.05 to 0.1 mm.
MAX_SIGMA = 3.5e-3


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
        if v > MAX_SIGMA:
            raise ParameterError(f"sigma {name!r} = {v:g} m is not a manufacturing tolerance (at most {MAX_SIGMA:g} m: "
                                 "errors that large do not leave the robot assembled)")
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


def _solve_pairs(bg: BatchGeometry, q: np.ndarray, x: np.ndarray, free_q: bool,
                 jac0_inv: np.ndarray) -> tuple[cf.PlateState, np.ndarray, np.ndarray, np.ndarray]:
    """The closures of robot-pose pairs (flat): the chord method from the nominal Jacobian, then
    full Newton on the pairs it left unconverged (:func:`h4pin.kinematics.closed_form.newton`)."""
    start = cf.rigid_state(x, q)
    st, done, theta, tilt = cf.newton(bg, x, start, free_q, jac0_inv=jac0_inv, max_iter=8)
    bad = np.flatnonzero(~done)
    if bad.size:
        sub = bg.take(bad, pose_axis=False)
        st2, done2, theta2, tilt2 = cf.newton(sub, x[bad], cf.PlateState(*(a[bad] for a in start)), free_q)
        for a, a2 in zip((*st, theta, tilt), (*st2, theta2, tilt2), strict=True):
            a[bad] = a2
        done[bad] = done2
    return st, done, theta, tilt


def compliances(bg: BatchGeometry) -> dict[str, np.ndarray]:
    """Spring compliances of each robot (:meth:`h4pin.H4Geometry.compliances` with a robot axis):
    the forearm lengths r and bar lengths l are each robot's own."""
    r = np.linalg.norm(bg.A0.reshape(*bg.A0.shape[:-2], 4, 2, 3).mean(axis=-2) - bg.P, axis=-1)
    return spring_compliances(bg.springs, r, bg.l)


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
    from h4pin.kinematics.closed_form import centre_pose

    c = centre_pose(h4)
    steps = np.array([[0.03, 0, 0, 0], [-0.03, 0, 0, 0], [0, 0.03, 0, 0], [0, -0.03, 0, 0], [0, 0, 0.03, 0],
                      [0, 0, -0.03, 0], [0, 0, 0, 0.2]])
    return np.vstack([c, c + steps])


def check_size(n_robots: int, n_poses: int) -> None:
    """Refuse, before any draw, a study whose arrays do not fit in memory (:data:`BYTES_PER_ROBOT`,
    :data:`BYTES_PER_PAIR`; limit :func:`h4pin.limits.memory_limit`, ``H4PIN_MEMORY_LIMIT``); the
    message also gives the time it would take (:data:`PAIRS_PER_S`).

    Raises:
        h4pin.limits.TooLargeError: over the limit (a :class:`h4pin.ParameterError`).
    """
    need = n_robots * (BYTES_PER_ROBOT + n_poses * BYTES_PER_PAIR)
    limits.check_size(f"tolerance: {n_robots:,} robots x {n_poses:,} poses", need, n_robots * n_poses / PAIRS_PER_S,
                      "use fewer robots (--robots)")


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
        model: ``"paper"`` or ``"consistent"`` (:mod:`h4pin.stiffness.api`).
        progress: Show a tqdm progress bar.
        workers: Threads over chunks of robot-pose pairs (default: one per core); the result does
            not depend on it.

    Raises:
        ParameterError: a bad sigma, n_robots or model.
        PoseError (and subclasses): a pose the nominal robot cannot take.
    """
    from h4pin.stiffness.api import MODELS, compliance

    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}, got {model!r}")
    g: H4Geometry = h4.geometry
    x = default_poses(h4) if poses is None else cf.as_poses(poses, "poses")
    x = np.atleast_2d(x)
    check_size(limits.count(n_robots), len(x))
    nom = compliance(h4, x, model)  # raises the typed error of a bad pose
    # The robot's optional elements: their terms at the nominal geometry (manufacturing errors
    # change them only to second order), added to every robot's eq. 30.
    element_k = None if nom.elements is None else nom.matrix - compliance(h4, x, model, elements=False).matrix
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
    pts0 = cf.points(g, cf.rigid_state(x, q_nom))
    inv_free = np.linalg.inv(cf.newton_jacobian(g, pts0, True))
    inv_fwd = np.linalg.inv(cf.newton_jacobian(g, pts0, False))
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
        # Compliance at the pose: the robot's own inverse geometry (q and the tilt free); eq. 30
        # from the one numpy reference, with each robot's springs.
        st, ok1, _, _ = _solve_pairs(bg, qp, xp, True, inv_free[pi])
        m1, H, N, l = products(bg, cf.points(bg, st))
        kk = sum(eq30.terms(eq30.inverse(m1), H, N, l, compliances(bg), model).values())
        if element_k is not None:
            kk = kk + element_k[pi]
        # Pose error at the commanded nominal q (forward geometry).
        fw, ok2, theta, fw_tilt = _solve_pairs(bg, qp, xp, False, inv_fwd[pi])
        ok = ok1 & ok2
        e = np.concatenate([fw.D - xp[:, :3], (theta - xp[:, 3])[..., None]], axis=-1)
        comp[ri, pi] = np.where(ok[..., None, None], kk[..., :3, :3], np.nan)
        err[ri, pi] = np.where(ok[..., None], e, np.nan)
        tilt[ri, pi] = np.where(ok, np.linalg.norm(fw_tilt[..., :2], axis=-1), np.nan)
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
    limits.warn_non_finite("tolerance study, compliance of the robots that assembled",
                           int(np.sum(conv & ~np.all(np.isfinite(comp), axis=(-1, -2)))), int(conv.sum()))
    if not conv.any():
        raise ConvergenceError(f"none of the {n_robots} robots assembles at the poses with these sigmas "
                               f"({', '.join(f'{k} {v:g} m' for k, v in check_sigmas(sigmas).items() if v)}): "
                               "the errors are too large for this robot")
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
        out[kind] = {name: float(np.subtract(*np.nanpercentile(v - nominal_of(res, name), [95, 5])))
                     for name, v in res.outputs().items()}
    return out


def nominal_of(res: ToleranceResult, name: str) -> np.ndarray:
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
    nominal_centre = {name: float(nominal_of(res, name)[0]) for name, _, _ in OUTPUTS}
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
    v = res.outputs()[name] - nominal_of(res, name)
    return float(np.subtract(*np.nanpercentile(v, [95, 5])))


__all__ = ["DEFAULT_SIGMAS", "KINDS", "OUTPUTS", "BatchGeometry", "ToleranceResult", "check_sigmas", "default_poses",
           "check_size", "report", "robot_geometry", "sample", "sensitivity", "study"]
