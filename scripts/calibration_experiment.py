#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The synthetic tracker experiments of docs/calibration.md: a robot whose offsets, geometry,
springs, lateral hinges, beams and masses are drawn from a prior, measured under gravity and
known loads with Gaussian noise, then calibrated.

    python scripts/calibration_experiment.py [--runs 50] [--workers 2] [--out docs] [--skip-h4]

Prints the Cassie-like leg's stage table (fit and held-out errors per stage) and writes its
residual figure (docs/calibration_stages.png); the coverage of 50 seeded experiments of each of
three designs (a five-bar with a beam, the Cassie-like leg, a UR5 arm; tests/test_calibration.py
runs the same designs); the H4's experiment (its actuators' stiffness and placements recovered
from the tool point). About 10 minutes on two cores.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
ROBOTS = ROOT / "tests" / "robots"

#: The Cassie-like leg: each rod's spin about itself strains nothing; one joint of each rod pair
#: is held rigid in the equilibrium.
LEG_LOCKED = ("foot_2_half_planta_rode_2_rev2", "tarsus_half_hachil_rode_rev2")


def _quiet_urdf(path: Path):
    from h4pin.errors import MechanismWarning
    from h4pin.mechanism import Mechanism

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        return Mechanism.from_urdf(path)


def five_bar() -> dict:
    """Gepetto's five-bar with its distal link a flexible aluminium tube: base, offsets, a joint's
    placement, springs, lateral hinges, the beam's scale and a link's mass; 40 poses, loads of
    30 N at the effector, 0.2 mm noise."""
    from h4pin.mechanism import Beam

    mech = _quiet_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")
    mech = mech.with_beams({"part_3": Beam.tube(0.025, 0.002, E=70e9, G=26e9)})
    rng = np.random.default_rng(100)
    n = 40
    springs = {"mot1": 2e3, "mot2": 2e3, "free1": 300.0}
    prior = {**{f"base/{a}": (0.0, 0.01) for a in ("tx", "ty", "tz", "rx", "ry", "rz")},
             "offsets/mot1": (0.0, 0.005), "offsets/mot2": (0.0, 0.005),
             **{f"springs/{j}": (k, 0.2 * k) for j, k in springs.items()},
             "lateral/free2/a": (3000.0, 600.0), "lateral/free2/b": (3000.0, 600.0), "beams/part_3": (1.0, 0.3)}
    return {"mech": mech, "markers": ["effector"], "springs": springs, "prior": prior, "noise": 2e-4,
            "parameters": {"base": None, "offsets": None, "geometry": ["free1"], "springs": None,
                           "lateral": ["free2"], "beams": None, "masses": ["free2"]},
            "motors": rng.uniform(-0.3, 0.3, (n, 2)),
            "loads": {"effector": np.c_[rng.normal(0.0, 30.0, (n, 3)), np.zeros((n, 3))]}}


def leg(n: int = 30, seed: int = 7) -> dict:
    """Gepetto's Cassie-like leg (five motors, two 6D closures through rods): base, offsets,
    springs, the knee motor's lateral hinges and the knee's mass; markers on the foot and its
    frame; n poses, loads of 20 N at the foot, 0.1 mm noise."""
    mech = _quiet_urdf(ROBOTS / "cassie_like" / "robot.urdf")
    rng = np.random.default_rng(seed)
    springs = {"motor_hip1": 300.0, "motor_hip2": 300.0, "motor_tigh": 300.0, "motor_knee": 300.0,
               "motor_ankle": 100.0}
    prior = {**{f"springs/{j}": (k, 0.2 * k) for j, k in springs.items()},
             "lateral/motor_knee/a": (3000.0, 600.0), "lateral/motor_knee/b": (3000.0, 600.0)}
    return {"mech": mech, "markers": ["foot", "foot_frame"], "springs": springs, "prior": prior, "noise": 1e-4,
            "locked": LEG_LOCKED,
            "parameters": {"base": None, "offsets": None, "springs": None, "lateral": ["motor_knee"],
                           "masses": ["free_knee"]},
            "motors": rng.uniform(-0.2, 0.2, (n, 5)),
            "loads": {"foot": np.c_[rng.normal(0.0, 20.0, (n, 3)), np.zeros((n, 3))]}}


def ur5() -> dict:
    """The UR5 of example-robot-data as a tree with joint springs: base, offsets, the last joint's
    placement, springs, the shoulder's lateral hinges and the forearm's mass; 60 configurations,
    loads of 30 N at the tool, 0.1 mm noise."""
    import example_robot_data as erd

    from h4pin.mechanism import Mechanism
    from h4pin.studies.serial import UR5_JOINT_STIFFNESS

    model = erd.load("ur5").model
    names = list(model.names)[1:]
    springs = {n: float(k) for n, k in zip(names, UR5_JOINT_STIFFNESS, strict=True)}
    rng = np.random.default_rng(3)
    n = 60
    prior = {**{f"springs/{j}": (k, 0.3 * k) for j, k in springs.items()},
             **{f"offsets/{j}": (0.0, 0.01) for j in springs},
             **{f"base/{a}": (0.0, 0.02) for a in ("tx", "ty", "tz", "rx", "ry", "rz")},
             "lateral/shoulder_lift_joint/a": (3e5, 6e4), "lateral/shoulder_lift_joint/b": (3e5, 6e4)}
    return {"mech": Mechanism(model, [], [], name="ur5"), "markers": ["tool0"], "springs": springs,
            "prior": prior, "noise": 1e-4,
            "parameters": {"base": None, "offsets": None, "geometry": ["wrist_3_joint"], "springs": None,
                           "lateral": ["shoulder_lift_joint"], "masses": ["elbow_joint"]},
            "configurations": rng.uniform(-1.5, 1.5, (n, 6)),
            "loads": {"tool0": np.c_[rng.normal(0.0, 30.0, (n, 3)), np.zeros((n, 3))]}}


