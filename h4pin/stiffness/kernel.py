# SPDX-License-Identifier: Apache-2.0
"""The default compiled path: the Python front end of the compiled pipeline
(:mod:`h4pin.stiffness.pipeline`), eq. 30 of Company, Pierrot and Fauroux (ICRA 2005) and the
robot's compliant elements per pose.

One call of the pipeline does a whole pose: the inverse geometry (closed form, elbow out), the
verdict (:mod:`h4pin.verdicts`), M1 (eq. 6) and its inverse, eq. 30 and the element terms. One
pose and a batch run the same compiled function (one pose is a block of one lane); batches from
:data:`PARALLEL_FROM` poses are cut into one run a thread. Robots whose parallelograms are exact
(:attr:`H4Geometry.ideal <h4pin.H4Geometry>`); the numpy reference (:mod:`h4pin.stiffness.eq30`)
covers every robot and a parametrised test keeps them equal.

The robot comes as an :class:`h4pin.H4Geometry` (``h4.geometry``) or any object with the
attributes listed in :func:`prepare`, packed once into one float vector; its elements
(:class:`h4pin.Elements`) into a table (:func:`pack_elements`, :meth:`Kernel.with_elements`).

K is NaN unless the status is 0 (:data:`h4pin.verdicts.OK`).
"""

from __future__ import annotations

import concurrent.futures
import functools
import os
import types
import weakref
from collections.abc import Iterable, Iterator
from typing import Any

import numba
import numpy as np

from h4pin import _jit
from h4pin.description.elements import AXES, FORMS, SITES, Elements, Kind
from h4pin.description.geometry import H4Geometry, forearms, spring_compliances
from h4pin.errors import ParameterError, PoseError
from h4pin.kinematics.closed_form import as_poses
from h4pin.stiffness import pipeline
from h4pin.stiffness.eq30 import MODELS
from h4pin.stiffness.packed import (
    EL_HEADER,
    EL_ROW,
    G_SIZE,
    NO_ELEMENTS,
    NO_J_N,
    NO_TERMS_N,
    NO_X_N,
    SHAPES,
    KernelResult,
    beam_lengths,
    check_packed,
    pack,
)

#: Default chunk of :func:`iter_compliance` (about 36 MB of output without terms).
CHUNK = 65_536
#: Batches from this many poses are cut in one contiguous run of blocks a thread (numba's number
#: of threads, ``numba.set_num_threads``); smaller ones run in the calling thread (handing a run
#: to a pool thread costs about 20 us: 45 poses).
PARALLEL_FROM = 256


# ----------------------------------------------------------------------------------------------
# Geometry object


def _inputs(f: Any, c: dict[str, np.ndarray]) -> dict[str, Any]:
    """The arguments of :func:`pack` from the fields ``f`` of :class:`H4Geometry` (the object,
    or a mapping as :func:`h4pin.description.geometry.geometry_arrays` gives) and their spring
    compliances ``c``."""
    get = f.__getitem__ if isinstance(f, dict) else functools.partial(getattr, f)
    return dict(P=get("P"), u=get("u"), A0=get("A0"), l=get("l"), lat=get("lat"), C0=get("C0"), b=get("b"),
                c_ctrl=c["control"], c_bend=c["bending"], c_tors=c["torsion"], c_tens=c["tension"], q_lo=get("q_lo"),
                q_hi=get("q_hi"), omega_lo=get("omega_lo"), omega_hi=get("omega_hi"),
                bar_clearance=get("bar_clearance"))


def _namespace(g: H4Geometry) -> types.SimpleNamespace:
    """The geometry object of :func:`prepare` for an :class:`h4pin.description.geometry.H4Geometry` (a loaded
    robot's ``h4.geometry``): its arrays, with the spring compliances per element."""
    if not g.ideal:
        raise ParameterError("the compiled kernel handles robots whose parallelograms are exact (H4Geometry.ideal); "
                             "use the numpy path (method='closed_form') for a toleranced robot")
    return types.SimpleNamespace(**_inputs(g, g.compliances()))


