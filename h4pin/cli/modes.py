# SPDX-License-Identifier: Apache-2.0
"""``h4pin modes``: natural frequencies of the elastic H4 (and a map of the first)."""

from __future__ import annotations

import math
from pathlib import Path

import typer

from h4pin.cli import common


def modes(
    variant: common.Variant | None = typer.Option(None, help=common.VARIANT),
    urdf: Path | None = typer.Option(None, help=common.URDF),
    pose: tuple[float, float, float, float] | None = typer.Option(
        None, metavar="X Y Z THETA", help="pose of D in m and rad (default: all actuators at 45 deg)"),
    payload: float = typer.Option(0.0, metavar="KG", help=common.PAYLOAD),
    count: int = typer.Option(4, help="how many modes to print"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH",
                                       help="write a map of the first frequency over x-y to this PNG"),
    grid: int = typer.Option(21, help="--figure: points per side of the x-y grid"),
    span: float = typer.Option(0.3, help="--figure: side of the x-y grid around the centre, m"),
    overwrite: bool = typer.Option(False, "--overwrite", help=common.OVERWRITE),
) -> None:
    """Natural frequencies of the elastic robot (actuators locked, link inertias from the URDF)."""
    from h4pin import limits

    figure_name = "--figure"
    common.check_finite("--pose", pose)
    common.check_payload(payload)
    limits.check_range("--payload", payload, "payload")
    if count < 1:
        common.fail(f"--count must be >= 1, got {count}")
    if figure is not None:
        if grid < 2 or not (math.isfinite(span) and span > 0):
            common.fail(f"--grid must be >= 2 and --span a length > 0 (m), got {grid} and {span:g}")
        from h4pin.files import check_output, check_replace
        from h4pin.studies.frequency import check_size

        check_size(grid * grid, f"modes --grid {grid}")

        check_output(figure, figure_name, suffixes=(".png",))
        check_replace(figure, figure_name, overwrite)
    import numpy as np

    from h4pin.kinematics.closed_form import centre_pose
    from h4pin.mechanism import Payload
    from h4pin.vibration import modes as natural_modes

    h4 = common.load_robot(variant, urdf)
    x = centre_pose(h4) if pose is None else np.array(pose, dtype=float)
    load_ = Payload(payload) if payload > 0 else None
    res = natural_modes(h4, x, load_)
    typer.echo(f"natural modes at x y z theta = {' '.join(f'{v:g}' for v in x)} (m, rad), payload {payload:g} kg")
    typer.echo(f"{'mode':>4}  {'Hz':>8}  plate motion (largest of dD mm, dOmega x 0.1 m)")
    for k in range(min(count, len(res.frequencies))):
        tp = res.shapes_tp[k]
        parts = np.r_[np.abs(tp[:3]), np.abs(tp[3:6]) * 0.1]
        axis = ("x", "y", "z", "rx", "ry", "rz")[int(np.argmax(parts))]
        typer.echo(f"{k + 1:>4}  {res.frequencies[k]:8.1f}  mostly {axis}")
    if figure is not None:
        from h4pin import plots
        from h4pin.studies import frequency

        c = centre_pose(h4)
        axis = np.linspace(-span / 2, span / 2, grid)
        ds = frequency.frequency_map(h4, c[0] + axis, c[1] + axis, float(x[2]), float(x[3]), load_)
        f = ds.first_frequency.values
        ok = np.isfinite(f)
        if ok.any():
            typer.echo(f"first frequency over the map: {f[ok].min():.1f} to {f[ok].max():.1f} Hz "
                       f"({int(ok.sum())} of {f.size} poses reachable and regular)")
        else:
            typer.echo(f"first frequency over the map: none of its {f.size} poses is reachable and regular")
        common.wrote(plots.frequency_map(ds, figure))


