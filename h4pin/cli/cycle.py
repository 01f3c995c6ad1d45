# SPDX-License-Identifier: Apache-2.0
"""``h4pin cycle``: the tool's deflection along the pick-and-place cycle."""

from __future__ import annotations

import math
from pathlib import Path

import typer

from h4pin.cli.common import (
    CYCLE_MODEL,
    OVERWRITE,
    PAYLOAD,
    URDF,
    VARIANT,
    Model,
    Variant,
    check_finite,
    check_payload,
    fail,
    load_robot,
    wrote,
)


def cycle(
    time: float = typer.Option(0.5, "--time", help="cycle time, s (25 mm up, 305 mm across, 25 mm down and back)"),
    payload: list[float] = typer.Option([0.5], metavar="KG", help=f"{PAYLOAD}; repeat for one column per payload"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH",
                                       help="write trajectory, load, deflection and torques to this PNG"),
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    heading: float = typer.Option(0.0, help="direction of the stroke in the horizontal plane, rad (0: +x)"),
    samples: int = typer.Option(400, help="time steps over the cycle"),
    model: Model = typer.Option(CYCLE_MODEL, help="'consistent' (symmetric K; the cycle's dynamics need it) "
                                "or 'paper' (eq. 30 as printed)"),
    elastic: bool = typer.Option(False, "--elastic", help="also the elastic robot's own answer: the whole robot's "
                                 "loads, its vibration along the cycle and after the stop"),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
) -> None:
    """Tool deflection along the standard pick-and-place cycle (closed-loop inverse dynamics, quasi-static;
    with --elastic, the elastic robot's dynamics too)."""
    from h4pin import limits
    from h4pin.files import check_output, check_replace
    from h4pin.studies import cycle as cycle_module

    if not (math.isfinite(time) and time > 0):
        fail(f"--time must be a finite number > 0 (s), got {time:g}")
    limits.check_range("--time", time, "cycle_time")
    check_payload(payload)
    limits.check_range("--payload", payload, "payload")
    if samples < 8:
        fail(f"--samples must be >= 8, got {samples}")
    limits.check_cycle_samples(samples, len(payload))
    if elastic:  # its motion and the stop after it (sampled at the cycle's step), before the rigid cycle runs
        from h4pin.studies.elastic_cycle import HOLD

        limits.check_elastic_cycle(samples, math.ceil(HOLD / (time / samples)), len(payload))
    check_finite("--heading", (heading,))
    if figure is not None:
        check_output(figure, "--figure", suffixes=(".png",))
        check_replace(figure, "--figure", overwrite)
    h4 = load_robot(variant, urdf)
    results = [cycle_module.run(h4, time, p, samples=samples, model=model, heading=heading) for p in payload]
    typer.echo(cycle_module.report(results))
    if elastic:
        from h4pin.studies import elastic_cycle

        typer.echo("\n" + elastic_cycle.report([elastic_cycle.run(h4, time, p, samples=samples, heading=heading)
                                                for p in payload]))
    if figure is not None:
        from h4pin import plots

        wrote(plots.cycle(results[-1], figure, results[:-1]))


