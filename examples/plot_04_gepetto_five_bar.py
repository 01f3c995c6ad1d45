# SPDX-License-Identifier: Apache-2.0
"""
A robot from Gepetto's files: the five-bar of example-parallel-robots
=====================================================================

:meth:`h4pin.Mechanism.from_urdf` reads a URDF and the YAML sidecar of Gepetto's closed-loop
toolbox (``closed_loop`` frame pairs, ``type``, ``name_mot``), as that toolbox's loader does.
The planar five-bar ``5bar_linkage_iso3d`` (BSD-3-Clause, ``tests/robots/README.md``) has two
motors and one loop closed by a point. With a servo spring on each motor, its compliance at the
closure point, its natural frequencies with the file's inertias, and the compliance ellipse over
a range of one motor.
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pinocchio as pin

import h4pin

# the checkout's third-party robots, from the working directory (the repository's root, or examples/)
ROBOTS = next(p / "tests" / "robots" for p in (Path.cwd(), *Path.cwd().parents) if (p / "tests" / "robots").is_dir())
five_bar = h4pin.Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")  # robot.yaml beside it
print(five_bar)
q = five_bar.assemble(pin.neutral(five_bar.model) + 0.05)  # q = 0 is not assembled in the file
print("closure errors (m, rad):", five_bar.closure_errors(q))

springs = {"mot1": 2.0e3, "mot2": 3.0e3}  # N m/rad
C = five_bar.compliance(q, springs, ["closedloop3D_1B"])
print("compliance at the closure point [um/N]:\n", (C[:3, :3] * 1e6).round(3))
print("natural frequencies [Hz]:", five_bar.modes(q, springs).frequencies.round(2))

# %%
# Over a range of the first motor (the other held), by continuation: ``assemble(motors=M)`` closes
# each row of motor positions from the one before, and one ``compliance`` call takes the batch.
i1, i2 = (five_bar.model.joints[five_bar.model.getJointId(m)].idx_q for m in five_bar.actuated)
start = q[[i1, i2]]
motors = np.column_stack([start[0] + np.linspace(-0.3, 0.3, 7), np.full(7, start[1])])
Q = five_bar.assemble(motors=motors)
Cs = five_bar.compliance(Q, springs, ["closedloop3D_1B"])
data = five_bar.model.createData()
fid = five_bar.model.getFrameId("closedloop3D_1B")
points = []
for qk in Q:
    pin.framesForwardKinematics(five_bar.model, data, qk)
    points.append(data.oMf[fid].translation.copy())
points = np.array(points)
plane = np.argsort(np.abs(Cs[0, :3, :3]).diagonal())[::-1][:2]  # the linkage's plane: where it gives way
plane.sort()
force = 200.0  # N, in every direction of the plane
t = np.linspace(0, 2 * np.pi, 60)
fig, ax = plt.subplots(figsize=(6, 5))
for p, Ck in zip(points, Cs, strict=True):
    deflection = Ck[np.ix_(plane, plane)] @ (force * np.array([np.cos(t), np.sin(t)]))
    ax.plot(p[plane[0]] + deflection[0], p[plane[1]] + deflection[1], color="tab:green")
    ax.plot(p[plane[0]], p[plane[1]], "k.")
ax.set_aspect("equal")
ax.set_xlabel(f"{'xyz'[plane[0]]} [m]")
ax.set_ylabel(f"{'xyz'[plane[1]]} [m]")
ax.set_title(f"deflection under {force:.0f} N, any direction (to scale)")
fig.tight_layout()
plt.show()
