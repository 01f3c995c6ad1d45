#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The gap between eq. 30 and Table II, with the package's own numbers (see docs/gap.md).

Prints, at q_i = 45 deg: the four terms and their shapes; that control and bending share one
shape and tension lies in the span of that shape and the tilt (SVD); the best non-negative
combination of the terms against the paper's computed table (nnls, and the least possible
largest misfit, linprog) against its rounding; the region of C_k offset x tilt factor where the
table is met within rounding; why the measured table is out of reach (zz/xx, noise); and how
these conclusions move with an actuator zero offset of +-3 deg or +-5 % on an unstated length.

    python scripts/gap_analysis.py [--step-mm 2]
"""

from __future__ import annotations

import argparse

import numpy as np

from h4pin.studies import gap

US = 1e6  # m/N -> um/N, printing only


def _row(label: str, values: np.ndarray, fmt: str = "{:9.2f}") -> str:
    return f"  {label:<26}" + "".join(fmt.format(v) for v in values)


def print_terms(blocks: dict[str, np.ndarray]) -> None:
    head = "".join(f"{e:>9}" for e in gap.ENTRIES)
    print(f"Terms at q_i = 45 deg, stated geometry [um/N]{'':<3}{head}")
    for t, b in blocks.items():
        print(_row(t, gap.entries(b) * US))
    print(f"\nShapes (each term / its xx){'':<13}{head}")
    for t, s in gap.shapes(blocks).items():
        print(_row(t, gap.entries(s), "{:9.4f}"))
    ratio = blocks["bending"] / blocks["control"]
    finite = ratio[np.abs(blocks["control"]) > 1e-3 * np.abs(blocks["control"]).max()]
    print(f"\nbending / control, entry by entry: {finite.min():.6f} .. {finite.max():.6f} (one scalar: kc and EI "
          "cannot be told apart)")
    sv = gap.span_singular_values(blocks)
    print(f"singular values of the 4 stacked unit-norm term blocks: {', '.join(f'{v:.3g}' for v in sv)}"
          f"  -> rank {int(np.sum(sv > 1e-10 * sv[0]))}")
    coef, res = gap.in_span(blocks)
    print(f"tension = {coef[0]:.4f} control + {coef[1]:.4f} torsion  (relative residual {res:.1e})")


def print_combination(title: str, comb: gap.Combination, tol: float, tol_name: str) -> None:
    factors = ", ".join(f"{k} x{v:.3f}" for k, v in comb.factors.items())
    print(f"\n{title}: {factors}")
    print(_row("fitted [um/N]", comb.fitted * US))
    print(_row("misfit [um/N]", comb.misfit * US, "{:+9.2f}"))
    print(f"  largest |misfit| {comb.max_abs * US:.3f} um/N, rms {comb.rms * US:.3f} um/N; "
          f"{'beyond' if comb.max_abs > tol else 'within'} {tol_name} ({tol * US:.2f} um/N)")


def print_region(region: gap.FitRegion) -> None:
    feas = region.feasible.any(axis=2)
    print(f"\nC_k moved by (dx, dy) [mm] x tilt factor tau in {region.taus[0]:g}..{region.taus[-1]:g}: cells where "
          "some axial factor a meets all four entries within +-0.5 um/N ('#'; 'o': also with a = 1, the stated kc, EI)")
    print("  dx \\ dy " + "".join(f"{v * 1e3:4.0f}" for v in region.dy))
    stated_any = region.stated_axial.any(axis=2)
    for i, u in enumerate(region.dx):
        cells = "".join(f"{'o' if stated_any[i, j] else '#' if feas[i, j] else '.':>4}" for j in range(len(region.dy)))
        print(f"  {u * 1e3:6.0f}  {cells}")
    if not feas.any():
        print("  no cell meets the table within rounding")
        return
    idx = np.argwhere(region.feasible)
    dist = np.hypot(region.dx[idx[:, 0]], region.dy[idx[:, 1]])
    a = region.axial[region.feasible]
    print(f"  feasible cells: {feas.sum()} of {feas.size}; "
          f"|C_k offset| {dist.min() * 1e3:.1f} .. {dist.max() * 1e3:.1f} mm, "
          f"tau {region.taus[idx[:, 2]].min():.2f} .. {region.taus[idx[:, 2]].max():.2f}, "
          f"a {np.nanmin(a[:, 0]):.3f} .. {np.nanmax(a[:, 1]):.3f}")
    for name, sel in (("dx < 0", region.dx[idx[:, 0]] < 0), ("dx >= 0", region.dx[idx[:, 0]] >= 0)):
        if sel.any():
            sub = idx[sel]
            print(f"  {name}: dx {region.dx[sub[:, 0]].min() * 1e3:.0f} .. {region.dx[sub[:, 0]].max() * 1e3:.0f} mm, "
                  f"dy {region.dy[sub[:, 1]].min() * 1e3:.0f} .. {region.dy[sub[:, 1]].max() * 1e3:.0f} mm, "
                  f"tau {region.taus[sub[:, 2]].min():.2f} .. {region.taus[sub[:, 2]].max():.2f}, "
                  f"a {np.nanmin(a[sel, 0]):.3f} .. {np.nanmax(a[sel, 1]):.3f}")
    if region.stated_axial.any():
        s = np.argwhere(region.stated_axial)
        print(f"  with the stated axial springs (a = 1): dx {region.dx[s[:, 0]].min() * 1e3:.0f} .. "
              f"{region.dx[s[:, 0]].max() * 1e3:.0f} mm, dy {region.dy[s[:, 1]].min() * 1e3:.0f} .. "
              f"{region.dy[s[:, 1]].max() * 1e3:.0f} mm, tau {region.taus[s[:, 2]].min():.2f} .. "
              f"{region.taus[s[:, 2]].max():.2f}")
    else:
        print("  with the stated axial springs (a = 1): nowhere")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--step-mm", type=float, default=2.0, help="grid step of the C_k sweep (mm)")
    parser.add_argument("--range-mm", type=float, default=40.0, help="C_k offsets swept: +-this (mm)")
    args = parser.parse_args()
    blocks = gap.term_blocks()
    print_terms(blocks)
    measured = gap.model_projection(gap.MEASURED)
    sigma, dof = gap.noise_from_asymmetry()
    for target, name, tol, tol_name in ((gap.COMPUTED, "computed", gap.ROUNDING, "the table's rounding"),
                                        (measured, "measured, symmetrised (xz = (11 + 15) / 2)", sigma,
                                         "the noise sigma from the asymmetry")):
        print(f"\n=== paper, {name}: " + ", ".join(f"{e} {v * US:g}" for e, v in zip(gap.ENTRIES, gap.entries(target),
                                                                                    strict=True)))
        print_combination("best non-negative combination of the 4 terms (nnls)", gap.best_combination(blocks, target),
                          tol, tol_name)
        two = gap.two_shapes(blocks)
        print_combination("the same on the two shapes (nnls)", gap.best_combination(two, target), tol, tol_name)
        print_combination("least largest misfit, 4 terms (linprog)", gap.minimax_combination(blocks, target), tol,
                          tol_name)
    lo, hi = gap.ratio_range(blocks, "yy", "xx")
    print(f"\nyy/xx reachable at the stated geometry: {lo:.3f} .. {hi:.3f}; paper computed 21/40 = "
          f"{gap.COMPUTED[1, 1] / gap.COMPUTED[0, 0]:.3f}")
    dx = np.arange(-args.range_mm, args.range_mm + 1e-9, args.step_mm) * 1e-3
    dy = np.arange(-args.range_mm, args.range_mm + 1e-9, 2 * args.step_mm) * 1e-3
    taus = np.arange(1.0, 10.0 + 1e-9, 0.05)
    region = gap.fit_region(dx, dy, taus, progress=True)
    print_region(region)
    lo, hi = gap.ratio_range(blocks)
    zz = gap.MEASURED[2, 2] / gap.MEASURED[0, 0]
    print(f"\nzz/xx: measured {zz:.3f}; reachable at the stated geometry {lo:.3f} .. {hi:.3f}; least over the C_k "
          f"sweep {region.zz_xx_min.min():.3f}")
    print(f"measured table: noise from its asymmetry sigma = {sigma * US:.2f} um/N ({dof} dof); "
          f"zz/xx at the reachable minimum would need zz = {region.zz_xx_min.min() * gap.MEASURED[0, 0] * US:.1f} "
          f"um/N against 9 measured, {(region.zz_xx_min.min() * gap.MEASURED[0, 0] - gap.MEASURED[2, 2]) / sigma:.1f} "
          "sigma")
    print_robustness()


def print_robustness() -> None:
    """Sections 1-3's conclusions under an actuator zero offset of +-3 deg and +-5 % on each length
    the paper does not state (docs/gap.md, section 8)."""
    print("\nRobustness: every actuator at 45 +- 3 deg, or +-5 % on an unstated length (h, C_k's |y| and z)")
    print(f"  {'change':<18}{'yy/xx reachable':>18}{'zz/xx reachable':>18}{'least miss':>12}  springs alone meet the "
          "computed table")
    for r in gap.robustness():
        print(f"  {r.name:<18}{r.yy_xx[0]:>10.3f} .. {r.yy_xx[1]:.3f}{r.zz_xx[0]:>10.3f} .. {r.zz_xx[1]:.3f}"
              f"{r.least_miss * US:>9.2f} um/N  {'yes' if r.meets else 'no'}")
    print("  smallest move of C_k (2 mm grid, every spring free) that meets the computed table within rounding:")
    for q in (42.0, 45.0, 48.0):
        found = gap.smallest_joint_offset(np.deg2rad(q))
        where = "none within 60 mm" if found is None else (
            f"({found[0] * 1e3:+.0f}, {found[1] * 1e3:+.0f}) mm, |move| {np.hypot(*found[:2]) * 1e3:.0f} mm")
        print(f"    actuators at {q:.0f} deg: {where}")


if __name__ == "__main__":
    main()
