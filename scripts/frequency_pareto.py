#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The frequency-workspace-compliance Pareto of a design sweep: docs/frequency_pareto.png.

Runs a sweep (Sobol designs, h4pin.studies.sweep) with the first natural frequency of every design
(Spec.frequency: the lowest over the task box's centre and its 16 corners, the elastic robot with
the URDF's link inertias, each design's mass model from its parameters), in a temporary folder,
on two Dask workers; then the Pareto front of (first frequency up, workspace volume up, worst
compliance over the task box down) and its figure.

    python scripts/frequency_pareto.py [--designs 100000] [--workers 2] [--out docs/frequency_pareto.png]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from h4pin import plots
from h4pin.studies import frequency, sweep

DOCS = Path(__file__).resolve().parent.parent / "docs"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", type=int, default=100_000)
    parser.add_argument("--workers", type=int, default=2, help="Dask workers (0: this process, numba threads)")
    parser.add_argument("--out", type=Path, default=DOCS / "frequency_pareto.png")
    args = parser.parse_args()
    spec = sweep.Spec(n_designs=args.designs, chunk=256, frequency=True)
    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        res = sweep.run(Path(tmp) / "sweep.zarr", spec, workers=args.workers or None, progress=True)
    seconds = time.perf_counter() - t
    par = frequency.frequency_pareto(res)
    reach = int(res["reach_all"].sum())
    print(f"{args.designs:,} designs in {seconds:.0f} s ({seconds / args.designs * 1e3:.1f} ms a design, "
          f"{args.workers or 1} worker(s)); {reach:,} reach the task box, first frequency "
          f"{np.nanmin(par['frequency']):.1f} to {np.nanmax(par['frequency']):.1f} Hz; front of {len(par['front'])}")
    for i in par["front"][:: max(1, len(par["front"]) // 12)]:
        print(f"  design {par['design'][i]}: {par['frequency'][i]:.1f} Hz, volume {par['volume'][i] * 1e3:.0f} dm^3, "
              f"worst compliance {par['worst'][i] * 1e6:.1f} um/N")
    print(f"wrote {plots.frequency_pareto(par, args.out)}")


if __name__ == "__main__":
    main()