def _array(g: Any, name: str) -> np.ndarray:
    try:
        value = np.asarray(getattr(g, name), dtype=float)
    except AttributeError:
        raise ParameterError(f"geometry object has no attribute {name!r}") from None
    if value.shape != SHAPES[name]:
        raise ParameterError(f"geometry.{name} must have shape {SHAPES[name]}, got {value.shape}")
    if not np.all(np.isfinite(value)):
        raise ParameterError(f"geometry.{name} has non-finite entries")
    return value


def _check(a: dict[str, Any]) -> None:
    """The checks of :func:`prepare` on the arguments of :func:`pack` (leading robot axes allowed),
    before packing."""
    lat = a["lat"]
    if not np.all((lat == 0) | (lat == 1)) or np.any(lat[..., 0::2] != lat[..., 1::2]):
        raise ParameterError(f"geometry.lat must be 0 or 1, the same for both bars of a leg, got {lat.tolist()}")
    if np.any(np.abs(np.linalg.norm(a["u"], axis=-1) - 1.0) > 1e-9):
        raise ParameterError("geometry.u must hold unit vectors")
    for name in ("l", "c_ctrl", "c_bend", "c_tors", "c_tens"):
        if np.any(a[name] <= 0):
            raise ParameterError(f"geometry.{name} must be > 0, got {a[name].tolist()}")
    clearance = a["bar_clearance"]
    if not np.all(np.isfinite(clearance)) or np.any(clearance < 0):
        raise ParameterError(f"geometry.bar_clearance must be finite and >= 0, got {clearance!r}")


def pack_fields(fields: dict[str, Any]) -> np.ndarray:
    """The packed vectors (..., G_SIZE) of many robots at once, checked as :func:`prepare` checks
    one: ``fields`` are those of :class:`H4Geometry` with leading robot axes, as
    :func:`h4pin.description.geometry.geometry_arrays` gives them (robots with exact
    parallelograms, as H4Params makes them). ``Kernel.from_packed(G[k])`` is then robot k's kernel."""
    r = forearms(np.asarray(fields["A0"], dtype=float), np.asarray(fields["P"], dtype=float))[2]
    a = _inputs(fields, spring_compliances(fields["springs"], r, fields["l"]))
    _check(a)
    G = pack(**a)
    check_packed(G)
    return G


def pack_elements(elements: Elements | None, packed: np.ndarray) -> np.ndarray:
    """The element table of the compiled pipeline (:data:`h4pin.stiffness.packed.EL_ROW`) for the
    kinds of ``elements`` that are on (in the schema's order), with the beam lengths of the
    packed geometry ``packed``. Read-only; :data:`NO_ELEMENTS` when none is on."""
    on = () if elements is None else elements.kinds_on()
    return element_table([(k, getattr(elements, k.name)) for k in on], packed)


def element_table(kinds: list[tuple[Kind, Any]], packed: np.ndarray) -> np.ndarray:
    """The element table of (kind, values) pairs: any :class:`h4pin.description.elements.Kind`
    (a schema row: site, form, axis, normal), values ``kind.count`` compliances, or rigidities
    when ``kind.rigidity``. This is all the compiled pipeline knows of an element: a new kind is
    a schema row, not code. Read-only; :data:`NO_ELEMENTS` when ``kinds`` is empty."""
    if not kinds:
        return NO_ELEMENTS
    lengths = beam_lengths(packed)
    rows, values = [], []
    offset = EL_HEADER + EL_ROW * len(kinds)
    for kind, value in kinds:
        length = lengths.get(kind.axis, np.zeros(kind.count))
        rows.append([SITES.index(kind.site), FORMS.index(kind.form), AXES.index(kind.axis), kind.count, offset,
                     AXES.index(kind.normal)])
        values.append(np.stack([kind.compliance(value), np.broadcast_to(length, (kind.count,))], axis=1).ravel())
        offset += 2 * kind.count
    table = np.concatenate([[float(len(kinds))], np.ravel(rows), *values]).astype(np.float64)
    table.setflags(write=False)
    return table


