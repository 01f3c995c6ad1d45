#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Identify the unstated quantities of the H4 prototype against Table II (see docs/gap.md).

Bounded least squares (scipy.optimize.least_squares) of the tool/load points, the position of
the revolute joints C_k, the half-width, the tilt (torsion) and axial (kc, E) compliance scales:

* measured table, force and dial indicators at two different points (11 parameters);
* measured table, one point (p' = p, 8 parameters): the ``measured_match`` variant;
* measured table, at D (5 robot parameters only);
* computed table, at D (5 robot parameters).

For each: the values against their plausible bounds, the residual per entry in units of the
noise, the SVD of the scaled Jacobian (condition number, combinations, their uncertainty). Then
the figure docs/table2_fit.png: the four tables (h4pin default, fitted, paper computed, paper
measured) and the 2-D sections of their compliance ellipsoids.

    python scripts/identify.py [--out docs/table2_fit.png] [--starts 6]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import h4pin  # noqa: E402
from h4pin.files import save_figure  # noqa: E402
from h4pin.kinematics.closed_form import CENTRE_Q  # noqa: E402
from h4pin.stiffness.api import compliance  # noqa: E402
from h4pin.studies import (
    gap,  # noqa: E402
    identify,  # noqa: E402
)

US = 1e6


def _fmt(name: str, value: float) -> str:
    p = identify.PARAMETERS[name]
    return f"{value * 1e3:8.1f} mm" if p.unit == "m" else f"{value:8.3f}   "


def print_fit(title: str, fit: identify.Fit) -> None:
    print(f"\n=== {title}")
    print(f"  noise sigma = {fit.sigma * US:.2f} um/N per entry; cost 0.5*sum(r^2) = {fit.cost:.3f}, "
          f"largest |residual| = {np.max(np.abs(fit.residual)):.2f} sigma "
          f"({np.max(np.abs(fit.model - fit.target)) * US:.2f} um/N)")
    print(f"  {'parameter':<11}{'value':>12}{'bounds':>24}{'1-sigma':>12}")
    for n in fit.names:
        p = identify.PARAMETERS[n]
        lo, hi = fit.bounds[n]
        lo, hi = (lo * 1e3, hi * 1e3) if p.unit == "m" else (lo, hi)
        std = fit.std[n]
        s = "  (not identifiable)" if np.isnan(std) else (f"{std * 1e3:9.1f} mm" if p.unit == "m" else f"{std:9.3f}   ")
        flag = "  AT BOUND" if n in fit.at_bound else ""
        print(f"  {n:<11}{_fmt(n, fit.values[n]):>12}{f'[{lo:g}, {hi:g}]':>24}{s:>12}{flag}")
    print(f"  {'':<8}{'model [um/N]':<24}{'target [um/N]':<24}residual [sigma]")
    for a, r in enumerate("xyz"):
        print(f"  d{r:<6}" + "".join(f"{v:8.2f}" for v in fit.model[a] * US) + "".join(
            f"{v:8.1f}" for v in fit.target[a] * US) + "".join(f"{v:+8.2f}" for v in fit.residual[a]))
    print(f"  scaled Jacobian (parameters / plausible range, residuals / sigma): condition number "
          f"{fit.condition:.3g}; singular values {', '.join(f'{s:.3g}' for s in fit.singular_values)}")
    for c in fit.combinations:
        main = sorted(c.vector.items(), key=lambda kv: -abs(kv[1]))
        terms = " ".join(f"{v:+.2f} {k}" for k, v in main if abs(v) >= 0.2)
        kind = "identifiable" if c.std_scaled < 0.25 else "not identifiable"
        print(f"    s = {c.singular_value:8.3g}  std {min(c.std_scaled, 1e9):9.3g} ranges  {kind:<17} {terms}")


def _ellipse(block: np.ndarray, n: int = 200) -> np.ndarray:
    """Displacements (2, n) of the 2x2 block under unit forces turning in its plane."""
    t = np.linspace(0, 2 * np.pi, n)
    return block @ np.vstack([np.cos(t), np.sin(t)])


def plot(tables: dict[str, np.ndarray], path: Path) -> None:
    fig = plt.figure(figsize=(16, 8))
    vmax = max(np.abs(t).max() for t in tables.values()) * US
    for k, (name, t) in enumerate(tables.items()):
        ax = fig.add_subplot(2, 4, k + 1)
        im = ax.imshow(t * US, cmap="RdBu_r", vmin=-vmax, vmax=vmax)
        for a in range(3):
            for b in range(3):
                ax.text(b, a, f"{np.round(t[a, b] * US, 1) + 0.0:.1f}", ha="center", va="center", fontsize=11)
        ax.set_xticks(range(3), ["Fx", "Fy", "Fz"])
        ax.set_yticks(range(3), ["dx", "dy", "dz"])
        ax.set_title(name, fontsize=10)
    fig.colorbar(im, ax=fig.axes, shrink=0.5, location="right", label="um/N")
    colours = ("C0", "C1", "C2", "C3")
    for k, (i, j) in enumerate(((0, 2), (0, 1), (1, 2))):
        ax = fig.add_subplot(2, 3, 4 + k)
        for (name, t), c in zip(tables.items(), colours, strict=True):
            e = _ellipse(t[np.ix_([i, j], [i, j])]) * US
            ax.plot(e[0], e[1], color=c, label=name.split("\n")[0])
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel(f"d{'xyz'[i]} [um/N]")
        ax.set_ylabel(f"d{'xyz'[j]} [um/N]")
        ax.set_title(f"{'xyz'[i]}{'xyz'[j]} section: displacement under a unit force turning in the plane", fontsize=9)
    fig.axes[-1].legend(fontsize=8)
    fig.suptitle("H4 Table II at q_i = 45 deg: h4pin default, measured_match variant, paper computed and measured")
    save_figure(fig, path, dpi=80)


def print_selection(rows: list) -> None:
    """The candidate parameter sets on the six symmetric numbers, best AIC first."""
    sigma, dof = identify.noise_from_antisymmetry()
    print(f"\nModel selection on the measured table's symmetric part (6 numbers), noise from its antisymmetric "
          f"part alone: sigma = {sigma * US:.2f} um/N ({dof} dof); leave-one-out z of xx, yy, zz, xy, xz, yz:")
    print(f"  {'set':<22}{'k':>3}{'dof':>5}{'chi2':>8}{'AIC':>8}   leave-one-out z                    on a bound")
    for s in rows:
        loo = " ".join(f"{z:+5.1f}" for z in s.loo)
        print(f"  {s.name:<22}{s.k:>3}{s.dof:>5}{s.chi2:>8.2f}{s.aic:>8.2f}   {loo}   {', '.join(s.at_bound) or '-'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent.parent / "docs" / "table2_fit.png",
                        help="figure to write (PNG)")
    parser.add_argument("--starts", type=int, default=6, help="starting points per fit (defaults + seeded random)")
    args = parser.parse_args()
    if not args.out.parent.is_dir():
        raise SystemExit(f"error: folder {args.out.parent} does not exist")
    sigma, dof = gap.noise_from_asymmetry()
    print(f"Noise of the measured table from its asymmetry: sigma = {sigma * US:.2f} um/N ({dof} dof); "
          f"computed table: rounding, sigma = {identify.ROUNDING_SIGMA * US:.2f} um/N")
    print("Plausible bounds:")
    for n, p in identify.PARAMETERS.items():
        lo, hi = (p.lower * 1e3, p.upper * 1e3) if p.unit == "m" else (p.lower, p.upper)
        print(f"  {n:<11}[{lo:g}, {hi:g}]{' mm' if p.unit == 'm' else ''}: {p.why}")

    two = identify.fit(gap.MEASURED, identify.MEASURED_FIT, starts=args.starts)
    print_fit("measured table, force at p', dial indicators at p (11 parameters)", two)
    one = identify.fit_measured_one_point(starts=args.starts)
    print_fit("measured table, force and dial indicators at one point p (8 parameters, saturated): the "
              "'measured_match' variant", one)
    # FITTED is current when it costs no more than this fit and agrees with it in the parameters the
    # data fixes (identifiable, or on a bound); along the null directions (half-width with tilt,
    # exactly) any point of the valley is as good, and where the solver stops there is round-off.
    fixed = [k for k in identify.FITTED if np.isfinite(one.std.get(k, np.nan)) or k in one.at_bound]
    drift = {k: abs(one.values[k] - identify.FITTED[k]) / identify.FITTED_ROUNDING[k] for k in fixed}
    at_fitted = 0.5 * float(np.sum(((identify.table(identify.fitted_values()) - gap.MEASURED) / one.sigma) ** 2))
    stale = [k for k, d in drift.items() if d > 1.0] + (["cost"] if at_fitted - one.cost > 1e-3 else [])
    print(f"  identify.FITTED {'is current' if not stale else 'is STALE in ' + ', '.join(stale)}: cost there "
          f"{at_fitted:.3f}; {', '.join(fixed)} within {max(drift.values()):.2f} x their rounding (the others lie "
          "along directions the data does not fix)")
    relaxed = identify.fit(gap.MEASURED, identify.ONE_POINT_FIT, starts=args.starts, same_point=True,
                           bounds={"axial": (0.05, 2.0), "ck_dy": (-0.05, 0.05)})
    print_fit("the same with the axial factor allowed down to 0.05 and C_k +-50 mm across: what the data asks for",
              relaxed)
    at_d = identify.fit(gap.MEASURED, identify.COMPUTED_FIT, starts=max(2, args.starts // 3))
    print_fit("measured table at D (5 robot parameters)", at_d)
    comp = identify.fit(gap.COMPUTED, identify.COMPUTED_FIT, starts=args.starts)
    print_fit("paper's computed table at D (5 robot parameters)", comp)
    print(f"  computed table met within rounding (+-0.5 um/N): "
          f"{np.max(np.abs(comp.model - comp.target)) <= gap.ROUNDING}")

    print_selection(identify.select(starts=args.starts))

    default = h4pin.load("prototype")
    fitted = h4pin.load("measured_match")
    tables = {
        "h4pin default, at D": compliance(default, default.forward_geometry(CENTRE_Q)).translational,
        "measured_match, at p": compliance(fitted, fitted.forward_geometry(CENTRE_Q)).at(identify.fitted_point()),
        "paper, computed": gap.COMPUTED,
        "paper, measured": gap.MEASURED,
    }
    plot(tables, args.out)
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
