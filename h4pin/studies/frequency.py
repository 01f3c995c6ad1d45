# SPDX-License-Identifier: Apache-2.0
"""The first natural frequency over the workspace and across designs (:func:`h4pin.modes`).

* :func:`first_frequency`: the lowest natural frequency (Hz) of the elastic robot at many poses
  (actuators locked, link inertias from the URDF, an optional payload), NaN where the robot
  cannot take the pose or it is singular (the verdicts of :func:`h4pin.compliance`);
* :func:`frequency_map`: the same over an x-y grid at one height and angle, with the verdicts,
  and :func:`h4pin.plots.frequency_map` draws it;
* :func:`design_frequencies` and :func:`frequency_pareto`: the first frequency at the centre
  pose of each design of a sweep (:mod:`h4pin.studies.sweep`), and the designs for which no
  other one has both a higher first frequency and a larger workspace.

Cost: the compiled twin of :func:`h4pin.modes` (:mod:`h4pin.stiffness.frequencies`), about 30 us a
pose on one core (the Pinocchio route it equals takes 2.5 ms); a design of a sweep adds its mass
model from its parameters, without a URDF (:func:`h4pin.description.urdf.mass_model`), about 4 ms
(``Spec.frequency`` of :mod:`h4pin.studies.sweep`). Both are timed by ``scripts/bench.py``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from tqdm import tqdm

from h4pin import limits, verdicts
from h4pin.errors import H4Error, ParameterError
from h4pin.kinematics.closed_form import as_poses, centre_pose
from h4pin.mechanism import Payload
from h4pin.vibration import modes


def first_frequency(robot: Any, poses: np.ndarray, payload: Payload | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lowest natural frequency (Hz) at each pose, and the verdicts (:func:`h4pin.modes`).

    Args:
        robot: an :class:`h4pin.H4`.
        poses: (N, 4) or (4,) [x, y, z, theta] (m, rad).
        payload: an :class:`h4pin.Payload` on the plate, or None.

    Returns:
        (frequency (N,) Hz, NaN where status is not 0; status (N,) int8, :mod:`h4pin.verdicts`).
    """
    limits.check_springs(robot, "robot")  # a robot given as parameters (an H4 checked its own); the payload: modes
    x = as_poses(poses)
    x = x[None] if x.ndim == 1 else x
    check_size(len(x))
    out = modes(robot, x, payload)
    first, status = out.first.copy(), out.status.astype(np.int8)
    ok = status == verdicts.OK
    limits.warn_non_finite("first natural frequency at the poses the robot takes",
                           int(np.sum(ok & ~(np.isfinite(first) & (first > 0)))), int(ok.sum()),
                           "a frequency of 0 Hz or none: check the robot's springs and masses")
    return first, status


def check_size(n: int, what: str = "first natural frequency") -> None:
    """Refuse, before any work, ``n`` poses whose natural frequencies do not fit in memory
    (:data:`h4pin.limits.MODES_BYTES_PER_POSE`; limit ``H4PIN_MEMORY_LIMIT``).

    Raises:
        h4pin.limits.TooLargeError: over the limit (a :class:`h4pin.ParameterError`).
    """
    n = limits.count(n)
    limits.check_size(f"{what}: {n:,} poses", n * limits.MODES_BYTES_PER_POSE, n / limits.MODES_POSES_PER_S,
                      "use fewer poses (a coarser grid)")


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
    check_size(len(xs) * len(ys), "frequency map")
    zc = float(centre_pose(h4)[2]) if z is None else float(z)
    gy, gx = np.meshgrid(ys, xs, indexing="ij")
    poses = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, zc), np.full(gx.size, float(theta))], axis=1)
    freq, status = first_frequency(h4, poses, payload)
    shape = (len(ys), len(xs))
    return xr.Dataset(
        {"first_frequency": (("y", "x"), freq.reshape(shape), {"units": "Hz", "long_name": "first natural frequency"}),
         "status": (("y", "x"), status.reshape(shape), {"units": "1", "long_name": "verdict (h4pin.verdicts)"})},
        coords={"x": ("x", xs, {"units": "m"}), "y": ("y", ys, {"units": "m"})},
        attrs={"z": zc, "theta": float(theta), "payload_kg": 0.0 if payload is None else payload.mass,
               "h4pin": "frequency_map"})


