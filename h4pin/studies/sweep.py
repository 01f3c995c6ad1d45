# SPDX-License-Identifier: Apache-2.0
"""Design sweeps: the compliance of eq. 30 (Company, Pierrot, Fauroux, ICRA 2005) over many designs.

A design is an :class:`h4pin.H4Params` with six numbers changed (:data:`VARIABLES`): the
parallelogram half-width, the forearm and bar lengths, the actuator layout radius (a factor on
the x, y of P), the plate size (a factor on the x, y of DB and DC) and the actuator stiffness kc.
For each design, the compiled kernel (:mod:`h4pin.stiffness.kernel`) gives, over

* the task workspace (a box of poses, :class:`Task`): whether every pose is reachable, within the
  joint limits, bar-clear and regular (``reach_all``), and the worst compliance over it -- the
  largest eigenvalue of the symmetric part of K_tt, m/N (``worst``);
* a fixed, larger grid at theta = 0: the workspace volume, the count of poses with status 0
  times the cell volume, m^3 (``volume``).

The sweep runs locally (numba threads) or on Dask (``workers=N`` starts a LocalCluster,
``scheduler=ADDRESS`` uses a running one). Results go to a zarr store, one zarr chunk per task
of ``chunk`` designs, and a ``done`` flag per chunk written after its results: a killed sweep
resumes where it stopped. Every number depends on its design only, so local and Dask runs agree
exactly. See ``docs/scaling.md``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from h4pin import files, limits
from h4pin.description.elements import ELEMENTS, Elements
from h4pin.description.params import H4Params
from h4pin.errors import ParameterError
from h4pin.extras import require
from h4pin.files import check_output, clean_stale, make_readable, tmp_prefix
from h4pin.stiffness import frequencies, kernel, pipeline
from h4pin.studies import _derived

#: The design variables, in order: name -> (unit, meaning).
VARIABLES = {
    "half_width": ("m", "half the width h of each parallelogram"),
    "r": ("m", "forearm length"),
    "l": ("m", "bar length"),
    "layout": ("1", "factor on the x, y of the actuator axis points P (layout radius)"),
    "plate": ("1", "factor on the x, y of DB and DC (plate size)"),
    "kc": ("N.m/rad", "actuator control stiffness"),
}
#: Default bounds of the design space (the prototype is inside).
BOUNDS = {"half_width": (0.02, 0.05), "r": (0.2, 0.32), "l": (0.4, 0.6), "layout": (0.8, 1.25),
          "plate": (0.9, 1.3), "kc": (4e3, 12e3)}


@dataclasses.dataclass(frozen=True)
class Task:
    """A box of poses [x, y, z, theta]: ``centre`` +- ``half`` (m, rad), ``counts`` points per axis."""

    centre: tuple[float, float, float, float] = (0.0, 0.0, -0.6, 0.0)
    half: tuple[float, float, float, float] = (0.1, 0.1, 0.05, 0.3)
    counts: tuple[int, int, int, int] = (5, 5, 5, 8)

    def poses(self) -> np.ndarray:
        axes = [np.linspace(c - h, c + h, n) if n > 1 else np.array([c])
                for c, h, n in zip(self.centre, self.half, self.counts, strict=True)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 4)

    def corners(self) -> np.ndarray:
        """(17, 4) the box's centre and its 16 corners."""
        signs = np.array(np.meshgrid(*([[-1.0, 1.0]] * 4), indexing="ij")).reshape(4, -1).T
        return np.concatenate([[self.centre], np.asarray(self.centre) + signs * np.asarray(self.half)])


@dataclasses.dataclass(frozen=True)
class VolumeGrid:
    """The fixed grid (theta = 0) whose reachable cells measure the workspace volume: ``lo`` to
    ``hi`` (m) with ``counts`` cell centres per axis."""

    lo: tuple[float, float, float] = (-0.5, -0.5, -1.1)
    hi: tuple[float, float, float] = (0.5, 0.5, -0.1)
    counts: tuple[int, int, int] = (12, 12, 12)

    @property
    def cell(self) -> float:
        """Volume of one cell, m^3."""
        return float(np.prod([(h - l) / n for l, h, n in zip(self.lo, self.hi, self.counts, strict=True)]))

    def poses(self) -> np.ndarray:
        axes = [l + (np.arange(n) + 0.5) * (h - l) / n for l, h, n in zip(self.lo, self.hi, self.counts, strict=True)]
        xyz = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        return np.concatenate([xyz, np.zeros((len(xyz), 1))], axis=1)


