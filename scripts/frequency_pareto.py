#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The first natural frequency across a design sweep: docs/frequency_pareto.png.

Runs a small sweep (256 Sobol designs, h4pin.studies.sweep) in a temporary folder, computes the
first natural frequency with a 0.5 kg payload at the centre pose of the 120 stiffest designs that
reach the whole task box (h4pin.studies.frequency, about 25 ms a design), and plots it against
the workspace volume with the Pareto front.

    python scripts/frequency_pareto.py [--designs 256] [--limit 120] [--out docs/frequency_pareto.png]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from h4pin.elastic import Payload
from h4pin.studies import frequency, sweep

DOCS = Path(__file__).resolve().parent.parent / "docs"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", type=int, default=256)
    parser.add_argument("--limit", type=int, default=120)
    parser.add_argument("--payload", type=float, default=0.5, help="kg at D")
    parser.add_argument("--out", type=Path, default=DOCS / "frequency_pareto.png")
    args = parser.parse_args()
    spec = sweep.Spec(n_designs=args.designs, chunk=64)
    with tempfile.TemporaryDirectory() as tmp:
        res = sweep.run(Path(tmp) / "sweep.zarr", spec, progress=False)
    t = time.perf_counter()
    par = frequency.frequency_pareto(res, sweep.designs(spec), Payload(args.payload) if args.payload else None,
                                     limit=args.limit)
    seconds = time.perf_counter() - t
    print(f"{len(par['design'])} designs in {seconds:.1f} s ({seconds / len(par['design']) * 1e3:.0f} ms a design); "
          f"first frequency {par['frequency'].min():.1f} to {par['frequency'].max():.1f} Hz")
    for i in par["front"]:
        print(f"  design {par['design'][i]}: {par['frequency'][i]:.1f} Hz, volume {par['volume'][i] * 1e3:.0f} dm^3")
    print(f"wrote {frequency.plot_frequency_pareto(par, args.out)}")


if __name__ == "__main__":
    main()
