#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""How much the forearms' bending out of their plane changes K over the workspace.

Eq. 30 bends each forearm about u_i only (section IV-B.2 of the paper). A round tube has the same
E I about its other normal: the prototype with ``forearm_out_EI = E I`` (70 GPa x 1.6e4 mm^4 =
1 120 N.m^2, the paper's own forearm data) against the paper's model, both 'consistent', on a
grid of poses (theta = 0) at three heights. Prints, over the reachable, non-singular poses, the
range of the relative change of the translational compliance K_tt (3 x 3 at D): its largest
eigenvalue (the worst direction), ||dK_tt|| / ||K_tt|| (Frobenius), and each entry's change over
the largest entry |K_tt| of that pose; writes the map of the first two (``--figure``).

    python scripts/forearm_out_of_plane.py [--n 61] [--figure docs/forearm_out_of_plane.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import h4pin
from h4pin.files import save_figure
from h4pin.kinematics.closed_form import centre_pose

ENTRIES = {"xx": (0, 0), "yy": (1, 1), "zz": (2, 2), "xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


def changes(h4: h4pin.H4, poses: np.ndarray, ei: float) -> dict[str, np.ndarray]:
    """Per pose (NaN where a model refuses it): relative change of K_tt's largest eigenvalue, of
    its Frobenius norm, and of each entry over the pose's largest |entry|."""
    paper = h4pin.compliance(h4, poses, "consistent", on_error="nan")
    out_of_plane = h4pin.compliance(h4, poses, "consistent", elements=h4pin.Elements(forearm_out_EI=ei),
                                    on_error="nan")
    ok = np.asarray(paper.valid) & np.asarray(out_of_plane.valid)
    a, b = paper.matrix[ok, :3, :3], out_of_plane.matrix[ok, :3, :3]
    res = {"worst": np.linalg.eigvalsh(b)[:, -1] / np.linalg.eigvalsh(a)[:, -1] - 1.0,
           "norm": np.linalg.norm(b - a, axis=(1, 2)) / np.linalg.norm(a, axis=(1, 2))}
    scale = np.abs(a).max(axis=(1, 2))
    for name, (i, j) in ENTRIES.items():
        res[name] = (b[:, i, j] - a[:, i, j]) / scale
    full = {}
    for name, v in res.items():
        full[name] = np.full(len(poses), np.nan)
        full[name][ok] = v
    return full


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=61, help="grid points along x and y (over -0.3..0.3 m)")
    parser.add_argument("--figure", type=Path, help="write the map here (PNG)")
    args = parser.parse_args()
    if args.n < 2:
        parser.error("--n must be at least 2")
    h4 = h4pin.load("prototype")
    s = h4.geometry.springs
    ei = float(s["E"][0] * s["I"][0])
    c = centre_pose(h4)
    heights = (c[2] - 0.1, c[2], c[2] + 0.1)
    xs = np.linspace(-0.3, 0.3, args.n)
    gx, gy = np.meshgrid(xs, xs, indexing="xy")
    maps = []
    print(f"prototype, forearm_out_EI = E I = {ei:.0f} N.m^2 vs rigid out of plane (the paper), 'consistent', "
          f"{args.n} x {args.n} poses a height, theta = 0")
    centre = changes(h4, c[None, :], ei)
    print(f"at the Table II pose: worst direction {centre['worst'][0]:+.4%}, norm {centre['norm'][0]:+.4%}, "
          + ", ".join(f"{n} {centre[n][0]:+.4%}" for n in ENTRIES))
    for z in heights:
        poses = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z), np.zeros(gx.size)])
        res = changes(h4, poses, ei)
        ok = np.isfinite(res["worst"])
        w = res["worst"][ok]
        inner = ok & (np.abs(poses[:, 0]) <= 0.15) & (np.abs(poses[:, 1]) <= 0.15)
        print(f"z = {z:+.3f} m: {ok.sum()} of {ok.size} poses computed; worst direction: median {np.median(w):+.2%}, "
              f"90 % of poses under {np.quantile(w, 0.9):+.2%}, max {w.max():+.2%} (near the reach's edge); "
              f"within |x|, |y| <= 0.15 m: {res['worst'][inner].min():+.2%}..{res['worst'][inner].max():+.2%}")
        print("    range per quantity: " + "; ".join(f"{n} {np.nanmin(res[n]):+.2%}..{np.nanmax(res[n]):+.2%}"
                                                   for n in res))
        maps.append({n: v.reshape(gx.shape) for n, v in res.items()})
    if args.figure is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.colors import LogNorm

        fig, axes = plt.subplots(2, len(heights), figsize=(4.2 * len(heights), 7.4), constrained_layout=True)
        for row, (name, title) in enumerate((("worst", "worst-direction compliance"),
                                             ("norm", "||dK_tt|| / ||K_tt||"))):
            top = max(np.nanmax(m[name]) for m in maps) * 100
            for col, (z, m) in enumerate(zip(heights, maps, strict=True)):
                ax = axes[row, col]
                im = ax.pcolormesh(xs, xs, np.maximum(m[name] * 100, 1e-3), norm=LogNorm(1e-3, top), shading="auto",
                                   cmap="viridis")
                ax.set_aspect("equal")
                ax.set_title(f"{title}\nz = {z:+.3f} m", fontsize=9)
                ax.set_xlabel("x (m)")
                ax.set_ylabel("y (m)")
            fig.colorbar(im, ax=axes[row, :], label="increase (%), log scale", shrink=0.9)
        fig.suptitle("Forearms bending out of plane (EI = 1 120 N.m²) vs the paper's rigid forearms", fontsize=10)
        args.figure.parent.mkdir(parents=True, exist_ok=True)
        save_figure(fig, args.figure, dpi=90)  # atomic, with h4pin's marker
        print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