class Kernel:
    """A geometry packed for the compiled pipeline (see :func:`prepare`), with the element table
    of the elements it includes (none by default: :meth:`with_elements`). Calling it on one pose
    is the fast single-pose path: ``K, q, condition, status = kernel(pose)``."""

    geometry: Any
    packed: np.ndarray
    elements: np.ndarray

    def __init__(self, g: Any):
        self.geometry = g
        a: dict[str, Any] = {name: _array(g, name) for name in SHAPES}
        a["bar_clearance"] = float(getattr(g, "bar_clearance", np.nan))
        _check(a)
        G = pack(**a)
        check_packed(G)
        G.setflags(write=False)
        self.packed = G
        self.elements = NO_ELEMENTS

    @classmethod
    def from_packed(cls, G: np.ndarray, elements: np.ndarray = NO_ELEMENTS) -> Kernel:
        """The kernel of a vector packed by :func:`pack_fields` (a read-only copy; ``geometry``
        is None) and an element table (:func:`pack_elements`)."""
        packed = np.array(G, dtype=np.float64)
        if packed.shape != (G_SIZE,):
            raise ParameterError(f"a packed kernel vector has shape ({G_SIZE},), got {packed.shape}")
        packed.setflags(write=False)
        kern = cls.__new__(cls)
        kern.geometry, kern.packed, kern.elements = None, packed, elements
        return kern

    def with_elements(self, elements: Elements | None) -> Kernel:
        """The same geometry with the terms of ``elements`` (None or all off: eq. 30 alone)."""
        if elements is not None and not isinstance(elements, Elements):
            raise ParameterError(f"elements must be an h4pin.Elements or None, got {type(elements).__name__}")
        kern = Kernel.__new__(Kernel)
        kern.geometry, kern.packed, kern.elements = self.geometry, self.packed, pack_elements(elements, self.packed)
        return kern

    @property
    def kinds(self) -> int:
        """Number of element kinds on (the terms after eq. 30's four)."""
        return int(self.elements[0])

    def __call__(self, pose: np.ndarray, model: str = "paper") -> tuple[np.ndarray, np.ndarray, float, int]:
        """K (8, 8), q (4,), condition, status at one pose [x, y, z, theta] (m, rad)."""
        x = np.asarray(pose, dtype=np.float64)
        if x.shape != (4,):
            x = as_poses(pose)
            if x.ndim != 1:
                raise PoseError(f"a Kernel call takes one pose (4,), got shape {x.shape}; use compliance_batch")
        K, q, cond, status, _ = one(self, x, model_code(model))
        return K, q, cond, status


def prepare(g: H4Geometry | Kernel | Any) -> Kernel:
    """Check and pack a geometry object once, for many calls of the kernel.

    ``g`` has the attributes (SI, world frame, legs i = 0..3, bars n = 2 i + j):

    * ``P`` (4, 3): a point of actuator axis i, the foot of the perpendicular from A_i;
      ``u`` (4, 3): unit actuator axis (q right-handed about u_i);
    * ``A0`` (8, 3): ball-joint centres A_ij at q_i = 0; ``l`` (8,): bar lengths;
    * ``lat`` (8,): lateral bar (0/1) of each bar; ``C0`` (2, 3): C_k - D at theta = 0 in the
      central bar's frame; ``b`` (8, 3): B_ij - C_k (the lateral bars only translate);
    * springs: ``c_ctrl`` (4,) 1/kc_i, ``c_bend`` (4,) phi^3 r_i/(3 E I), ``c_tors`` (4,)
      phi r_i/(G I0) (rad/(N.m)), ``c_tens`` (8,) l/(Sb Eb) (m/N);
    * limits: ``q_lo``, ``q_hi`` (4,) actuator angles, ``omega_lo``, ``omega_hi`` (2,) lateral
      revolutes (rad); ``bar_clearance`` (m): least distance between the axes of two bars of
      different legs.

    An :class:`h4pin.H4Geometry` (``h4.geometry``, ideal parallelograms) is converted.

    Raises:
        ParameterError: an attribute is missing or has the wrong shape (the message names it).
    """
    if isinstance(g, Kernel):
        return g
    if isinstance(g, H4Geometry):
        g = _namespace(g)
    return Kernel(g)