@dataclasses.dataclass(frozen=True)
class Spec:
    """Everything that fixes the numbers of a sweep (stored with the results, checked on resume)."""

    n_designs: int = 1000
    seed: int = 0
    bounds: dict = dataclasses.field(default_factory=lambda: dict(BOUNDS))
    task: Task = Task()
    volume: VolumeGrid = VolumeGrid()
    model: str = "consistent"
    chunk: int = 64
    #: The compliant elements every design carries (:class:`h4pin.Elements` fields, SI; none by
    #: default: eq. 30 alone), in the compiled pipeline with each design's own beam lengths.
    elements: dict = dataclasses.field(default_factory=dict)
    #: Also the lowest first natural frequency over the task box's centre and its 16 corners
    #: (:meth:`Task.corners`; those the design reaches) (Hz; the elastic robot with the URDF's link
    #: inertias, :mod:`h4pin.stiffness.frequencies`). Not the lowest over the box: 17 poses, not
    #: the task grid, so an upper bound of it (docs/modes.md: up to 2.4 % above the lowest over
    #: the 1 000 task poses for designs that reach them all, 26 % for one that does not).
    frequency: bool = False

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> Spec:
        d = json.loads(text)
        d["task"] = Task(**{k: tuple(v) for k, v in d["task"].items()})
        d["volume"] = VolumeGrid(**{k: tuple(v) for k, v in d["volume"].items()})
        d["bounds"] = {k: tuple(v) for k, v in d["bounds"].items()}
        return cls(**d)

    def __post_init__(self) -> None:
        if self.n_designs < 1:
            raise ParameterError(f"n_designs must be >= 1, got {self.n_designs!r}")
        if self.chunk < 1:
            raise ParameterError(f"chunk must be >= 1, got {self.chunk!r}")
        if set(self.bounds) != set(VARIABLES):
            raise ParameterError(f"bounds must give {tuple(VARIABLES)}, got {tuple(self.bounds)}")
        object.__setattr__(self, "bounds", {k: tuple(float(v) for v in self.bounds[k]) for k in VARIABLES})
        limits.check_springs({"kc": self.bounds["kc"]}, "bounds")
        kernel.model_code(self.model)
        self.element_set()  # checked now: a bad name or value is refused before any work

    @property
    def n_chunks(self) -> int:
        return -(-self.n_designs // self.chunk)

    def element_set(self) -> Elements | None:
        """The designs' :class:`h4pin.Elements` (None when none is on)."""
        if not isinstance(self.elements, dict):
            raise ParameterError(f"elements must be a dict of h4pin.Elements fields, got {self.elements!r}")
        unknown = set(self.elements) - set(ELEMENTS)
        if unknown:
            raise ParameterError(f"unknown element kinds {sorted(unknown)}; the kinds are {ELEMENTS}")
        el = Elements(**self.elements)
        return None if el.off else el


#: Bytes a sweep holds per design: the Sobol points (up to twice n_designs, 6 float64) and the
#: table (measured 146 bytes a design over 1e6 designs), the table read back by :func:`run` (48)
#: and the results :func:`load` returns (~80): rounded up.
BYTES_PER_DESIGN = 300
#: Designs a second on 2 cores (measured 670/s with the default task box and volume grid, 210/s
#: with the first frequency; rounded down).
DESIGNS_PER_S, FREQUENCY_DESIGNS_PER_S = 500.0, 150.0


def check_size(spec: Spec) -> None:
    """Refuse, before any work, a sweep whose design table and results do not fit in memory
    (:data:`BYTES_PER_DESIGN`; limit :func:`h4pin.limits.memory_limit`, ``H4PIN_MEMORY_LIMIT``);
    the message also gives the time it would take (:data:`DESIGNS_PER_S`).

    Raises:
        h4pin.limits.TooLargeError: over the limit (a :class:`h4pin.ParameterError`).
    """
    n = limits.count(spec.n_designs)
    # a zarr chunk is held whole in memory while it is written: --chunk larger than the sweep costs its size
    chunk = limits.count(spec.chunk)
    # the poses counted, not made (a task box of 1e12 poses would fail in making them)
    poses = sum(limits.count(math.prod(limits.count(c) for c in counts))
                for counts in (spec.task.counts, spec.volume.counts))
    need = (n + 2 * chunk) * BYTES_PER_DESIGN + poses * limits.COMPLIANCE_BYTES_PER_POSE
    rate = FREQUENCY_DESIGNS_PER_S if spec.frequency else DESIGNS_PER_S
    limits.check_size(f"sweep: {n:,} designs in chunks of {chunk:,}", need, n / rate,
                      "use fewer designs (--designs) or smaller chunks (--chunk)")


def designs(spec: Spec) -> np.ndarray:
    """The design table (n_designs, 6), columns :data:`VARIABLES`: the first n_designs points of
    a scrambled Sobol sequence (seeded, 2^m points drawn) over the bounds."""
    from scipy.stats import qmc

    check_size(spec)

    m = max(0, int(np.ceil(np.log2(spec.n_designs))))
    unit = qmc.Sobol(len(VARIABLES), scramble=True, seed=spec.seed).random_base2(m)[:spec.n_designs]
    lo = np.array([spec.bounds[k][0] for k in VARIABLES])
    hi = np.array([spec.bounds[k][1] for k in VARIABLES])
    return lo + unit * (hi - lo)


_BASE: list[H4Params] = []


def _base() -> H4Params:
    """The prototype's :class:`H4Params`, made once (validating it costs 0.3 ms)."""
    if not _BASE:
        _BASE.append(H4Params())
    return _BASE[0]


#: Which coordinates the layout and plate factors scale: x and y, not z.
_XY = np.array([[1.0], [1.0], [0.0]])


def _design_arrays(rows: np.ndarray, base: H4Params) -> dict[str, np.ndarray]:
    """The changed :class:`h4pin.H4Params` fields of many design rows (n, 6), as H4Params holds
    them, with a leading design axis: P, DB, DC (n, 3, 4 or 2), half_width, r, kc (n, 4), l (n, 8)."""
    rows = np.asarray(rows, dtype=float).reshape(-1, len(VARIABLES))
    h, r, l, layout, plate, kc = (rows[:, k] for k in range(6))
    per = {"half_width": h, "r": r, "l": l, "kc": kc}
    out = {name: np.repeat(v[:, None], 8 if name == "l" else 4, axis=1) for name, v in per.items()}
    out["P"] = base.P * (1 + (layout[:, None, None] - 1) * _XY)
    out["DB"] = base.DB * (1 + (plate[:, None, None] - 1) * _XY)
    out["DC"] = base.DC * (1 + (plate[:, None, None] - 1) * _XY)
    return out


def params_of(row: np.ndarray, base: H4Params | None = None) -> H4Params:
    """The :class:`h4pin.H4Params` of one design row (raises ParameterError if it is invalid,
    e.g. ball joints colliding on the plate)."""
    base = base or _base()
    return base.replace(**{name: v[0] for name, v in _design_arrays(row, base).items()})


def kernels(rows: np.ndarray, elements: Elements | None = None) -> list[kernel.Kernel | None]:
    """The packed kernels of many design rows at once (None for an invalid design), with the
    table of ``elements`` for each (its beam lengths are the design's): the design
    arrays of all rows (:func:`_design_arrays`), then the validity checks of H4Params
    (:func:`~h4pin.description.params.ball_joints_apart`, :func:`~h4pin.description.params.bars_reach`),
    the geometry (:func:`~h4pin.description.geometry.geometry_arrays`) and the packing
    (:func:`h4pin.stiffness.kernel.pack_fields`), each over the design axis: the same as
    ``kernel.prepare(geometry_from_params(params_of(row)))``, in a fraction of the time."""
    from h4pin.description.geometry import geometry_arrays
    from h4pin.description.params import SPRINGS, ball_joints_apart, bars_reach

    base = _base()
    d = _design_arrays(rows, base)
    valid = (ball_joints_apart(d["DB"], base.U, d["half_width"], base.ball_radius)
             & bars_reach(d["P"], base.U, d["DB"], d["r"], d["l"]))
    d = {name: v[valid] for name, v in d.items()}
    springs = {name: getattr(base, name) for name in SPRINGS}
    springs["kc"] = d["kc"]
    G = kernel.pack_fields(geometry_arrays(d["P"], base.U, base.forearm_dirs, d["r"], d["l"], d["half_width"],
                                           d["DB"], d["DC"], springs))
    packed = iter(G)
    out = []
    for ok in valid:
        g = next(packed) if ok else None
        out.append(None if g is None else kernel.Kernel.from_packed(g, kernel.pack_elements(elements, g)))
    return out


#: scripts/bench.py's name for it (until bench.py is restructured).


def evaluate(rows: np.ndarray, spec: Spec, threads: int | None = None) -> dict[str, np.ndarray]:
    """Results of some designs (rows of :func:`designs`): ``valid``, ``reach_all``, ``worst``
    (m/N), ``volume`` (m^3), ``task_ok`` (count of task poses with status 0) and, with
    ``spec.frequency``, ``first_frequency`` (Hz, the lowest over the task box's centre and 16
    corners that the design reaches: :attr:`Spec.frequency`, not the lowest over the task poses).

    Per design: one kernel call over the task poses and the volume grid, reduced in compiled
    code (:func:`h4pin.studies._derived.design_reduce`); the kernels of all the rows are packed
    at once (:func:`kernels`)."""
    import numba

    if threads is not None:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    task, grid = spec.task.poses(), spec.volume.poses()
    poses = np.ascontiguousarray(np.concatenate([task, grid]))
    n = len(rows)
    out = {"valid": np.zeros(n, bool), "reach_all": np.zeros(n, bool), "worst": np.full(n, np.nan),
           "volume": np.full(n, np.nan), "task_ok": np.zeros(n, np.int32), "first_frequency": np.full(n, np.nan)}
    buf = kernel.empty_result(len(poses), False, False)
    n_task = len(task)
    if spec.frequency:
        corners = kernel.readonly(np.ascontiguousarray(spec.task.corners()))
        f_buf = kernel.empty_result(len(corners), False, False)
        inter = np.empty((len(corners), pipeline.NX))
        freq, counts = np.empty((len(corners), 1)), np.empty((len(corners), 2), dtype=np.int64)
        work = frequencies.work_arrays(frequencies.NY, frequencies.NS)
    for d, kern in enumerate(kernels(rows, spec.element_set())):
        if kern is None:
            continue
        res = kernel.compliance_batch(kern, poses, spec.model, buf)
        n_ok, worst, n_grid = _derived.design_reduce(res.K, res.status, n_task)
        out["valid"][d] = True
        out["task_ok"][d] = n_ok
        out["reach_all"][d] = n_ok == n_task
        out["worst"][d] = worst
        out["volume"][d] = n_grid * spec.volume.cell
        if spec.frequency:
            MP, CF, CI = frequencies.pack_masses_params(params_of(rows[d]))
            kernel.run_poses(kern, corners, pipeline.CONSISTENT, f_buf, False, False, inter)
            frequencies.frequencies_run(corners, 0, len(corners), f_buf.q, f_buf.status, inter, kern.packed,
                                        kern.elements, MP, CF, CI, freq, counts, work)
            ok = f_buf.status == 0
            out["first_frequency"][d] = float(np.min(freq[ok, 0])) if ok.any() else np.nan
    return out


def _chunk_task(spec_json: str, c: int, rows: np.ndarray, threads: int | None) -> tuple[int, dict[str, np.ndarray]]:
    """Chunk ``c`` of a sweep: its design rows come with it (the table is made once, by
    :func:`run`), so a task does not rebuild the Sobol sequence."""
    return c, evaluate(rows, Spec.from_json(spec_json), threads)


_RESULTS = {"valid": ("bool", False), "reach_all": ("bool", False), "worst": ("float64", np.nan),
            "volume": ("float64", np.nan), "task_ok": ("int32", 0), "first_frequency": ("float64", np.nan)}


def _open_store(path: Path, spec: Spec, overwrite: bool = False):
    """The store of ``spec`` at ``path`` (the caller holds :func:`h4pin.files.store_lock`): resumed
    if it holds this sweep; else created in a temporary folder beside it and moved into place in
    one rename (replacing, with ``overwrite``, a zarr store h4pin did not write), so that a kill at
    any moment leaves either no store or a whole one (and a stale temporary folder, removed next
    time)."""
    import zarr

    clean_stale(path)
    if check_store(path, "path", overwrite) == "ours":
        group = zarr.open_group(str(path), mode="a")
        stored = group.attrs.get("spec")
        if stored is None:
            raise ParameterError(f"path: {path} is an unfinished sweep store (no spec): remove it (rm -r {path}) and "
                                 "run again")
        if Spec.from_json(stored) != spec:
            raise ParameterError(f"path: {path} holds a different sweep (spec {stored}); use another path")
        return group
    tmp = Path(tempfile.mkdtemp(prefix=tmp_prefix(path), dir=path.parent))
    try:
        group = zarr.open_group(str(tmp / "store"), mode="w")
        create = getattr(group, "create_array", None) or group.create_dataset  # zarr 3, zarr 2
        table = designs(spec)
        arr = create("designs", shape=table.shape, chunks=(spec.chunk, table.shape[1]), dtype="float64")
        arr[:] = table
        for name, (dtype, fill) in _RESULTS.items():
            create(name, shape=(spec.n_designs,), chunks=(spec.chunk,), dtype=dtype, fill_value=fill)
        create("done", shape=(spec.n_chunks,), chunks=(spec.n_chunks,), dtype="bool", fill_value=False)
        group.attrs[files.STORE_ATTR] = files.store_tag("sweep")
        group.attrs["variables"] = list(VARIABLES)
        group.attrs["units"] = {**{k: v[0] for k, v in VARIABLES.items()}, "worst": "m/N", "volume": "m^3",
                                "first_frequency": "Hz"}
        group.attrs["spec"] = spec.to_json()
        make_readable(tmp / "store")
        if path.is_dir() and any(path.iterdir()):  # a user's store, replaced with overwrite (check_store)
            os.replace(path, tmp / "old")
        os.replace(tmp / "store", path)  # atomic: the store appears whole, spec included
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return zarr.open_group(str(path), mode="a")


def check_store(path: str | Path, what: str = "path", overwrite: bool = False) -> str:
    """Refuse, before any work, a sweep output that is not writable or is an existing folder that
    is not an h4pin sweep store (:func:`h4pin.files.check_store_folder`: another zarr store is
    replaced only with ``overwrite``, any other folder never). Returns ``"new"`` (nothing there,
    or an empty folder, which is used), ``"ours"`` (a sweep store: resumed if it holds the same
    spec) or ``"foreign"`` (replaced)."""
    return files.check_store_folder(check_output(path, what, folder=True), "sweep", what, overwrite)


def check_scheduler(address: str, timeout: float = 5.0) -> None:
    """Refuse, within about ``timeout`` s, an address at which no Dask scheduler answers: nothing
    listens there (refused, or no answer to the connection), or something else does (an HTTP
    server, an SSH daemon, ...), which ``distributed.Client`` would wait on without a word or
    read as a message of exabytes.

    A Dask scheduler speaks first: on a new TCP connection it sends its handshake, one message
    framed as ``distributed.comm.tcp`` frames every message (an 8-byte little-endian length, then
    that many bytes: an 8-byte frame count, the frames' 8-byte lengths and the frames, msgpack
    of a dict that names the ``pickle-protocol``). This reads that message (at most 64 KiB) and
    closes the connection. Addresses of other schemes (``tls://``, ``ws://``, ...) are only
    connected to (their handshake is the protocol's own).
    """
    import socket
    import struct
    from urllib.parse import urlparse

    url = urlparse(address if "://" in address else f"tcp://{address}")
    deadline = time.monotonic() + timeout

    def refuse(why: str) -> ParameterError:
        return ParameterError(f"scheduler: cannot reach a Dask scheduler at {address} ({why})")

    if not isinstance(address, str) or not address.strip():
        raise ParameterError(f"scheduler: an address such as tcp://host:8786, got {address!r}")
    if url.scheme != "tcp":
        raise ParameterError(f"scheduler: {address}: h4pin reaches a Dask scheduler over tcp:// only "
                             f"(not {url.scheme}://); give tcp://host:port")
    try:
        _ = url.port  # a port that is not a number raises here
    except ValueError:
        raise ParameterError(f"scheduler: {address}: the port must be a number (tcp://host:8786)") from None

    def recv(sock: socket.socket, n: int) -> bytes:
        data = b""
        while len(data) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise refuse(f"something listens there but sent no Dask handshake within {timeout:g} s"
                             if not data else "its answer stopped half-way")
            sock.settimeout(left)
            try:
                part = sock.recv(n - len(data))
            except TimeoutError:
                continue
            if not part:
                raise refuse("the server there closed the connection: it is not a Dask scheduler")
            data += part
        return data

    try:
        port = url.port or 8786
        host = url.hostname or ""
        sock = socket.create_connection((host, port), timeout=timeout)
    except (OSError, ValueError) as exc:
        raise refuse(str(exc)) from None
    with sock:
        if url.scheme not in ("tcp", ""):
            return
        try:
            (size,) = struct.unpack("<Q", recv(sock, 8))
            if not 16 <= size <= 65536:
                raise refuse(f"the server there does not answer as a Dask scheduler does: it announced a message of "
                             f"{size:,} bytes")
            body = recv(sock, size)
        except OSError as exc:
            raise refuse(str(exc)) from None
        (n_frames,) = struct.unpack_from("<Q", body)
        if not 1 <= n_frames <= 64 or b"pickle-protocol" not in body:
            raise refuse("the server there does not answer as a Dask scheduler does (no Dask handshake)")


def run(path: str | Path, spec: Spec, *, workers: int | None = None, scheduler: str | None = None,
        threads: int | None = None, stop_after: int | None = None, progress: bool = True,
        overwrite: bool = False) -> dict[str, np.ndarray]:
    """Run (or resume) the sweep ``spec`` into the zarr store ``path``; returns :func:`load`.
    One run at a time per store (:func:`h4pin.files.store_lock`): a second one is refused.

    Args:
        workers: Start a Dask LocalCluster with this many single-threaded workers.
        scheduler: Address of a running Dask scheduler (``tcp://host:8786``).
        threads: numba threads per task (default: all locally, 1 on Dask workers).
        stop_after: Stop after this many chunks (to test resuming).
        progress: tqdm progress bar over the chunks.
        overwrite: Replace a zarr store at ``path`` that h4pin did not write (:func:`check_store`).
    """
    if workers is not None and scheduler is not None:
        raise ParameterError("give workers or scheduler, not both")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ParameterError(f"workers must be an integer >= 1 (Dask workers), got {workers!r}")
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
        raise ParameterError(f"threads must be an integer >= 1, got {threads!r}")
    check_size(spec)
    require("zarr", extra="studies", what="the design sweep (h4pin.studies.sweep)")
    if workers is not None or scheduler is not None:
        require("distributed", extra="studies", what="a sweep on Dask")
    check_store(path, "path", overwrite)
    path = Path(path)
    if scheduler is not None:
        check_scheduler(scheduler)
    with files.store_lock(path, "sweep"):
        _run_locked(path, spec, workers, scheduler, threads, stop_after, progress, overwrite)
    return load(path)


def _run_locked(path: Path, spec: Spec, workers: int | None, scheduler: str | None, threads: int | None,
                stop_after: int | None, progress: bool, overwrite: bool) -> None:
    """:func:`run` once it holds the store's lock."""
    from tqdm import tqdm

    group = _open_store(path, spec, overwrite)
    table = group["designs"][:]  # made once, when the store was created (n_designs x 6 floats)
    done = group["done"][:]
    todo = [c for c in range(spec.n_chunks) if not done[c]]
    if stop_after is not None:
        todo = todo[:stop_after]
    text = spec.to_json()

    def write(c: int, res: dict[str, np.ndarray]) -> None:
        sl = slice(c * spec.chunk, min(spec.n_designs, (c + 1) * spec.chunk))
        for name in _RESULTS:
            group[name][sl] = res[name]
        group["done"][c] = True  # after the results: a chunk killed half-way is done again

    bar = tqdm(total=len(todo), desc="sweep", unit="chunk", disable=not progress)
    if workers is None and scheduler is None:
        for c in todo:
            write(*_chunk_task(text, c, table[c * spec.chunk:(c + 1) * spec.chunk], threads))
            bar.update()
    else:
        with Client(workers, scheduler) as client:
            from distributed import as_completed

            futures = [client.submit(_chunk_task, text, c, table[c * spec.chunk:(c + 1) * spec.chunk], threads or 1,
                                     pure=False) for c in todo]
            for future in as_completed(futures):
                write(*future.result())
                bar.update()
    bar.close()
    make_readable(path)


class Client:
    """A Dask client on a new LocalCluster (closed on exit) or on a running scheduler."""

    def __init__(self, workers: int | None, scheduler: str | None):
        self.workers, self.scheduler = workers, scheduler

    def __enter__(self):
        from distributed import Client, LocalCluster

        if self.scheduler is not None:
            self.cluster = None
            self.client = Client(self.scheduler)
        else:
            self.cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None)
            self.client = Client(self.cluster)
        return self.client

    def __exit__(self, *exc: object) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def load(path: str | Path) -> dict[str, np.ndarray]:
    """The sweep's arrays (``designs``, the results, ``done``) and its ``spec``."""
    import zarr

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no sweep at {path}")
    group = zarr.open_group(str(path), mode="r")
    out: dict[str, Any] = {name: group[name][:] if name in group else np.full(group["designs"].shape[0], fill)
                           for name, fill in (("designs", None), *((n, f) for n, (_, f) in _RESULTS.items()),
                                              ("done", None))}
    out["spec"] = Spec.from_json(group.attrs["spec"])
    return out


