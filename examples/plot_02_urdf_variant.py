# SPDX-License-Identifier: Apache-2.0
"""
A variant of the H4, written as a URDF and loaded back
======================================================

:class:`h4pin.H4Params` holds every dimension and spring of the robot, validated. Change one
(here the forearms, 300 mm instead of the prototype's 260), write the robot as a URDF file,
load the file as any other H4, and compare its compliance with the prototype's along a vertical
line through the workspace.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import h4pin
from h4pin.description.urdf import write_urdf
from h4pin.kinematics.closed_form import centre_pose

prototype = h4pin.load("prototype")
params = h4pin.H4Params(r=0.30)  # forearm length (m), the same for the four legs

with tempfile.TemporaryDirectory() as folder:
    path = write_urdf(params, Path(folder) / "h4_long_forearms.urdf")
    print(f"wrote {path.name}: {path.stat().st_size} bytes")
    longer = h4pin.load(path)  # read back through Pinocchio, as any URDF would be
print(longer.geometry.r)  # forearm lengths read from the file, per leg (m)

# %%
# The compliance along z at the centre of the workspace, and its diagonal (um/N), for both.
for name, robot in (("prototype", prototype), ("forearms 300 mm", longer)):
    x = centre_pose(robot)
    diag = h4pin.compliance(robot, x).translational.diagonal() * 1e6
    print(f"{name:16s} D at z = {x[2] * 1e3:8.2f} mm, compliance diagonal {diag.round(1)} um/N")

# %%
# Along a vertical line through the centre: poses are (N, 4) arrays [x, y, z, theta], and one call
# computes them all. ``on_error="nan"`` leaves unreachable poses as NaN rows instead of raising.
z = np.linspace(-0.70, -0.45, 26)
fig, ax = plt.subplots(figsize=(6, 3.8))
for name, robot in (("prototype", prototype), ("forearms 300 mm", longer)):
    poses = np.column_stack([np.zeros_like(z), np.zeros_like(z), z, np.zeros_like(z)])
    res = h4pin.compliance(robot, poses, on_error="nan")
    worst = np.linalg.eigvalsh(res.translational).max(axis=-1) * 1e6
    ax.plot(z * 1e3, worst, label=name)
ax.set_xlabel("height of D, z [mm]")
ax.set_ylabel("worst-direction compliance [um/N]")
ax.legend()
fig.tight_layout()
plt.show()
