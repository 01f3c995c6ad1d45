#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Design chart of the pick-and-place cycle on the elastic robot (h4pin.studies.elastic_cycle).

For cycle times 0.3 to 3 s and payloads 0, 0.5 and 1 kg at D (the prototype, its actuators as
servos of stiffness kc, every load of the whole robot): the peak displacement of the tool (D)
over the cycle, quasi-static and dynamic; the residual vibration after the stop (its largest
amplitude about the static sag) and the time it takes to stay within 50 um; and where the
quasi-static answer is within 10 % of the dynamic one. Damping: stiffness-proportional, 1e-4 s
(1 % at the first natural frequency, 32.7 Hz bare), the elastic MuJoCo file's; ``--damping``
changes it.

    python scripts/cycle_chart.py [--figure docs/cycle_chart.png] [--damping 1e-4]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

import h4pin
from h4pin.files import save_figure
from h4pin.studies import elastic_cycle as ec

PERIODS = (0.3, 0.4, 0.5, 0.6, 0.75, 1.0, 1.5, 2.0, 3.0)
PAYLOADS = (0.0, 0.5, 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figure", type=Path, help="write the chart here (PNG)")
    parser.add_argument("--damping", type=float, default=ec.DAMPING, help="stiffness-proportional damping (s)")
    parser.add_argument("--samples", type=int, default=300, help="samples a cycle")
    args = parser.parse_args()
    h4 = h4pin.load("prototype")

    def progress(a: int, b: int, r: ec.ElasticCycle) -> None:
        ratio = r.peak_quasi_static / r.peak_dynamic
        print(f"  {r.cycle.period:4.2f} s, {r.payload:3.1f} kg: peak quasi-static {r.peak_quasi_static * 1e6:7.1f} um, "
              f"dynamic {r.peak_dynamic * 1e6:7.1f} um (quasi-static / dynamic {ratio:4.2f}"
              f"{', within 10 %' if abs(ratio - 1) <= 0.1 else ''}), residual {r.residual.max() * 1e6:6.1f} um, "
              f"settles to {ec.BAND * 1e6:.0f} um in {r.settling_time:.3f} s", flush=True)

    print(f"prototype, standard cycle, damping {args.damping:g} s x stiffness, {args.samples} samples a cycle")
    res = ec.chart(h4, PERIODS, PAYLOADS, samples=args.samples, damping=args.damping, progress=progress)
    if args.figure is None:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), constrained_layout=True)
    p = res["periods"]
    for a, (m, colour) in enumerate(zip(PAYLOADS, ("C0", "C1", "C2"), strict=True)):
        axes[0].plot(p, res["quasi_static"][a] * 1e6, "--", color=colour, label=f"{m:g} kg quasi-static")
        axes[0].plot(p, res["dynamic"][a] * 1e6, "-o", color=colour, ms=3, label=f"{m:g} kg dynamic")
        close = np.abs(res["quasi_static"][a] / res["dynamic"][a] - 1) <= 0.1
        axes[0].plot(p[close], res["dynamic"][a][close] * 1e6, "s", mfc="none", color=colour, ms=9)
        axes[1].plot(p, res["residual"][a] * 1e6, "-o", color=colour, ms=3, label=f"{m:g} kg")
        settle = np.where(np.isfinite(res["settling"][a]), res["settling"][a], np.nan)
        axes[2].plot(p, settle * 1e3, "-o", color=colour, ms=3, label=f"{m:g} kg")
    axes[0].set_title("peak tool displacement over the cycle\n(squares: quasi-static within 10 % of dynamic)")
    axes[0].set_ylabel("um")
    axes[1].set_title("largest residual vibration after the stop\n(about the static sag)")
    axes[1].set_ylabel("um")
    axes[1].axhline(ec.BAND * 1e6, color="k", lw=0.6, ls=":")
    axes[2].set_title(f"settling time to {ec.BAND * 1e6:.0f} um after the stop")
    axes[2].set_ylabel("ms")
    for ax in axes:
        ax.set_xlabel("cycle time (s)")
        ax.set_xscale("log")
        ax.set_xticks(p, [f"{x:g}" for x in p])
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_yscale("log")
    axes[1].set_yscale("log")
    fig.suptitle(f"H4 prototype, standard 25/305/25 mm cycle, elastic robot, damping {args.damping:g} s "
                 f"({math.pi * 32.7 * args.damping:.1%} at 32.7 Hz)", fontsize=10)
    args.figure.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, args.figure, dpi=90)  # atomic, with h4pin's marker
    print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
