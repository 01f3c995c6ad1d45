# SPDX-License-Identifier: Apache-2.0
"""Every figure h4pin draws, in one place (as pycapacity keeps ``visual.py`` apart): the studies
return values, these functions draw them. Each writes a PNG atomically
(:func:`h4pin.files.save_figure`) and returns its path.

* :func:`atlas_maps`: the maps of an atlas, the H4's workspace atlas (:mod:`h4pin.studies.atlas`)
  or any mechanism's motor-space atlas (:mod:`h4pin.mechanism.atlas`), with the boundary of the
  points of status 0;
* :func:`frequency_map` and :func:`frequency_pareto` (:mod:`h4pin.studies.frequency`);
* :func:`sweep_pareto` (:mod:`h4pin.studies.sweep`), :func:`cycle` (:mod:`h4pin.studies.cycle`),
  :func:`tolerance` (:mod:`h4pin.studies.tolerance`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from h4pin import verdicts
from h4pin.description.params import H4Params
from h4pin.errors import ParameterError
from h4pin.files import save_figure
from h4pin.mechanism import atlas as motor_atlas
from h4pin.studies import atlas as h4_atlas
from h4pin.studies import sweep
from h4pin.studies import tolerance as tol

#: How an atlas quantity is shown: (factor, unit label, log colour scale).
DISPLAY = {
    "compliance_max": (1e6, "um/N", True),
    "first_frequency": (1.0, "Hz", False),
    "stiffness_z": (1e-6, "N/um", True),
    "isotropy": (1.0, "", False),
    "cond_J": (1.0, "", True),
    "cond_M1": (1.0, "", True),
}


def atlas_maps(ds: Any, folder: str | Path, prefix: str = "atlas_", max_panels: int = 4) -> list[Path]:
    """One PNG per quantity of an atlas (and one of its verdict) in ``folder``,
    ``{prefix}{quantity}.png``: the H4's workspace atlas (one panel per (theta, z) slice) or a
    motor-space atlas (maps over the first two motors, one panel per slice of the others), at most
    ``max_panels`` panels, evenly chosen; colours span the 1st to 99th percentile (compliance grows
    without bound near a singularity), and a black contour bounds the points of status 0.

    Raises:
        ParameterError: ``folder`` does not exist, or ``ds`` is not an atlas.
    """
    if ds.attrs.get("kind") == "mechanism":
        return _motor_maps(ds, folder, prefix, max_panels)
    if "theta" not in ds.dims:
        raise ParameterError("ds: an atlas (h4pin.studies.atlas or h4pin.mechanism.atlas)")
    return _workspace_maps(ds, folder, prefix, max_panels)


def _workspace_maps(ds: Any, folder: str | Path, prefix: str = "atlas_", max_panels: int = 4) -> list[Path]:
    """The H4 workspace atlas's maps (:func:`atlas_maps`): one PNG per quantity (and one of the
    verdict) in ``folder``: ``{prefix}{quantity}.png``.

    Each figure has one panel per (theta, z) slice (at most ``max_panels``, evenly chosen), the
    quantity as a colour map in display units (1st to 99th percentile of the panels shown: compliance grows without
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
    # Only the panels' slices are read (a streamed atlas is a lazily opened store).
    status = {s: ds.status.isel(theta=s[0], z=s[1]).values for s in slices}
    written = []
    for q in (*(q for q in (*h4_atlas.QUANTITIES, *h4_atlas.FREQUENCY) if q in ds), "status"):
        fig = Figure(figsize=(4.2 * len(slices) + 1.0, 4.0), layout="constrained")
        axs = fig.subplots(1, len(slices), squeeze=False)[0]
        if q == "status":
            factor, unit, log = 1.0, "", False
            values = {s: v.astype(float) for s, v in status.items()}
            vmin, vmax = -0.5, 4.5
        else:
            factor, unit, log = DISPLAY[q]
            values = {s: ds[q].isel(theta=s[0], z=s[1]).values * factor for s in slices}
            finite = np.concatenate([v[np.isfinite(v)] for v in values.values()])
            # Near a singularity the compliance grows without bound: colour the 1st-99th percentiles.
            vmin, vmax = (float(v) for v in np.percentile(finite, [1, 99])) if finite.size else (0.0, 1.0)
        mesh = None
        for ax, (t, zi) in zip(axs, slices, strict=True):
            v = values[t, zi]
            norm = LogNorm(vmin, vmax) if log and vmin > 0 else None
            mesh = ax.pcolormesh(x, y, v, shading="nearest", cmap="viridis", norm=norm,
                                 **({} if norm else {"vmin": vmin, "vmax": vmax}))
            reach = (status[t, zi] == verdicts.OK).astype(float)
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
        meaning = {**h4_atlas.QUANTITIES, **h4_atlas.FREQUENCY}.get(q, ("", "verdict"))[1]
        fig.suptitle(f"H4 atlas ({ds.attrs.get('model', '')} model): {meaning}", fontsize=9)
        target = folder / f"{prefix}{q}.png"
        written.append(save_figure(fig, target, dpi=110))
    return written


def _panels(ds: Any, max_panels: int) -> list[dict[str, int]]:
    """Index selections of the motors past the first two, one per panel (at most ``max_panels``,
    evenly chosen): each panel is a map over the first two motors."""
    dims = list(ds.status.dims)
    rest = [ds.sizes[d] for d in dims[2:]]
    slices = list(np.ndindex(*rest)) if rest else [()]
    if len(slices) > max_panels:
        slices = [slices[i] for i in np.linspace(0, len(slices) - 1, max_panels).round().astype(int)]
    return [dict(zip(dims[2:], s, strict=True)) for s in slices]




def _motor_maps(ds: Any, folder: str | Path, prefix: str = "atlas_", max_panels: int = 4) -> list[Path]:
    """A motor-space atlas's maps (:func:`atlas_maps`): one PNG per quantity in ``folder``,
    ``{prefix}{quantity}.png``: ``compliance_max`` (um/N,
    log colours), ``first_frequency`` (Hz) when the atlas has it, and ``status``. Each figure maps
    the quantity over the first two motors (a curve over the motor for a one-motor robot), one
    panel per slice of the other motors (at most ``max_panels``, evenly chosen); colours span the
    1st to 99th percentile (compliance grows without bound near a singularity), and the black
    contour bounds the points of status 0."""
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    names = motor_atlas.motors(ds)
    folder = Path(folder)
    if not folder.is_dir():
        raise ParameterError(f"folder {str(folder)!r} does not exist")
    dims = list(ds.status.dims)
    panels = _panels(ds, max_panels)
    written = []
    for q in ("compliance_max", *(("first_frequency",) if "first_frequency" in ds else ()), "status"):
        factor, unit, log = DISPLAY[q] if q != "status" else (1.0, "", False)
        fig = Figure(figsize=(4.2 * len(panels) + 1.0, 4.0), layout="constrained")
        axs = fig.subplots(1, len(panels), squeeze=False)[0]
        values = [ds[q].isel(p).values.astype(float) * factor for p in panels]
        finite = np.concatenate([v[np.isfinite(v)] for v in values])
        vmin, vmax = (float(v) for v in np.percentile(finite, [1, 99])) if finite.size else (0.0, 1.0)
        if q == "status":
            vmin, vmax = -0.5, len(motor_atlas.STATUS_NAMES) - 0.5
        mesh = None
        for ax, p, v in zip(axs, panels, values, strict=True):
            x = ds[dims[-1] if len(dims) == 1 else dims[1]].values
            if len(dims) == 1:
                ax.plot(x, v, "o-" if q == "status" else "-", color="C0")
                ax.set_ylabel(f"{q} [{unit}]" if unit else q)
                if log and vmin > 0:
                    ax.set_yscale("log")
            else:
                y = ds[dims[0]].values
                norm = LogNorm(vmin, vmax) if log and vmin > 0 else None
                mesh = ax.pcolormesh(x, y, v, shading="nearest", cmap="viridis", norm=norm,
                                     **({} if norm else {"vmin": vmin, "vmax": vmax}))
                ok = (ds.status.isel(p).values == motor_atlas.OK).astype(float)
                if 0 < ok.sum() < ok.size and len(x) > 1 and len(y) > 1:
                    ax.contour(x, y, ok, levels=[0.5], colors="k", linewidths=1.2)
                ax.set_ylabel(f"{names[0]} [rad or m]")
            ax.set_xlabel(f"{names[-1] if len(dims) == 1 else names[1]} [rad or m]")
            ax.set_title(", ".join(f"{names[dims.index(d)]} = {float(ds[d].values[i]):.3g}" for d, i in p.items())
                         or ds.attrs.get("mechanism", ""), fontsize=8)
        if mesh is not None:
            label = f"{q} [{unit}]" if unit else q
            if q == "status":
                label = "status: " + ", ".join(f"{c} {s}" for c, s in enumerate(motor_atlas.STATUS_NAMES))
            fig.colorbar(mesh, ax=list(axs), shrink=0.9).set_label(label, fontsize=8)
        what = {"compliance_max": "worst-direction compliance", "first_frequency": "first natural frequency"}.get(
            q, "verdict")
        fig.suptitle(f"{ds.attrs.get('mechanism', '')} at {ds.attrs.get('output', '')}: {what}", fontsize=9)
        written.append(save_figure(fig, folder / f"{prefix}{q}.png", dpi=110))
    return written


def frequency_map(ds: Any, path: str | Path) -> Path:
    """The map of :func:`h4pin.studies.frequency.frequency_map` as a PNG: colour = first frequency (Hz), the workspace
    boundary (status 0) in black."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.6, 4.6), layout="constrained")
    ax = fig.subplots()
    x, y = ds.x.values * 1e3, ds.y.values * 1e3
    mesh = ax.pcolormesh(x, y, ds.first_frequency.values, shading="nearest", cmap="viridis")
    _map_frame(fig, ax, x, y, mesh, ds.status.values == verdicts.OK, "first natural frequency [Hz]")
    payload = ds.attrs.get("payload_kg", 0.0)
    ax.set_title(f"H4 first natural frequency, z = {ds.attrs['z'] * 1e3:.0f} mm, theta = {ds.attrs['theta']:.2f} rad"
                 + (f", payload {payload:g} kg" if payload else ""), fontsize=9)
    return save_figure(fig, path, dpi=110)


def _map_frame(fig: Any, ax: Any, x: np.ndarray, y: np.ndarray, mesh: Any, ok: np.ndarray, label: str) -> None:
    """An x-y map's frame: the edge of the points ``ok`` (a black line), the colour bar, mm axes."""
    ok = ok.astype(float)
    if 0 < ok.sum() < ok.size and len(x) > 1 and len(y) > 1:
        ax.contour(x, y, ok, levels=[0.5], colors="k", linewidths=1.2)
    fig.colorbar(mesh, ax=ax).set_label(label)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_aspect("equal")


def frequency_pareto(par: dict[str, np.ndarray], path: str | Path) -> Path:
    """First frequency against workspace volume, coloured by the worst compliance over the task
    box, the Pareto front of the three highlighted (PNG)."""
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.2, 4.4), layout="constrained")
    ax = fig.subplots()
    w = par["worst"] * 1e6
    sc = ax.scatter(par["volume"] * 1e3, par["frequency"], s=4, c=w, cmap="viridis_r", norm=LogNorm(w.min(), w.max()),
                    label=f"{len(w):,} designs reaching the task box", rasterized=True)
    f = par["front"]
    ax.scatter(par["volume"][f] * 1e3, par["frequency"][f], s=14, facecolors="none", edgecolors="C3", linewidths=0.8,
               label=f"Pareto front ({len(f)}: frequency, volume, compliance)")
    fig.colorbar(sc, ax=ax).set_label("worst compliance over the task box [um/N]")
    ax.set_xlabel("workspace volume [dm^3]")
    ax.set_ylabel("first natural frequency [Hz]")
    ax.legend(fontsize=7, loc="lower left")
    return save_figure(fig, path, dpi=110)


