# SPDX-License-Identifier: Apache-2.0
"""An atlas slice (:mod:`h4pin.studies.atlas`) in the meshcat viewer, as a coloured point cloud.

Each reachable grid point (status 0) of the chosen theta is drawn at its position of D, coloured
(viridis) by a quantity of the atlas -- by default the worst-direction compliance, the largest
eigenvalue of K_tt of eq. 30 (Company, Pierrot, Fauroux, ICRA 2005). The quantities are those
the atlas holds (:func:`quantities`: its data variables on the grid, with their ``units``), so an
atlas with ``first_frequency`` or one a later release extends is drawn as it is stored::

    from h4pin import load

    from h4pin.studies import atlas

    from h4pin.io import viewer

    from h4pin.io import viewer_atlas
    h4 = load()
    ds = atlas.atlas(h4, x, y, z)
    with viewer.scene(h4) as scene:
        viewer_atlas.show_atlas(scene, ds, "compliance_max")
        scene.write_html("atlas.html")
"""

from __future__ import annotations

import matplotlib
import meshcat.geometry as mg
import numpy as np

from h4pin.extras import require

require("xarray", extra="studies", what="the atlas point cloud (h4pin.io.viewer_atlas)")
import xarray as xr  # noqa: E402

from h4pin import verdicts  # noqa: E402
from h4pin.errors import ParameterError  # noqa: E402
from h4pin.mechanism.scene import Scene  # noqa: E402

_GRID = {"theta", "z", "y", "x"}


def quantities(ds: xr.Dataset) -> dict[str, str]:
    """The quantities an atlas holds and their units: every data variable on the (theta, z, y, x)
    grid but the verdicts (``status``), with its ``units`` attribute ("" without one)."""
    return {str(name): str(var.attrs.get("units", "")) for name, var in ds.data_vars.items()
            if name != "status" and set(var.dims) == _GRID}


def atlas_points(ds: xr.Dataset, quantity: str = "compliance_max", theta: float | None = None,
                 log: bool | None = None) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Positions (3, n) in m and colours (3, n) in [0, 1] of the reachable points of one theta
    slice (the nearest to ``theta``; default the first), and the colour range (lo, hi) in the
    quantity's SI unit. Colours are viridis of the value (of its log if ``log``; default: log when
    every value is positive and the 1st to 99th percentile span more than a decade), spread over
    the 1st to 99th percentile. ``quantity``: one of :func:`quantities`."""
    known = quantities(ds)
    if quantity not in known:
        raise ParameterError(f"quantity must be one of the atlas's {tuple(known)}, got {quantity!r}")
    sl = ds.isel(theta=0) if theta is None else ds.sel(theta=theta, method="nearest")
    z, y, x = np.meshgrid(sl.z.values, sl.y.values, sl.x.values, indexing="ij")
    ok = sl.status.values == verdicts.OK
    if not np.any(ok):
        raise ParameterError("the atlas slice has no reachable point (status 0)")
    values = sl[quantity].values[ok]
    if log is None:
        lo, hi = np.percentile(values, [1, 99])
        log = bool(np.all(values > 0) and hi > 10 * lo)
    shown = np.log(values) if log else values
    lo, hi = np.percentile(shown, [1, 99])
    t = np.clip((shown - lo) / (hi - lo), 0.0, 1.0) if hi > lo else np.full(shown.shape, 0.5)
    colours = matplotlib.colormaps["viridis"](t)[:, :3].T
    positions = np.stack([x[ok], y[ok], z[ok]])
    back = np.exp if log else (lambda v: v)
    return positions, colours, float(back(lo)), float(back(hi))


def show_atlas(scene: Scene, ds: xr.Dataset, quantity: str = "compliance_max", theta: float | None = None,
               size: float = 0.006, path: str = "atlas") -> tuple[float, float]:
    """Draw :func:`atlas_points` into ``scene`` (a :class:`h4pin.mechanism.scene.Scene`) as a
    ``meshcat.geometry.PointCloud`` of point size ``size`` (m); add a legend line.

    Returns:
        The colour range (lo, hi) in the quantity's SI unit.
    """
    positions, colours, lo, hi = atlas_points(ds, quantity, theta)
    cloud = mg.PointCloud(positions.astype(np.float32), colours.astype(np.float32), size=size)
    scene.vis[path].set_object(cloud)
    unit = quantities(ds)[quantity]
    th = float(ds.theta.values[0] if theta is None else ds.sel(theta=theta, method="nearest").theta)
    scene.legend.append(f"atlas: {quantity} at theta = {th:.2f} rad, {positions.shape[1]} reachable points, "
                        f"{lo:.3g} (dark) to {hi:.3g} (yellow) {unit}")
    return lo, hi
