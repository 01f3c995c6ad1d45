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
  limits, bar-clear and regular (the quantities above are NaN elsewhere).

The result is an :class:`xarray.Dataset` with dims ``(theta, z, y, x)`` and units in the
attributes; :func:`save` writes it to NetCDF (``.nc``) or zarr (``.zarr``) atomically, and
:func:`plot` draws one map per quantity with the workspace boundary (the contour of status 0).
See ``docs/atlas.md``.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from h4pin.extras import require

require("xarray", extra="studies", what="the atlas (h4pin.studies.atlas)")
import xarray as xr  # noqa: E402

from h4pin import verdicts  # noqa: E402
from h4pin.description.geometry import geometry_from_params  # noqa: E402
from h4pin.description.params import H4Params  # noqa: E402
from h4pin.errors import ParameterError  # noqa: E402
from h4pin.files import check_output, clean_stale, make_readable, save_figure, tmp_prefix  # noqa: E402
from h4pin.stiffness import kernel  # noqa: E402

#: The quantities of an atlas, with their units and a description.
QUANTITIES = dict(
    compliance_max=("m/N", "largest eigenvalue of the symmetric part of K_tt (worst-direction compliance)"),
    stiffness_z=("N/m", "stiffness along z, 1 / K_zz"),
    isotropy=("1", "smallest / largest eigenvalue of the symmetric part of K_tt"),
    cond_J=("1", "2-norm condition number of J = Jx^-1 Jq (eq. 8)"),
    cond_M1=("1", "1-norm condition number of M1 (eq. 6), rows / l_ij, rotation columns / mean bar length"),
)
#: How :func:`plot` shows each quantity: (factor, unit label, log colour scale).
_DISPLAY = {
    "compliance_max": (1e6, "um/N", True),
    "stiffness_z": (1e-6, "N/um", True),
    "isotropy": (1.0, "", False),
    "cond_J": (1.0, "", True),
    "cond_M1": (1.0, "", True),
}


def _axis(name: str, values: Any) -> np.ndarray:
    a = np.atleast_1d(np.asarray(values, dtype=float))
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise ParameterError(f"{name} must be a non-empty 1-D array of finite values, got {values!r}")
    return a


def _geometry(source: Any) -> tuple[Any, str]:
    """The kernel of ``source``, or the robot itself when the kernel alone does not give its
    compliance (a robot whose parallelograms are not exact, or that carries optional elements,
    goes through :func:`h4pin.compliance`, :func:`_robot_chunks`)."""
    g = getattr(source, "geometry", None)  # an h4pin.H4: its geometry read from the URDF
    if g is not None:
        name = Path(str(getattr(source, "source", "H4"))).name
        return (kernel.for_geometry(g), name) if g.ideal and source.elements.off else (source, name)
    if isinstance(source, H4Params):
        return kernel.prepare(geometry_from_params(source)), "H4Params"
    return kernel.prepare(source), type(source).__name__


def _robot_chunks(h4: Any, chunks: Any, model: str) -> Any:
    """``(start, result)`` like :func:`h4pin.stiffness.kernel.iter_compliance`, from
    :func:`h4pin.compliance` (its elements included; J of eq. 8 from the closed forms)."""
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


