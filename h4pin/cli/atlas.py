# SPDX-License-Identifier: Apache-2.0
"""``h4pin atlas``: the H4's workspace atlas, or any closed-loop robot's motor-space atlas (``--robot``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from h4pin.cli.common import (
    JOINT_K,
    MODEL,
    MOTOR_K,
    OVERWRITE,
    QUIET,
    ROBOT,
    SIDECAR,
    URDF,
    VARIANT,
    Model,
    Variant,
    check_payload,
    fail,
    given,
    load_mechanism,
    load_robot,
    wrote,
)


def _atlas_ranges(ds: Any, ok: Any, frequency: bool, where: str, fmt: str) -> None:
    """The ranges of an atlas's worst compliance (and first frequency) over its valid points."""
    if int(ok.sum()):
        c = ds.compliance_max * 1e6
        typer.echo(f"worst-direction compliance{where}: {float(c.min()):{fmt}} to {float(c.max()):{fmt}} um/N")
        if frequency:
            f = ds.first_frequency
            typer.echo(f"first natural frequency {float(f.min()):{fmt}} to {float(f.max()):{fmt}} Hz")


def atlas(
    ctx: typer.Context,
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    x: tuple[float, float, int] = typer.Option((-0.3, 0.3, 61), metavar="LO HI N", help="x grid, m"),
    y: tuple[float, float, int] = typer.Option((-0.3, 0.3, 61), metavar="LO HI N", help="y grid, m"),
    z: list[float] | None = typer.Option(None, metavar="Z",
                                         help="z of a slice, m; repeat for several (default: centre z)"),
    z_range: tuple[float, float, int] | None = typer.Option(None, metavar="LO HI N", help="3-D box: z grid, m"),
    theta: list[float] | None = typer.Option(None, metavar="THETA",
                                             help="theta of a slice, rad; repeat for several (default 0)"),
    model: Model = typer.Option("paper", help=f"{MODEL}; both give the same K_tt"),
    out: Path = typer.Option(Path("atlas.nc"), metavar="PATH", help="output file: .nc (NetCDF) or .zarr"),
    figures: Path | None = typer.Option(None, metavar="DIR", help="folder for the maps atlas_<quantity>.png"),
    frequency: bool = typer.Option(False, "--frequency", help="also the first natural frequency (Hz)"),
    quiet: bool = typer.Option(False, "--quiet", help=QUIET),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
    robot: Path | None = typer.Option(None, metavar="FILE", help=f"{ROBOT}: its motor-space atlas instead of the H4's "
                                      "workspace (the H4 options --variant ... --model do not apply)"),
    sidecar: Path | None = typer.Option(None, metavar="YAML", help=SIDECAR),
    output: str | None = typer.Option(None, metavar="FRAME", help="with --robot: the frame whose compliance is mapped"),
    motor: list[str] | None = typer.Option(None, metavar="NAME=LO:HI:N", help="with --robot: a motor's grid (rad or m);"
                                           " repeat per motor (default: its file range where finite, else the "
                                           "reference assembly +- 0.25 rad or 0.025 m)"),
    count: int | None = typer.Option(None, metavar="N", help="with --robot: grid points per motor not given by "
                                     "--motor (default: 21 for one or two motors, 7 for three, 3 beyond)"),
    motor_stiffness: float = typer.Option(100.0, metavar="K", help=f"with --robot: {MOTOR_K}"),
    joint_stiffness: float = typer.Option(100.0, metavar="K", help=f"with --robot: {JOINT_K}"),
    lock: list[str] | None = typer.Option(None, metavar="JOINT", help="with --robot: a joint held rigid; repeat"),
    threads: int | None = typer.Option(None, help="with --robot: threads of each block's compliance (default: one "
                                       "per core)"),
    gravity: bool = typer.Option(False, "--gravity", help="with --robot: also the output's sag under the robot's "
                                 "weight (loaded equilibrium, docs/loaded.md)"),
    payload: float = typer.Option(0.0, metavar="KG", help="with --robot --gravity: a point payload at --output, kg"),
) -> None:
    """Workspace atlas: worst compliance, z stiffness, isotropy, cond(J), cond(M1), reachability
    (and the first natural frequency). With --robot FILE, any closed-loop robot's atlas over its
    motors: worst compliance and ellipsoid at --output, validity (and the first natural frequency)."""
    import numpy as np

    from h4pin import plots
    from h4pin.files import check_output, check_replace
    from h4pin.kinematics.closed_form import centre_pose
    from h4pin.mechanism import store
    from h4pin.studies import atlas as atlas_module

    if robot is not None:
        h4_only = [f"--{n.replace('_', '-')}" for n in ("variant", "urdf", "x", "y", "z", "z_range", "theta", "model")
                   if given(ctx, n)]
        if h4_only:
            fail(f"{h4_only[0]} is an option of the H4's atlas; with --robot the grid is --motor NAME=LO:HI:N")
        return _motor_atlas(robot, sidecar, output, motor or [], count, motor_stiffness, joint_stiffness, lock or [],
                            threads, out, figures, frequency, quiet, overwrite, (gravity, payload))
    robot_only = ("sidecar", "output", "motor", "count", "motor_stiffness", "joint_stiffness", "lock", "threads",
                  "gravity", "payload")
    extra = [f"--{n.replace('_', '-')}" for n in robot_only if given(ctx, n)]
    if extra:
        fail(f"{extra[0]} goes with --robot FILE (any closed-loop robot's atlas)")
    if z and z_range:
        fail("give --z or --z-range, not both")
    for name, axis in (("--x", x), ("--y", y), ("--z-range", z_range)):
        if axis is not None and axis[2] < 1:
            fail(f"{name} LO HI N needs N >= 1, got {axis[2]}")
    store.check_out(out, "--out", overwrite)  # a .zarr store: an h4pin atlas, or --overwrite
    check_replace(out, "--out", overwrite)  # a .nc file
    if figures is not None:
        check_output(figures / "atlas_status.png", "--figures")
        maps = (*atlas_module.QUANTITIES, *(atlas_module.FREQUENCY if frequency else ()), "status")
        for q in maps:
            check_replace(figures / f"atlas_{q}.png", "--figures", overwrite)
    n_z = z_range[2] if z_range else max(len(z or []), 1)
    # a .zarr atlas streams to disk: its memory grows with its blocks, not with its poses
    atlas_module.check_memory((max(len(theta or []), 1), n_z, y[2], x[2]), frequency=frequency,
                              streamed=out.suffix == ".zarr")
    h4 = load_robot(variant, urdf)
    grid = {name: np.linspace(lo, hi, n) for name, (lo, hi, n) in (("x", x), ("y", y))}
    zs = np.linspace(*z_range[:2], z_range[2]) if z_range else (z or [float(centre_pose(h4)[2])])
    ds = atlas_module.atlas(h4, grid["x"], grid["y"], zs, theta or [0.0], model, progress=not quiet, out=out,
                            frequency=frequency, overwrite=overwrite)
    ok = ds.status == 0  # lazy (dask) for a streamed .zarr atlas: reduced chunk by chunk
    typer.echo(f"{int(ok.sum())} of {ok.size} poses reachable and regular")
    _atlas_ranges(ds, ok, frequency, "", ".1f")
    wrote(out, *(plots.atlas_maps(ds, figures) if figures is not None else ()))




