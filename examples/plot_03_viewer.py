# SPDX-License-Identifier: Apache-2.0
"""
The viewer: a page of the robot, its deflection and its ellipsoids
==================================================================

:func:`h4pin.io.viewer.show` draws the H4 in meshcat: the robot at its pose, the green
translational compliance ellipsoid at the tool point D, the red ghost deflected under a load
(exaggerated, the factor in the legend) and, with ``field=True``, the ellipsoids over the
workspace. The scene owns a meshcat server; used as a context manager it stops the server at
the end, and :meth:`~h4pin.mechanism.scene.Scene.write_html` leaves a self-contained page that
works offline. Here the page is rendered by headless Chromium when it is installed.
"""

import shutil
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import h4pin
from h4pin.io import viewer
from h4pin.mechanism.scene import screenshot

h4 = h4pin.load("prototype")
folder = Path(tempfile.mkdtemp(prefix="h4pin-viewer-"))
with viewer.show(h4, load=[0, 0, -10], field=True) as scene:  # centre pose, 10 N downwards at D
    page = scene.write_html(folder / "h4.html")
    print("\n".join(scene.legend))
print(f"{page.name}: {page.stat().st_size / 1e6:.1f} MB, the server stopped: {scene.server_pid is None}")

# %%
# The page in a browser (Debian's ``chromium``, software WebGL): open ``h4.html`` yourself to
# turn the robot around.
if shutil.which("chromium"):
    png = screenshot(page, folder / "h4.png", size=(900, 650))
    fig, ax = plt.subplots(figsize=(9, 6.5))
    ax.imshow(plt.imread(png))
    ax.set_axis_off()
    fig.tight_layout()
    plt.show()
else:
    print("no chromium on this machine: the page is not rendered here")
shutil.rmtree(folder)