def sweep_pareto(res: dict[str, np.ndarray], path: str | Path) -> Path:
    """Worst compliance over the task against workspace volume, front highlighted (PNG)."""
    from matplotlib.figure import Figure

    path = Path(path)
    fig = Figure(figsize=(6.4, 4.6), layout="constrained")
    ax = fig.subplots()
    ok = res["reach_all"]
    vol, worst = res["volume"] * 1e3, res["worst"] * 1e6
    ax.scatter(vol[~ok & res["valid"]], worst[~ok & res["valid"]], s=4, c="0.75",
               label="misses part of the task workspace (worst over the reached part)")
    ax.scatter(vol[ok], worst[ok], s=6, c="tab:blue", label="reaches the whole task workspace")
    front = sweep.pareto(res)
    if front.size:
        ax.plot(vol[front], worst[front], "o-", c="tab:red", ms=4, label="Pareto front")
    spec = res["spec"]
    p = H4Params()
    proto = sweep.evaluate(np.array([[p.half_width[0], p.r[0], p.l[0], 1.0, 1.0, p.kc[0]]]), spec)
    ax.plot(proto["volume"] * 1e3, proto["worst"] * 1e6, "k*", ms=12, label="prototype")
    ax.set_yscale("log")
    ax.set_xlabel("workspace volume at theta = 0 [dm^3]")
    ax.set_ylabel("worst compliance over the task box [um/N]")
    ax.set_title(f"{spec.n_designs} designs, {len(spec.task.poses())} task poses, model '{spec.model}'", fontsize=9)
    ax.legend(fontsize=7)
    return save_figure(fig, path, dpi=110)