def pareto(res: dict[str, np.ndarray]) -> np.ndarray:
    """Indices of the designs that reach the whole task and are Pareto-optimal (no other such
    design is both stiffer -- smaller ``worst`` -- and larger in ``volume``), by rising ``worst``."""
    cand = np.flatnonzero(res["reach_all"] & np.isfinite(res["worst"]))
    cand = cand[np.lexsort((-res["volume"][cand], res["worst"][cand]))]
    front, best = [], -np.inf
    for d in cand:
        if res["volume"][d] > best:
            front.append(d)
            best = res["volume"][d]
    return np.array(front, dtype=int)


def write_best(res: dict[str, np.ndarray], folder: str | Path, k: int = 3) -> list[Path]:
    """URDF variants of up to ``k`` Pareto designs (stiffest, largest and one between):
    ``h4_sweep_<index>.urdf`` in ``folder``, loadable by :func:`h4pin.load`.

    Raises:
        ParameterError: no design on the front; ``folder`` missing or not writable, or a folder
            where one of the files goes (checked for all before any is written).
    """
    from h4pin.description.urdf import write_urdf

    front = pareto(res)
    if front.size == 0:
        raise ParameterError("no design reaches the whole task workspace")
    pick = front[np.unique(np.linspace(0, front.size - 1, min(k, front.size)).round().astype(int))]
    paths = [check_output(Path(folder) / f"h4_sweep_{d}.urdf", "folder") for d in pick]  # all, before any is written
    return [write_urdf(params_of(res["designs"][d]), path) for d, path in zip(pick, paths, strict=True)]


