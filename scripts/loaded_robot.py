#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The loaded robot's numbers and figures of docs/loaded.md: the H4's sag under its weight and a
payload at Table II's pose and over an x-y map, how the load changes its compliance there, the
compensated pick-and-place cycle; a corpus robot's sag and critical load (the 5-bar of Gepetto's
files); Euler's cantilever against its virtual-joint segments.

    python scripts/loaded_robot.py [--grid 9] [--samples 40] [--out docs]

Prints every number docs/loaded.md quotes, and writes docs/loaded_sag_map.png and
docs/loaded_cycle.png (about two minutes on one core).
"""

from __future__ import annotations

import argparse
import math
import time
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin

import h4pin
from h4pin import plots
from h4pin.kinematics.closed_form import centre_pose
from h4pin.mechanism import Beam, Mechanism, Payload
from h4pin.studies import loaded

ROOT = Path(__file__).resolve().parent.parent


def h4_numbers(h4: h4pin.H4) -> None:
    c = centre_pose(h4)
    for kg in (0.0, 0.5, 2.0):
        s = loaded.sag(h4, c, kg)
        d = s.displacement[0]
        print(f"H4 at Table II's pose, payload {kg:g} kg: sag of D ({d[0] * 1e6:.1f}, {d[1] * 1e6:.1f}, "
              f"{d[2] * 1e6:.1f}) um, |sag| {np.linalg.norm(d[:3]) * 1e6:.1f} um, rotation about y "
              f"{d[4] * 1e6:.1f} urad; largest change of K_tt under the load {s.change[0] * 100:.3f} %")
        if kg == 2.0:
            print("  K_tt unloaded (um/N):", np.array2string(s.linear[0] * 1e6, precision=2, suppress_small=True))
            print("  K_tt loaded (um/N):  ", np.array2string(s.tangent[0] * 1e6, precision=2, suppress_small=True))


def corpus_numbers() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = Mechanism.from_urdf(ROOT / "tests" / "robots" / "5bar_linkage_iso3d" / "robot.urdf")
    springs = {n: 2e3 if n in mech.actuated else 50.0 for n in list(mech.model.names)[1:]}
    q = mech.assemble()
    mass = sum(i.mass for i in mech.model.inertias)
    eq = mech.equilibrium(q, springs, gravity=True, payload=("effector", Payload(0.2)))
    d = eq.displacement("effector")
    lin = mech.compliance(q, springs, ["effector"])[:3, :3]
    tan = eq.compliance(["effector"])[:3, :3]
    print(f"5-bar (Gepetto's 5bar_linkage_iso3d, {mass:.1f} kg of links, motors 2e3 and passive joints 50 N.m/rad): "
          f"sag of the effector under its weight and 0.2 kg ({d[0] * 1e3:.3f}, {d[1] * 1e3:.3f}, {d[2] * 1e3:.3f}) mm; "
          f"largest change of C_tt {np.abs(tan - lin).max() / np.abs(lin).max() * 100:.1f} %")
    crit = mech.critical_load(q, springs, gravity=True, max_factor=50.0)
    print(f"  critical gravity factor: {crit.factor:.3f} ({crit.kind})")
    d0 = pin.Data(mech.model)
    pin.framesForwardKinematics(mech.model, d0, q)
    target = d0.oMf[mech.model.getFrameId("effector")].translation + [0.01, 0.0, 0.005]
    comp = mech.compensate({"effector": target}, springs, gravity=True, payload=("effector", Payload(0.2)))
    print(f"  compensation of a target 10 mm across, 5 mm up: sag at the rigid inverse "
          f"{np.linalg.norm(comp.sag) * 1e3:.3f} mm, after {np.linalg.norm(comp.error):.1e} m; motors moved by "
          f"{np.array2string((comp.motors - comp.rigid) * 1e3, precision=3)} mrad")


def euler_numbers() -> None:
    length, d, e = 0.5, 0.01, 70e9
    euler = math.pi**2 * e * (math.pi * d**4 / 64) / (4 * length**2)
    for n in (1, 2, 3, 4, 8):
        model = pin.Model()
        j = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "root")
        model.appendBodyToJoint(j, pin.Inertia(0.1, np.array([length / 2, 0, 0]), np.eye(3) * 1e-4), pin.SE3.Identity())
        model.addFrame(pin.Frame("link", j, 0, pin.SE3.Identity(), pin.FrameType.BODY))
        model.addFrame(pin.Frame("tip", j, 0, pin.SE3(np.eye(3), np.array([length, 0, 0])), pin.FrameType.OP_FRAME))
        rod = Beam(**{**Beam.circle(d, e, 0.4 * e, to="tip").__dict__, "segments": n})
        mech = Mechanism(model, [], ["root"]).with_beams({"link": rod})
        crit = mech.critical_load(mech.assemble(), {}, {"tip": [-1.0, 0, 0]}, max_factor=1e6)
        print(f"cantilever, {n} segment(s): critical load {crit.factor:.1f} N, Euler {euler:.1f} N, "
              f"{(crit.factor / euler - 1) * 100:+.2f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=9, help="points per side of the sag map")
    parser.add_argument("--samples", type=int, default=40, help="samples of the compensated cycle")
    parser.add_argument("--out", type=Path, default=ROOT / "docs", help="folder of the figures")
    args = parser.parse_args()
    t0 = time.perf_counter()
    h4 = h4pin.load("prototype")
    h4_numbers(h4)
    corpus_numbers()
    euler_numbers()
    c = centre_pose(h4)
    axis = np.linspace(-0.15, 0.15, args.grid)
    ds = loaded.sag_map(h4, c[0] + axis, c[1] + axis, float(c[2]), 0.0, 0.5, progress=False)
    ok = ds.status.values == 0
    print(f"sag map ({args.grid} x {args.grid}, 0.5 kg): |sag| {ds.sag_norm.values[ok].min() * 1e6:.0f} to "
          f"{ds.sag_norm.values[ok].max() * 1e6:.0f} um; K_tt change up to {ds.change.values[ok].max() * 100:.2f} %")
    print(f"wrote {plots.sag_map(ds, args.out / 'loaded_sag_map.png')}")
    res = loaded.compensated_cycle(h4, 0.5, 0.5, samples=args.samples)
    print(f"cycle (0.5 kg, {args.samples} samples): sag up to {np.abs(res.sag).max() * 1e6:.0f} um, after "
          f"compensation up to {np.abs(res.error).max():.1e} m; corrections up to "
          f"{np.abs(res.motors - res.rigid).max() * 1e6:.0f} urad")
    print(f"wrote {plots.compensated_cycle(res, args.out / 'loaded_cycle.png')}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