def cycle(result: Any, path: str | Path, others: Sequence[Any] = ()) -> Path:
    """Trajectory, load, deflection and actuator torques along the cycle, written atomically as
    PNG. ``others``: more results (another payload) whose ‖dD‖ is drawn beside."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    if not path.parent.is_dir():
        raise ParameterError(f"cannot write {path}: folder {path.parent} does not exist")
    r, c = result, result.cycle
    t = r.t * 1e3
    fig, axes = plt.subplots(2, 3, figsize=(16, 8.5))
    ax = axes[0, 0]
    along = (r.pose[:, :3] - c.start) @ c.direction
    ax.plot(along * 1e3, (r.pose[:, 2] - c.start[2]) * 1e3, "k.-", ms=2, lw=0.8)
    ax.set_xlabel("along the stroke (mm)")
    ax.set_ylabel("z - z_start (mm)")
    ax.set_ylim(-0.2 * c.height * 1e3, 1.4 * c.height * 1e3)
    ax.set_title(f"path of D: {c.height * 1e3:.0f} / {c.length * 1e3:.0f} / {c.height * 1e3:.0f} mm, "
                 f"{c.period:g} s cycle\n(dots every {c.period / (len(r.t) - 1) * 1e3:.2f} ms)")
    ax = axes[0, 1]
    for k, name in enumerate("xyz"):
        ax.plot(t, r.acceleration[:, k], label=f"{name}''")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("acceleration of D (m/s^2)")
    ax.set_title("time law: 5th-order per motion, corners overlapped")
    ax.legend(loc="best", fontsize=8)
    ax = axes[0, 2]
    for k, name in enumerate("xyz"):
        ax.plot(t, r.load[:, k], label=f"F{name} (N)")
    ax.plot(t, np.linalg.norm(r.load[:, :3], axis=1), "k--", lw=0.8, label="|F| (N)")
    for k, name in enumerate("xyz"):
        if np.abs(r.load[:, 3 + k]).max() > 1e-9:
            ax.plot(t, r.load[:, 3 + k] * 10, ":", label=f"T{name} x 10 (N.m)")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("load on the legs at D")
    ax.set_title(f"Gamma_ext = weight + d'Alembert load of\nthe plate and a {r.payload:g} kg payload")
    ax.legend(loc="best", fontsize=8)
    ax = axes[1, 0]
    for k, name in enumerate("xyz"):
        ax.plot(t, r.deflection[:, k] * 1e6, label=f"d{name}")
    ax.plot(t, np.linalg.norm(r.deflection[:, :3], axis=1) * 1e6, "k-", lw=1.2, label=f"|dD|, {r.payload:g} kg")
    for o in others:
        ax.plot(o.t * 1e3, np.linalg.norm(o.deflection[:, :3], axis=1) * 1e6, "k:", lw=1.2,
                label=f"|dD|, {o.payload:g} kg")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("deflection of D (um)")
    ax.set_title(f"quasi-static deflection dD = K Gamma_ext (model '{r.model}')")
    ax.legend(loc="best", fontsize=8)
    ax = axes[1, 1]
    for name, d in r.term_deflection.items():
        ax.plot(t, np.linalg.norm(d, axis=1) * 1e6, label=name)
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("|dD| of one term of K (um)")
    ax.set_title(f"deflection per term of eq. 30, {r.payload:g} kg")
    ax.legend(loc="best", fontsize=8)
    ax = axes[1, 2]
    for k in range(4):
        ax.plot(t, r.torque[:, k], ls="-" if k % 2 == 0 else "--", label=f"actuator {k + 1}")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("torque (N.m)")
    ax.set_title("actuator torques, closed-loop inverse dynamics")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=90)


def tolerance(res: Any, path: str | Path) -> Path:
    """Histograms of every output (deviation from nominal for the compliance), written
    atomically (temporary file, then rename) as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    if not path.parent.is_dir():
        raise ParameterError(f"cannot write {path}: folder {path.parent} does not exist")
    outs = res.outputs()
    fig, axes = plt.subplots(2, 5, figsize=(16, 6.5))
    for ax, (name, f, unit) in zip(axes.ravel(), tol.OUTPUTS, strict=True):
        v = (outs[name] - (tol.nominal_of(res, name) if name in ("xx", "yy", "zz", "xz", "lambda_max") else 0.0)) * f
        v = v[np.isfinite(v)]
        ax.hist(v, bins=60, color="tab:blue", alpha=0.8)
        for p in np.percentile(v, [5, 50, 95]) if v.size else ():
            ax.axvline(p, color="k", lw=0.8, ls="--")
        label = f"d{name}" if name in ("xx", "yy", "zz", "xz", "lambda_max") else name
        ax.set_xlabel(f"{label} ({unit})")
        ax.set_yticks([])
    r, m = res.converged.shape
    fig.suptitle(f"H4 tolerance study: {r} robots x {m} poses (dashed: 5, 50, 95 %; compliance as deviation "
                 "from nominal)")
    fig.tight_layout()
    return save_figure(fig, path, dpi=90)


