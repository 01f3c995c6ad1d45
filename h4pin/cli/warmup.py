# SPDX-License-Identifier: Apache-2.0
"""``h4pin warmup``: compile the kernels into numba's cache ahead of use."""

from __future__ import annotations

import typer


def warmup(
    quiet: bool = typer.Option(False, "--quiet", help="print only the total, not each kernel as it compiles"),
) -> None:
    """Compile the compliance kernels into numba's cache now (else the first calls after an install
    use the numpy path while they compile in the background)."""
    from h4pin.warmup import compile_all

    total = compile_all(None if quiet else lambda name, seconds: typer.echo(f"compiled {name} in {seconds:.1f} s"),
                        isolate=True)
    typer.echo(f"compiled code cached ({total:.1f} s)")