def parse_motors(values: list[str]) -> dict[str, tuple[float, float, int]]:
    """``--motor NAME=LO:HI:N`` options as ``{name: (lo, hi, n)}``."""
    out = {}
    for v in values:
        name, _, spec = v.partition("=")
        parts = spec.split(":")
        try:
            lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
            if len(parts) != 3:
                raise ValueError
        except (ValueError, IndexError):
            fail(f"--motor takes NAME=LO:HI:N (rad or m, N points), got {v!r}")
        if name in out:
            fail(f"--motor {name} is given twice")
        out[name] = (lo, hi, n)
    return out



def _motor_atlas(robot: Path, sidecar: Path | None, output: str | None, motor: list[str], count: int | None,
                 motor_k: float, joint_k: float, lock: list[str], threads: int | None, out: Path,
                 figures: Path | None, frequency: bool, quiet: bool, overwrite: bool,
                 loaded: tuple[bool, float] = (False, 0.0)) -> None:
    """``h4pin atlas --robot FILE``: :func:`h4pin.mechanism.atlas.atlas`."""
    from h4pin import plots
    from h4pin.files import check_output, check_replace
    from h4pin.mechanism import atlas as motor_atlas
    from h4pin.mechanism import store

    if output is None:
        fail("--robot needs --output FRAME (the frame whose compliance is mapped)")
    grid = parse_motors(motor)
    store.check_out(out, "--out")
    check_replace(out, "--out", overwrite)
    if figures is not None:
        check_output(figures / "atlas_status.png", "--figures")
        for q in ("compliance_max", *(("first_frequency",) if frequency else ()), "status"):
            check_replace(figures / f"atlas_{q}.png", "--figures", overwrite)
    mech = load_mechanism(robot, sidecar)
    springs = motor_atlas.default_springs(mech, motor_k, joint_k, lock)
    axes = motor_atlas.motor_axes(mech, grid, count=count) if count is not None else grid
    check_payload(loaded[1])
    if loaded[1] > 0 and not loaded[0]:
        fail("--payload goes with --gravity (its weight)")
    ds = motor_atlas.atlas(mech, output, axes, springs, lock, frequency=frequency, threads=threads,
                           progress=not quiet, out=out, gravity=loaded[0], payload=loaded[1])
    ok = ds.status == motor_atlas.OK
    typer.echo(f"{mech.name}: {int(ok.sum())} of {ok.size} grid points assembled and restrained "
               f"({', '.join(f'{s} {int((ds.status == c).sum())}' for c, s in enumerate(motor_atlas.STATUS_NAMES))})")
    _atlas_ranges(ds, ok, frequency, f" at {output}", ".4g")
    if loaded[0] and int(ok.sum()):
        import numpy as np

        sag = np.sqrt((ds.sag ** 2).sum("xyz"))
        typer.echo(f"sag of {output} under the robot's weight{f' and {loaded[1]:g} kg' if loaded[1] else ''}: "
                   f"{float(sag.min()) * 1e3:.4g} to {float(sag.max()) * 1e3:.4g} mm")
    wrote(out, *(plots.atlas_maps(ds, figures) if figures is not None else ()))