def model_code(model: str) -> int:
    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}, got {model!r}")
    return MODELS.index(model)


# ----------------------------------------------------------------------------------------------
# Running the pipeline

#: Whether the pipeline's entries are compiled (:mod:`h4pin._jit`): until then
#: ``compliance(method="auto")`` takes the numpy reference instead of compiling in the call. One
#: pose (:func:`h4pin.stiffness.pipeline.one`) is compiled first.
ONE = _jit.Gate("compiled pipeline, one pose", pipeline.one, step="one")
BATCH = _jit.Gate("compiled pipeline, batch", pipeline.run, step="batch")

_POOL: list[concurrent.futures.ThreadPoolExecutor] = []
_ENTRIES: dict[str, Any] = {}


def _pool() -> concurrent.futures.ThreadPoolExecutor:
    """The threads that run the pipeline beside the calling one (made at first need; a forked
    child makes its own)."""
    if not _POOL:
        _POOL.append(concurrent.futures.ThreadPoolExecutor(max(1, numba.config.NUMBA_NUM_THREADS - 1),
                                                           thread_name_prefix="h4pin-pipeline"))
    return _POOL[0]


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_POOL.clear)


def _call(name: str, *args: Any) -> None:
    """``h4pin.stiffness.pipeline.<name>`` (``run`` or ``one``) through the compiled entry point
    of its one overload (every caller passes the same types: read-only poses and tables, fresh or
    checked outputs), which skips the dispatcher's typing of a dozen arguments (about 1 us a
    call); the first call goes through the dispatcher and looks the overload up by the types it
    was given."""
    entry = _ENTRIES.get(name)
    if entry is not None:
        entry(*args)
        return
    f = getattr(pipeline, name)
    f(*args)
    overload = getattr(f, "overloads", {}).get(tuple(numba.typeof(a) for a in args))
    if overload is not None and getattr(overload, "entry_point", None) is not None:
        _ENTRIES[name] = overload.entry_point


def readonly(x: np.ndarray) -> np.ndarray:
    """A read-only view (one type for every caller: no second compiled version)."""
    if not x.flags.writeable:
        return x
    v = x.view()
    v.setflags(write=False)
    return v


