# SPDX-License-Identifier: Apache-2.0
"""``h4pin table2``: the paper's Table II beside this robot's compliance."""

from __future__ import annotations

from pathlib import Path

import typer

from h4pin.cli.common import MODEL, PAYLOAD, URDF, VARIANT, Model, Variant, check_payload, fail, load_robot


def table2(
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    model: Model = typer.Option("paper", help=MODEL),
    match: bool = typer.Option(False, "--measured-match", help="side by side: this robot, the 'measured_match' "
                               "variant (a saturated fit of the measured table) at its point, the paper's tables"),
    gravity: bool = typer.Option(False, "--gravity", help="also the robot under its own weight there: the sag of D "
                                 "and the loaded (tangent) K_tt beside the unloaded one (docs/loaded.md)"),
    payload: float = typer.Option(0.0, metavar="KG", help=f"with --gravity: {PAYLOAD}"),
) -> None:
    """Table II of the paper: compliance at q_i = 45 deg beside the paper's computed and measured tables."""
    from h4pin.studies.table2 import report, report_match

    check_payload(payload)
    if payload > 0 and not gravity:
        fail("--payload goes with --gravity (its weight)")
    h4 = load_robot(variant, urdf)
    typer.echo((report_match if match else report)(h4, model=model))
    if gravity:
        from h4pin.studies.loaded import loaded_report

        typer.echo("\n" + loaded_report(h4, payload))


