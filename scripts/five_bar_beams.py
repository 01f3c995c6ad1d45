#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""How much aluminium links add to a five-bar's servo compliance (h4pin.mechanism.Beam, Mechanism.with_beams).

Gepetto's planar five-bar (tests/robots/5bar_linkage_iso3d, BSD-3-Clause), its two motors servos of
2 000 and 3 000 N.m/rad, every link an aluminium tube (E 70 GPa, G 26 GPa) of outer diameter --d and
wall --t: over a grid of the two motor angles around the file's assembled configuration, the
worst-direction translational compliance of the closure point (the tool) in the linkage's plane (x, z),
servos alone and with the links, and their ratio. Out of the plane the servos give nothing (a planar
linkage of rigid links does not move there) and the links everything: printed, not mapped. Prints
the table at the start configuration and writes the map.

    python scripts/five_bar_beams.py [--d 0.025] [--t 0.002] [--figure docs/five_bar_beams.png]
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from h4pin.errors import H4Error, MechanismWarning
from h4pin.files import save_figure
from h4pin.mechanism import Beam, Mechanism

ROBOT = Path(__file__).resolve().parent.parent / "tests" / "robots" / "5bar_linkage_iso3d" / "robot.urdf"
TOOL = "closedloop3D_1B"
SPRINGS = {"mot1": 2.0e3, "mot2": 3.0e3}


def worst(c: np.ndarray) -> float:
    """m/N, the largest eigenvalue of the translational block in the linkage's plane (x, z)."""
    t = c[np.ix_([0, 2], [0, 2])]
    return float(np.linalg.eigvalsh(0.5 * (t + t.T))[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--d", type=float, default=0.025, help="tube outer diameter (m)")
    parser.add_argument("--t", type=float, default=0.002, help="tube wall (m)")
    parser.add_argument("--span", type=float, default=0.5, help="motor angles around the start, +- rad")
    parser.add_argument("--n", type=int, default=21, help="grid points a motor")
    parser.add_argument("--figure", type=Path, help="write the map here (PNG)")
    args = parser.parse_args()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        rigid = Mechanism.from_urdf(ROBOT)
        q0 = rigid.assemble()
    tube = Beam.tube(args.d, args.t, E=70e9, G=26e9)
    beams, seen = {}, set()
    for f in rigid.model.frames:  # the first link on each joint (others are fixed to it)
        if f.type.name != "BODY" or f.parentJoint == 0 or f.parentJoint in seen:
            continue
        seen.add(f.parentJoint)
        try:
            rigid.with_beams({f.name: tube})
        except H4Error:
            continue  # a link with no far end (or several): left rigid
        beams[f.name] = tube
    flex = rigid.with_beams(beams)
    c_rigid, c_flex = rigid.compliance(q0, SPRINGS, [TOOL]), flex.compliance(q0, SPRINGS, [TOOL])
    print(f"five-bar, servos {SPRINGS} N.m/rad, links: aluminium tube {args.d * 1e3:g} x {args.t * 1e3:g} mm "
          f"({', '.join(beams)})")
    print(f"tool compliance at the start (um/N, world x y z):\n servos alone\n{np.round(c_rigid[:3, :3] * 1e6, 3)}"
          f"\n servos and links\n{np.round(c_flex[:3, :3] * 1e6, 3)}")
    print(f"worst direction in the plane: {worst(c_rigid) * 1e6:.3f} -> {worst(c_flex) * 1e6:.3f} um/N "
          f"(links add {worst(c_flex) / worst(c_rigid) - 1:+.1%}); out of the plane (y): "
          f"{c_rigid[1, 1] * 1e6:.3f} -> {c_flex[1, 1] * 1e6:.3f} um/N")
    motors = [rigid.model.joints[rigid.model.getJointId(m)].idx_q for m in rigid.actuated]
    grid = np.linspace(-args.span, args.span, args.n)
    ratio = np.full((args.n, args.n), np.nan)
    base = np.full((args.n, args.n), np.nan)
    for a, da in enumerate(grid):
        q = q0.copy()
        for b, db in enumerate(grid):
            start = q.copy()
            start[motors] = q0[motors] + [da, db]
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", MechanismWarning)
                    q = rigid.assemble(start, fixed=rigid.actuated)
                r, f = worst(rigid.compliance(q, SPRINGS, [TOOL])), worst(flex.compliance(q, SPRINGS, [TOOL]))
            except H4Error:
                q = q0.copy()
                continue
            base[a, b], ratio[a, b] = r, f / r
    ok = np.isfinite(ratio)
    print(f"over the grid ({ok.sum()} of {ok.size} configurations assemble): the links add "
          f"{np.nanmin(ratio) - 1:+.1%} to {np.nanmax(ratio) - 1:+.1%} (median {np.nanmedian(ratio) - 1:+.1%})")
    if args.figure is None:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    ext = [grid[0], grid[-1], grid[0], grid[-1]]
    im = axes[0].imshow(base.T * 1e6, origin="lower", extent=ext, cmap="viridis")
    fig.colorbar(im, ax=axes[0], label="um/N")
    axes[0].set_title("worst in-plane tool compliance, servos alone")
    im = axes[1].imshow((ratio.T - 1) * 100, origin="lower", extent=ext, cmap="magma")
    fig.colorbar(im, ax=axes[1], label="%")
    axes[1].set_title(f"what aluminium links ({args.d * 1e3:g} x {args.t * 1e3:g} mm tube) add")
    for ax in axes:
        ax.set_xlabel(f"{rigid.actuated[0]} - start (rad)")
        ax.set_ylabel(f"{rigid.actuated[1]} - start (rad)")
    save_figure(fig, args.figure)
    print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