def atlas(source: Any, x: Any, y: Any, z: Any, theta: Any = 0.0, model: str = "consistent", *,
          chunk: int = kernel.CHUNK, progress: bool = True) -> xr.Dataset:
    """The atlas over the grid ``theta x z x y x`` (1-D coordinates in m and rad).

    Args:
        source: An :class:`h4pin.H4` (any robot: the compiled kernel, or the numpy path for a
            robot whose parallelograms are not exact), an :class:`h4pin.H4Params`, a kernel
            geometry object or a :class:`h4pin.stiffness.kernel.Kernel`.
        x, y, z, theta: Grid coordinates (scalars or 1-D), m and rad.
        model: ``"paper"`` or ``"consistent"`` (eq. 30; K_tt is the same in both).
        chunk: Poses per kernel call (memory stays at one chunk).
        progress: Show a tqdm progress bar.

    Returns:
        An :class:`xarray.Dataset` with the variables of :data:`QUANTITIES` and ``status``.
    """
    kern, name = _geometry(source)
    axes = {"theta": _axis("theta", theta), "z": _axis("z", z), "y": _axis("y", y), "x": _axis("x", x)}
    shape = tuple(len(v) for v in axes.values())
    n = int(np.prod(shape))
    check_memory(n)
    out = {q: np.full(n, np.nan) for q in QUANTITIES}
    status = np.empty(n, dtype=np.int8)

    def chunks():
        for start in range(0, n, chunk):
            idx = np.unravel_index(np.arange(start, min(n, start + chunk)), shape)
            yield np.stack([axes["x"][idx[3]], axes["y"][idx[2]], axes["z"][idx[1]], axes["theta"][idx[0]]], axis=1)

    with tqdm(total=n, desc="atlas", unit="pose", disable=not progress) as bar:
        results = (kernel.iter_compliance(kern, chunks(), model, chunk=chunk, jacobian=True)
                   if isinstance(kern, kernel.Kernel) else _robot_chunks(kern, chunks(), model))
        for start, res in results:
            m = len(res.status)
            sl = slice(start, start + m)
            status[sl] = res.status
            out["cond_M1"][sl] = res.condition
            ok = res.status == verdicts.OK
            if np.any(ok):
                idx = np.flatnonzero(ok) + start
                ktt = res.K[ok, :3, :3]
                lam = np.linalg.eigvalsh(0.5 * (ktt + np.swapaxes(ktt, 1, 2)))
                out["compliance_max"][idx] = lam[:, 2]
                out["isotropy"][idx] = lam[:, 0] / lam[:, 2]
                out["stiffness_z"][idx] = 1.0 / res.K[ok, 2, 2]
                out["cond_J"][idx] = np.linalg.cond(res.J[ok])
            bar.update(m)
    dims = tuple(axes)
    data = {q: (dims, v.reshape(shape), {"units": QUANTITIES[q][0], "long_name": QUANTITIES[q][1]})
            for q, v in out.items()}
    data["status"] = (dims, status.reshape(shape), {
        "units": "1", "long_name": "verdict (h4pin.verdicts)",
        "flag_values": np.arange(len(verdicts.STATUS_NAMES), dtype=np.int8),
        "flag_meanings": " ".join(s.replace(" ", "_") for s in verdicts.STATUS_NAMES)})
    coords = {k: (k, v, {"units": "rad" if k == "theta" else "m"}) for k, v in axes.items()}
    return xr.Dataset(data, coords=coords, attrs={
        "title": "H4 workspace atlas", "h4pin": "atlas", "model": model, "source": name,
        "reference": "Company, Pierrot, Fauroux, ICRA 2005, eq. 30 (compliance), eq. 8 (J), eq. 6 (M1)",
        "pose": "D = (x, y, z), central bar rotated by theta about z",
    })


#: Bytes an atlas holds per pose: five float64 quantities and the int8 verdict, twice (the arrays
#: and the copy a file engine may make while writing).
BYTES_PER_POSE = 2 * (5 * 8 + 1)


def check_memory(n: int) -> None:
    """Refuse, before any work, a grid whose results do not fit in the memory this machine has
    available (:data:`BYTES_PER_POSE`)."""
    need = n * BYTES_PER_POSE
    try:
        avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # not Linux: no check
        return
    if need > avail:
        raise ParameterError(f"a grid of {n:,} poses needs about {need / 2**30:.1f} GiB, this machine has "
                             f"{avail / 2**30:.1f} GiB available: use fewer points or several slices")


def check_out(path: str | Path, what: str = "path") -> Path:
    """Refuse, before any work, an atlas output that :func:`save` could not write: not ``.nc`` or
    ``.zarr``, an unwritable folder, a folder where the ``.nc`` file should go, or an existing
    ``.zarr`` folder that is not an atlas (it would be replaced)."""
    path = check_output(path, what, folder=Path(path).suffix == ".zarr", suffixes=(".nc", ".zarr"))
    if path.suffix == ".zarr" and path.exists() and not _is_atlas_store(path):
        raise ParameterError(f"{what} {path} exists and is not an h4pin atlas: give a new path (an existing atlas "
                             "is replaced)")
    return path


def _is_atlas_store(path: Path) -> bool:
    for meta in ("zarr.json", ".zattrs"):
        f = path / meta
        if f.is_file() and '"atlas"' in f.read_text(encoding="utf-8", errors="replace"):
            return True
    return False