def _noop(x: int) -> int:
    return x


def dask_overhead(workers: int = 2, n: int = 400, client: Any = None) -> float:
    """Worker-seconds lost per task on Dask: the wall time of ``n`` empty tasks times the
    number of workers, over ``n`` (each task also pays its result's transfer, a few KB here)."""
    with Client(workers, None) if client is None else _nullcontext(client) as c:
        c.gather(c.map(_noop, range(50), pure=False))  # warm up
        t0 = time.perf_counter()
        c.gather(c.map(_noop, range(n), pure=False))
        wall = time.perf_counter() - t0
        n_workers = len(c.scheduler_info()["workers"])
    return wall * n_workers / n


class _nullcontext:
    def __init__(self, value: Any):
        self.value = value

    def __enter__(self) -> Any:
        return self.value

    def __exit__(self, *exc: object) -> None:
        return None


def bench(n_designs: int = 10_000, threads: int = 1, workers: int | None = None, n_poses: int = 1000,
          timer: Callable[[], float] = time.perf_counter) -> tuple[float, int]:
    """Seconds for a sweep of ``n_designs`` x ``n_poses`` task poses (plus the volume grid) in a
    temporary store, and the number of design-poses evaluated (task + volume grid)."""
    import tempfile

    spec = Spec(n_designs=n_designs, chunk=max(1, min(256, n_designs // 8 or 1)))
    if len(spec.task.poses()) != n_poses:
        raise ParameterError(f"n_poses: the default task box has {len(spec.task.poses())} poses, not {n_poses}")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = timer()
        run(Path(tmp) / "s.zarr", spec, workers=workers, threads=threads, progress=False)
        secs = timer() - t0
    return secs, n_designs * (len(spec.task.poses()) + len(spec.volume.poses()))
