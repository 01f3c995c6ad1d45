# SPDX-License-Identifier: Apache-2.0
"""
An atlas over the motors: the five-bar's compliance map
=======================================================

:func:`h4pin.mechanism.atlas.atlas` maps any closed-loop robot over a grid of its motor
positions: at each point it closes the loops by continuation from its neighbour and computes the
compliance of an output frame. The result is an :class:`xarray.Dataset` (the ``studies`` extra),
one dimension per motor, with a status where the loops do not close or a motion is unrestrained.
Here Gepetto's five-bar on a small 15 x 15 grid.
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import h4pin
from h4pin.mechanism import atlas

# the checkout's third-party robots, from the working directory (the repository's root, or examples/)
ROBOTS = next(p / "tests" / "robots" for p in (Path.cwd(), *Path.cwd().parents) if (p / "tests" / "robots").is_dir())
five_bar = h4pin.Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")
reference = five_bar.assemble(five_bar.reference + 0.05)
axes = atlas.motor_axes(five_bar, reference=reference, count=15)  # each motor +- its default span
springs = {"mot1": 2.0e3, "mot2": 3.0e3}
ds = atlas.atlas(five_bar, "closedloop3D_1B", axes, springs, progress=False)
print(ds)

# %%
# The worst-direction compliance (um/N) over the grid; blank where the grid point has no valid
# compliance (the status says why).
first, second = atlas.motors(ds)
worst = ds.compliance_max.transpose(first, second).values * 1e6
fig, ax = plt.subplots(figsize=(6, 4.8))
mesh = ax.pcolormesh(ds[second].values, ds[first].values, worst, shading="nearest")
fig.colorbar(mesh, label="worst-direction compliance [um/N]")
ax.set_xlabel(f"{second} [rad]")
ax.set_ylabel(f"{first} [rad]")
ax.set_title(f"{five_bar.name}: {int((ds.status == atlas.OK).sum())} of {ds.status.size} points hold")
fig.tight_layout()
plt.show()
print("range:", np.nanmin(worst).round(2), "to", np.nanmax(worst).round(2), "um/N")
