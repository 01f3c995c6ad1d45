#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The elastic cycle's dynamics against MuJoCo: h4pin's linearised model (h4pin.studies.elastic_cycle.run),
with and without the terms of the moving configuration, against the elastic MuJoCo model driven by its
position servos along the same cycle (elastic_cycle.mujoco_cycle: MuJoCo's full nonlinear dynamics).

For each case (cycle time, payload at D): the peak |dD| over the cycle and the stop, the RMS of the
difference to MuJoCo over the cycle (% of MuJoCo's peak), the largest residual after the stop (about
the sag at rest) and the settling time to 50 um, followed for --hold s.

    python scripts/cycle_mujoco.py [--hold 3] [--timestep 5e-5] [--samples 400]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import h4pin
from h4pin.studies import elastic_cycle as ec

CASES = ((0.5, 0.0), (0.5, 0.5), (1.0, 0.0), (1.0, 0.5))


def settling(residual: np.ndarray, t: np.ndarray) -> float:
    """s from t[0] until ``residual`` stays within the band (inf: not within the record)."""
    out = np.flatnonzero(residual > ec.BAND)
    if not out.size:
        return 0.0
    return math.inf if out[-1] == len(residual) - 1 else float(t[out[-1] + 1] - t[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hold", type=float, default=3.0, help="s followed after the stop")
    parser.add_argument("--timestep", type=float, default=5e-5, help="MuJoCo's time step (s)")
    parser.add_argument("--samples", type=int, default=400, help="h4pin's samples a cycle")
    args = parser.parse_args()
    h4 = h4pin.load("prototype")
    print(f"prototype, standard cycle, damping {ec.DAMPING:g} s x stiffness; MuJoCo step {args.timestep:g} s, "
          f"h4pin {args.samples} samples a cycle; the stop followed for {args.hold:g} s")
    print(f"{'case':<14}{'model':<34}{'peak [um]':>10}{'RMS diff':>10}{'residual [um]':>15}{'settling [s]':>14}")
    for period, payload in CASES:
        mj = ec.mujoco_cycle(h4, period, payload, timestep=args.timestep, hold=args.hold)
        peak = np.linalg.norm(mj.displacement, axis=1).max()
        case = f"{period:g} s, {payload:g} kg"
        settle = settling(mj.residual, mj.t[mj.stop:])
        print(f"{case:<14}{'MuJoCo (nonlinear, servos)':<34}{peak * 1e6:10.1f}{'':>10}{mj.residual.max() * 1e6:15.1f}"
              f"{settle:14.2f}", flush=True)
        for motion, name in ((False, "h4pin, M_s only (before)"), (True, "h4pin, complete linearisation")):
            r = ec.run(h4, period, payload, samples=args.samples, hold=args.hold, motion=motion)
            ours = np.column_stack([np.interp(mj.t, r.t, r.dynamic[:, k]) for k in range(3)])
            cyc = slice(0, mj.stop + 1)
            rms = np.sqrt(np.mean(np.sum((ours[cyc] - mj.displacement[cyc]) ** 2, axis=1))) / peak
            print(f"{'':<14}{name:<34}{r.peak_dynamic * 1e6:10.1f}{rms * 100:9.2f}%{r.residual.max() * 1e6:15.1f}"
                  f"{r.settling_time:14.2f}", flush=True)


if __name__ == "__main__":
    main()