DESIGNS = {"five-bar with a beam": five_bar, "Cassie-like leg": leg, "UR5": ur5}


def h4() -> dict:
    """The elastic H4 (its 16 elastic joints): base, the actuators' offsets, the stiffness of its
    actuators and forearms' torsion, two actuators' placements; 60 poses over the central
    workspace (x, y within 60 mm, z within 30 mm, theta within 0.15 rad), loads of 20 N at D,
    20 um noise (a laser tracker's)."""
    import h4pin
    from h4pin.kinematics.closed_form import centre_pose

    robot = h4pin.load()
    em = h4pin.elastic_model(robot)
    mech = em.mechanism
    idx = [mech.model.joints[mech.model.getJointId(a)].idx_q for a in mech.actuated]
    rng = np.random.default_rng(0)
    n = 60
    poses = centre_pose(robot) + rng.uniform(-1.0, 1.0, (n, 4)) * [0.06, 0.06, 0.03, 0.15]
    springs = dict(em.stiffness)
    fitted = [j for j in springs if j.startswith(("actuator_", "forearm_"))]
    prior = {**{f"springs/{j}": (k, 0.3 * k) for j, k in springs.items()},
             **{f"base/{a}": (0.0, 0.01) for a in ("tx", "ty", "tz", "rx", "ry", "rz")},
             **{f"offsets/{a}": (0.0, 0.01) for a in mech.actuated}}
    return {"mech": mech, "markers": ["D"], "springs": springs, "prior": prior, "noise": 2e-5,
            "parameters": {"base": None, "offsets": None, "springs": fitted, "geometry": ["actuator_1", "actuator_3"]},
            "motors": np.array([em.configuration(x)[idx] for x in poses]),
            "loads": {"D": np.c_[rng.normal(0.0, 20.0, (n, 3)), np.zeros((n, 3))]}}


def session(design: dict, seed: int = 0):
    """``(measurements, truth)`` of one synthetic tracker session of a design."""
    from h4pin.mechanism import calibration as cal

    d = dict(design)
    return cal.synthetic(d.pop("mech"), d.pop("parameters"), d.pop("markers"), seed=seed, **d)


def fit_options(design: dict) -> dict:
    """The calibration's options of a design (its springs, prior, held joints)."""
    return {k: design[k] for k in ("springs", "prior", "locked") if k in design}


#: The leg's stage table: the groups each stage adds.
STAGES = [["base"], ["offsets"], ["springs"], {"lateral": ["motor_knee"]}, {"masses": ["free_knee"]}]


def stage_table(out: Path | None) -> None:
    from h4pin import plots
    from h4pin.mechanism import calibration as cal

    design = leg(n=60)
    meas, truth = session(design, seed=1)
    start = time.perf_counter()
    rows = cal.stages(design["mech"], meas, STAGES, holdout=0.25, **fit_options(design))
    print(f"\nCassie-like leg, 60 poses (15 held out), markers foot and foot_frame, 0.1 mm noise "
          f"({time.perf_counter() - start:.0f} s):")
    print(cal.stage_table(rows))
    last = rows[-1].calibration
    print(f"noise estimated {last.noise * 1e3:.4f} mm (true 0.1000); not identified: {last.unidentifiable or 'none'}")
    z = {n: (last.values[n] - truth[n]) / last.std[n] for n in truth}
    print(f"largest |value - truth| / std: {max(abs(v) for v in z.values()):.2f} ({max(z, key=lambda n: abs(z[n]))})")
    if out is not None:
        print("wrote", plots.calibration(rows, out / "calibration_stages.png"))


def coverage(runs: int, workers: int) -> None:
    from h4pin.mechanism import calibration as cal

    for name, make in DESIGNS.items():
        design = make()
        d = dict(design)
        start = time.perf_counter()
        cv = cal.coverage(d.pop("mech"), d.pop("parameters"), d.pop("markers"), runs=runs, workers=workers, **d)
        print(f"\n{name}: {runs} experiments ({time.perf_counter() - start:.0f} s on {workers} workers)")
        print(cv.table())
        held = sorted({u for run in cv.unidentifiable for u in run}, key=len)[:4]
        print("not identified (first run's):", "; ".join(cv.unidentifiable[0]) or "none", f"[{len(held)} kinds]")


def h4_experiment() -> None:
    from h4pin.mechanism import calibration as cal

    design = h4()
    meas, truth = session(design, seed=0)
    start = time.perf_counter()
    c = cal.calibrate(design["mech"], meas, design["parameters"], **fit_options(design))
    print(f"\nThe H4, 60 poses, tracker on D, 20 um noise ({time.perf_counter() - start:.0f} s): "
          f"error {c.summary()}")
    print(f"{'parameter':<32}{'truth':>12}{'fitted':>12}{'std':>10}{'prior std':>11}{'z':>7}")
    for p in c.model.params:
        n = p.name
        prior = design["prior"].get(n, (0.0, p.sigma))[1]
        print(f"{n:<32}{truth[n]:>12.5g}{c.values[n]:>12.5g}{c.std[n]:>10.3g}{prior:>11.3g}"
              f"{(c.values[n] - truth[n]) / c.std[n]:>7.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=ROOT / "docs")
    parser.add_argument("--skip-h4", action="store_true")
    args = parser.parse_args()
    stage_table(args.out)
    coverage(args.runs, args.workers)
    if not args.skip_h4:
        h4_experiment()


if __name__ == "__main__":
    main()
