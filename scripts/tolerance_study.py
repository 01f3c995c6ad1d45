#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Tolerance study of the prototype H4: percentile table, one-at-a-time sensitivity and
histograms written to docs/tolerance.png (see docs/tolerance.md).

    python scripts/tolerance_study.py [--robots 10000] [--seed 0] [--out docs/tolerance.png]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import h4pin
from h4pin import plots
from h4pin.studies import tolerance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=10_000, help="robots drawn")
    parser.add_argument("--sens-robots", type=int, default=2000, help="robots per one-at-a-time run")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent.parent / "docs" / "tolerance.png")
    args = parser.parse_args()
    h4 = h4pin.load("prototype")
    t0 = time.perf_counter()
    res = tolerance.study(h4, n_robots=args.robots, seed=args.seed, progress=True)
    t1 = time.perf_counter()
    sens = tolerance.sensitivity(h4, n_robots=args.sens_robots, seed=args.seed)
    print(tolerance.report(res, sens))
    print(f"\n{args.robots} robots x {len(res.poses)} poses in {t1 - t0:.2f} s")
    print(f"wrote {plots.tolerance(res, args.out)}")


if __name__ == "__main__":
    main()
