# SPDX-License-Identifier: Apache-2.0
"""Command line: ``h4pin table2`` (the paper's Table II) and ``h4pin view`` (meshcat viewer).

Errors a user can act on (unreachable or singular pose, bad parameter, malformed URDF, bad
arguments) print one line on stderr and exit with status 2; nothing is half-written.
"""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from h4pin.errors import H4Error

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="The H4 parallel robot on Pinocchio and its stiffness (Company et al., ICRA 2005).")


@app.callback()
def _root() -> None:
    """The H4 parallel robot on Pinocchio and its stiffness (Company et al., ICRA 2005)."""


def fail(message: str) -> None:
    """Print a one-line error and exit with status 2."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(2)


def load_robot(variant: str | None, urdf: Path | None):
    """The robot named by ``--variant`` or ``--urdf`` (not both)."""
    from h4pin.robot import load

    if variant and urdf:
        fail("give --variant or --urdf, not both")
    return load(urdf if urdf else (variant or "prototype"))


@app.command()
def table2(
    variant: str | None = typer.Option(None, help="shipped variant (default: prototype)"),
    urdf: Path | None = typer.Option(None, help="path to an H4 URDF instead of a variant"),
    model: str = typer.Option("paper", help="'paper' (eq. 30 as printed) or 'consistent' (erratum 4 fixed)"),
) -> None:
    """Table II of the paper: compliance at q_i = 45 deg beside the paper's computed and measured tables."""
    from h4pin.table2 import report

    typer.echo(report(load_robot(variant, urdf), model=model))


def main() -> None:
    """Entry point of the ``h4pin`` console script."""
    try:
        app()
    except (H4Error, ValueError, FileNotFoundError) as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)


if __name__ == "__main__":
    main()