def design_frequencies(rows: np.ndarray, payload: Payload | None = None, *, progress: bool = True) -> np.ndarray:
    """First frequency (Hz) at the centre pose (all actuators at 45 deg) of each design, rows of
    :func:`h4pin.studies.sweep.designs`; NaN where a design cannot be built or is singular there.
    Each design's mass model comes from its parameters (no URDF is written)."""
    from h4pin.description.geometry import geometry_from_params
    from h4pin.stiffness import frequencies, kernel, pipeline
    from h4pin.studies.sweep import kernels, params_of

    out = np.full(len(rows), np.nan)
    work = frequencies.work_arrays(frequencies.NY, frequencies.NS)
    inter = np.empty((1, pipeline.NX))
    for d, kern in enumerate(tqdm(kernels(rows), desc="designs", unit="design", disable=not progress)):
        if kern is None:
            continue
        params = params_of(rows[d])
        try:
            x = kernel.readonly(centre_pose(geometry_from_params(params))[None])
        except H4Error:
            continue
        res = kernel.run_poses(kern, x, pipeline.CONSISTENT, kernel.empty_result(1, False, False), False, False, inter)
        MP, CF, CI = frequencies.pack_masses_params(params, payload)
        freq, counts = np.empty((1, 1)), np.empty((1, 2), dtype=np.int64)
        frequencies.frequencies_run(x, 0, 1, res.q, res.status, inter, kern.packed, kern.elements, MP, CF, CI,
                                    freq, counts, work)
        out[d] = freq[0, 0]
    return out


def frequency_pareto(res: dict[str, np.ndarray], rows: np.ndarray | None = None, payload: Payload | None = None, *,
                     limit: int | None = 200, progress: bool = True) -> dict[str, np.ndarray]:
    """The designs of a sweep that reach the whole task box, their first frequency, workspace
    volume and worst compliance, and the Pareto front of the three (first frequency and volume
    up, worst compliance down).

    Args:
        res: a sweep's results (:func:`h4pin.studies.sweep.load`): ``reach_all``, ``worst``,
            ``volume`` and, from a sweep with ``Spec.frequency``, ``first_frequency`` (the lowest
            over the task box's centre and corners: every design that reaches the box is used).
        rows: the sweep's designs, for a sweep without frequencies: the first frequency at the
            centre pose of at most ``limit`` designs (the stiffest first), :func:`design_frequencies`.
        payload: for ``rows`` (a sweep with frequencies has its own).

    Returns:
        ``design`` (indices), ``frequency`` (Hz), ``volume`` (m^3), ``worst`` (m/N), ``front``
        (indices into ``design`` of the front, by rising frequency).
    """
    cand = np.flatnonzero(res["reach_all"] & np.isfinite(res["worst"]))
    swept = "first_frequency" in res and np.any(np.isfinite(res["first_frequency"][cand]))
    if swept:
        cand = cand[np.isfinite(res["first_frequency"][cand])]
        freq = res["first_frequency"][cand]
    else:
        if rows is None:
            raise ParameterError("rows: a sweep without frequencies (Spec.frequency) needs its designs")
        cand = cand[np.argsort(res["worst"][cand], kind="stable")]
        if limit is not None:
            cand = cand[:limit]
        freq = design_frequencies(rows[cand], payload, progress=progress)
    vol, worst = res["volume"][cand], res["worst"][cand]
    return {"design": cand, "frequency": freq, "volume": vol, "worst": worst,
            "front": pareto_indices(freq, vol, worst)}


def pareto_indices(freq: np.ndarray, vol: np.ndarray, worst: np.ndarray | None = None) -> np.ndarray:
    """Indices of the points (finite ones) that no other dominates: at least as high a frequency,
    as large a volume (and, when given, as small a worst compliance), one of them strictly; by
    rising frequency."""
    cost = -np.stack([freq, vol] + ([] if worst is None else [-worst]), axis=1)  # all to minimise
    ok = np.flatnonzero(np.all(np.isfinite(cost), axis=1))
    order = ok[np.lexsort(cost[ok].T[::-1])]  # by the first objective, then the others
    front: list[int] = []
    kept = np.empty((0, cost.shape[1]))
    for i in order:  # a point is dominated only by one before it in this order
        c = cost[i]
        if kept.size and np.any(np.all(kept <= c, axis=1) & np.any(kept < c, axis=1)):
            continue
        if kept.size and np.any(np.all(kept == c, axis=1)):
            continue
        front.append(i)
        kept = np.vstack([kept, c])
    return np.array(sorted(front, key=lambda i: freq[i]), dtype=int)


__all__ = ["check_size", "design_frequencies", "first_frequency", "frequency_map", "frequency_pareto", "pareto_indices"]