def save(ds: xr.Dataset, path: str | Path) -> Path:
    """Write an atlas atomically: ``.nc`` (NetCDF4 through h5netcdf) or ``.zarr`` (a folder).
    Files are mode 0644; nothing is left half-written if the write fails, and the temporary
    folder a killed save left is removed the next time (:func:`h4pin.files.clean_stale`).

    Raises:
        ParameterError: as :func:`check_out`.
    """
    path = check_out(path)
    require("h5netcdf" if path.suffix == ".nc" else "zarr", extra="studies", what=f"writing {path.suffix} atlases")
    clean_stale(path)
    tmp = Path(tempfile.mkdtemp(prefix=tmp_prefix(path), dir=path.parent))
    try:
        if path.suffix == ".nc":
            target = tmp / path.name
            ds.to_netcdf(target, engine="h5netcdf")
            os.chmod(target, 0o644)
            os.replace(target, path)
        else:
            target = tmp / path.name
            ds.to_zarr(target, mode="w", consolidated=False)
            make_readable(target)
            if path.exists():
                os.replace(path, tmp / "old")
            os.replace(target, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path


def open_atlas(path: str | Path) -> xr.Dataset:
    """Read an atlas written by :func:`save` into memory."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no atlas at {path}")
    if path.suffix == ".zarr":
        with xr.open_zarr(path, consolidated=False) as ds:
            return ds.load()
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()


def plot(ds: xr.Dataset, folder: str | Path, prefix: str = "atlas_", max_panels: int = 4) -> list[Path]:
    """One PNG per quantity (and one of the verdict) in ``folder``: ``{prefix}{quantity}.png``.

    Each figure has one panel per (theta, z) slice (at most ``max_panels``, evenly chosen), the
    quantity as a colour map in display units (1st to 99th percentile: compliance grows without
    bound near singularities), and the workspace boundary (status 0) in black.
    """
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    folder = Path(folder)
    if not folder.is_dir():
        raise ParameterError(f"folder {str(folder)!r} does not exist")
    slices = [(t, z) for t in range(ds.sizes["theta"]) for z in range(ds.sizes["z"])]
    if len(slices) > max_panels:
        slices = [slices[i] for i in np.linspace(0, len(slices) - 1, max_panels).round().astype(int)]
    x, y = ds.x.values * 1e3, ds.y.values * 1e3
    written = []
    for q in (*QUANTITIES, "status"):
        fig = Figure(figsize=(4.2 * len(slices) + 1.0, 4.0), layout="constrained")
        axs = fig.subplots(1, len(slices), squeeze=False)[0]
        if q == "status":
            factor, unit, log = 1.0, "", False
            values = ds.status.values.astype(float)
            vmin, vmax = -0.5, 4.5
        else:
            factor, unit, log = _DISPLAY[q]
            values = ds[q].values * factor
            finite = values[np.isfinite(values)]
            # Near a singularity the compliance grows without bound: colour the 1st-99th percentiles.
            vmin, vmax = (float(v) for v in np.percentile(finite, [1, 99])) if finite.size else (0.0, 1.0)
        mesh = None
        for ax, (t, zi) in zip(axs, slices, strict=True):
            v = values[t, zi]
            norm = LogNorm(vmin, vmax) if log and vmin > 0 else None
            mesh = ax.pcolormesh(x, y, v, shading="nearest", cmap="viridis", norm=norm,
                                 **({} if norm else {"vmin": vmin, "vmax": vmax}))
            reach = (ds.status.values[t, zi] == verdicts.OK).astype(float)
            if 0 < reach.sum() < reach.size and len(x) > 1 and len(y) > 1:
                ax.contour(x, y, reach, levels=[0.5], colors="k", linewidths=1.2)
            ax.set_title(f"z = {ds.z.values[zi] * 1e3:.0f} mm, theta = {ds.theta.values[t]:.2f} rad", fontsize=9)
            ax.set_xlabel("x [mm]")
            ax.set_aspect("equal")
        axs[0].set_ylabel("y [mm]")
        label = f"{q} [{unit}]" if unit else q
        if q == "status":
            label = "status: " + ", ".join(f"{c} {s}" for c, s in enumerate(verdicts.STATUS_NAMES))
        cb = fig.colorbar(mesh, ax=list(axs), shrink=0.9, extend="neither" if q == "status" else "both")
        cb.set_label(label, fontsize=8)
        fig.suptitle(f"H4 atlas ({ds.attrs.get('model', '')} model): {QUANTITIES.get(q, ('', 'verdict'))[1]}",
                     fontsize=9)
        target = folder / f"{prefix}{q}.png"
        written.append(save_figure(fig, target, dpi=110))
    return written
