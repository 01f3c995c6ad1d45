# SPDX-License-Identifier: Apache-2.0
"""The result store every atlas writes: a labelled :class:`xarray.Dataset` saved atomically to
NetCDF (``.nc``) or zarr (``.zarr``), or streamed block by block into a zarr store that a killed
run resumes.

One format family for the H4's workspace atlas (:mod:`h4pin.studies.atlas`) and the motor-space
atlas of any mechanism (:mod:`h4pin.mechanism.atlas`):

* a zarr store is tagged as h4pin's (:data:`h4pin.files.STORE_ATTR`, format ``"atlas"``): an
  existing store is replaced only if h4pin wrote it, or with ``overwrite`` (:func:`check_out`);
* a streamed run (:func:`partial`) makes the store's arrays first, with their final shape, in a
  partial store beside the target (``.NAME.h4pin-partial``, :func:`partial_path`), under a lock
  (one writer at a time, :func:`h4pin.files.store_lock`); each block is written there and then
  flagged done in the array :data:`DONE`, whose ``key`` attribute is the run's fingerprint (what
  fixes its numbers). A run with another fingerprint starts anew; one with the same resumes from
  the blocks done. :func:`finish` removes the flags and renames the partial store to the target:
  the target is never half-written;
* blocks are whole rows of the last dim when a row fits in ``chunk`` points (:func:`block_layout`),
  one zarr chunk and one computation each.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from h4pin import files
from h4pin.errors import InputFileError, ParameterError
from h4pin.extras import require
from h4pin.files import check_output, clean_stale, make_readable, tmp_prefix

#: Name of the store a run streams into, beside its target: ``.NAME.h4pin-partial``. It is
#: renamed to the target once every block is in; a killed run leaves it for the next run.
PARTIAL_TAG = "h4pin-partial"
#: The array of the partial store that flags finished blocks (removed before the rename).
DONE = "h4pin_done"
#: The store format of :func:`h4pin.files.store_tag`.
FORMAT = "atlas"


def block_layout(shape: tuple[int, ...], chunk: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The blocks of a grid of ``shape``: each block is whole rows of the last dim when a row fits
    in ``chunk`` points (as many rows of the second-last dim as fit), else pieces of ``chunk``
    points of one row; one everywhere else. Returns the block shape and the number of blocks
    along each dim."""
    if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
        raise ParameterError(f"chunk must be an integer >= 1, got {chunk!r}")
    cx = min(shape[-1], int(chunk))
    if len(shape) == 1:
        block: tuple[int, ...] = (cx,)
    else:
        block = (*(1,) * (len(shape) - 2), max(1, min(shape[-2], int(chunk) // max(cx, 1))), cx)
    return block, tuple(-(-s // b) for s, b in zip(shape, block, strict=True))


def partial_path(path: str | Path) -> Path:
    """Where a streamed run writes the store ``path`` until it is whole."""
    path = Path(path)
    return path.parent / f".{path.name}.{PARTIAL_TAG}"


def check_out(path: str | Path, what: str = "path", overwrite: bool = False) -> Path:
    """Refuse, before any work, an output that :func:`save` could not write: not ``.nc`` or
    ``.zarr``, an unwritable folder, a folder where the ``.nc`` file should go, or an existing
    ``.zarr`` folder that is not an h4pin store (:func:`h4pin.files.check_store_folder`: another
    zarr store is replaced only with ``overwrite``, any other folder never)."""
    path = check_output(path, what, folder=Path(path).suffix == ".zarr", suffixes=(".nc", ".zarr"))
    if path.suffix == ".zarr":
        files.check_store_folder(path, FORMAT, what, overwrite)
    return path


def open_partial(path: Path, template: Any, key: str, n_blocks: int) -> Any:
    """The partial store of ``path`` (the caller holds :func:`h4pin.files.store_lock`): resumed if
    it holds this run (its :data:`DONE` flags' ``key``), else made anew from ``template`` (a lazy
    Dataset with the final shapes and chunks) -- in a temporary folder, moved into place whole."""
    import zarr

    partial = partial_path(path)
    for _ in range(3):
        if not partial.exists():
            tmp = Path(tempfile.mkdtemp(prefix=tmp_prefix(path), dir=path.parent))
            try:
                store = tmp / "store"
                tagged = template.assign_attrs({files.STORE_ATTR: files.store_tag(FORMAT)})
                tagged.to_zarr(store, mode="w", consolidated=False, compute=False)
                group = zarr.open_group(str(store), mode="a")
                create = getattr(group, "create_array", None) or group.create_dataset  # zarr 3, zarr 2
                done = create(DONE, shape=(n_blocks,), chunks=(n_blocks,), dtype="bool", fill_value=False)
                done.attrs["key"] = key
                os.replace(store, partial)  # atomic: the partial store appears whole
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
        try:
            group = zarr.open_group(str(partial), mode="a")
            same = group[DONE].attrs.get("key") == key
        except (KeyError, OSError, ValueError):  # a damaged partial store (zarr's errors are ValueErrors)
            same = False
        if same:
            return group
        shutil.rmtree(partial, ignore_errors=True)  # another run's (or a damaged) partial store
    raise ParameterError(f"out: cannot make the partial store {partial}")


def check_stream(path: str | Path, what: str = "out", overwrite: bool = False) -> Path:
    """:func:`check_out` for a streamed run: a ``.zarr`` path only (zarr installed)."""
    require("zarr", extra="studies", what="writing .zarr stores")
    path = check_out(path, what, overwrite)
    if path.suffix != ".zarr":
        raise ParameterError(f"{what} {path}: a streamed atlas is a .zarr store")
    return path


@contextlib.contextmanager
def partial(path: str | Path, template: Any, key: str, n_blocks: int, *, what: str = "out",
            overwrite: bool = False) -> Iterator[Any]:
    """The partial zarr group of a streamed run into ``path``, under the store's lock: the output
    checked again under the lock (another run may have written it meanwhile), a stale temporary
    folder removed, the partial store resumed or made (:func:`open_partial`). The caller fills
    the blocks and calls :func:`finish` inside the block.

    Raises:
        ParameterError: not a ``.zarr`` path; as :func:`check_out`; another process writes there.
    """
    path = check_stream(path, what, overwrite)
    with files.store_lock(path, FORMAT):
        check_out(path, what, overwrite)
        clean_stale(path)
        yield open_partial(path, template, key, n_blocks)


def finish(path: Path) -> None:
    """Move the whole partial store of ``path`` into place (the caller holds the lock): the done
    flags removed, files made readable, an old store at ``path`` replaced."""
    part = partial_path(path)
    shutil.rmtree(part / DONE)
    make_readable(part)
    tmp = Path(tempfile.mkdtemp(prefix=tmp_prefix(path), dir=path.parent))
    try:
        if path.exists():
            os.replace(path, tmp / "old")
        os.replace(part, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def opened(path: Path) -> Any:
    """The store at ``path`` opened lazily, without its own tag (:data:`h4pin.files.STORE_ATTR`)."""
    import xarray as xr

    ds = xr.open_zarr(path, consolidated=False)
    ds.attrs.pop(files.STORE_ATTR, None)
    return ds


def save(ds: Any, path: str | Path, overwrite: bool = False) -> Path:
    """Write a Dataset atomically: ``.nc`` (NetCDF4 through h5netcdf) or ``.zarr`` (a folder,
    tagged as h4pin's, written by one process at a time). Files are mode 0644; nothing is left
    half-written if the write fails, and the temporary folder a killed save left is removed the
    next time (:func:`h4pin.files.clean_stale`).

    Raises:
        ParameterError: as :func:`check_out`; another process writes the ``.zarr`` store now.
    """
    path = check_out(path, "path", overwrite)
    require("h5netcdf" if path.suffix == ".nc" else "zarr", extra="studies", what=f"writing {path.suffix} files")
    if path.suffix == ".zarr":
        with files.store_lock(path, FORMAT):
            check_out(path, "path", overwrite)  # again, under the lock
            return _save(ds, path)
    return _save(ds, path)


def _save(ds: Any, path: Path) -> Path:
    clean_stale(path)
    tmp = Path(tempfile.mkdtemp(prefix=tmp_prefix(path), dir=path.parent))
    try:
        target = tmp / path.name
        if path.suffix == ".nc":
            ds.to_netcdf(target, engine="h5netcdf")
            os.chmod(target, 0o644)
        else:
            ds.assign_attrs({files.STORE_ATTR: files.store_tag(FORMAT)}).to_zarr(target, mode="w", consolidated=False)
            make_readable(target)
            if path.exists():
                os.replace(path, tmp / "old")
        os.replace(target, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path


def open_store(path: str | Path, what: str = "atlas") -> Any:
    """Read a Dataset written by :func:`save` (or a finished streamed run) into memory: a
    ``.zarr`` folder tagged as an h4pin atlas (:func:`h4pin.files.store_format`), or a NetCDF
    file whose attributes say ``h4pin: atlas``. ``what`` names the argument in messages.

    Raises:
        InputFileError: naming ``what`` and the path: missing, not a regular file (a FIFO, a
            device) or a folder, a folder that is no zarr store or a store h4pin did not write
            (or of another format or version), a file that is not NetCDF or not an h4pin atlas.
    """
    import xarray as xr

    zarr_store = Path(files.input_path(path, what)).suffix == ".zarr"
    path = files.check_input(path, what, max_bytes=2**62, folder=zarr_store)
    if zarr_store:
        if files.store_format(path) != FORMAT:
            attrs = files.store_attributes(path)
            why = ("is not a zarr store" if attrs is None else files.not_ours(attrs, FORMAT)
                   .replace("exists and h4pin did not write it", "is a zarr store h4pin did not write (no "
                            f"{files.STORE_ATTR} attribute)"))
            raise InputFileError(f"{what} {path} {why}: give an atlas h4pin wrote")
    try:
        with (opened(path) if zarr_store else xr.open_dataset(path, engine="h5netcdf")) as ds:
            if not zarr_store and ds.attrs.get("h4pin") != FORMAT:
                raise InputFileError(f"{what} {path} is a NetCDF file h4pin did not write as an atlas (its attributes "
                                     "hold no h4pin: atlas): give an atlas h4pin wrote")
            return ds.load()
    except (OSError, ValueError, KeyError, TypeError) as exc:
        if isinstance(exc, InputFileError):
            raise
        raise InputFileError(f"{what} {path}: h4pin cannot read it as an atlas ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:300]})") from None


__all__ = ["DONE", "FORMAT", "PARTIAL_TAG", "block_layout", "check_out", "check_stream", "finish", "open_partial",
           "open_store", "opened", "partial", "partial_path", "save"]
