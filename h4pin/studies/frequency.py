# SPDX-License-Identifier: Apache-2.0
"""The first natural frequency over the workspace and across designs (:func:`h4pin.modes`).

* :func:`first_frequency`: the lowest natural frequency (Hz) of the elastic robot at many poses
  (actuators locked, link inertias from the URDF, an optional payload), NaN where the robot
  cannot take the pose or it is singular (the verdicts of :func:`h4pin.compliance`);
* :func:`frequency_map`: the same over an x-y grid at one height and angle, with the verdicts,
  and :func:`plot_map`;
* :func:`design_frequencies` and :func:`frequency_pareto`: the first frequency at the centre
  pose of each design of a sweep (:mod:`h4pin.studies.sweep`), and the designs for which no
  other one has both a higher first frequency and a larger workspace.

Cost: one :func:`h4pin.modes` per pose, about 2.5 ms on one core (the configuration, Pinocchio's
Jacobians and ``crba`` on the 44-dof elastic model, two SVDs and an 8-to-16-dof eigenproblem);
the verdicts come first from the compiled kernel, so refused poses cost nothing. A design adds
the URDF generation, the elastic model and its Pinocchio data, about 40 ms. Both are timed by
``scripts/bench.py`` (``--modes``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from h4pin import verdicts
from h4pin.elastic import Payload, elastic_model, modes
from h4pin.errors import H4Error, ParameterError
from h4pin.files import save_figure
from h4pin.kinematics.closed_form import as_poses, centre_pose
from h4pin.stiffness.api import compliance


def first_frequency(robot: Any, poses: np.ndarray, payload: Payload | None = None, *,
                    progress: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Lowest natural frequency (Hz) at each pose, and the verdicts.

    Args:
        robot: an :class:`h4pin.H4` (its elastic model is built once here).
        poses: (N, 4) or (4,) [x, y, z, theta] (m, rad).
        payload: an :class:`h4pin.Payload` on the plate, or None.
        progress: show a progress bar.

    Returns:
        (frequency (N,) Hz, NaN where status is not 0; status (N,) int8, :mod:`h4pin.verdicts`).
    """
    x = as_poses(poses)
    x = x[None] if x.ndim == 1 else x
    status = compliance(robot, x, "consistent", on_error="nan").status.astype(np.int8)
    out = np.full(len(x), np.nan)
    em = elastic_model(robot)
    for k in tqdm(np.flatnonzero(status == verdicts.OK), desc="modes", unit="pose", disable=not progress):
        try:
            out[k] = modes(em, x[k], payload).frequencies[0]
        except H4Error:  # a pose the elastic model finds singular: as the verdict would say
            status[k] = verdicts.SINGULAR
    return out, status


def frequency_map(h4: Any, x: Any, y: Any, z: float | None = None, theta: float = 0.0,
                  payload: Payload | None = None, *, progress: bool = True):
    """First frequency over the grid y x x at height ``z`` (default: the centre pose's) and angle
    ``theta``: an :class:`xarray.Dataset` with ``first_frequency`` (Hz) and ``status``."""
    from h4pin.extras import require

    require("xarray", extra="studies", what="frequency maps")
    import xarray as xr

    xs, ys = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (x, y))
    if xs.ndim != 1 or ys.ndim != 1 or not (np.all(np.isfinite(xs)) and np.all(np.isfinite(ys))):
        raise ParameterError("x and y must be 1-D arrays of finite values (m)")
    zc = float(centre_pose(h4)[2]) if z is None else float(z)
    gy, gx = np.meshgrid(ys, xs, indexing="ij")
    poses = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, zc), np.full(gx.size, float(theta))], axis=1)
    freq, status = first_frequency(h4, poses, payload, progress=progress)
    shape = (len(ys), len(xs))
    return xr.Dataset(
        {"first_frequency": (("y", "x"), freq.reshape(shape), {"units": "Hz", "long_name": "first natural frequency"}),
         "status": (("y", "x"), status.reshape(shape), {"units": "1", "long_name": "verdict (h4pin.verdicts)"})},
        coords={"x": ("x", xs, {"units": "m"}), "y": ("y", ys, {"units": "m"})},
        attrs={"z": zc, "theta": float(theta), "payload_kg": 0.0 if payload is None else payload.mass,
               "h4pin": "frequency_map"})


