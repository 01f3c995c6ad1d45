# SPDX-License-Identifier: Apache-2.0
"""Workspace atlas: the compliance of eq. 30 (Company, Pierrot, Fauroux, ICRA 2005) over a grid.

Over a grid of poses -- x-y slices at chosen z and theta, or a 3-D box (many z) -- the compiled
kernel (:mod:`h4pin.stiffness.kernel`) gives K of eq. 30, J of eq. 8 and a verdict per pose, reduced here to

* ``compliance_max`` (m/N): the worst-direction translational compliance, largest eigenvalue of
  the symmetric part of the 3x3 block K_tt (a unit force along it deflects D by this much);
* ``stiffness_z`` (N/m): the stiffness along z, ``1 / K_zz``;
* ``isotropy`` (1): smallest over largest eigenvalue of the symmetric part of K_tt;
* ``cond_J`` (1): 2-norm condition number of J = Jx^-1 Jq (eq. 8; mixed units m/rad, rad/rad);
* ``cond_M1`` (1): the kernel's scaled 1-norm condition number of M1 (eq. 6);
* ``status`` (int8): the kernel's verdict, 0 where the pose is reachable, within the joint
  limits, bar-clear and regular (the quantities above are NaN elsewhere);
* with ``frequency=True``, ``first_frequency`` (Hz): the lowest natural frequency of the elastic
  robot (:mod:`h4pin.stiffness.frequencies`, about 30 us a pose on one core).

The result is an :class:`xarray.Dataset` with dims ``(theta, z, y, x)`` and units in the
attributes; :func:`h4pin.mechanism.store.save` writes it to NetCDF (``.nc``) or zarr (``.zarr``)
atomically, the store every atlas shares (a streamed ``.zarr`` atlas resumes after a kill), and
:func:`h4pin.plots.atlas_maps` draws one map per quantity with the workspace boundary (the
contour of status 0).
See ``docs/atlas.md``.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from h4pin.extras import require

require("xarray", extra="studies", what="the atlas (h4pin.studies.atlas)")
import xarray as xr  # noqa: E402

from h4pin import limits, verdicts  # noqa: E402
from h4pin.description.geometry import geometry_from_params  # noqa: E402
from h4pin.description.params import H4Params  # noqa: E402
from h4pin.errors import ParameterError  # noqa: E402
from h4pin.mechanism import store  # noqa: E402
from h4pin.stiffness import frequencies, kernel, pipeline  # noqa: E402
from h4pin.studies import _derived  # noqa: E402

#: The quantities of an atlas, with their units and a description.
QUANTITIES = dict(
    compliance_max=("m/N", "largest eigenvalue of the symmetric part of K_tt (worst-direction compliance)"),
    stiffness_z=("N/m", "stiffness along z, 1 / K_zz"),
    isotropy=("1", "smallest / largest eigenvalue of the symmetric part of K_tt"),
    cond_J=("1", "2-norm condition number of J = Jx^-1 Jq (eq. 8)"),
    cond_M1=("1", "1-norm condition number of M1 (eq. 6), rows / l_ij, rotation columns / mean bar length"),
)
#: The quantity an atlas adds with ``frequency=True``.
FREQUENCY = dict(first_frequency=("Hz", "lowest natural frequency (elastic robot, URDF inertias, actuators locked)"))


def _axis(name: str, values: Any) -> np.ndarray:
    a = np.atleast_1d(np.asarray(values, dtype=float))
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise ParameterError(f"{name} must be a non-empty 1-D array of finite values, got {values!r}")
    return a


def _geometry(source: Any) -> tuple[Any, str]:
    """The kernel of ``source`` (with the robot's optional elements), or the robot itself when
    the compiled pipeline does not take it (a robot whose parallelograms are not exact goes
    through :func:`h4pin.compliance`, :func:`_robot_chunks`)."""
    g = getattr(source, "geometry", None)  # an h4pin.H4: its geometry read from the URDF
    if g is not None:
        name = Path(str(getattr(source, "source", "H4"))).name
        elements = None if source.elements.off else source.elements
        return (kernel.for_geometry(g, elements), name) if g.ideal else (source, name)
    if isinstance(source, H4Params):
        return kernel.prepare(geometry_from_params(source)), "H4Params"
    return kernel.prepare(source), type(source).__name__


def _robot_chunks(h4: Any, chunks: Any, model: str) -> Any:
    """``(start, result)`` like :func:`h4pin.stiffness.kernel.iter_compliance`, from
    :func:`h4pin.compliance` (its elements included; J of eq. 8 from the closed forms): the
    route of robots whose parallelograms are not exact."""
    from h4pin.kinematics import closed_form as geometry
    from h4pin.stiffness.api import compliance
    from h4pin.stiffness.matrices import from_points

    start = 0
    for x in chunks:
        res = compliance(h4, x, model, on_error="nan")
        J = np.full((len(x), 4, 4), np.nan)
        ok = np.flatnonzero(res.status == verdicts.OK)
        if ok.size:
            state = geometry.solve(h4.geometry, x[ok], check=False).state
            J[ok] = from_points(h4.geometry, geometry.points(h4.geometry, state)).J
        yield start, kernel.KernelResult(res.matrix, res.q, res.condition, res.status.astype(np.int8), None, J)
        start += len(x)


def _regions(axes: dict[str, np.ndarray], block: tuple[int, ...], grid: tuple[int, ...], todo: Any) -> Any:
    """``(index, region, poses)`` of the blocks ``todo`` (flat indices over ``grid``): the
    region as (theta, z, y slice, x slice) and the poses (m, 4) [x, y, z, theta] in C order."""
    x, y, z, th = axes["x"], axes["y"], axes["z"], axes["theta"]
    for b in todo:
        t, k, j, i = np.unravel_index(b, grid)
        ys = slice(j * block[2], min(len(y), (j + 1) * block[2]))
        xs = slice(i * block[3], min(len(x), (i + 1) * block[3]))
        yy, xx = np.meshgrid(y[ys], x[xs], indexing="ij")
        poses = np.empty((xx.size, 4))
        poses[:, 0], poses[:, 1], poses[:, 2], poses[:, 3] = xx.ravel(), yy.ravel(), z[k], th[t]
        yield int(b), (int(t), int(k), ys, xs), poses


def _masses(source: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mass model and configuration constants of the natural frequencies
    (:mod:`h4pin.stiffness.frequencies`) of an :class:`h4pin.H4` or an :class:`h4pin.H4Params`."""
    from h4pin.kinematics import pinocchio as kin

    if isinstance(source, H4Params):
        return frequencies.pack_masses_params(source)
    if getattr(source, "geometry", None) is not None and source.geometry.ideal:
        return (frequencies.pack_masses(source), *kin.configuration_pack(source))
    raise ParameterError("frequency: the first natural frequency needs an h4pin.H4 whose parallelograms are exact or "
                         f"an h4pin.H4Params (the link inertias), got {type(source).__name__}")


def _kernel_chunks(kern: Any, parts: Any, model: str, chunk: int, masses: Any) -> Any:
    """``(start, result, first frequency)`` of the pipeline over ``parts`` (J of eq. 8 included;
    the first frequency, Hz, with ``masses`` from :func:`_masses`, else None). Arrays reused from
    one chunk to the next (:func:`h4pin.stiffness.kernel.iter_compliance`)."""
    if masses is None:
        for start, res in kernel.iter_compliance(kern, parts, model, chunk=chunk, jacobian=True):
            yield start, res, None
        return
    MP, CF, CI = masses
    work = frequencies.work_arrays(frequencies.NY, frequencies.NS)
    start = 0
    for part in parts:
        x = kernel.readonly(np.ascontiguousarray(part, dtype=float))
        n = len(x)
        res = kernel.empty_result(n, False, True)
        inter = np.empty((n, pipeline.NX))
        kernel.run_poses(kern, x, kernel.model_code(model), res, False, True, inter)
        freq, counts = np.empty((n, 1)), np.empty((n, 2), dtype=np.int64)
        frequencies.frequencies_run(x, 0, n, res.q, res.status, inter, kern.packed, kern.elements, MP, CF, CI, freq,
                                    counts, work)
        yield start, res, freq[:, 0]
        start += n


def _compute(kern: Any, regions: Any, model: str, chunk: int, write: Any, bar: Any, masses: Any = None) -> None:
    """Run the kernel (or the numpy path of a robot) over ``regions`` (:func:`_regions`) and call
    ``write(index, region, fields)`` per block, ``fields`` the quantities of :data:`QUANTITIES`
    (and :data:`FREQUENCY` with ``masses``, :func:`_masses`) and ``status`` as flat arrays
    (reused from one block to the next)."""
    blocks: list = []

    def poses():
        for item in regions:
            blocks.append(item)
            yield item[2]

    results = (_kernel_chunks(kern, poses(), model, chunk, masses) if isinstance(kern, kernel.Kernel)
               else ((s, r, None) for s, r in _robot_chunks(kern, poses(), model)))
    buf = {q: np.empty(0) for q in ("compliance_max", "isotropy", "stiffness_z", "cond_J")}
    n_ok = n_bad = 0
    for _, res, first in results:
        b, region, _ = blocks.pop(0)
        m = len(res.status)
        if len(buf["cond_J"]) < m:
            buf = {q: np.empty(m) for q in buf}
        f = {q: v[:m] for q, v in buf.items()}
        _derived.atlas_fields(np.ascontiguousarray(res.K), np.ascontiguousarray(res.J), res.status,
                              f["compliance_max"], f["isotropy"], f["stiffness_z"], f["cond_J"])
        f["cond_M1"] = res.condition
        f["status"] = res.status
        if first is not None:
            f["first_frequency"] = first
        ok = res.status == verdicts.OK
        n_ok += int(ok.sum())
        n_bad += int(np.sum(ok & ~np.isfinite(f["compliance_max"])))
        if first is not None:
            n_bad += int(np.sum(ok & ~(np.isfinite(first) & (first > 0))))
        write(b, region, f)
        bar.update(m)
    limits.warn_non_finite("atlas, at the poses the robot takes", n_bad, n_ok,
                           "check the robot's springs (h4pin.limits.SPRING_RANGES)")


def atlas(source: Any, x: Any, y: Any, z: Any, theta: Any = 0.0, model: str = "consistent", *,
          chunk: int = kernel.CHUNK, progress: bool = True, out: str | Path | None = None,
          frequency: bool = False, overwrite: bool = False) -> xr.Dataset:
    """The atlas over the grid ``theta x z x y x`` (1-D coordinates in m and rad).

    Args:
        source: An :class:`h4pin.H4` (any robot: the compiled kernel, or the numpy path for a
            robot whose parallelograms are not exact), an :class:`h4pin.H4Params`, a kernel
            geometry object or a :class:`h4pin.stiffness.kernel.Kernel`.
        x, y, z, theta: Grid coordinates (scalars or 1-D), m and rad.
        model: ``"paper"`` or ``"consistent"`` (eq. 30; K_tt is the same in both).
        chunk: Poses per kernel call (at most; a block is whole rows of x, :func:`block_layout`).
        progress: Show a tqdm progress bar.
        out: Also write the atlas there. A ``.zarr`` path streams: each block goes to the store
            as soon as it is computed, memory stays at one block whatever the grid, a killed run
            resumes from the blocks it finished (:func:`stream`), and the returned Dataset is
            the store opened lazily (dask arrays). A ``.nc`` path is computed in memory and
            saved (:func:`h4pin.mechanism.store.save`).
        frequency: Also the first natural frequency (:data:`FREQUENCY`; a robot whose
            parallelograms are exact, or an H4Params: :mod:`h4pin.stiffness.frequencies`).
        overwrite: Replace a zarr store at ``out`` that h4pin did not write (:func:`h4pin.mechanism.store.check_out`).

    Returns:
        An :class:`xarray.Dataset` with the variables of :data:`QUANTITIES` (and
        :data:`FREQUENCY`) and ``status``, dims ``(theta, z, y, x)``.
    """
    if out is not None and Path(out).suffix == ".zarr":
        return stream(source, x, y, z, theta, model, out=out, chunk=chunk, progress=progress, frequency=frequency,
                      overwrite=overwrite)
    if out is not None:
        store.check_out(out, "out", overwrite)
    limits.check_springs(source, "source")
    kern, name = _geometry(source)
    masses = _masses(source) if frequency else None
    axes = _axes(x, y, z, theta)
    shape = tuple(len(v) for v in axes.values())
    block, grid = store.block_layout(shape, chunk)
    check_memory(shape, frequency=frequency, chunk=chunk)
    data = {q: np.full(shape, np.nan) for q in _quantities(frequency)}
    data["status"] = np.empty(shape, dtype=np.int8)

    def write(b, region, fields):
        t, k, ys, xs = region
        for q, v in data.items():
            v[t, k, ys, xs] = fields[q].reshape(ys.stop - ys.start, xs.stop - xs.start)

    with tqdm(total=int(np.prod(shape)), desc="atlas", unit="pose", disable=not progress) as bar:
        _compute(kern, _regions(axes, block, grid, range(int(np.prod(grid)))), model, chunk, write, bar, masses)
    ds = _dataset(axes, data, model, name)
    if out is not None:
        store.save(ds, out, overwrite)
    return ds


def _axes(x: Any, y: Any, z: Any, theta: Any) -> dict[str, np.ndarray]:
    return {"theta": _axis("theta", theta), "z": _axis("z", z), "y": _axis("y", y), "x": _axis("x", x)}


def _quantities(frequency: bool) -> dict[str, tuple[str, str]]:
    return {**QUANTITIES, **FREQUENCY} if frequency else QUANTITIES


def _dataset(axes: dict[str, np.ndarray], data: dict[str, Any], model: str, name: str) -> xr.Dataset:
    """The atlas Dataset of the arrays ``data`` (numpy, or dask for a store's template)."""
    dims = tuple(axes)
    known = {**QUANTITIES, **FREQUENCY}
    out = {q: (dims, data[q], {"units": known[q][0], "long_name": known[q][1]}) for q in known if q in data}
    out["status"] = (dims, data["status"], {
        "units": "1", "long_name": "verdict (h4pin.verdicts)",
        "flag_values": np.arange(len(verdicts.STATUS_NAMES), dtype=np.int8),
        "flag_meanings": " ".join(s.replace(" ", "_") for s in verdicts.STATUS_NAMES)})
    coords = {k: (k, v, {"units": "rad" if k == "theta" else "m"}) for k, v in axes.items()}
    return xr.Dataset(out, coords=coords, attrs={
        "title": "H4 workspace atlas", "h4pin": "atlas", "model": model, "source": name,
        "reference": "Company, Pierrot, Fauroux, ICRA 2005, eq. 30 (compliance), eq. 8 (J), eq. 6 (M1)",
        "pose": "D = (x, y, z), central bar rotated by theta about z",
    })


def _fingerprint(kern: Any, axes: dict[str, np.ndarray], model: str, block: tuple[int, ...],
                 masses: Any = None) -> str:
    """What fixes the numbers of a streamed atlas: the robot (packed kernel geometry and element
    table, or the URDF and elements of a robot on the numpy path), the grid, the model and the
    blocks."""
    h = hashlib.sha256()
    if isinstance(kern, kernel.Kernel):
        h.update(np.ascontiguousarray(kern.packed).tobytes())
        h.update(np.ascontiguousarray(kern.elements).tobytes())
    else:
        h.update(str(getattr(kern, "urdf", "")).encode())
        h.update(repr(getattr(kern, "elements", "")).encode())
    for k, v in axes.items():
        h.update(k.encode() + np.ascontiguousarray(v, dtype="<f8").tobytes())
    h.update(f"{model} {block}".encode())
    if masses is not None:
        h.update(b"".join(np.ascontiguousarray(a).tobytes() for a in masses))
    return h.hexdigest()


def stream(source: Any, x: Any, y: Any, z: Any, theta: Any = 0.0, model: str = "consistent", *,
           out: str | Path, chunk: int = kernel.CHUNK, progress: bool = True, frequency: bool = False,
           overwrite: bool = False) -> xr.Dataset:
    """The atlas of :func:`atlas`, streamed into the zarr store ``out`` with memory constant in
    the number of poses (one block of at most ``chunk`` poses, about 700 bytes a pose).

    The store's arrays are made first, with their final (theta, z, y, x) shape, in a partial
    store beside ``out`` (``.NAME.h4pin-partial``, :func:`h4pin.mechanism.store.partial`); each block (whole rows
    of x, one zarr chunk) is written there as it is computed, then flagged done. When every
    block is in, the flags are removed and the partial store is renamed to ``out`` (replacing an
    atlas there). A killed run leaves the partial store: the next run with the same robot,
    grid, model and ``chunk`` resumes from the blocks done; any other run restarts it. ``out``
    itself is never half-written. One run at a time per ``out`` (:func:`h4pin.files.store_lock`:
    a second run is refused). A zarr store at ``out`` that h4pin did not write is replaced only
    with ``overwrite`` (:func:`h4pin.mechanism.store.check_out`).

    Returns:
        The store at ``out``, opened lazily (:func:`xarray.open_zarr`).
    """
    import dask.array as da

    path = store.check_stream(out, "out", overwrite)
    limits.check_springs(source, "source")
    kern, name = _geometry(source)
    masses = _masses(source) if frequency else None
    kernel.model_code(model)
    axes = _axes(x, y, z, theta)
    shape = tuple(len(v) for v in axes.values())
    block, grid = store.block_layout(shape, chunk)
    check_memory(shape, frequency=frequency, streamed=True, chunk=chunk)
    lazy = {q: da.full(shape, np.nan, chunks=block) for q in _quantities(frequency)}
    lazy["status"] = da.zeros(shape, dtype=np.int8, chunks=block)
    template = _dataset(axes, lazy, model, name)
    with store.partial(path, template, _fingerprint(kern, axes, model, block, masses), int(np.prod(grid)),
                       overwrite=overwrite) as group:
        _fill(group, path, axes, block, grid, kern, model, chunk, progress, masses, frequency)
    return store.opened(path)


def _fill(group: Any, path: Path, axes: dict[str, np.ndarray], block: tuple[int, ...], grid: tuple[int, ...],
          kern: Any, model: str, chunk: int, progress: bool, masses: Any, frequency: bool) -> None:
    """Compute the blocks of the partial store ``group`` not flagged done, then move it to ``path``."""
    shape = tuple(len(v) for v in axes.values())
    done = group[store.DONE]
    flags = done[:]
    todo = np.flatnonzero(~flags)
    arrays = {q: group[q] for q in (*_quantities(frequency), "status")}

    def write(b, region, fields):
        t, k, ys, xs = region
        rows = (ys.stop - ys.start, xs.stop - xs.start)
        for q, arr in arrays.items():
            arr[t, k, ys, xs] = fields[q].reshape(rows)
        flags[b] = True
        done[:] = flags  # after the block's values: a block killed half-way is computed again

    with tqdm(total=int(np.prod(shape)), desc="atlas", unit="pose", disable=not progress,
              initial=int(np.prod(shape)) - _poses_in(todo, axes, block, grid)) as bar:
        _compute(kern, _regions(axes, block, grid, todo), model, chunk, write, bar, masses)
    store.finish(path)


def _poses_in(todo: np.ndarray, axes: dict[str, np.ndarray], block: tuple[int, ...], grid: tuple[int, ...]) -> int:
    """Number of poses in the blocks ``todo``."""
    if len(todo) == 0:
        return 0
    _, _, j, i = np.unravel_index(todo, grid)
    ny, nx = len(axes["y"]), len(axes["x"])
    rows = np.minimum(ny, (j + 1) * block[2]) - j * block[2]
    cols = np.minimum(nx, (i + 1) * block[3]) - i * block[3]
    return int(np.sum(rows * cols))


#: Bytes an atlas holds per pose: five float64 quantities and the int8 verdict, twice (the arrays
#: and the copy a file engine may make while writing); with ``frequency``, :data:`FREQUENCY_BYTES` more.
BYTES_PER_POSE = 2 * (5 * 8 + 1)
FREQUENCY_BYTES = 2 * 8
#: Bytes of one block of poses in flight (the kernel's buffers, ~1.2 kB a pose; with the natural
#: frequencies' intermediates ~4 kB) and per block of a streamed atlas (the lazy template of its
#: seven arrays and its zarr metadata: measured 25.5 kB and 3.3 ms a block over 20,000 blocks).
BLOCK_BYTES_PER_POSE = 4200
BYTES_PER_BLOCK, SECONDS_PER_BLOCK = 26_000, 3.5e-3
#: Poses a second (measured: 9.5e5/s over a 200 x 200 slice on 2 cores, 2.9e4/s with the first
#: natural frequency; rounded down).
POSES_PER_S, FREQUENCY_POSES_PER_S = 5e5, 2.5e4


def check_memory(n: int | tuple[int, ...], *, frequency: bool = False, streamed: bool = False,
                 chunk: int = kernel.CHUNK) -> None:
    """Refuse, before any work, a grid whose atlas does not fit in memory: ``n`` poses, or the
    grid's shape (theta, z, y, x). In memory (a ``.nc`` atlas), :data:`BYTES_PER_POSE` a pose; a
    streamed ``.zarr`` atlas holds one block, and :data:`BYTES_PER_BLOCK` a block of the grid.
    The limit is :func:`h4pin.limits.memory_limit` (``H4PIN_MEMORY_LIMIT``); the message also
    gives the time the atlas would take.

    Raises:
        h4pin.limits.TooLargeError: over the limit (a :class:`h4pin.ParameterError`).
    """
    shape = n if isinstance(n, tuple) else None
    n = limits.count(math.prod(n) if shape is not None else n)
    in_flight = min(n, max(1, int(chunk))) * BLOCK_BYTES_PER_POSE
    if streamed:
        blocks = -(-n // max(1, int(chunk)))
        if shape is not None and len(shape) == 4 and min(shape) > 0:
            blocks = math.prod(store.block_layout(tuple(int(v) for v in shape), chunk)[1])
        need = blocks * BYTES_PER_BLOCK + in_flight
    else:
        blocks = 0
        need = n * (BYTES_PER_POSE + (FREQUENCY_BYTES if frequency else 0)) + in_flight
    seconds = n / (FREQUENCY_POSES_PER_S if frequency else POSES_PER_S) + blocks * SECONDS_PER_BLOCK
    limits.check_size(f"atlas: a grid of {n:,} poses", need, seconds,
                      "use fewer points or several slices" + ("" if streamed else ", or a .zarr output (streamed)"))