def run_poses(kern: Kernel, x: np.ndarray, code: int, res: KernelResult, terms: bool, jacobian: bool,
         inter: np.ndarray | None = None) -> KernelResult:
    """The pipeline over all the poses of x (N, 4) C-contiguous float64 into ``res`` (of its size),
    on numba's number of threads: one contiguous run of whole blocks a thread, the calling thread
    taking the first (the compiled code releases the GIL). Python threads and not a ``prange``:
    a parallel numba function recompiles the pipeline under its own options (four times the
    compile time for the same speed). ``inter``: (N, :data:`h4pin.stiffness.pipeline.NX`) to
    receive each pose's intermediates (M1^-1, the factors of eq. 30, the lane scratch)."""
    n = len(x)
    if not n:
        return res
    x = readonly(x)
    T = res.terms if terms else NO_TERMS_N
    J = res.J if jacobian else NO_J_N
    args = (kern.packed, kern.elements, code, res.K, res.q, res.condition, res.status, T, terms, J, jacobian,
            NO_X_N if inter is None else inter, inter is not None)
    threads = min(numba.get_num_threads(), -(-n // pipeline.LANES)) if n >= PARALLEL_FROM else 1
    if threads <= 1:
        _call("run", x, 0, n, *args)
        return res
    step = pipeline.LANES * -(-n // (pipeline.LANES * threads))
    bounds = [(lo, min(n, lo + step)) for lo in range(0, n, step)]
    if "run" not in _ENTRIES:
        _call("run", x, 0, 1, *args)  # the entry point, known before the threads start
    futures = [_pool().submit(_call, "run", x, lo, hi, *args) for lo, hi in bounds[1:]]
    _call("run", x, *bounds[0], *args)
    for f in futures:
        f.result()
    return res


def empty_result(n: int, terms: bool, jacobian: bool, kinds: int = 0) -> KernelResult:
    return KernelResult(np.empty((n, 8, 8)), np.empty((n, 4)), np.empty(n), np.empty(n, dtype=np.int8),
                        np.empty((n, 4 + kinds, 8, 8)) if terms else None, np.empty((n, 4, 4)) if jacobian else None)


def _check_out(out: KernelResult, n: int, terms: bool, jacobian: bool, kinds: int) -> KernelResult:
    shapes = {"K": (n, 8, 8), "q": (n, 4), "condition": (n,), "status": (n,)}
    if terms:
        shapes["terms"] = (n, 4 + kinds, 8, 8)
    if jacobian:
        shapes["J"] = (n, 4, 4)
    for name, shape in shapes.items():
        arr = getattr(out, name)
        want = np.int8 if name == "status" else np.float64
        if (not isinstance(arr, np.ndarray) or arr.shape != shape or arr.dtype != want
                or not arr.flags.c_contiguous or not arr.flags.writeable):
            raise ParameterError(f"out.{name} must be a writable C-contiguous {np.dtype(want).name} array of "
                                 f"shape {shape}")
    return out


#: The T and X arguments of :func:`one` without terms or intermediates (never written).
NO_TERMS = np.empty((4, 8, 8))
NO_X = np.empty(1)


def one(kern: Kernel, x: np.ndarray, code: int, terms: bool = False, inter: np.ndarray | None = None) -> tuple:
    """One pose through the pipeline's one-pose entry (:func:`h4pin.stiffness.pipeline.one`), for
    a caller that has checked it: ``x`` a read-only finite float64 pose (4,), ``code`` 0 (paper)
    or 1 (consistent); ``inter`` (:data:`h4pin.stiffness.pipeline.NX`,) receives the pose's
    intermediates. Returns K (8, 8), q (4,), condition, status and the terms (4 + kinds, 8, 8)
    (None unless ``terms``)."""
    K, q = np.empty((8, 8)), np.empty(4)
    T = np.empty((4 + int(kern.elements[0]), 8, 8)) if terms else NO_TERMS
    X = NO_X if inter is None else inter
    entry = _ENTRIES.get("one")
    if entry is not None:
        cond, status = entry(x, kern.packed, kern.elements, code, K, q, T, terms, X, inter is not None)
    else:
        args = (readonly(x), kern.packed, kern.elements, code, K, q, T, terms, X, inter is not None)
        cond, status = pipeline.one(*args)
        overload = getattr(pipeline.one, "overloads", {}).get(tuple(numba.typeof(a) for a in args))
        if overload is not None and getattr(overload, "entry_point", None) is not None:
            _ENTRIES["one"] = overload.entry_point
    return K, q, cond, status, T if terms else None


def compliance_batch(g: Any, poses: np.ndarray, model: str = "paper", out: KernelResult | None = None, *,
                     terms: bool = False, jacobian: bool = False) -> KernelResult:
    """K of eq. 30 (with the kernel's elements: :meth:`Kernel.with_elements`), q, the condition
    and the verdict at N poses, in parallel over the poses.

    Args:
        g: A geometry (see :func:`prepare`) or a :class:`Kernel`.
        poses: (N, 4) or (4,) poses [x, y, z, theta] (m, rad).
        model: ``"paper"`` or ``"consistent"`` (see :mod:`h4pin.stiffness.api`).
        out: Arrays to fill (a :class:`KernelResult` of the right shapes, writable and
            C-contiguous, e.g. memory-mapped files); allocated if None.
        terms: Also return the terms (eq. 30's four, then one per element kind on; 512 bytes a
            term a pose).
        jacobian: Also return J = Jx^-1 Jq (eq. 8).

    The number of threads is numba's (``numba.set_num_threads``).
    """
    kern = prepare(g)
    code = model_code(model)
    x = as_poses(poses)
    x = np.ascontiguousarray(x[None] if x.ndim == 1 else x)
    res = (empty_result(len(x), terms, jacobian, kern.kinds) if out is None
           else _check_out(out, len(x), terms, jacobian, kern.kinds))
    return run_poses(kern, x, code, res, terms, jacobian)


def compliance_one(g: Any, pose: np.ndarray, model: str = "paper") -> tuple[np.ndarray, np.ndarray, float, int]:
    """K (8, 8), q (4,), condition, status at one pose. Pass a :class:`Kernel` (:func:`prepare`)
    for the fast path; a geometry object is packed at every call."""
    return prepare(g)(pose, model)


def iter_compliance(g: Any, poses: np.ndarray | Iterable[np.ndarray], model: str = "paper", *, chunk: int = CHUNK,
                    terms: bool = False, jacobian: bool = False) -> Iterator[tuple[int, KernelResult]]:
    """Stream the pipeline over many poses in chunks: yields ``(start, result)`` per chunk.

    ``poses`` is an (N, 4) array (cut into ``chunk`` rows) or an iterable of (n, 4) arrays (each
    one a chunk, e.g. generated on the fly). The result's arrays are reused from one chunk to
    the next: reduce or copy them before asking for the next one. Memory stays at one chunk.
    """
    kern = prepare(g)
    if chunk < 1:
        raise ParameterError(f"chunk must be >= 1, got {chunk!r}")
    if isinstance(poses, np.ndarray):
        x = as_poses(poses)
        x = x[None] if x.ndim == 1 else x
        parts: Iterable[np.ndarray] = (x[s:s + chunk] for s in range(0, len(x), chunk))
    else:
        parts = poses
    buf: KernelResult | None = None
    start = 0
    for part in parts:
        n = len(part)
        if buf is None or len(buf.K) < n:
            buf = empty_result(max(n, chunk), terms, jacobian, kern.kinds)
        view = KernelResult(*(None if a is None else a[:n] for a in buf))
        yield start, compliance_batch(kern, part, model, view, terms=terms, jacobian=jacobian)
        start += n


def cached() -> bool:
    """Whether the compiled pipeline is ready (compiled here, or current in numba's on-disk
    cache); else a call that needs it compiles it once."""
    return ONE.cached() and BATCH.cached()


def threads() -> int:
    """numba's current number of threads for the pipeline."""
    return numba.get_num_threads()


#: The names the studies call these by (h4pin.studies.atlas, .sweep, .frequency), until they use the public ones.

_KERNELS: dict[tuple[int, int], Kernel] = {}


def for_geometry(g: H4Geometry, elements: Elements | None = None) -> Kernel:
    """The packed kernel of a loaded robot's geometry and of ``elements`` (None: eq. 30 alone),
    made once per pair (a read-only cache keyed by the immutable :class:`h4pin.H4Geometry` and
    :class:`h4pin.Elements`, outside them; threads may share it). Keyed by their ids and dropped
    when either goes (a plain dict lookup: a WeakKeyDictionary costs 0.6 us)."""
    key = (id(g), id(elements))
    kern = _KERNELS.get(key)
    if kern is None:
        kern = prepare(g) if elements is None else for_geometry(g).with_elements(elements)
        if _KERNELS.setdefault(key, kern) is kern:
            weakref.finalize(g, _KERNELS.pop, key, None)
            if elements is not None:
                weakref.finalize(elements, _KERNELS.pop, key, None)
    return kern


def backend(h4, x: np.ndarray, model: str, terms: bool, elements: Elements | None = None):
    """The pipeline as a backend of :func:`h4pin.compliance` (:class:`h4pin.stiffness.eq30.Raw`):
    eq. 30 and the terms of ``elements``; robots whose parallelograms are exact."""
    from h4pin.stiffness.eq30 import Raw

    kern = for_geometry(h4.geometry, elements)
    res = run_poses(kern, x, MODELS.index(model), empty_result(len(x), terms, False, kern.kinds), terms, False)
    return Raw(res.K, res.terms, res.q, res.condition, res.status)


__all__ = ["BATCH", "CHUNK", "ONE", "PARALLEL_FROM", "Kernel", "KernelResult", "backend", "cached", "compliance_batch",
           "compliance_one", "empty_result", "for_geometry", "iter_compliance", "one", "pack", "pack_elements",
           "pack_fields", "prepare", "readonly", "run_poses", "threads"]