def sag_map(ds: Any, path: str | Path) -> Path:
    """The map of :func:`h4pin.studies.loaded.sag_map`: colour = ‖sag of D‖ (um), arrows = its
    horizontal part, the boundary of the computed poses in black."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.6, 4.6), layout="constrained")
    ax = fig.subplots()
    x, y = ds.x.values * 1e3, ds.y.values * 1e3
    mesh = ax.pcolormesh(x, y, ds.sag_norm.values * 1e6, shading="nearest", cmap="viridis")
    xx, yy = np.meshgrid(x, y)
    ax.quiver(xx, yy, ds.sag.values[..., 0], ds.sag.values[..., 1], color="w", width=0.004)
    _map_frame(fig, ax, x, y, mesh, ds.status.values == 0, "|sag of D| [um]")
    payload = ds.attrs.get("payload_kg", 0.0)
    ax.set_title(f"H4 sag under its weight{f' and {payload:g} kg at D' if payload else ''}, "
                 f"z = {ds.attrs['z'] * 1e3:.0f} mm", fontsize=9)
    return save_figure(fig, path, dpi=110)


def compensated_cycle(res: Any, path: str | Path) -> Path:
    """:func:`h4pin.studies.loaded.compensated_cycle`: D's sag at the rigid inverse and after the
    compensation (um), and the actuators' corrections (urad), along the cycle."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 3.8), layout="constrained")
    a, b = fig.subplots(1, 2)
    t = res.t * 1e3
    for k, name in enumerate("xyz"):
        a.plot(t, res.sag[:, k] * 1e6, label=f"d{name}, rigid inverse")
    a.plot(t, np.linalg.norm(res.error, axis=1) * 1e6, "k--", label="|error|, compensated")
    a.set_xlabel("t [ms]")
    a.set_ylabel("D from its target [um]")
    a.legend(fontsize=7)
    for k in range(res.motors.shape[1]):
        b.plot(t, (res.motors[:, k] - res.rigid[:, k]) * 1e6, label=f"actuator {k + 1}")
    b.set_xlabel("t [ms]")
    b.set_ylabel("compensated - rigid angle [urad]")
    b.legend(fontsize=7)
    fig.suptitle(f"pick-and-place cycle under the H4's weight and {res.payload:g} kg at D, quasi-static", fontsize=9)
    return save_figure(fig, path, dpi=110)



