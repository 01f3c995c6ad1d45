# SPDX-License-Identifier: Apache-2.0
"""
A robot from an MJCF file: the xArm7 gripper
============================================

:meth:`h4pin.Mechanism.from_mjcf` reads an MJCF file as MuJoCo compiles it: ``connect`` and
``weld`` closures, joint couplings (``<equality><joint polycoef>``), the keyframe, ranges and the
joints' ``stiffness``. The UFACTORY xArm7 gripper (``tests/robots/mjcf/ufactory_xarm7/hand.xml``,
BSD-3-Clause, kinematics only) closes two four-bar linkages, and one coupling makes the right
driver follow the left. Its actuator drives a tendon, not a joint, so the motor is named here.
It needs Pinocchio 4 (closures read from MJCF) and the ``mujoco`` extra.
"""

from pathlib import Path

import numpy as np

import h4pin

# the checkout's third-party robots, from the working directory (the repository's root, or examples/)
ROBOTS = next(p / "tests" / "robots" for p in (Path.cwd(), *Path.cwd().parents) if (p / "tests" / "robots").is_dir())
hand = h4pin.Mechanism.from_mjcf(ROBOTS / "mjcf" / "ufactory_xarm7" / "hand.xml", actuated=["left_driver_joint"])
print(hand)
print("the file's joint springs (N m/rad):", hand.springs)
print("couplings:", [f"{c.joint1} follows {c.joint2}" for c in hand.couplings])

q = hand.assemble()  # from the file's keyframe
print("closure errors (m, rad):", hand.closure_errors(q))

# %%
# The file's springs and a servo of 5 N m/rad on the driver; the compliance of the left
# finger's frame (force at its origin, world axes), in mm/N, and the natural frequencies with the
# file's inertias.
springs = {**hand.springs, "left_driver_joint": 5.0}
C = hand.compliance(q, springs, ["left_finger"])
print("translational compliance [mm/N]:\n", (C[:3, :3] * 1e3).round(4))
print("its principal values [mm/N]:", (np.linalg.eigvalsh(C[:3, :3]) * 1e3).round(4))
print("natural frequencies [Hz]:", hand.modes(q, springs).frequencies.round(1))