def plot_map(ds, path: str | Path) -> Path:
    """The map of :func:`frequency_map` as a PNG: colour = first frequency (Hz), the workspace
    boundary (status 0) in black."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.6, 4.6), layout="constrained")
    ax = fig.subplots()
    x, y = ds.x.values * 1e3, ds.y.values * 1e3
    mesh = ax.pcolormesh(x, y, ds.first_frequency.values, shading="nearest", cmap="viridis")
    reach = (ds.status.values == verdicts.OK).astype(float)
    if 0 < reach.sum() < reach.size and len(x) > 1 and len(y) > 1:
        ax.contour(x, y, reach, levels=[0.5], colors="k", linewidths=1.2)
    fig.colorbar(mesh, ax=ax).set_label("first natural frequency [Hz]")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_aspect("equal")
    payload = ds.attrs.get("payload_kg", 0.0)
    ax.set_title(f"H4 first natural frequency, z = {ds.attrs['z'] * 1e3:.0f} mm, theta = {ds.attrs['theta']:.2f} rad"
                 + (f", payload {payload:g} kg" if payload else ""), fontsize=9)
    return save_figure(fig, path, dpi=110)


def design_frequencies(rows: np.ndarray, payload: Payload | None = None, *, progress: bool = True) -> np.ndarray:
    """First frequency (Hz) at the centre pose (all actuators at 45 deg) of each design, rows of
    :func:`h4pin.studies.sweep.designs`; NaN where a design cannot be built or is singular there."""
    from h4pin.robot import load
    from h4pin.studies.sweep import params_of

    out = np.full(len(rows), np.nan)
    for d, row in enumerate(tqdm(rows, desc="designs", unit="design", disable=not progress)):
        try:
            h4 = load(params_of(row))
            out[d] = modes(elastic_model(h4), centre_pose(h4), payload).frequencies[0]
        except H4Error:
            continue
    return out


def frequency_pareto(res: dict[str, np.ndarray], rows: np.ndarray, payload: Payload | None = None, *,
                     limit: int | None = 200, progress: bool = True) -> dict[str, np.ndarray]:
    """The first frequency of a sweep's designs that reach the whole task box (at most ``limit``,
    the stiffest first), and the Pareto front of (first frequency, workspace volume).

    Args:
        res: a sweep's results (:func:`h4pin.studies.sweep.load`): ``reach_all``, ``worst``, ``volume``.
        rows: the sweep's designs (:func:`h4pin.studies.sweep.designs`).

    Returns:
        ``design`` (indices), ``frequency`` (Hz), ``volume`` (m^3), ``front`` (indices into
        ``design`` of the front, by rising frequency).
    """
    cand = np.flatnonzero(res["reach_all"] & np.isfinite(res["worst"]))
    cand = cand[np.argsort(res["worst"][cand], kind="stable")]
    if limit is not None:
        cand = cand[:limit]
    freq = design_frequencies(rows[cand], payload, progress=progress)
    vol = res["volume"][cand]
    return {"design": cand, "frequency": freq, "volume": vol, "front": pareto_indices(freq, vol)}


def pareto_indices(freq: np.ndarray, vol: np.ndarray) -> np.ndarray:
    """Indices of the points (finite ones) that no other has both a higher-or-equal frequency and
    a higher-or-equal volume, one of them strictly; by rising frequency."""
    ok = np.flatnonzero(np.isfinite(freq) & np.isfinite(vol))
    order = ok[np.lexsort((-vol[ok], -freq[ok]))]  # highest frequency first, then largest volume
    front, best = [], -np.inf
    for i in order:
        if vol[i] > best:
            front.append(i)
            best = vol[i]
    return np.array(front[::-1], dtype=int)


def plot_frequency_pareto(par: dict[str, np.ndarray], path: str | Path) -> Path:
    """First frequency against workspace volume, the front highlighted (PNG)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.6, 4.2), layout="constrained")
    ax = fig.subplots()
    ax.scatter(par["volume"] * 1e3, par["frequency"], s=10, c="0.6", label="designs reaching the task box")
    f = par["front"]
    ax.plot(par["volume"][f] * 1e3, par["frequency"][f], "o-", c="C3", label="Pareto front")
    ax.set_xlabel("workspace volume [dm^3]")
    ax.set_ylabel("first natural frequency [Hz]")
    ax.legend(fontsize=8)
    return save_figure(fig, path, dpi=110)


__all__ = ["design_frequencies", "first_frequency", "frequency_map", "frequency_pareto", "pareto_indices",
           "plot_frequency_pareto", "plot_map"]
