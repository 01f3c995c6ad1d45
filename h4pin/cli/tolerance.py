# SPDX-License-Identifier: Apache-2.0
"""``h4pin tolerance``: the tolerance study (robots with manufacturing errors)."""

from __future__ import annotations

from pathlib import Path

import typer

from h4pin.cli.common import MODEL, OVERWRITE, QUIET, URDF, VARIANT, Model, Variant, fail, load_robot, wrote


def tolerance(
    variant: Variant | None = typer.Option(None, help=f"nominal robot: {VARIANT}"),
    urdf: Path | None = typer.Option(None, help=f"nominal robot: {URDF}"),
    robots: int = typer.Option(1000, help="robots drawn"),
    seed: int = typer.Option(0, help="seed of the draws"),
    sigma: list[str] = typer.Option([], metavar="NAME=METRES",
                                    help="sigma of one tolerance in m (forearm, A0, b, P, C0, l, mismatch)"),
    sensitivity: bool = typer.Option(True, help="also run one tolerance at a time"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH", help="write the histograms to this PNG"),
    model: Model = typer.Option("paper", help=MODEL),
    quiet: bool = typer.Option(False, "--quiet", help=QUIET),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
) -> None:
    """Tolerance study: compliance and static pose error of robots with manufacturing errors."""
    from h4pin.errors import ParameterError
    from h4pin.files import check_output, check_replace
    from h4pin.studies import tolerance as tol

    sigmas: dict[str, float] = {}
    for item in sigma:
        name, sep, value = item.partition("=")
        if not sep:
            raise ParameterError(f"--sigma must be NAME=METRES, got {item!r}")
        sigmas[name.strip()] = value  # type: ignore[assignment]  # checked by tol.check_sigmas
    sigmas = tol.check_sigmas(sigmas)
    if figure is not None:
        check_output(figure, "--figure", suffixes=(".png",))
        check_replace(figure, "--figure", overwrite)
    if robots < 1:
        fail(f"--robots must be >= 1, got {robots}")
    h4 = load_robot(variant, urdf)
    res = tol.study(h4, n_robots=robots, sigmas=sigmas, seed=seed, model=model, progress=not quiet)
    sens = tol.sensitivity(h4, n_robots=min(robots, 1000), sigmas=sigmas, seed=seed, model=model) if sensitivity \
        else None
    typer.echo(tol.report(res, sens))
    if figure is not None:
        from h4pin import plots

        wrote(plots.tolerance(res, figure))


