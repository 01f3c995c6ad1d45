# SPDX-License-Identifier: Apache-2.0
"""``h4pin sweep``: the design sweep and its Pareto front."""

from __future__ import annotations

from pathlib import Path

import typer

from h4pin.cli.common import MODEL, OVERWRITE, QUIET, Model, fail, wrote


def sweep(
    out: Path = typer.Option(Path("sweep.zarr"), metavar="PATH", help="zarr store of the results (resumed if it "
                             "exists)"),
    designs: int = typer.Option(1000, help="number of designs (Sobol sequence over the design space)"),
    seed: int = typer.Option(0, help="seed of the Sobol sequence"),
    chunk: int = typer.Option(64, help="designs per task (and per zarr chunk)"),
    model: Model = typer.Option("paper", help=f"{MODEL}; both give the same K_tt"),
    workers: int | None = typer.Option(None, help="run on a Dask LocalCluster with this many workers"),
    scheduler: str | None = typer.Option(None, help="run on the Dask scheduler at this address"),
    threads: int | None = typer.Option(None, help="numba threads per task (default: all locally, 1 on Dask)"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH", help="write the Pareto figure to this PNG"),
    urdf_dir: Path | None = typer.Option(None, metavar="DIR", help="write the best designs here as URDF variants"),
    frequency: bool = typer.Option(False, "--frequency",
                                   help="also each design's first natural frequency (Hz): the lowest over the task "
                                   "box's centre and 16 corners that the design reaches, not the box's lowest "
                                   "(a few per cent above it, more where a corner is out of reach; docs/modes.md)"),
    quiet: bool = typer.Option(False, "--quiet", help=QUIET),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
) -> None:
    """Design sweep: which designs reach the task box, their worst compliance and workspace volume
    (and first natural frequency)."""
    from h4pin import plots
    from h4pin.files import check_output, check_replace
    from h4pin.studies import sweep as sweep_module

    figure_name = "--figure"
    spec = sweep_module.Spec(n_designs=designs, seed=seed, chunk=chunk, model=model, frequency=frequency)
    sweep_module.check_store(out, "--out", overwrite)
    if figure is not None:
        check_output(figure, figure_name, suffixes=(".png",))
        check_replace(figure, figure_name, overwrite)
    if urdf_dir is not None:
        if not urdf_dir.is_dir():
            fail(f"--urdf-dir: folder {urdf_dir} does not exist")
        check_output(urdf_dir / "h4_sweep.urdf", "--urdf-dir")
        for old in sorted(urdf_dir.glob("h4_sweep_*.urdf")):  # the names depend on the results: all that could be
            check_output(old, "--urdf-dir")  # a folder of that name
            check_replace(old, "--urdf-dir", overwrite)
    if workers is not None and workers < 1:
        fail(f"--workers must be >= 1 (Dask workers), got {workers}")
    res = sweep_module.run(out, spec, workers=workers, scheduler=scheduler, threads=threads, progress=not quiet,
                           overwrite=overwrite)
    front = sweep_module.pareto(res)
    typer.echo(f"{res['done'].sum()} of {len(res['done'])} chunks done; {res['valid'].sum()} valid designs, "
               f"{res['reach_all'].sum()} reach the whole task box, {front.size} on the Pareto front")
    for d in front:
        hz = f", first frequency {res['first_frequency'][d]:.1f} Hz" if frequency else ""
        typer.echo(f"  design {d}: worst {res['worst'][d] * 1e6:.1f} um/N, volume {res['volume'][d] * 1e3:.0f} dm^3"
                   f"{hz}")
    wrote(*([plots.sweep_pareto(res, figure)] if figure is not None else ()),
          *(sweep_module.write_best(res, urdf_dir) if urdf_dir is not None else ()))


