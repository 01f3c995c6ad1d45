# SPDX-License-Identifier: Apache-2.0
"""``h4pin calibrate``: any robot's calibration from measured tool positions, a stage table, the
calibrated URDF."""

from __future__ import annotations

from pathlib import Path

import typer

from h4pin.cli.common import OVERWRITE, ROBOT, SIDECAR, fail, is_number, load_mechanism, wrote


def _springs(values: list[str]) -> dict[str, float]:
    out = {}
    for item in values:
        joint, _, value = item.partition("=")
        if not joint or not is_number(value):
            fail(f"--spring takes JOINT=K (K in N.m/rad or N/m), got {item!r}")
        out[joint] = float(value)
    return out


def _stages(text: str) -> list[dict[str, list[str] | None]]:
    """``"base,markers +offsets +geometry:free1|free2"``: the first stage's groups, then each ``+``
    step's; ``group:a|b`` fits the group's targets a and b only (joints, markers, links)."""
    out = []
    for step in text.split("+"):
        spec: dict[str, list[str] | None] = {}
        for item in (g.strip() for g in step.split(",")):
            if not item:
                continue
            group, _, targets = item.partition(":")
            names = [t.strip() for t in targets.split("|") if t.strip()]
            if targets and not names:
                fail(f"--stages: {item!r} names no target after ':'")
            spec[group.strip()] = names or None
        if spec:
            out.append(spec)
    return out


def calibrate(
    robot: Path = typer.Option(..., metavar="FILE", help=ROBOT),
    measurements: Path = typer.Option(..., metavar="FILE", help="the tracker's samples: .csv (q.<joint> or "
                                      "m.<motor>, p.<frame>.x/y/z, f.<frame>.fx..tz columns) or .npz "
                                      "(docs/calibration.md)"),
    stages: str = typer.Option("base,markers +offsets +springs", metavar="GROUPS",
                               help="the groups fitted, stage by stage: 'base,markers +offsets +geometry +springs "
                               "+lateral' (groups: base, markers, offsets, geometry, springs, lateral, beams, masses); "
                               "group:a|b fits the targets a and b only (joints, markers, links); the last stage "
                               "is the calibration written"),
    sidecar: Path | None = typer.Option(None, metavar="YAML", help=SIDECAR),
    spring: list[str] | None = typer.Option(None, metavar="JOINT=K", help="a joint's nominal spring, N.m/rad or N/m; "
                                            "repeat (default: the file's springs)"),
    gravity: bool = typer.Option(True, help="the robot's weight deflects it in every sample (the loaded equilibrium)"),
    noise: float | None = typer.Option(None, metavar="M", help="the markers' noise per axis, m (default: estimated)"),
    loss: str = typer.Option("linear", help="SciPy's robust loss: linear, soft_l1, huber, cauchy, arctan"),
    holdout: float = typer.Option(0.2, metavar="FRACTION", help="samples kept out of every stage's fit and scored"),
    out: Path | None = typer.Option(None, metavar="PATH", help="write the calibrated robot here (.urdf, and its "
                                    "sidecar .yaml beside it)"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH", help="write the markers' errors before and "
                                       "after to this PNG"),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
) -> None:
    """Calibrate any robot from measured tool positions: a stage-by-stage table of the markers'
    errors (fit and held-out samples), what the data cannot identify, the calibrated values.

    The fit: h4pin.calibrate (docs/calibration.md): the loaded equilibrium under gravity and the
    known loads in every prediction, the prior's nominal model and sigmas."""
    from h4pin.files import check_output, check_replace
    from h4pin.mechanism import calibration as cal
    from h4pin.mechanism.measurements import Measurements

    steps = _stages(stages)
    if not steps:
        fail("--stages: give at least one group")
    for name, path, suffixes in (("--out", out, (".urdf",)), ("--figure", figure, (".png",))):
        if path is not None:
            check_output(path, name, suffixes=suffixes)
            check_replace(path, name, overwrite)
            if name == "--out":
                check_replace(path.with_suffix(".yaml"), name, overwrite)
    mech = load_mechanism(robot, sidecar)
    meas = Measurements.read(measurements)
    options = {"springs": _springs(spring) if spring else None, "gravity": gravity, "noise": noise, "loss": loss}
    rows = cal.stages(mech, meas, steps, holdout=holdout, **options)
    typer.echo(f"{mech.name}: {meas.n} samples, {len(meas.markers)} marker(s), {holdout:.0%} held out")
    typer.echo(cal.stage_table(rows))
    last = rows[-1].calibration
    if last.unidentifiable:
        typer.echo("not identified by the data (held at the prior): " + "; ".join(last.unidentifiable))
    typer.echo(f"{'parameter':<34}{'value':>16}{'std':>14}")
    for name, value in last.values.items():
        typer.echo(f"{name:<34}{value:>16.6g}{last.std[name]:>14.3g}")
    written = []
    if out is not None:
        written += list(last.to_urdf(out, overwrite=overwrite))
    if figure is not None:
        from h4pin import plots

        written.append(plots.calibration(rows, figure))
    wrote(*written)
