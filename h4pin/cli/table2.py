# SPDX-License-Identifier: Apache-2.0
"""``h4pin table2``: the paper's Table II beside this robot's compliance."""

from __future__ import annotations

from pathlib import Path

import typer

from h4pin.cli.common import MODEL, URDF, VARIANT, Model, Variant, load_robot


def table2(
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    model: Model = typer.Option("paper", help=MODEL),
    match: bool = typer.Option(False, "--measured-match", help="side by side: this robot, the 'measured_match' "
                               "variant (a saturated fit of the measured table) at its point, the paper's tables"),
) -> None:
    """Table II of the paper: compliance at q_i = 45 deg beside the paper's computed and measured tables."""
    from h4pin.studies.table2 import report, report_match

    typer.echo((report_match if match else report)(load_robot(variant, urdf), model=model))