def calibration(rows: Sequence[Any], path: str | Path) -> Path:
    """The markers' errors of a stage table (:func:`h4pin.mechanism.calibration.stages`): per
    stage, mean and max on the fitted and held-out samples (mm); and the distribution of the
    errors of the nominal model and of the last stage."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 4.0), layout="constrained")
    a, b = fig.subplots(1, 2)
    names = ["\n+ ".join(r.groups) if k == 0 else "+ " + r.groups[-1] for k, r in enumerate(rows)]
    x = np.arange(len(rows))
    for k, (label, style) in enumerate((("fit", "o-"), ("held out", "s--"))):
        mean = np.array([(r.fit if k == 0 else r.held)[0] for r in rows]) * 1e3
        top = np.array([(r.fit if k == 0 else r.held)[2] for r in rows]) * 1e3
        a.plot(x, mean, style, color=f"C{k}", label=f"mean, {label}")
        a.plot(x, top, style, color=f"C{k}", alpha=0.4, label=f"max, {label}")
    a.set_xticks(x, names, fontsize=7)
    a.set_yscale("log")
    a.set_ylabel("marker error [mm]")
    a.legend(fontsize=7)
    errors = []
    for r in (rows[0], rows[-1]):
        e = np.linalg.norm(r.calibration.residuals, axis=-1).ravel() * 1e3
        errors.append(e[np.isfinite(e) & (e > 0)])
    every = np.concatenate(errors)
    bins = np.geomspace(every.min(), every.max(), 60) if every.size and every.max() > every.min() else 40
    for r, e, colour in ((rows[0], errors[0], "0.6"), (rows[-1], errors[1], "C2")):
        b.hist(e, bins=bins, color=colour, alpha=0.7, label=" + ".join(r.groups))
    if not isinstance(bins, int):
        b.set_xscale("log")
    b.set_xlabel("marker error on the fitted samples [mm]")
    b.set_ylabel("readings")
    b.legend(fontsize=7)
    fig.suptitle("calibration, stage by stage", fontsize=9)
    return save_figure(fig, path, dpi=110)


__all__ = ["DISPLAY", "atlas_maps", "calibration", "compensated_cycle", "cycle", "frequency_map", "frequency_pareto",
           "sag_map", "sweep_pareto", "tolerance"]
